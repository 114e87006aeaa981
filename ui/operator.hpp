#pragma once
// Operator commands to the MP (operator_command_t / operator_reply_t over request/reply), shared
// by the command line and the web console.

#include <chrono>
#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "mrroc/comm/request_reply.hpp"
#include "mrroc/msg/emergency_stop.hpp"
#include "mrroc/msg/operator.hpp"
#include "mrroc_lcm/operator_command_t.hpp"
#include "mrroc_lcm/operator_reply_t.hpp"

namespace mrroc::ui {

/// The operator commands, as the command line and the API name them.
enum class OperatorCommand : std::int8_t {
  start = static_cast<std::int8_t>(mp::OperatorCommandType::start),
  pause = static_cast<std::int8_t>(mp::OperatorCommandType::pause),
  resume = static_cast<std::int8_t>(mp::OperatorCommandType::resume),
  stop = static_cast<std::int8_t>(mp::OperatorCommandType::stop),
  terminate = static_cast<std::int8_t>(mp::OperatorCommandType::terminate),
  status = static_cast<std::int8_t>(mp::OperatorCommandType::status),
};

/// "start", "pause", ... ; nothing for another word.
std::optional<OperatorCommand> operator_command_from_string(const std::string& word);
const char* to_string(OperatorCommand command);
/// "IDLE", "RUNNING", ... for operator_reply_t::state; "UNKNOWN(n)" otherwise.
std::string mp_state_name(std::int8_t state);

/// The MP's answer in plain values.
struct MpStatus {
  bool accepted = false;
  std::string state;  ///< mp_state_name
  std::string task;
  int runs = 0;
  std::int64_t started_utime = 0;  ///< [us since the Unix epoch], 0 if never started
  std::string text;
};

/// The client of the MP's operator link (its messages are encoded and decoded by the codecs of
/// comm/messages.hpp in send_operator_command).
using MpClient = comm::Client<mrroc_lcm::operator_command_t, mrroc_lcm::operator_reply_t>;

/// Sends one command. @throws TimeoutError when no MP answers, comm::DecodeError when its
/// answer does not validate.
MpStatus send_operator_command(MpClient& client, OperatorCommand command);

}  // namespace mrroc::ui

namespace mrroc::comm {
class Bus;
}

namespace mrroc::ui {
/// Publishes emergency_stop_t on mrroc/estop 5 times, 5 ms apart (UDP may drop one; an EDP acts
/// on the first copy and ignores the others). `robot` empty: every robot. Honours
/// MRROC_LINK_FAULTS (comm/faults.hpp), so that a test can drop every copy.
/// Every copy carries the same command number; returns the command's name (sender, number).
EstopCommandRef publish_emergency_stop(comm::Bus& bus, bool engage, const std::string& robot,
                                       const std::string& reason);

/// How long the operator's tools wait for every robot to confirm the stop (or its release).
inline constexpr std::chrono::milliseconds kEstopConfirmDeadline{500};
/// How long after sending they wait at least for the latch holder's announcement naming it.
inline constexpr std::chrono::milliseconds kEstopLatchWait{500};

/// The answer of the robots to an emergency stop or release.
struct EstopConfirmation {
  std::vector<std::string> confirmed;        ///< robots whose robot_state_t showed the new state
  std::vector<std::string> unconfirmed;      ///< robots that did not within the deadline
  std::map<std::string, double> latency_ms;  ///< per confirmed robot: from sending to the state
  std::map<std::string, std::int64_t> servo_step;  ///< the step of the confirming state
  /// The latch holder whose authentic announcement named this command ("launch#41"), empty
  /// when none did: then the stop is not confirmed either (an EDP that starts, or missed the
  /// command, would not know).
  std::string latched_by;
  [[nodiscard]] bool all() const { return unconfirmed.empty() && !latched_by.empty(); }
};

/// Sends the stop (publish_emergency_stop) and waits at most `deadline` for the robot_state_t of
/// each of `robots` (on <robot>/edp/state, received after the send) to show `estop == engage`.
/// The bus must be started.
EstopConfirmation send_and_confirm_emergency_stop(
    comm::Bus& bus, bool engage, const std::vector<std::string>& robots, const std::string& robot,
    const std::string& reason, std::chrono::milliseconds deadline = kEstopConfirmDeadline);
/// One line: "confirmed by irb6 (24 ms), irb6b (31 ms)" / "NOT CONFIRMED by irb6 within 500 ms
/// (no robot_state_t shows the stop engaged); confirmed by ...", plus the latch.
std::string describe_confirmation(bool engage, const EstopConfirmation& c,
                                  std::chrono::milliseconds deadline = kEstopConfirmDeadline);
/// "EMERGENCY STOP (operator) for every robot", as printed and reported to the SRP.
std::string describe_emergency_stop(bool engage, const std::string& robot,
                                    const std::string& reason);
}  // namespace mrroc::ui
