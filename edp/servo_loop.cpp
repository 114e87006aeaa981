#include "servo_loop.hpp"

#include <pthread.h>
#include <sched.h>
#include <sys/prctl.h>
#include <time.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <limits>
#include <mutex>

#include <fmt/format.h>

#include "motion_blend.hpp"
#include "mrroc/core/error.hpp"
#include "mrroc/core/process.hpp"
#include "mrroc/msg/edp_instruction.hpp"
#include "stopping_ramp.hpp"

namespace mrroc::edp {

namespace {
std::int64_t to_ns(const timespec& t) {
  return static_cast<std::int64_t>(t.tv_sec) * 1000000000LL + t.tv_nsec;
}
timespec from_ns(std::int64_t ns) {
  timespec t{};
  t.tv_sec = static_cast<time_t>(ns / 1000000000LL);
  t.tv_nsec = static_cast<long>(ns % 1000000000LL);
  return t;
}
/// The longest a motion from rest waits for its lookahead: the pauses of a shared host (about
/// 60 ms, docs/operating.md) and more, not a lone long macro-step's whole lookahead.
constexpr double kMaxStartHoldS = 0.2;
/// Catch-up (hardware that keeps its own clock): the motion runs at most this much faster than
/// planned while it makes up the servo steps of periods a stall took from it ...
constexpr double kMaxWarp = 0.25;
/// ... keeping every joint's commanded acceleration (the planned one grown by the square of the
/// rate, plus the rate's change times the velocity) within this share of its limit ...
constexpr double kWarpAccelerationShare = 0.9;
/// ... running faster only while no joint's planned acceleration uses more than this share of
/// its limit (at the top rate it grows to 0.44 x 1.25^2 = 0.69 of the limit) ...
constexpr double kWarpPlannedAccelerationShare = 0.44;
/// ... nor the change of the mean velocities of the macro-steps queued this share (a blend
/// between them peaks at about three times that), and winding the rate down otherwise ...
constexpr double kWarpQueuedAccelerationShare = 0.15;
/// ... and never beyond this share of a joint's velocity limit. Winding the rate down takes at
/// least this share of the acceleration limit where the planned motion left less.
constexpr double kWarpVelocityShare = 0.9;
constexpr double kWarpMinimumUnwindShare = 0.2;
/// Macro-steps that must be queued behind the running one for the motion to run faster.
constexpr std::size_t kWarpQueuedMacroSteps = 2;
std::chrono::nanoseconds seconds(double s) {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::duration<double>(s));
}
}  // namespace

ServoLoop::ServoLoop(Hardware& hardware, const RobotModel& model, double period_s)
    : hardware_(hardware),
      model_(model),
      axes_(model.axes()),
      period_s_(period_s),
      synchroniser_(model),
      unsynced_model_(model) {
  if (axes_ == 0 || axes_ > kMaxAxes)
    throw HardwareError(
        fmt::format("robot '{}' has {} axes; the EDP supports 1..{}", model.name, axes_, kMaxAxes));
  if (hardware_.axis_count() != axes_)
    throw HardwareError(fmt::format("hardware plugin '{}' has {} axes, robot model '{}' has {}",
                                    hardware_.name(), hardware_.axis_count(), model.name, axes_));
  device_ = hardware_.device();
  keeps_time_ = !hardware_.simulated();
  homed_axes_ = hardware_.self_homing_axes();
  if (axes_ < 32) homed_axes_ &= (1U << axes_) - 1U;
  if (device_.command.size() > kMaxDeviceFields || device_.reply.size() > kMaxDeviceFields)
    throw HardwareError(
        fmt::format("hardware plugin '{}': device '{}' has {} command and {} reply "
                    "fields; the EDP supports at most {} each",
                    hardware_.name(), device_.name, device_.command.size(), device_.reply.size(),
                    kMaxDeviceFields));
  latest_.device_fields = device_.reply.size();
  set_unsynchronised_limits(UnsynchronisedLimits{});
}

void ServoLoop::set_unsynchronised_limits(const UnsynchronisedLimits& limits) {
  if (!(limits.velocity_fraction >= 0.01 && limits.velocity_fraction <= 1.0))
    throw Error(fmt::format("unsynchronised velocity fraction {} is outside 0.01..1",
                            limits.velocity_fraction));
  if (!(limits.acceleration_fraction >= 0.01 && limits.acceleration_fraction <= 1.0))
    throw Error(fmt::format("unsynchronised acceleration fraction {} is outside 0.01..1",
                            limits.acceleration_fraction));
  if (!(limits.max_move > 0.0) || !std::isfinite(limits.max_move))
    throw Error(
        fmt::format("unsynchronised max_move {} is not a positive length", limits.max_move));
  unsynced_ = limits;
  for (std::size_t i = 0; i < axes_; ++i) {
    unsynced_model_.max_velocity[i] = model_.max_velocity[i] * limits.velocity_fraction;
    unsynced_model_.max_acceleration[i] = model_.max_acceleration[i] * limits.acceleration_fraction;
    // Raw axis positions are not joint coordinates: no joint limit applies to them.
    unsynced_model_.lower_limits[i] = -std::numeric_limits<double>::infinity();
    unsynced_model_.upper_limits[i] = std::numeric_limits<double>::infinity();
  }
}

ServoLoop::~ServoLoop() { stop(); }

void ServoLoop::set_lookahead(int depth) {
  if (depth < 1 || depth > kMaxLookahead)
    throw Error(fmt::format("lookahead {} macro-steps is outside 1..{}", depth, kMaxLookahead));
  lookahead_ = depth;
}

void ServoLoop::start() {
  if (running_.exchange(true)) return;
  activate_and_read();
  start_recovery_thread();
  thread_ = std::thread([this] { run(); });
}

void ServoLoop::activate_and_read() {
  hardware_.activate();
  if (hardware_.read(std::span(feedback_.data(), axes_)) != CycleStatus::ok)
    throw HardwareError("hardware plugin '" + hardware_.name() +
                        "' failed its first read: " + hardware_.fault_text());
  for (std::size_t i = 0; i < axes_; ++i) desired_[i] = feedback_[i].position;
  // The inputs and the device as they are before the first cycle (a GET INPUTS or GET DEVICE
  // may come before it).
  latest_.inputs = hardware_.read_inputs();
  if (!device_.reply.empty()) {
    hardware_.read_device(std::span(device_sample_.data(), device_.reply.size()));
    latest_.device = device_sample_;
  }
}

void ServoLoop::start_recovery_thread() {
  recovery_quit_ = false;
  recovery_job_ = 0;
  recovery_done_ = 0;
  recovery_number_ = 0;
  recovery_in_flight_ = kNoRecovery;
  recovery_thread_ = std::thread([this] { run_recovery(); });
}

