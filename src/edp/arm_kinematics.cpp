// Registry of arm kinematics, and the joint-only kinematics of robots that declare none.
#include "mrroc/edp/arm_kinematics.hpp"

#include <fmt/format.h>

#include "../core/registry.hpp"
#include "mrroc/core/error.hpp"
#include "mrroc/msg/edp_instruction.hpp"

namespace mrroc::edp {

namespace {

::mrroc::detail::Registry<ArmKinematicsFactory>& registry() {
  static ::mrroc::detail::Registry<ArmKinematicsFactory> r("kinematics solver");
  return r;
}

/// Motor = joint; no Cartesian representations.
class JointOnlyKinematics : public ArmKinematics {
 public:
  explicit JointOnlyKinematics(const RobotModel& model) : model_(model) {}
  std::string name() const override { return "joint-only"; }
  std::vector<double> motors_from_joints(std::span<const double> q) const override {
    return {q.begin(), q.end()};
  }
  std::vector<double> joints_from_motors(std::span<const double> m) const override {
    return {m.begin(), m.end()};
  }
  void check_motor_limits(std::span<const double> m, const char* what) const override {
    model_.check_joint_limits({m.begin(), m.end()}, what);
  }
  void check_joint_limits(std::span<const double> q, const char* what) const override {
    model_.check_joint_limits({q.begin(), q.end()}, what);
  }
  bool within_limits(std::span<const double> q) const noexcept override {
    if (q.size() != model_.axes()) return false;
    for (std::size_t i = 0; i < q.size(); ++i)
      if (!(q[i] >= model_.lower_limits[i] && q[i] <= model_.upper_limits[i])) return false;
    return true;
  }
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
    throw CommandError(error_code::not_supported,
                       fmt::format("robot '{}' declares no Cartesian kinematics "
                                   "([robot.kinematics] solver in {}/parameters.toml)",
                                   model_.name, model_.folder.string()));
  }
  const RobotModel& model_;
  Eigen::Isometry3d tool_ = Eigen::Isometry3d::Identity();
};

}  // namespace

void register_arm_kinematics(const std::string& name, ArmKinematicsFactory factory) {
  registry().add(name, std::move(factory));
}

std::unique_ptr<ArmKinematics> make_arm_kinematics(const RobotModel& model) {
  if (model.kinematics.empty()) return std::make_unique<JointOnlyKinematics>(model);
  ArmKinematicsFactory factory;
  try {
    factory = registry().get(model.kinematics);
  } catch (const ConfigError& e) {
    throw e.at(SourceLocation::whole_file(model.parameters_file().string()));
  }
  return factory(model);
}

}  // namespace mrroc::edp
