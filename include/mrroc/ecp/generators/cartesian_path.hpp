#pragma once
/// @file
/// Stock generator: straight lines and circular arcs of the tool frame in the robot's base frame,
/// with the orientation interpolated by slerp (spherical linear interpolation of quaternions),
/// under linear and angular velocity and acceleration limits. Commands are absolute Cartesian poses
/// (FRAME by default), so the EDP solves the inverse kinematics; the generator solves it too, for
/// every macro-step target before the first command, to refuse a path the arm cannot follow.
///
/// 5-axis arms (IRb-6): only frames whose approach axis lies in the arm plane are reachable, so a
/// path must keep it there: e.g. lines and arcs in a vertical plane through the column axis with
/// orientation changes about the pitch axis or the approach axis, or arcs about the column axis
/// with `rotate_orientation`. Other paths are refused, naming the first macro-step that leaves the
/// reachable set.

#include <cmath>
#include <cstdint>
#include <vector>

#include <Eigen/Geometry>

#include "mrroc/core/time.hpp"
#include "mrroc/ecp/generators/motion_profile.hpp"
#include "mrroc/ecp/generators/planned_motion.hpp"

namespace mrroc::ecp {

/// Options of `CartesianPathGenerator`.
struct CartesianOptions {
  ProfileShape profile = ProfileShape::quintic;
  double max_linear_velocity = 0.1;       ///< tool frame origin [m/s]
  double max_linear_acceleration = 0.5;   ///< [m/s^2]
  double max_angular_velocity = 0.5;      ///< tool frame orientation [rad/s]
  double max_angular_acceleration = 2.0;  ///< [rad/s^2]
  /// Fractions (0, 1] of the model's max joint velocity / acceleration that the joint motion of
  /// every macro-step must respect (mean velocity over the macro-step, and its change per
  /// macro-step duration); a path violating them (typically near a singularity) is refused.
  double joint_velocity_scale = 1.0;
  double joint_acceleration_scale = 1.0;
  /// FRAME, XYZ_ANGLE_AXIS or XYZ_EULER_ZYZ (absolute) for the commands.
  edp::ArmRepresentation representation = edp::ArmRepresentation::frame;
  /// Tool frame in the flange frame, kinematic model and local corrector the path is planned
  /// with. With `set_tool_and_model` the first command SETs them in the EDP too, so that the EDP
  /// solves the same inverse kinematics; without it they must equal the EDP's current settings.
  Eigen::Isometry3d tool = Eigen::Isometry3d::Identity();
  int kinematic_model_no = 0;
  int corrector_no = 0;
  bool set_tool_and_model = true;
  int motion_steps = 10;                         ///< servo steps per macro-step (2..1000)
  double servo_period_s = kDefaultServoPeriodS;  ///< the EDP's servo period [s]
};

/// One piece of a Cartesian path, starting where the previous one ends (the first one at the
/// tool frame of the robot's current desired joints). Positions in the base frame [m].
struct CartesianSegment {
  enum class Kind : std::int8_t {
    line,         ///< straight line to `end` (position and orientation, slerp)
    line_by,      ///< straight line by `point` (a displacement), orientation kept
    arc_through,  ///< circular arc from the start through `point` to `end`'s position (slerp)
    arc_about     ///< rotation of the start by `angle` about the axis through `point`
  };

  /// Straight line to the tool frame `end`; the orientation is slerped from the start's.
  static CartesianSegment line_to(const Eigen::Isometry3d& end);
  /// Straight line by `displacement` [m] in the base frame; constant orientation.
  static CartesianSegment line_by(const Eigen::Vector3d& displacement);
  /// Three-point arc: the circle through the start, `via` and `end`'s position, from the start
  /// through `via` to `end` (less than a full turn); the orientation is slerped from the start's
  /// to `end`'s. The three positions must not be collinear.
  static CartesianSegment arc_through(const Eigen::Vector3d& via, const Eigen::Isometry3d& end);
  /// Arc about the axis through `centre` along `axis` (any length but 0), by `angle` [rad]
  /// (right-hand rule about `axis`, |angle| <= 2 pi). The radius is the start's distance from the
  /// axis (not 0). `rotate_orientation`: the orientation turns with the arc (as if the tool were
  /// fixed to a turntable); otherwise it stays constant.
  static CartesianSegment arc_about(const Eigen::Vector3d& centre, const Eigen::Vector3d& axis,
                                    double angle, bool rotate_orientation = false);

  Kind kind = Kind::line;
  Eigen::Isometry3d end = Eigen::Isometry3d::Identity();
  Eigen::Vector3d point = Eigen::Vector3d::Zero();  ///< displacement, via point or centre [m]
  Eigen::Vector3d axis = Eigen::Vector3d::UnitZ();
  double angle = 0.0;  ///< [rad]
  bool rotate_orientation = false;
  /// Duration of the segment [s]; 0: as fast as the limits allow. A duration the limits do not
  /// allow is refused. A segment of zero length with a duration is a dwell.
  double duration_s = 0.0;
  /// (0, 1]: velocity limits times this, acceleration limits times its square.
  double velocity_scale = 1.0;
};

/// A circle arc in space: p(s) = centre + Rot(normal, s * angle) * (start - centre), s in [0, 1].
struct CircleArc {
  Eigen::Vector3d centre = Eigen::Vector3d::Zero();
  Eigen::Vector3d normal = Eigen::Vector3d::UnitZ();  ///< unit
  Eigen::Vector3d start = Eigen::Vector3d::Zero();
  double radius = 0.0;  ///< [m]
  double angle = 0.0;   ///< [rad]

  /// The arc from `start` through `via` to `end`: normal = (via - start) x (end - start)
  /// normalised, angle in (0, 2 pi). @throws CommandError (bad_argument) when the points are
  /// (nearly) collinear or coincide.
  static CircleArc through(const Eigen::Vector3d& start, const Eigen::Vector3d& via,
                           const Eigen::Vector3d& end);
  [[nodiscard]] Eigen::Vector3d at(double s) const;
  [[nodiscard]] double length() const { return radius * std::abs(angle); }
};

/// Executes a list of Cartesian segments, each from rest to rest.
///
/// Checks before the first command (first_step throws CommandError naming the segment, the
/// macro-step, and the joint and value where one is involved; nothing moves):
/// - inverse kinematics of every macro-step target (seeded with the previous one, as the EDP
///   does): reachable, joints within the joint and linkage limits;
/// - the joint-space path the EDP interpolates to each target, servo step by servo step, within
///   the joint and motor limits;
/// - joint velocity (joint change per macro-step / macro-step duration) and acceleration (change
///   of that velocity per macro-step duration, from rest and to rest) within the model's limits
///   times joint_velocity_scale / joint_acceleration_scale.
class CartesianPathGenerator : public PlannedMotionGenerator {
 public:
  /// @throws CommandError (not_supported) when the robot has no Cartesian kinematics,
  ///   (bad_argument) for a malformed segment; `Error` for options out of range.
  CartesianPathGenerator(const RobotModel& model, std::vector<CartesianSegment> segments,
                         CartesianOptions options = {});

  [[nodiscard]] const CartesianOptions& options() const { return options_; }

  /// The tool frame of `joints` with the generator's tool, model and corrector.
  [[nodiscard]] Eigen::Isometry3d forward(const std::vector<double>& joints) const;

 protected:
  [[nodiscard]] MotionPlan make_plan(const std::vector<double>& start_joints) const override;

 private:
  std::vector<CartesianSegment> segments_;
  CartesianOptions options_;
};

}  // namespace mrroc::ecp
