#include "mrroc/ecp/generators/motion_profile.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>

#include "mrroc/core/error.hpp"

namespace mrroc::ecp {

namespace {
// Peak velocity and acceleration of the quintic scaling for a unit move in unit time.
constexpr double kQuinticPeakVelocity = 1.875;
constexpr double kQuinticPeakAcceleration = 5.773502691896258;  // 10 / sqrt(3)

void check_limits(double max_velocity, double max_acceleration) {
  if (!(std::isfinite(max_velocity) && max_velocity > 0.0))
    throw Error(fmt::format("motion profile: velocity limit {} 1/s is not a positive number",
                            max_velocity));
  if (!(std::isfinite(max_acceleration) && max_acceleration > 0.0))
    throw Error(fmt::format("motion profile: acceleration limit {} 1/s^2 is not a positive number",
                            max_acceleration));
}

double quintic(double tau) { return tau * tau * tau * (10.0 + tau * (-15.0 + 6.0 * tau)); }
double quintic_rate(double tau) { return 30.0 * tau * tau * (1.0 - tau) * (1.0 - tau); }
}  // namespace

const char* to_string(ProfileShape shape) {
  switch (shape) {
    case ProfileShape::trapezoidal: return "TRAPEZOIDAL";
    case ProfileShape::quintic: return "QUINTIC";
  }
  return "?";
}

MotionProfile MotionProfile::fastest(ProfileShape shape, double max_velocity,
                                     double max_acceleration) {
  check_limits(max_velocity, max_acceleration);
  if (shape == ProfileShape::quintic) {
    const double duration = std::max(kQuinticPeakVelocity / max_velocity,
                                     std::sqrt(kQuinticPeakAcceleration / max_acceleration));
    return {shape, duration, 0.0, 0.0};
  }
  // Trapezoid for a unit distance: a cruise phase exists when the ramps to the velocity limit
  // cover less than the distance (v^2 / a < 1); otherwise a triangle with peak sqrt(a).
  if (max_velocity * max_velocity / max_acceleration < 1.0)
    return {shape, 1.0 / max_velocity + max_velocity / max_acceleration, max_velocity,
            max_acceleration};
  const double peak = std::sqrt(max_acceleration);
  return {shape, 2.0 / peak, peak, max_acceleration};
}

MotionProfile MotionProfile::with_duration(ProfileShape shape, double max_velocity,
                                           double max_acceleration, double duration) {
  const MotionProfile fast = fastest(shape, max_velocity, max_acceleration);
  if (!std::isfinite(duration) || duration < fast.duration() * (1.0 - 1e-12))
    throw Error(
        fmt::format("motion profile: duration {} s is shorter than the {:.6f} s the "
                    "limits allow",
                    duration, fast.duration()));
  duration = std::max(duration, fast.duration());
  if (shape == ProfileShape::quintic) return {shape, duration, 0.0, 0.0};
  // The same shape, slower: velocity times k, acceleration times k^2 (a triangle stays a
  // triangle, a trapezoid keeps the share of its cruise phase).
  const double k = fast.duration() / duration;
  return {shape, duration, fast.cruise_velocity_ * k, fast.acceleration_ * k * k};
}

double MotionProfile::cruise_duration() const {
  if (shape_ == ProfileShape::quintic) return 0.0;
  const double cruise = duration_ - 2.0 * cruise_velocity_ / acceleration_;
  return cruise > 1e-9 * duration_ ? cruise : 0.0;  // a triangle, up to rounding
}

double MotionProfile::peak_velocity() const {
  if (shape_ == ProfileShape::quintic) return kQuinticPeakVelocity / duration_;
  return cruise_velocity_;
}

double MotionProfile::peak_acceleration() const {
  if (shape_ == ProfileShape::quintic) return kQuinticPeakAcceleration / (duration_ * duration_);
  return acceleration_;
}

double MotionProfile::position(double t) const {
  if (t <= 0.0) return 0.0;
  if (t >= duration_) return 1.0;
  if (shape_ == ProfileShape::quintic) return quintic(t / duration_);
  const double ramp = cruise_velocity_ / acceleration_;
  if (t < ramp) return 0.5 * acceleration_ * t * t;
  const double remaining = duration_ - t;
  if (remaining < ramp) return 1.0 - 0.5 * acceleration_ * remaining * remaining;
  return 0.5 * acceleration_ * ramp * ramp + cruise_velocity_ * (t - ramp);
}

double MotionProfile::velocity(double t) const {
  if (t <= 0.0 || t >= duration_) return 0.0;
  if (shape_ == ProfileShape::quintic) return quintic_rate(t / duration_) / duration_;
  const double ramp = cruise_velocity_ / acceleration_;
  if (t < ramp) return acceleration_ * t;
  const double remaining = duration_ - t;
  if (remaining < ramp) return acceleration_ * remaining;
  return cruise_velocity_;
}

}  // namespace mrroc::ecp
