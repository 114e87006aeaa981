// The operator's commands to the MP (START, PAUSE, RESUME, STOP, TERMINATE, STATUS over
// request/reply, as mrroc-ui sends them), the EDP's robot_state_t broadcast, and the EDP's
// overrun report when its servo loop stalls: real process sets started by mrroc-launch.
#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <map>
#include <mutex>
#include <regex>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "launch_helpers.hpp"
#include "mrroc/comm/auth.hpp"
#include "mrroc/comm/bus.hpp"
#include "mrroc/comm/request_reply.hpp"
#include "mrroc/config/process_set.hpp"
#include "mrroc/robot/robot_model.hpp"
#include "mrroc_lcm/edp_instruction_t.hpp"
#include "mrroc_lcm/operator_command_t.hpp"
#include "mrroc_lcm/operator_reply_t.hpp"
#include "mrroc_lcm/robot_state_t.hpp"
#include "state_watch.hpp"

namespace fs = std::filesystem;
using namespace mrroc;
using namespace mrroc::test;
using Command = mrroc_lcm::operator_command_t;
using Reply = mrroc_lcm::operator_reply_t;

namespace {

constexpr const char* kUrl = "udpm://239.255.76.67:7667?ttl=0";

/// A process-set file in a temporary folder.
std::string write_config(const std::string& name, const std::string& mp, const std::string& edp,
                         const std::string& poses, const std::string& system = {}) {
  const fs::path dir = fs::temp_directory_path() / ("mrroc-operator-" + std::to_string(getpid()));
  fs::create_directories(dir);
  const fs::path file = dir / (name + ".toml");
  std::ofstream(file) << "[system]\nname = \"" << name << "\"\nlcm_url = \"" << kUrl << "\"\n"
                      << system << "\n"
                      << "[mp]\ntask = \"start_and_wait\"\n"
                      << mp << "\n"
                      << "[[robot]]\nname = \"irb6\"\nmodel = \"" << MRROC_SOURCE_DIR
                      << "/robots/irb6\"\n[robot.edp]\n"
                      << edp << "\n"
                      << "[robot.ecp]\ntask = \"visit_joint_poses\"\n[robot.ecp.args]\nposes = "
                      << poses << "\nvelocity_scale = 0.5\nacceleration_scale = 0.5\n";
  return file.string();
}

/// mrroc-launch running in the background.
class BackgroundLaunch {
 public:
  explicit BackgroundLaunch(std::string config)
      : thread_([this, c = std::move(config)] {
          LaunchRun r = launch_and_kill(c);
          std::lock_guard lock(mutex_);
          run_ = std::move(r);
          done_ = true;
        }) {}
  ~BackgroundLaunch() {
    if (thread_.joinable()) thread_.join();
  }
  BackgroundLaunch(const BackgroundLaunch&) = delete;
  BackgroundLaunch& operator=(const BackgroundLaunch&) = delete;
  LaunchRun wait() {
    thread_.join();
    std::lock_guard lock(mutex_);
    return run_;
  }
  bool done() {
    std::lock_guard lock(mutex_);
    return done_;
  }

 private:
  std::mutex mutex_;
  LaunchRun run_;
  bool done_ = false;
  std::thread thread_;
};

class Operator : public ::testing::Test {
 protected:
  Operator() : bus_(kUrl) {}
  void SetUp() override { bus_.start(); }
  void TearDown() override { bus_.stop(); }

  Reply send(std::int8_t command) {
    Command c{};
    c.command = command;
    return client_.call(c);
  }
  /// STATUS until the MP answers (it starts after the other processes).
  Reply wait_for_mp(std::chrono::seconds timeout) {
    const auto until = Clock::now() + timeout;
    for (;;) {
      try {
        return send(Command::STATUS);
      } catch (const TimeoutError&) {
        if (Clock::now() > until) throw;
      }
    }
  }
  Reply wait_for_state(std::int8_t state, std::chrono::seconds timeout) {
    const auto until = Clock::now() + timeout;
    Reply r = send(Command::STATUS);
    while (r.state != state && Clock::now() < until) {
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
      r = send(Command::STATUS);
    }
    return r;
  }

