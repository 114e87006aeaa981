#include "servo_loop.hpp"

#include <pthread.h>
#include <sched.h>
#include <sys/prctl.h>
#include <time.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>

#include <fmt/format.h>

#include "mrroc/core/error.hpp"

namespace mrroc::edp {

namespace {
constexpr double kSynchroSpeed = 0.1;        // joint speed while searching a switch [rad/s]
constexpr double kSynchroSearchRange = 0.4;  // farthest a switch may be from the start [rad]
constexpr std::size_t kLatenessSamples = 1 << 16;

std::int64_t to_ns(const timespec& t) {
  return static_cast<std::int64_t>(t.tv_sec) * 1000000000LL + t.tv_nsec;
}
timespec from_ns(std::int64_t ns) {
  timespec t{};
  t.tv_sec = static_cast<time_t>(ns / 1000000000LL);
  t.tv_nsec = static_cast<long>(ns % 1000000000LL);
  return t;
}
}  // namespace

ServoLoop::ServoLoop(Hardware& hardware, const RobotModel& model, double period_s)
    : hardware_(hardware), model_(model), axes_(model.axes()), period_s_(period_s) {
  if (axes_ == 0 || axes_ > kMaxAxes)
    throw HardwareError(fmt::format("robot '{}' has {} axes; the EDP supports 1..{}", model.name,
                                    axes_, kMaxAxes));
  if (hardware_.axis_count() != axes_)
    throw HardwareError(fmt::format("hardware plugin '{}' has {} axes, robot model '{}' has {}",
                                    hardware_.name(), hardware_.axis_count(), model.name, axes_));
  lateness_us_.assign(kLatenessSamples, 0.0F);
}

ServoLoop::~ServoLoop() { stop(); }

void ServoLoop::start() {
  if (running_.exchange(true)) return;
  hardware_.activate();
  if (hardware_.read(std::span(feedback_.data(), axes_)) != CycleStatus::ok)
    throw HardwareError("hardware plugin '" + hardware_.name() +
                        "' failed its first read: " + hardware_.fault_text());
  for (std::size_t i = 0; i < axes_; ++i) desired_[i] = feedback_[i].position;
  thread_ = std::thread([this] { run(); });
}

void ServoLoop::stop() {
  if (!running_.exchange(false)) return;
  {
    std::lock_guard lock(mutex_);  // wakes a lock-step loop waiting for work or a successor
    cv_.notify_all();
  }
  if (thread_.joinable()) thread_.join();
  hardware_.deactivate();
  cv_.notify_all();
}

void ServoLoop::run() {
  sched_param sp{};
  sp.sched_priority = 80;
  const bool fifo = pthread_setschedparam(pthread_self(), SCHED_FIFO, &sp) == 0;
  if (!fifo) prctl(PR_SET_TIMERSLACK, 1UL, 0UL, 0UL, 0UL);
  {
    std::lock_guard lock(mutex_);
    scheduling_ = fifo ? "SCHED_FIFO 80" : "SCHED_OTHER, timer slack 1 ns (SCHED_FIFO refused)";
    if (lock_step_) scheduling_ += ", lock-step";
  }
  if (lock_step_) {
    run_lock_step();
    return;
  }
  const auto period_ns = static_cast<std::int64_t>(std::llround(period_s_ * 1e9));
  timespec now{};
  clock_gettime(CLOCK_MONOTONIC, &now);
  std::int64_t deadline = to_ns(now) + period_ns;
  while (running_.load(std::memory_order_relaxed)) {
    const timespec wake = from_ns(deadline);
    while (clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &wake, nullptr) == EINTR) {
    }
    clock_gettime(CLOCK_MONOTONIC, &now);
    const std::int64_t late_ns = to_ns(now) - deadline;
    cycle();
    record_cycle(late_ns, period_ns);
    deadline += period_ns;
    // After an overrun, skip the periods already missed instead of running a burst of cycles.
    if (late_ns > period_ns) deadline += (late_ns / period_ns) * period_ns;
  }
}

