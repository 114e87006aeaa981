#include "servo_timing.hpp"

#include <algorithm>

namespace mrroc::edp {

void ServoTiming::record(std::int64_t late_ns, std::int64_t period_ns, std::int64_t work_ns,
                         std::int64_t lock_wait_ns) {
  window_.worst_work_us = std::max(window_.worst_work_us, static_cast<double>(work_ns) / 1000.0);
  window_.worst_lock_wait_us =
      std::max(window_.worst_lock_wait_us, static_cast<double>(lock_wait_ns) / 1000.0);
  const double late_us = static_cast<double>(late_ns) / 1000.0;
  lateness_us_[next_] = static_cast<float>(late_us);
  next_ = (next_ + 1) % kSamples;
  max_us_ = std::max(max_us_, late_us);
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

std::size_t ServoTiming::samples(float* out) const {
  const std::size_t n = std::min<std::size_t>(static_cast<std::size_t>(cycles_), kSamples);
  std::copy_n(lateness_us_.begin(), n, out);
  return n;
}

TimingStats ServoTiming::stats(const std::vector<float>& sorted, double period_s) const {
  TimingStats t;
  t.cycles = cycles_;
  t.overruns = overruns_;
  t.lateness_max_us = max_us_;
  t.period_us = period_s * 1e6;
  if (!sorted.empty()) {
    auto pct = [&](double p) {
      return static_cast<double>(
          sorted[static_cast<std::size_t>(p * static_cast<double>(sorted.size() - 1))]);
    };
    t.lateness_p50_us = pct(0.50);
    t.lateness_p99_us = pct(0.99);
  }
  return t;
}

TimingWindow ServoTiming::take_window() {
  TimingWindow w = window_;
  w.lateness_mean_us = w.cycles > 0 ? window_sum_us_ / static_cast<double>(w.cycles) : 0.0;
  w.overruns_total = overruns_;
  window_ = TimingWindow{};
  window_sum_us_ = 0;
  return w;
}

}  // namespace mrroc::edp
