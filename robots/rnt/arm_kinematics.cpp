// The RNT's kinematics for the EDP: KDL on the serial-equivalent chain of each kinematic model's
// URDF ([robot.kinematics] models), the parallelogram transmission of
// include/mrroc/kinematics/rnt.hpp with its coupled limit (q1 + q2), and local correctors.
#include <fmt/format.h>

#include "mrroc/core/error.hpp"
#include "mrroc/edp/arm_kinematics.hpp"
#include "mrroc/kinematics/kdl_solver.hpp"
#include "mrroc/kinematics/pose.hpp"
#include "mrroc/kinematics/rnt.hpp"
#include "mrroc/msg/edp_instruction.hpp"

namespace mrroc::robots::rnt {

namespace {
std::array<double, kAxes> axes_of(std::span<const double> v, const char* what) {
  if (v.size() != kAxes)
    throw CommandError(edp::error_code::bad_argument,
                       fmt::format("{} has {} values, the RNT has {} axes", what, v.size(), kAxes));
  std::array<double, kAxes> out{};
  std::copy(v.begin(), v.end(), out.begin());
  return out;
}
}  // namespace

class RntArmKinematics : public edp::ArmKinematics {
 public:
  explicit RntArmKinematics(const RobotModel& model) : model_(model) {
    if (model.axes() != kAxes)
      throw ConfigError(
          SourceLocation::whole_file(model.parameters_file().string()),
          fmt::format("rnt kinematics needs {} axes, the model has {}", kAxes, model.axes()));
    std::vector<std::filesystem::path> files = model.kinematic_models;
    if (files.empty()) files.push_back(model.urdf);
    for (const auto& f : files) solvers_.emplace_back(f, "base_link", "flange");
  }

  std::string name() const override { return "rnt"; }

  std::vector<double> motors_from_joints(std::span<const double> q) const override {
    const MotorPosition m = rnt::motors_from_joints(axes_of(q, "joints"));
    return {m.begin(), m.end()};
  }
  std::vector<double> joints_from_motors(std::span<const double> m) const override {
    const JointPosition q = rnt::joints_from_motors(axes_of(m, "motors"));
    return {q.begin(), q.end()};
  }
  void motors_from_joints(std::span<const double> q, std::span<double> m) const override {
    const MotorPosition motors = rnt::motors_from_joints(axes_of(q, "joints"));
    if (m.size() != kAxes) (void)axes_of(m, "motors");  // throws: the wrong size
    std::copy(motors.begin(), motors.end(), m.begin());
  }
  void check_motor_limits(std::span<const double> m, const char* what) const override {
    rnt::check_motor_limits(axes_of(m, what), what);
  }
  void check_joint_limits(std::span<const double> q, const char* what) const override {
    model_.check_joint_limits(q, what);
    rnt::check_limits(axes_of(q, what), what);  // adds the parallelogram's q1 + q2 range
  }
  LimitViolation joint_limit_violation(std::span<const double> q) const noexcept override {
    if (const LimitViolation v = model_.joint_limit_violation(q)) return v;
    if (q.size() != kAxes)
      return {LimitKind::invalid, 0, static_cast<double>(q.size()), static_cast<double>(kAxes)};
    JointPosition joints{};
    std::copy(q.begin(), q.end(), joints.begin());
    return rnt::limit_violation(joints);
  }
  LimitViolation motor_limit_violation(std::span<const double> m) const noexcept override {
    if (m.size() != kAxes)
      return {LimitKind::invalid, 0, static_cast<double>(m.size()), static_cast<double>(kAxes)};
    MotorPosition motors{};
    std::copy(m.begin(), m.end(), motors.begin());
    return rnt::motor_limit_violation(motors);
  }

  bool within_limits(std::span<const double> q) const noexcept override {
    if (q.size() != kAxes) return false;
    JointPosition joints{};
    std::copy(q.begin(), q.end(), joints.begin());
    return !rnt::limit_violation(joints);  // the joint, motor and parallelogram limits
  }
  bool cartesian() const override { return true; }
  Eigen::Isometry3d forward(std::span<const double> q) const override {
    return corrector_ * solver().forward({q.begin(), q.end()}) * tool_;
  }
  std::vector<double> inverse(const Eigen::Isometry3d& target,
                              std::span<const double> seed) const override {
    const Eigen::Isometry3d flange = corrector_.inverse() * target * tool_.inverse();
    std::vector<double> q = solver().inverse(flange, {seed.begin(), seed.end()});
    check_joint_limits(q, "inverse kinematics solution");
    return q;
  }

  int model_count() const override { return static_cast<int>(solvers_.size()); }
  int corrector_count() const override { return 1 + static_cast<int>(model_.correctors.size()); }
  void select_model(int model_no, int corrector_no) override {
    if (model_no < 0 || model_no >= model_count())
      throw CommandError(edp::error_code::bad_argument,
                         fmt::format("kinematic model {} is outside 0..{} of robot '{}'", model_no,
                                     model_count() - 1, model_.name));
    if (corrector_no < 0 || corrector_no >= corrector_count())
      throw CommandError(edp::error_code::bad_argument,
                         fmt::format("corrector {} is outside 0..{} of robot '{}'", corrector_no,
                                     corrector_count() - 1, model_.name));
    corrector_ = Eigen::Isometry3d::Identity();
    if (corrector_no > 0)
      corrector_ =
          kinematics::from_values(model_.correctors[static_cast<std::size_t>(corrector_no - 1)],
                                  edp::ArmRepresentation::xyz_angle_axis);
    model_no_ = model_no;
    corrector_no_ = corrector_no;
  }

  void set_tool(const Eigen::Isometry3d& tool) override { tool_ = tool; }
  Eigen::Isometry3d tool() const override { return tool_; }

 private:
  const kinematics::KdlSolver& solver() const {
    return solvers_[static_cast<std::size_t>(model_no_)];
  }

  const RobotModel& model_;
  std::vector<kinematics::KdlSolver> solvers_;
  Eigen::Isometry3d corrector_ = Eigen::Isometry3d::Identity();
  Eigen::Isometry3d tool_ = Eigen::Isometry3d::Identity();
};

MRROC_REGISTER_ARM_KINEMATICS("rnt", RntArmKinematics);

}  // namespace mrroc::robots::rnt
