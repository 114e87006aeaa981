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
};

class ServoTiming {
 public:
  static constexpr std::size_t kSamples = 1 << 16;
  ServoTiming() : lateness_us_(kSamples, 0.0F) {}

  /// One cycle that woke `late_ns` after its deadline (lock-step: 0).
  void record(std::int64_t late_ns, std::int64_t period_ns);
  [[nodiscard]] std::int64_t cycles() const { return cycles_; }
  /// The samples in the ring (copied out, to sort without the lock).
  void samples(std::vector<float>& out) const;
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
