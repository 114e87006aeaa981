#include "servo_timing.hpp"

#include <algorithm>

#include <fmt/format.h>

namespace mrroc::srp {

std::string describe(const TimingSummary& s) {
  return fmt::format(
      "period {:.3f} ms, lateness mean {:.1f} us, max {:.1f} us, overruns {} (total {}), "
      "{} states, {} servo steps",
      s.servo_period_s * 1e3, s.lateness_mean_us, s.lateness_max_us, s.overruns, s.overruns_total,
      s.states, s.servo_steps);
}

void ServoTiming::Accumulator::add(const TimingSample& sample, std::int64_t steps,
                                   std::int64_t new_overruns) {
  ++summary.states;
  summary.servo_period_s = sample.servo_period_s;
  summary.lateness_max_us = std::max(summary.lateness_max_us, sample.lateness_max_us);
  // A state covers the servo steps since the previous one; the first (steps 0) weighs one step.
  const double w = static_cast<double>(std::max<std::int64_t>(steps, 1));
  weighted_lateness += sample.lateness_mean_us * w;
  weight += w;
  summary.servo_steps += std::max<std::int64_t>(steps, 0);
  summary.overruns += new_overruns;
  summary.overruns_total = sample.overruns;
}

TimingSummary ServoTiming::Accumulator::result() const {
  TimingSummary s = summary;
  s.lateness_mean_us = weight > 0 ? weighted_lateness / weight : 0.0;
  return s;
}

void ServoTiming::add(const std::string& robot, const TimingSample& sample) {
  Robot& r = robots_[robot];
  // A restarted EDP counts from 0 again: its first state covers one step.
  const bool first = r.last_step < 0;
  const bool restarted = !first && sample.servo_step < r.last_step;
  const std::int64_t steps = first || restarted ? 0 : sample.servo_step - r.last_step;
  // The first state's counter holds overruns from before the SRP listened: not counted.
  const std::int64_t new_overruns =
      first ? 0
            : std::max<std::int64_t>(
                  restarted ? sample.overruns : sample.overruns - r.last_overruns, 0);
  r.last_step = sample.servo_step;
  r.last_overruns = sample.overruns;
  r.window.add(sample, steps, new_overruns);
  r.all.add(sample, steps, new_overruns);
}

std::map<std::string, TimingSummary> ServoTiming::take_window() {
  std::map<std::string, TimingSummary> out;
  for (auto& [name, r] : robots_) {
    if (r.window.summary.states == 0) continue;
    out[name] = r.window.result();
    r.window = Accumulator{};
  }
  return out;
}

std::map<std::string, TimingSummary> ServoTiming::total() const {
  std::map<std::string, TimingSummary> out;
  for (const auto& [name, r] : robots_) out[name] = r.all.result();
  return out;
}

}  // namespace mrroc::srp
