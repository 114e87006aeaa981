#pragma once
/// @file
/// The limit check of a macro-step's straight joint-space path, the one both sides use: the EDP's
/// command interpreter before it queues a SET (CommandInterpreter::check_path) and the ECP's
/// planned motions before they send one (detail::check_macro_step_path), so that a plan that
/// passes in the ECP is not refused by the EDP (for the same kinematic model and tool).
///
/// The target's joint limits are checked first; then every interpolation step k = 1..steps,
/// q_k = from + (to - from) k / steps, against the joint limits (with any a linkage adds) and the
/// motor limits of its motor positions. Allocation-free while the path passes (up to
/// kPathCheckMaxAxes axes; more take two buffers per call): at the largest motion_steps, 100000,
/// that is the check of every SET. The text of a refusal is formatted only when it fails, by the
/// kinematics' own checks (check_joint_limits / check_motor_limits) at the step that fails.

#include <cstddef>
#include <span>

#include "mrroc/edp/arm_kinematics.hpp"
#include "mrroc/robot/limit_violation.hpp"

namespace mrroc::edp {

/// Axes a path check holds on the stack.
inline constexpr std::size_t kPathCheckMaxAxes = 16;

/// The first limit the straight path from `from` to `to` in `steps` interpolation steps leaves
/// (LimitViolation::step: 0 for the target's joint limits, else the step), or LimitKind::none.
/// `from` and `to` hold one value per axis; `steps` >= 1.
[[nodiscard]] LimitViolation find_path_limit_violation(const ArmKinematics& kinematics,
                                                       std::span<const double> from,
                                                       std::span<const double> to, int steps);

/// The same check, throwing the kinematics' refusal for the first limit the path leaves, with
/// `what` "target" or "<step_name> k of <steps>" ("step 412 of 1000" in the EDP, "servo step 412
/// of 1000" in the ECP): "joint 2 (upper_arm) step 412 of 1000 0.700100 rad exceeds upper limit
/// 0.698132 rad".
/// @throws CommandError (out_of_limits; bad_argument for a value that is not a finite number).
void check_straight_path(const ArmKinematics& kinematics, std::span<const double> from,
                         std::span<const double> to, int steps, const char* step_name);

/// Throws the refusal for `violation`, a result of find_path_limit_violation for the same path.
/// @throws CommandError, always.
[[noreturn]] void throw_path_limit_violation(const ArmKinematics& kinematics,
                                             std::span<const double> from,
                                             std::span<const double> to, int steps,
                                             const char* step_name,
                                             const LimitViolation& violation);

}  // namespace mrroc::edp