void ServoLoop::record_cycle(std::int64_t late_ns, std::int64_t period_ns) {
  std::lock_guard lock(mutex_);
  const double late_us = static_cast<double>(late_ns) / 1000.0;
  lateness_us_[lateness_next_] = static_cast<float>(late_us);
  lateness_next_ = (lateness_next_ + 1) % kLatenessSamples;
  lateness_max_us_ = std::max(lateness_max_us_, late_us);
  ++cycles_;
  ++window_.cycles;
  window_sum_us_ += late_us;
  window_.lateness_max_us = std::max(window_.lateness_max_us, late_us);
  if (late_ns > period_ns) {
    ++overruns_;
    ++window_.overruns;
    window_.worst_overrun_us = std::max(window_.worst_overrun_us, late_us);
  }
}

bool ServoLoop::has_work() const {
  return mode_ != Mode::hold || current_.has_value() || next_.has_value() || reset_pending_ ||
         after_stop_id_ != 0 || hold_at_measured_ || outputs_pending_ || servo_pending_;
}

bool ServoLoop::awaiting_successor() const {
  return current_ && current_->value_in_step_no < current_->steps &&
         current_->step + 1 >= current_->steps && !next_ && !faulted_ && !emergency_stop_;
}

void ServoLoop::run_lock_step() {
  // Simulated time advances only in cycle() (the plugin's write()), so cycles with work run back
  // to back; idle, the loop holds once a period (status and inputs stay fresh).
  const auto period = std::chrono::duration_cast<std::chrono::steady_clock::duration>(
      std::chrono::duration<double>(period_s_));
  const auto successor_wait = std::chrono::duration_cast<std::chrono::steady_clock::duration>(
      std::chrono::duration<double>(successor_wait_s_));
  while (running_.load(std::memory_order_relaxed)) {
    {
      std::unique_lock lock(mutex_);
      cv_.wait_for(lock, period, [&] { return !running_.load() || has_work(); });
      // The ECP read this macro-step early to send its successor: simulated time stands still
      // until it is queued (a real-time loop would run out of motion if it came late).
      if (awaiting_successor())
        cv_.wait_for(lock, successor_wait,
                     [&] { return !running_.load() || !awaiting_successor() || reset_pending_; });
    }
    if (!running_.load(std::memory_order_relaxed)) break;
    cycle();
    record_cycle(0, 1);
  }
}

void ServoLoop::set_fault(const char* text) {
  std::snprintf(fault_, sizeof fault_, "%s", text);
  faulted_ = true;
  current_.reset();
  next_.reset();
  mode_ = Mode::hold;
}

void ServoLoop::store_reading(std::uint64_t id, int step_no) {
  delivered_ = latest_;
  delivered_.macro_step = id;
  delivered_.step_no = step_no;
  cv_.notify_all();
}