  comm::Bus bus_;
  comm::Client<Command, Reply> client_{bus_,
                                       comm::unique_endpoint_name("test-ui"),
                                       "MP",
                                       channels::mp_command,
                                       channels::mp_reply,
                                       comm::ClientOptions{std::chrono::milliseconds(200), 5, {}}};
};

const char* kPoses =
    "[[0.6, -1.35, 0.15, 0.5, 1.0], [-0.5, -1.8, -0.2, -0.6, -1.2], [0.6, -1.35, 0.15, 0.5, 1.0], "
    "[0.0, -1.5708, 0.0, 0.0, 0.0]]";

}  // namespace

TEST_F(Operator, StartPauseResumeStopAndTerminate) {
  const std::string config =
      write_config("operator", "start = \"operator\"", "plugin = \"mujoco\"", kPoses);
  StateWatch states(bus_);
  BackgroundLaunch launch(config);
  Reply r = wait_for_mp(std::chrono::seconds(60));
  EXPECT_EQ(r.state, +Reply::IDLE) << r.text;
  EXPECT_EQ(r.task, "start_and_wait");
  EXPECT_EQ(r.runs, 0);
  // Commands that do not apply are refused with the reason, and nothing moves.
  r = send(Command::PAUSE);
  EXPECT_FALSE(r.accepted);
  EXPECT_NE(r.text.find("PAUSE refused: no task is running (state IDLE)"), std::string::npos)
      << r.text;
  r = send(Command::RESUME);
  EXPECT_FALSE(r.accepted);
  ASSERT_TRUE(states.wait_for([](const auto& s) { return !s.moving; }, std::chrono::seconds(5)));
  std::this_thread::sleep_for(std::chrono::milliseconds(500));
  EXPECT_LT(max_speed(states.last()), 1e-6) << "the robot moved before START";
  EXPECT_EQ(states.last().n_joints, 5);

  // START: the task runs and the robot moves.
  r = send(Command::START);
  EXPECT_TRUE(r.accepted) << r.text;
  EXPECT_EQ(r.state, +Reply::RUNNING);
  EXPECT_EQ(r.runs, 1);
  EXPECT_GT(r.started_utime, 0);
  ASSERT_TRUE(states.wait_for([](const auto& s) { return s.synchronised && max_speed(s) > 0.05; },
                              std::chrono::seconds(30)))
      << "the robot never moved after START";
  r = send(Command::START);
  EXPECT_FALSE(r.accepted) << "a second START while running";

  // PAUSE: the robot comes to a standstill and stays there; RESUME: it moves again.
  r = send(Command::PAUSE);
  EXPECT_TRUE(r.accepted) << r.text;
  EXPECT_EQ(r.state, +Reply::PAUSED);
  const auto paused =
      states.wait_for([](const auto& s) { return max_speed(s) < 1e-3; }, std::chrono::seconds(5));
  ASSERT_TRUE(paused) << "still moving 5 s after PAUSE";
  const std::vector<double> held = paused->q;
  std::this_thread::sleep_for(std::chrono::seconds(1));
  const auto still = states.last();
  for (std::size_t i = 0; i < held.size(); ++i)
    EXPECT_NEAR(still.q[i], held[i], 1e-3) << "axis " << i << " moved while paused";
  EXPECT_EQ(send(Command::STATUS).state, +Reply::PAUSED);
  r = send(Command::RESUME);
  EXPECT_TRUE(r.accepted) << r.text;
  EXPECT_EQ(r.state, +Reply::RUNNING);
  ASSERT_TRUE(
      states.wait_for([](const auto& s) { return max_speed(s) > 0.05; }, std::chrono::seconds(10)))
      << "the robot did not move again after RESUME";

  // The run finishes at the last pose.
  r = wait_for_state(Reply::FINISHED, std::chrono::seconds(60));
  // Pausing stopped the robot off its planned path; the task went on from where it stood: no
  // commanded motion ever exceeded a joint's velocity limit.
  const RobotModel model = load_robot_model(std::string(MRROC_SOURCE_DIR) + "/robots/irb6");
  const std::vector<double> rates = states.max_desired_rate();
  ASSERT_EQ(rates.size(), model.axes());
  for (std::size_t i = 0; i < rates.size(); ++i) {
    EXPECT_LE(rates[i], model.max_velocity[i] * 1.001) << "joint " << i;
    std::printf("joint %zu: fastest commanded %.3f rad/s (limit %.3f)\n", i, rates[i],
                model.max_velocity[i]);
  }
  ASSERT_EQ(r.state, +Reply::FINISHED) << r.text;
  const auto end =
      states.wait_for([](const auto& s) { return !s.moving; }, std::chrono::seconds(5));
  ASSERT_TRUE(end);
  const std::vector<double> home{0.0, -1.5708, 0.0, 0.0, 0.0};
  for (std::size_t i = 0; i < home.size(); ++i) EXPECT_NEAR(end->q[i], home[i], 2e-3) << i;

  // A second run, stopped by the operator: the robot holds, the run counts as failed.
  r = send(Command::START);
  EXPECT_TRUE(r.accepted) << r.text;
  EXPECT_EQ(r.runs, 2);
  ASSERT_TRUE(
      states.wait_for([](const auto& s) { return max_speed(s) > 0.05; }, std::chrono::seconds(30)));
  r = send(Command::STOP);
  EXPECT_TRUE(r.accepted) << r.text;
  r = wait_for_state(Reply::FAILED, std::chrono::seconds(20));
  EXPECT_EQ(r.state, +Reply::FAILED);
  EXPECT_NE(r.text.find("stopped by the operator"), std::string::npos) << r.text;
  EXPECT_TRUE(states.wait_for([](const auto& s) { return max_speed(s) < 1e-3 && !s.moving; },
                              std::chrono::seconds(5)))
      << "the robot did not come to a standstill after STOP";

  // TERMINATE ends the MP and so the set; the last run failed: the launcher says so.
  r = send(Command::TERMINATE);
  EXPECT_TRUE(r.accepted);
  EXPECT_EQ(r.state, +Reply::TERMINATING);
  const LaunchRun run = launch.wait();
  EXPECT_EQ(run.exit_code, 1) << run.output;
  EXPECT_TRUE(has(run.output, "START from the operator")) << run.output;
  EXPECT_TRUE(has(run.output, "PAUSE from the operator")) << run.output;
  EXPECT_TRUE(has(run.output, "TERMINATE from the operator")) << run.output;
  expect_nothing_left();
}

