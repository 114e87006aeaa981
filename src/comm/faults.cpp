#include "mrroc/comm/faults.hpp"

#include <fmt/format.h>

#include <atomic>
#include <cstdio>
#include <cstdlib>
#include <sstream>
#include <string>

#include "mrroc/core/error.hpp"
#include "mrroc_build_options.hpp"

namespace mrroc::comm {

LinkFaults link_faults_from_environment() {
  LinkFaults faults;
  const char* text = std::getenv("MRROC_LINK_FAULTS");
  if (text == nullptr || *text == '\0') return faults;
  if constexpr (!kLinkFaultInjection) {
    static std::atomic<bool> told{false};
    if (!told.exchange(true))
      std::fprintf(stderr,
                   "MRROC_LINK_FAULTS is ignored: this build has no link fault injection (a "
                   "testing aid, only in a build configured with "
                   "-DMRROC_LINK_FAULT_INJECTION=ON)\n");
    return faults;
  }
  std::stringstream all(text);
  std::string item;
  while (std::getline(all, item, ',')) {
    const auto eq = item.find('=');
    const std::string key = item.substr(0, eq);
    const std::string value = eq == std::string::npos ? "" : item.substr(eq + 1);
    char* end = nullptr;
    const double number = std::strtod(value.c_str(), &end);
    if (value.empty() || end == nullptr || *end != '\0')
      throw Error(fmt::format("MRROC_LINK_FAULTS: '{}' needs a number (e.g. drop=0.1)", item));
    if (key == "drop" || key == "duplicate" || key == "delay") {
      if (!(number >= 0.0 && number < 1.0))
        throw Error(
            fmt::format("MRROC_LINK_FAULTS: {} = {} is outside 0..1 (a probability)", key, number));
      (key == "drop" ? faults.drop : key == "duplicate" ? faults.duplicate : faults.delay) = number;
    } else if (key == "delay_ms") {
      if (!(number >= 0.0 && number <= 10000.0))
        throw Error(
            fmt::format("MRROC_LINK_FAULTS: delay_ms = {} ms is outside 0..10000 ms", number));
      faults.delay_ms = number;
    } else if (key == "seed") {
      faults.seed = static_cast<std::uint64_t>(number);
    } else {
      throw Error(fmt::format(
          "MRROC_LINK_FAULTS: unknown key '{}' (drop, duplicate, delay, delay_ms, seed)", key));
    }
  }
  return faults;
}

}  // namespace mrroc::comm
