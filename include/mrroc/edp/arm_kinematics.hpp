#pragma once
/// @file
/// What the EDP needs to know about a robot's kinematics to accept every arm representation:
/// the motor <-> joint transmission with its limits, and the forward/inverse kinematics of the
/// tool frame under a selectable kinematic model and local corrector.
///
/// Frames: tool frame = corrector * FK_model(q) * tool, in the robot base frame [m].
/// Used only from the EDP's command thread.

#include <Eigen/Geometry>
#include <functional>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "mrroc/robot/limit_violation.hpp"
#include "mrroc/robot/robot_model.hpp"

namespace mrroc::edp {

class ArmKinematics {
 public:
  virtual ~ArmKinematics() = default;

  [[nodiscard]] virtual std::string name() const = 0;

  /// Motor shaft angles [rad] from joint coordinates, and back.
  [[nodiscard]] virtual std::vector<double> motors_from_joints(std::span<const double> q) const = 0;
  [[nodiscard]] virtual std::vector<double> joints_from_motors(std::span<const double> m) const = 0;
  /// The motor shaft angles [rad] of joints `q`, written into `m` (as many values as axes):
  /// allocation-free for a `q` that passes joint_limit_violation. @throws CommandError as the
  /// other overload does (bad_argument also for an `m` of the wrong size).
  virtual void motors_from_joints(std::span<const double> q, std::span<double> m) const = 0;
  /// @throws CommandError (out_of_limits) naming motor, value, unit and limit.
  virtual void check_motor_limits(std::span<const double> m, const char* what) const = 0;
  /// Joint limits including any the linkage adds. @throws CommandError (out_of_limits).
  virtual void check_joint_limits(std::span<const double> q, const char* what) const = 0;
  /// The checks of check_joint_limits and check_motor_limits as values: the first limit `q` (or
  /// `m`) leaves, in the order those report them, or LimitKind::none. Allocation-free; the text
  /// of a refusal comes from check_joint_limits / check_motor_limits, called only on a failure
  /// (edp::check_straight_path does that).
  [[nodiscard]] virtual LimitViolation joint_limit_violation(
      std::span<const double> q) const noexcept = 0;
  [[nodiscard]] virtual LimitViolation motor_limit_violation(
      std::span<const double> m) const noexcept = 0;
  /// True when `q` is inside every joint, linkage and motor limit. Thread-safe; used by the
  /// servo loop's stopping ramp, so it does not allocate for a `q` inside the limits.
  [[nodiscard]] virtual bool within_limits(std::span<const double> q) const noexcept = 0;

  /// True when FRAME / XYZ_EULER_ZYZ / XYZ_ANGLE_AXIS are available.
  [[nodiscard]] virtual bool cartesian() const = 0;
  /// Tool frame of joints `q`. @throws CommandError (not_supported) without Cartesian kinematics.
  [[nodiscard]] virtual Eigen::Isometry3d forward(std::span<const double> q) const = 0;
  /// Joints putting the tool frame at `target`, nearest to `seed`.
  /// @throws CommandError (out_of_limits) when unreachable, naming why.
  [[nodiscard]] virtual std::vector<double> inverse(const Eigen::Isometry3d& target,
                                                    std::span<const double> seed) const = 0;

  /// Kinematic models (0 = nominal) and local correctors (0 = none) this robot offers.
  [[nodiscard]] virtual int model_count() const = 0;
  [[nodiscard]] virtual int corrector_count() const = 0;
  /// @throws CommandError (bad_argument) naming the number and the range.
  virtual void select_model(int model_no, int corrector_no) = 0;
  [[nodiscard]] int model_no() const { return model_no_; }
  [[nodiscard]] int corrector_no() const { return corrector_no_; }

  virtual void set_tool(const Eigen::Isometry3d& tool) = 0;
  [[nodiscard]] virtual Eigen::Isometry3d tool() const = 0;

 protected:
  int model_no_ = 0;
  int corrector_no_ = 0;
};

/// Kinematics named by [robot.kinematics] solver ("irb6", ...; built in: "urdf", "joint-only");
/// none named: "urdf" (kinematics/urdf_arm.hpp) given the joints' serial chain, else joint-only.
/// @throws ConfigError naming the unknown kinematics and the file, or the URDF's problem ("urdf").
std::unique_ptr<ArmKinematics> make_arm_kinematics(const RobotModel& model);

using ArmKinematicsFactory = std::function<std::unique_ptr<ArmKinematics>(const RobotModel&)>;
void register_arm_kinematics(const std::string& name, ArmKinematicsFactory factory);

namespace detail {
struct ArmKinematicsRegistrar {
  ArmKinematicsRegistrar(const char* name, ArmKinematicsFactory f) {
    register_arm_kinematics(name, std::move(f));
  }
};
}  // namespace detail

}  // namespace mrroc::edp

/// Registers kinematics under a name: `MRROC_REGISTER_ARM_KINEMATICS("irb6", Irb6ArmKinematics)`;
/// the class is constructed from a `const RobotModel&`.
#define MRROC_REGISTER_ARM_KINEMATICS(NAME, CLASS)                                         \
  static const ::mrroc::edp::detail::ArmKinematicsRegistrar mrroc_arm_kinematics_##CLASS { \
    NAME, [](const ::mrroc::RobotModel& m) {                                               \
      return std::unique_ptr<::mrroc::edp::ArmKinematics>(new CLASS(m));                   \
    }                                                                                      \
  }
