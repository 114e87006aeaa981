#pragma once
/// @file
/// Kinematics of the IRb-6 (5 axes: column, lower arm, upper arm, wrist pitch, wrist roll):
/// motor <-> joint transmissions, joint/motor limits, the kinematic models (nominal and calibrated
/// link lengths, from the robot's parameters.toml), analytic forward and inverse kinematics, tool
/// and local corrector.
///
/// Conventions (robots/irb6/README.md and irb6.urdf are authoritative):
/// - q = (q0 column, q1 lower_arm, q2 upper_arm, q3 wrist_pitch, q4 wrist_roll) [rad];
///   absolute pitch angles t1 = q1, t2 = q1 + q2 + pi/2, t3 = t2 + q3; a link at absolute pitch
///   t points along (cos t, 0, -sin t) in the column frame (a positive pitch lowers its tip).
/// - Flange frame: origin on the roll axis at d5 from the wrist-pitch axis; z axis = approach
///   direction (roll axis), x axis = -z of the URDF `roll_link`. Flange rotation
///   R = Rz(q0) Ry(t3) Rx(q4) Ry(pi/2); position p = (c0 r, s0 r, d1 - a2 s1 - a3 s2 - d5 s3),
///   r = a2 c1 + a3 c2 + d5 c3 (c_i = cos t_i, s_i = sin t_i).
/// - Synchronisation pose: q = (0, -pi/2, 0, 0, 0) at motor positions
///   (-15.9, -5.0, -8.527, 151.31, 314.665) rad.
///
/// Every function here is allocation-free except when it throws.

#include <array>
#include <cstddef>
#include <numbers>
#include <span>
#include <vector>

#include <Eigen/Geometry>

#include "mrroc/robot/limit_violation.hpp"

namespace mrroc {
struct RobotModel;
}  // namespace mrroc

