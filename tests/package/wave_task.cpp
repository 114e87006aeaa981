// An ECP task written outside the mrroc tree: the robot synchronises and waves its column
// `waves` times by `amplitude` rad around the synchronisation pose, with the stock generator.
#include <fmt/format.h>

#include "mrroc/ecp/generators/joint_poses.hpp"
#include "mrroc/ecp/task.hpp"

class Wave : public mrroc::ecp::EcpTask {
 public:
  explicit Wave(mrroc::ecp::TaskContext& context)
      : context_(context),
        waves_(context.args.get_int("waves", 2)),
        amplitude_(context.args.get_double("amplitude", 0.3)) {
    context.args.reject_unread("robot.ecp.args");
  }

  void main_task() override {
    auto& robot = context_.robot;
    robot.synchronise();
    const std::vector<double> home = robot.model().synchro_joint_positions;
    std::vector<std::vector<double>> poses;
    for (std::int64_t i = 0; i < waves_; ++i) {
      for (double side : {1.0, -1.0}) {
        std::vector<double> q = home;
        q[0] += side * amplitude_;
        poses.push_back(q);
      }
    }
    poses.push_back(home);
    mrroc::ecp::JointPosesOptions options;
    options.servo_period_s = context_.servo_period_s;
    mrroc::ecp::JointPosesGenerator generator(robot.model(), poses, options);
    mrroc::ecp::Move(robot, {}, generator);
    context_.reporter.info(fmt::format("waved {} times", waves_));
  }

 private:
  mrroc::ecp::TaskContext& context_;
  std::int64_t waves_;
  double amplitude_;
};

MRROC_REGISTER_ECP_TASK("wave", Wave);
