// The IRb-6's kinematics for the EDP: the analytic solver and the ball-screw transmission of
// include/mrroc/kinematics/irb6.hpp, the kinematic models of parameters.toml (0: the nominal link
// lengths of [robot.kinematics], 1: [robot.kinematics.calibrated]) and its local correctors.
#include <fmt/format.h>

#include "mrroc/core/error.hpp"
#include "mrroc/edp/arm_kinematics.hpp"
#include "mrroc/kinematics/irb6.hpp"
#include "mrroc/kinematics/pose.hpp"
#include "mrroc/msg/edp_instruction.hpp"

namespace mrroc::robots::irb6 {

class Irb6ArmKinematics : public edp::ArmKinematics {
 public:
  explicit Irb6ArmKinematics(const RobotModel& model)
      : model_(model), models_(checked_models(model)), solver_(models_.front()) {}

  std::string name() const override { return "irb6"; }

  std::vector<double> motors_from_joints(std::span<const double> q) const override {
    const MotorPosition m = robots::irb6::motors_from_joints(axes_from_values(q, "joints"));
    return {m.begin(), m.end()};
  }
  std::vector<double> joints_from_motors(std::span<const double> m) const override {
    const JointPosition q = robots::irb6::joints_from_motors(axes_from_values(m, "motors"));
    return {q.begin(), q.end()};
  }
  void motors_from_joints(std::span<const double> q, std::span<double> m) const override {
    const MotorPosition motors = robots::irb6::motors_from_joints(axes_from_values(q, "joints"));
    if (m.size() != kAxes) (void)axes_from_values(m, "motors");  // throws: the wrong size
    std::copy(motors.begin(), motors.end(), m.begin());
  }
  void check_motor_limits(std::span<const double> m, const char* what) const override {
    robots::irb6::check_motor_limits(axes_from_values(m, what), what);
  }
  void check_joint_limits(std::span<const double> q, const char* what) const override {
    model_.check_joint_limits(q, what);
    robots::irb6::check_joint_limits(axes_from_values(q, what), what);
  }
  LimitViolation joint_limit_violation(std::span<const double> q) const noexcept override {
    if (const LimitViolation v = model_.joint_limit_violation(q)) return v;
    if (q.size() != kAxes)
      return {LimitKind::invalid, 0, static_cast<double>(q.size()), static_cast<double>(kAxes)};
    JointPosition joints{};
    std::copy(q.begin(), q.end(), joints.begin());
    return robots::irb6::joint_limit_violation(joints);
  }
  LimitViolation motor_limit_violation(std::span<const double> m) const noexcept override {
    if (m.size() != kAxes)
      return {LimitKind::invalid, 0, static_cast<double>(m.size()), static_cast<double>(kAxes)};
    MotorPosition motors{};
    std::copy(m.begin(), m.end(), motors.begin());
    return robots::irb6::motor_limit_violation(motors);
  }

  bool within_limits(std::span<const double> q) const noexcept override {
    if (q.size() != kAxes) return false;
    JointPosition joints{};
    std::copy(q.begin(), q.end(), joints.begin());
    // Inside the joint and linkage limits, motors_from_joints does not throw.
    return !robots::irb6::joint_limit_violation(joints) &&
           !robots::irb6::motor_limit_violation(robots::irb6::motors_from_joints(joints));
  }
  bool cartesian() const override { return true; }
  Eigen::Isometry3d forward(std::span<const double> q) const override {
    return solver_.forward(axes_from_values(q, "joints"));
  }
  std::vector<double> inverse(const Eigen::Isometry3d& target,
                              std::span<const double> seed) const override {
    const JointPosition q = solver_.inverse(target, axes_from_values(seed, "seed"));
    return {q.begin(), q.end()};
  }

  int model_count() const override { return static_cast<int>(models_.size()); }
  int corrector_count() const override { return 1 + static_cast<int>(model_.correctors.size()); }
  void select_model(int model_no, int corrector_no) override {
    if (corrector_no < 0 || corrector_no >= corrector_count())
      throw CommandError(edp::error_code::bad_argument,
                         fmt::format("corrector {} is outside 0..{} (0 = none; the others are "
                                     "listed in {}/parameters.toml)",
                                     corrector_no, corrector_count() - 1, model_.folder.string()));
    if (model_no < 0 || model_no >= model_count())
      throw CommandError(
          edp::error_code::bad_argument,
          model_count() > kCalibratedModel
              ? fmt::format("kinematic model {} does not exist for the IRb-6 (0 = nominal, "
                            "1 = calibrated)",
                            model_no)
              : fmt::format("kinematic model {} does not exist for the IRb-6 (0 = nominal; {} "
                            "has no [robot.kinematics.calibrated])",
                            model_no, model_.parameters_file().string()));
    solver_.geometry = models_[static_cast<std::size_t>(model_no)];
    solver_.corrector = Eigen::Isometry3d::Identity();
    if (corrector_no > 0) {
      const auto& c = model_.correctors[static_cast<std::size_t>(corrector_no - 1)];
      solver_.corrector = kinematics::from_values(c, edp::ArmRepresentation::xyz_angle_axis);
    }
    model_no_ = model_no;
    corrector_no_ = corrector_no;
  }

  void set_tool(const Eigen::Isometry3d& tool) override { solver_.tool = tool; }
  Eigen::Isometry3d tool() const override { return solver_.tool; }

 private:
  static std::vector<Irb6Geometry> checked_models(const RobotModel& model) {
    if (model.axes() != kAxes)
      throw ConfigError(
          SourceLocation::whole_file(model.parameters_file().string()),
          fmt::format("irb6 kinematics needs {} axes, the model has {}", kAxes, model.axes()));
    return kinematic_models(model);
  }

  const RobotModel& model_;
  std::vector<Irb6Geometry> models_;  ///< kinematic model i is models_[i]
  Irb6Kinematics solver_;
};

MRROC_REGISTER_ARM_KINEMATICS("irb6", Irb6ArmKinematics);

}  // namespace mrroc::robots::irb6
