/// @file
/// Plain virtual-sensor values (see mrroc/msg/sensor_reading.hpp).
#include "mrroc/msg/sensor_reading.hpp"

#include <fmt/format.h>

#include "mrroc/core/error.hpp"

namespace mrroc::vsp {

double Reading::value(const std::string& name) const {
  for (std::size_t i = 0; i < names.size() && i < values.size(); ++i)
    if (names[i] == name) return values[i];
  throw Error(
      fmt::format("the reading has no value '{}' (it has: {})", name, fmt::join(names, ", ")));
}

const char* to_string(Command c) {
  switch (c) {
    case Command::configure: return "CONFIGURE";
    case Command::initiate_reading: return "INITIATE_READING";
    case Command::get_reading: return "GET_READING";
    case Command::terminate: return "TERMINATE";
  }
  return "?";
}

}  // namespace mrroc::vsp
