#pragma once
/// @file
/// Stock generator: point-to-point interpolation in joint or motor coordinates through a list of
/// waypoints, with a trapezoidal or quintic time scaling. All axes are synchronised (they follow
/// one time scaling, so they start and finish together); the robot is at rest at every waypoint.

#include <vector>

#include "mrroc/core/time.hpp"
#include "mrroc/ecp/generators/motion_profile.hpp"
#include "mrroc/ecp/generators/planned_motion.hpp"

namespace mrroc::ecp {

/// Options of `InterpolationGenerator`. Units follow the representation: JOINT rad (or m for a
/// prismatic joint), MOTOR rad of the motor shaft.
struct InterpolationOptions {
  /// JOINT or MOTOR (the coordinates interpolated and commanded).
  edp::ArmRepresentation representation = edp::ArmRepresentation::joint;
  ProfileShape profile = ProfileShape::quintic;
  /// Fractions (0, 1] of the default limits (below). Not applied to explicit limits.
  double velocity_scale = 0.5;
  double acceleration_scale = 0.5;
  /// Explicit per-axis limits [unit/s], [unit/s^2]; empty: the defaults, which are the model's
  /// max_velocity / max_acceleration for JOINT and, for MOTOR, those times the transmission
  /// ratio |dm_i/dq_i| of each axis at the motion's start (central finite differences of
  /// ArmKinematics::motors_from_joints).
  std::vector<double> max_velocity;
  std::vector<double> max_acceleration;
  int motion_steps = 10;                         ///< servo steps per macro-step (2..1000)
  double servo_period_s = kDefaultServoPeriodS;  ///< the EDP's servo period [s]
};

/// A pose to reach, and how.
struct Waypoint {
  std::vector<double> position;  ///< one value per axis, in the generator's representation
  /// Duration of the segment ending here [s]; 0: as fast as the limits allow. A duration the
  /// limits do not allow is refused. A segment of zero length with a duration is a dwell.
  double duration_s = 0.0;
  /// (0, 1]: this segment runs at `velocity_scale` times the limits' velocity and its square
  /// times their acceleration (the same motion, slowed down by 1 / velocity_scale).
  double velocity_scale = 1.0;
  /// True: `position` is a displacement from the previous waypoint (the start, for the first).
  bool relative = false;
};

/// Absolute waypoints at full speed, one per pose.
std::vector<Waypoint> to_waypoints(const std::vector<std::vector<double>>& poses);

/// Interpolates from the robot's current (desired) pose through every waypoint.
///
/// Checks before the first command (the constructor and first_step throw; nothing moves):
/// - sizes, finite values, options;
/// - every macro-step target and the joint-space path the EDP interpolates to it (each servo
///   step) against the joint, linkage and motor limits (ArmKinematics);
/// - the joint velocities and accelerations per macro-step against the model's max_velocity and
///   max_acceleration. In MOTOR coordinates the nonlinear and coupled transmissions can make a
///   joint faster than its motor limit suggests; such a segment is slowed down until every joint
///   is within its limits (a segment with an explicit duration is refused instead).
class InterpolationGenerator : public PlannedMotionGenerator {
 public:
  /// @throws CommandError (bad_argument: wrong size, value not finite; out_of_limits: an absolute
  ///   waypoint outside the joint or motor limits), `Error` for options out of range.
  InterpolationGenerator(const RobotModel& model, std::vector<Waypoint> waypoints,
                         InterpolationOptions options = {});

  [[nodiscard]] const InterpolationOptions& options() const { return options_; }
  [[nodiscard]] const std::vector<Waypoint>& waypoints() const { return waypoints_; }

 protected:
  [[nodiscard]] MotionPlan make_plan(const std::vector<double>& start_joints) const override;

 private:
  void limits_at(const std::vector<double>& joints, std::vector<double>& max_velocity,
                 std::vector<double>& max_acceleration) const;

  std::vector<Waypoint> waypoints_;
  InterpolationOptions options_;
};

}  // namespace mrroc::ecp
