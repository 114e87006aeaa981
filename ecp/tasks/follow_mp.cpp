// Stock ECP task "follow_mp": synchronises the robot and terminates; from then on the ECP follows
// the MP's NEXT_POSE and NEXT_STATE commands (tight and loose coordination).
#include <fmt/format.h>
#include <fmt/ranges.h>

#include "binary_outputs.hpp"
#include "mrroc/ecp/task.hpp"

namespace mrroc::ecp {

class FollowMp : public EcpTask {
 public:
  explicit FollowMp(TaskContext& context) : context_(context) {
    context.args.reject_unread("robot.ecp.args");
  }
  void main_task() override {
    context_.robot.synchronise();
    context_.reporter.info(fmt::format("synchronised at [{:.4f}]; following the MP",
                                       fmt::join(context_.robot.image().joints, ", ")));
  }

 private:
  TaskContext& context_;
};

MRROC_REGISTER_ECP_TASK("follow_mp", FollowMp);

/// Stock ECP task "set_outputs": SET OUTPUTS (args: outputs = <bits>), e.g. a gripper valve.
class SetOutputs : public EcpTask {
 public:
  explicit SetOutputs(TaskContext& context)
      : context_(context), outputs_(outputs_argument(context.args, "outputs")) {
    context.args.reject_unread("set_outputs arguments");
  }
  void main_task() override {
    set_outputs(context_.robot, outputs_, /*get_inputs=*/true);
    // The inputs as the EDP read them in the cycle before the outputs changed.
    context_.reporter.info(fmt::format("outputs set to {:#x}; inputs {:#x}", outputs_,
                                       context_.robot.image().inputs.value_or(0)));
  }

 private:
  TaskContext& context_;
  std::uint32_t outputs_;
};

MRROC_REGISTER_ECP_TASK("set_outputs", SetOutputs);

}  // namespace mrroc::ecp
