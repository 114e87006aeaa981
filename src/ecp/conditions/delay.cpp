#include <fmt/format.h>

#include <cmath>

#include "mrroc/core/error.hpp"
#include "mrroc/ecp/conditions.hpp"

namespace mrroc::ecp {

DelayCondition::DelayCondition(double seconds, SteadyClock clock) : clock_(std::move(clock)) {
  if (!(std::isfinite(seconds) && seconds >= 0.0))
    throw Error(fmt::format("delay condition: {} s is not a number >= 0", seconds));
  delay_ = std::chrono::duration_cast<std::chrono::steady_clock::duration>(
      std::chrono::duration<double>(seconds));
  if (!clock_) clock_ = [] { return std::chrono::steady_clock::now(); };
}

bool DelayCondition::check(const SensorList&) {
  const auto now = clock_();
  if (!start_) start_ = now;
  return now - *start_ >= delay_;
}

double DelayCondition::elapsed_s() const {
  if (!start_) return 0.0;
  return std::chrono::duration<double>(clock_() - *start_).count();
}

}  // namespace mrroc::ecp
