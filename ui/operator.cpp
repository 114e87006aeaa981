#include "operator.hpp"

#include <fmt/format.h>

#include <chrono>
#include <thread>

#include "mrroc/comm/auth.hpp"
#include "mrroc/comm/bus.hpp"
#include "mrroc/comm/sync_annotations.hpp"
#include "mrroc/config/process_set.hpp"
#include "mrroc/core/time.hpp"
#include "mrroc_lcm/emergency_stop_t.hpp"

namespace mrroc::ui {

namespace {
struct Name {
  OperatorCommand command;
  const char* word;
};
constexpr Name kNames[] = {
    {OperatorCommand::start, "start"},         {OperatorCommand::pause, "pause"},
    {OperatorCommand::resume, "resume"},       {OperatorCommand::stop, "stop"},
    {OperatorCommand::terminate, "terminate"}, {OperatorCommand::status, "status"},
};
}  // namespace

std::optional<OperatorCommand> operator_command_from_string(const std::string& word) {
  for (const Name& n : kNames)
    if (word == n.word) return n.command;
  return std::nullopt;
}

const char* to_string(OperatorCommand command) {
  for (const Name& n : kNames)
    if (command == n.command) return n.word;
  return "?";
}

std::string mp_state_name(std::int8_t state) {
  using R = mrroc_lcm::operator_reply_t;
  switch (state) {
    case R::IDLE:
      return "IDLE";
    case R::RUNNING:
      return "RUNNING";
    case R::PAUSED:
      return "PAUSED";
    case R::STOPPING:
      return "STOPPING";
    case R::FINISHED:
      return "FINISHED";
    case R::FAILED:
      return "FAILED";
    case R::TERMINATING:
      return "TERMINATING";
    default:
      return fmt::format("UNKNOWN({})", state);
  }
}

MpStatus send_operator_command(MpClient& client, OperatorCommand command) {
  mrroc_lcm::operator_command_t request{};
  request.command = static_cast<std::int8_t>(command);
  const mrroc_lcm::operator_reply_t reply = client.call(request);
  MpStatus out;
  out.accepted = reply.accepted;
  out.state = mp_state_name(reply.state);
  out.task = reply.task;
  out.runs = reply.runs;
  out.started_utime = reply.started_utime;
  out.text = reply.text;
  return out;
}

void publish_emergency_stop(comm::Bus& bus, bool engage, const std::string& robot,
                            const std::string& reason) {
  mrroc_lcm::emergency_stop_t m{};
  m.header.sender = comm::unique_endpoint_name("ui");
  m.header.kind = mrroc_lcm::header_t::BROADCAST;
  m.action = engage ? mrroc_lcm::emergency_stop_t::ENGAGE : mrroc_lcm::emergency_stop_t::RELEASE;
  m.robot = robot;
  m.reason = reason;
  for (int i = 0; i < 5; ++i) {
    m.header.seq = i + 1;
    m.header.utime = now_utime();
    if (bus.auth() != nullptr) comm::sign(*bus.auth(), m);  // an EDP releases only when signed
    comm::detail::published();
    bus.lcm().publish(channels::emergency_stop, &m);
    if (i < 4) std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
}

std::string describe_emergency_stop(bool engage, const std::string& robot,
                                    const std::string& reason) {
  return fmt::format("{}{} for {}", engage ? "EMERGENCY STOP" : "emergency stop released",
                     reason.empty() ? "" : " (" + reason + ")",
                     robot.empty() ? "every robot" : "robot " + robot);
}

}  // namespace mrroc::ui
