#pragma once
/// @file
/// Time scalings s(t) of a point-to-point move along a path parameter s from 0 to 1, starting and
/// ending at rest. Multi-axis generators express their per-axis limits as limits on s (an axis
/// moving by d has velocity d * ds/dt), so every axis follows the same s(t) and all of them finish
/// together.

#include <cstdint>

namespace mrroc::ecp {

/// Shape of a time scaling.
enum class ProfileShape : std::int8_t {
  /// Constant acceleration, cruise at the velocity limit, constant deceleration ("trapezoid");
  /// a short move never reaches the velocity limit and has no cruise phase ("triangle").
  /// Fastest under velocity and acceleration limits; the acceleration jumps.
  trapezoidal = 1,
  /// s = 10 tau^3 - 15 tau^4 + 6 tau^5 (tau = t / T): velocity and acceleration continuous and
  /// zero at both ends; slower than the trapezoid under the same limits (peak velocity 1.875 / T,
  /// peak acceleration 5.7735 / T^2).
  quintic = 2
};

/// Name of a shape ("TRAPEZOIDAL", "QUINTIC").
const char* to_string(ProfileShape shape);

/// One time scaling s(t), t in [0, duration()] [s], s in [0, 1].
class MotionProfile {
 public:
  /// The shortest profile whose |ds/dt| <= max_velocity [1/s] and |d2s/dt2| <= max_acceleration
  /// [1/s^2]. @throws Error when a limit is not a positive finite number.
  static MotionProfile fastest(ProfileShape shape, double max_velocity, double max_acceleration);

  /// The fastest profile stretched in time to last exactly `duration` [s]: the same shape with
  /// velocities times k and accelerations times k^2, k = fastest duration / `duration` (a
  /// triangle stays a triangle; a trapezoid keeps the share of its cruise phase).
  /// @throws Error when a limit is not a positive finite number or `duration` is shorter than
  ///   `fastest(...).duration()` (the text names both durations).
  static MotionProfile with_duration(ProfileShape shape, double max_velocity,
                                     double max_acceleration, double duration);

  [[nodiscard]] ProfileShape shape() const { return shape_; }
  /// [s]
  [[nodiscard]] double duration() const { return duration_; }
  /// Time spent at constant velocity [s] (trapezoid; 0 for a triangle and for the quintic).
  [[nodiscard]] double cruise_duration() const;
  /// Largest ds/dt [1/s] and |d2s/dt2| [1/s^2] of the profile.
  [[nodiscard]] double peak_velocity() const;
  [[nodiscard]] double peak_acceleration() const;

  /// s(t), clamped to [0, 1] outside [0, duration()].
  [[nodiscard]] double position(double t) const;
  /// ds/dt [1/s] (0 outside [0, duration()]).
  [[nodiscard]] double velocity(double t) const;

 private:
  MotionProfile(ProfileShape shape, double duration, double cruise_velocity, double acceleration)
      : shape_(shape),
        duration_(duration),
        cruise_velocity_(cruise_velocity),
        acceleration_(acceleration) {}

  ProfileShape shape_;
  double duration_;
  double cruise_velocity_;  ///< trapezoid: the velocity after the acceleration phase
  double acceleration_;     ///< trapezoid: |d2s/dt2| of the ramps
};

}  // namespace mrroc::ecp
