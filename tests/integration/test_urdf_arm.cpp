// End-to-end: ARM6 (robots/arm6), a robot added with its URDF, MJCF and parameters.toml only,
// moved in FRAME representation by a real process set (configs/demo-arm6.toml: SRP, EDP with
// MuJoCo and the generic URDF kinematics, ECP writing "MRROC" with the stock Cartesian task, MP)
// inside a private network namespace. Judged by the motion, as test_continuity does: the ECP
// commanded FRAME poses, the EDP solved them with the "urdf" kinematics, the pen tip stayed on the
// strokes, the robot ended at the last stroke's lifted end, no EDP brought the robot to a
// standstill for want of a macro-step, and every commanded joint velocity and acceleration stayed
// within the robot's limits (from the states the EDP broadcast).
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <mutex>
#include <regex>
#include <string>
#include <vector>

#include "launch_helpers.hpp"
#include "mrroc/comm/bus.hpp"
#include "mrroc/comm/codec.hpp"
#include "mrroc/config/process_set.hpp"
#include "mrroc/edp/arm_kinematics.hpp"
#include "mrroc/robot/robot_model.hpp"
#include "state_watch.hpp"

namespace fs = std::filesystem;
using namespace mrroc;
using mrroc::test::StateWatch;

namespace {

const fs::path kSource = MRROC_SOURCE_DIR;

/// Counts the SET ARM instructions the ECP sent the EDP, by representation.
class ArmCommands {
 public:
  ArmCommands(comm::Bus& bus, const std::string& robot) {
    bus.subscribe<ArmCommands*>(channels::edp_command(robot), &ArmCommands::dispatch, this);
  }
  static void dispatch(const lcm::ReceiveBuffer* buffer, const std::string&, ArmCommands* self) {
    mrroc_lcm::edp_instruction_t msg;
    if (!comm::detail::decode_received(buffer, msg)) return;
    const edp::Instruction in = comm::decode(msg);
    if ((in.type != edp::InstructionType::set && in.type != edp::InstructionType::set_get) ||
        (in.set & edp::item::arm) == 0)
      return;
    std::lock_guard lock(self->mutex_);
    if (in.set_arm_type == edp::ArmRepresentation::frame) {
      ++self->frame_;
    } else {
      ++self->other_;
    }
  }
  int frame() {
    std::lock_guard lock(mutex_);
    return frame_;
  }
  int other() {
    std::lock_guard lock(mutex_);
    return other_;
  }

 private:
  std::mutex mutex_;
  int frame_ = 0;
  int other_ = 0;
};

int count_of(const std::string& text, const std::string& what) {
  int n = 0;
  for (std::size_t at = text.find(what); at != std::string::npos; at = text.find(what, at + 1)) ++n;
  return n;
}

}  // namespace

TEST(UrdfArm, WritesInFrameRepresentationSmoothlyAndEndsAtTheLastStroke) {
  const std::string file = (kSource / "configs/demo-arm6.toml").string();
  const ProcessSetConfig config = load_process_set(file);
  ASSERT_EQ(config.robots.size(), 1U);
  const RobotModel model = load_robot_model(config.robots[0].model_dir);
  ASSERT_TRUE(model.kinematics.empty()) << "ARM6 must rely on the generic kinematics";
  const double period_s = config.robots[0].edp.servo_period_s;

  comm::Bus bus(config.lcm_url);
  StateWatch states(bus, "arm6");
  ArmCommands commands(bus, "arm6");
  bus.start();
  const test::LaunchRun run = test::launch_and_kill(file);
  bus.stop();
  ASSERT_EQ(run.exit_code, 0) << run.output;

  // The EDP used the generic URDF kinematics; the ECP moved the arm in FRAME representation.
  EXPECT_NE(run.output.find("kinematics 'urdf'"), std::string::npos) << run.output;
  EXPECT_GT(commands.frame(), 100) << run.output;
  std::printf("SET ARM commands: %d in FRAME, %d in other representations\n", commands.frame(),
              commands.other());

  // The task's own check: the pen tip within the tolerance of the strokes.
  const Params& args = config.robots[0].ecp.args;
  const double tolerance = args.get_double("tolerance", 0.0);
  std::smatch m;
  const std::regex report(R"(engraved 'MRROC': ([0-9]+) strokes, ([0-9]+) cutting samples, )"
                          R"(cutter tip within ([0-9.]+) mm)");
  ASSERT_TRUE(std::regex_search(run.output, m, report)) << run.output;
  EXPECT_GT(std::stoi(m[2]), 200) << run.output;
  EXPECT_LE(std::stod(m[3]), tolerance * 1e3) << run.output;
  std::printf("pen tip within %s mm of the strokes (%s samples)\n", m[3].str().c_str(),
              m[2].str().c_str());

  // No standstill for want of a macro-step.
  EXPECT_EQ(count_of(run.output, "no next macro-step from the ECP in time"), 0) << run.output;

  // Velocities and accelerations within the limits, over the whole run.
  const test::MotionCheck motion = test::check_commanded_motion(states.history(), model, period_s);
  EXPECT_GT(motion.states, 200) << "too few states from the EDP";
  std::printf("%d states: velocity up to %.0f %%, acceleration up to %.0f %% of the limits\n",
              motion.states, motion.worst_velocity_share * 100,
              motion.worst_acceleration_share * 100);

  // The reached pose: the pen tip at the lifted end of the last stroke of "C" (the stroke font's
  // arc from 45 to 315 degrees ends at (0.5 + 0.5 cos 315, 0.5 + 0.5 sin 315) of the letter's
  // box), the pen still pointing down.
  const std::vector<double> origin = args.get_doubles("origin");
  const double height = args.get_double("letter_height", 0);
  const double width = args.get_double("letter_width", 0);
  const double spacing = args.get_double("spacing", 0);
  const double lift = args.get_double("lift", 0);
  const double pen = args.get_double("cutter", 0);
  const double u = 0.5 + 0.5 * std::cos(315.0 * M_PI / 180.0);
  const double v = 0.5 + 0.5 * std::sin(315.0 * M_PI / 180.0);
  const Eigen::Vector3d expected(origin[0] - v * height,
                                 origin[1] + 4 * (width + spacing) + u * width, origin[2] + lift);
  const auto last = states.last();
  ASSERT_EQ(last.q.size(), model.axes());
  auto kinematics = edp::make_arm_kinematics(model);
  Eigen::Isometry3d tool = Eigen::Isometry3d::Identity();
  tool.translation() = Eigen::Vector3d(0, 0, pen);
  kinematics->set_tool(tool);
  const Eigen::Isometry3d reached = kinematics->forward(last.q);
  EXPECT_LT((reached.translation() - expected).norm(), 1e-3)
      << "reached (" << reached.translation().transpose() << "), expected (" << expected.transpose()
      << ")";
  EXPECT_LT((reached.linear().col(2) - Eigen::Vector3d(0, 0, -1)).norm(), 5e-3);
  std::printf("final pen tip %.2f mm from the end of the last stroke\n",
              (reached.translation() - expected).norm() * 1e3);
  test::expect_nothing_left();
}
