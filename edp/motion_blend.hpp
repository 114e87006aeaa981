#pragma once
/// @file
/// How the EDP moves through a macro-step without exceeding a joint's acceleration limit.
///
/// A macro-step ends exactly at its target after its `steps` servo steps (the paper's
/// semantics), but the velocity never jumps: each joint accelerates uniformly for the first half
/// of the macro-step and uniformly again for the second half, from the velocity v0 the previous
/// macro-step ended with to an end velocity v1 that the EDP chooses. With u the macro-step's mean
/// velocity and T its duration, the two accelerations are (4u - 3 v0 - v1) / T and
/// (v0 + 3 v1 - 4u) / T and the velocity at half time is 2u - (v0 + v1) / 2.
///
/// v1 is 0 when the macro-step promises no successor (value_in_step_no >= steps): the robot comes
/// to rest exactly at its target. Otherwise the EDP looks at the macro-steps queued behind it (the
/// lookahead; at most 8 of them), works out backwards which end velocities still let all of them,
/// down to a final rest, stay within the limits, and picks the one nearest to the mean of this
/// macro-step's and its successor's mean velocities (its own, when no successor is queued yet).
/// No motion that starts at v0 and covers the macro-step's distance in T stays below
/// 2 |u - v0| / T; a macro-step that
/// cannot be joined within a joint's acceleration and velocity limits (or would pass a joint limit
/// between its ends) is refused before it starts.
///
/// Pure functions, allocation-free (they run in the servo thread).

#include <cstddef>
#include <span>

#include "macro_step_queue.hpp"
#include "mrroc/core/time.hpp"
#include "mrroc/robot/robot_model.hpp"

namespace mrroc::edp {

/// What a macro-step needs to know to be planned.
struct BlendInput {
  const AxisArray* start = nullptr;     ///< where it starts (the previous end) [rad | m]
  const AxisArray* velocity = nullptr;  ///< the velocity it starts with [rad/s | m/s]
  const MacroStep* step = nullptr;      ///< target, steps, value_in_step_no
  /// The macro-steps queued behind it, oldest first (at most MacroStepQueue::kCapacity).
  std::span<const MacroStep* const> following;
  double period_s = kDefaultServoPeriodS;
  bool after_ramp = false;  ///< it starts where a stopping ramp left the robot (for the message)
};

enum class BlendRefusal { none, velocity, acceleration, limit };

/// Chooses the end velocities (written into `end_velocity`) or explains in `why` (a
/// NUL-terminated text naming joint, value, unit and limit) why the macro-step is refused.
BlendRefusal plan_blend(const BlendInput& in, const RobotModel& model, std::size_t axes,
                        AxisArray& end_velocity, std::span<char> why);

/// Position at fraction s (0..1) of a macro-step of duration T from p0 (velocity v0) to p1
/// (velocity v1), accelerating uniformly in each half.
inline double blend_position(double p0, double p1, double v0, double v1, double duration_s,
                             double s) {
  const double u = (p1 - p0) / duration_s;
  const double vm = 2.0 * u - 0.5 * (v0 + v1);
  const double half = 0.5 * duration_s;
  const double t = s * duration_s;
  if (t <= half) return p0 + 0.5 * (v0 + (v0 + (vm - v0) * t / half)) * t;
  const double pm = p0 + 0.5 * (v0 + vm) * half;
  const double r = t - half;
  return pm + 0.5 * (vm + (vm + (v1 - vm) * r / half)) * r;
}

/// The two uniform accelerations of a macro-step of duration T from p0 (velocity v0) to p1
/// (velocity v1): in its first half and in its second half [unit/s^2].
struct BlendAccelerations {
  double first = 0.0;
  double second = 0.0;
};
inline BlendAccelerations blend_accelerations(double p0, double p1, double v0, double v1,
                                              double duration_s) {
  const double u = (p1 - p0) / duration_s;
  return {(4.0 * u - 3.0 * v0 - v1) / duration_s, (v0 + 3.0 * v1 - 4.0 * u) / duration_s};
}

/// Shortest rest-to-rest macro-step (in servo steps) that moves `distance` within the velocity
/// and acceleration limits: T >= max(2 sqrt(|d| / a), 2 |d| / v).
int shortest_rest_to_rest_steps(double distance, double max_velocity, double max_acceleration,
                                double period_s);

}  // namespace mrroc::edp
