#include "estop_listener.hpp"

#include <fmt/format.h>
#include <pthread.h>
#include <sched.h>

#include <algorithm>
#include <cerrno>
#include <cstring>

#include "mrroc/comm/auth.hpp"
#include "mrroc/config/process_set.hpp"

namespace mrroc::edp {

namespace {
/// The servo thread's SCHED_FIFO priority (servo_loop.cpp); the listener never goes above it.
constexpr int kServoPriority = 80;
/// The listener's priority when the command threads run at the normal scheduler.
constexpr int kDefaultPriority = 70;
}  // namespace

int EstopListener::priority_for(int command_priority) {
  return std::min(kServoPriority, std::max(kDefaultPriority, command_priority + 1));
}

EstopListener::EstopListener(ServoLoop& servo, std::string robot, const std::string& lcm_url,
                             const std::filesystem::path& auth_key_file, int priority,
                             comm::Bus::DropSink drop_sink)
    : servo_(servo), robot_(std::move(robot)), bus_(lcm_url), priority_(priority) {
  comm::enable_auth_from_file(bus_, auth_key_file);
  bus_.set_drop_sink(std::move(drop_sink));
  reason_ = "the EDP starts stopped until it hears the emergency stop's state";
  servo_.emergency_stop();  // before anything can move
  subscriber_.emplace(
      bus_, channels::emergency_stop,
      [this](const EmergencyStop& m, const comm::Received& in) { on_message(m, in); });
  std::unique_lock lock(mutex_);
  thread_ = std::thread([this] { run(); });
  heard_cv_.wait(lock, [this] { return !scheduling_.empty(); });
}

EstopListener::~EstopListener() {
  stop_ = true;
  if (thread_.joinable()) thread_.join();
  subscriber_.reset();
  bus_.set_drop_sink({});
}

void EstopListener::run() {
  sched_param sp{};
  sp.sched_priority = priority_;
  const int rc = pthread_setschedparam(pthread_self(), SCHED_FIFO, &sp);
  {
    std::lock_guard lock(mutex_);
    scheduling_ = rc == 0 ? fmt::format("SCHED_FIFO {}", priority_)
                          : fmt::format("SCHED_OTHER (SCHED_FIFO {} refused: {})", priority_,
                                        std::strerror(rc));
  }
  heard_cv_.notify_all();
  while (!stop_) {
    // Returns at once when a message is waiting; the timeout only bounds how long stopping waits.
    if (bus_.lcm().handleTimeout(100) < 0) break;
  }
}

void EstopListener::on_message(const EmergencyStop& m, const comm::Received& in) {
  if (!m.robot.empty() && m.robot != robot_) return;
  const std::string& from = in.header().sender;
  switch (m.action) {
    case EstopAction::engage: {
      bool now_held = false;
      {
        std::lock_guard lock(mutex_);
        heard_ = true;
        // A copy of an ENGAGE already released (a late datagram) does not stop again.
        (void)record_.engage(EstopCommandRef{from, m.command_id});
        now_held = record_.holding();
      }
      if (now_held) engage(m.reason + " (from " + from + ")", false);
      break;
    }
    case EstopAction::release: {
      if (!in.authentic()) return;
      std::lock_guard lock(mutex_);
      heard_ = true;
      if (!record_.release(EstopCommandRef{from, m.command_id})) break;  // a copy, obeyed
      release_locked();
      break;
    }
    case EstopAction::engaged: {
      bool stop = false;
      {
        std::lock_guard lock(mutex_);
        announcer_ = from;
        heard_ = true;
        // Every ENGAGE it names was released here already (by an operator's RELEASE the latch
        // has not heard yet): the EDP's own later command stands.
        (void)record_.latched_engaged(m.engages, from);
        stop = record_.holding();
      }
      if (stop) engage(fmt::format("latched: {} (announced by {})", m.reason, from), true);
      break;
    }
    case EstopAction::released: {
      if (!in.authentic()) return;
      std::lock_guard lock(mutex_);
      announcer_ = from;
      heard_ = true;
      // Releases only a stop whose every ENGAGE this announcement names as ended, or the hold the
      // EDP started in when it holds no ENGAGE: never a stop the latch did not see.
      const bool emptied = record_.latched_released(m.engages);
      if (emptied || !record_.holding()) release_locked();
      break;
    }
  }
  heard_cv_.notify_all();
}

void EstopListener::engage(const std::string& why, bool only_if_released) {
  {
    std::lock_guard lock(mutex_);
    heard_ = true;
    const bool holds = servo_.emergency_stopped();
    // A stop that holds keeps the reason it was engaged for: the launcher's announcement of the
    // same stop, a moment after the command itself, does not rename it (the EDP reports the
    // reason when it sees the stop, so a rename made the report depend on which came first).
    // The hold the EDP starts in is nobody's stop: the first command or announcement names it.
    if (!holds || starting_hold_) {
      reason_ = why;
      starting_hold_ = false;
    }
    if (only_if_released && holds) return;
  }
  servo_.emergency_stop();
}

void EstopListener::release_locked() {
  // Only a stop that is engaged is released: a release resets the hold position to the measured
  // joints, which must not happen to a robot in motion (announcements come every 150 ms).
  if (shutdown_ || !servo_.emergency_stopped()) return;
  starting_hold_ = false;
  servo_.release_emergency_stop();
}

bool EstopListener::wait_state(std::chrono::milliseconds timeout) {
  std::unique_lock lock(mutex_);
  return heard_cv_.wait_for(lock, timeout, [this] { return heard_; });
}

std::string EstopListener::scheduling() const {
  std::lock_guard lock(mutex_);
  return scheduling_;
}

std::string EstopListener::reason() const {
  std::lock_guard lock(mutex_);
  return reason_;
}

std::string EstopListener::announcer() const {
  std::lock_guard lock(mutex_);
  return announcer_;
}

void EstopListener::hold_for_shutdown() {
  {
    std::lock_guard lock(mutex_);
    shutdown_ = true;
    reason_ = "the EDP is stopping";
  }
  servo_.emergency_stop();
}

}  // namespace mrroc::edp
