#pragma once
/// @file
/// Transmissions of the RNT (6 axes: waist, shoulder, elbow, wrist pitch, wrist yaw, wrist roll),
/// a documented approximation of the prototype serial-parallel robot (robots/rnt/README.md is
/// authoritative for every number).
///
/// Three levels of coordinates:
/// - joints q [rad]: the serial-equivalent chain of rnt.urdf; q2 (elbow) is the forearm angle
///   relative to the upper arm;
/// - actuator (link-side drive) angles a = C q [rad]: what the drives turn before the gears. The
///   shoulder and elbow are driven through a closed parallelogram: the elbow drive turns the crank
///   relative to the base, so a2 = q1 + q2 (absolute forearm pitch); all other a_i = q_i;
/// - motor shaft angles m = G a [rad]: G = diag(kGearRatios) (the sign is the motor's direction),
///   zero where the actuator angle is zero.
/// `C` and `G` are also in robots/rnt/parameters.toml ([robot.transmission]), which the MuJoCo EDP
/// plugin reads; the tests check that both agree.
///
/// Every function here is allocation-free except when it throws.

#include <array>
#include <cstddef>
#include <numbers>

#include "mrroc/robot/limit_violation.hpp"

namespace mrroc::robots::rnt {

inline constexpr std::size_t kAxes = 6;

/// Joint coordinates q0..q5 [rad].
using JointPosition = std::array<double, kAxes>;
/// Link-side drive angles a0..a5 [rad] (a = C q).
using ActuatorPosition = std::array<double, kAxes>;
/// Motor shaft angles [rad] (encoder side of the transmissions).
using MotorPosition = std::array<double, kAxes>;

/// Joint names, as in rnt.urdf, rnt.xml (actuator names) and parameters.toml.
inline constexpr std::array<const char*, kAxes> kJointNames = {
    "waist", "shoulder", "elbow", "wrist_pitch", "wrist_yaw", "wrist_roll"};

namespace detail {
constexpr double deg(double degrees) { return degrees * std::numbers::pi / 180.0; }
}  // namespace detail

/// Nominal lengths [m] (rnt.urdf, rnt.xml and parameters.toml [robot.kinematics]).
inline constexpr double kD1 = 0.60;     ///< base to the shoulder axis
inline constexpr double kA2 = 0.50;     ///< upper arm: shoulder axis to elbow axis
inline constexpr double kA3 = 0.50;     ///< forearm: elbow axis to the wrist centre
inline constexpr double kD6 = 0.10;     ///< wrist centre to the flange
inline constexpr double kCrank = 0.15;  ///< parallelogram crank = forearm lever behind the elbow
inline constexpr double kCutterLength = 0.15;  ///< flange to the cutter tip (tool frame), along z

/// Joint limits [rad] (the same values as rnt.urdf: -160..160, -45..80, -70..70, -120..120,
/// -80..80, -170..170 deg).
inline constexpr JointPosition kJointLowerLimits = {detail::deg(-160), detail::deg(-45),
                                                    detail::deg(-70),  detail::deg(-120),
                                                    detail::deg(-80),  detail::deg(-170)};
inline constexpr JointPosition kJointUpperLimits = {detail::deg(160), detail::deg(80),
                                                    detail::deg(70),  detail::deg(120),
                                                    detail::deg(80),  detail::deg(170)};

/// Coupling C (a = C q), row by row: the parallelogram row a2 = q1 + q2.
inline constexpr std::array<std::array<double, kAxes>, kAxes> kCoupling = {{
    {1.0, 0.0, 0.0, 0.0, 0.0, 0.0},
    {0.0, 1.0, 0.0, 0.0, 0.0, 0.0},
    {0.0, 1.0, 1.0, 0.0, 0.0, 0.0},
    {0.0, 0.0, 0.0, 1.0, 0.0, 0.0},
    {0.0, 0.0, 0.0, 0.0, 1.0, 0.0},
    {0.0, 0.0, 0.0, 0.0, 0.0, 1.0},
}};

/// Gear ratios [motor rad per actuator rad]; the sign is the motor's direction.
inline constexpr MotorPosition kGearRatios = {-160.0, 160.0, 160.0, -100.0, 100.0, -80.0};

/// Motor limits [rad of motor shaft]. Motor 2 (elbow) bounds the absolute forearm pitch
/// q1 + q2 to -1.03125 .. 1.90625 rad (-59.1 .. 109.2 deg); the others lie just outside
/// gear ratio x joint limits, so that the joint limits act first.
inline constexpr MotorPosition kMotorLowerLimits = {-450.0, -130.0, -165.0, -210.0, -140.0, -240.0};
inline constexpr MotorPosition kMotorUpperLimits = {450.0, 225.0, 305.0, 210.0, 140.0, 240.0};

/// Joints at the synchronisation switches [rad]: upper arm vertical, forearm horizontal, tool
/// pointing down; and the motor positions there [rad].
inline constexpr JointPosition kSynchroJointPositions = {0.0, 0.0, 0.0, std::numbers::pi / 2,
                                                         0.0, 0.0};
inline constexpr MotorPosition kSynchroMotorPositions = {
    0.0, 0.0, 0.0, -100.0 * std::numbers::pi / 2, 0.0, 0.0};

/// a = C q.
ActuatorPosition actuators_from_joints(const JointPosition& joints);
/// q = C^-1 a (q2 = a2 - a1).
JointPosition joints_from_actuators(const ActuatorPosition& actuators);

/// Motor positions from joints: m = G C q. Motor limits are not checked here.
/// @throws CommandError (code edp::error_code::bad_argument) for a value that is not finite.
MotorPosition motors_from_joints(const JointPosition& joints);

/// Joints from motor positions: q = C^-1 G^-1 m; the exact inverse of `motors_from_joints` (up to
/// rounding). Joint limits are not checked here.
/// @throws CommandError (code edp::error_code::bad_argument) for a value that is not finite.
JointPosition joints_from_motors(const MotorPosition& motors);

/// Checks `kMotorLowerLimits` / `kMotorUpperLimits`. `what` is the word used in the text.
/// @throws CommandError (code edp::error_code::out_of_limits) such as
///   "motor 2 (elbow) position 305.5 rad exceeds upper limit 305.0 rad" or
///   "motor 0 (waist) position -451.0 rad is below lower limit -450.0 rad"; (code bad_argument)
///   for a value that is not finite.
void check_motor_limits(const MotorPosition& motors, const char* what = "position");
/// The checks of `check_motor_limits` as a value (kind motor, or invalid). Allocation-free.
LimitViolation motor_limit_violation(const MotorPosition& motors) noexcept;

/// Checks the joint limits, then the motor limits of `motors_from_joints(joints)` (which adds the
/// parallelogram's limit on the absolute forearm pitch q1 + q2).
/// @throws CommandError (code edp::error_code::out_of_limits) such as
///   "joint 2 (elbow) target 1.300000 rad exceeds upper limit 1.221730 rad" or
///   "motor 2 (elbow) target 320.0 rad exceeds upper limit 305.0 rad (absolute forearm pitch
///   shoulder + elbow = 2.000000 rad, limit 1.906250 rad)"; (code bad_argument) for a value
///   that is not finite.
void check_limits(const JointPosition& joints, const char* what = "target");
/// The checks of `check_limits` as a value: the first value that is not finite, joint limit
/// (kind joint) or motor limit (kind motor, the parallelogram's included) left. Allocation-free.
LimitViolation limit_violation(const JointPosition& joints) noexcept;

}  // namespace mrroc::robots::rnt