void ServoLoop::cycle() {
  bool reset = false;
  {
    std::lock_guard lock(mutex_);
    reset = reset_pending_;
  }
  if (reset) {
    try {
      hardware_.deactivate();
      hardware_.activate();
    } catch (...) {
      // Stays faulted: read() below reports why.
    }
  }
  // Sample without the lock (the hardware may take a while), publish under it. A plugin must
  // not throw here; if it does, the loop holds the robot and reports it as a fault.
  CycleStatus read_status = CycleStatus::ok;
  char thrown[200] = {};  // the exception's text, copied while the exception lives
  try {
    read_status = hardware_.read(std::span(sample_.data(), axes_));
  } catch (const std::exception& e) {
    read_status = CycleStatus::fault;
    std::snprintf(thrown, sizeof thrown, "%s", e.what());
  } catch (...) {
    read_status = CycleStatus::fault;
    std::snprintf(thrown, sizeof thrown, "unknown exception");
  }
  std::lock_guard lock(mutex_);
  feedback_ = sample_;
  const std::span<const AxisFeedback> fb(feedback_.data(), axes_);
  if (reset) {
    reset_pending_ = false;
    if (read_status == CycleStatus::ok) {
      faulted_ = false;
      fault_[0] = '\0';
      synchronised_ = false;
      mode_ = Mode::hold;
      current_.reset();
      next_.reset();
      for (std::size_t i = 0; i < axes_; ++i) desired_[i] = fb[i].position;
    }
    cv_.notify_all();
  }
  if (read_status != CycleStatus::ok && !faulted_) {
    if (thrown[0] != '\0') {
      char text[256];
      std::snprintf(text, sizeof text, "plugin threw in read(): %s", thrown);
      set_fault(text);
    } else {
      set_fault(hardware_.fault_text().c_str());
    }
  }
  const bool synced = synchronised_.load(std::memory_order_relaxed);
  latest_.cycle = cycles_;
  latest_.synchronised = synced;
  for (std::size_t i = 0; i < axes_; ++i) {
    latest_.joints[i] = fb[i].position + (synced ? offset_[i] : 0.0);
    latest_.velocities[i] = fb[i].velocity;
  }

  latest_.inputs = hardware_.read_inputs();
  if (outputs_pending_) {
    hardware_.write_outputs(outputs_);
    outputs_pending_ = false;
  }
  latest_.outputs = outputs_;
  if (servo_pending_) {
    for (std::size_t i = 0; i < axes_; ++i)
      hardware_.set_servo(i, servo_algorithm_[i], servo_parameter_set_[i]);
    servo_pending_ = false;
  }
  latest_.servo_algorithm = servo_algorithm_;
  latest_.servo_parameter_set = servo_parameter_set_;

  const AxisArray previous_desired = desired_;
  if (faulted_) {
    // Hold still where the axes are.
    for (std::size_t i = 0; i < axes_; ++i) desired_[i] = latest_.joints[i];
  } else if (mode_ == Mode::stopping) {
    stop_cycle();
  } else if (mode_ != Mode::hold) {
    synchro_cycle();
  } else {
    if (hold_at_measured_ && !current_ && !next_) {
      hold_at_measured_ = false;
      for (std::size_t i = 0; i < axes_; ++i) desired_[i] = latest_.joints[i];
    }
    if (after_stop_id_ != 0) {
      store_reading(after_stop_id_, after_stop_step_);
      after_stop_id_ = 0;
    }
    if (!current_ && next_) {
      // The macro-step starts where the robot stands (after a stopping ramp for a late
      // successor, that is past the last target, not where the task planned it to start): a
      // straight line to its target faster than a joint's velocity limit is refused, and the
      // robot holds.
      bool too_fast = false;
      for (std::size_t i = 0; i < axes_ && !too_fast; ++i) {
        const double v = std::abs(next_->target[i] - desired_[i]) /
                         (static_cast<double>(next_->steps) * period_s_);
        if (v > model_.max_velocity[i] * (1.0 + 1e-9)) {
          too_fast = true;
          std::snprintf(refused_text_, sizeof refused_text_,
                        "joint %zu would move at %.3f rad/s, above its limit of %.3f rad/s "
                        "(from %.4f to %.4f rad in %d steps of %.1f ms%s); the robot holds",
                        i, v, model_.max_velocity[i], desired_[i], next_->target[i],
                        next_->steps, period_s_ * 1e3,
                        after_ramp_ ? ", starting where a stopping ramp left the robot" : "");
        }
      }
      after_ramp_ = false;
      if (too_fast) {
        refused_id_ = next_->id;
        next_.reset();
      } else {
        current_ = next_;
        next_.reset();
        current_->start = desired_;
      }
      cv_.notify_all();  // the queue slot is free
    }
    if (current_) {
      Motion& m = *current_;
      ++m.step;
      const double s = static_cast<double>(m.step) / static_cast<double>(m.steps);
      for (std::size_t i = 0; i < axes_; ++i)
        desired_[i] = m.start[i] + (m.target[i] - m.start[i]) * s;
      latest_.desired = desired_;
      if (m.step == m.value_in_step_no) store_reading(m.id, m.step);
      if (m.step >= m.steps) {
        // A reading before the last step promises the next macro-step in time (the paper: one
        // step early suffices for a seamless transition); in or after the last step it does not.
        const bool promised_successor = m.value_in_step_no < m.steps;
        if (!promised_successor) {
          after_stop_id_ = m.id;
          after_stop_step_ = m.steps + 1;
        }
        current_.reset();
        if (promised_successor && !next_) {
          // The ECP read this macro-step early to send the next one in time, and none came:
          // the link or the ECP is lost. Bring the robot to a standstill within its
          // acceleration limits instead of stopping it dead.
          ++lost_successors_;
          mode_ = Mode::stopping;
          after_ramp_ = true;
        }
      }
    }
  }
  if (synced && !faulted_)
    for (std::size_t i = 0; i < axes_; ++i)
      commanded_velocity_[i] = (desired_[i] - previous_desired[i]) / period_s_;
  else
    commanded_velocity_.fill(0.0);
  latest_.desired = desired_;
  if (trace_count_ < trace_.size()) {
    TraceSample& t = trace_[trace_count_++];
    t.cycle = cycles_;
    t.synchronised = synced;
    t.desired = desired_;
    t.measured = latest_.joints;
  }
  const bool use_offset = synchronised_.load(std::memory_order_relaxed);
  for (std::size_t i = 0; i < axes_; ++i)
    raw_setpoints_[i] = desired_[i] - (use_offset ? offset_[i] : 0.0);
  CycleStatus write_status = CycleStatus::ok;
  try {
    write_status = hardware_.write(std::span<const double>(raw_setpoints_.data(), axes_));
  } catch (const std::exception& e) {
    if (!faulted_) {
      char text[256];
      std::snprintf(text, sizeof text, "plugin threw in write(): %s", e.what());
      set_fault(text);
    }
  } catch (...) {
    if (!faulted_) set_fault("plugin threw in write(): unknown exception");
  }
  if (write_status != CycleStatus::ok && !faulted_) set_fault(hardware_.fault_text().c_str());
}

