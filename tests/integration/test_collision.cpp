// The EDP's collision guard in a running process set (MP, ECP, EDP with MuJoCo, SRP, launcher,
// real LCM in a private network namespace): a SET ARM whose path would hit a fixed object of
// the cell ([[collision.object]]) is refused before the robot moves, and the task gets error
// code 16 (collision) with both bodies, the distance, the clearance and the servo step.
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <future>
#include <numbers>
#include <regex>
#include <string>

#include "launch_helpers.hpp"
#include "mrroc/comm/bus.hpp"
#include "mrroc/config/process_set.hpp"
#include "state_watch.hpp"

namespace fs = std::filesystem;
using namespace mrroc;
using namespace mrroc::test;

namespace {

constexpr const char* kUrl = "udpm://239.255.76.67:7667?ttl=0";

/// One IRb-6 (MuJoCo plugin) with a box at (0.6, 0.6, 1.155): at a column angle of 45 degrees
/// its horizontal upper arm and wrist pass through it. The ECP (test task "single_set") sends one
/// SET ARM JOINT turning the column by 90 degrees from the synchronisation pose in 2 s.
std::string write_config(const fs::path& dir) {
  fs::create_directories(dir);
  const fs::path file = dir / "collision.toml";
  std::ofstream(file) << "[system]\nname = \"collision\"\nlcm_url = \"" << kUrl << "\"\n\n"
                      << "[mp]\ntask = \"start_and_wait\"\n\n"
                      << "[collision]\nclearance = 0.02\n"
                      << "[[collision.object]]\nname = \"box\"\nsize = [0.05, 0.05, 0.05]\n"
                      << "pos = [0.6, 0.6, 1.155]\n\n"
                      << "[[robot]]\nname = \"irb6\"\nmodel = \"" << MRROC_SOURCE_DIR
                      << "/robots/irb6\"\n[robot.edp]\nplugin = \"mujoco\"\n"
                      << "[robot.ecp]\ntask = \"single_set\"\nlibrary = \"" << MRROC_TEST_TASKS
                      << "\"\n[robot.ecp.args]\ntarget = [1.5707963267948966, "
                         "-1.5707963267948966, 0.0, 0.0, 0.0]\nmotion_steps = 1000\n";
  return file.string();
}

}  // namespace

TEST(Collision, TheEdpRefusesASetIntoAFixedObjectBeforeTheRobotMoves) {
  const fs::path dir =
      fs::temp_directory_path() / ("mrroc-collision-" + std::to_string(::getpid()));
  const std::string config = write_config(dir);
  comm::Bus bus(kUrl);
  bus.start();
  StateWatch states(bus);
  auto run = std::async(std::launch::async, [&] { return launch_and_kill(config); });
  const LaunchRun r = run.get();
  bus.stop();
  fs::remove_all(dir);

  // The EDP said what it guards.
  EXPECT_TRUE(
      has(r.output, "collision guard on: 5 links, 1 fixed object ('box'), clearance 0.02 m"))
      << r.output;
  // The task got the refusal with code 16, naming both bodies, the distance, the clearance and
  // the servo step; the joints read back from the EDP: the commanded ones did not move at all,
  // the measured ones only by the servo's settling after the synchronisation (MuJoCo physics).
  std::smatch m;
  ASSERT_TRUE(std::regex_search(
      r.output, m,
      std::regex(R"(SET refused with code 16: EDP irb6 refused SET: SET refused: link '(\w+)' )"
                 R"(would (?:come within ([0-9.]+) m of|penetrate) 'box'(?: by [0-9.]+ m)? )"
                 R"(\(clearance 0\.02 m\) at servo step (\d+) of 1000; commanded joints moved by )"
                 R"(at most ([0-9.e+-]+) rad, measured by at most ([0-9.e+-]+) rad)")))
      << r.output;
  EXPECT_EQ(std::stod(m[4].str()), 0.0) << m[0];
  EXPECT_LT(std::stod(m[5].str()), 1e-3) << m[0];
  EXPECT_LT(std::stoi(m[3].str()), 500) << "refused before the 45 degrees where the box is";
  // The EDP's timing report at its end counts the one path it checked, refused.
  EXPECT_TRUE(has(r.output, "collision guard: 1 path checked, 1 refusal, ")) << r.output;
  // The ECP passed the EDP's code and class on: the MP saw a non-fatal error with code 16.
  EXPECT_TRUE(has(r.output, "[16]")) << r.output;
  EXPECT_NE(r.exit_code, 0) << r.output;

  // What the console saw: once the synchronised robot came to rest it was never commanded
  // anywhere else and never moved again (the refused SET was its only motion command).
  int resting = 0;
  bool moved = false;
  double farthest = 0.0;
  std::vector<double> rest;
  for (const auto& s : states.history()) {
    if (rest.empty()) {
      if (s.synchronised && !s.moving) rest = s.q_desired;
      continue;
    }
    ++resting;
    moved = moved || s.moving;
    for (std::size_t i = 0; i < s.q_desired.size() && i < rest.size(); ++i)
      farthest = std::max(farthest, std::abs(s.q_desired[i] - rest[i]));
  }
  EXPECT_GE(resting, 10) << "too few states of the robot at rest were heard";
  EXPECT_FALSE(moved) << "a state said the robot was moving";
  EXPECT_EQ(farthest, 0.0) << "rad: the robot was commanded away from where it rested";
  std::printf(
      "%s; %d states after the robot came to rest, commanded at most %.1e rad from "
      "there\n",
      m[0].str().c_str(), resting, farthest);
}
