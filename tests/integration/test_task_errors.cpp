// Error conditions thrown by user tasks and operator PAUSE/RESUME, through real process sets
// whose tasks come from a plugin library (tests/integration/test_tasks.cpp).
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <mutex>
#include <regex>
#include <string>
#include <vector>

#include "mrroc/comm/bus.hpp"
#include "mrroc/config/process_set.hpp"

namespace fs = std::filesystem;
using namespace mrroc;
using Clock = std::chrono::steady_clock;

namespace {

struct RunResult {
  int exit_code = -1;
  std::string output;
};

class TaskErrors : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("mrroc-task-errors-" + std::to_string(getpid()));
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }

  std::string config(const std::string& mp_task, const std::string& mp_args,
                     const std::string& ecp_task) {
    const fs::path file = dir_ / (mp_task + ".toml");
    std::ofstream(file) << "[system]\nname = \"t\"\nlcm_url = \"udpm://239.255.76.67:7667?ttl=0\"\n"
                        << "[mp]\ntask = \"" << mp_task << "\"\nlibrary = \"" << MRROC_TEST_TASKS
                        << "\"\n[mp.args]\n"
                        << mp_args << "\n[[robot]]\nname = \"irb6\"\n"
                        << "model = \"" << MRROC_SOURCE_DIR << "/robots/irb6\"\n"
                        << "[robot.edp]\nplugin = \"mujoco\"\n[robot.ecp]\ntask = \"" << ecp_task
                        << "\"\nlibrary = \"" << MRROC_TEST_TASKS << "\"\n";
    return file.string();
  }

  static RunResult launch(const std::string& file) {
    const std::string command = std::string(MRROC_BIN_DIR) + "/mrroc-launch " + file + " 2>&1";
    RunResult r;
    FILE* pipe = popen(command.c_str(), "r");
    char buf[4096];
    while (std::fgets(buf, sizeof buf, pipe) != nullptr) r.output += buf;
    const int status = pclose(pipe);
    r.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
    return r;
  }

  fs::path dir_;
};

}  // namespace

TEST_F(TaskErrors, NonFatalErrorsLetTheMpGoOn) {
  const RunResult r = launch(config(
      "retry", "arguments = \"class = 'non_fatal'\\ntimes = 2\\n\"\nattempts = 3", "follow_mp"));
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("non-fatal error (code 201), retrying"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("succeeded at attempt 3"), std::string::npos) << r.output;
  // The SRP saw the ECP's report of the error, with its code.
  EXPECT_NE(r.output.find("ecp/irb6   warning [201] sub-task 'fail': deliberate non_fatal error"),
            std::string::npos)
      << r.output;
}

TEST_F(TaskErrors, TheEdpsClassOfARefusalReachesTheMp) {
  // The EDP refuses a macro-step (its reading after the last servo step: bad_argument, code 7)
  // as non-fatal: nothing moved. The ECP passes the EDP's code and class on, and the MP retries.
  const RunResult r = launch(config(
      "retry", "arguments = \"class = 'edp_refusal'\\ntimes = 1\\n\"\nattempts = 2", "follow_mp"));
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("non-fatal error (code 7), retrying"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("value_in_step_no 15 is outside 1..11"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("succeeded at attempt 2"), std::string::npos) << r.output;
}

TEST_F(TaskErrors, EverythingAGetReturnsReachesTheTask) {
  // The task (tests/integration/test_tasks.cpp, "edp_settings") checks the image itself and
  // fails naming any mismatch.
  const RunResult r = launch(config("start_and_wait", "", "edp_settings"));
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("edp settings read back: tool z 0.2500 m, model 1, inputs 0x5"),
            std::string::npos)
      << r.output;
  EXPECT_EQ(r.output.find("not as expected"), std::string::npos) << r.output;
}

