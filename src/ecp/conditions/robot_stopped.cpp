#include <fmt/format.h>

#include <cmath>

#include "mrroc/core/error.hpp"
#include "mrroc/ecp/conditions.hpp"

namespace mrroc::ecp {

RobotStoppedCondition::RobotStoppedCondition(const RobotImage& image, double velocity_threshold,
                                             int consecutive, std::function<void()> refresh)
    : image_(image),
      threshold_(velocity_threshold),
      consecutive_(consecutive),
      refresh_(std::move(refresh)) {
  if (!(std::isfinite(threshold_) && threshold_ > 0.0))
    throw Error(
        fmt::format("robot stopped condition: velocity threshold {} rad/s is not a "
                    "positive number",
                    threshold_));
  if (consecutive_ < 1)
    throw Error(fmt::format("robot stopped condition: consecutive {} is not >= 1", consecutive_));
}

bool RobotStoppedCondition::check(const SensorList&) {
  if (refresh_) refresh_();
  if (image_.joint_velocities.empty()) return false;
  if (last_cycle_ && *last_cycle_ == image_.servo_cycle) return count_ >= consecutive_;
  last_cycle_ = image_.servo_cycle;
  bool still = true;
  for (const double v : image_.joint_velocities)
    if (!(std::abs(v) < threshold_)) still = false;  // NaN counts as moving
  count_ = still ? count_ + 1 : 0;
  return count_ >= consecutive_;
}

}  // namespace mrroc::ecp
