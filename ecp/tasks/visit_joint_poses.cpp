// Stock ECP task "visit_joint_poses": synchronise the robot, then visit the poses given in the
// config ([robot.ecp.args] poses = [[...], ...], in rad), reporting each pose reached.
// Optional arguments beside the motion options (joint_motion_options.hpp):
//   wait_input = 16        binary input line (0..31) that must be on before the first pose
//                          (e.g. a light barrier seeing a part); wait_input_state = false waits
//                          for it to be off; wait_timeout = 60.0 [s] (0: for ever)
//   outputs_at_end = 0x1   binary outputs set after the last pose (SET OUTPUTS)
#include <fmt/format.h>
#include <fmt/ranges.h>

#include <cmath>
#include <optional>

#include "binary_outputs.hpp"
#include "joint_motion_options.hpp"
#include "mrroc/config/check.hpp"
#include "mrroc/ecp/conditions.hpp"
#include "mrroc/ecp/generators/joint_poses.hpp"
#include "mrroc/ecp/task.hpp"

namespace mrroc::ecp {

class VisitJointPoses : public EcpTask {
 public:
  explicit VisitJointPoses(TaskContext& context) : context_(context) {
    const Params& args = context.args;
    // Every argument checked on its own at its own line (a mistake in one does not hide the
    // others), then each pose (arity, joint limits), then the paths between them.
    ConfigErrorList errors;
    const bool have_poses =
        errors.run(args.location_of("poses"), [&] { poses_ = args.get_double_rows("poses"); });
    options_ = joint_motion_options(args, context.servo_period_s, errors);
    if (args.has("wait_input")) {
      errors.run(args.location_of("wait_input"), [&] {
        const std::int64_t line = args.get_int("wait_input");
        if (line < 0 || line > 31)
          throw ConfigError(
              args.location_of("wait_input"),
              fmt::format("'wait_input' = {} is not a binary input line (0..31)", line));
        wait_input_ = static_cast<int>(line);
      });
      errors.run(args.location_of("wait_input_state"),
                 [&] { wait_state_ = args.get_bool("wait_input_state", true); });
      errors.run(args.location_of("wait_timeout"), [&] {
        wait_timeout_ = args.get_double("wait_timeout", 60.0);
        if (!(std::isfinite(wait_timeout_) && wait_timeout_ >= 0.0))
          throw ConfigError(args.location_of("wait_timeout"),
                            fmt::format("'wait_timeout' = {} s must be >= 0 s", wait_timeout_));
      });
    }
    if (args.has("outputs_at_end"))
      errors.run(args.location_of("outputs_at_end"),
                 [&] { outputs_at_end_ = outputs_argument(args, "outputs_at_end"); });
    errors.run(args.location(), [&] { args.reject_unread("robot.ecp.args"); });
    const RobotModel& model = context.robot.model();
    for (std::size_t i = 0; i < poses_.size(); ++i)
      errors.run(args.location_of_row("poses", i), [&] {
        model.check_joint_limits(poses_[i], fmt::format("pose {}", i + 1).c_str());
      });
    if (have_poses && errors.empty())
      errors.run(args.location_of("poses"),
                 [&] { JointPosesGenerator check(model, poses_, options_); });
    errors.throw_if_any();
  }

  void main_task() override {
    Robot& robot = context_.robot;
    robot.synchronise();
    context_.reporter.info(
        fmt::format("synchronised at [{:.4f}]", fmt::join(robot.image().joints, ", ")));
    if (wait_input_) {
      context_.reporter.info(
          fmt::format("waiting for input {} to be {}", *wait_input_, wait_state_ ? "on" : "off"));
      InputCondition input(*wait_input_, wait_state_, wait_timeout_);
      Wait(robot, {}, input);
      context_.reporter.info(fmt::format("input {} {} after {:.2f} s", *wait_input_,
                                         wait_state_ ? "on" : "off", input.waited_s()));
    }
    for (std::size_t i = 0; i < poses_.size(); ++i) {
      JointPosesGenerator generator(robot.model(), {poses_[i]}, options_);
      Move(robot, {}, generator);
      context_.reporter.info(fmt::format("pose {}/{} reached: joints [{:.4f}] rad", i + 1,
                                         poses_.size(), fmt::join(robot.image().joints, ", ")));
    }
    if (outputs_at_end_) {
      set_outputs(robot, *outputs_at_end_, /*get_inputs=*/false);
      context_.reporter.info(fmt::format("outputs set to {:#x}", *outputs_at_end_));
    }
  }

 private:
  TaskContext& context_;
  std::vector<std::vector<double>> poses_;
  JointPosesOptions options_;
  std::optional<int> wait_input_;
  bool wait_state_ = true;
  double wait_timeout_ = 60.0;
  std::optional<std::uint32_t> outputs_at_end_;
};

MRROC_REGISTER_ECP_TASK("visit_joint_poses", VisitJointPoses);

}  // namespace mrroc::ecp
