#pragma once
/// @file
/// The client of one robot's EDP: instructions out, replies in, over the ECP -> EDP request/reply
/// link (channels `<robot>/edp/cmd` and `<robot>/edp/reply`; docs/architecture.md). The ECP's
/// robot (ecp::Robot, mrroc/ecp/robot.hpp) is built on it; so is anything else that drives an
/// EDP, e.g. the console's jogs.
///
/// It keeps the rules of the EDP's one owner (docs/edp.md, "One owner at a time"): the first
/// instruction other than QUERY after construction, after a timeout or after take_over_next()
/// takes the EDP over. Requests are re-sent after `attempt_timeout` until `max_attempts` went
/// unanswered (docs/messages.md, "Request/reply protocol").
///
/// No LCM here: the link lives behind a pointer, in src/edp/client.cpp.

#include <chrono>
#include <memory>
#include <string>

#include "mrroc/core/error.hpp"
#include "mrroc/msg/edp_instruction.hpp"

namespace mrroc::comm {
class Bus;
struct ClientOptions;
}  // namespace mrroc::comm

namespace mrroc::edp {

/// Thrown when the EDP refuses an instruction (code and text are the EDP's; nothing moved).
class Refused : public RemoteError {
 public:
  using RemoteError::RemoteError;
};

struct ClientOptions {
  std::chrono::milliseconds attempt_timeout{250};  ///< wait per attempt before re-sending
  int max_attempts = 12;  ///< silent attempts (no reply, no IN_PROGRESS) before TimeoutError
};

class Client {
 public:
  /// @param process_name  the caller's name (e.g. "ecp/irb6"); the link adds "#<pid>".
  /// @param robot_name    the robot whose EDP is called (its channels are named after it).
  Client(comm::Bus& bus, const std::string& process_name, const std::string& robot_name,
         ClientOptions options = {});
  /// With the request/reply layer's own options (mrroc/comm/request_reply.hpp), fault injection
  /// on the outgoing instructions included.
  Client(comm::Bus& bus, const std::string& process_name, const std::string& robot_name,
         const comm::ClientOptions& options);
  ~Client();
  Client(const Client&) = delete;
  Client& operator=(const Client&) = delete;

  [[nodiscard]] const std::string& robot() const;

  /// Sends `instruction` (with take_over set when a take-over is due and it is not a QUERY) and
  /// returns the EDP's reply.
  /// @throws Refused when the EDP answers an error (its code and text; the message names the
  /// robot and the instruction), TimeoutError when no attempt got an answer (the next
  /// instruction then takes the EDP over: whatever it did with this one, it starts afresh),
  /// DecodeError for a reply that does not decode, CallAbandoned after abandon().
  Reply call(const Instruction& instruction);
  /// Ends the wait of the call in progress at once (CallAbandoned; the next instruction then
  /// takes the EDP over, as after a timeout). Thread-safe; a later call is not affected.
  void abandon();

  /// The next instruction other than QUERY takes the EDP over (edp_instruction_t.take_over): the
  /// EDP then obeys this client only, and forgets a QUERY that was due. Set by the constructor
  /// and after a timeout; the console sets it before every jog.
  void take_over_next();
  /// True while a take-over is due: from the constructor, a timeout or take_over_next() until
  /// the EDP answers an instruction with anything but a refusal for not being its owner.
  [[nodiscard]] bool take_over_due() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace mrroc::edp