// A task with sensors runs any number of times in one set: each run's ECP makes its VSP clients
// again under the same endpoint name, and the VSPs answer them (they once dropped the second
// run's requests as stale: "VSP 'wrist_force' did not answer CONFIGURE").
TEST_F(Operator, ASensorTaskRunsTwiceInOneSet) {
  std::ifstream in(std::string(MRROC_SOURCE_DIR) + "/configs/sensing-touch.toml");
  std::stringstream text;
  text << in.rdbuf();
  std::string config = text.str();
  const std::string dir = MRROC_SOURCE_DIR;
  for (const auto& [from, to] : std::vector<std::pair<std::string, std::string>>{
           {"scene = \"scenes/", "scene = \"" + dir + "/configs/scenes/"},
           {"model = \"../robots/", "model = \"" + dir + "/robots/"},
           {"task = \"start_and_wait\"", "task = \"start_and_wait\"\nstart = \"operator\""}}) {
    const auto at = config.find(from);
    ASSERT_NE(at, std::string::npos) << from;
    config.replace(at, from.size(), to);
  }
  const fs::path file = fs::temp_directory_path() / ("mrroc-operator-" + std::to_string(getpid())) /
                        "sensing-twice.toml";
  fs::create_directories(file.parent_path());
  std::ofstream(file) << config;
  BackgroundLaunch launch(file.string());
  Reply r = wait_for_mp(std::chrono::seconds(60));
  ASSERT_EQ(r.state, +Reply::IDLE) << r.text;
  for (int run = 1; run <= 2; ++run) {
    r = send(Command::START);
    ASSERT_TRUE(r.accepted) << "run " << run << ": " << r.text;
    EXPECT_EQ(r.runs, run);
    r = wait_for_state(Reply::FINISHED, std::chrono::seconds(60));
    ASSERT_EQ(r.state, +Reply::FINISHED) << "run " << run << ": " << r.text;
  }
  r = send(Command::TERMINATE);
  EXPECT_TRUE(r.accepted) << r.text;
  const LaunchRun run = launch.wait();
  EXPECT_EQ(run.exit_code, 0) << run.output;
  // Each run touched the table: the ECP's report, printed once (the SRP's line).
  const std::regex touched("ecp/irb6 +info +touched: first contact");
  const auto touches = std::distance(
      std::sregex_iterator(run.output.begin(), run.output.end(), touched), std::sregex_iterator());
  EXPECT_EQ(touches, 2) << run.output;
  EXPECT_FALSE(has(run.output, "did not answer")) << run.output;
  expect_nothing_left();
}

