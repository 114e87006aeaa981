#include "operator.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <mutex>
#include <optional>
#include <thread>

#include "mrroc/comm/auth.hpp"
#include "mrroc/comm/bus.hpp"
#include "mrroc/comm/edge.hpp"
#include "mrroc/comm/faults.hpp"
#include "mrroc/comm/request_reply.hpp"
#include "mrroc/comm/sync_annotations.hpp"
#include "mrroc/config/process_set.hpp"
#include "mrroc/core/time.hpp"

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
  if (state < static_cast<std::int8_t>(mp::TaskState::idle) ||
      state > static_cast<std::int8_t>(mp::TaskState::terminating))
    return fmt::format("UNKNOWN({})", state);
  return mp::to_string(static_cast<mp::TaskState>(state));
}

MpStatus send_operator_command(MpClient& client, OperatorCommand command) {
  const mp::OperatorReply reply = comm::decode(client.call(
      comm::encode(mp::OperatorCommand{static_cast<mp::OperatorCommandType>(command)})));
  MpStatus out;
  out.accepted = reply.accepted;
  out.state = mp::to_string(reply.state);
  out.task = reply.task;
  out.runs = reply.runs;
  out.started_utime = reply.started_utime;
  out.text = reply.text;
  return out;
}

EstopCommandRef publish_emergency_stop(comm::Bus& bus, bool engage, const std::string& robot,
                                       const std::string& reason) {
  // The process' number for each of its commands; it starts at the time of the first, so that a
  // later process with the same pid (the sender's name) does not repeat a number.
  static std::atomic<std::int64_t> next_id{0};
  std::int64_t expected = 0;
  (void)next_id.compare_exchange_strong(expected, std::max<std::int64_t>(1, now_utime()));
  EmergencyStop stop;
  stop.action = engage ? EstopAction::engage : EstopAction::release;
  stop.robot = robot;
  stop.reason = reason;
  stop.command_id = next_id++;
  comm::Envelope header;
  header.sender = comm::unique_endpoint_name("ui");
  comm::FaultDice dice(comm::link_faults_from_environment());
  for (int i = 0; i < 5; ++i) {
    header.seq = i + 1;
    header.utime = now_utime();
    // Signed when the set has a key (an EDP releases only when signed).
    comm::broadcast(bus, channels::emergency_stop, header, stop, &dice);
    if (i < 4) std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  return EstopCommandRef{header.sender, stop.command_id};
}

EstopConfirmation send_and_confirm_emergency_stop(comm::Bus& bus, bool engage,
                                                  const std::vector<std::string>& robots,
                                                  const std::string& robot,
                                                  const std::string& reason,
                                                  std::chrono::milliseconds deadline) {
  using Clock = std::chrono::steady_clock;
  struct Watch {
    std::mutex mutex;
    std::condition_variable cv;
    bool engage = false;
    bool armed = false;
    EstopCommandRef command;
    Clock::time_point sent{};
    std::map<std::string, double> latency_ms;
    std::map<std::string, std::int64_t> step;
    std::string latched_by;
  } w;
  w.engage = engage;
  // The operator's tool only watches: what does not decode is not its to report.
  const comm::SubscriberOptions quiet = comm::SubscriberOptions::unreported();
  std::vector<comm::Subscriber<RobotState>> states;
  for (const std::string& r : robots) {
    if (!robot.empty() && r != robot) continue;
    states.emplace_back(
        bus, channels::robot_state(r),
        [&w](const RobotState& s, const comm::Received& in) {
          const auto now = Clock::now();
          std::lock_guard lock(w.mutex);
          if (!w.armed || w.latency_ms.count(s.robot) != 0 || s.estop != w.engage) return;
          if (!in.authentic()) return;  // with a key, only an EDP's own state confirms
          w.latency_ms[s.robot] = std::chrono::duration<double, std::milli>(now - w.sent).count();
          w.step[s.robot] = s.servo_step;
          w.cv.notify_all();
        },
        quiet);
  }
  std::optional<comm::Subscriber<EmergencyStop>> announcements;
  announcements.emplace(
      bus, channels::emergency_stop,
      [&w](const EmergencyStop& m, const comm::Received& in) {
        if (m.action != EstopAction::engaged && m.action != EstopAction::released) return;
        {
          std::lock_guard lock(w.mutex);
          if (w.command.id == 0 || !w.latched_by.empty()) return;
          // Only an announcement that names this very command confirms that the latch holds it:
          // ENGAGED among the ENGAGEs it holds, RELEASED as the RELEASE that set it.
          const bool names_it = w.engage ? m.action == EstopAction::engaged &&
                                               std::find(m.engages.begin(), m.engages.end(),
                                                         w.command) != m.engages.end()
                                         : m.action == EstopAction::released && m.by == w.command;
          if (!names_it) return;
        }
        if (!in.authentic()) return;  // with a key, only the set's latch confirms
        std::lock_guard lock(w.mutex);
        w.latched_by = in.header().sender;
      },
      quiet);
  {
    std::lock_guard lock(w.mutex);
    w.armed = true;
    w.sent = Clock::now();
  }
  const EstopCommandRef command = publish_emergency_stop(bus, engage, robot, reason);
  {
    std::lock_guard lock(w.mutex);
    w.command = command;
  }
  EstopConfirmation out;
  {
    std::unique_lock lock(w.mutex);
    const std::size_t wanted = states.size();
    w.cv.wait_until(lock, w.sent + deadline, [&] { return w.latency_ms.size() >= wanted; });
  }
  // The latch announces at once on every command it obeys (and every 150 ms): give it a moment.
  const auto latch_until = w.sent + kEstopLatchWait;
  while (Clock::now() < latch_until) {
    {
      std::lock_guard lock(w.mutex);
      if (!w.latched_by.empty()) break;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  states.clear();
  announcements.reset();
  std::lock_guard lock(w.mutex);
  for (const std::string& r : robots) {
    if (!robot.empty() && r != robot) continue;
    if (auto it = w.latency_ms.find(r); it != w.latency_ms.end()) {
      out.confirmed.push_back(r);
      out.latency_ms[r] = it->second;
      out.servo_step[r] = w.step[r];
    } else {
      out.unconfirmed.push_back(r);
    }
  }
  out.latched_by = w.latched_by;
  return out;
}

std::string describe_confirmation(bool engage, const EstopConfirmation& c,
                                  std::chrono::milliseconds deadline) {
  std::string text;
  if (!c.unconfirmed.empty()) {
    std::string names;
    for (const auto& r : c.unconfirmed) names += (names.empty() ? "" : ", ") + r;
    text = fmt::format("NOT CONFIRMED by {} within {} ms (no robot_state_t showed the stop {})",
                       names, deadline.count(), engage ? "engaged" : "released");
  }
  if (!c.confirmed.empty()) {
    std::string names;
    for (const auto& r : c.confirmed)
      names += fmt::format("{}{} ({:.0f} ms)", names.empty() ? "" : ", ", r, c.latency_ms.at(r));
    text += (text.empty() ? "" : "; ") + std::string("confirmed by ") + names;
  }
  text += c.latched_by.empty()
              ? fmt::format(
                    "; NOT LATCHED: no latch holder announced this {} (an EDP that "
                    "starts or missed it will not know: is mrroc-launch running?)",
                    engage ? "stop" : "release")
              : "; latched by " + c.latched_by;
  return text;
}

std::string describe_emergency_stop(bool engage, const std::string& robot,
                                    const std::string& reason) {
  return fmt::format("{}{} for {}", engage ? "EMERGENCY STOP" : "emergency stop released",
                     reason.empty() ? "" : " (" + reason + ")",
                     robot.empty() ? "every robot" : "robot " + robot);
}

}  // namespace mrroc::ui
