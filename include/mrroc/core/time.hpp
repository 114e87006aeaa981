#pragma once
/// @file
/// Clock helpers.

#include <cstdint>
#include <string>

namespace mrroc {

/// The servo period of an EDP whose config does not say otherwise ([robot.edp] servo_period_ms),
/// and the default of everything that must agree with it (generators, the CiA 402 cycle) [s].
inline constexpr double kDefaultServoPeriodS = 0.002;

/// Wall-clock time [us since the Unix epoch] (message stamps).
std::int64_t now_utime();
/// Monotonic time [ns] (timeouts, loops).
std::int64_t monotonic_ns();
/// "HH:MM:SS.mmm" (local time) of a utime, for consoles.
std::string format_utime(std::int64_t utime);

}  // namespace mrroc