void ServoLoop::run_recovery() {
  // Below the servo thread (SCHED_FIFO 80) and above the EDP's communication: a plugin keeps its
  // devices supervised during a homing (the CAN master's SYNC and heartbeat), which a busy host
  // must not hold up; where SCHED_FIFO is refused, the thread runs as it was started. In
  // lock-step (simulated time) it runs as it was started too, as the servo thread does.
  if (!lock_step_) {
    sched_param sp{};
    sp.sched_priority = kRecoveryPriority;
    (void)pthread_setschedparam(pthread_self(), SCHED_FIFO, &sp);
  }
  std::uint64_t ended = 0;
  for (;;) {
    const std::uint32_t seen = recovery_wake_.value();
    const std::uint64_t posted = recovery_job_.load(std::memory_order_acquire);
    if (posted / 4 != ended) {
      const auto job = static_cast<int>(posted % 4);
      recovery_failure_[0] = '\0';
      try {
        if (job == kResetRecovery) {
          hardware_.deactivate();
          hardware_.activate();
        } else {
          hardware_.home_axes();
        }
      } catch (const std::exception& e) {
        // A reset that fails stays faulted (the next read() says why); a homing's text names the
        // axis, the method and the time (Hardware::home_axes).
        std::snprintf(recovery_failure_, sizeof recovery_failure_, "%s", e.what());
      } catch (...) {
        std::snprintf(recovery_failure_, sizeof recovery_failure_, "%s",
                      job == kResetRecovery ? "plugin threw in activate(): unknown exception"
                                            : "plugin threw in home_axes(): unknown exception");
      }
      ended = posted / 4;
      recovery_done_.store(ended, std::memory_order_release);
      changed_.notify();  // a lock-step or stepped loop waits for it
      continue;
    }
    if (recovery_quit_.load(std::memory_order_acquire)) return;
    recovery_wake_.wait_for(seen, std::chrono::milliseconds(100));
  }
}

void ServoLoop::post_recovery(bool reset) {
  recovery_in_flight_ = reset ? kResetRecovery : kHomingRecovery;
  ++recovery_number_;
  recovery_job_.store(recovery_number_ * 4 + static_cast<std::uint64_t>(recovery_in_flight_),
                      std::memory_order_release);
  recovery_wake_.notify();
}

bool ServoLoop::recovery_ended(bool wait) {
  for (;;) {
    const std::uint32_t seen = changed_.value();
    if (recovery_done_.load(std::memory_order_acquire) == recovery_number_) return true;
    if (!wait) return false;
    changed_.wait_for(seen, std::chrono::milliseconds(10));
  }
}

void ServoLoop::start_stepped() {
  if (running_.load()) return;
  activate_and_read();
  stepped_ = true;
  start_recovery_thread();
  running_ = true;
}

void ServoLoop::step(std::int64_t missed_periods) {
  const auto period_ns = static_cast<std::int64_t>(std::llround(period_s_ * 1e9));
  cycle(missed_periods * period_ns, period_ns, keeps_time_ ? missed_periods : std::int64_t{0});
}

void ServoLoop::stop() {
  if (!running_.exchange(false)) return;
  changed_.notify();  // wakes a lock-step loop waiting for work or a successor
  if (thread_.joinable()) thread_.join();
  // A recovery in flight ends first (an emergency stop ends a homing early).
  recovery_quit_.store(true, std::memory_order_release);
  recovery_wake_.notify();
  if (recovery_thread_.joinable()) recovery_thread_.join();
  hardware_.deactivate();
  changed_.notify();
}

void ServoLoop::run() {
  if (lock_step_) {
    // Simulated time has no deadline, and a loop whose cycles run back to back at SCHED_FIFO 80
    // would keep a core from every other process of the host (the rest of its own process set
    // included) for as long as it has work: a lock-step loop runs as it was started.
    const std::string policy = apply_priority(0);  // changes nothing: names the policy in force
    {
      std::lock_guard lock(mutex_);
      std::snprintf(scheduling_, sizeof scheduling_,
                    "%s, lock-step (simulated time: no real-time "
                    "priority of its own)",
                    policy.c_str());
    }
    run_lock_step();
    return;
  }
  sched_param sp{};
  sp.sched_priority = 80;
  const bool fifo = pthread_setschedparam(pthread_self(), SCHED_FIFO, &sp) == 0;
  if (!fifo) prctl(PR_SET_TIMERSLACK, 1UL, 0UL, 0UL, 0UL);
  {
    std::lock_guard lock(mutex_);
    std::snprintf(scheduling_, sizeof scheduling_, "%s",
                  fifo ? "SCHED_FIFO 80" : "SCHED_OTHER, timer slack 1 ns (SCHED_FIFO refused)");
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
    const std::int64_t woke = to_ns(now);
    const std::int64_t late_ns = woke - deadline;
    cycle(late_ns, period_ns, keeps_time_ ? late_ns / period_ns : std::int64_t{0});
    clock_gettime(CLOCK_MONOTONIC, &now);
    work_ns_ = to_ns(now) - woke;  // recorded with the next cycle
    deadline += period_ns;
    // After an overrun, skip the periods already missed instead of running a burst of cycles.
    if (late_ns > period_ns) {
      deadline += (late_ns / period_ns) * period_ns;
      if (!keeps_time_) owed_cycles_ = std::min(owed_cycles_ + late_ns / period_ns, kMaxOwedCycles);
    }
    // Simulated hardware steps its world once a cycle: a skipped period is simulated time lost,
    // and a robot simulated by another EDP, which was not held up, would be that far ahead of it
    // for the rest of the motion (two carriers 16 periods apart read as a grip distance 1.4 mm
    // off). The periods owed are made up in the idle time before the next deadline, as many as
    // fit, never as a burst that would make the next cycle late.
    while (owed_cycles_ > 0 && running_.load(std::memory_order_relaxed)) {
      clock_gettime(CLOCK_MONOTONIC, &now);
      const std::int64_t start = to_ns(now);
      if (start + std::max(work_ns_, period_ns / 4) > deadline) break;
      cycle(0, period_ns, 0);
      --owed_cycles_;
      {
        std::lock_guard lock(mutex_);
        ++caught_up_total_;
      }
      clock_gettime(CLOCK_MONOTONIC, &now);
      work_ns_ = to_ns(now) - start;
    }
  }
}

bool ServoLoop::has_work() const {
  return mode_ != Mode::hold || current_.has_value() || !queue_.empty() || reset_pending_ ||
         after_stop_id_ != 0 || hold_at_measured_ || outputs_pending_ || servo_pending_ ||
         device_pending_;
}

