// A user's generator, condition, hardware plugin and sensor plugin, compiled with LCM's and the
// TOML parser's headers replaced by ones that stop the compiler (tests/package/CMakeLists.txt):
// the extension points include neither.
#include "mrroc/ecp/conditions.hpp"
#include "mrroc/ecp/generator.hpp"
#include "mrroc/ecp/generators/cartesian_path.hpp"
#include "mrroc/ecp/generators/errors.hpp"
#include "mrroc/ecp/generators/guarded_move.hpp"
#include "mrroc/ecp/generators/interpolation.hpp"
#include "mrroc/ecp/generators/joint_poses.hpp"
#include "mrroc/ecp/generators/motion_profile.hpp"
#include "mrroc/ecp/generators/pass_through.hpp"
#include "mrroc/ecp/generators/planned_motion.hpp"
#include "mrroc/ecp/generators/teach_in.hpp"
#include "mrroc/ecp/generators/trajectory_file.hpp"
#include "mrroc/edp/arm_kinematics.hpp"
#include "mrroc/edp/hardware.hpp"
#include "mrroc/vsp/sensor.hpp"

namespace {

/// Holds the first joint where it is for `steps` macro-steps.
class HoldGenerator : public mrroc::ecp::Generator {
 public:
  explicit HoldGenerator(int steps) : steps_(steps) {}
  bool first_step(mrroc::ecp::RobotImage& robot, const mrroc::ecp::SensorList&) override {
    robot.command.type = mrroc::edp::InstructionType::set;
    robot.command.arm = robot.desired_joints;
    return steps_ > 0;
  }
  bool next_step(mrroc::ecp::RobotImage&, const mrroc::ecp::SensorList&) override {
    return --steps_ > 0;
  }

 private:
  int steps_;
};

}  // namespace

int extension_points_compile() {
  HoldGenerator g(3);
  mrroc::ecp::RobotImage image;
  return g.first_step(image, {}) ? 1 : 0;
}
