#include "mrroc/core/time.hpp"

#include <chrono>
#include <ctime>

#include <fmt/format.h>

namespace mrroc {

std::int64_t now_utime() {
  return std::chrono::duration_cast<std::chrono::microseconds>(
             std::chrono::system_clock::now().time_since_epoch())
      .count();
}

std::int64_t monotonic_ns() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(
             std::chrono::steady_clock::now().time_since_epoch())
      .count();
}

std::string format_utime(std::int64_t utime) {
  const std::time_t seconds = static_cast<std::time_t>(utime / 1000000);
  std::tm local{};
  localtime_r(&seconds, &local);
  return fmt::format("{:02}:{:02}:{:02}.{:03}", local.tm_hour, local.tm_min, local.tm_sec,
                     (utime / 1000) % 1000);
}

}  // namespace mrroc