bool ServoLoop::awaiting_successor() const {
  return current_ && current_->promises_successor() && current_->step + 1 >= current_->steps &&
         queue_.empty() && !faulted_ && !emergency_stop_;
}

bool ServoLoop::at_rest() const {
  for (std::size_t i = 0; i < axes_; ++i)
    if (end_velocity_[i] != 0.0) return false;
  return true;
}

bool ServoLoop::awaiting_lookahead() const {
  // At the start of macro-step k, its client may have sent up to k + lookahead - 2 (the reply to
  // k + lookahead - 1 is the reading taken in k): waiting for those cannot deadlock.
  if (current_ || queue_.empty() || faulted_ || emergency_stop_ || mode_ != Mode::hold)
    return false;
  if (!queue_.back().promises_successor()) return false;  // the motion's end is queued
  if (queue_.back().id <= waived_upto_) return false;     // the client said none follows
  const std::size_t known = queue_.size() - 1;
  return lookahead_ >= 3 && known < static_cast<std::size_t>(lookahead_ - 2);
}

void ServoLoop::run_lock_step() {
  // Simulated time advances only in cycle() (the plugin's write()), so cycles with work run back
  // to back; idle, the loop holds once a period (status and inputs stay fresh).
  const auto period = seconds(period_s_);
  const auto successor_wait = seconds(successor_wait_s_);
  while (running_.load(std::memory_order_relaxed)) {
    wait_until_ready(mutex_, changed_, period, [&] { return !running_.load() || has_work(); });
    // The ECP read this macro-step early to send its successor: simulated time stands still
    // until it is queued (a real-time loop would run out of motion if it came late).
    // Likewise at the start of a macro-step for the successors its client may already send,
    // so that its end velocity is chosen knowing them (motion_blend.hpp), as in real time.
    wait_until_ready(mutex_, changed_, successor_wait, [&] {
      return !running_.load() || (!awaiting_successor() && !awaiting_lookahead()) || reset_pending_;
    });
    if (!running_.load(std::memory_order_relaxed)) break;
    cycle(0, 1, 0);
  }
}

void ServoLoop::set_fault(const char* text) {
  std::snprintf(fault_, sizeof fault_, "%s", text);
  faulted_ = true;
  current_.reset();
  end_velocity_.fill(0.0);
  drop_queue();
  synchroniser_.abandon();
  homing_pending_ = false;
  mode_ = Mode::hold;
  notify_pending_ = true;
}

void ServoLoop::drop_queue() {
  if (!queue_.empty()) reached_id_ = std::max(reached_id_, queue_.back().id);
  queue_.clear();
  notify_pending_ = true;
}

void ServoLoop::store_reading(std::uint64_t id, int step_no) {
  Reading& r = delivered_[id % kDeliveredKept];
  r = latest_;
  r.macro_step = id;
  r.step_no = step_no;
  r.macro_steps_ahead = queued();
  r.ramps_before = lost_successors_ + planned_stops_;
  reached_id_ = std::max(reached_id_, id);
  notify_pending_ = true;
}

void ServoLoop::cycle(std::int64_t late_ns, std::int64_t period_ns, std::int64_t missed) {
  // How long the servo thread waits for its mutex (every holder only copies; measured so that an
  // overrun report can tell a held lock from a late wake-up).
  std::int64_t lock_wait_ns = 0;
  auto lock_timed = [&] {
    timespec t0{};
    timespec t1{};
    clock_gettime(CLOCK_MONOTONIC, &t0);
    mutex_.lock();
    clock_gettime(CLOCK_MONOTONIC, &t1);
    lock_wait_ns = std::max(lock_wait_ns, to_ns(t1) - to_ns(t0));
  };
  bool reset = false;
  bool home = false;
  // 0. A reset after a fault (deactivate(), activate(): a bring-up) and the hardware's own homing
  // at SYNCHRO block for up to seconds: they run on the recovery thread, never on this one. No
  // plugin call is made from here while one runs (the robot is held by a fault, or stands while
  // it synchronises); in real time the cycles go on meanwhile without the plugin, in lock-step
  // and stepped loops the cycle waits for it. The cycle after it reads the result.
  if (recovery_in_flight_ == kNoRecovery) {
    lock_timed();
    reset = reset_pending_;
    home =
        homing_pending_ && !reset && !faulted_ && !emergency_stop_ && mode_ == Mode::synchronising;
    if (home) {
      homing_pending_ = false;
      homing_running_ = true;
    }
    mutex_.unlock();
    if (reset || home) post_recovery(reset);
  }
  char homing_failure[sizeof fault_] = {};
  if (recovery_in_flight_ != kNoRecovery) {
    const bool wait = lock_step_ || stepped_;
    if (!recovery_ended(wait)) return;  // real time: the next cycle looks again
    reset = recovery_in_flight_ == kResetRecovery;
    home = recovery_in_flight_ == kHomingRecovery;
    // A reset that failed stays faulted: read() below reports why. A homing's failure names the
    // axis, the method and the time (Hardware::home_axes); the synchroniser starts from the
    // positions read below.
    if (home) std::snprintf(homing_failure, sizeof homing_failure, "%s", recovery_failure_);
    recovery_in_flight_ = kNoRecovery;
  }
  // 1. Sample, without the lock. A plugin must not throw here; if it does, the loop holds the
  // robot and reports it as a fault.
  CycleStatus read_status = CycleStatus::ok;
  char thrown[200] = {};  // the exception's text, copied while the exception lives
  std::uint32_t inputs = 0;
  try {
    read_status = hardware_.read(std::span(sample_.data(), axes_));
    inputs = hardware_.read_inputs();
    if (!device_.reply.empty())
      hardware_.read_device(std::span(device_sample_.data(), device_.reply.size()));
  } catch (const std::exception& e) {
    read_status = CycleStatus::fault;
    std::snprintf(thrown, sizeof thrown, "%s", e.what());
  } catch (...) {
    read_status = CycleStatus::fault;
    std::snprintf(thrown, sizeof thrown, "unknown exception");
  }

  // 2. Decide the setpoints under the lock (copies and arithmetic only).
  bool write_outputs = false;
  bool write_device = false;
  bool switch_servo = false;
  std::uint32_t outputs = 0;
  std::array<std::int8_t, kMaxAxes> algorithm{};
  std::array<std::int8_t, kMaxAxes> parameter_set{};
  bool notify = false;
  lock_timed();
  {
    std::lock_guard lock(mutex_, std::adopt_lock);
    feedback_ = sample_;
    latest_.inputs = inputs;
    latest_.device = device_sample_;
    if (reset) {
      reset_pending_ = false;
      if (read_status == CycleStatus::ok) {
        faulted_ = false;
        fault_[0] = '\0';
        synchronised_ = false;
        mode_ = Mode::hold;
        current_.reset();
        drop_queue();
        for (std::size_t i = 0; i < axes_; ++i) desired_[i] = feedback_[i].position;
      }
      notify_pending_ = true;
    }
    if (home) finish_homing(homing_failure, read_status == CycleStatus::ok);
    if (read_status != CycleStatus::ok && !faulted_) {
      if (thrown[0] != '\0') {
        char text[256];
        std::snprintf(text, sizeof text, "plugin threw in read(): %s", thrown);
        set_fault(text);
      } else {
        set_fault(hardware_.fault_text().c_str());
      }
    }
    plan_cycle(missed);
    write_outputs = outputs_pending_;
    outputs_pending_ = false;
    outputs = outputs_;
    write_device = device_pending_;
    device_pending_ = false;
    if (write_device) device_write_ = device_command_;
    switch_servo = servo_pending_;
    servo_pending_ = false;
    algorithm = servo_algorithm_;
    parameter_set = servo_parameter_set_;
    const bool use_offset = synchronised_.load(std::memory_order_relaxed);
    for (std::size_t i = 0; i < axes_; ++i)
      raw_setpoints_[i] = desired_[i] - (use_offset ? offset_[i] : 0.0);
    notify = notify_pending_;
    notify_pending_ = false;
    // Counted after the cycle's reading took the counter (latest_.cycle), as before the write.
    timing_.record(late_ns, period_ns, work_ns_, lock_wait_ns);
  }
  if (notify) changed_.notify();

  // 3. Write, without the lock (a simulation steps its physics here).
  char failure[256] = {};
  try {
    if (write_outputs) hardware_.write_outputs(outputs);
    if (write_device)
      hardware_.write_device(std::span<const double>(device_write_.data(), device_.command.size()));
    if (switch_servo)
      for (std::size_t i = 0; i < axes_; ++i)
        hardware_.set_servo(i, algorithm[i], parameter_set[i]);
    if (hardware_.write(std::span<const double>(raw_setpoints_.data(), axes_)) != CycleStatus::ok)
      std::snprintf(failure, sizeof failure, "%s", hardware_.fault_text().c_str());
  } catch (const std::exception& e) {
    std::snprintf(failure, sizeof failure, "plugin threw in write(): %s", e.what());
  } catch (...) {
    std::snprintf(failure, sizeof failure, "plugin threw in write(): unknown exception");
  }
  if (failure[0] != '\0') {
    {
      std::lock_guard lock(mutex_);
      if (!faulted_) set_fault(failure);
      notify_pending_ = false;
    }
    changed_.notify();
  }
}

