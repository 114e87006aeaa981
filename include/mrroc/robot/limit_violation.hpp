#pragma once
/// @file
/// Which limit a position leaves, as a value: the result of the allocation-free limit checks
/// (RobotModel::joint_limit_violation, the kinematics' joint_limit_violation and
/// motor_limit_violation, edp::find_path_limit_violation). The text of a refusal is formatted from
/// it only when a check fails.

#include <cstddef>
#include <cstdint>

namespace mrroc {

enum class LimitKind : std::uint8_t {
  none,     ///< inside every limit checked
  invalid,  ///< a value that is not a finite number (axis, value), or the wrong number of values
            ///< (value: how many were given, limit: how many the robot has)
  joint,    ///< a joint limit [rad | m]
  linkage,  ///< a limit a linkage puts on a joint (value: the linkage's angle [rad])
  motor,    ///< a motor limit [rad]
};

struct LimitViolation {
  LimitKind kind = LimitKind::none;
  std::size_t axis = 0;  ///< the joint's or motor's index
  double value = 0.0;    ///< the value beyond the limit
  double limit = 0.0;    ///< the limit it is beyond: above it when value > limit, else below
  /// In a path check: the interpolation step (1..steps) that leaves the limit; 0: the target
  /// itself, checked first.
  int step = 0;

  [[nodiscard]] explicit operator bool() const { return kind != LimitKind::none; }
  [[nodiscard]] bool above() const { return value > limit; }
};

}  // namespace mrroc
