// End-to-end: mrroc-launch runs real process sets (SRP, EDP with MuJoCo, ECP, MP) over LCM.
// Runs inside a private network and PID namespace (scripts/netns-run), so "no mrroc- process is
// left" can be checked exactly and no packet leaves the machine.
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <functional>
#include <mutex>
#include <optional>
#include <regex>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "mrroc/comm/bus.hpp"
#include "mrroc/comm/codec.hpp"
#include "mrroc/comm/sync_annotations.hpp"
#include "mrroc/config/process_set.hpp"
#include "mrroc/robot/robot_model.hpp"
#include "mrroc_build_options.hpp"

namespace fs = std::filesystem;
using namespace mrroc;
using Clock = std::chrono::steady_clock;

namespace {

const fs::path kBin = MRROC_BIN_DIR;
const fs::path kSource = MRROC_SOURCE_DIR;

struct RunResult {
  int exit_code = -1;
  std::string output;
  double seconds = 0;
  bool timed_out = false;
};

/// Runs a command, collecting stdout+stderr. `on_line` may return true to send SIGINT once.
RunResult run(const std::vector<std::string>& argv, double timeout_s,
              const std::function<bool(const std::string&)>& on_line = {}) {
  int fds[2];
  EXPECT_EQ(pipe(fds), 0);
  const auto t0 = Clock::now();
  const pid_t pid = fork();
  if (pid == 0) {
    dup2(fds[1], 1);
    dup2(fds[1], 2);
    close(fds[0]);
    close(fds[1]);
    std::vector<char*> args;
    for (const auto& a : argv) args.push_back(const_cast<char*>(a.c_str()));
    args.push_back(nullptr);
    execv(args[0], args.data());
    _exit(127);
  }
  close(fds[1]);
  RunResult r;
  std::string pending;
  bool signalled = false;
  FILE* in = fdopen(fds[0], "r");
  char buf[4096];
  // The child's output ends when every process of the set has closed it.
  while (std::fgets(buf, sizeof buf, in) != nullptr) {
    const std::string line = buf;
    r.output += line;
    if (on_line && !signalled && on_line(line)) {
      signalled = true;
      kill(pid, SIGINT);
    }
    if (std::chrono::duration<double>(Clock::now() - t0).count() > timeout_s && !r.timed_out) {
      r.timed_out = true;
      kill(pid, SIGKILL);
    }
  }
  std::fclose(in);
  int status = 0;
  waitpid(pid, &status, 0);
  r.seconds = std::chrono::duration<double>(Clock::now() - t0).count();
  r.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
  return r;
}

/// mrroc- processes alive in this PID namespace.
std::vector<std::string> mrroc_processes() {
  std::vector<std::string> found;
  for (const auto& entry : fs::directory_iterator("/proc")) {
    const std::string name = entry.path().filename();
    if (name.find_first_not_of("0123456789") != std::string::npos) continue;
    std::ifstream comm(entry.path() / "comm");
    std::string c;
    std::getline(comm, c);
    if (c.rfind("mrroc-", 0) == 0) found.push_back(name + " " + c);
  }
  return found;
}

/// Records every EDP reply of a robot, decoded, as the EDP sent it.
class EdpReplyRecorder {
 public:
  EdpReplyRecorder(comm::Bus& bus, const std::string& robot) {
    bus.subscribe<EdpReplyRecorder*>(channels::edp_reply(robot), &EdpReplyRecorder::dispatch, this);
  }
  static void dispatch(const lcm::ReceiveBuffer* buffer, const std::string&,
                       EdpReplyRecorder* self) {
    mrroc_lcm::edp_reply_t msg;
    if (comm::detail::decode_received(buffer, msg)) self->on_reply(&msg);
  }
  void on_reply(const mrroc_lcm::edp_reply_t* msg) {
    if (msg->header.kind != mrroc_lcm::header_t::REPLY) return;
    std::lock_guard lock(mutex_);
    last_arrival_ = std::chrono::steady_clock::now();
    replies_.push_back(comm::decode(*msg));
    const bool to_ecp = msg->header.recipient.rfind("ecp/", 0) == 0;
    if (to_ecp && replies_.back().type == edp::ReplyType::data &&
        (!final_ || msg->header.seq > final_seq_)) {
      final_ = replies_.back();
      final_seq_ = msg->header.seq;
    }
  }
  /// Returns once no reply has arrived for `quiet` (at most `limit`): the replies the EDP sent
  /// before the set ended may still wait in this process' socket. The bus' thread reads them
  /// after the launcher exited when the host is busy; stopping the bus at once would drop them
  /// (a lock-step run sends its whole motion in about a second).
  void wait_until_quiet(std::chrono::milliseconds quiet = std::chrono::milliseconds(300),
                        std::chrono::seconds limit = std::chrono::seconds(10)) {
    const auto end = std::chrono::steady_clock::now() + limit;
    while (std::chrono::steady_clock::now() < end) {
      {
        std::lock_guard lock(mutex_);
        if (std::chrono::steady_clock::now() - last_arrival_ >= quiet) return;
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
  }
  /// Every reply, in the order it arrived (with faulty links: copies, and out of order).
  std::vector<edp::Reply> replies() {
    std::lock_guard lock(mutex_);
    return replies_;
  }
  /// The reading that answered the ECP's last request: the data reply with the highest sequence
  /// number (a delayed copy of an older reply may arrive after it).
  std::optional<edp::Reply> final_reading() {
    std::lock_guard lock(mutex_);
    return final_;
  }

 private:
  std::mutex mutex_;
  std::vector<edp::Reply> replies_;
  std::optional<edp::Reply> final_;
  std::int64_t final_seq_ = 0;
  std::chrono::steady_clock::time_point last_arrival_ = std::chrono::steady_clock::now();
};

std::string launcher() { return (kBin / "mrroc-launch").string(); }
std::string demo_config() { return (kSource / "configs/demo-irb6.toml").string(); }

}  // namespace

TEST(LaunchDemo, RunsToTheEndAndReachesTheTargets) {
  const ProcessSetConfig config = load_process_set(demo_config());
  const auto poses = config.robots[0].ecp.args.get_double_rows("poses");
  comm::Bus bus(config.lcm_url);
  EdpReplyRecorder recorder(bus, "irb6");
  bus.start();

  const RunResult r = run({launcher(), demo_config()}, 60.0);
  recorder.wait_until_quiet();
  bus.stop();
  ASSERT_FALSE(r.timed_out) << r.output;
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_LT(r.seconds, 30.0) << "the demo must finish within 30 s";
  std::printf("demo finished in %.2f s\n", r.seconds);

  // Progress printed, child output prefixed with the process name.
  for (const char* expected : {"mrroc-launch: started srp", "mrroc-launch: edp/irb6 ready",
                               "pose 1/3 reached", "pose 3/3 reached", "task finished"})
    EXPECT_NE(r.output.find(expected), std::string::npos) << "missing '" << expected << "'\n"
                                                          << r.output;
  // Every line starts with the time the launcher printed it. Each report is printed once: the
  // SRP's line (the SRP runs from before the first report to after the last), not the
  // process' own stderr line "[ecp/irb6] ecp/irb6: info: ...".
  const std::regex stamp(R"(\d\d:\d\d:\d\d\.\d{3} )");
  const std::regex own_report(
      R"(\d\d:\d\d:\d\d\.\d{3} \[([^\]]+)\] +([^ ]+): (debug|info|warning|error|fatal): .*)");
  int ecp_started = 0;
  int mp_started = 0;
  std::istringstream lines(r.output);
  for (std::string line; std::getline(lines, line);) {
    EXPECT_TRUE(std::regex_search(line, stamp, std::regex_constants::match_continuous)) << line;
    std::smatch m;
    if (std::regex_match(line, m, own_report)) {
      EXPECT_NE(m[1], m[2]) << line;
    }
    if (line.find("task 'visit_joint_poses' started") != std::string::npos) {
      ++ecp_started;
      EXPECT_TRUE(std::regex_search(
          line, std::regex(R"(\[srp\] +\d\d:\d\d:\d\d\.\d{3} ecp/irb6 +info +task)")))
          << line;
    }
    if (line.find("task 'start_and_wait' started") != std::string::npos) {
      ++mp_started;
      EXPECT_TRUE(
          std::regex_search(line, std::regex(R"(\[srp\] +\d\d:\d\d:\d\d\.\d{3} mp +info +task)")))
          << line;
    }
  }
  EXPECT_EQ(ecp_started, 1) << r.output;
  EXPECT_EQ(mp_started, 1) << r.output;

  // Final joints read back from the EDP's own replies.
  const auto replies = recorder.replies();
  ASSERT_FALSE(replies.empty()) << "no EDP reply observed";
  const std::optional<edp::Reply> last = recorder.final_reading();
  ASSERT_TRUE(last.has_value());
  EXPECT_TRUE(last->synchronised);
  const auto& target = poses.back();
  ASSERT_EQ(last->joints.size(), target.size());
  for (std::size_t j = 0; j < target.size(); ++j)
    EXPECT_NEAR(last->joints[j], target[j], 2e-3) << "joint " << j;
  // The EDP refused nothing the task planned. The one refusal a busy host may cause is part of
  // the recovery from a late macro-step: the EDP brought the robot to a standstill past its
  // target (a "lost successor", reported to SRP), refused the planned continuation as too fast
  // from there, and Move re-planned from where the robot stood. Anything else fails the test.
  const RobotModel model = load_robot_model(config.robots[0].model_dir);
  int recoveries = 0;
  for (const auto& reply : replies) {
    if (reply.type == edp::ReplyType::error) {
      const bool after_ramp =
          reply.error_code == edp::error_code::too_fast &&
          reply.error_text.find("starting where a stopping ramp left the robot") !=
              std::string::npos;
      EXPECT_TRUE(after_ramp) << "EDP refused: " << reply.error_text;
      if (after_ramp) ++recoveries;
    }
    // Every reading in joint coordinates (after synchronisation) stayed inside the joint limits.
    if (!reply.synchronised) continue;
    for (std::size_t j = 0; j < reply.joints.size() && j < model.lower_limits.size(); ++j) {
      EXPECT_GE(reply.joints[j], model.lower_limits[j] - 1e-3) << "joint " << j;
      EXPECT_LE(reply.joints[j], model.upper_limits[j] + 1e-3) << "joint " << j;
    }
  }
  if (recoveries > 0) {
    std::printf("%d late macro-step(s) recovered by re-planning\n", recoveries);
    EXPECT_NE(r.output.find("no next macro-step from the ECP in time"), std::string::npos)
        << "a refusal after a stopping ramp without the EDP's report of the late macro-step\n"
        << r.output;
  }

  // SRP received messages from every process.
  const auto summary_at = r.output.find("srp summary:");
  ASSERT_NE(summary_at, std::string::npos) << r.output;
  const std::string summary =
      r.output.substr(summary_at, r.output.find('\n', summary_at) - summary_at);
  for (const char* process : {"mp (", "ecp/irb6 (", "edp/irb6 ("})
    EXPECT_NE(summary.find(process), std::string::npos) << summary;

  EXPECT_TRUE(mrroc_processes().empty()) << "left behind: " << mrroc_processes().front();
}

TEST(LaunchDemo, SigintMidMotionStopsEverythingInReverseOrder) {
  const RunResult r = run({launcher(), demo_config()}, 60.0, [](const std::string& line) {
    return line.find("pose 1/3 reached") != std::string::npos;
  });
  ASSERT_FALSE(r.timed_out) << r.output;
  EXPECT_EQ(r.exit_code, 128 + SIGINT) << r.output;
  EXPECT_EQ(r.output.find("pose 3/3 reached"), std::string::npos) << "the task went on";
  const auto mp = r.output.find("stopping mp");
  const auto ecp = r.output.find("stopping ecp/irb6");
  const auto edp = r.output.find("stopping edp/irb6");
  const auto srp = r.output.find("stopping srp");
  ASSERT_NE(srp, std::string::npos) << r.output;
  EXPECT_LT(ecp, edp) << r.output;
  EXPECT_LT(edp, srp) << r.output;
  if (mp != std::string::npos) {
    EXPECT_LT(mp, ecp);
  }
  EXPECT_EQ(r.output.find("killed"), std::string::npos) << "a process needed SIGKILL:\n"
                                                        << r.output;
  // The arm was moving: the EDP brought it to rest within its acceleration limits before it
  // exited: a planned stop (the stopping task told it no macro-step follows), for want of a next
  // macro-step, or on its own stop request. The SRP shows the EDP's report of it before the
  // EDP's last status (both in the order the EDP sent them).
  const std::string after_stop =
      r.output.substr(std::min(r.output.size(), r.output.find("stopping mp")));
  std::smatch ramp;
  ASSERT_TRUE(std::regex_search(
      after_stop, ramp,
      std::regex(R"(\[srp\] +[0-9:.]+ edp/irb6 +[a-z]+ +.*brought to (a standstill|rest))")))
      << r.output;
  std::smatch finished;
  ASSERT_TRUE(std::regex_search(after_stop, finished,
                                std::regex(R"(\[srp\] +[0-9:.]+ edp/irb6 +status +finished)")))
      << r.output;
  EXPECT_LT(ramp.position(0), finished.position(0)) << r.output;
  EXPECT_TRUE(mrroc_processes().empty()) << "left behind: " << mrroc_processes().front();
}

TEST(LaunchDemo, EmergencyStopFromTheUiStopsTheTask) {
  bool sent = false;
  const RunResult r = run({launcher(), demo_config()}, 60.0, [&](const std::string& line) {
    if (sent || line.find("pose 1/3 reached") == std::string::npos) return false;
    sent = true;
    const RunResult ui =
        run({(kBin / "mrroc-ui").string(), "estop", "--config", demo_config(), "--reason", "test"},
            10.0);
    EXPECT_EQ(ui.exit_code, 0) << ui.output;
    return false;
  });
  ASSERT_TRUE(sent) << r.output;
  EXPECT_EQ(r.exit_code, 1) << "the task must fail\n" << r.output;
  EXPECT_NE(r.output.find("EMERGENCY STOP: robot brought to a standstill: test"), std::string::npos)
      << r.output;
  EXPECT_NE(r.output.find("emergency stop engaged"), std::string::npos) << r.output;
  EXPECT_EQ(r.output.find("pose 3/3 reached"), std::string::npos) << r.output;
  EXPECT_EQ(r.output.find("killed"), std::string::npos) << r.output;
  EXPECT_TRUE(mrroc_processes().empty());
}

TEST(LaunchDemo, ConfigTypoStartsNothing) {
  const fs::path dir = fs::temp_directory_path() / ("mrroc-typo-" + std::to_string(getpid()));
  fs::create_directories(dir);
  std::ifstream demo(demo_config());
  std::stringstream text;
  text << demo.rdbuf();
  std::string config = text.str();
  config.replace(config.find("servo_period_ms"), 15, "servo_period_sm");
  // Point the model folder at the real one from the temporary place.
  config.replace(config.find("\"../robots/irb6\""), 16,
                 "\"" + (kSource / "robots/irb6").string() + "\"");
  const fs::path file = dir / "typo.toml";
  std::ofstream(file) << config;
  const RunResult r = run({launcher(), file.string()}, 20.0);
  fs::remove_all(dir);
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find(file.string() + ":"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find(": error: unknown key 'servo_period_sm' in [robot.edp]"),
            std::string::npos)
      << r.output;
  EXPECT_EQ(r.output.find("mrroc-launch: started"), std::string::npos) << r.output;
}

TEST(LaunchDemo, CheckPrintsThePlanAndStartsNothing) {
  const RunResult r = run({launcher(), "--check", demo_config()}, 20.0);
  EXPECT_EQ(r.exit_code, 0) << r.output;
  for (const char* expected : {"1. srp", "2. edp/irb6", "3. ecp/irb6", "4. mp", "config is valid"})
    EXPECT_NE(r.output.find(expected), std::string::npos) << r.output;
  EXPECT_EQ(r.output.find("mrroc-launch: started"), std::string::npos) << r.output;
}

TEST(LaunchDemo, EveryBinaryAnswersHelpAndVersionAndExits2OnABadCommandLine) {
  for (const char* name : {"mrroc-launch", "mrroc-mp", "mrroc-ecp", "mrroc-edp", "mrroc-srp",
                           "mrroc-vsp", "mrroc-ui", "mrroc-axis-emu", "mrroc-plot"}) {
    const std::string bin = (kBin / name).string();
    const RunResult help = run({bin, "--help"}, 10.0);
    EXPECT_EQ(help.exit_code, 0) << name << "\n" << help.output;
    EXPECT_NE(help.output.find(name), std::string::npos) << help.output;
    EXPECT_NE(help.output.find("--help"), std::string::npos) << help.output;
    EXPECT_NE(help.output.find("--version"), std::string::npos) << help.output;
    const RunResult version = run({bin, "--version"}, 10.0);
    EXPECT_EQ(version.exit_code, 0) << name << "\n" << version.output;
    EXPECT_NE(version.output.find(std::string(name) + " (mrroc) "), std::string::npos)
        << version.output;
    const RunResult bad = run({bin, "--no-such-option"}, 10.0);
    EXPECT_EQ(bad.exit_code, 2) << name << "\n" << bad.output;
    EXPECT_NE(bad.output.find("Run with --help for more information."), std::string::npos)
        << name << "\n"
        << bad.output;
  }
  const RunResult missing = run({(kBin / "mrroc-edp").string(), "--robot", "irb6"}, 10.0);
  EXPECT_EQ(missing.exit_code, 2) << missing.output;
  EXPECT_NE(missing.output.find("--config is required"), std::string::npos) << missing.output;
  const RunResult range =
      run({(kBin / "mrroc-ui").string(), "serve", "-c", "x.toml", "--port", "70000"}, 10.0);
  EXPECT_EQ(range.exit_code, 2) << range.output;
  EXPECT_NE(range.output.find("70000"), std::string::npos) << range.output;
}

TEST(LaunchDemo, UnknownPluginFailsBeforeTheTaskStarts) {
  const fs::path dir = fs::temp_directory_path() / ("mrroc-plugin-" + std::to_string(getpid()));
  fs::create_directories(dir);
  std::ifstream demo(demo_config());
  std::stringstream text;
  text << demo.rdbuf();
  std::string config = text.str();
  config.replace(config.find("\"mujoco\""), 8, "\"mujocoo\"");
  config.replace(config.find("\"../robots/irb6\""), 16,
                 "\"" + (kSource / "robots/irb6").string() + "\"");
  const fs::path file = dir / "plugin.toml";
  std::ofstream(file) << config;
  // --check finds it before anything starts: the EDP's own check (--check-config), at the line
  // of `plugin`.
  const RunResult check = run({launcher(), "--check", file.string()}, 20.0);
  EXPECT_EQ(check.exit_code, 2) << check.output;
  EXPECT_NE(check.output.find(file.string() + ":19: error: unknown hardware plugin 'mujocoo' "
                                              "(known: can, faulty, mock, mujoco)"),
            std::string::npos)
      << check.output;
  EXPECT_EQ(check.output.find("config is valid"), std::string::npos) << check.output;
  const RunResult r = run({launcher(), file.string()}, 30.0);
  fs::remove_all(dir);
  EXPECT_EQ(r.exit_code, 3) << r.output;
  EXPECT_NE(r.output.find("unknown hardware plugin 'mujocoo' (known: can, faulty, mock, mujoco)"),
            std::string::npos)
      << r.output;
  EXPECT_NE(r.output.find(file.string() + ":"), std::string::npos) << r.output;
  EXPECT_EQ(r.output.find("started mp"), std::string::npos) << r.output;
  EXPECT_TRUE(mrroc_processes().empty());
}

/// The demo config with `extra` added to [robot.edp] and the model path made absolute, written
/// to a temporary folder.
static fs::path demo_variant(const std::string& tag, const std::string& edp_extra,
                             const std::string& plugin = "mujoco") {
  const fs::path dir =
      fs::temp_directory_path() / ("mrroc-" + tag + "-" + std::to_string(getpid()));
  fs::create_directories(dir);
  std::ifstream demo(demo_config());
  std::stringstream text;
  text << demo.rdbuf();
  std::string config = text.str();
  config.replace(config.find("plugin = \"mujoco\""), 17,
                 "plugin = \"" + plugin + "\"\n" + edp_extra);
  config.replace(config.find("\"../robots/irb6\""), 16,
                 "\"" + (kSource / "robots/irb6").string() + "\"");
  const fs::path file = dir / (tag + ".toml");
  std::ofstream(file) << config;
  return file;
}

TEST(LaunchDemo, LockStepDemoRunsToTheEnd) {
  const fs::path file = demo_variant("lockstep", "lock_step = true");
  const ProcessSetConfig config = load_process_set(file);
  ASSERT_TRUE(config.robots[0].edp.lock_step);
  const auto poses = config.robots[0].ecp.args.get_double_rows("poses");
  comm::Bus bus(config.lcm_url);
  EdpReplyRecorder recorder(bus, "irb6");
  bus.start();
  const RunResult r = run({launcher(), file.string()}, 60.0);
  recorder.wait_until_quiet();
  bus.stop();
  fs::remove_all(file.parent_path());
  ASSERT_FALSE(r.timed_out) << r.output;
  EXPECT_EQ(r.exit_code, 0) << r.output;
  std::printf("lock-step demo finished in %.2f s\n", r.seconds);
  for (const char* expected : {"lock-step", "pose 3/3 reached", "task finished"})
    EXPECT_NE(r.output.find(expected), std::string::npos) << "missing '" << expected << "'\n"
                                                          << r.output;
  // Simulated time stands still while the EDP waits for a successor: none is ever lost.
  EXPECT_EQ(r.output.find("no next macro-step from the ECP in time"), std::string::npos)
      << r.output;
  for (const auto& reply : recorder.replies())
    EXPECT_NE(reply.type, edp::ReplyType::error) << reply.error_text;
  const std::optional<edp::Reply> last = recorder.final_reading();
  ASSERT_TRUE(last.has_value());
  for (std::size_t j = 0; j < poses.back().size(); ++j)
    EXPECT_NEAR(last->joints[j], poses.back()[j], 2e-3) << "joint " << j;
  EXPECT_TRUE(mrroc_processes().empty());
}

TEST(LaunchDemo, LockStepNeedsSimulatedHardware) {
  const fs::path file = demo_variant("lockstep-can", "lock_step = true", "can");
  const RunResult r = run({launcher(), file.string()}, 30.0);
  fs::remove_all(file.parent_path());
  EXPECT_EQ(r.exit_code, 3) << r.output;
  EXPECT_NE(r.output.find("lock_step = true needs simulated hardware; plugin 'can' drives its "
                          "axes in real time"),
            std::string::npos)
      << r.output;
  EXPECT_EQ(r.output.find("started mp"), std::string::npos) << r.output;
  EXPECT_TRUE(mrroc_processes().empty());
}

TEST(LaunchDemo, RntDemoRunsToTheEnd) {
  const std::string config = (kSource / "configs/demo-rnt.toml").string();
  const RunResult r = run({launcher(), config}, 90.0);
  ASSERT_FALSE(r.timed_out) << r.output;
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("kinematics 'rnt'"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("task finished"), std::string::npos) << r.output;
  std::printf("RNT demo finished in %.2f s\n", r.seconds);
  EXPECT_TRUE(mrroc_processes().empty());
}

namespace {
/// Runs the demo with MRROC_LINK_FAULTS = `faults` on every link of every process and checks that
/// the robot ends at the demo's last pose.
void demo_reaches_final_pose_with_link_faults(const char* faults, const char* what) {
  ::setenv("MRROC_LINK_FAULTS", faults, 1);
  const ProcessSetConfig config = load_process_set(demo_config());
  const auto poses = config.robots[0].ecp.args.get_double_rows("poses");
  comm::Bus bus(config.lcm_url);
  EdpReplyRecorder recorder(bus, "irb6");
  bus.start();
  const RunResult r = run({launcher(), demo_config()}, 600.0);
  recorder.wait_until_quiet();
  bus.stop();
  ::unsetenv("MRROC_LINK_FAULTS");
  ASSERT_FALSE(r.timed_out) << r.output;
  EXPECT_EQ(r.exit_code, 0) << r.output;
  // Copies of replies are delayed and reordered here: the final reading is the answer to the
  // ECP's last request, not the last copy to arrive.
  const std::optional<edp::Reply> last = recorder.final_reading();
  ASSERT_TRUE(last.has_value());
  for (std::size_t j = 0; j < poses.back().size(); ++j)
    EXPECT_NEAR(last->joints[j], poses.back()[j], 2e-3) << "joint " << j;
  std::printf("demo over %s links finished in %.2f s\n", what, r.seconds);
  EXPECT_TRUE(mrroc_processes().empty());
}
}  // namespace

TEST(LaunchDemo, LossyAndDuplicatingLinksStillReachTheSameFinalPose) {
  // Registered with ctest only in a build that injects faults (tests/integration/CMakeLists.txt).
  ASSERT_TRUE(kLinkFaultInjection) << "this build ignores MRROC_LINK_FAULTS: configure it with "
                                      "-DMRROC_LINK_FAULT_INJECTION=ON";
  // Every request and reply on every link of every process: 10% dropped, 10% sent twice.
  demo_reaches_final_pose_with_link_faults("drop=0.1,duplicate=0.1,seed=11", "lossy");
}

TEST(LaunchDemo, DelayedAndReorderedLinksStillReachTheSameFinalPose) {
  // Registered with ctest only in a build that injects faults (tests/integration/CMakeLists.txt).
  ASSERT_TRUE(kLinkFaultInjection) << "this build ignores MRROC_LINK_FAULTS: configure it with "
                                      "-DMRROC_LINK_FAULT_INJECTION=ON";
  // 20% of the copies held back up to 30 ms (so overtaken by later messages), besides 5% dropped
  // and 5% duplicated.
  demo_reaches_final_pose_with_link_faults("drop=0.05,duplicate=0.05,delay=0.2,delay_ms=30,seed=13",
                                           "delayed");
}