void ServoLoop::finish_homing(const char* failure, bool read_ok) {
  homing_running_ = false;
  notify_pending_ = true;
  // The homed axes count from their new reference now: hold every axis where it stands, so
  // that nothing jumps whatever comes next.
  for (std::size_t i = 0; i < axes_; ++i) desired_[i] = feedback_[i].position;
  if (failure[0] != '\0') {
    if (!faulted_) set_fault(failure);
    return;
  }
  // A read that failed is reported as a fault by the caller.
  if (!read_ok || mode_ != Mode::synchronising) return;
  if (emergency_stop_) {
    // Engaged as the homing ended (the hardware's quick stop ends one that still runs, as a
    // failure): the synchronisation is abandoned, the robot held.
    synchroniser_.abandon();
    mode_ = Mode::hold;
    return;
  }
  for (std::size_t i = 0; i < axes_; ++i) {
    if ((homed_axes_ & (1U << i)) == 0U) continue;
    const double q = feedback_[i].position;
    const bool below = q < model_.lower_limits[i];
    if (below || q > model_.upper_limits[i]) {
      char text[sizeof fault_];
      std::snprintf(text, sizeof text,
                    "axis %zu (%s) stands at %.4f %s after its homing, %s its %s limit of "
                    "%.4f %s (the homing's offset is the joint's position at the home point)",
                    i, model_.joint_names[i].c_str(), q, model_.unit(i), below ? "below" : "above",
                    below ? "lower" : "upper",
                    below ? model_.lower_limits[i] : model_.upper_limits[i], model_.unit(i));
      set_fault(text);
      return;
    }
  }
  synchroniser_.begin(std::span<const AxisFeedback>(feedback_.data(), axes_), desired_, offset_,
                      homed_axes_);
}

void ServoLoop::plan_cycle(std::int64_t missed) {
  const bool synced = synchronised_.load(std::memory_order_relaxed);
  const std::span<const AxisFeedback> fb(feedback_.data(), axes_);
  latest_.cycle = timing_.cycles();
  latest_.synchronised = synced;
  for (std::size_t i = 0; i < axes_; ++i) {
    latest_.joints[i] = fb[i].position + (synced ? offset_[i] : 0.0);
    latest_.velocities[i] = fb[i].velocity;
  }
  latest_.outputs = outputs_;  // written in this cycle
  latest_.servo_algorithm = servo_algorithm_;
  latest_.servo_parameter_set = servo_parameter_set_;

  const AxisArray previous_desired = desired_;
  if (faulted_) {
    // Hold still where the axes are.
    for (std::size_t i = 0; i < axes_; ++i) desired_[i] = latest_.joints[i];
  } else if (mode_ == Mode::stopping) {
    const RampStep r =
        stopping_ramp_step(std::span<const double>(commanded_velocity_.data(), axes_),
                           std::span(desired_.data(), axes_), std::span(scratch_.data(), axes_),
                           motion_limits(), period_s_, ramp_guard());
    if (r.at_limit) ++limit_stops_;
    if (!r.moving) {
      mode_ = Mode::hold;
      notify_pending_ = true;
    }
  } else if (mode_ == Mode::synchronising) {
    char text[200] = {};
    const Synchroniser::Result r =
        synchroniser_.step(fb, period_s_, desired_, offset_, std::span(text, sizeof text));
    if (synchroniser_.found() && !synchronised_) synchronised_ = true;
    if (r == Synchroniser::Result::failed) {
      set_fault(text);
    } else if (r == Synchroniser::Result::done) {
      synchronised_ = true;
      mode_ = Mode::hold;
      notify_pending_ = true;
    }
  } else {
    motion_cycle(synced ? catch_up_advance(missed) : 1.0);
  }
  warp_velocity_ = commanded_velocity_;
  // The commanded velocity in one coordinate system: not across the cycle in which the
  // synchronisation switches desired_ from raw axis positions to joint coordinates.
  if (synced == synchronised_.load(std::memory_order_relaxed) && !faulted_)
    for (std::size_t i = 0; i < axes_; ++i)
      commanded_velocity_[i] = (desired_[i] - previous_desired[i]) / period_s_;
  else
    commanded_velocity_.fill(0.0);
  latest_.desired = desired_;
  latest_.macro_steps_ahead = queued();
  if (trace_count_ < trace_.size()) {
    TraceSample& t = trace_[trace_count_++];
    t.cycle = timing_.cycles();
    t.synchronised = synced;
    t.desired = desired_;
    t.measured = latest_.joints;
    t.outputs = outputs_;
  }
}

