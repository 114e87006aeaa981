#include "estop_latch.hpp"

#include <fmt/format.h>
#include <unistd.h>

#include <set>

#include "mrroc/comm/auth.hpp"
#include "mrroc/comm/request_reply.hpp"
#include "mrroc/comm/sync_annotations.hpp"
#include "mrroc/config/process_set.hpp"
#include "mrroc/core/time.hpp"

namespace mrroc::launch {

EstopLatch::EstopLatch(comm::Bus& bus, std::vector<std::string> robots,
                       std::function<void(const std::string&)> log)
    : bus_(bus), sender_(comm::unique_endpoint_name("launch")), log_(std::move(log)) {
  for (auto& r : robots) robots_[std::move(r)] = Latched{};
  commands_.emplace(
      bus_, channels::emergency_stop, [this](const EmergencyStop& m, const comm::Received& in) {
        if (m.action == EstopAction::release) {
          if (!in.authentic()) return;
        } else if (m.action != EstopAction::engage) {
          return;  // announcements (ours, or another latch's)
        }
        on_command(m.action, m.robot, m.reason, EstopCommandRef{in.header().sender, m.command_id});
      });
  thread_ = std::thread([this] { run(); });
}

EstopLatch::~EstopLatch() {
  commands_.reset();
  {
    std::lock_guard lock(mutex_);
    stop_ = true;
  }
  cv_.notify_all();
  if (thread_.joinable()) thread_.join();
}

bool EstopLatch::engaged(const std::string& robot) const {
  std::lock_guard lock(mutex_);
  auto it = robots_.find(robot);
  return it != robots_.end() && it->second.record.holding();
}

void EstopLatch::on_command(EstopAction action, const std::string& robot, const std::string& reason,
                            const EstopCommandRef& command) {
  const bool engage = action == EstopAction::engage;
  std::string line;
  {
    std::lock_guard lock(mutex_);
    std::vector<std::string> flipped;
    bool obeyed = false;  // a new command (not a copy) for a robot of this set
    for (auto& [name, l] : robots_) {
      if (!robot.empty() && robot != name) continue;
      // In the order the commands arrive here: no sender's clock orders them (a forged time
      // could otherwise make a later announcement release an ENGAGE this latch never heard).
      if (engage) {
        const bool was = l.record.holding();
        // A late copy of an ENGAGE released is not held; a copy of one held is not new.
        obeyed = l.record.engage(command) || obeyed;
        if (was || !l.record.holding()) continue;
        flipped.push_back(name);
        l.by = command;
        l.reason = reason + " (from " + command.sender + ")";
      } else {
        const bool was = l.record.holding();
        auto ended = l.record.release(command);
        if (!ended) continue;  // a copy of a RELEASE obeyed
        obeyed = true;
        l.by = command;
        // A RELEASE that ended nothing here keeps naming what the last one ended, for an EDP
        // that missed both.
        if (!ended->empty()) l.ended = std::move(*ended);
        l.reason.clear();
        if (was) flipped.push_back(name);
      }
    }
    if (obeyed) changed_ = true;  // announced at once: the sender waits to see it named
    if (flipped.empty()) {
      if (obeyed) cv_.notify_all();
      return;  // a copy, a command that changed no state, or a robot of another set
    }
    std::string names;
    for (const auto& n : flipped) names += (names.empty() ? "" : ", ") + n;
    line = fmt::format(
        "mrroc-launch: emergency stop {} for {} ({}from {}, command {}): latched and announced "
        "every {} ms",
        engage ? "ENGAGED" : "released", names, engage && !reason.empty() ? reason + ", " : "",
        command.sender, command.id, kPeriod.count());
    changed_ = true;
  }
  cv_.notify_all();
  if (log_) log_(line);
}

void EstopLatch::announce() {
  std::map<std::string, Latched> copy;
  {
    std::lock_guard lock(mutex_);
    copy = robots_;
  }
  for (const auto& [name, l] : copy) {
    EmergencyStop m;
    const bool engaged = l.record.holding();
    m.action = engaged ? EstopAction::engaged : EstopAction::released;
    m.robot = name;
    m.reason = l.reason;
    m.by = l.by;
    if (engaged) {
      m.engages.assign(l.record.held().begin(), l.record.held().end());
    } else {
      m.engages = l.ended;
    }
    if (m.engages.size() > kMaxEstopEngages)
      m.engages.erase(m.engages.begin(), m.engages.end() - kMaxEstopEngages);
    comm::Envelope header;
    header.sender = sender_;
    header.utime = now_utime();
    comm::broadcast(bus_, channels::emergency_stop, header, m);  // signed with the set's key
  }
}

void EstopLatch::run() {
  std::unique_lock lock(mutex_);
  while (!stop_) {
    changed_ = false;
    lock.unlock();
    announce();
    lock.lock();
    cv_.wait_for(lock, starting_ ? kStartingPeriod : kPeriod, [this] { return stop_ || changed_; });
  }
}

void EstopLatch::set_starting(bool starting) {
  {
    std::lock_guard lock(mutex_);
    starting_ = starting;
    changed_ = changed_ || starting;  // the first announcement at once
  }
  cv_.notify_all();
}

std::string RunningSet::describe() const {
  std::string out = launcher.empty() ? "no launcher table heard" : launcher;
  for (const auto& e : edps) out += "; " + e;
  return out;
}

std::optional<RunningSet> running_set(comm::Bus& bus, const std::vector<std::string>& robots,
                                      std::vector<std::string>* ignored) {
  struct Heard {
    std::mutex mutex;
    std::string table;                        // from launch_status_t
    std::string announcer;                    // sender of stop announcements
    std::map<std::string, std::string> edps;  // robot -> sender
    std::set<std::string> unauthenticated;    // what a set with a key does not believe
  } heard;
  // With a key only what is signed with it counts: anybody could send a launcher's table or a
  // robot's state and so keep the set from starting. What is not is listed, not acted on.
  const bool keyed = bus.auth() != nullptr;
  auto believed = [keyed, &heard](const comm::Received& in, const std::string& what) {
    if (!keyed || in.authentic_unreported()) return true;
    std::lock_guard lock(heard.mutex);
    heard.unauthenticated.insert(fmt::format("{} from '{}'", what, in.header().sender));
    return false;
  };
  // Only listening: what does not decode is not the launcher's to report.
  const comm::SubscriberOptions quiet = comm::SubscriberOptions::unreported();
  std::optional<comm::Subscriber<LaunchStatus>> tables;
  tables.emplace(
      bus, channels::launch_status,
      [&heard, &believed](const LaunchStatus& m, const comm::Received& in) {
        if (!believed(in, fmt::format("a launcher's table (set '{}')", m.set_name))) return;
        std::lock_guard lock(heard.mutex);
        heard.table = fmt::format(
            "a launcher (pid {}, '{}') runs set '{}' from {} (state {}, up {:.1f} s)",
            m.launcher_pid, in.header().sender, m.set_name, m.config_file, m.state, m.uptime_s);
      },
      quiet);
  std::optional<comm::Subscriber<EmergencyStop>> announcements;
  announcements.emplace(
      bus, channels::emergency_stop,
      [&heard, &believed](const EmergencyStop& m, const comm::Received& in) {
        if (m.action != EstopAction::engaged && m.action != EstopAction::released) return;
        if (!believed(in, "an emergency stop announcement")) return;
        std::lock_guard lock(heard.mutex);
        heard.announcer = in.header().sender;
      },
      quiet);
  std::vector<comm::Subscriber<RobotState>> states;
  for (const std::string& robot : robots)
    states.emplace_back(
        bus, channels::robot_state(robot),
        [&heard, &believed](const RobotState& m, const comm::Received& in) {
          if (!believed(in, fmt::format("the state of robot {}", m.robot))) return;
          std::lock_guard lock(heard.mutex);
          heard.edps[m.robot] = in.header().sender;
        },
        quiet);
  auto any = [&] {
    std::lock_guard lock(heard.mutex);
    return !heard.table.empty() || !heard.announcer.empty() || !heard.edps.empty();
  };
  const auto start = std::chrono::steady_clock::now();
  while (std::chrono::steady_clock::now() - start < kRunningSetListen)
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  if (any()) {  // give its launcher's table (every second) time to name the set
    const auto until = std::chrono::steady_clock::now() + kRunningSetNameWait;
    for (;;) {
      {
        std::lock_guard lock(heard.mutex);
        if (!heard.table.empty() || heard.announcer.empty()) break;  // named, or no launcher
      }
      if (std::chrono::steady_clock::now() >= until) break;
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
    }
  }
  tables.reset();
  announcements.reset();
  states.clear();
  std::lock_guard lock(heard.mutex);
  if (ignored != nullptr)
    ignored->assign(heard.unauthenticated.begin(), heard.unauthenticated.end());
  if (heard.table.empty() && heard.announcer.empty() && heard.edps.empty()) return std::nullopt;
  RunningSet out;
  out.launcher =
      !heard.table.empty() ? heard.table
      : !heard.announcer.empty()
          ? fmt::format("a launcher ('{}') announces the emergency stop's state", heard.announcer)
          : std::string{};
  for (const auto& [robot, sender] : heard.edps)
    out.edps.push_back(
        fmt::format("the EDP of robot {} ('{}') broadcasts its state", robot, sender));
  return out;
}

}  // namespace mrroc::launch