TEST_F(Operator, TerminateWhileIdleEndsTheSetCleanly) {
  const std::string config = write_config("idle", "start = \"operator\"", "plugin = \"mujoco\"",
                                          "[[0.0, -1.5708, 0.0, 0.0, 0.0]]");
  BackgroundLaunch launch(config);
  Reply r = wait_for_mp(std::chrono::seconds(60));
  EXPECT_EQ(r.state, +Reply::IDLE);
  r = send(Command::TERMINATE);
  EXPECT_TRUE(r.accepted);
  const LaunchRun run = launch.wait();
  EXPECT_EQ(run.exit_code, 0) << run.output;
  expect_nothing_left();
}

TEST_F(Operator, AutoStartRefusesStart) {
  const std::string config = write_config("auto", "", "plugin = \"mujoco\"", kPoses);
  BackgroundLaunch launch(config);
  Reply r = wait_for_mp(std::chrono::seconds(60));
  if (r.state == Reply::RUNNING) {
    r = send(Command::START);
    EXPECT_FALSE(r.accepted);
    EXPECT_NE(r.text.find("starts by itself"), std::string::npos) << r.text;
  }
  const LaunchRun run = launch.wait();
  EXPECT_EQ(run.exit_code, 0) << run.output;
}

TEST_F(Operator, RobotStateCarriesJointsVelocitiesAndTiming) {
  const std::string config = write_config("state", "", "plugin = \"mujoco\"", kPoses);
  StateWatch states(bus_);
  BackgroundLaunch launch(config);
  // While moving: velocities agree with the change of position between two states.
  const auto a =
      states.wait_for([](const auto& s) { return max_speed(s) > 0.2; }, std::chrono::seconds(60));
  ASSERT_TRUE(a);
  const auto b = states.wait_for([](const auto&) { return true; }, std::chrono::seconds(1));
  ASSERT_TRUE(b);
  EXPECT_GT(b->servo_step, a->servo_step);
  const double dt = static_cast<double>(b->servo_step - a->servo_step) * b->servo_period_s;
  double best = 1e9;
  for (std::size_t i = 0; i < a->q.size(); ++i)
    if (std::abs(a->dq[i]) > 0.2)
      best = std::min(best, std::abs((b->q[i] - a->q[i]) / dt - (a->dq[i] + b->dq[i]) / 2) /
                                std::abs(a->dq[i]));
  EXPECT_LT(best, 0.25) << "velocity does not match the change of position";
  EXPECT_TRUE(b->synchronised);
  EXPECT_TRUE(b->moving);
  EXPECT_FALSE(b->estop);
  EXPECT_FALSE(b->fault);
  EXPECT_DOUBLE_EQ(b->servo_period_s, 0.002);
  EXPECT_GE(b->lateness_max_us, b->lateness_mean_us);
  EXPECT_GT(b->lateness_mean_us, 0.0);
  // States come every 20 ms.
  const int before = states.count();
  std::this_thread::sleep_for(std::chrono::seconds(1));
  const int per_second = states.count() - before;
  EXPECT_GE(per_second, 40);
  EXPECT_LE(per_second, 60);
  const LaunchRun run = launch.wait();
  EXPECT_EQ(run.exit_code, 0) << run.output;
}