double ServoLoop::catch_up_advance(std::int64_t missed) {
  // Hardware that keeps its own clock (drives) went on while this thread was held: the motion
  // fell behind its planned time line by the periods it missed, and a robot moving with others
  // would stay behind them for the rest of the motion. It makes them up by running a little
  // faster than planned (the rate 1 + warp), within the joints' limits, starting and ending that
  // smoothly.
  const bool in_motion = current_.has_value() || (!queue_.empty() && !at_rest());
  if (!keeps_time_ || !in_motion) {
    lag_steps_ = 0.0;
    warp_ = 0.0;
    previous_rate_ = 1.0;
    return 1.0;
  }
  if (missed > 0) {
    lag_steps_ += static_cast<double>(missed);
    caught_up_total_ += missed;
  }
  const double rate = 1.0 + warp_;  // of the last cycle; previous_rate_: of the one before
  if (lag_steps_ <= 0.0 && warp_ <= 0.0) {
    previous_rate_ = rate;
    return 1.0;
  }
  // The planned velocity and acceleration (the commanded ones without the warp) of the last
  // cycles, and the planned acceleration of the servo steps this cycle will take, bound the top
  // rate and how fast it may change. Not the last cycle's acceleration alone: a blend's
  // acceleration jumps half way through a macro-step and where two meet (0.16 to 0.54 rad/s^2
  // where a plan speeds up harder), and a rise sized from the acceleration before the jump took
  // a step of the column to 3.08 rad/s^2 against its limit of 3 (test_edp_catch_up.cpp).
  double top = kMaxWarp;
  double up = kMaxWarp;
  double down = kMaxWarp;
  bool hard = false;  // a planned acceleration, now or queued, leaves too little room
  for (std::size_t i = 0; i < axes_; ++i) {
    const double v = commanded_velocity_[i] / rate;
    // Both per cycle at the last rate: a planned acceleration a changes the velocity between two
    // cycles by a * rate * period.
    const double last =
        std::abs(v - warp_velocity_[i] / previous_rate_) / period_s_ / model_.max_acceleration[i];
    const double ahead =
        planned_acceleration_ahead(i, 1.0 + kMaxWarp) * rate / model_.max_acceleration[i];
    const double share = std::max(last, ahead);
    hard = hard || share > kWarpPlannedAccelerationShare;
    if (share > 1e-9) top = std::min(top, std::sqrt(0.8 * kWarpAccelerationShare / share) - 1.0);
    if (std::abs(v) > 1e-9) {
      const double per_rate = model_.max_acceleration[i] * period_s_ / std::abs(v);
      top = std::min(top, kWarpVelocityShare * model_.max_velocity[i] / std::abs(v) - 1.0);
      const double room = std::max(0.0, kWarpAccelerationShare - share * rate * rate);
      up = std::min(up, room * per_rate);
      down = std::min(down, std::max(room, kWarpMinimumUnwindShare) * per_rate);
    }
  }
  // The macro-steps queued: the change of their mean velocities, a planned acceleration the
  // warp must have wound down before (the lookahead gives it that time).
  if (current_ && !hard) {
    AxisArray from = current_->target;
    AxisArray velocity{};
    double duration = static_cast<double>(current_->steps) * period_s_;
    for (std::size_t i = 0; i < axes_; ++i)
      velocity[i] = (current_->target[i] - current_->start[i]) / duration;
    for (std::size_t k = 0; k < queue_.size() && !hard; ++k) {
      const MacroStep& next = queue_.at(k);
      const double next_duration = static_cast<double>(next.steps) * period_s_;
      for (std::size_t i = 0; i < axes_; ++i) {
        const double v = (next.target[i] - from[i]) / next_duration;
        hard = hard || std::abs(v - velocity[i]) / (0.5 * (duration + next_duration)) >
                           kWarpQueuedAccelerationShare * model_.max_acceleration[i];
        velocity[i] = v;
        from[i] = next.target[i];
      }
      duration = next_duration;
    }
  }
  // Running faster takes the client's time: only while it is ahead (two macro-steps queued
  // behind the running one), so that a catch-up never makes the queue run dry.
  if (queue_.size() < kWarpQueuedMacroSteps) hard = true;
  top = hard ? 0.0 : std::max(top, 0.0);
  // Towards the top rate while the lag lasts, and back to none before it runs out: winding down
  // from w by `down` a cycle takes up about w^2 / (2 down) + w of it. A small lead left at the
  // end (a fraction of a step) is forgotten.
  const double braking = down > 0.0 ? warp_ * warp_ / (2.0 * down) + warp_ : 0.0;
  const double wanted = lag_steps_ > braking ? top : 0.0;
  previous_rate_ = rate;
  warp_ = wanted > warp_ ? std::min(wanted, warp_ + up) : std::max(wanted, warp_ - down);
  lag_steps_ -= warp_;
  if (warp_ <= 0.0 && lag_steps_ < 0.0) lag_steps_ = 0.0;
  return 1.0 + warp_;
}

double ServoLoop::planned_acceleration_ahead(std::size_t i, double reach) const {
  if (!current_) return 0.0;
  const MacroStep& m = *current_;
  const auto steps = static_cast<double>(m.steps);
  const BlendAccelerations a = blend_accelerations(m.start[i], m.target[i], m.start_velocity[i],
                                                   m.end_velocity[i], steps * period_s_);
  const double end = m.progress + reach;
  double out = 0.0;
  if (m.progress < 0.5 * steps) out = std::abs(a.first);
  if (end > 0.5 * steps) out = std::max(out, std::abs(a.second));
  if (end > steps && !queue_.empty()) {
    // The successor's end velocity is chosen only when it starts (plan_blend): here the one
    // plan_blend prefers, the mean of its own and its successor's mean velocities.
    const MacroStep& next = queue_.front();
    const double duration = static_cast<double>(next.steps) * period_s_;
    const double mean = (next.target[i] - m.target[i]) / duration;
    double v1 = 0.0;
    if (next.promises_successor()) {
      v1 = mean;
      if (queue_.size() > 1) {
        const MacroStep& after = queue_.at(1);
        v1 = 0.5 * (mean + (after.target[i] - next.target[i]) /
                               (static_cast<double>(after.steps) * period_s_));
      }
    }
    const BlendAccelerations b =
        blend_accelerations(m.target[i], next.target[i], m.end_velocity[i], v1, duration);
    out = std::max({out, std::abs(b.first), std::abs(b.second)});
  }
  return out;
}

