#include "estop_latch.hpp"

#include <fmt/format.h>
#include <unistd.h>

#include <set>

#include "mrroc/comm/auth.hpp"
#include "mrroc/comm/request_reply.hpp"
#include "mrroc/comm/sync_annotations.hpp"
#include "mrroc/config/process_set.hpp"
#include "mrroc/core/time.hpp"
#include "mrroc_lcm/emergency_stop_t.hpp"
#include "mrroc_lcm/launch_status_t.hpp"
#include "mrroc_lcm/robot_state_t.hpp"

namespace mrroc::launch {

using Stop = mrroc_lcm::emergency_stop_t;

EstopLatch::EstopLatch(comm::Bus& bus, std::vector<std::string> robots,
                       std::function<void(const std::string&)> log)
    : bus_(bus), sender_(comm::unique_endpoint_name("launch")), log_(std::move(log)) {
  for (auto& r : robots) robots_[std::move(r)] = Latched{};
  subscription_ = bus_.subscribe<EstopLatch*>(
      channels::emergency_stop,
      +[](const lcm::ReceiveBuffer* buffer, const std::string& channel, EstopLatch* self) {
        Stop m;
        if (!comm::detail::decode_received(buffer, m)) {
          comm::detail::report_malformed(self->bus_, channel, static_cast<int>(buffer->data_size));
          return;
        }
        if (m.action == Stop::RELEASE) {
          if (!comm::detail::authentic(self->bus_, m, channel, self->dropped_)) return;
        } else if (m.action != Stop::ENGAGE) {
          return;  // announcements (ours, or another latch's) and unknown values
        }
        self->on_command(m.action, m.robot, m.reason, m.header.sender, m.header.utime);
      },
      this);
  thread_ = std::thread([this] { run(); });
}

EstopLatch::~EstopLatch() {
  bus_.unsubscribe(subscription_);
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
  return it != robots_.end() && it->second.engaged;
}

void EstopLatch::on_command(std::int8_t action, const std::string& robot, const std::string& reason,
                            const std::string& sender, std::int64_t utime) {
  const bool engage = action == Stop::ENGAGE;
  std::string line;
  {
    std::lock_guard lock(mutex_);
    std::vector<std::string> flipped;
    for (auto& [name, l] : robots_) {
      if (!robot.empty() && robot != name) continue;
      if (l.engaged != engage) flipped.push_back(name);
      l.engaged = engage;
      l.utime = std::max(l.utime, utime);
      l.reason = engage ? reason + " (from " + sender + ")" : std::string{};
    }
    if (flipped.empty()) return;  // a repeated copy, or a robot of another set
    std::string names;
    for (const auto& n : flipped) names += (names.empty() ? "" : ", ") + n;
    line = fmt::format(
        "mrroc-launch: emergency stop {} for {} ({}from {}): latched and announced "
        "every {} ms",
        engage ? "ENGAGED" : "released", names, engage && !reason.empty() ? reason + ", " : "",
        sender, kPeriod.count());
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
    Stop m{};
    m.header.sender = sender_;
    m.header.kind = mrroc_lcm::header_t::BROADCAST;
    m.header.utime = now_utime();
    m.action = l.engaged ? Stop::ENGAGED : Stop::RELEASED;
    m.robot = name;
    m.reason = l.reason;
    m.latched_utime = l.utime;
    comm::publish(bus_, channels::emergency_stop, m);  // signed with the set's key
  }
}

void EstopLatch::run() {
  std::unique_lock lock(mutex_);
  while (!stop_) {
    changed_ = false;
    lock.unlock();
    announce();
    lock.lock();
    cv_.wait_for(lock, kPeriod, [this] { return stop_ || changed_; });
  }
}

std::string RunningSet::describe() const {
  std::string out = launcher.empty() ? "no launcher table heard" : launcher;
  for (const auto& e : edps) out += "; " + e;
  return out;
}

std::optional<RunningSet> running_set(comm::Bus& bus, const std::vector<std::string>& robots) {
  struct Heard {
    std::mutex mutex;
    std::string table;                        // from launch_status_t
    std::string announcer;                    // sender of stop announcements
    std::map<std::string, std::string> edps;  // robot -> sender
  } heard;
  std::vector<mrroc::comm::Subscription*> subs;
  subs.push_back(bus.subscribe<Heard*>(
      channels::launch_status,
      +[](const lcm::ReceiveBuffer* b, const std::string&, Heard* h) {
        mrroc_lcm::launch_status_t m;
        if (!comm::detail::decode_received(b, m)) return;
        std::lock_guard lock(h->mutex);
        h->table = fmt::format(
            "a launcher (pid {}, '{}') runs set '{}' from {} (state {}, up {:.1f} s)",
            m.launcher_pid, m.header.sender, m.set_name, m.config_file, m.state, m.uptime_s);
      },
      &heard));
  subs.push_back(bus.subscribe<Heard*>(
      channels::emergency_stop,
      +[](const lcm::ReceiveBuffer* b, const std::string&, Heard* h) {
        Stop m;
        if (!comm::detail::decode_received(b, m)) return;
        if (m.action != Stop::ENGAGED && m.action != Stop::RELEASED) return;
        std::lock_guard lock(h->mutex);
        h->announcer = m.header.sender;
      },
      &heard));
  for (const std::string& robot : robots)
    subs.push_back(bus.subscribe<Heard*>(
        channels::robot_state(robot),
        +[](const lcm::ReceiveBuffer* b, const std::string&, Heard* h) {
          mrroc_lcm::robot_state_t m;
          if (!comm::detail::decode_received(b, m)) return;
          std::lock_guard lock(h->mutex);
          h->edps[m.robot] = m.header.sender;
        },
        &heard));
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
  for (mrroc::comm::Subscription* s : subs) bus.unsubscribe(s);
  std::lock_guard lock(heard.mutex);
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
