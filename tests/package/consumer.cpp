// Uses the installed mrroc: loads a robot model and plans joint poses with a stock generator.
#include <cstdio>

#include "mrroc/ecp/generators/joint_poses.hpp"
#include "mrroc/robot/robot_model.hpp"

int main(int argc, char** argv) {
  if (argc != 2) return 2;
  const mrroc::RobotModel model = mrroc::load_robot_model(argv[1]);
  mrroc::ecp::JointPosesGenerator generator(model, {{0.1, -1.4, 0.1, 0.1, 0.1}});
  mrroc::ecp::RobotImage image;
  image.desired_joints = model.synchro_joint_positions;
  int steps = 0;
  if (generator.first_step(image, {})) {
    do {
      image.desired_joints = image.command.arm;
      ++steps;
    } while (generator.next_step(image, {}));
  }
  std::printf("robot %s: %zu axes, %d macro-steps\n", model.name.c_str(), model.axes(), steps);
  return steps > 0 ? 0 : 1;
}