bool ServoLoop::start_next_macro_step(bool mid_cycle) {
  // The macro-step starts where the previous one ended, with the velocity it ended with, or where
  // the robot stands (after a stopping ramp for a late successor, that is past the last target,
  // not where the task planned it to start). One that would need more than a joint's velocity or
  // acceleration limit, or pass a joint limit, is refused with every macro-step queued behind
  // it; a robot still moving is brought to rest within its acceleration limits, else it holds.
  const MacroStep& next = queue_.front();
  BlendInput in;
  in.start = &desired_;
  in.velocity = &end_velocity_;
  in.step = &next;
  std::size_t following = 0;
  for (std::size_t k = 1; k < queue_.size(); ++k) following_[following++] = &queue_.at(k);
  in.following = std::span<const MacroStep* const>(following_.data(), following);
  in.period_s = period_s_;
  in.after_ramp = after_ramp_;
  AxisArray end_velocity{};
  const bool synced = synchronised_.load(std::memory_order_relaxed);
  const BlendRefusal refusal = plan_blend(in, motion_limits(), axes_, end_velocity, refused_text_);
  after_ramp_ = false;
  if (refusal != BlendRefusal::none) {
    bool moving = false;
    for (std::size_t i = 0; i < axes_; ++i) moving = moving || end_velocity_[i] != 0.0;
    std::size_t used = std::strlen(refused_text_);
    if (!synced && used < sizeof refused_text_)
      std::snprintf(refused_text_ + used, sizeof refused_text_ - used,
                    " (before SYNCHRO: %.2f of the velocity and %.2f of the acceleration limits, "
                    "[robot.edp] unsynchronised_*)",
                    unsynced_.velocity_fraction, unsynced_.acceleration_fraction);
    used = std::strlen(refused_text_);
    std::snprintf(refused_text_ + used, sizeof refused_text_ - used, "%s",
                  moving ? "; the robot is brought to rest within its acceleration limits"
                         : "; the robot holds");
    refused_code_ = refusal == BlendRefusal::acceleration ? error_code::too_abrupt
                    : refusal == BlendRefusal::limit      ? error_code::out_of_limits
                                                          : error_code::too_fast;
    refused_first_ = next.id;
    refused_last_ = queue_.back().id;
    drop_queue();
    end_velocity_.fill(0.0);
    if (moving && mid_cycle) {
      // This cycle already moved: the caller finishes it, and the ramp starts in the next one.
      mode_ = Mode::stopping;
    } else if (moving) {
      // The ramp's first step is taken in this cycle, from the velocity of the last one.
      mode_ = Mode::stopping;
      const RampStep r =
          stopping_ramp_step(std::span<const double>(commanded_velocity_.data(), axes_),
                             std::span(desired_.data(), axes_), std::span(scratch_.data(), axes_),
                             motion_limits(), period_s_, ramp_guard());
      if (r.at_limit) ++limit_stops_;
      if (!r.moving) mode_ = Mode::hold;
    }
    notify_pending_ = true;
    return false;
  }
  current_ = queue_.pop();
  current_->start = desired_;
  current_->start_velocity = end_velocity_;
  current_->end_velocity = end_velocity;
  notify_pending_ = true;  // a queue slot is free
  return true;
}

void ServoLoop::motion_cycle(double advance) {
  if (hold_at_measured_ && !current_ && queue_.empty()) {
    hold_at_measured_ = false;
    for (std::size_t i = 0; i < axes_; ++i) desired_[i] = latest_.joints[i];
  }
  if (after_stop_id_ != 0) {
    store_reading(after_stop_id_, after_stop_step_);
    after_stop_id_ = 0;
  }
  if (!current_ && !queue_.empty()) {
    // A motion from rest starts once the successors its client may already send are queued (at
    // most the time the lookahead covers, and kMaxStartHoldS): a client held back just after
    // the first macro-step would otherwise leave the robot with no queue to ride that pause on,
    // and of a group of robots moving together the one whose client is late would start late.
    const std::int64_t hold_limit =
        std::min(static_cast<std::int64_t>(lookahead_ - 1) * queue_.front().steps,
                 static_cast<std::int64_t>(std::ceil(kMaxStartHoldS / period_s_)));
    if (!lock_step_ && at_rest() && awaiting_lookahead() && start_held_cycles_ < hold_limit) {
      ++start_held_cycles_;
      return;
    }
    start_held_cycles_ = 0;
    start_next_macro_step(false);
  }
  // Whole steps as planned; only a catch-up (advance > 1) makes `progress` fractional, and then
  // the part of the advance past a macro-step's end is taken in its successor in the same cycle.
  constexpr double kEps = 1e-9;
  double left = advance;
  while (current_) {
    MacroStep& m = *current_;
    const double before = m.progress;
    m.progress += left;
    left = 0.0;
    const auto steps = static_cast<double>(m.steps);
    if (m.progress >= steps - kEps) {
      m.step = m.steps;
      left = std::max(0.0, m.progress - steps);
      for (std::size_t i = 0; i < axes_; ++i) desired_[i] = m.target[i];
    } else {
      m.step = static_cast<int>(std::floor(m.progress + kEps));
      const double s = m.progress / steps;
      const double duration = steps * period_s_;
      for (std::size_t i = 0; i < axes_; ++i)
        desired_[i] = blend_position(m.start[i], m.target[i], m.start_velocity[i],
                                     m.end_velocity[i], duration, s);
    }
    latest_.desired = desired_;
    const auto reading_step = static_cast<double>(m.value_in_step_no);
    if (m.value_in_step_no <= m.steps && before < reading_step - kEps &&
        m.progress >= reading_step - kEps)
      store_reading(m.id, m.value_in_step_no);
    if (m.step < m.steps) return;
    // A reading before the last step promises the next macro-step in time (the paper: one step
    // early suffices for a seamless transition); in or after the last step it does not.
    const bool promised_successor = m.promises_successor();
    if (!promised_successor && m.value_in_step_no > m.steps) {
      after_stop_id_ = m.id;
      after_stop_step_ = m.steps + 1;
    }
    end_velocity_ = m.end_velocity;
    const std::uint64_t id = m.id;
    current_.reset();
    notify_pending_ = true;
    if (promised_successor && queue_.empty()) {
      // The ECP read this macro-step early to send the next one in time, and none came: the
      // link or the ECP is lost, or the host held it back longer than the lookahead covers (or,
      // when the client waived it, the task paused or stopped). Bring the robot to a standstill
      // within its acceleration limits instead of stopping it dead.
      if (id <= waived_upto_)
        ++planned_stops_;
      else
        ++lost_successors_;
      mode_ = Mode::stopping;
      after_ramp_ = true;
      coast(end_velocity_, left);
      end_velocity_.fill(0.0);  // the ramp ends at rest
      return;
    }
    if (left <= kEps || queue_.empty()) return;
    // Continues in this cycle with what is left of the advance; if the successor is refused, with
    // the velocity this one ended with, and the ramp to rest from the next cycle.
    const AxisArray ended_with = end_velocity_;
    if (!start_next_macro_step(true)) {
      coast(ended_with, left);
      return;
    }
  }
}

