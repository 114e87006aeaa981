#include "stopping_ramp.hpp"

#include <algorithm>
#include <cmath>

namespace mrroc::edp {

RampStep stopping_ramp_step(std::span<const double> velocity, std::span<double> desired,
                            std::span<double> scratch, const RobotModel& model, double period_s,
                            const ArmKinematics* guard) {
  const std::size_t axes = desired.size();
  double keep = 0.0;  // the common factor for this step's velocities, 0..1
  for (std::size_t i = 0; i < axes; ++i) {
    const double speed = std::abs(velocity[i]);
    if (speed > 0.0) keep = std::max(keep, 1.0 - model.max_acceleration[i] * period_s / speed);
  }
  RampStep out;
  bool inside = true;
  for (std::size_t i = 0; i < axes; ++i) {
    const double v = velocity[i] * keep;
    scratch[i] = desired[i] + v * period_s;
    inside = inside && scratch[i] >= model.lower_limits[i] && scratch[i] <= model.upper_limits[i];
    out.moving = out.moving || v != 0.0;
  }
  if (inside && guard != nullptr) inside = guard->within_limits(scratch.first(axes));
  if (!inside) {
    out.moving = false;
    out.at_limit = true;
    return out;
  }
  std::copy(scratch.begin(), scratch.begin() + static_cast<std::ptrdiff_t>(axes), desired.begin());
  return out;
}

}  // namespace mrroc::edp