void ServoLoop::stop_cycle() {
  // Decelerate all axes by one common factor, as fast as the axis with the least acceleration
  // to spare allows: the joint velocities keep their ratios, so the robot stops on the straight
  // continuation of its last motion (a tool in a groove stays in it) instead of each axis
  // turning off the path as it stops on its own. Never past a joint limit: the ramp goes on past
  // the last target, where no limit was checked, so a step that would leave a joint, linkage or
  // motor limit ends the ramp where it is (the robot never leaves them).
  double keep = 0.0;  // the common factor for this step's velocities, 0..1
  for (std::size_t i = 0; i < axes_; ++i) {
    const double speed = std::abs(commanded_velocity_[i]);
    if (speed > 0.0)
      keep = std::max(keep, 1.0 - model_.max_acceleration[i] * period_s_ / speed);
  }
  bool moving = false;
  bool inside = true;
  for (std::size_t i = 0; i < axes_; ++i) {
    const double v = commanded_velocity_[i] * keep;
    proposal_[i] = desired_[i] + v * period_s_;
    inside = inside && proposal_[i] >= model_.lower_limits[i] &&
             proposal_[i] <= model_.upper_limits[i];
    moving = moving || v != 0.0;
  }
  if (inside && guard_ != nullptr) inside = guard_->within_limits(std::span(proposal_.data(), axes_));
  if (inside) {
    for (std::size_t i = 0; i < axes_; ++i) desired_[i] = proposal_[i];
  } else {
    moving = false;
    ++limit_stops_;
  }
  if (!moving) {
    mode_ = Mode::hold;
    cv_.notify_all();
  }
}

void ServoLoop::emergency_stop() {
  hardware_.emergency_stop(true);
  std::lock_guard lock(mutex_);
  emergency_stop_ = true;
  current_.reset();
  next_.reset();
  if (synchronised_ && !faulted_ && (mode_ == Mode::hold || mode_ == Mode::stopping))
    mode_ = Mode::stopping;
  else if (mode_ != Mode::hold)
    mode_ = Mode::hold;  // a synchronisation search is simply abandoned (it is slow)
  cv_.notify_all();
}

void ServoLoop::release_emergency_stop() {
  std::lock_guard lock(mutex_);
  emergency_stop_ = false;
  // Hold where the axes really are: drives with their own quick stop may have stopped a little
  // away from the loop's own ramp.
  hold_at_measured_ = true;
  cv_.notify_all();
  hardware_.emergency_stop(false);
}

bool ServoLoop::emergency_stopped() const {
  std::lock_guard lock(mutex_);
  return emergency_stop_;
}