void ServoLoop::coast(const AxisArray& velocity, double steps) {
  // A catch-up (or the lead it left, a fraction of a step) carries a motion's end into the middle
  // of a cycle. When the stopping ramp follows, this cycle must still advance by all of it:
  // stopping at the end point would take that fraction of a step's distance off this cycle's
  // velocity at once (0.0058 rad/s of 0.3 rad/s after a stall of one period, 2.9 rad/s^2 against
  // a limit of 2; 0.29 rad/s, 147 rad/s^2, with the rate still raised by a 20-period stall), before
  // the ramp brakes from what is left within the limits. The plan's end velocity continues it.
  if (steps <= 0.0) return;
  if (!move_within_limits(std::span<const double>(velocity.data(), axes_), steps * period_s_,
                          std::span(desired_.data(), axes_), std::span(scratch_.data(), axes_),
                          motion_limits(), ramp_guard()))
    ++limit_stops_;
  latest_.desired = desired_;
}

void ServoLoop::emergency_stop() {
  hardware_.emergency_stop(true);
  {
    std::lock_guard lock(mutex_);
    emergency_stop_ = true;
    // The outputs take their safe state in the next cycle (kept lines stay); a release does not
    // restore them.
    outputs_ = (outputs_ & kept_outputs_) | (safe_outputs_ & ~kept_outputs_);
    outputs_pending_ = true;
    if (current_) reached_id_ = std::max(reached_id_, current_->id);
    current_.reset();
    end_velocity_.fill(0.0);
    drop_queue();
    if (!faulted_ && (mode_ == Mode::hold || mode_ == Mode::stopping)) {
      // A motion (synchronised or before SYNCHRO, within motion_limits()) is ramped to rest;
      // a robot at rest ends the ramp in the next cycle.
      mode_ = Mode::stopping;
    } else if (homing_running_) {
      // The hardware's homing runs on the recovery thread: the quick stop
      // (hardware_.emergency_stop above) ends it, and the cycle after it reports how
      // (finish_homing); SYNCHRO waits for it.
    } else if (mode_ != Mode::hold) {
      synchroniser_.abandon();  // a synchronisation search is simply abandoned (it is slow)
      homing_pending_ = false;
      mode_ = Mode::hold;
    }
  }
  changed_.notify();
}

void ServoLoop::release_emergency_stop() {
  {
    std::lock_guard lock(mutex_);
    emergency_stop_ = false;
    // Hold where the axes really are: drives with their own quick stop may have stopped a little
    // away from the loop's own ramp.
    hold_at_measured_ = true;
  }
  changed_.notify();
  hardware_.emergency_stop(false);
}

bool ServoLoop::emergency_stopped() const {
  std::lock_guard lock(mutex_);
  return emergency_stop_;
}

std::int64_t ServoLoop::caught_up_steps() const {
  std::lock_guard lock(mutex_);
  return caught_up_total_;
}

std::int64_t ServoLoop::lost_successors() const {
  std::lock_guard lock(mutex_);
  return lost_successors_;
}

void ServoLoop::waive_successor() {
  std::lock_guard lock(mutex_);
  waived_upto_ = next_id_ - 1;
}

std::int64_t ServoLoop::planned_stops() const {
  std::lock_guard lock(mutex_);
  return planned_stops_;
}

bool ServoLoop::reset_fault(double timeout_s) {
  {
    std::lock_guard lock(mutex_);
    if (!faulted_) return true;
    reset_pending_ = true;
  }
  changed_.notify();
  wait_until_ready(mutex_, changed_, seconds(timeout_s),
                   [&] { return !reset_pending_ || !running_; });
  return !faulted_;
}

std::uint64_t ServoLoop::submit(const std::vector<double>& target, int steps,
                                int value_in_step_no) {
  std::uint64_t id = 0;
  for (;;) {
    const std::uint32_t seen = changed_.value();
    {
      std::lock_guard lock(mutex_);
      if (emergency_stop_) throw HardwareError("emergency stop engaged");
      if (faulted_) throw HardwareError(fault_);
      if (!running_) throw HardwareError("the servo loop is not running");
      if (!queue_.full()) {
        MacroStep m;
        m.id = next_id_++;
        for (std::size_t i = 0; i < axes_; ++i) m.target[i] = target[i];
        m.steps = steps;
        m.value_in_step_no = value_in_step_no;
        queue_.push(m);
        id = m.id;
        break;
      }
    }
    changed_.wait_for(seen, std::chrono::milliseconds(100));
  }
  changed_.notify();  // a lock-step loop waits for work
  return id;
}

std::uint64_t ServoLoop::reply_due_at(std::uint64_t id, bool promises_successor) const {
  const auto ahead = static_cast<std::uint64_t>(lookahead_ - 1);
  if (!promises_successor || ahead == 0) return id;
  return id > ahead ? id - ahead : 0;
}

std::int64_t ServoLoop::queued_steps() const {
  std::lock_guard lock(mutex_);
  std::int64_t steps = current_ ? current_->steps - current_->step : 0;
  for (std::size_t i = 0; i < queue_.size(); ++i) steps += queue_.at(i).steps;
  return steps;
}

std::vector<double> ServoLoop::planned_end() const {
  AxisArray end{};
  {
    std::lock_guard lock(mutex_);
    end = !queue_.empty() ? queue_.back().target : current_ ? current_->target : desired_;
  }
  return {end.begin(), end.begin() + static_cast<std::ptrdiff_t>(axes_)};
}

std::optional<Reading> ServoLoop::wait_reading(std::uint64_t id, double timeout_s) {
  return wait_reply(id, id, timeout_s);
}

