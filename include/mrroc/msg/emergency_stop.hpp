#pragma once
/// @file
/// The emergency stop (emergency_stop_t, channel mrroc/estop) as a plain value; see
/// docs/messages.md for who sends which action and how an EDP follows them.

#include <cstdint>
#include <string>

namespace mrroc {

enum class EstopAction : std::int8_t {
  engage = 1,    ///< an operator's command: stop
  release = 2,   ///< an operator's command: release (obeyed only when authentic)
  engaged = 3,   ///< the latch holder's announcement: the stop is latched engaged
  released = 4,  ///< the latch holder's announcement: the stop is latched released
};
const char* to_string(EstopAction a);

struct EmergencyStop {
  EstopAction action = EstopAction::engage;
  std::string robot;   ///< "" for every robot
  std::string reason;  ///< ENGAGE: the operator's text; ENGAGED: the text of the ENGAGE latched
  /// ENGAGED / RELEASED: header.utime of the operator's command that set this state (0: the
  /// state the latch started with) [us since the Unix epoch]; else 0.
  std::int64_t latched_utime = 0;
};

}  // namespace mrroc