// A servo cycle whose hardware read blocks for 80 ms: the loop notices the overrun, reports it to
// the SRP at once with the cycle's own work (80 ms: the plugin, not the host), skips the missed
// periods instead of bursting, and the task still finishes.
TEST_F(Operator, StalledServoLoopIsDetectedAndReported) {
  const std::string config =
      write_config("stall", "",
                   "plugin = \"faulty\"\n[robot.edp.params]\nfault = \"stall\"\nstall_ms = 80\n"
                   "fault_after_cycles = 1500",
                   kPoses);
  StateWatch states(bus_);
  BackgroundLaunch launch(config);
  const auto overrun =
      states.wait_for([](const auto& s) { return s.overruns > 0 && s.lateness_max_us >= 75000.0; },
                      std::chrono::seconds(60));
  ASSERT_TRUE(overrun) << "no 80 ms overrun seen in the robot state";
  EXPECT_GE(overrun->overruns, 1);  // the stall; a slow (instrumented) build may add its own
  EXPECT_GE(overrun->lateness_max_us, 75000.0);
  const LaunchRun run = launch.wait();
  EXPECT_EQ(run.exit_code, 0) << run.output;
  EXPECT_TRUE(std::regex_search(
      run.output,
      std::regex("edp/irb6.*warning.*\\[11\\] servo loop overrun: [0-9]+ cycle\\(s\\) "
                 "woke more than one period \\(2000 us\\) late, the worst [0-9]{5,} us")))
      << run.output;
  // The report puts the blame where it was: the cycle itself worked 80 ms (the plugin's read).
  EXPECT_TRUE(std::regex_search(
      run.output, std::regex("the worst [0-9]{5,} us; missed periods were skipped(, and the "
                             "simulation makes them up between cycles \\([0-9]+ so far\\))?; "
                             "the longest cycle worked [0-9]{5,} us and waited [0-9]+ us for its "
                             "lock\n")))
      << run.output;
  EXPECT_TRUE(std::regex_search(run.output,
                                std::regex("servo loop: [0-9]+ cycles .* [1-9][0-9]* overruns")))
      << run.output;
}

