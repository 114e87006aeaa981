#pragma once
// SET OUTPUTS from the stock ECP tasks: reading the bits from a task argument, and the
// instruction.
#include <fmt/format.h>

#include <cstdint>
#include <string>

#include "mrroc/config/params.hpp"
#include "mrroc/core/error.hpp"
#include "mrroc/ecp/robot.hpp"

namespace mrroc::ecp {

/// The binary outputs of argument `key` (bit i = line i). @throws ConfigError outside 32 bits.
inline std::uint32_t outputs_argument(const Params& args, const std::string& key) {
  const std::int64_t bits = args.get_int(key);
  if (bits < 0 || bits > 0xFFFFFFFFLL)
    throw ConfigError(args.location_of(key),
                      fmt::format("'{}' = {} is outside 0..0xFFFFFFFF", key, bits));
  return static_cast<std::uint32_t>(bits);
}

/// SET OUTPUTS `bits`; with `get_inputs`, a SET_GET that also reads the inputs into the image
/// (as the EDP read them in the cycle before the outputs changed).
inline void set_outputs(Robot& robot, std::uint32_t bits, bool get_inputs) {
  edp::Instruction& c = robot.image().command;
  c = edp::Instruction{};
  c.type = get_inputs ? edp::InstructionType::set_get : edp::InstructionType::set;
  c.set = edp::item::outputs;
  if (get_inputs) c.get = edp::item::inputs;
  c.output_values = bits;
  robot.execute();
}

}  // namespace mrroc::ecp
