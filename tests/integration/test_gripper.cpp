// A robot with a device, end to end: configs/gripper-irb6.toml run as real processes (MP, ECP,
// EDP with the `mujoco` plugin simulating the IRb-6 with its two-finger gripper and a part on a
// table, SRP). The ECP's task drives the robot class Gripper (ecp/tasks/gripper.hpp) through SET
// and GET DEVICE. Judged by the physical outcome the EDP measured (the gripper holds the part
// with its opening equal to the part's width, still holds it after the lift, is open at the end)
// and by the motion (no standstill for want of a macro-step, commanded joint velocities and
// accelerations within their limits in every state the EDP broadcast once synchronised).
#include <gtest/gtest.h>

#include <cstdio>
#include <filesystem>
#include <regex>
#include <string>

#include "launch_helpers.hpp"
#include "mrroc/robot/robot_model.hpp"
#include "state_watch.hpp"

namespace fs = std::filesystem;
using namespace mrroc;
using mrroc::test::LaunchRun;
using mrroc::test::StateWatch;

namespace {

const fs::path kSource = MRROC_SOURCE_DIR;
constexpr double kPartWidth = 0.04;       // across the fingers, robots/irb6/irb6_gripper.xml [m]
constexpr double kWidthTolerance = 1e-3;  // contact softness and the pads' tilt [m]
constexpr double kOpenWidth = 0.08;       // the fingers' widest opening [m]

/// The opening [m] the task reported after `what` ("holding the part", ...), -1 if missing.
double opening_after(const std::string& output, const std::string& what) {
  std::smatch m;
  const std::regex line(what + ": opening ([0-9.]+) m");
  return std::regex_search(output, m, line) ? std::stod(m[1]) : -1.0;
}

}  // namespace

TEST(Gripper, PicksThePartLiftsItStillHoldingAndPutsItBack) {
  const std::string file = (kSource / "configs/gripper-irb6.toml").string();
  const RobotModel model = load_robot_model(kSource / "robots/irb6");
  comm::Bus bus(comm::kDefaultLcmUrl);
  bus.start();
  StateWatch states(bus, "irb6");
  const LaunchRun run = mrroc::test::launch_and_kill(file);
  bus.stop();
  ASSERT_EQ(run.exit_code, 0) << run.output;

  const double held = opening_after(run.output, "holding the part");
  const double lifted = opening_after(run.output, "lifted, still holding");
  const double released = opening_after(run.output, "put back and released");
  EXPECT_NEAR(held, kPartWidth, kWidthTolerance) << run.output;
  EXPECT_NEAR(lifted, kPartWidth, kWidthTolerance) << run.output;
  EXPECT_NEAR(released, kOpenWidth, kWidthTolerance) << run.output;
  EXPECT_TRUE(mrroc::test::has(run.output, "holding no")) << run.output;
  std::printf("opening holding %.5f m, after the lift %.5f m, released %.5f m\n", held, lifted,
              released);

  EXPECT_FALSE(mrroc::test::has(run.output, "no next macro-step from the ECP in time"))
      << run.output;
  // Every synchronised state: commanded velocities and accelerations within the limits, and the
  // arm did move (the task's moves run at half the limits).
  const mrroc::test::MotionCheck motion =
      mrroc::test::check_commanded_motion(states.history(), model, 0.002);
  EXPECT_GT(motion.states, 150) << "too few synchronised states";
  EXPECT_GT(motion.worst_velocity_share, 0.2);
  std::printf("%d states: worst velocity %.2f, worst acceleration %.2f of the limits\n",
              motion.states, motion.worst_velocity_share, motion.worst_acceleration_share);
  mrroc::test::expect_nothing_left();
}