std::int64_t ServoLoop::lost_successors() const {
  std::lock_guard lock(mutex_);
  return lost_successors_;
}

bool ServoLoop::reset_fault(double timeout_s) {
  std::unique_lock lock(mutex_);
  if (!faulted_) return true;
  reset_pending_ = true;
  cv_.notify_all();
  cv_.wait_for(lock, std::chrono::duration<double>(timeout_s),
               [&] { return !reset_pending_ || !running_; });
  return !faulted_;
}

void ServoLoop::synchro_cycle() {
  const double step = kSynchroSpeed * period_s_;
  if (mode_ == Mode::synchro_search) {
    bool all_found = true;
    for (std::size_t i = 0; i < axes_; ++i) {
      if (switch_found_[i]) continue;
      if (feedback_[i].synchro_switch != switch_initial_[i]) {
        // The switch toggled: here the axis is at its synchronisation position.
        switch_found_[i] = true;
        offset_[i] = model_.synchro_joint_positions[i] - feedback_[i].position;
        desired_[i] = feedback_[i].position;  // stop searching on this axis
        continue;
      }
      all_found = false;
      desired_[i] += search_direction_[i] * step;
      if (std::abs(desired_[i] - search_start_[i]) > kSynchroSearchRange) {
        char text[200];
        std::snprintf(text, sizeof text,
                      "synchronisation: axis %zu (%s) switch not found within %.2f rad", i,
                      model_.joint_names[i].c_str(), kSynchroSearchRange);
        set_fault(text);
        cv_.notify_all();
        return;
      }
    }
    if (all_found) {
      // Switch to joint coordinates and approach the synchronisation pose exactly.
      double longest = 0;
      for (std::size_t i = 0; i < axes_; ++i) {
        desired_[i] += offset_[i];
        longest = std::max(longest, std::abs(model_.synchro_joint_positions[i] - desired_[i]));
      }
      approach_steps_left_ = 1 + static_cast<int>(std::ceil(longest / step));
      for (std::size_t i = 0; i < axes_; ++i)
        approach_step_[i] =
            (model_.synchro_joint_positions[i] - desired_[i]) / approach_steps_left_;
      synchronised_ = true;
      mode_ = Mode::synchro_approach;
    }
  } else if (mode_ == Mode::synchro_approach) {
    for (std::size_t i = 0; i < axes_; ++i) desired_[i] += approach_step_[i];
    if (--approach_steps_left_ <= 0) {
      for (std::size_t i = 0; i < axes_; ++i) desired_[i] = model_.synchro_joint_positions[i];
      mode_ = Mode::hold;
      cv_.notify_all();
    }
  }
}

std::uint64_t ServoLoop::submit(const std::vector<double>& target, int steps,
                                int value_in_step_no) {
  std::unique_lock lock(mutex_);
  if (emergency_stop_) throw HardwareError("emergency stop engaged");
  cv_.wait(lock, [&] { return !next_ || faulted_ || !running_; });
  if (faulted_) throw HardwareError(fault_);
  if (!running_) throw HardwareError("the servo loop is not running");
  Motion m;
  m.id = next_id_++;
  for (std::size_t i = 0; i < axes_; ++i) m.target[i] = target[i];
  m.steps = steps;
  m.value_in_step_no = value_in_step_no;
  next_ = m;
  cv_.notify_all();  // a lock-step loop waits for work
  return m.id;
}

std::vector<double> ServoLoop::planned_end() const {
  std::lock_guard lock(mutex_);
  const AxisArray& end = next_ ? next_->target : current_ ? current_->target : desired_;
  return {end.begin(), end.begin() + static_cast<std::ptrdiff_t>(axes_)};
}

std::optional<Reading> ServoLoop::wait_reading(std::uint64_t id, double timeout_s) {
  std::unique_lock lock(mutex_);
  const bool ok = cv_.wait_for(lock, std::chrono::duration<double>(timeout_s), [&] {
    return delivered_.macro_step >= id || refused_id_ == id || faulted_ || emergency_stop_ ||
           !running_;
  });
  if (!ok || delivered_.macro_step != id) return std::nullopt;
  return delivered_;
}

