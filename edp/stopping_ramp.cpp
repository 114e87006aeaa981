#include "stopping_ramp.hpp"

#include <algorithm>
#include <cmath>

#include "macro_step_queue.hpp"

namespace mrroc::edp {

bool move_within_limits(std::span<const double> velocity, double duration_s,
                        std::span<double> desired, std::span<double> scratch,
                        const RobotModel& model, const ArmKinematics* guard) {
  const std::size_t axes = desired.size();
  bool inside = true;
  for (std::size_t i = 0; i < axes; ++i) {
    scratch[i] = desired[i] + velocity[i] * duration_s;
    inside = inside && scratch[i] >= model.lower_limits[i] && scratch[i] <= model.upper_limits[i];
  }
  if (inside && guard != nullptr) inside = guard->within_limits(scratch.first(axes));
  if (!inside) return false;
  std::copy(scratch.begin(), scratch.begin() + static_cast<std::ptrdiff_t>(axes), desired.begin());
  return true;
}

RampStep stopping_ramp_step(std::span<const double> velocity, std::span<double> desired,
                            std::span<double> scratch, const RobotModel& model, double period_s,
                            const ArmKinematics* guard) {
  const std::size_t axes = desired.size();
  double keep = 0.0;  // the common factor for this step's velocities, 0..1
  for (std::size_t i = 0; i < axes; ++i) {
    const double speed = std::abs(velocity[i]);
    if (speed > 0.0) keep = std::max(keep, 1.0 - model.max_acceleration[i] * period_s / speed);
  }
  AxisArray kept{};  // this step's velocities
  RampStep out;
  for (std::size_t i = 0; i < axes; ++i) {
    kept[i] = velocity[i] * keep;
    out.moving = out.moving || kept[i] != 0.0;
  }
  if (!move_within_limits(std::span<const double>(kept.data(), axes), period_s, desired, scratch,
                          model, guard)) {
    out.moving = false;
    out.at_limit = true;
  }
  return out;
}

}  // namespace mrroc::edp
