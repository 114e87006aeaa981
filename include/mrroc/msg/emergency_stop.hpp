#pragma once
/// @file
/// The emergency stop (emergency_stop_t, channel mrroc/estop) as a plain value; see
/// docs/messages.md for who sends which action and how an EDP follows them.

#include <cstdint>
#include <string>
#include <vector>

namespace mrroc {

enum class EstopAction : std::int8_t {
  engage = 1,    ///< an operator's command: stop
  release = 2,   ///< an operator's command: release (obeyed only when authentic)
  engaged = 3,   ///< the latch holder's announcement: the stop is latched engaged
  released = 4,  ///< the latch holder's announcement: the stop is latched released
};
const char* to_string(EstopAction a);

/// Names one operator command (ENGAGE or RELEASE): its sender and the sender's number for it.
struct EstopCommandRef {
  std::string sender;   ///< header.sender of the command
  std::int64_t id = 0;  ///< its command_id
  friend bool operator==(const EstopCommandRef& a, const EstopCommandRef& b) {
    return a.id == b.id && a.sender == b.sender;
  }
  friend bool operator!=(const EstopCommandRef& a, const EstopCommandRef& b) { return !(a == b); }
};

/// The most ENGAGEs one announcement names.
inline constexpr std::size_t kMaxEstopEngages = 16;

struct EmergencyStop {
  EstopAction action = EstopAction::engage;
  std::string robot;   ///< "" for every robot
  std::string reason;  ///< ENGAGE: the operator's text; ENGAGED: the text of the ENGAGE latched
  /// ENGAGE / RELEASE: the sender's number of this command (> 0), the same in every copy; else 0.
  std::int64_t command_id = 0;
  /// ENGAGED / RELEASED: the command that set this state (empty: the latch's initial state).
  EstopCommandRef by;
  /// ENGAGED: the ENGAGEs the latch holds; RELEASED: the ENGAGEs the RELEASE `by` ended (at most
  /// kMaxEstopEngages).
  std::vector<EstopCommandRef> engages;
};

}  // namespace mrroc
