#pragma once
/// @file
/// Lateness of the servo loop's wake-ups against their absolute deadlines: a ring of the last
/// samples for percentiles, the worst ever, overruns, and a window read by the state broadcast.
/// Preallocated; not thread-safe by itself (the servo loop guards it with its mutex).

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

namespace mrroc::edp {

/// Lateness of the servo wake-ups against their absolute deadlines.
struct TimingStats {
  std::int64_t cycles = 0;
  std::int64_t overruns = 0;  ///< cycles woken more than one period late
  double period_us = 0;
  double lateness_p50_us = 0;
  double lateness_p99_us = 0;
  double lateness_max_us = 0;
  std::string scheduling;  ///< "SCHED_FIFO 80" or "SCHED_OTHER, timer slack 1 ns"
};

/// Wake-up lateness since the previous `take_window()` (for the robot-state broadcast).
struct TimingWindow {
  std::int64_t cycles = 0;
  double lateness_mean_us = 0;
  double lateness_max_us = 0;
  std::int64_t overruns_total = 0;
  /// The worst overrun in the window: how late that cycle woke [us] (0 if none in the window).
  double worst_overrun_us = 0;
  std::int64_t overruns = 0;  ///< overruns in the window
  /// The longest a cycle of the window worked, from its wake-up to its write's end [us]: an
  /// overrun after short cycles is a wake-up the scheduler or the host held back, not the
  /// cycle's own work.
  double worst_work_us = 0;
  /// The longest a cycle of the window waited for the servo loop's mutex [us].
  double worst_lock_wait_us = 0;
};

class ServoTiming {
 public:
  static constexpr std::size_t kSamples = 1 << 16;
  ServoTiming() : lateness_us_(kSamples, 0.0F) {}

  /// One cycle that woke `late_ns` after its deadline (lock-step: 0); the previous cycle worked
  /// `work_ns` (wake-up to the end of its write) and this one waited `lock_wait_ns` for the lock.
  void record(std::int64_t late_ns, std::int64_t period_ns, std::int64_t work_ns = 0,
              std::int64_t lock_wait_ns = 0);
  [[nodiscard]] std::int64_t cycles() const { return cycles_; }
  /// Copies the samples in the ring into `out` (room for kSamples, allocated by the caller
  /// before it takes the lock: nothing under the servo loop's lock allocates); returns how many.
  std::size_t samples(float* out) const;
  /// Statistics over `sorted` samples (from samples(), sorted).
  [[nodiscard]] TimingStats stats(const std::vector<float>& sorted, double period_s) const;
  TimingWindow take_window();

 private:
  std::int64_t cycles_ = 0;
  std::int64_t overruns_ = 0;
  std::vector<float> lateness_us_;  ///< ring of the last samples
  std::size_t next_ = 0;
  double max_us_ = 0;
  TimingWindow window_{};
  double window_sum_us_ = 0;
};

}  // namespace mrroc::edp