std::string ServoLoop::refusal(std::uint64_t id) const {
  std::lock_guard lock(mutex_);
  return refused_id_ == id ? std::string(refused_text_) : std::string{};
}

Reading ServoLoop::latest() const {
  std::lock_guard lock(mutex_);
  return latest_;
}

bool ServoLoop::moving() const {
  std::lock_guard lock(mutex_);
  return current_.has_value() || next_.has_value() || mode_ != Mode::hold;
}

bool ServoLoop::stopped() const {
  std::lock_guard lock(mutex_);
  bool still = !current_ && !next_ && mode_ == Mode::hold;
  for (std::size_t i = 0; i < axes_; ++i) still = still && commanded_velocity_[i] == 0.0;
  return still;
}

void ServoLoop::begin_synchronisation() {
  std::lock_guard lock(mutex_);
  for (std::size_t i = 0; i < axes_; ++i) {
    switch_found_[i] = false;
    switch_initial_[i] = feedback_[i].synchro_switch;
    // A pressed switch is released by moving down, a released one pressed by moving up.
    search_direction_[i] = feedback_[i].synchro_switch ? -1.0 : 1.0;
    search_start_[i] = desired_[i];
  }
  mode_ = Mode::synchro_search;
}

bool ServoLoop::wait_synchronised(double timeout_s) {
  std::unique_lock lock(mutex_);
  cv_.wait_for(lock, std::chrono::duration<double>(timeout_s),
               [&] { return mode_ == Mode::hold || faulted_ || !running_; });
  return mode_ == Mode::hold && synchronised_ && !faulted_;
}

void ServoLoop::request_outputs(std::uint32_t values) {
  std::lock_guard lock(mutex_);
  outputs_ = values;
  outputs_pending_ = true;
  cv_.notify_all();
}

void ServoLoop::request_servo(const std::vector<std::int8_t>& algorithm,
                             const std::vector<std::int8_t>& parameter_set) {
  std::lock_guard lock(mutex_);
  for (std::size_t i = 0; i < axes_ && i < algorithm.size(); ++i) {
    servo_algorithm_[i] = algorithm[i];
    servo_parameter_set_[i] = parameter_set[i];
  }
  servo_pending_ = true;
  cv_.notify_all();
}

void ServoLoop::enable_trace(std::size_t capacity) {
  std::lock_guard lock(mutex_);
  trace_.assign(capacity, TraceSample{});
  trace_count_ = 0;
}

std::vector<TraceSample> ServoLoop::trace() const {
  std::lock_guard lock(mutex_);
  return {trace_.begin(), trace_.begin() + static_cast<std::ptrdiff_t>(trace_count_)};
}

std::string ServoLoop::fault_text() const {
  std::lock_guard lock(mutex_);
  return fault_;
}

TimingWindow ServoLoop::take_timing_window() {
  std::lock_guard lock(mutex_);
  TimingWindow w = window_;
  w.lateness_mean_us = w.cycles > 0 ? window_sum_us_ / static_cast<double>(w.cycles) : 0.0;
  w.overruns_total = overruns_;
  window_ = TimingWindow{};
  window_sum_us_ = 0;
  return w;
}

TimingStats ServoLoop::timing() const {
  std::vector<float> samples;
  TimingStats t;
  {
    std::lock_guard lock(mutex_);
    const std::size_t n =
        std::min<std::size_t>(static_cast<std::size_t>(cycles_), lateness_us_.size());
    samples.assign(lateness_us_.begin(), lateness_us_.begin() + static_cast<std::ptrdiff_t>(n));
    t.cycles = cycles_;
    t.overruns = overruns_;
    t.lateness_max_us = lateness_max_us_;
    t.scheduling = scheduling_;
  }
  t.period_us = period_s_ * 1e6;
  if (!samples.empty()) {
    std::sort(samples.begin(), samples.end());
    auto pct = [&](double p) {
      return static_cast<double>(
          samples[static_cast<std::size_t>(p * static_cast<double>(samples.size() - 1))]);
    };
    t.lateness_p50_us = pct(0.50);
    t.lateness_p99_us = pct(0.99);
  }
  return t;
}

}  // namespace mrroc::edp