std::optional<Reading> ServoLoop::wait_reply(std::uint64_t id, std::uint64_t due_at,
                                             double timeout_s) {
  std::optional<Reading> out;
  auto refused = [&] { return id >= refused_first_ && id <= refused_last_ && refused_first_ != 0; };
  wait_until_ready(mutex_, changed_, seconds(timeout_s), [&] {
    if (refused() || faulted_ || emergency_stop_ || !running_) return true;
    if (reached_id_ < due_at) return false;
    if (const Reading& kept = delivered_[due_at % kDeliveredKept];
        due_at != 0 && kept.macro_step == due_at &&
        kept.ramps_before == lost_successors_ + planned_stops_) {
      out = kept;
    } else {
      // The macro-step it waits for took no reading (it was dropped, or refused), took it more
      // than kDeliveredKept macro-steps ago, or the robot was brought to rest since (a client
      // resuming from there needs where it stands): the freshest reading answers.
      out = latest_;
      out->macro_step = due_at;
      out->step_no = current_ ? current_->step : 0;
    }
    return true;
  });
  return out;
}

std::string ServoLoop::refusal(std::uint64_t id) const {
  char text[sizeof refused_text_] = {};
  {
    std::lock_guard lock(mutex_);
    if (refused_first_ != 0 && id >= refused_first_ && id <= refused_last_)
      std::memcpy(text, refused_text_, sizeof text);
  }
  return text;
}

int ServoLoop::refusal_code(std::uint64_t id) const {
  std::lock_guard lock(mutex_);
  return refused_first_ != 0 && id >= refused_first_ && id <= refused_last_ ? refused_code_ : 0;
}

std::uint64_t ServoLoop::refused_upto() const {
  std::lock_guard lock(mutex_);
  return refused_last_;
}

Reading ServoLoop::latest() const {
  std::lock_guard lock(mutex_);
  return latest_;
}

bool ServoLoop::moving() const {
  std::lock_guard lock(mutex_);
  return current_.has_value() || !queue_.empty() || mode_ != Mode::hold;
}

bool ServoLoop::stopped() const {
  std::lock_guard lock(mutex_);
  bool still = !current_ && queue_.empty() && mode_ == Mode::hold;
  for (std::size_t i = 0; i < axes_; ++i) still = still && commanded_velocity_[i] == 0.0;
  return still;
}

void ServoLoop::begin_synchronisation() {
  {
    std::lock_guard lock(mutex_);
    if (homed_axes_ != 0U)
      homing_pending_ = true;  // the next cycle homes them; the search begins after it
    else
      synchroniser_.begin(std::span<const AxisFeedback>(feedback_.data(), axes_), desired_,
                          offset_);
    mode_ = Mode::synchronising;
  }
  changed_.notify();
}

bool ServoLoop::wait_synchronised(double timeout_s) {
  wait_until_ready(mutex_, changed_, seconds(timeout_s),
                   [&] { return mode_ == Mode::hold || faulted_ || !running_; });
  std::lock_guard lock(mutex_);
  return mode_ == Mode::hold && synchronised_ && !faulted_;
}

bool ServoLoop::request_outputs(std::uint32_t values) {
  {
    std::lock_guard lock(mutex_);
    // Checked under the lock that emergency_stop() takes: a stop engaged after the EDP's own
    // check cannot be overwritten by the SET that was on its way.
    if (emergency_stop_) return false;
    outputs_ = values;
    outputs_pending_ = true;
  }
  changed_.notify();
  return true;
}

void ServoLoop::set_stop_outputs(std::uint32_t safe, std::uint32_t kept) {
  std::lock_guard lock(mutex_);
  safe_outputs_ = safe;
  kept_outputs_ = kept;
}

void ServoLoop::request_device(const std::vector<double>& command) {
  {
    std::lock_guard lock(mutex_);
    const std::size_t n = std::min(command.size(), device_.command.size());
    std::copy_n(command.begin(), n, device_command_.begin());
    device_pending_ = true;
  }
  changed_.notify();
}

bool ServoLoop::request_servo(const std::vector<std::int8_t>& algorithm,
                              const std::vector<std::int8_t>& parameter_set) {
  {
    std::lock_guard lock(mutex_);
    if (emergency_stop_) return false;
    for (std::size_t i = 0; i < axes_ && i < algorithm.size(); ++i) {
      servo_algorithm_[i] = algorithm[i];
      servo_parameter_set_[i] = parameter_set[i];
    }
    servo_pending_ = true;
  }
  changed_.notify();
  return true;
}

void ServoLoop::enable_trace(std::size_t capacity) {
  std::vector<TraceSample> fresh(capacity);  // allocated (and freed) outside the lock
  std::lock_guard lock(mutex_);
  trace_.swap(fresh);
  trace_count_ = 0;
}

std::vector<TraceSample> ServoLoop::trace() const {
  std::size_t capacity = 0;
  {
    std::lock_guard lock(mutex_);
    capacity = trace_.size();
  }
  std::vector<TraceSample> out(capacity);  // trace_ keeps its size once the loop runs
  std::lock_guard lock(mutex_);
  const std::size_t n = std::min(trace_count_, out.size());
  std::copy_n(trace_.begin(), n, out.begin());
  out.resize(n);  // shrinks: no allocation
  return out;
}

std::string ServoLoop::fault_text() const {
  char text[sizeof fault_] = {};
  {
    std::lock_guard lock(mutex_);
    std::memcpy(text, fault_, sizeof text);
  }
  return text;
}

TimingWindow ServoLoop::take_timing_window() {
  std::lock_guard lock(mutex_);
  return timing_.take_window();
}

TimingStats ServoLoop::timing() const {
  // Allocated before the lock: the servo thread may wait for it, and an allocation can wait for
  // the kernel's memory map, which other threads of this process hold without priority
  // inheritance.
  std::vector<float> samples(ServoTiming::kSamples);
  char scheduling[sizeof scheduling_] = {};
  std::size_t n = 0;
  {
    std::lock_guard lock(mutex_);
    n = timing_.samples(samples.data());
    std::memcpy(scheduling, scheduling_, sizeof scheduling);
  }
  samples.resize(n);
  std::sort(samples.begin(), samples.end());
  TimingStats t = timing_stats(samples);
  t.scheduling = scheduling;
  return t;
}

TimingStats ServoLoop::timing_stats(const std::vector<float>& sorted) const {
  std::lock_guard lock(mutex_);
  return timing_.stats(sorted, period_s_);  // TimingStats' string stays empty here: no allocation
}

}  // namespace mrroc::edp
