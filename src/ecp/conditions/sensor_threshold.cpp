#include <fmt/format.h>

#include <cmath>

#include "mrroc/core/error.hpp"
#include "mrroc/ecp/conditions.hpp"
#include "mrroc/ecp/generators/errors.hpp"

namespace mrroc::ecp {

SensorThresholdCondition::SensorThresholdCondition(std::function<double()> reading,
                                                   double threshold, Direction direction,
                                                   double hysteresis)
    : reading_(std::move(reading)),
      threshold_(threshold),
      direction_(direction),
      hysteresis_(hysteresis) {
  if (!reading_) throw Error("sensor threshold condition: no reading function");
  if (!std::isfinite(threshold_))
    throw Error(fmt::format("sensor threshold condition: threshold {} is not finite", threshold_));
  if (!(std::isfinite(hysteresis_) && hysteresis_ >= 0.0))
    throw Error(
        fmt::format("sensor threshold condition: hysteresis {} is not a number >= 0", hysteresis_));
}

bool SensorThresholdCondition::check(const SensorList&) {
  const double x = reading_();
  if (std::isnan(x))
    throw GeneratorError(
        fmt::format("sensor threshold condition: the reading is not a number "
                    "(threshold {})",
                    threshold_));
  last_ = x;
  if (direction_ == Direction::above) {
    if (!state_ && x >= threshold_)
      state_ = true;
    else if (state_ && x <= threshold_ - hysteresis_ && x < threshold_)
      state_ = false;
  } else {
    if (!state_ && x <= threshold_)
      state_ = true;
    else if (state_ && x >= threshold_ + hysteresis_ && x > threshold_)
      state_ = false;
  }
  return state_;
}

}  // namespace mrroc::ecp