namespace mrroc::robots::irb6 {

inline constexpr std::size_t kAxes = 5;

/// Joint coordinates q0..q4 [rad].
using JointPosition = std::array<double, kAxes>;
/// Motor shaft angles [rad] (encoder side of the transmissions).
using MotorPosition = std::array<double, kAxes>;

/// Joint names, as in irb6.urdf and irb6.xml.
inline constexpr std::array<const char*, kAxes> kJointNames = {"column", "lower_arm", "upper_arm",
                                                               "wrist_pitch", "wrist_roll"};

namespace detail {
constexpr double deg(double degrees) { return degrees * std::numbers::pi / 180.0; }
}  // namespace detail

/// Joint limits [rad] (the same values as irb6.urdf: -170..170, -130..-50, -25..40, -90..92,
/// -165..168 deg).
inline constexpr JointPosition kJointLowerLimits = {
    detail::deg(-170), detail::deg(-130), detail::deg(-25), detail::deg(-90), detail::deg(-165)};
inline constexpr JointPosition kJointUpperLimits = {
    detail::deg(170), detail::deg(-50), detail::deg(40), detail::deg(92), detail::deg(168)};

/// Motor limits [rad of motor shaft].
inline constexpr MotorPosition kMotorLowerLimits = {-470.0, -110.0, -80.0, -70.0, -80.0};
inline constexpr MotorPosition kMotorUpperLimits = {450.0, 100.0, 100.0, 380.0, 490.0};

/// Motor positions at the synchronisation switches [rad] and the joints there [rad].
inline constexpr MotorPosition kSynchroMotorPositions = {-15.9, -5.0, -8.527, 151.31, 314.665};
inline constexpr JointPosition kSynchroJointPositions = {0.0, -std::numbers::pi / 2, 0.0, 0.0, 0.0};

/// Harmonic-drive transmissions: joint = direction * (motor - motor_sync) / ratio + joint_sync.
inline constexpr double kColumnRatio = 158.0;           ///< motor rad per joint rad
inline constexpr double kWristPitchRatio = 128.0;       ///< motor rad per joint rad
inline constexpr double kWristRollRatio = 128.0 * 0.6;  ///< harmonic 128 x bevel 0.6
inline constexpr double kHarmonicDirection = -1.0;      ///< the same for all three
/// Ball-screw lead [mm per motor revolution].
inline constexpr double kScrewLead = 5.0;

/// Ball screw driving an arm through a linkage triangle. The screw length l [mm] is
/// l = (motor - motor_sync) * kScrewLead / (2 pi) + synchro_length, and the angle theta fed to
/// the linkage satisfies l^2 = s + mu cos(theta) + nu sin(-theta). Of the two triangle solutions
/// the one used is theta = -atan2(nu, mu) - acos((l^2 - s) / hypot(mu, nu)), on which l grows
/// monotonically with theta; it covers the ranges quoted for the machine.
/// The fed angle is q1 for the lower arm and q1 + q2 + pi/2 (the absolute upper-arm pitch t2) for
/// the upper arm; [min_angle, max_angle] is the usable linkage range of that angle.
struct ScrewLinkage {
  double s;               ///< [mm^2]
  double mu;              ///< [mm^2]
  double nu;              ///< [mm^2]
  double synchro_length;  ///< l0: screw length at the synchronisation position [mm]
  double min_angle;       ///< [rad]
  double max_angle;       ///< [rad]
};

/// Lower arm: fed angle q1, linkage range -150..25 deg (the triangle degenerates at about
/// -154.3 and 25.7 deg).
inline constexpr ScrewLinkage kLowerArmScrew = {77895.25, 60902.55,          -29346.68,
                                                220.3374, detail::deg(-150), detail::deg(25)};
/// Upper arm: fed angle q1 + q2 + pi/2, linkage range -45..130 deg (the triangle degenerates at
/// about -49.3 and 130.7 deg). Within the individual joint limits that angle spans -65..80 deg, so
/// the lower bound is a real further limit on (q1, q2).
inline constexpr ScrewLinkage kUpperArmScrew = {77895.25, -44100.0,         -51240.0,
                                                183.8348, detail::deg(-45), detail::deg(130)};

/// Converts `values` (e.g. an instruction's arm vector) to a fixed-size position.
/// @throws CommandError (code edp::error_code::bad_argument) when there are not exactly 5 values
///   ("joint target has 4 values, the IRb-6 has 5 axes"; `what` names the quantity).
std::array<double, kAxes> axes_from_values(std::span<const double> values, const char* what);

/// Joints from motor positions (transmissions above; the wrist-roll joint depends on
/// motor_roll - motor_pitch: q4 = -((m4 - m4_sync) - (m3 - m3_sync)) / kWristRollRatio).
/// The ball-screw maps carry angle offsets chosen so that the synchronisation motor positions
/// give exactly the synchronisation joints: q = q_sync + g(l) - g(l0), g the triangle solution.
/// (With the quoted l0 the triangle alone gives q1 = -pi/2 - 2.6e-9 and t2 = -3.2e-7 rad.)
/// Joint limits are not checked here (see `check_joint_limits`).
/// @throws CommandError (code edp::error_code::out_of_limits) when a screw length has no triangle
///   solution or the resulting fed angle leaves its linkage range, naming the motor, its value
///   [rad] and the limit; (code bad_argument) for a value that is not finite.
JointPosition joints_from_motors(const MotorPosition& motors);

/// Motor positions from joints; the exact inverse of `joints_from_motors`.
/// Motor limits are not checked here (see `check_motor_limits`).
/// @throws CommandError (code edp::error_code::out_of_limits) when q1 or q1 + q2 + pi/2 leaves its
///   linkage range, naming the joint, value [rad] and limit; (code bad_argument) for a value that
///   is not finite.
MotorPosition motors_from_joints(const JointPosition& joints);

/// Checks the joint limits (`kJointLowerLimits`, `kJointUpperLimits`), then the linkage ranges of
/// q1 and of q1 + q2 + pi/2. `what` is the word used in the text ("target", "position", ...).
/// @throws CommandError (code edp::error_code::out_of_limits) such as
///   "joint 2 (upper_arm) target 0.810000 rad exceeds upper limit 0.698132 rad" or
///   "joint 2 (upper_arm) target: q1 + q2 + pi/2 = -0.900000 rad is below the upper-arm linkage
///   limit -0.785398 rad"; (code bad_argument) for a value that is not finite.
void check_joint_limits(const JointPosition& joints, const char* what = "target");

/// The checks of `check_joint_limits` as a value: the first value that is not finite, joint
/// limit (kind joint) or linkage range (kind linkage, axis 1 or 2, value the fed angle q1 or
/// q1 + q2 + pi/2) left. Allocation-free.
LimitViolation joint_limit_violation(const JointPosition& joints) noexcept;

/// Checks `kMotorLowerLimits` / `kMotorUpperLimits`.
/// @throws CommandError (code edp::error_code::out_of_limits) such as
///   "motor 2 (upper_arm) position 101.2 rad exceeds upper limit 100.0 rad" or
///   "motor 0 (column) position -471.5 rad is below lower limit -470.0 rad"; (code bad_argument)
///   for a value that is not finite.
void check_motor_limits(const MotorPosition& motors, const char* what = "position");
/// The checks of `check_motor_limits` as a value (kind motor, or invalid). Allocation-free.
LimitViolation motor_limit_violation(const MotorPosition& motors) noexcept;

/// Link lengths [m] of a kinematic model. They come from the robot's parameters.toml
/// (`kinematic_models`); robots/irb6/parameters.toml gives d1 0.70, a2 0.455, a3 0.67, d5 0.19
/// (nominal, the figures irb6.urdf and irb6.xml were written with) and a2 0.4596, a3 0.6729,
/// d5 0.1903 (calibrated).
struct Irb6Geometry {
  double d1;  ///< column height: base to the lower-arm axis
  double a2;  ///< lower arm
  double a3;  ///< upper arm
  double d5;  ///< wrist-pitch axis to the flange
};

inline constexpr int kNominalModel = 0;
inline constexpr int kCalibratedModel = 1;

/// The kinematic models of a robot model (`RobotModel::link_lengths` of solver "irb6", read from
/// parameters.toml): model 0 the nominal lengths of [robot.kinematics] d1, a2, a3, d5, model 1
/// (when the file has [robot.kinematics.calibrated]) the calibrated ones.
/// @throws ConfigError naming the parameters file when the model has no IRb-6 link lengths
///   (its solver is not "irb6").
std::vector<Irb6Geometry> kinematic_models(const RobotModel& model);

/// Flange frame in the base frame for joints `q` (model only: no corrector, no tool).
/// Equals the KDL chain of irb6.urdf for the nominal geometry.
Eigen::Isometry3d forward_kinematics(const JointPosition& q, const Irb6Geometry& geometry);

/// Tool frame in the base frame: `forward_kinematics(q, geometry) * tool` (`tool` is the tool
/// frame in the flange frame; the default gripper is a translation of 0.25 m along flange z).
Eigen::Isometry3d forward_kinematics(const JointPosition& q, const Irb6Geometry& geometry,
                                     const Eigen::Isometry3d& tool);

/// Largest approach deviation from the arm plane [rad] that `inverse_kinematics` accepts.
inline constexpr double kOrientationTolerance = 1e-6;

/// Result of `inverse_nearest`.
struct NearestSolution {
  JointPosition joints{};
  /// Angle [rad] of the rotation that made the requested orientation reachable (0 if it was).
  double deviation = 0.0;
  /// The reachable frame that `joints` reach (same level as the request: flange, or tool for
  /// `Irb6Kinematics`); its position equals the requested one at the pivot (see below).
  Eigen::Isometry3d frame = Eigen::Isometry3d::Identity();
};

/// Analytic inverse kinematics: joints whose flange frame is `flange`.
///
/// Reachable orientations. A 5-axis arm reaches a 5-dimensional set of frames: the flange origin,
/// its approach axis (flange z), the wrist centre (d5 behind the flange along -z) and the column
/// axis must lie in one vertical plane (the arm plane, at azimuth q0); the rotation about the
/// approach axis is free (wrist roll). The arm plane is the vertical plane through the column axis
/// and the pivot point P = flange origin + pivot * flange z (for a reachable frame that is the
/// plane of the wrist centre). The deviation is the angle between the requested approach
/// direction and that plane; above `orientation_tolerance` the request is refused. Below it, the
/// orientation is first projected (as in `inverse_nearest`), so FK(result) is within
/// `orientation_tolerance` of the request.
///
/// Configuration. Of the up to four solutions (column q0 or q0 + pi, elbow either side) the joint
/// and linkage limits of the IRb-6 leave at most one (the wrist centre stays at least 0.18 m in
/// front of the column axis and q2 + pi/2 is in 65..130 deg); if several were valid, the one
/// nearest `seed` would be taken. A solution joint less than 1e-9 rad outside its limit (round-off
/// of a target at the limit) is put onto the limit. `seed` (normally the current joints) also fixes
/// the column angle when the pivot and the wrist centre are on the column axis, and the approach in
/// `inverse_nearest` when it is perpendicular to the arm plane.
///
/// @param pivot distance [m] along the flange z axis of the point that defines the arm plane.
/// @throws CommandError (code edp::error_code::out_of_limits):
///   "orientation not reachable by a 5-axis arm: approach deviates 0.12 rad from the arm plane
///   (tolerance 1e-06 rad)"; "position not reachable: wrist centre 1.300000 m from the lower-arm
///   axis, the arm reaches 0.215000 .. 1.125000 m"; a solution outside the joint or linkage
///   limits, naming the joint as `check_joint_limits` does (what = "inverse kinematics solution").
///   (code bad_argument) for a frame that is not finite.
JointPosition inverse_kinematics(const Eigen::Isometry3d& flange, const JointPosition& seed,
                                 const Irb6Geometry& geometry,
                                 double orientation_tolerance = kOrientationTolerance,
                                 double pivot = 0.0);

/// Inverse kinematics of the nearest reachable frame: the pivot point (flange origin + pivot *
/// flange z) is kept, and the orientation is turned by the smallest rotation (about an axis through
/// the pivot) that puts the approach direction into the arm plane, i.e. onto its projection on
/// that plane. This rotation's angle is the deviation, and no reachable frame with the same pivot
/// position has a smaller geodesic orientation distance to the request.
/// @throws CommandError as `inverse_kinematics`, except for the orientation.
NearestSolution inverse_nearest(const Eigen::Isometry3d& flange, const JointPosition& seed,
                                const Irb6Geometry& geometry, double pivot = 0.0);

/// The kinematics the EDP uses: a kinematic model, a local corrector and a tool.
///
///     tool frame in the base = corrector * forward_kinematics(q, geometry) * tool
///
/// The local corrector is applied on the base side of the flange pose: it maps the flange frame
/// that the model computes (in the model's base frame) to the flange frame in the base frame the
/// commands use, so it corrects the model's error as seen from the base (identity = no
/// correction). The tool is applied on the flange side. The inverse therefore solves
/// forward_kinematics(q) = corrector^-1 * target * tool^-1, and the arm-plane condition and
/// `inverse_nearest` use the tool origin's projection on the flange z axis as pivot (for a tool
/// along flange z, such as the gripper, the tool point itself is kept).
struct Irb6Kinematics {
  explicit Irb6Kinematics(const Irb6Geometry& model) : geometry(model) {}

  Irb6Geometry geometry;
  Eigen::Isometry3d corrector = Eigen::Isometry3d::Identity();  ///< base side of the flange
  Eigen::Isometry3d tool = Eigen::Isometry3d::Identity();       ///< tool in the flange frame
  double orientation_tolerance = kOrientationTolerance;         ///< [rad]

  /// corrector * forward_kinematics(q, geometry).
  [[nodiscard]] Eigen::Isometry3d flange(const JointPosition& q) const;
  /// corrector * forward_kinematics(q, geometry) * tool.
  [[nodiscard]] Eigen::Isometry3d forward(const JointPosition& q) const;
  /// Joints that put the tool frame at `target`. @throws CommandError as `inverse_kinematics`.
  [[nodiscard]] JointPosition inverse(const Eigen::Isometry3d& target,
                                      const JointPosition& seed) const;
  /// Joints of the nearest reachable tool frame (`frame` is at tool level).
  /// @throws CommandError as `inverse_nearest`.
  [[nodiscard]] NearestSolution inverse_nearest(const Eigen::Isometry3d& target,
                                                const JointPosition& seed) const;
};

}  // namespace mrroc::robots::irb6
