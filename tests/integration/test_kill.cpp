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
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <mutex>
#include <regex>
#include <string>
#include <thread>

namespace {

using Clock = std::chrono::steady_clock;

struct LaunchRun {
  int exit_code = -1;
  std::string output;
};

/// Launches `config`, waits until `trigger` appears in the output, waits `delay`, kills the
/// process named `victim` (pid from the launcher's "started <victim> (pid N)" line) with SIGKILL.
LaunchRun launch_and_kill(const std::string& config, const std::string& victim,
                    const std::string& trigger, std::chrono::milliseconds delay) {
  int out[2];
  if (pipe(out) != 0) return {};
  const pid_t pid = fork();
  if (pid == 0) {
    dup2(out[1], STDOUT_FILENO);
    dup2(out[1], STDERR_FILENO);
    close(out[0]);
    close(out[1]);
    const std::string exe = std::string(MRROC_BIN_DIR) + "/mrroc-launch";
    execl(exe.c_str(), exe.c_str(), config.c_str(), static_cast<char*>(nullptr));
    _exit(127);
  }
  close(out[1]);
  LaunchRun run;
  std::mutex m;
  FILE* in = fdopen(out[0], "r");
  std::thread reader([&] {
    char line[4096];
    while (std::fgets(line, sizeof line, in) != nullptr) {
      std::lock_guard lock(m);
      run.output += line;
    }
  });
  const std::regex started("started " + victim + " \\(pid ([0-9]+)\\)");
  pid_t victim_pid = 0;
  const auto deadline = Clock::now() + std::chrono::seconds(60);
  bool triggered = false;
  while (Clock::now() < deadline && !triggered) {
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
    std::lock_guard lock(m);
    std::smatch match;
    if (victim_pid == 0 && std::regex_search(run.output, match, started))
      victim_pid = std::stoi(match[1]);
    triggered = victim_pid != 0 && run.output.find(trigger) != std::string::npos;
  }
  if (triggered) {
    std::this_thread::sleep_for(delay);
    kill(victim_pid, SIGKILL);
  }
  int status = 0;
  waitpid(pid, &status, 0);
  reader.join();
  std::fclose(in);
  run.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  if (!triggered) run.output += "\n[test] trigger '" + trigger + "' never came\n";
  return run;
}

std::string demo() { return std::string(MRROC_SOURCE_DIR) + "/configs/demo-irb6-can.toml"; }

bool has(const std::string& s, const std::string& what) { return s.find(what) != std::string::npos; }

/// Nothing of the set is left running (the test runs in its own PID namespace).
void expect_nothing_left() {
  FILE* ps = popen("ps -eo comm= | grep '^mrroc-' || true", "r");
  char buf[256];
  std::string left;
  while (std::fgets(buf, sizeof buf, ps) != nullptr) left += buf;
  pclose(ps);
  EXPECT_EQ(left, "");
}

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