TEST_F(TaskErrors, TheMpHearsTheFirstEcpAndWaitsOnRobotImages) {
  // Two robots: "quick" visits one pose, "slow" three; the MP (test task "first_then_rest")
  // starts both, reports the first to finish, then Waits on the MP level until both stand still.
  const fs::path file = dir_ / "first.toml";
  std::ofstream out(file);
  out << "[system]\nname = \"first\"\nlcm_url = \"udpm://239.255.76.67:7667?ttl=0\"\n"
      << "[mp]\ntask = \"first_then_rest\"\nlibrary = \"" << MRROC_TEST_TASKS << "\"\n";
  for (const auto& [name, poses] :
       {std::pair<std::string, std::string>{"quick", "[[0.1, -1.5708, 0.0, 0.0, 0.0]]"},
        {"slow",
         "[[0.6, -1.35, 0.15, 0.5, 1.0], [-0.5, -1.8, -0.2, -0.6, -1.2], "
         "[0.0, -1.5708, 0.0, 0.0, 0.0]]"}})
    out << "[[robot]]\nname = \"" << name << "\"\nmodel = \"" << MRROC_SOURCE_DIR
        << "/robots/irb6\"\n[robot.edp]\nplugin = \"mujoco\"\n[robot.ecp]\n"
        << "task = \"visit_joint_poses\"\n[robot.ecp.args]\nposes = " << poses << "\n";
  out.close();
  const RunResult r = launch(file.string());
  EXPECT_EQ(r.exit_code, 0) << r.output;
  const auto first = r.output.find("first to finish: quick");
  const auto rest = r.output.find("every robot at rest after");
  const auto slow_done = r.output.find("pose 3/3 reached");
  ASSERT_NE(first, std::string::npos) << r.output;
  ASSERT_NE(rest, std::string::npos) << r.output;
  ASSERT_NE(slow_done, std::string::npos) << r.output;
  EXPECT_LT(first, slow_done) << "the MP heard the quick robot before the slow one ended\n"
                              << r.output;
  EXPECT_NE(r.output.find("every robot's task ended"), std::string::npos) << r.output;
}

TEST_F(TaskErrors, FatalErrorAbortsTheTask) {
  const RunResult r = launch(
      config("retry", "arguments = \"class = 'fatal'\\ntimes = 5\\n\"\nattempts = 3", "follow_mp"));
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_NE(r.output.find("aborting: ecp/irb6: deliberate fatal error, run 1"), std::string::npos)
      << r.output;
  EXPECT_EQ(r.output.find("retrying"), std::string::npos) << r.output;
  // Nothing crashed: every process ended by itself when the set was stopped.
  EXPECT_EQ(r.output.find("killed"), std::string::npos) << r.output;
}

