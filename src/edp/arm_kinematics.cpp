// Registry of arm kinematics; the generic kinematics from the URDF ("urdf") of a robot that names
// no solver, and the joint-only kinematics ("joint-only") of one that has no serial chain.
#include "mrroc/edp/arm_kinematics.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <memory>
#include <string>
#include <utility>

#include "../core/registry.hpp"
#include "mrroc/core/error.hpp"
#include "mrroc/kinematics/urdf_arm.hpp"
#include "mrroc/msg/edp_instruction.hpp"

namespace mrroc::edp {

namespace {

/// Motor = joint, the joint limits of the URDF: the transmission of the robots without their own
/// kinematics class.
class DirectDriveKinematics : public ArmKinematics {
 public:
  explicit DirectDriveKinematics(const RobotModel& model) : model_(model) {}
  std::vector<double> motors_from_joints(std::span<const double> q) const override {
    return {q.begin(), q.end()};
  }
  std::vector<double> joints_from_motors(std::span<const double> m) const override {
    return {m.begin(), m.end()};
  }
  void motors_from_joints(std::span<const double> q, std::span<double> m) const override {
    if (m.size() != q.size())
      throw CommandError(error_code::bad_argument,
                         fmt::format("room for {} motor values, robot '{}' has {} joint values",
                                     m.size(), model_.name, q.size()));
    std::copy(q.begin(), q.end(), m.begin());
  }
  void check_motor_limits(std::span<const double> m, const char* what) const override {
    model_.check_joint_limits(m, what);
  }
  void check_joint_limits(std::span<const double> q, const char* what) const override {
    model_.check_joint_limits(q, what);
  }
  LimitViolation joint_limit_violation(std::span<const double> q) const noexcept override {
    return model_.joint_limit_violation(q);
  }
  LimitViolation motor_limit_violation(std::span<const double> m) const noexcept override {
    return model_.joint_limit_violation(m);
  }
  bool within_limits(std::span<const double> q) const noexcept override {
    return !model_.joint_limit_violation(q);
  }

 protected:
  const RobotModel& model_;
};

/// No Cartesian representations; `why` says why (shown with every refusal).
class JointOnlyKinematics : public DirectDriveKinematics {
 public:
  JointOnlyKinematics(const RobotModel& model, std::string why)
      : DirectDriveKinematics(model), why_(std::move(why)) {}
  std::string name() const override { return "joint-only"; }
  bool cartesian() const override { return false; }
  Eigen::Isometry3d forward(std::span<const double>) const override { unsupported(); }
  std::vector<double> inverse(const Eigen::Isometry3d&, std::span<const double>) const override {
    unsupported();
  }
  int model_count() const override { return 1; }
  int corrector_count() const override { return 1; }
  void select_model(int model_no, int corrector_no) override {
    if (model_no != 0 || corrector_no != 0)
      throw CommandError(error_code::bad_argument,
                         fmt::format("robot '{}' has only kinematic model 0 and corrector 0 "
                                     "(got {} and {})",
                                     model_.name, model_no, corrector_no));
  }
  void set_tool(const Eigen::Isometry3d& tool) override { tool_ = tool; }
  Eigen::Isometry3d tool() const override { return tool_; }

 private:
  [[noreturn]] void unsupported() const {
    throw CommandError(
        error_code::not_supported,
        fmt::format("robot '{}' has no Cartesian kinematics: {}", model_.name, why_));
  }
  std::string why_;
  Eigen::Isometry3d tool_ = Eigen::Isometry3d::Identity();
};

/// Generic Cartesian kinematics from the URDF's serial chain (kinematics::UrdfArm, KDL).
class UrdfKinematics : public DirectDriveKinematics {
 public:
  explicit UrdfKinematics(const RobotModel& model) : DirectDriveKinematics(model), arm_(model) {}
  std::string name() const override { return "urdf"; }
  bool cartesian() const override { return true; }
  Eigen::Isometry3d forward(std::span<const double> q) const override {
    return arm_.forward({q.begin(), q.end()});
  }
  std::vector<double> inverse(const Eigen::Isometry3d& target,
                              std::span<const double> seed) const override {
    return arm_.inverse(target, {seed.begin(), seed.end()});
  }
  int model_count() const override { return arm_.model_count(); }
  int corrector_count() const override { return arm_.corrector_count(); }
  void select_model(int model_no, int corrector_no) override {
    arm_.select(model_no, corrector_no);
    model_no_ = model_no;
    corrector_no_ = corrector_no;
  }
  void set_tool(const Eigen::Isometry3d& tool) override { arm_.set_tool(tool); }
  Eigen::Isometry3d tool() const override { return arm_.tool(); }

 private:
  kinematics::UrdfArm arm_;
};

std::string declared_joint_only(const RobotModel& model) {
  return fmt::format("[robot.kinematics] solver = \"joint-only\" in {}",
                     model.parameters_file().string());
}

::mrroc::detail::Registry<ArmKinematicsFactory>& registry() {
  static ::mrroc::detail::Registry<ArmKinematicsFactory> r("kinematics solver");
  static const bool builtins = [] {
    r.add("urdf", [](const RobotModel& m) { return std::make_unique<UrdfKinematics>(m); });
    r.add("joint-only", [](const RobotModel& m) {
      return std::make_unique<JointOnlyKinematics>(m, declared_joint_only(m));
    });
    return true;
  }();
  (void)builtins;
  return r;
}

}  // namespace

void register_arm_kinematics(const std::string& name, ArmKinematicsFactory factory) {
  registry().add(name, std::move(factory));
}

std::unique_ptr<ArmKinematics> make_arm_kinematics(const RobotModel& model) {
  if (model.kinematics.empty()) {
    // No solver named: the generic kinematics when the URDF has the serial chain of the joints.
    std::string why_not;
    if (kinematics::find_serial_chain(model, why_not))
      return std::make_unique<UrdfKinematics>(model);
    return std::make_unique<JointOnlyKinematics>(
        model, fmt::format("no [robot.kinematics] solver in {}, and no serial chain for the "
                           "generic URDF kinematics: {}",
                           model.parameters_file().string(), why_not));
  }
  ArmKinematicsFactory factory;
  try {
    factory = registry().get(model.kinematics);
  } catch (const ConfigError& e) {
    throw e.at(SourceLocation::whole_file(model.parameters_file().string()));
  }
  return factory(model);
}

}  // namespace mrroc::edp
