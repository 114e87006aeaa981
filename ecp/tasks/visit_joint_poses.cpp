// Stock ECP task "visit_joint_poses": synchronise the robot, then visit the poses given in the
// config ([robot.ecp.args] poses = [[...], ...], in rad), reporting each pose reached.
#include <fmt/format.h>
#include <fmt/ranges.h>

#include "joint_motion_options.hpp"
#include "mrroc/config/check.hpp"
#include "mrroc/ecp/generators/joint_poses.hpp"
#include "mrroc/ecp/task.hpp"

namespace mrroc::ecp {

class VisitJointPoses : public EcpTask {
 public:
  explicit VisitJointPoses(TaskContext& context) : context_(context) {
    const Params& args = context.args;
    poses_ = args.get_double_rows("poses");
    options_ = joint_motion_options(args, context.servo_period_s);
    args.reject_unread("robot.ecp.args");
    // Validate every pose and option before anything moves, naming where they were written:
    // the options, each pose on its own (arity, joint limits), then the paths between them.
    ConfigErrorList errors;
    const SourceLocation at = args.location_of("poses");
    const RobotModel& model = context.robot.model();
    errors.run(at, [&] { JointPosesGenerator options_only(model, {}, options_); });
    for (std::size_t i = 0; i < poses_.size(); ++i)
      errors.run(
          at, [&] { model.check_joint_limits(poses_[i], fmt::format("pose {}", i + 1).c_str()); });
    if (errors.empty()) errors.run(at, [&] { JointPosesGenerator check(model, poses_, options_); });
    errors.throw_if_any();
  }

  void main_task() override {
    Robot& robot = context_.robot;
    robot.synchronise();
    context_.reporter.info(
        fmt::format("synchronised at [{:.4f}]", fmt::join(robot.image().joints, ", ")));
    for (std::size_t i = 0; i < poses_.size(); ++i) {
      JointPosesGenerator generator(robot.model(), {poses_[i]}, options_);
      Move(robot, {}, generator);
      context_.reporter.info(fmt::format("pose {}/{} reached: joints [{:.4f}] rad", i + 1,
                                         poses_.size(), fmt::join(robot.image().joints, ", ")));
    }
  }

 private:
  TaskContext& context_;
  std::vector<std::vector<double>> poses_;
  JointPosesOptions options_;
};

MRROC_REGISTER_ECP_TASK("visit_joint_poses", VisitJointPoses);

}  // namespace mrroc::ecp