TEST_F(TaskErrors, AStateMachineGoesByTheClassOfAnEcpsError) {
  // The MP task state_machine with the test library's ECP task "fail" (its ECP fails the first
  // `times` runs of it in the process): two non-fatal errors lead to a pause and a new attempt,
  // the third attempt succeeds; then a fatal error leads to 'failed' with the state's message.
  const fs::path machine = dir_ / "retry.fsm.toml";
  std::ofstream(machine) << "initial = \"start\"\n"
                            "[state.start]\n"
                            "start_tasks = [\"irb6\"]\n"
                            "next = \"attempt\"\n"
                            "[state.attempt]\n"
                            "robot = \"irb6\"\n"
                            "subtask = \"fail\"\n"
                            "args = { class = \"non_fatal\", times = 2 }\n"
                            "next = \"give_up\"\n"
                            "on_non_fatal = \"pause\"\n"
                            "on_error = \"failed\"\n"
                            "[state.pause]\n"
                            "delay = 0.2\n"
                            "report = \"a new attempt after a non-fatal error\"\n"
                            "next = \"attempt\"\n"
                            "[state.give_up]\n"
                            "robot = \"irb6\"\n"
                            "subtask = \"fail\"\n"
                            "args = { class = \"fatal\", times = 9 }\n"
                            "next = \"done\"\n"
                            "on_fatal = \"failed\"\n"
                            "message = \"gave up on a fatal error\"\n";
  const RunResult r =
      launch(config("state_machine", "file = \"" + machine.string() + "\"", "follow_mp"));
  EXPECT_EQ(r.exit_code, 1) << r.output;
  const std::regex to_pause(
      "state 'attempt' -> 'pause' \\(non-fatal error: [^\\n]*deliberate "
      "non_fatal error, run [12]");
  const auto pauses = std::distance(
      std::sregex_iterator(r.output.begin(), r.output.end(), to_pause), std::sregex_iterator());
  EXPECT_EQ(pauses, 2) << r.output;
  EXPECT_NE(r.output.find("a new attempt after a non-fatal error"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("state 'attempt' -> 'give_up' (succeeded)"), std::string::npos)
      << r.output;
  EXPECT_NE(r.output.find("state 'give_up' -> 'failed' (fatal error: "), std::string::npos)
      << r.output;
  EXPECT_NE(r.output.find("gave up on a fatal error ("), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("deliberate fatal error, run 4"), std::string::npos) << r.output;
}

TEST_F(TaskErrors, AStateMachinesTimeoutStopsTheSubTaskAndGoesOn) {
  // A sub-task longer than its state's timeout: its ECP gets STOP, the machine goes to
  // `on_timeout`, and the next sub-task brings the column back to where it started; once it
  // stands, a decision state ('when') finds it there.
  const fs::path machine = dir_ / "timeout.fsm.toml";
  std::ofstream(machine) << "initial = \"start\"\n"
                            "[state.start]\n"
                            "start_tasks = [\"irb6\"]\n"
                            "next = \"far\"\n"
                            "[state.far]\n"
                            "robot = \"irb6\"\n"
                            "subtask = \"visit_joint_poses\"\n"
                            "args = { poses = [[1.5, -1.5708, 0.0, 0.0, 0.0]], velocity_scale "
                            "= 0.2 }\n"
                            "timeout = 0.5\n"
                            "next = \"failed\"\n"
                            "on_timeout = \"back\"\n"
                            "[state.back]\n"
                            "robot = \"irb6\"\n"
                            "subtask = \"visit_joint_poses\"\n"
                            "args = { poses = [[0.0, -1.5708, 0.0, 0.0, 0.0]] }\n"
                            "next = \"home\"\n"
                            "[state.home]\n"
                            "wait = { robot = \"irb6\", moving = false }\n"
                            "timeout = 1.0\n"
                            "next = \"check\"\n"
                            "[state.check]\n"
                            "when = [{ robot = \"irb6\", joint = 0, above = -0.002, below = 0.002, "
                            "next = \"done\" }]\n"
                            "next = \"failed\"\n"
                            "message = \"the column is not back at 0 rad\"\n";
  const RunResult r =
      launch(config("state_machine", "file = \"" + machine.string() + "\"", "follow_mp"));
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("state 'far' -> 'back' (state 'far' took longer than its timeout of "
                          "0.5 s)"),
            std::string::npos)
      << r.output;
  EXPECT_NE(r.output.find("state 'back' -> 'home' (succeeded)"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("state 'home' -> 'check' (succeeded)"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("state 'check' -> 'done' (irb6 joint 0 in (-0.002, 0.002) holds"),
            std::string::npos)
      << r.output;
}

namespace {
/// Times at which the EDP sent replies.
class ReplyTimes {
 public:
  explicit ReplyTimes(comm::Bus& bus) {
    bus.subscribe<ReplyTimes*>(channels::edp_reply("irb6"), &ReplyTimes::on, this);
  }
  static void on(const lcm::ReceiveBuffer*, const std::string&, ReplyTimes* self) {
    std::lock_guard lock(self->mutex_);
    self->times_.push_back(Clock::now());
  }
  double largest_gap_s() {
    std::lock_guard lock(mutex_);
    double gap = 0;
    for (std::size_t i = 1; i < times_.size(); ++i)
      gap = std::max(gap, std::chrono::duration<double>(times_[i] - times_[i - 1]).count());
    return gap;
  }

 private:
  std::mutex mutex_;
  std::vector<Clock::time_point> times_;
};
}  // namespace

TEST_F(TaskErrors, PauseHoldsTheRobotUntilResume) {
  comm::Bus bus("udpm://239.255.76.67:7667?ttl=0");
  ReplyTimes replies(bus);
  bus.start();
  const RunResult r = launch(config("pause_resume", "pause_s = 1.2", "follow_mp"));
  bus.stop();
  ASSERT_EQ(r.exit_code, 0) << r.output;
  // The ECP's reports, as the SRP shows them.
  EXPECT_TRUE(std::regex_search(r.output, std::regex("ecp/irb6 +info +paused"))) << r.output;
  EXPECT_TRUE(std::regex_search(r.output, std::regex("ecp/irb6 +info +resumed"))) << r.output;
  // While paused the ECP sends no macro-step: the EDP's replies stop for the pause.
  const double gap = replies.largest_gap_s();
  EXPECT_GT(gap, 1.0) << "no pause in the EDP traffic";
  EXPECT_LT(gap, 2.5);
  std::printf("longest silence of the EDP during the pause: %.3f s\n", gap);
  const std::regex took("move with pause took ([0-9.]+) s");
  std::smatch m;
  ASSERT_TRUE(std::regex_search(r.output, m, took)) << r.output;
  EXPECT_GT(std::stod(m[1]), 1.2);
}
