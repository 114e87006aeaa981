#include "console/state.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>

#include "console/common.hpp"

namespace mrroc::ui {

namespace {

bool same_message(const SrpMessage& a, const SrpMessage& b) {
  return a.utime == b.utime && a.process == b.process && a.text == b.text && a.code == b.code;
}

}  // namespace

double seconds_since(SteadyClock::time_point t) {
  return std::chrono::duration<double>(SteadyClock::now() - t).count();
}

ConsoleState::ConsoleState(std::string set_name, std::vector<ConsoleRobot> robots)
    : set_name_(std::move(set_name)), robots_(std::move(robots)), data_(robots_.size()) {}

std::size_t ConsoleState::robot_index(const std::string& name) const {
  for (std::size_t i = 0; i < robots_.size(); ++i)
    if (robots_[i].name == name) return i;
  std::string names;
  for (const auto& r : robots_) names += (names.empty() ? "" : ", ") + r.name;
  throw ApiError(404,
                 fmt::format("no robot '{}' in set '{}' (robots: {})", name, set_name_, names));
}

const ConsoleRobot& ConsoleState::robot(const std::string& name) const {
  return robots_[robot_index(name)];
}

void ConsoleState::on_robot_state(std::size_t index, const RobotState& s, std::int64_t utime,
                                  SteadyClock::time_point received) {
  if (index >= robots_.size() || s.q.size() != robots_[index].model.axes()) return;
  std::lock_guard lock(mutex_);
  RobotData& data = data_[index];
  data.reading = RobotReading{s, utime, received};
  if (!data.samples.empty() && data.samples.back().step >= s.servo_step) {
    // The same step again (the EDP's state thread ran while its servo loop stalled) or a state
    // overtaken by a newer one: not a new sample. Far behind: the EDP started again.
    if (data.samples.back().step - s.servo_step < kRestartSteps) return;
    data.samples.clear();
  }
  data.samples.push_back(
      Sample{s.servo_step, utime, s.q, s.dq, s.lateness_mean_us, s.lateness_max_us});
  while (data.samples.size() > kMaxSamples) data.samples.pop_front();
}

void ConsoleState::on_launch_status(const launch::LaunchStatus& status,
                                    SteadyClock::time_point received) {
  std::lock_guard lock(mutex_);
  launch_ = status;
  launch_received_ = received;
}

void ConsoleState::on_scene_objects(const SceneObjects& objects, std::int64_t utime,
                                    std::int64_t seq, SteadyClock::time_point received) {
  std::lock_guard lock(mutex_);
  objects_ = ObjectsReading{objects, utime, seq, received};
}

std::optional<ObjectsReading> ConsoleState::scene_objects() const {
  std::lock_guard lock(mutex_);
  return objects_;
}

void ConsoleState::on_message(const SrpMessage& message) {
  std::lock_guard lock(mutex_);
  log_.push_back(LogEntry{log_next_++, message});
  while (log_.size() > kMaxLog) log_.pop_front();
}

void ConsoleState::on_process_status(const ProcessStatus& status,
                                     SteadyClock::time_point received) {
  std::lock_guard lock(mutex_);
  processes_[status.process] = {status, received};
}

void ConsoleState::on_mp_status(const MpStatus& status, SteadyClock::time_point received) {
  std::lock_guard lock(mutex_);
  mp_ = MpReading{status, received};
  mp_error_.clear();
}

void ConsoleState::on_mp_silent(const std::string& error) {
  std::lock_guard lock(mutex_);
  mp_.reset();
  mp_error_ = error;
}

void ConsoleState::merge_history(const std::vector<SrpMessage>& history, std::int64_t srp_last) {
  std::lock_guard lock(mutex_);
  history_loaded_ = true;
  srp_last_ = srp_last;
  // Live messages received meanwhile may also be in the history: keep one copy of each.
  std::deque<LogEntry> merged;
  for (const SrpMessage& h : history) merged.push_back(LogEntry{0, h});
  for (LogEntry& live : log_) {
    const bool duplicate = std::any_of(merged.begin(), merged.end(), [&](const LogEntry& h) {
      return same_message(h.message, live.message);
    });
    if (!duplicate) merged.push_back(std::move(live));
  }
  std::int64_t n = 1;
  for (LogEntry& e : merged) e.number = n++;
  log_ = std::move(merged);
  log_next_ = n;
  ++log_epoch_;
}

bool ConsoleState::history_loaded() const {
  std::lock_guard lock(mutex_);
  return history_loaded_;
}

StateSnapshot ConsoleState::snapshot() const {
  std::lock_guard lock(mutex_);
  StateSnapshot out;
  out.mp_error = mp_error_;
  if (mp_ && mp_->fresh())
    out.mp = mp_->status;
  else if (mp_)
    out.mp_error = fmt::format("no answer from the MP for {:.1f} s (the last said {})",
                               mp_->age_s(), mp_->status.state);
  if (launch_ && seconds_since(launch_received_) < kLaunchFreshS) out.launch = launch_;
  for (const auto& [name, seen] : processes_)
    out.processes[name] = SeenProcess{seen.first, seconds_since(seen.second)};
  for (const RobotData& d : data_) {
    StateSnapshot::Robot r;
    if (d.reading) {
      r.reading = d.reading;
      r.age_s = seconds_since(d.reading->received);
    }
    out.robots.push_back(std::move(r));
  }
  out.log_last = log_.empty() ? 0 : log_.back().number;
  out.log_epoch = log_epoch_;
  out.history_loaded = history_loaded_;
  return out;
}

std::optional<RobotReading> ConsoleState::reading(std::size_t index) const {
  std::lock_guard lock(mutex_);
  return index < data_.size() ? data_[index].reading : std::nullopt;
}

std::vector<Sample> ConsoleState::samples_after(std::size_t index, std::int64_t after) const {
  std::lock_guard lock(mutex_);
  std::vector<Sample> out;
  if (index >= data_.size()) return out;
  for (const Sample& s : data_[index].samples)
    if (s.step > after) out.push_back(s);
  return out;
}

LogView ConsoleState::messages(std::int64_t after, int min_severity, std::size_t max) const {
  std::lock_guard lock(mutex_);
  LogView out;
  for (const LogEntry& e : log_) {
    if (e.number <= after || static_cast<int>(e.message.severity) < min_severity) continue;
    out.entries.push_back(e);
  }
  // The newest `max` of them.
  if (out.entries.size() > max)
    out.entries.erase(out.entries.begin(),
                      out.entries.begin() + static_cast<std::ptrdiff_t>(out.entries.size() - max));
  out.last = log_.empty() ? 0 : log_.back().number;
  out.epoch = log_epoch_;
  out.history_loaded = history_loaded_;
  out.srp_last = srp_last_;
  return out;
}

std::optional<MpStatus> ConsoleState::mp() const {
  std::lock_guard lock(mutex_);
  if (!mp_ || !mp_->fresh()) return std::nullopt;
  return mp_->status;
}

std::optional<MpReading> ConsoleState::mp_reading() const {
  std::lock_guard lock(mutex_);
  return mp_;
}

std::string ConsoleState::mp_error() const {
  std::lock_guard lock(mutex_);
  return mp_error_;
}

bool ConsoleState::at_rest_since(std::size_t index, SteadyClock::time_point since) const {
  std::lock_guard lock(mutex_);
  if (index >= data_.size()) return false;
  const auto& r = data_[index].reading;
  return r && !r->state.moving && r->received > since;
}

std::map<std::string, std::int64_t> ConsoleState::estimated_servo_steps(
    const std::string& robot) const {
  std::lock_guard lock(mutex_);
  std::map<std::string, std::int64_t> steps;
  for (std::size_t i = 0; i < robots_.size(); ++i) {
    const auto& r = data_[i].reading;
    if (!r || (!robot.empty() && robots_[i].name != robot)) continue;
    const double period =
        r->state.servo_period_s > 0 ? r->state.servo_period_s : robots_[i].servo_period_s;
    steps[robots_[i].name] =
        r->state.servo_step +
        static_cast<std::int64_t>(std::llround(seconds_since(r->received) / period));
  }
  return steps;
}

}  // namespace mrroc::ui