// With [system] auth_key_file, a publisher without the key on the same bus can neither start the
// task nor move a robot (a foreign SYNCHRO straight to the EDP), and each attempt is reported to
// the SRP; an operator tool with the key works as before.
TEST(Authentication, AForeignPublisherCannotMoveARobot) {
  const fs::path key =
      fs::temp_directory_path() / ("mrroc-operator-key-" + std::to_string(getpid()));
  std::ofstream(key) << "00112233445566778899aabbccddeeff00112233445566778899aabbccddeeff\n";
  fs::permissions(key, fs::perms::owner_read | fs::perms::owner_write);
  const std::string config =
      write_config("auth", "start = \"operator\"", "plugin = \"mujoco\"",
                   "[[0.3, -1.4, 0.1, 0.2, 0.3], [0.0, -1.5708, 0.0, 0.0, 0.0]]",
                   "auth_key_file = \"" + key.string() + "\"");
  comm::Bus stranger(kUrl);  // no key
  comm::Bus operator_bus(kUrl);
  comm::enable_auth_from_file(operator_bus, key);
  StateWatch states(stranger);
  stranger.start();
  operator_bus.start();
  comm::Client<Command, Reply> foreign(stranger, comm::unique_endpoint_name("intruder"), "MP",
                                       channels::mp_command, channels::mp_reply,
                                       comm::ClientOptions{std::chrono::milliseconds(100), 3, {}});
  comm::Client<Command, Reply> ui(operator_bus, comm::unique_endpoint_name("ui"), "MP",
                                  channels::mp_command, channels::mp_reply,
                                  comm::ClientOptions{std::chrono::milliseconds(200), 5, {}});
  BackgroundLaunch launch(config);
  Command status{};
  status.command = Command::STATUS;
  Reply r{};
  const auto until = Clock::now() + std::chrono::seconds(60);
  for (;;) {
    try {
      r = ui.call(status);
      break;
    } catch (const TimeoutError&) {
      ASSERT_LT(Clock::now(), until) << "the MP never answered the operator with the key";
    }
  }
  EXPECT_EQ(r.state, +Reply::IDLE);
  const auto before = states.wait_for([](const auto&) { return true; }, std::chrono::seconds(5));
  ASSERT_TRUE(before);
  EXPECT_FALSE(before->synchronised);

  // The stranger's START gets no answer and starts nothing.
  Command start{};
  start.command = Command::START;
  EXPECT_THROW((void)foreign.call(start), TimeoutError);
  // The stranger's SYNCHRO straight to the EDP (it would move every axis) is dropped.
  mrroc_lcm::edp_instruction_t synchro{};
  synchro.header.sender = "intruder#1";
  synchro.header.seq = 1;
  synchro.header.utime = now_utime();
  synchro.instruction = mrroc_lcm::edp_instruction_t::SYNCHRO;
  for (int i = 0; i < 3; ++i) {
    stranger.lcm().publish(channels::edp_command("irb6"), &synchro);
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
  std::this_thread::sleep_for(std::chrono::seconds(1));
  const auto after = states.last();
  EXPECT_FALSE(after.synchronised) << "the foreign SYNCHRO was executed";
  for (std::size_t i = 0; i < after.q.size(); ++i)
    EXPECT_NEAR(after.q[i], before->q[i], 1e-6) << "axis " << i << " moved";
  r = ui.call(status);
  EXPECT_EQ(r.state, +Reply::IDLE) << "the foreign START started the task";
  EXPECT_EQ(r.runs, 0);

  // The operator with the key starts the task; it runs to the end.
  r = ui.call(start);
  EXPECT_TRUE(r.accepted) << r.text;
  const auto until_done = Clock::now() + std::chrono::seconds(60);
  while (r.state != Reply::FINISHED && r.state != Reply::FAILED && Clock::now() < until_done) {
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
    r = ui.call(status);
  }
  EXPECT_EQ(r.state, +Reply::FINISHED) << r.text;
  Command terminate{};
  terminate.command = Command::TERMINATE;
  (void)ui.call(terminate);
  const LaunchRun run = launch.wait();
  stranger.stop();
  operator_bus.stop();
  fs::remove(key);
  EXPECT_EQ(run.exit_code, 0) << run.output;
  EXPECT_TRUE(std::regex_search(run.output,
                                std::regex("mp .*\\[12\\] dropped a message on 'mrroc/mp/cmd' from "
                                           "'intruder#[0-9]+': no authentication tag")))
      << run.output;
  EXPECT_TRUE(std::regex_search(
      run.output, std::regex("edp/irb6 .*\\[12\\] dropped a message on 'irb6/edp/cmd' from "
                             "'intruder#1': no authentication tag")))
      << run.output;
  EXPECT_TRUE(has(run.output, "task 'start_and_wait' finished")) << run.output;
  expect_nothing_left();
}
