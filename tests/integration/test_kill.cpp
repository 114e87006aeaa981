// Fault injection by kill -9 in the middle of a motion, with the documented reactions
// (docs/hil.md, "Processes that die"). The process set is configs/demo-irb6-can.toml: the EDP
// drives emulated CiA 402 drives, so the drives' own reactions can be seen too.
//   EDP killed      -> every drive misses its SYNCs and faults (EMCY 0x8130) within 50 ms: the
//                      brakes hold the arm; the launcher stops the set, exit 4.
//   emulator killed -> the EDP finds its drives silent within 10 cycles (20 ms) and holds; the
//                      task fails or the launcher stops the set (exit 1 or 4).
//   ECP killed      -> the EDP gets no next macro-step and ramps the arm down to standstill;
//                      the launcher stops the set, exit 4.
//   MP killed       -> the task has failed: launcher exit 1; every other process stops cleanly.
// In every case no process is left behind and nothing else crashes.
#include <gtest/gtest.h>

#include <chrono>
#include <regex>
#include <string>

#include "launch_helpers.hpp"

namespace {

using namespace mrroc::test;

std::string demo() { return std::string(MRROC_SOURCE_DIR) + "/configs/demo-irb6-can.toml"; }

}  // namespace

TEST(Kill, EdpKilledMidMotionDrivesBrakeThemselves) {
  const LaunchRun r = launch_and_kill(demo(), "edp/irb6", "pose 1/3 reached", std::chrono::milliseconds(300));
  EXPECT_EQ(r.exit_code, 4) << r.output;
  EXPECT_TRUE(has(r.output, "edp/irb6 ended while the task was running (code 137)")) << r.output;
  // Every drive of the arm noticed the missing SYNCs and faulted (brake on).
  for (const char* axis : {"'column'", "'lower_arm'", "'upper_arm'", "'wrist_pitch'", "'wrist_roll'"})
    EXPECT_TRUE(std::regex_search(
        r.output, std::regex(std::string("emu: error: robot 'irb6' axis [0-9] ") + axis +
                             ".*EMCY 0x8130 heartbeat / life guard error")))
        << axis << "\n" << r.output;
  expect_nothing_left();
}

TEST(Kill, EmulatorKilledMidMotionTheEdpHolds) {
  const LaunchRun r = launch_and_kill(demo(), "emu", "pose 1/3 reached", std::chrono::milliseconds(300));
  EXPECT_TRUE(r.exit_code == 1 || r.exit_code == 4) << r.output;
  EXPECT_TRUE(std::regex_search(r.output, std::regex("edp/irb6.*silent: no TPDO for 10 cycles")))
      << r.output;
  EXPECT_TRUE(has(r.output, "the robot is held")) << r.output;
  expect_nothing_left();
}

TEST(Kill, EcpKilledMidMotionTheEdpRampsDown) {
  const LaunchRun r = launch_and_kill(demo(), "ecp/irb6", "pose 1/3 reached", std::chrono::milliseconds(300));
  EXPECT_EQ(r.exit_code, 4) << r.output;
  EXPECT_TRUE(has(r.output, "ecp/irb6 ended while the task was running (code 137)")) << r.output;
  expect_nothing_left();
}

TEST(Kill, MpKilledTheTaskFailsAndEverythingStops) {
  const LaunchRun r = launch_and_kill(demo(), "mp", "pose 1/3 reached", std::chrono::milliseconds(300));
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_TRUE(has(r.output, "task FAILED (mp exit code 137)")) << r.output;
  for (const char* p : {"emu", "edp/irb6", "ecp/irb6", "srp"})
    EXPECT_TRUE(has(r.output, std::string(p) + " exited with code 0")) << p << "\n" << r.output;
  expect_nothing_left();
}
