// The web console's parts, each alone and without a bus: the state (fed plain values), jogging
// (its checks, the rest-to-rest profile, the EDP's refusal, one jog at a time; through a link
// that records what it is asked to do), teach-in (the file it writes, in a temporary folder)
// and the HTTP API (an in-process server on a loopback port: JSON shapes, error codes for
// malformed bodies, the token and cross-site checks), the generated token and its file, and the
// server's limits against hostile clients (slow senders, too many connections, huge bodies, a
// flood of idle connections beside the emergency stop).
#include <fmt/format.h>
#include <gtest/gtest.h>

#include <arpa/inet.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/resource.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <future>
#include <limits>
#include <map>
#include <mutex>
#include <sstream>
#include <string>
#include <string_view>
#include <thread>
#include <tuple>
#include <vector>

#include "console/http_api.hpp"
#include "console/jog.hpp"
#include "console/state.hpp"
#include "console/teach_in.hpp"
#include "console/token.hpp"
#include "mrroc/ecp/generators/trajectory_file.hpp"
#include "mrroc/ecp/robot_image.hpp"

// Last: <httplib.h>, which it includes, includes <resolv.h>, which defines `_res`, a name Eigen's
// headers use.
#include "console/http_server.hpp"

using namespace mrroc;
using namespace mrroc::ui;
using json = nlohmann::json;
using namespace std::chrono_literals;

namespace {

const RobotModel& irb6() {
  static const RobotModel m = load_robot_model(std::string(MRROC_SOURCE_DIR) + "/robots/irb6");
  return m;
}

std::vector<ConsoleRobot> one_robot() { return {ConsoleRobot{"irb6", irb6(), 0.002}}; }

/// A robot state of the irb6 at rest, synchronised, released, without fault.
RobotState robot_state(std::int64_t step, std::vector<double> q = {}) {
  RobotState s;
  s.robot = "irb6";
  s.synchronised = true;
  s.servo_step = step;
  s.servo_period_s = 0.002;
  s.q = q.empty() ? std::vector<double>(irb6().axes(), 0.1) : q;
  s.dq.assign(irb6().axes(), 0.0);
  s.q_desired = s.q;
  return s;
}

/// Hands `s` to the state as the bus feed does, sent at a time that follows from its step.
void on_state(ConsoleState& state, const RobotState& s,
              SteadyClock::time_point received = SteadyClock::now()) {
  state.on_robot_state(0, s, 1'700'000'000'000'000 + s.servo_step * 2000, received);
}

/// Hands the MP's answer to STATUS, its task in state `task` ("IDLE", ...), to the state as the
/// bus feed's poller does.
void mp_is(ConsoleState& state, const std::string& task,
           SteadyClock::time_point received = SteadyClock::now()) {
  MpStatus mp;
  mp.accepted = true;
  mp.state = task;
  state.on_mp_status(mp, received);
}

SrpMessage message(std::int64_t utime, const std::string& text,
                   Severity severity = Severity::info) {
  SrpMessage m;
  m.utime = utime;
  m.process = "edp/irb6";
  m.robot = "irb6";
  m.severity = severity;
  m.text = text;
  return m;
}

/// The HTTP status and text of the ApiError `f` throws (status 0: it threw none).
template <class F>
std::pair<int, std::string> api_error(F&& f) {
  try {
    f();
  } catch (const ApiError& e) {
    return {e.status, e.what()};
  }
  return {0, ""};
}

bool has(const std::string& text, const std::string& part) {
  return text.find(part) != std::string::npos;
}

/// Reports sent to the SRP, kept for the assertions.
struct Reports {
  std::mutex mutex;
  std::vector<std::pair<Severity, std::string>> sent;
  ReportFn fn() {
    return [this](Severity s, const std::string& t) {
      std::lock_guard lock(mutex);
      sent.emplace_back(s, t);
    };
  }
};

/// A jog link that records what it was asked and answers as told; it can hold the motion until
/// released, to test one jog at a time.
struct RecordingLink : JogLink {
  struct Shared {
    std::mutex mutex;
    std::condition_variable cv;
    std::vector<std::pair<std::vector<double>, int>> calls;
    std::vector<double> joints_after;
    std::string refuse;  // non-empty: throw JogRefused with it
    bool timeout = false;
    bool hold = false;  // block until `hold` is false again
    bool entered = false;
    int synchronisations = 0;
    std::vector<std::pair<std::vector<double>, int>> tool_calls;
  };
  std::shared_ptr<Shared> shared = std::make_shared<Shared>();
  std::vector<double> move_joints_relative(const std::vector<double>& delta,
                                           int motion_steps) override {
    std::unique_lock lock(shared->mutex);
    shared->calls.emplace_back(delta, motion_steps);
    shared->entered = true;
    shared->cv.notify_all();
    shared->cv.wait(lock, [&] { return !shared->hold; });
    if (!shared->refuse.empty()) throw JogRefused(shared->refuse);
    if (shared->timeout) throw TimeoutError("no EDP irb6 answers");
    return shared->joints_after;
  }
  std::vector<double> move_tool_relative(const std::vector<double>& delta,
                                         int motion_steps) override {
    std::lock_guard lock(shared->mutex);
    shared->tool_calls.emplace_back(delta, motion_steps);
    if (!shared->refuse.empty()) throw JogRefused(shared->refuse);
    return shared->joints_after;
  }
  std::vector<double> synchronise() override {
    std::lock_guard lock(shared->mutex);
    ++shared->synchronisations;
    if (!shared->refuse.empty()) throw JogRefused(shared->refuse);
    if (shared->timeout) throw TimeoutError("no EDP irb6 answers");
    return shared->joints_after;
  }
};

/// A state with one robot, a jogger on a recording link, and a teach-in.
struct Parts {
  ConsoleState state{"demo", one_robot()};
  Reports reports;
  std::shared_ptr<RecordingLink::Shared> link;
  std::unique_ptr<Jogger> jogger;
  Parts() {
    auto l = std::make_unique<RecordingLink>();
    link = l->shared;
    std::map<std::string, std::unique_ptr<JogLink>> links;
    links["irb6"] = std::move(l);
    jogger = std::make_unique<Jogger>(state, JogOptions{}, std::move(links), reports.fn());
  }
};

/// A fresh folder per test under the system's temporary folder.
class TempDir {
 public:
  TempDir() {
    path_ = std::filesystem::temp_directory_path() /
            ("mrroc-console-" + std::to_string(::getpid()) + "-" +
             ::testing::UnitTest::GetInstance()->current_test_info()->name());
    std::filesystem::remove_all(path_);
  }
  ~TempDir() {
    std::error_code ec;
    std::filesystem::remove_all(path_, ec);
  }
  TempDir(const TempDir&) = delete;
  TempDir& operator=(const TempDir&) = delete;
  [[nodiscard]] const std::filesystem::path& path() const { return path_; }

 private:
  std::filesystem::path path_;
};

std::string read_file(const std::filesystem::path& p) {
  std::ifstream in(p);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

}  // namespace

// --- state -----------------------------------------------------------------------------------

TEST(ConsoleState, KeepsTheLatestRobotStateAndItsSamples) {
  ConsoleState state("demo", one_robot());
  EXPECT_FALSE(state.reading(0).has_value());
  on_state(state, robot_state(10));
  on_state(state, robot_state(20, {0.5, -1.0, 0.2, 0.0, 0.3}));
  const auto r = state.reading(0);
  ASSERT_TRUE(r.has_value());
  EXPECT_EQ(r->state.servo_step, 20);
  EXPECT_DOUBLE_EQ(r->state.q[1], -1.0);
  EXPECT_TRUE(r->fresh());
  const auto samples = state.samples_after(0, 10);
  ASSERT_EQ(samples.size(), 1u);
  EXPECT_EQ(samples[0].step, 20);
  EXPECT_EQ(state.samples_after(0, 0).size(), 2u);
  // A state with another number of joints than the model's is not this robot's: ignored.
  auto wrong = robot_state(30);
  wrong.q.resize(3);
  on_state(state, wrong);
  EXPECT_EQ(state.reading(0)->state.servo_step, 20);
  // The same step again (the EDP's state thread ran while its servo loop stalled, as on a busy
  // host) or a slightly older one: the reading, but no new sample, and the samples stay.
  on_state(state, robot_state(20));
  on_state(state, robot_state(15));
  EXPECT_EQ(state.samples_after(0, 0).size(), 2u);
  // Far behind the last sample: the EDP started again; the old samples go.
  on_state(state, robot_state(20 + kRestartSteps));
  on_state(state, robot_state(5));
  const auto after_restart = state.samples_after(0, -1);
  ASSERT_EQ(after_restart.size(), 1u);
  EXPECT_EQ(after_restart[0].step, 5);
}

TEST(ConsoleState, KeepsAtMostThirtySecondsOfSamples) {
  ConsoleState state("demo", one_robot());
  for (std::int64_t step = 1; step <= static_cast<std::int64_t>(kMaxSamples) + 100; ++step)
    on_state(state, robot_state(step));
  const auto samples = state.samples_after(0, 0);
  ASSERT_EQ(samples.size(), kMaxSamples);
  EXPECT_EQ(samples.front().step, 101);
}

TEST(ConsoleState, StaleStatesAndLauncherTables) {
  ConsoleState state("demo", one_robot());
  on_state(state, robot_state(1), SteadyClock::now() - 2s);
  EXPECT_FALSE(state.reading(0)->fresh());
  launch::LaunchStatus launch;
  launch.set_name = "demo";
  launch.state = "running";
  state.on_launch_status(launch, SteadyClock::now() - 5s);
  EXPECT_FALSE(state.snapshot().launch.has_value()) << "a table older than 3 s is not shown";
  state.on_launch_status(launch);
  ASSERT_TRUE(state.snapshot().launch.has_value());
  EXPECT_EQ(state.snapshot().launch->state, "running");
  ProcessStatus p;
  p.process = "mp";
  p.state = ProcessState::ready;
  state.on_process_status(p, SteadyClock::now() - 2s);
  const auto snap = state.snapshot();
  ASSERT_EQ(snap.processes.count("mp"), 1u);
  EXPECT_NEAR(snap.processes.at("mp").silent_s, 2.0, 0.5);
  ASSERT_EQ(snap.robots.size(), 1u);
  EXPECT_NEAR(snap.robots[0].age_s, 2.0, 0.5);
}

TEST(ConsoleState, MpStatusAndSilence) {
  ConsoleState state("demo", one_robot());
  MpStatus s;
  s.accepted = true;
  s.state = "RUNNING";
  state.on_mp_status(s);
  EXPECT_EQ(state.mp()->state, "RUNNING");
  state.on_mp_silent("no MP answers on 'mrroc/mp/cmd'");
  EXPECT_FALSE(state.mp().has_value());
  EXPECT_EQ(state.snapshot().mp_error, "no MP answers on 'mrroc/mp/cmd'");
  state.on_mp_status(s);
  EXPECT_EQ(state.snapshot().mp_error, "");
  // An answer older than kMpFreshS (the poller stopped or hangs): the state is unknown again.
  state.on_mp_status(s, SteadyClock::now() - 2500ms);
  EXPECT_FALSE(state.mp().has_value()) << "a stale MP state was kept";
  ASSERT_TRUE(state.mp_reading().has_value());
  EXPECT_FALSE(state.mp_reading()->fresh());
  EXPECT_EQ(state.mp_reading()->status.state, "RUNNING");
  const auto snap = state.snapshot();
  EXPECT_FALSE(snap.mp.has_value());
  EXPECT_TRUE(has(snap.mp_error, "no answer from the MP for 2.5 s (the last said RUNNING)"))
      << snap.mp_error;
}

TEST(ConsoleState, NumbersFiltersAndMergesTheSrpLog) {
  ConsoleState state("demo", one_robot());
  state.on_message(message(100, "live one"));
  state.on_message(message(200, "live two", Severity::error));
  state.on_message(message(300, "live three"));
  auto log = state.messages(0, 0, 1000);
  ASSERT_EQ(log.entries.size(), 3u);
  EXPECT_EQ(log.entries[2].number, 3);
  EXPECT_EQ(log.last, 3);
  EXPECT_EQ(log.epoch, 1);
  EXPECT_FALSE(log.history_loaded);
  EXPECT_EQ(state.messages(1, 0, 1000).entries.size(), 2u);
  const auto errors = state.messages(0, static_cast<int>(Severity::error), 1000);
  ASSERT_EQ(errors.entries.size(), 1u);
  EXPECT_EQ(errors.entries[0].message.text, "live two");
  const auto newest = state.messages(0, 0, 2);
  ASSERT_EQ(newest.entries.size(), 2u);
  EXPECT_EQ(newest.entries[0].message.text, "live two");
  // The SRP's history holds older messages and one that also came live: one copy each,
  // history first, numbered again, and the epoch changes.
  state.merge_history({message(10, "before the console"), message(200, "live two")}, 77);
  EXPECT_TRUE(state.history_loaded());
  log = state.messages(0, 0, 1000);
  ASSERT_EQ(log.entries.size(), 4u);
  EXPECT_EQ(log.entries[0].message.text, "before the console");
  EXPECT_EQ(log.entries[1].message.text, "live two");
  EXPECT_EQ(log.entries[2].message.text, "live one");
  EXPECT_EQ(log.entries[3].number, 4);
  EXPECT_EQ(log.epoch, 2);
  EXPECT_EQ(log.srp_last, 77);
  state.on_message(message(400, "after"));
  EXPECT_EQ(state.messages(4, 0, 1000).entries.at(0).number, 5);
}

TEST(ConsoleState, KeepsAtMostFiveThousandMessages) {
  ConsoleState state("demo", one_robot());
  for (std::int64_t i = 1; i <= static_cast<std::int64_t>(kMaxLog) + 10; ++i)
    state.on_message(message(i, "m"));
  const auto log = state.messages(0, 0, 100000);
  ASSERT_EQ(log.entries.size(), kMaxLog);
  EXPECT_EQ(log.entries.front().number, 11);
}

TEST(ConsoleState, UnknownRobotNamesTheSetsRobots) {
  ConsoleState state("demo", one_robot());
  const auto [status, text] = api_error([&] { (void)state.robot("nope"); });
  EXPECT_EQ(status, 404);
  EXPECT_EQ(text, "no robot 'nope' in set 'demo' (robots: irb6)");
  EXPECT_EQ(state.robot_index("irb6"), 0u);
}

TEST(ConsoleState, EstimatesTheServoStepNow) {
  ConsoleState state("demo", one_robot());
  EXPECT_TRUE(state.estimated_servo_steps("").empty()) << "no state: no estimate";
  on_state(state, robot_state(1000), SteadyClock::now() - 1s);
  const auto steps = state.estimated_servo_steps("");
  ASSERT_EQ(steps.count("irb6"), 1u);
  // 1 s at 2 ms per step after step 1000 (the test may be slow: allow 0.2 s more).
  EXPECT_GE(steps.at("irb6"), 1500);
  EXPECT_LE(steps.at("irb6"), 1600);
  EXPECT_TRUE(state.estimated_servo_steps("other").empty());
}

TEST(ConsoleState, AtRestOnlyFromAStateAfterTheGivenTime) {
  ConsoleState state("demo", one_robot());
  const auto t0 = SteadyClock::now();
  on_state(state, robot_state(1), t0 - 10ms);
  EXPECT_FALSE(state.at_rest_since(0, t0));
  auto moving = robot_state(2);
  moving.moving = true;
  on_state(state, moving, t0 + 10ms);
  EXPECT_FALSE(state.at_rest_since(0, t0));
  on_state(state, robot_state(3), t0 + 20ms);
  EXPECT_TRUE(state.at_rest_since(0, t0));
}

TEST(ConsoleState, WritersAndReadersOnOtherThreads) {
  ConsoleState state("demo", one_robot());
  std::atomic<bool> done{false};
  std::thread writer([&] {
    for (std::int64_t step = 1; step <= 3000; ++step) {
      on_state(state, robot_state(step, std::vector<double>(5, static_cast<double>(step))));
      state.on_message(message(step, "m"));
    }
    done.store(true);
  });
  std::size_t reads = 0;
  while (!done.load()) {
    // Every sample is whole: its positions are its step, written together.
    for (const Sample& s : state.samples_after(0, 0))
      ASSERT_EQ(s.q[4], static_cast<double>(s.step));
    const auto snap = state.snapshot();
    if (const auto& r = snap.robots[0].reading) {
      ASSERT_EQ(r->state.q[0], static_cast<double>(r->state.servo_step));
    }
    ++reads;
  }
  writer.join();
  EXPECT_EQ(state.reading(0)->state.servo_step, 3000);
  EXPECT_EQ(state.messages(0, 0, 10).last, 3000);
  EXPECT_GT(reads, 0u);
}

// --- jog ---------------------------------------------------------------------------------------

TEST(Jog, MovesOneAxisFromRestToRestWithinAQuarterOfItsLimits) {
  Parts p;
  mp_is(p.state, "IDLE");
  on_state(p.state, robot_state(100));
  p.link->joints_after = {0.1, 0.1, 0.0, 0.1, 0.1};
  // The EDP's broadcast shows the robot at rest after the motion (else the jog waits 100 ms).
  std::thread broadcaster([&] {
    std::this_thread::sleep_for(20ms);
    on_state(p.state, robot_state(700, {0.1, 0.1, 0.0, 0.1, 0.1}));
  });
  const JogResult r = p.jogger->jog(JogRequest{"irb6", 2, 0.1, -1});
  broadcaster.join();
  ASSERT_EQ(p.link->calls.size(), 1u);
  const auto& [delta, steps] = p.link->calls[0];
  EXPECT_EQ(delta, (std::vector<double>{0.0, 0.0, -0.1, 0.0, 0.0}));
  std::vector<double> magnitude(5, 0.0);
  magnitude[2] = 0.1;
  EXPECT_EQ(steps, ecp::rest_to_rest_steps(irb6(), magnitude, 0.25, 0.002, 0.1));
  // Peak velocity 2 d / T and acceleration 4 d / T^2 within a quarter of the axis' limits.
  const double t = steps * 0.002;
  EXPECT_LE(2 * 0.1 / t, 0.25 * irb6().max_velocity[2] + 1e-9);
  EXPECT_LE(4 * 0.1 / (t * t), 0.25 * irb6().max_acceleration[2] + 1e-9);
  EXPECT_GE(t, 0.1);
  EXPECT_EQ(r.motion_steps, steps);
  EXPECT_EQ(r.q_before, std::vector<double>(5, 0.1));
  EXPECT_EQ(r.q, p.link->joints_after);
  EXPECT_TRUE(has(r.text, "irb6 axis 2 (" + irb6().joint_names[2] + ") moved -0.1000 rad in " +
                              std::to_string(steps) + " servo steps"))
      << r.text;
  EXPECT_TRUE(has(r.text, ": 0.0000 rad")) << r.text;
  ASSERT_EQ(p.reports.sent.size(), 1u);
  EXPECT_EQ(p.reports.sent[0].first, Severity::info);
  EXPECT_EQ(p.reports.sent[0].second, "operator jog: " + r.text);
}

TEST(Jog, RefusesBadInputNamingValueUnitAndLimit) {
  Parts p;
  mp_is(p.state, "IDLE");
  on_state(p.state, robot_state(100));
  const std::vector<std::tuple<JogRequest, int, std::string>> cases = {
      {{"irb6", 99, 0.01, 1}, 400, "axis 99 is out of range: robot irb6 has axes 0..4"},
      {{"irb6", -1, 0.01, 1}, 400, "axis -1 is out of range: robot irb6 has axes 0..4"},
      {{"irb6", 0, 0.5, 1}, 400, "jog step 0.5 rad is outside (0, 0.2] rad"},
      {{"irb6", 0, 0.0, 1}, 400, "jog step 0 rad is outside (0, 0.2] rad"},
      {{"irb6", 0, -0.01, 1}, 400, "jog step -0.01 rad is outside (0, 0.2] rad"},
      {{"irb6", 0, std::numeric_limits<double>::quiet_NaN(), 1}, 400, "rad is outside (0, 0.2]"},
      {{"irb6", 0, 1e308, 1}, 400, "jog step 1e+308 rad is outside (0, 0.2] rad"},
      {{"nope", 0, 0.01, 1}, 404, "no robot 'nope' in set 'demo' (robots: irb6)"},
  };
  for (const auto& [request, status, text] : cases) {
    const JogRequest& jog = request;  // clang 14 captures no structured binding in a lambda
    const auto [got_status, got_text] = api_error([&] { (void)p.jogger->jog(jog); });
    EXPECT_EQ(got_status, status) << text;
    EXPECT_TRUE(has(got_text, text)) << got_text;
  }
  EXPECT_TRUE(p.link->calls.empty()) << "nothing was sent to the EDP";
}

TEST(Jog, RefusesWhatTheStateForbids) {
  Parts p;
  mp_is(p.state, "IDLE");
  const JogRequest request{"irb6", 0, 0.05, 1};
  auto refusal = [&] { return api_error([&] { (void)p.jogger->jog(request); }); };
  EXPECT_EQ(refusal(), std::make_pair(409, std::string("jogging refused: no robot_state_t from "
                                                       "EDP irb6 in the last 1 s")));
  on_state(p.state, robot_state(1), SteadyClock::now() - 1500ms);
  EXPECT_EQ(refusal().first, 409) << "a state older than 1 s is stale";
  auto s = robot_state(2);
  s.estop = true;
  on_state(p.state, s);
  EXPECT_EQ(refusal(), std::make_pair(409, std::string("jogging refused: the emergency stop of "
                                                       "irb6 is engaged; release it first")));
  s = robot_state(3);
  s.fault = true;
  s.error = "drive 2 over temperature";
  on_state(p.state, s);
  EXPECT_EQ(refusal().second,
            "jogging refused: irb6 has a hardware fault: drive 2 over temperature");
  s = robot_state(5);
  s.moving = true;
  on_state(p.state, s);
  EXPECT_EQ(refusal().second, "jogging refused: irb6 is moving");
  on_state(p.state, robot_state(6));
  for (const char* running : {"RUNNING", "PAUSED", "STOPPING"}) {
    MpStatus mp;
    mp.state = running;
    p.state.on_mp_status(mp);
    EXPECT_EQ(refusal(), std::make_pair(409, "jogging refused: the MP task is " +
                                                 std::string(running) + "; stop it first"));
  }
  mp_is(p.state, "TERMINATING");
  EXPECT_EQ(refusal(), std::make_pair(409, std::string("jogging refused: the MP task is "
                                                       "TERMINATING; jogging needs it IDLE, "
                                                       "FINISHED or FAILED")));
  EXPECT_TRUE(p.link->calls.empty());
  for (const char* resting : {"IDLE", "FINISHED", "FAILED"}) {
    mp_is(p.state, resting);
    EXPECT_EQ(p.jogger->check(request), std::vector<double>(5, 0.1)) << resting;
  }
}

// A robot at rest may be resting in the middle of a task: without a fresh answer from the MP
// saying its task is IDLE, FINISHED or FAILED, neither a jog nor a synchronisation takes it over.
TEST(Jog, RefusedWhileTheMpsStateIsUnknownOrStale) {
  Parts p;
  on_state(p.state, robot_state(1));
  p.link->joints_after.assign(5, 0.1);
  const JogRequest request{"irb6", 0, 0.05, 1};
  auto refusal = [&] { return api_error([&] { (void)p.jogger->jog(request); }); };
  auto sync_refusal = [&] { return api_error([&] { (void)p.jogger->synchronise("irb6"); }); };
  // No answer yet.
  EXPECT_EQ(refusal(),
            std::make_pair(409, std::string("jogging refused: the MP's state is unknown (no answer "
                                            "from the MP yet): a task may be running; jogging "
                                            "needs the MP answering and its task IDLE, FINISHED "
                                            "or FAILED")));
  EXPECT_EQ(sync_refusal().first, 409);
  EXPECT_TRUE(has(sync_refusal().second,
                  "synchronisation refused: the MP's state is unknown (no answer from the MP"))
      << sync_refusal().second;
  // It fell silent: the poller's text says where it was asked.
  mp_is(p.state, "IDLE");
  p.state.on_mp_silent("no MP answers on 'mrroc/mp/cmd'");
  EXPECT_EQ(refusal(),
            std::make_pair(409, std::string("jogging refused: the MP's state is unknown (no answer "
                                            "from the MP: no MP answers on 'mrroc/mp/cmd'): a "
                                            "task may be running; jogging needs the MP answering "
                                            "and its task IDLE, FINISHED or FAILED")));
  // Its last answer is stale (the asking stopped): IDLE then says nothing of now.
  mp_is(p.state, "IDLE", SteadyClock::now() - 3s);
  const auto [status, text] = refusal();
  EXPECT_EQ(status, 409);
  EXPECT_TRUE(has(text,
                  "jogging refused: the MP's state is unknown (no answer from the MP for "
                  "3.0 s, limit 2 s; the last said IDLE): a task may be running"))
      << text;
  EXPECT_TRUE(p.link->calls.empty()) << "nothing was sent to the EDP";
  EXPECT_EQ(p.link->synchronisations, 0);
  // A fresh IDLE: the jog goes out.
  mp_is(p.state, "IDLE");
  (void)p.jogger->jog(request);
  EXPECT_EQ(p.link->calls.size(), 1u);
}

TEST(Jog, TheEdpsRefusalAndSilence) {
  Parts p;
  mp_is(p.state, "IDLE");
  on_state(p.state, robot_state(1));
  p.link->refuse = "EDP irb6 refused SET: joint 0 target 3.2 rad exceeds upper limit 2.9 rad";
  const auto [status, text] = api_error([&] { (void)p.jogger->jog({"irb6", 0, 0.1, 1}); });
  EXPECT_EQ(status, 409);
  EXPECT_EQ(text, p.link->refuse);
  ASSERT_EQ(p.reports.sent.size(), 1u);
  EXPECT_EQ(p.reports.sent[0].first, Severity::warning);
  EXPECT_TRUE(has(p.reports.sent[0].second, "operator jog of irb6 axis 0 (" +
                                                irb6().joint_names[0] +
                                                ") by +0.1000 rad refused: EDP irb6 refused"))
      << p.reports.sent[0].second;
  p.link->refuse.clear();
  p.link->timeout = true;
  EXPECT_EQ(api_error([&] { (void)p.jogger->jog({"irb6", 0, 0.1, 1}); }).first, 504);
}

TEST(Jog, OneJogOfARobotAtATime) {
  Parts p;
  mp_is(p.state, "IDLE");
  on_state(p.state, robot_state(1));
  p.link->hold = true;
  p.link->joints_after.assign(5, 0.1);
  auto first = std::async(std::launch::async, [&] { return p.jogger->jog({"irb6", 0, 0.1, 1}); });
  {
    std::unique_lock lock(p.link->mutex);
    ASSERT_TRUE(p.link->cv.wait_for(lock, 5s, [&] { return p.link->entered; }));
  }
  EXPECT_EQ(
      api_error([&] {
        (void)p.jogger->jog({"irb6", 1, 0.1, 1});
      }),
      std::make_pair(409, std::string("jogging refused: a jog or synchronisation of irb6 is in "
                                      "progress")));
  {
    std::lock_guard lock(p.link->mutex);
    p.link->hold = false;
    p.link->cv.notify_all();
  }
  EXPECT_EQ(first.get().motion_steps, p.link->calls.at(0).second);
  EXPECT_EQ(p.link->calls.size(), 1u);
}

TEST(Synchronise, OnlyARobotNotYetSynchronisedAtRestWithTheMpIdle) {
  Parts p;
  mp_is(p.state, "IDLE");
  // Already synchronised: nothing is sent, the answer says so.
  on_state(p.state, robot_state(1));
  JogResult r = p.jogger->synchronise("irb6");
  EXPECT_EQ(r.text, "irb6 is already synchronised");
  EXPECT_EQ(p.link->synchronisations, 0);

  auto s = robot_state(2);
  s.synchronised = false;
  auto refusal = [&] { return api_error([&] { (void)p.jogger->synchronise("irb6"); }); };
  MpStatus running;
  running.state = "RUNNING";
  p.state.on_mp_status(running);
  on_state(p.state, s);
  EXPECT_EQ(refusal(), std::make_pair(409, std::string("synchronisation refused: the MP task is "
                                                       "RUNNING; stop it first")));
  MpStatus idle;
  idle.state = "IDLE";
  p.state.on_mp_status(idle);
  s.servo_step = 3;
  s.estop = true;
  on_state(p.state, s);
  EXPECT_EQ(refusal(), std::make_pair(409, std::string("synchronisation refused: the emergency "
                                                       "stop of irb6 is engaged; release it "
                                                       "first")));
  s.servo_step = 4;
  s.estop = false;
  s.moving = true;
  on_state(p.state, s);
  EXPECT_EQ(refusal(), std::make_pair(409, std::string("synchronisation refused: irb6 is moving")));
  EXPECT_EQ(api_error([&] { (void)p.jogger->synchronise("nope"); }).first, 404);
  EXPECT_EQ(p.link->synchronisations, 0) << "nothing was sent while refused";

  // At rest, not synchronised, MP idle: SYNCHRO goes out once; the answer has the joints after.
  s.servo_step = 5;
  s.moving = false;
  on_state(p.state, s);
  p.link->joints_after = {0.0, -1.5708, 0.0, 0.0, 0.0};
  r = p.jogger->synchronise("irb6");
  EXPECT_EQ(p.link->synchronisations, 1);
  EXPECT_EQ(r.q, p.link->joints_after);
  EXPECT_TRUE(has(r.text, "irb6 synchronised at [0.0000, -1.5708")) << r.text;
  EXPECT_TRUE(p.link->calls.empty()) << "no jog was sent";

  // The EDP's refusal is the answer (409) and a warning to the SRP; silence is 504.
  p.link->refuse = "EDP irb6 refused SYNCHRO: hardware fault on axis 2";
  EXPECT_EQ(refusal(), std::make_pair(409, p.link->refuse));
  EXPECT_TRUE(has(p.reports.sent.back().second,
                  "operator synchronisation of irb6 refused: EDP irb6 refused SYNCHRO"))
      << p.reports.sent.back().second;
  EXPECT_EQ(p.reports.sent.back().first, Severity::warning);
  p.link->refuse.clear();
  p.link->timeout = true;
  EXPECT_EQ(refusal().first, 504);
}

TEST(Jog, TheToolFrameAlongAndAboutItsOwnAxes) {
  Parts p;
  mp_is(p.state, "IDLE");
  ASSERT_TRUE(p.jogger->cartesian("irb6"));
  const std::vector<double> q{0.3, -1.4, 0.1, 0.2, 0.4};
  on_state(p.state, robot_state(1, q));
  p.link->joints_after = q;
  // Along the tool's approach axis: the move the EDP makes of a relative XYZ_ANGLE_AXIS, with a
  // duration from the joints' change within a quarter of their limits.
  const JogResult r = p.jogger->jog({"irb6", 2, 0.01, -1, JogSpace::tool});
  ASSERT_EQ(p.link->tool_calls.size(), 1u);
  EXPECT_EQ(p.link->tool_calls[0].first, (std::vector<double>{0, 0, -0.01, 0, 0, 0}));
  const int steps = p.link->tool_calls[0].second;
  EXPECT_EQ(r.motion_steps, steps);
  EXPECT_GE(steps, 50) << "at least the shortest jog, 100 ms";
  EXPECT_TRUE(has(r.text, "irb6 tool z moved -0.0100 m in")) << r.text;
  EXPECT_TRUE(p.link->calls.empty()) << "no joint jog";
  // About the tool's own z axis (the wrist's roll).
  (void)p.jogger->jog({"irb6", 5, 0.1, 1, JogSpace::tool});
  ASSERT_EQ(p.link->tool_calls.size(), 2u);
  EXPECT_EQ(p.link->tool_calls[1].first, (std::vector<double>{0, 0, 0, 0, 0, 0.1}));
  // Bad input names the value, the unit and the limit; nothing moves.
  EXPECT_EQ(api_error([&] {
              (void)p.jogger->jog({"irb6", 0, 0.06, 1, JogSpace::tool});
            }),
            std::make_pair(400, std::string("jog step 0.06 m is outside (0, 0.05] m")));
  EXPECT_EQ(api_error([&] {
              (void)p.jogger->jog({"irb6", 4, 0.3, 1, JogSpace::tool});
            }),
            std::make_pair(400, std::string("jog step 0.3 rad is outside (0, 0.2] rad")));
  EXPECT_EQ(api_error([&] {
              (void)p.jogger->jog({"irb6", 6, 0.01, 1, JogSpace::tool});
            }),
            std::make_pair(400, std::string("tool axis 6 is out of range 0..5 (x y z rx ry rz)")));
  EXPECT_EQ(p.link->tool_calls.size(), 2u);
}

TEST(Jog, TheToolFrameOfARobotWithoutCartesianKinematicsIsRefused) {
  RobotModel conveyor =
      load_robot_model(std::filesystem::path(MRROC_SOURCE_DIR) / "robots" / "conveyor");
  ConsoleState state{"demo", {ConsoleRobot{"conveyor", conveyor, 0.002}}};
  Reports reports;
  std::map<std::string, std::unique_ptr<JogLink>> links;
  auto link = std::make_unique<RecordingLink>();
  auto shared = link->shared;
  links["conveyor"] = std::move(link);
  Jogger jogger(state, JogOptions{}, std::move(links), reports.fn());
  mp_is(state, "IDLE");
  EXPECT_FALSE(jogger.cartesian("conveyor"));
  RobotState s = robot_state(1, std::vector<double>(conveyor.axes(), 0.1));
  s.robot = "conveyor";
  on_state(state, s);
  EXPECT_EQ(api_error([&] {
              (void)jogger.jog({"conveyor", 0, 0.01, 1, JogSpace::tool});
            }),
            std::make_pair(409, std::string("tool jog refused: conveyor has no Cartesian "
                                            "kinematics (jog its joints)")));
  EXPECT_TRUE(shared->tool_calls.empty());
}

// Before SYNCHRO a joint jog is the EDP's motion before synchronisation: the same relative
// SET ARM JOINT, within the EDP's unsynchronised limits (0.1 of the axis' limits by default,
// not the jog's quarter), at most its unsynchronised_max_move, and marked in the text, the
// result and the report; a tool jog needs the position and points to Synchronise.
TEST(Synchronise, JoggingARobotNotSynchronisedIsSlowerBoundedAndMarked) {
  Parts p;
  mp_is(p.state, "IDLE");
  auto s = robot_state(1);
  s.synchronised = false;
  on_state(p.state, s);
  const ConsoleRobot& info = p.state.robots()[0];
  ASSERT_EQ(info.unsynchronised_fraction, 0.1);
  ASSERT_EQ(info.unsynchronised_max_move, 0.1);
  std::thread broadcaster([&] {
    std::this_thread::sleep_for(20ms);
    auto after = robot_state(900);
    after.synchronised = false;
    on_state(p.state, after);
  });
  const JogResult r = p.jogger->jog({"irb6", 0, 0.08, -1});
  broadcaster.join();
  ASSERT_EQ(p.link->calls.size(), 1u);
  const auto& [delta, steps] = p.link->calls[0];
  EXPECT_EQ(delta, (std::vector<double>{-0.08, 0.0, 0.0, 0.0, 0.0}));
  std::vector<double> magnitude(5, 0.0);
  magnitude[0] = 0.08;
  EXPECT_EQ(steps, ecp::rest_to_rest_steps(irb6(), magnitude, 0.1, 0.002, 0.1));
  EXPECT_GT(steps, ecp::rest_to_rest_steps(irb6(), magnitude, 0.25, 0.002, 0.1));
  const double t = steps * 0.002;
  EXPECT_LE(2 * 0.08 / t, 0.1 * irb6().max_velocity[0] + 1e-9);
  EXPECT_LE(4 * 0.08 / (t * t), 0.1 * irb6().max_acceleration[0] + 1e-9);
  EXPECT_FALSE(r.synchronised);
  EXPECT_EQ(r.text.rfind("UNSYNCHRONISED: irb6 axis 0 (", 0), 0u) << r.text;
  EXPECT_TRUE(has(r.text, "(raw axis position; at most 0.10 of the axis' limits until SYNCHRO)"))
      << r.text;
  ASSERT_EQ(p.reports.sent.size(), 1u);
  EXPECT_EQ(p.reports.sent[0].second, "operator jog: " + r.text);

  // Larger than the EDP takes before SYNCHRO: refused here, nothing sent.
  std::pair<int, std::string> refused = api_error([&] {
    (void)p.jogger->jog({"irb6", 0, 0.15, 1});
  });
  EXPECT_EQ(refused.first, 400);
  EXPECT_EQ(refused.second,
            "jog step 0.15 rad is outside (0, 0.1] rad while irb6 is not synchronised "
            "([robot.edp] unsynchronised_max_move)");
  JogRequest tool{"irb6", 2, 0.01, 1};
  tool.space = JogSpace::tool;
  refused = api_error([&] { (void)p.jogger->jog(tool); });
  EXPECT_EQ(refused.first, 409);
  EXPECT_TRUE(has(refused.second,
                  "tool jog refused: irb6 is not synchronised (its position is "
                  "unknown: press Synchronise; joint jogs work before it, at "
                  "reduced limits)"))
      << refused.second;
  EXPECT_EQ(p.link->calls.size(), 1u);
  EXPECT_TRUE(p.link->tool_calls.empty());
}

// --- teach-in ----------------------------------------------------------------------------------

TEST(TeachIn, AppendsJointPosesToATrajectoryFile) {
  TempDir dir;
  Parts p;
  TeachIn teach(p.state, dir.path() / "taught", p.reports.fn());
  on_state(p.state, robot_state(1, {0.5, -1.5, 0.25, 0.0, 0.125}));
  const TeachResult first = teach.record("irb6", "irb6.traj");
  EXPECT_EQ(first.points, 1u);
  EXPECT_EQ(first.file, dir.path() / "taught" / "irb6.traj");
  EXPECT_EQ(first.text, "pose 1 of irb6 recorded in " + first.file.string());
  on_state(p.state, robot_state(2, {0.75, -1.25, 0.0, 0.5, -0.25}));
  const TeachResult second = teach.record("irb6", "irb6.traj");
  EXPECT_EQ(second.points, 2u);
  EXPECT_EQ(second.pose, (std::vector<double>{0.75, -1.25, 0.0, 0.5, -0.25}));
  const std::string text = read_file(first.file);
  EXPECT_TRUE(has(text, "# mrroc trajectory v1 representation=JOINT axes=5 robot=irb6")) << text;
  EXPECT_TRUE(has(text, "0.5 -1.5 0.25 0 0.125\n")) << text;
  EXPECT_TRUE(has(text, "0.75 -1.25 0 0.5 -0.25\n")) << text;
  const auto loaded = ecp::TrajectoryFile::load(first.file);
  EXPECT_EQ(loaded.robot, "irb6");
  EXPECT_EQ(loaded.axes, 5u);
  ASSERT_EQ(loaded.points.size(), 2u);
  EXPECT_EQ(loaded.points[1].values, second.pose);
  ASSERT_EQ(p.reports.sent.size(), 2u);
  EXPECT_EQ(p.reports.sent[1].second, "teach-in: " + second.text);
}

// Records from many threads and two consoles' teach-ins on one file: each adds its pose (the
// file is read and replaced under a lock); a temporary name of its own per write, so that what
// lies at a fixed name (a folder, another writer's file) is no obstacle.
TEST(TeachIn, ConcurrentRecordsEachAddTheirPoseUnderALock) {
  TempDir dir;
  Parts p;
  std::mutex reports_mutex;
  std::size_t reported = 0;
  const ReportFn report = [&](Severity, const std::string&) {
    std::lock_guard lock(reports_mutex);
    ++reported;
  };
  TeachIn first(p.state, dir.path(), report);
  TeachIn second(p.state, dir.path(), report);  // a second console on the same folder
  // Received "in a minute": fresh however long the writes take on a slow disk.
  on_state(p.state, robot_state(1, {0.5, -1.5, 0.25, 0.0, 0.125}),
           SteadyClock::now() + std::chrono::seconds(60));
  std::filesystem::create_directories(dir.path() / "irb6.traj.tmp");  // in the way of a fixed name
  constexpr int kThreads = 6;
  constexpr int kEach = 10;
  std::atomic<int> failures{0};
  std::vector<std::thread> threads;
  for (int t = 0; t < kThreads; ++t)
    threads.emplace_back([&, t] {
      for (int i = 0; i < kEach; ++i) {
        try {
          (void)(t % 2 == 0 ? first : second).record("irb6", "irb6.traj");
        } catch (const std::exception& e) {
          std::printf("record failed: %s\n", e.what());
          ++failures;
        }
      }
    });
  for (auto& t : threads) t.join();
  EXPECT_EQ(failures.load(), 0);
  const auto loaded = ecp::TrajectoryFile::load(dir.path() / "irb6.traj");
  EXPECT_EQ(loaded.points.size(), static_cast<std::size_t>(kThreads * kEach))
      << "poses were lost between concurrent records";
  EXPECT_EQ(reported, static_cast<std::size_t>(kThreads * kEach));
  // Nothing left but the file, its lock and what was planted.
  std::vector<std::string> left;
  for (const auto& e : std::filesystem::directory_iterator(dir.path()))
    left.push_back(e.path().filename().string());
  std::sort(left.begin(), left.end());
  EXPECT_EQ(left, (std::vector<std::string>{".irb6.traj.lock", "irb6.traj", "irb6.traj.tmp"}));
}

TEST(TeachIn, Refusals) {
  TempDir dir;
  Parts p;
  TeachIn teach(p.state, dir.path(), p.reports.fn());
  for (const char* bad : {"../escape.traj", "", ".hidden", "a/b", "-x"}) {
    const auto [status, text] = api_error([&] { (void)teach.record("irb6", bad); });
    EXPECT_EQ(status, 400) << bad;
    EXPECT_EQ(text, "trajectory file name '" + std::string(bad) +
                        "' is not a plain file name (letters, digits, '_', '.', '-'; at most 100)");
  }
  EXPECT_EQ(api_error([&] { (void)teach.record("nope", "x.traj"); }).first, 404);
  EXPECT_EQ(api_error([&] { (void)teach.record("irb6", "x.traj"); }),
            std::make_pair(409, std::string("no robot_state_t from EDP irb6 in the last 1 s")));
  auto s = robot_state(1);
  s.synchronised = false;
  on_state(p.state, s);
  EXPECT_EQ(api_error([&] { (void)teach.record("irb6", "x.traj"); }),
            std::make_pair(409, std::string("irb6 is not synchronised: its joint positions are "
                                            "not known yet")));
  // A file of another robot is left as it is.
  std::filesystem::create_directories(dir.path());
  const auto other = dir.path() / "other.traj";
  {
    std::ofstream out(other);
    out << "# mrroc trajectory v1 representation=JOINT axes=3 robot=rnt\n0 0 0\n";
  }
  const std::string before = read_file(other);
  on_state(p.state, robot_state(2));
  const auto [status, text] = api_error([&] { (void)teach.record("irb6", "other.traj"); });
  EXPECT_EQ(status, 409);
  EXPECT_TRUE(has(text,
                  "holds a JOINT trajectory of 3 axes for robot 'rnt', not JOINT poses of "
                  "irb6 (5 axes)"))
      << text;
  EXPECT_EQ(read_file(other), before);
  EXPECT_FALSE(std::filesystem::exists(dir.path() / "x.traj"));
}

// --- HTTP API ----------------------------------------------------------------------------------

namespace {

/// The console's actions on the parts above, with the emergency stop and the MP's answers
/// recorded instead of sent.
struct PartsActions : ConsoleActions {
  Parts& parts;
  TeachIn& teach_in;
  std::vector<std::tuple<bool, std::string, std::string>> stops;
  std::vector<OperatorCommand> commands;
  MpStatus answer;
  bool mp_silent = false;
  PartsActions(Parts& p, TeachIn& t) : parts(p), teach_in(t) {}
  MpStatus command(OperatorCommand c) override {
    if (mp_silent) throw ApiError(504, "no MP answers on 'mrroc/mp/cmd'");
    commands.push_back(c);
    return answer;
  }
  EstopResult emergency_stop(bool engage, const std::string& robot,
                             const std::string& reason) override {
    stops.emplace_back(engage, robot, reason);
    EstopResult r;
    r.text = describe_emergency_stop(engage, robot, reason);
    r.servo_step_at_send = parts.state.estimated_servo_steps(robot);
    r.confirmation.confirmed = {"irb6"};
    r.confirmation.latency_ms["irb6"] = 12.5;
    return r;
  }
  JogResult jog(const JogRequest& request) override { return parts.jogger->jog(request); }
  JogResult synchronise(const std::string& robot) override {
    return parts.jogger->synchronise(robot);
  }
  TeachResult teach(const std::string& robot, const std::string& file) override {
    return teach_in.record(robot, file);
  }
};

constexpr const char* kToken = "0123456789abcdef-token";

/// The API on an in-process server at 127.0.0.1:<any free port>; client_ sends the token.
class ApiTest : public ::testing::Test {
 protected:
  void start(const std::string& token = kToken, ServerLimits limits = {}) {
    ApiSettings settings;
    settings.set_name = "demo";
    settings.config_file = "/configs/demo.toml";
    settings.operator_start = true;
    settings.teach_dir = dir_.path();
    settings.jog_max_step_rad = 0.2;
    settings.token = token;
    settings.token_hint = "the token is in the test's file";
    api_ = std::make_unique<HttpApi>(parts_.state, settings, actions_);
    server_ = std::make_unique<ConsoleServer>(limits);
    api_->install(*server_);
    port_ = server_->bind_to_any_port("127.0.0.1");
    ASSERT_GT(port_, 0);
    thread_ = std::thread([this] { server_->listen_after_bind(); });
    for (int i = 0; i < 500 && !server_->is_running(); ++i) std::this_thread::sleep_for(2ms);
    ASSERT_TRUE(server_->is_running());
    client_ = std::make_unique<httplib::Client>("127.0.0.1", port_);
    client_->set_default_headers({{"Authorization", "Bearer " + token}});
  }
  void TearDown() override {
    if (server_) server_->stop();
    if (thread_.joinable()) thread_.join();
  }
  /// POST with the cross-site header; {status, body as JSON (null if not JSON)}.
  std::pair<int, json> post(const std::string& path, const std::string& body) {
    auto res = client_->Post(path.c_str(), {{"X-Mrroc-Request", "1"}}, body, "application/json");
    if (!res) return {0, json()};
    return {res->status, json::parse(res->body, nullptr, false)};
  }
  std::pair<int, json> get(const std::string& path, const httplib::Headers& headers = {}) {
    auto res = client_->Get(path.c_str(), headers);
    if (!res) return {0, json()};
    return {res->status, json::parse(res->body, nullptr, false)};
  }

  TempDir dir_;
  Parts parts_;
  TeachIn teach_{parts_.state, dir_.path(), parts_.reports.fn()};
  PartsActions actions_{parts_, teach_};
  std::unique_ptr<HttpApi> api_;
  std::unique_ptr<ConsoleServer> server_;
  std::thread thread_;
  int port_ = 0;
  std::unique_ptr<httplib::Client> client_;
};

}  // namespace

TEST_F(ApiTest, StateHasEveryFieldThePageReads) {
  start();
  auto [status, state] = get("/api/state");
  ASSERT_EQ(status, 200);
  for (const char* key : {"set", "config", "utime", "operator_start", "mp", "launch", "processes",
                          "robots", "srp", "teach_dir", "jog_max_step_rad", "jog_max_step_m"})
    EXPECT_TRUE(state.contains(key)) << key << " in " << state.dump();
  EXPECT_EQ(state["set"], "demo");
  EXPECT_EQ(state["mp"]["state"], "NO MP");
  EXPECT_EQ(state["mp"]["available"], false);
  EXPECT_TRUE(state["launch"].is_null());
  ASSERT_EQ(state["robots"].size(), 1u);
  EXPECT_EQ(state["robots"][0]["name"], "irb6");
  EXPECT_EQ(state["robots"][0]["joint_names"].size(), 5u);
  EXPECT_TRUE(state["robots"][0]["state"].is_null());
  EXPECT_EQ(state["teach_dir"], dir_.path().string());

  on_state(parts_.state, robot_state(42));
  MpStatus mp;
  mp.accepted = true;
  mp.state = "IDLE";
  mp.task = "joint_poses";
  parts_.state.on_mp_status(mp);
  ProcessStatus p;
  p.process = "edp/irb6";
  p.robot = "irb6";
  p.state = ProcessState::ready;
  p.uptime_us = 2'500'000;
  parts_.state.on_process_status(p);
  std::tie(status, state) = get("/api/state");
  const json& s = state["robots"][0]["state"];
  for (const char* key :
       {"synchronised", "moving", "estop", "fault", "error", "servo_step", "servo_period_s", "q",
        "dq", "q_desired", "lateness_mean_us", "lateness_max_us", "overruns", "utime", "age_s"})
    EXPECT_TRUE(s.contains(key)) << key << " in " << s.dump();
  EXPECT_EQ(s["servo_step"], 42);
  EXPECT_EQ(s["synchronised"], true);
  EXPECT_EQ(s["utime"], 1'700'000'000'000'000 + 42 * 2000) << "the envelope's time of sending";
  EXPECT_EQ(state["mp"]["task"], "joint_poses");
  EXPECT_EQ(state["mp"]["available"], true);
  ASSERT_EQ(state["processes"].size(), 1u);
  EXPECT_EQ(state["processes"][0]["name"], "edp/irb6");
  EXPECT_EQ(state["processes"][0]["state"], "ready");
  EXPECT_DOUBLE_EQ(state["processes"][0]["uptime_s"].get<double>(), 2.5);
}

TEST_F(ApiTest, SamplesAndSrpMessages) {
  start();
  for (std::int64_t step = 1; step <= 5; ++step) on_state(parts_.state, robot_state(step));
  auto [status, samples] = get("/api/robots/irb6/samples?after=3");
  ASSERT_EQ(status, 200);
  EXPECT_EQ(samples["robot"], "irb6");
  ASSERT_EQ(samples["samples"].size(), 2u);
  EXPECT_EQ(samples["samples"][0]["step"], 4);
  EXPECT_EQ(samples["samples"][0]["q"].size(), 5u);
  EXPECT_EQ(get("/api/robots/nope/samples").first, 404);
  EXPECT_EQ(get("/api/robots/irb6/samples?after=x").first, 400);

  parts_.state.on_message(message(1'700'000'000'000'000, "hello", Severity::warning));
  auto [srp_status, srp] = get("/api/srp?after=0&min_severity=2");
  ASSERT_EQ(srp_status, 200);
  ASSERT_EQ(srp["messages"].size(), 1u);
  const json& m = srp["messages"][0];
  EXPECT_EQ(m["n"], 1);
  EXPECT_EQ(m["text"], "hello");
  EXPECT_EQ(m["severity"], 2);
  EXPECT_EQ(m["severity_name"], "warning");
  EXPECT_EQ(m["process"], "edp/irb6");
  EXPECT_TRUE(m.contains("time"));
  EXPECT_EQ(get("/api/srp?min_severity=3").second["messages"].size(), 0u);
  auto [bad_status, bad] = get("/api/srp?min_severity=9");
  EXPECT_EQ(bad_status, 400);
  EXPECT_EQ(bad["error"], "min_severity 9 is not a severity 0 (DEBUG) .. 4 (FATAL)");
  EXPECT_EQ(get("/api/srp?max=0").second["error"], "max 0 is out of range 1..5000");
  EXPECT_EQ(get("/api/srp?after=1x").second["error"],
            "query parameter 'after' is '1x', expected an integer");
}

TEST_F(ApiTest, SceneObjectsAndTheirPosesWithTheJoints) {
  start();
  auto [none_status, none] = get("/api/objects");
  ASSERT_EQ(none_status, 200);
  EXPECT_TRUE(none["objects"].empty());
  EXPECT_TRUE(none["seq"].is_null());
  EXPECT_TRUE(get("/api/joints").second["objects"].is_null());

  SceneObjects objects;
  objects.scene = "conveyor-pick";
  objects.sim_time_s = 2.5;
  SceneObjectPose part;
  part.name = "part";
  part.shape = SceneObjectShape::box;
  part.size = {0.03, 0.03, 0.03};
  part.rgba = {0.8, 0.2, 0.2, 1.0};
  part.attach = "conveyor/belt_link";
  part.local_position = {0.0, 0.0, 0.04};
  part.position = {0.1, -0.65, 0.79};
  part.quaternion = {1.0, 0.0, 0.0, 0.0};
  SceneObjectPose ball;
  ball.name = "ball";
  ball.shape = SceneObjectShape::sphere;
  ball.size = {0.05};
  ball.position = {0.5, 0.3, 0.05};
  ball.quaternion = {0.0, 0.0, 0.0, 1.0};
  objects.objects = {part, ball};
  parts_.state.on_scene_objects(objects, 1'700'000'000'000'000, 42);

  auto [status, served] = get("/api/objects");
  ASSERT_EQ(status, 200);
  EXPECT_EQ(served["scene"], "conveyor-pick");
  EXPECT_EQ(served["seq"], 42);
  EXPECT_EQ(served["utime"], 1'700'000'000'000'000);
  EXPECT_EQ(served["sim_time_s"], 2.5);
  ASSERT_EQ(served["objects"].size(), 2u);
  const json& p = served["objects"][0];
  EXPECT_EQ(p["name"], "part");
  EXPECT_EQ(p["shape"], "box");
  EXPECT_EQ(p["size"], json::array({0.03, 0.03, 0.03}));
  EXPECT_EQ(p["attach"], "conveyor/belt_link");
  EXPECT_EQ(p["local_position"], json::array({0.0, 0.0, 0.04}));
  EXPECT_EQ(p["position"], json::array({0.1, -0.65, 0.79}));
  EXPECT_EQ(served["objects"][1]["shape"], "sphere");
  EXPECT_EQ(served["objects"][1]["attach"], "");
  EXPECT_EQ(served["objects"][1]["quaternion"], json::array({0.0, 0.0, 0.0, 1.0}));
  httplib::Client bare("127.0.0.1", port_);  // sends no token
  EXPECT_EQ(bare.Get("/api/objects")->status, 401);

  const json joints = get("/api/joints").second;
  EXPECT_EQ(joints["objects"]["seq"], 42);
  EXPECT_EQ(joints["objects"]["poses"],
            json::array({json::array({0.1, -0.65, 0.79, 1.0, 0.0, 0.0, 0.0}),
                         json::array({0.5, 0.3, 0.05, 0.0, 0.0, 0.0, 1.0})}));
}

TEST_F(ApiTest, AKeptAliveConnectionIsAnsweredWithoutTheDelayedAckStall) {
  // The 3D view polls /api/joints 50 times a second on one kept-alive connection. With Nagle's
  // algorithm on the server's socket every answer after the first waited for the client's
  // delayed ACK: 40 ms each (25 answers a second at most). Answers take well under a millisecond
  // on loopback; 20 ms is half the stall.
  start();
  httplib::Client keep("127.0.0.1", port_);
  keep.set_keep_alive(true);
  keep.set_default_headers({{"Authorization", "Bearer " + std::string(kToken)}});
  std::vector<double> ms;
  for (int i = 0; i < 21; ++i) {
    const auto t0 = std::chrono::steady_clock::now();
    auto res = keep.Get("/api/state");
    ASSERT_TRUE(res);
    ASSERT_EQ(res->status, 200);
    ms.push_back(
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count());
  }
  EXPECT_LT(server_->counts().served, 21u)
      << "connections kept alive (cpp-httplib: 5 requests each)";
  std::sort(ms.begin(), ms.end());
  EXPECT_LT(ms[10], 20.0) << "median of 21 answers on one connection [ms]";
}

TEST_F(ApiTest, MalformedBodiesAreRefusedWithTheirReason) {
  start();
  on_state(parts_.state, robot_state(1));
  const std::vector<std::tuple<std::string, std::string, int, std::string>> cases = {
      {"/api/jog", "{", 400, "request body is not a JSON object"},
      {"/api/jog", "[1, 2]", 400, "request body is not a JSON object"},
      {"/api/jog", std::string("\xff\xfe\x00garbage", 10), 400, "not a JSON object"},
      {"/api/jog", R"({"robot": 5, "axis": 0, "step_rad": 0.01})", 400, "request body: "},
      {"/api/jog", R"({"robot": "irb6", "axis": "0", "step_rad": 0.01})", 400,
       "jog needs an integer 'axis'"},
      {"/api/jog", R"({"robot": "irb6", "axis": 0})", 400,
       "jog needs a number 'step_rad' [rad or m]"},
      {"/api/jog", R"({"robot": "irb6", "axis": 0, "space": "tool", "step_rad": 0.01})", 400,
       "jog needs a number 'step' [m or rad]"},
      {"/api/jog", R"({"robot": "irb6", "axis": 0, "space": "world", "step": 0.01})", 400,
       "jog space 'world' is neither 'joint' nor 'tool'"},
      {"/api/jog", R"({"robot": "irb6", "axis": 0, "step_rad": 0.01, "direction": 2})", 400,
       "jog direction 2 is neither +1 nor -1"},
      {"/api/jog", R"({"robot": "irb6", "axis": 0, "step_rad": 0.01, "direction": 1.5})", 400,
       "jog 'direction' must be +1 or -1"},
      {"/api/jog", R"({"robot": "irb6", "axis": 99, "step_rad": 0.01})", 400,
       "axis 99 is out of range: robot irb6 has axes 0..4"},
      {"/api/jog", R"({"robot": "irb6", "axis": 0, "step_rad": 1e308})", 400, "rad is outside"},
      {"/api/jog", R"({"robot": "nope", "axis": 0, "step_rad": 0.01})", 404, "no robot 'nope'"},
      {"/api/teach", R"({"robot": "irb6", "file": "../escape.traj"})", 400,
       "not a plain file name"},
      {"/api/teach", R"({"robot": "irb6", "file": 7})", 400, "request body: "},
      {"/api/synchronise", R"({"robot": 5})", 400, "synchronise needs a string 'robot'"},
      {"/api/synchronise", "{}", 400, "synchronise needs a string 'robot'"},
      {"/api/synchronise", R"({"robot": "nope"})", 404, "no robot 'nope'"},
      {"/api/release", "not json", 400, "not a JSON object"},
      {"/api/release", R"({"robot": "nope"})", 404, "no robot 'nope'"},
      {"/api/command/launch", "{}", 404, "unknown command 'launch'"},
  };
  for (const auto& [path, body, status, text] : cases) {
    const auto [got_status, answer] = post(path, body);
    EXPECT_EQ(got_status, status) << path << " " << body;
    ASSERT_TRUE(answer.is_object()) << path << " " << body;
    EXPECT_TRUE(has(answer.value("error", std::string()), text))
        << path << " " << body << ": " << answer.dump();
  }
  EXPECT_TRUE(parts_.link->calls.empty()) << "nothing moved";
  EXPECT_EQ(parts_.link->synchronisations, 0) << "nothing synchronised";
  EXPECT_TRUE(actions_.stops.empty()) << "nothing released";
  EXPECT_TRUE(actions_.commands.empty());
  EXPECT_FALSE(std::filesystem::exists(dir_.path() / "irb6.traj"));
}

TEST_F(ApiTest, AnEstopNotUnderstoodStopsEveryRobot) {
  start();
  for (const std::string body :
       {"not json", R"({"robot": 5})", R"({"robot": "nope"})", R"({"reason": []})"}) {
    actions_.stops.clear();
    const auto [status, answer] = post("/api/estop", body);
    EXPECT_EQ(status, 400) << body;
    EXPECT_EQ(answer["ok"], true) << body;
    EXPECT_TRUE(has(answer["error"].get<std::string>(), "every robot was stopped")) << body;
    ASSERT_EQ(actions_.stops.size(), 1u) << body;
    EXPECT_TRUE(std::get<0>(actions_.stops[0]));
    EXPECT_EQ(std::get<1>(actions_.stops[0]), "") << "every robot";
    EXPECT_TRUE(has(std::get<2>(actions_.stops[0]), "request not understood")) << body;
  }
  on_state(parts_.state, robot_state(100));
  const auto [status, answer] = post("/api/estop", R"({"robot": "irb6", "reason": "test"})");
  ASSERT_EQ(status, 200);
  for (const char* key : {"ok", "text", "servo_step_at_send", "confirmed", "unconfirmed",
                          "confirm_ms", "deadline_ms", "latched_by"})
    EXPECT_TRUE(answer.contains(key)) << key << " in " << answer.dump();
  EXPECT_FALSE(answer.contains("error"));
  EXPECT_EQ(answer["deadline_ms"], 500);
  EXPECT_EQ(answer["confirm_ms"]["irb6"], 12.5);
  EXPECT_GE(answer["servo_step_at_send"]["irb6"].get<std::int64_t>(), 100);
  EXPECT_EQ(actions_.stops.back(), std::make_tuple(true, std::string("irb6"), std::string("test")));
  const auto [release_status, release] = post("/api/release", "");
  EXPECT_EQ(release_status, 200);
  EXPECT_EQ(actions_.stops.back(),
            std::make_tuple(false, std::string(), std::string("operator console")));
  EXPECT_TRUE(has(release["text"].get<std::string>(), "for every robot")) << release.dump();
}

TEST_F(ApiTest, CommandsJogAndTeach) {
  start();
  actions_.answer.accepted = false;
  actions_.answer.state = "RUNNING";
  actions_.answer.text = "a task is running";
  auto [status, answer] = post("/api/command/start", "{}");
  EXPECT_EQ(status, 409);
  EXPECT_EQ(answer["command"], "start");
  EXPECT_EQ(answer["error"], "the MP refused START: a task is running");
  ASSERT_EQ(actions_.commands.size(), 1u);
  EXPECT_EQ(actions_.commands[0], OperatorCommand::start);
  actions_.answer.accepted = true;
  std::tie(status, answer) = post("/api/command/status", "");
  EXPECT_EQ(status, 200);
  EXPECT_FALSE(answer.contains("error"));
  EXPECT_EQ(answer["state"], "RUNNING");
  actions_.mp_silent = true;
  std::tie(status, answer) = post("/api/command/stop", "{}");
  EXPECT_EQ(status, 504);
  EXPECT_EQ(answer["error"], "no MP answers on 'mrroc/mp/cmd'");

  on_state(parts_.state, robot_state(1));
  mp_is(parts_.state, "IDLE");  // the MP's answer, as the poller gets it
  parts_.link->joints_after = {0.15, 0.1, 0.1, 0.1, 0.1};
  std::tie(status, answer) =
      post("/api/jog", R"({"robot": "irb6", "axis": 0, "direction": 1, "step_rad": 0.05})");
  ASSERT_EQ(status, 200) << answer.dump();
  for (const char* key : {"ok", "text", "q", "q_before", "motion_steps"})
    EXPECT_TRUE(answer.contains(key)) << key;
  EXPECT_EQ(answer["q"][0], 0.15);
  EXPECT_EQ(answer["motion_steps"], parts_.link->calls.at(0).second);
  EXPECT_EQ(parts_.link->calls.at(0).first[0], 0.05);

  std::tie(status, answer) = post("/api/teach", R"({"robot": "irb6"})");
  ASSERT_EQ(status, 200) << answer.dump();
  EXPECT_EQ(answer["file"], (dir_.path() / "irb6.traj").string());
  EXPECT_EQ(answer["points"], 1);
  EXPECT_EQ(answer["pose"].size(), 5u);
  EXPECT_EQ(ecp::TrajectoryFile::load(dir_.path() / "irb6.traj").points.size(), 1u);
}

TEST_F(ApiTest, CrossSiteAndTokenChecks) {
  start();
  httplib::Client bare("127.0.0.1", port_);  // sends no token
  auto refused = bare.Get("/api/state");
  ASSERT_TRUE(refused);
  EXPECT_EQ(refused->status, 401);
  // The answer says how to send the token and where to find it.
  const std::string error = json::parse(refused->body)["error"].get<std::string>();
  EXPECT_EQ(error,
            "missing or wrong token: send the header 'Authorization: Bearer TOKEN' (a browser: "
            "open the page once as /?token=TOKEN; the API takes the token only in the header); "
            "the token is in the test's file");
  EXPECT_EQ(bare.Get("/api/state", {{"Authorization", "Bearer wrong-token-of-same-len"}})->status,
            401);
  EXPECT_EQ(bare.Get("/api/state", {{"Authorization", "Bearer 0123456789abcdef-token"}})->status,
            200);
  // Never in the query string (logs and browser histories keep it): only the page takes it so.
  auto in_query = bare.Get("/api/state?token=0123456789abcdef-token");
  ASSERT_TRUE(in_query);
  EXPECT_EQ(in_query->status, 401);
  EXPECT_TRUE(has(json::parse(in_query->body)["error"].get<std::string>(), ", not as ?token="))
      << in_query->body;
  EXPECT_EQ(bare.Get("/?token=0123456789abcdef-token")->status, 200);
  EXPECT_EQ(get("/api/state").first, 200) << "client_ sends the token";
  // Every POST route wants it too, and nothing runs without it.
  for (const char* path :
       {"/api/estop", "/api/release", "/api/jog", "/api/teach", "/api/command/start"}) {
    auto res = bare.Post(path, {{"X-Mrroc-Request", "1"}}, "{}", "application/json");
    ASSERT_TRUE(res) << path;
    EXPECT_EQ(res->status, 401) << path;
  }
  EXPECT_TRUE(actions_.stops.empty());
  EXPECT_TRUE(actions_.commands.empty());
  // The page itself needs no token (it asks for the API's with ?token= once).
  auto page = bare.Get("/");
  ASSERT_TRUE(page);
  EXPECT_EQ(page->status, 200);
  EXPECT_TRUE(has(page->get_header_value("Content-Type"), "text/html"));
  EXPECT_EQ(bare.Get("/no-such-file.js")->status, 404);
  // A POST without the cross-site header is refused before anything happens.
  auto res = client_->Post("/api/estop", "{}", "application/json");
  ASSERT_TRUE(res);
  EXPECT_EQ(res->status, 403);
  EXPECT_TRUE(actions_.stops.empty());
  EXPECT_TRUE(api_->token_ok("Bearer 0123456789abcdef-token"));
  EXPECT_FALSE(api_->token_ok("0123456789abcdef-token"));
  EXPECT_FALSE(api_->token_ok("Bearer 0123456789abcdef-tokeN"));
  EXPECT_FALSE(api_->token_ok(""));
}

TEST(HttpApiToken, AlwaysRequired) {
  Parts parts;
  TempDir dir;
  TeachIn teach{parts.state, dir.path(), parts.reports.fn()};
  PartsActions actions{parts, teach};
  for (const std::string token : {"", "0123456789abcde"}) {
    ApiSettings settings;
    settings.token = token;
    try {
      HttpApi api(parts.state, settings, actions);
      FAIL() << "an API token of " << token.size() << " characters was accepted";
    } catch (const Error& e) {
      EXPECT_EQ(std::string(e.what()),
                "the console's API token has " + std::to_string(token.size()) +
                    " characters, at least 16 needed (every /api request must carry one)");
    }
  }
}

TEST(GeneratedToken, RandomHexAndAPrivateFileRemovedAtTheEnd) {
  const std::string a = generate_token();
  const std::string b = generate_token();
  EXPECT_EQ(a.size(), 2 * kTokenBytes) << a;
  EXPECT_GE(a.size() * 4, 128u) << "at least 128 bits";
  EXPECT_EQ(a.find_first_not_of("0123456789abcdef"), std::string::npos) << a;
  EXPECT_NE(a, b);

  TempDir dir;
  EXPECT_EQ(generated_token_file(dir.path() / "logs", 8093), dir.path() / "logs" / "ui-8093.token");
  EXPECT_EQ(generated_token_file("", 8080), std::filesystem::current_path() / "ui-8080.token");
  const auto file = generated_token_file(dir.path() / "logs", 8093);
  // A link planted where the file goes is replaced, not written through.
  std::filesystem::create_directories(dir.path() / "logs");
  const auto target = dir.path() / "target";
  std::ofstream(target) << "untouched\n";
  std::filesystem::create_symlink(target, file);
  {
    TokenFile written(file, a);
    EXPECT_EQ(written.path(), file);
    EXPECT_FALSE(std::filesystem::is_symlink(file));
    struct stat st {};
    ASSERT_EQ(::stat(file.c_str(), &st), 0);
    EXPECT_EQ(st.st_mode & 0777, 0600u) << std::oct << (st.st_mode & 0777);
    EXPECT_EQ(read_token_file(file), a) << "read back as a configured token file would be";
    EXPECT_EQ(read_file(target), "untouched\n");
    // No temporary file is left beside it.
    std::size_t entries = 0;
    for ([[maybe_unused]] const auto& e : std::filesystem::directory_iterator(dir.path() / "logs"))
      ++entries;
    EXPECT_EQ(entries, 1u);
  }
  EXPECT_FALSE(std::filesystem::exists(file)) << "removed at the end";
  // A token another console wrote over it since is left alone.
  {
    TokenFile mine(file, a);
    std::ofstream(file) << b << "\n";
  }
  EXPECT_EQ(read_token_file(file), b);
}

TEST(ReadTokenFile, NamesTheFileAndTheLength) {
  TempDir dir;
  std::filesystem::create_directories(dir.path());
  const auto file = dir.path() / "token";
  {
    std::ofstream out(file);
    out << "  short  \n";
  }
  std::filesystem::permissions(
      file, std::filesystem::perms::owner_read | std::filesystem::perms::owner_write);
  try {
    (void)read_token_file(file);
    FAIL() << "a token of 5 characters was accepted";
  } catch (const Error& e) {
    EXPECT_EQ(std::string(e.what()), "UI token file '" + file.string() +
                                         "': the token on its first line has 5 characters, at "
                                         "least 16 needed");
  }
  {
    std::ofstream out(file);
    out << " 0123456789abcdef\t\nsecond line\n";
  }
  EXPECT_EQ(read_token_file(file), "0123456789abcdef");
  EXPECT_THROW((void)read_token_file(dir.path() / "missing"), Error);
  // A token others can read is refused.
  std::filesystem::permissions(file, std::filesystem::perms::others_read,
                               std::filesystem::perm_options::add);
  try {
    (void)read_token_file(file);
    FAIL() << "a token file readable by others was accepted";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("has mode 0604: other users may read it"),
              std::string::npos)
        << e.what();
  }
}

TEST(HttpApiHosts, HostAndOriginParse) {
  EXPECT_EQ(HttpApi::host_of("127.0.0.1:8080", false), "127.0.0.1");
  EXPECT_EQ(HttpApi::host_of("Cell-PC", false), "cell-pc");
  EXPECT_EQ(HttpApi::host_of("[::1]:8080", false), "::1");
  EXPECT_EQ(HttpApi::host_of("[::1", false), "");
  EXPECT_EQ(HttpApi::host_of("::1", false), "");
  EXPECT_EQ(HttpApi::host_of("http://localhost:8080", true), "localhost");
  EXPECT_EQ(HttpApi::host_of("https://[::1]", true), "::1");
  EXPECT_EQ(HttpApi::host_of("null", true), "");
  EXPECT_EQ(HttpApi::host_of("file://x", true), "");
  EXPECT_EQ(HttpApi::host_of("http://evil.example/path", true), "");
}

TEST_F(ApiTest, ForeignHostsAndOriginsAreRefusedAndNothingMayFrameTheConsole) {
  start();
  // The console's own names work, and every answer forbids framing and type guessing.
  auto own = client_->Get("/api/state", {{"Origin", "http://127.0.0.1:" + std::to_string(port_)}});
  ASSERT_TRUE(own);
  EXPECT_EQ(own->status, 200);
  EXPECT_EQ(own->get_header_value("X-Frame-Options"), "DENY");
  EXPECT_EQ(own->get_header_value("Content-Security-Policy"), "frame-ancestors 'none'");
  EXPECT_EQ(own->get_header_value("X-Content-Type-Options"), "nosniff");
  EXPECT_EQ(client_->Get("/api/state", {{"Host", "localhost:8080"}})->status, 200);
  // DNS rebinding: a name of another site that resolves to this host.
  auto [status, body] = get("/api/state", {{"Host", "evil.example:8080"}});
  EXPECT_EQ(status, 403);
  EXPECT_EQ(body["error"],
            "Host 'evil.example:8080' is not a name of this console (localhost, 127.0.0.1, ::1; "
            "more in [ui] hosts)");
  EXPECT_EQ(get("/", {{"Host", "evil.example"}}).first, 403) << "the page too";
  // A page of another site: refused even for a POST with the console's header, and nothing ran.
  auto res =
      client_->Post("/api/estop", {{"X-Mrroc-Request", "1"}, {"Origin", "http://evil.example"}},
                    R"({"robot": "irb6"})", "application/json");
  ASSERT_TRUE(res);
  EXPECT_EQ(res->status, 403);
  EXPECT_NE(res->body.find("requests from pages of 'http://evil.example' are refused"),
            std::string::npos)
      << res->body;
  EXPECT_TRUE(actions_.stops.empty());
}

TEST_F(ApiTest, ABodyAbove64KiBIsRefused) {
  start();
  const std::string big(HttpApi::kMaxBodyBytes + 1, ' ');
  auto res = client_->Post("/api/estop", {{"X-Mrroc-Request", "1"}}, big, "application/json");
  ASSERT_TRUE(res);
  EXPECT_EQ(res->status, 413);
  EXPECT_EQ(json::parse(res->body)["error"],
            "request body of 65537 bytes is above the limit of 65536 bytes");
  EXPECT_TRUE(actions_.stops.empty());
}

// --- Hostile clients ---------------------------------------------------------------------------

namespace {

/// A TCP connection to 127.0.0.1:port (closed on destruction), from `source` when given (another
/// loopback address, 127.x.y.z: the whole of 127.0.0.0/8 is this computer's on Linux).
class RawConnection {
 public:
  explicit RawConnection(int port, const std::string& source = {})
      : fd_(::socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0)) {
    if (fd_ < 0) return;
    if (!source.empty()) {
      sockaddr_in from{};
      from.sin_family = AF_INET;
      if (::inet_pton(AF_INET, source.c_str(), &from.sin_addr) != 1 ||
          ::bind(fd_, reinterpret_cast<sockaddr*>(&from), sizeof from) != 0)
        return;
    }
    sockaddr_in addr{};
    addr.sin_family = AF_INET;
    addr.sin_port = htons(static_cast<std::uint16_t>(port));
    addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    connected_ = ::connect(fd_, reinterpret_cast<sockaddr*>(&addr), sizeof addr) == 0;
  }
  ~RawConnection() {
    if (fd_ >= 0) ::close(fd_);
  }
  RawConnection(const RawConnection&) = delete;
  RawConnection& operator=(const RawConnection&) = delete;
  [[nodiscard]] bool connected() const { return connected_; }
  /// Sends all of `data` (false: the server closed the connection), adding what went out to
  /// `*sent`.
  bool send(std::string_view data, std::atomic<std::size_t>* sent = nullptr) const {
    while (!data.empty()) {
      const ssize_t n = ::send(fd_, data.data(), data.size(), MSG_NOSIGNAL);
      if (n <= 0) return false;
      if (sent != nullptr) *sent += static_cast<std::size_t>(n);
      data.remove_prefix(static_cast<std::size_t>(n));
    }
    return true;
  }
  /// What arrives until the server closes the connection or `timeout` passes; `closed` tells
  /// which.
  std::string receive(std::chrono::milliseconds timeout, bool* closed = nullptr) const {
    const auto end = std::chrono::steady_clock::now() + timeout;
    std::string got;
    if (closed != nullptr) *closed = false;
    for (;;) {
      const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(
          end - std::chrono::steady_clock::now());
      pollfd p{fd_, POLLIN, 0};
      if (left.count() <= 0 || ::poll(&p, 1, static_cast<int>(left.count())) <= 0) return got;
      char buf[4096];
      const ssize_t n = ::recv(fd_, buf, sizeof buf, 0);
      if (n <= 0) {
        if (closed != nullptr) *closed = true;
        return got;
      }
      got.append(buf, static_cast<std::size_t>(n));
    }
  }
  [[nodiscard]] int fd() const { return fd_; }

 private:
  int fd_;
  bool connected_ = false;
};

/// Waits for `condition` (checked every millisecond) at most `timeout`.
template <class F>
bool wait_until(F&& condition, std::chrono::milliseconds timeout) {
  const auto end = std::chrono::steady_clock::now() + timeout;
  while (!condition()) {
    if (std::chrono::steady_clock::now() >= end) return false;
    std::this_thread::sleep_for(1ms);
  }
  return true;
}

/// Raises this process' limit of open files to at least `want` (as far as the hard limit
/// allows); the limit afterwards.
rlim_t raise_open_files(rlim_t want) {
  rlimit r{};
  if (::getrlimit(RLIMIT_NOFILE, &r) != 0) return 0;
  if (r.rlim_cur < want) {
    r.rlim_cur = r.rlim_max == RLIM_INFINITY ? want : std::min(want, r.rlim_max);
    (void)::setrlimit(RLIMIT_NOFILE, &r);
    (void)::getrlimit(RLIMIT_NOFILE, &r);
  }
  return r.rlim_cur;
}

double ms_since(std::chrono::steady_clock::time_point t) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t).count();
}

/// The resident memory of this process [KiB] (VmRSS of /proc/self/status).
long rss_kib() {
  std::ifstream in("/proc/self/status");
  std::string line;
  while (std::getline(in, line))
    if (line.rfind("VmRSS:", 0) == 0) return std::stol(line.substr(6));
  return -1;
}

/// Slow clients: every connection sent the start of a request (`start`) and then one byte of a
/// header every `period`, never finishing it (a "slowloris").
class SlowClients {
 public:
  SlowClients(int port, int count, std::chrono::milliseconds period,
              const std::string& start = "GET /api/state HTTP/1.1\r\n") {
    for (int i = 0; i < count; ++i) {
      connections_.push_back(std::make_unique<RawConnection>(port));
      (void)connections_.back()->send(start + "Host: 127.0.0.1\r\nX-Slow: ");
    }
    feeder_ = std::thread([this, period] {
      std::unique_lock lock(mutex_);
      while (!cv_.wait_for(lock, period, [this] { return done_; }))
        for (auto& c : connections_) (void)c->send("a");
    });
  }
  ~SlowClients() {
    {
      std::lock_guard lock(mutex_);
      done_ = true;
    }
    cv_.notify_all();
    feeder_.join();
  }
  SlowClients(const SlowClients&) = delete;
  SlowClients& operator=(const SlowClients&) = delete;
  [[nodiscard]] const std::vector<std::unique_ptr<RawConnection>>& connections() const {
    return connections_;
  }

 private:
  std::vector<std::unique_ptr<RawConnection>> connections_;
  std::mutex mutex_;
  std::condition_variable cv_;
  bool done_ = false;
  std::thread feeder_;
};

}  // namespace

TEST_F(ApiTest, SlowClientsCannotDelayTheEmergencyStop) {
  // Every connection on a thread of its own: all from 127.0.0.1, so no share per address.
  ServerLimits limits;
  limits.max_connections_per_peer = limits.max_connections;
  start(kToken, limits);
  // 32 slow clients, each on a connection the server is serving (cpp-httplib's pool of 16
  // threads, which the console used before, was full with 16 of them).
  SlowClients slow(port_, 32, 1000ms);
  ASSERT_TRUE(wait_until([&] { return server_->counts().open == 32; }, 5s))
      << server_->counts().open << " of 32 slow connections served";
  const auto sent = std::chrono::steady_clock::now();
  const auto [status, answer] = post("/api/estop", R"({"reason": "test"})");
  const auto answered_ms =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - sent).count();
  std::printf("emergency stop answered in %.1f ms beside 32 slow connections\n", answered_ms);
  EXPECT_EQ(status, 200) << answer.dump();
  EXPECT_LT(answered_ms, 1000.0);
  ASSERT_EQ(actions_.stops.size(), 1u) << "the stop was sent";
  EXPECT_EQ(actions_.stops[0], std::make_tuple(true, std::string(), std::string("test")));
  EXPECT_GE(server_->counts().most_open, 33u);
}

TEST_F(ApiTest, ASlowRequestIsClosedAtItsDeadlineAndStopEndsSlowConnections) {
  ServerLimits limits;
  limits.request_deadline = 300ms;
  start(kToken, limits);
  {
    // A byte every 50 ms: no single read waits long, but the request never ends.
    SlowClients slow(port_, 4, 50ms);
    ASSERT_TRUE(wait_until([&] { return server_->counts().open == 4; }, 5s));
    const auto begin = std::chrono::steady_clock::now();
    for (const auto& c : slow.connections()) {
      bool closed = false;
      (void)c->receive(3s, &closed);
      EXPECT_TRUE(closed) << "the server closed the slow connection";
    }
    const double closed_ms =
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - begin).count();
    std::printf("4 slow requests closed %.0f ms after they were served (deadline 300 ms)\n",
                closed_ms);
    EXPECT_LT(closed_ms, 1000.0);
    EXPECT_TRUE(wait_until([&] { return server_->counts().late == 4; }, 2s))
        << server_->counts().late;
  }
  // stop() does not wait for slow clients (a thread per connection is joined at the stop).
  SlowClients slow(port_, 8, 1000ms);
  ASSERT_TRUE(wait_until([&] { return server_->counts().open == 8; }, 5s))
      << server_->counts().open << " open, " << server_->counts().served << " served";
  const auto begin = std::chrono::steady_clock::now();
  server_->stop();
  thread_.join();
  const double stop_ms =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - begin).count();
  std::printf("stop() with 8 slow connections open: %.0f ms\n", stop_ms);
  EXPECT_LT(stop_ms, 1000.0);
  EXPECT_EQ(server_->counts().open, 0u);
}

TEST_F(ApiTest, ConnectionsAboveTheLimitAreAnswered503AndClosed) {
  ServerLimits limits;
  limits.max_connections = 4;
  limits.first_byte_timeout = 10s;  // the idle connections stay for the test
  start(kToken, limits);
  std::vector<std::unique_ptr<RawConnection>> idle;
  for (int i = 0; i < 4; ++i) idle.push_back(std::make_unique<RawConnection>(port_));
  ASSERT_TRUE(wait_until([&] { return server_->counts().open == 4; }, 5s));
  // A fifth is answered as soon as its first bytes show that it is not an emergency stop.
  RawConnection fifth(port_);
  ASSERT_TRUE(fifth.connected());
  ASSERT_TRUE(fifth.send("GET /api/state HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n"));
  bool closed = false;
  const std::string answer = fifth.receive(2s, &closed);
  EXPECT_TRUE(closed);
  EXPECT_TRUE(has(answer, "HTTP/1.1 503 Service Unavailable")) << answer;
  EXPECT_TRUE(has(answer,
                  "the console serves at most 4 connections at once; this one was closed "
                  "(beyond that it serves only POST /api/estop)"))
      << answer;
  EXPECT_EQ(server_->counts().refused, 1u);
  EXPECT_EQ(server_->counts().waiting, 0u);
  // A freed place serves again.
  idle.pop_back();
  ASSERT_TRUE(wait_until([&] { return server_->counts().open == 3; }, 5s));
  EXPECT_EQ(get("/api/state").first, 200);
}

TEST_F(ApiTest, AHundredMegabyteBodyIsRefusedWithoutBeingRead) {
  start();
  ASSERT_EQ(get("/api/state").first, 200);  // every lazily made allocation is made
  // What the clients send, allocated before the measurement (a sanitizer's allocator keeps freed
  // blocks resident).
  const std::string block(1 << 20, '{');
  const long rss_before = rss_kib();
  const std::string head = fmt::format(
      "POST /api/estop HTTP/1.1\r\nHost: 127.0.0.1:{}\r\nAuthorization: Bearer {}\r\n"
      "X-Mrroc-Request: 1\r\nContent-Type: application/json\r\n",
      port_, kToken);
  constexpr std::size_t kHundredMb = 100'000'000;
  struct Case {
    std::string headers;
    std::string status;
    std::string error;
  };
  const std::vector<Case> cases = {
      {"Content-Length: 100000000\r\n\r\n", "HTTP/1.1 413",
       "request body of 100000000 bytes is above the limit of 65536 bytes"},
      {"Transfer-Encoding: chunked\r\n\r\n", "HTTP/1.1 411",
       "a request body needs a Content-Length (at most 65536 bytes); 'Transfer-Encoding: "
       "chunked' is refused"},
  };
  for (const Case& c : cases) {
    RawConnection conn(port_);
    ASSERT_TRUE(conn.connected());
    // The body goes out as fast as the connection takes it, while the answer is read.
    std::atomic<std::size_t> sent{0};
    std::thread writer([&] {
      if (!conn.send(head + c.headers)) return;
      const bool chunked = has(c.headers, "chunked");
      const std::string chunk_head = fmt::format("{:x}\r\n", block.size());
      while (sent < kHundredMb) {
        if (chunked && !conn.send(chunk_head, &sent)) return;
        if (!conn.send(block, &sent)) return;
        if (chunked && !conn.send("\r\n", &sent)) return;
      }
    });
    bool closed = false;
    const std::string answer = conn.receive(5s, &closed);
    ::shutdown(conn.fd(), SHUT_RDWR);  // ends a writer still sending
    writer.join();
    std::printf("%s: %zu bytes of the body sent before the server closed the connection\n",
                c.status.c_str(), sent.load());
    EXPECT_TRUE(closed);
    EXPECT_EQ(answer.rfind(c.status, 0), 0u) << answer.substr(0, 200);
    EXPECT_TRUE(has(answer, c.error)) << answer.substr(0, 400);
    EXPECT_LT(sent.load(), kHundredMb / 4) << "the server stopped taking the body early";
  }
  // A client that asks first (Expect: 100-continue) is refused before it sends the body.
  {
    RawConnection conn(port_);
    ASSERT_TRUE(conn.send(head + "Content-Length: 100000000\r\nExpect: 100-continue\r\n\r\n"));
    bool closed = false;
    const std::string answer = conn.receive(5s, &closed);
    EXPECT_EQ(answer.rfind("HTTP/1.1 413", 0), 0u) << answer;
    EXPECT_TRUE(closed);
  }
  // A length that is not a number is not guessed at.
  {
    RawConnection conn(port_);
    ASSERT_TRUE(conn.send(head + "Content-Length: 12x\r\n\r\n"));
    const std::string answer = conn.receive(5s);
    EXPECT_EQ(answer.rfind("HTTP/1.1 400", 0), 0u) << answer;
    EXPECT_TRUE(has(answer, "Content-Length '12x' is not a number of bytes")) << answer;
  }
  const long rss_after = rss_kib();
  std::printf("resident memory: %ld KiB before, %ld KiB after (%+ld KiB)\n", rss_before, rss_after,
              rss_after - rss_before);
  EXPECT_GT(rss_before, 0);
  EXPECT_LT(rss_after - rss_before, 4 * 1024) << "KiB";
  EXPECT_TRUE(actions_.stops.empty()) << "nothing was read of the bodies, nothing ran";
}

TEST_F(ApiTest, ARequestLineWithoutEndIsCutAtTheByteLimit) {
  start();
  const std::string block(1 << 20, 'a');
  const long rss_before = rss_kib();
  RawConnection conn(port_);
  std::atomic<std::size_t> sent{0};
  std::thread writer([&] {
    if (!conn.send("GET /")) return;
    while (sent < 100'000'000 && conn.send(block, &sent)) {
    }
  });
  bool closed = false;
  (void)conn.receive(5s, &closed);
  ::shutdown(conn.fd(), SHUT_RDWR);
  writer.join();
  std::printf("endless request line: %zu bytes sent before the server closed the connection\n",
              sent.load());
  EXPECT_TRUE(closed);
  EXPECT_LT(sent.load(), 25'000'000u);
  EXPECT_TRUE(wait_until([&] { return server_->counts().too_large == 1; }, 2s));
  EXPECT_LT(rss_kib() - rss_before, 4 * 1024) << "KiB";
}

TEST(ReservedRequest, OnlyAWholeEmergencyStop) {
  const std::string head = "POST /api/estop HTTP/1.1\r\nHost: 127.0.0.1\r\nContent-Length: 4\r\n";
  EXPECT_EQ(classify_reserved_request(head + "\r\n{}{}", 1024), ReservedRequest::stop);
  EXPECT_EQ(classify_reserved_request(head + "\r\n{}", 1024), ReservedRequest::incomplete)
      << "the body has not all come";
  EXPECT_EQ(classify_reserved_request(head, 1024), ReservedRequest::incomplete);
  EXPECT_EQ(classify_reserved_request("POST /api/es", 1024), ReservedRequest::incomplete);
  EXPECT_EQ(classify_reserved_request("", 1024), ReservedRequest::incomplete);
  EXPECT_EQ(classify_reserved_request("POST /api/estop?token=x HTTP/1.1\r\n\r\n", 1024),
            ReservedRequest::stop);
  EXPECT_EQ(
      classify_reserved_request("post /api/estop HTTP/1.1\r\ncontent-length: 0\r\n\r\n", 1024),
      ReservedRequest::other)
      << "methods are upper case";
  EXPECT_EQ(
      classify_reserved_request("POST /api/estop HTTP/1.1\r\ncontent-length:  0 \r\n\r\n", 1024),
      ReservedRequest::stop)
      << "header names in any case";
  // Anything else, as soon as its first bytes tell.
  for (const std::string other :
       {"G", "POST /api/release HTTP/1.1\r\n\r\n", "POST /api/estopx",
        "POST /api/estop/ HTTP/1.1\r\n\r\n", "PUT /api/estop", " POST /api/estop HTTP/1.1\r\n\r\n"})
    EXPECT_EQ(classify_reserved_request(other, 1024), ReservedRequest::other) << other;
  // Bodies of any length or none declared right, heads above the limit.
  const std::string start = "POST /api/estop HTTP/1.1\r\n";
  for (const std::string headers :
       {"Transfer-Encoding: chunked\r\n", "Content-Length: 4097\r\n", "Content-Length: 12x\r\n",
        "Content-Length: 4\r\nContent-Length: 4\r\n", "Content-Length: \r\n",
        "Content-Length: -1\r\n"})
    EXPECT_EQ(classify_reserved_request(start + headers + "\r\n{}{}", 1024), ReservedRequest::other)
        << headers;
  EXPECT_EQ(classify_reserved_request(start + "Content-Length: 4096\r\n\r\n", 1024),
            ReservedRequest::incomplete);
  const std::string long_header = start + "X-Long: " + std::string(980, 'a');  // 1014 bytes
  EXPECT_EQ(classify_reserved_request(long_header, 1024), ReservedRequest::incomplete);
  EXPECT_EQ(classify_reserved_request(long_header + std::string(11, 'a'), 1024),
            ReservedRequest::other);
  EXPECT_EQ(classify_reserved_request(long_header + "\r\n\r\n", 1024), ReservedRequest::stop);
  EXPECT_EQ(classify_reserved_request(long_header + "aaaaaaa\r\n\r\n", 1024),
            ReservedRequest::other);
}

namespace {

/// Opens `count` connections that never send a byte, the i-th from `source(i)`.
template <class Source>
std::vector<std::unique_ptr<RawConnection>> idle_connections(int port, int count, Source source) {
  std::vector<std::unique_ptr<RawConnection>> idle;
  for (int i = 0; i < count; ++i) idle.push_back(std::make_unique<RawConnection>(port, source(i)));
  return idle;
}

}  // namespace

TEST_F(ApiTest, TheStopIsServedBesideTwoHundredIdleConnectionsFromOneAddress) {
  // Before, 128 idle connections (no token needed: nothing is read) made every further
  // connection, the stop's too, get 503.
  ASSERT_GE(raise_open_files(2048), 1024u);
  ServerLimits limits;
  limits.first_byte_timeout = 10s;  // the flood stays for the test (its default is 2 s)
  start(kToken, limits);
  const auto idle = idle_connections(port_, 200, [](int) { return std::string(); });
  for (const auto& c : idle) ASSERT_TRUE(c->connected());
  // 127.0.0.1's share is served, 64 wait on the reserved path, the older of the others were
  // answered 503 as newer ones came.
  ASSERT_TRUE(wait_until(
      [&] {
        const ServerCounts c = server_->counts();
        return c.open == 32 && c.waiting == 64 && c.peer_refused == 104;
      },
      10s))
      << server_->counts().open << " open, " << server_->counts().waiting << " waiting, "
      << server_->counts().peer_refused << " refused";
  bool closed = false;
  EXPECT_TRUE(has(idle[40]->receive(1s, &closed), "HTTP/1.1 503"));
  EXPECT_TRUE(closed);

  // Anything but the stop is refused, the release too.
  const auto [state_status, state_answer] = get("/api/state");
  EXPECT_EQ(state_status, 503);
  EXPECT_TRUE(has(state_answer.value("error", std::string()),
                  "at most 32 connections of one address (127.0.0.1)"))
      << state_answer.dump();
  EXPECT_EQ(post("/api/release", "").first, 503);
  // The stop without the token is refused as ever: same checks, same handler.
  httplib::Client bare("127.0.0.1", port_);
  const auto no_token = bare.Post("/api/estop", {{"X-Mrroc-Request", "1"}},
                                  R"({"reason": "no token"})", "application/json");
  ASSERT_TRUE(no_token);
  EXPECT_EQ(no_token->status, 401);
  EXPECT_TRUE(actions_.stops.empty());

  const auto sent = std::chrono::steady_clock::now();
  const auto [status, answer] = post("/api/estop", R"({"reason": "flood"})");
  const double answered_ms = ms_since(sent);
  std::printf("emergency stop answered in %.1f ms beside 200 idle connections of 127.0.0.1\n",
              answered_ms);
  EXPECT_EQ(status, 200) << answer.dump();
  EXPECT_LT(answered_ms, 1000.0);
  ASSERT_EQ(actions_.stops.size(), 1u) << "the stop was sent";
  EXPECT_EQ(actions_.stops[0], std::make_tuple(true, std::string(), std::string("flood")));
  EXPECT_EQ(server_->counts().reserved_stops, 2u);
  EXPECT_EQ(server_->counts().open, 32u) << "the idle connections were left as they were";
}

TEST_F(ApiTest, TheStopIsServedBesideTwoHundredIdleConnectionsFromManyAddresses) {
  ASSERT_GE(raise_open_files(2048), 1024u);
  ServerLimits limits;
  limits.first_byte_timeout = 10s;
  start(kToken, limits);
  // One from each of 127.0.0.2 ... 127.0.0.201.
  const auto idle =
      idle_connections(port_, 200, [](int i) { return fmt::format("127.0.0.{}", i + 2); });
  for (const auto& c : idle) ASSERT_TRUE(c->connected());
  ASSERT_TRUE(wait_until(
      [&] {
        const ServerCounts c = server_->counts();
        return c.open == 128 && c.waiting == 64 && c.refused == 8;
      },
      10s))
      << server_->counts().open << " open, " << server_->counts().waiting << " waiting, "
      << server_->counts().refused << " refused";
  EXPECT_EQ(server_->counts().peer_refused, 0u);
  const auto [state_status, state_answer] = get("/api/state");
  EXPECT_EQ(state_status, 503);
  EXPECT_TRUE(has(state_answer.value("error", std::string()), "at most 128 connections at once"))
      << state_answer.dump();

  const auto sent = std::chrono::steady_clock::now();
  const auto [status, answer] = post("/api/estop", R"({"reason": "flood"})");
  const double answered_ms = ms_since(sent);
  std::printf("emergency stop answered in %.1f ms beside 200 idle connections of 200 addresses\n",
              answered_ms);
  EXPECT_EQ(status, 200) << answer.dump();
  EXPECT_LT(answered_ms, 1000.0);
  ASSERT_EQ(actions_.stops.size(), 1u) << "the stop was sent";
  EXPECT_EQ(actions_.stops[0], std::make_tuple(true, std::string(), std::string("flood")));
  EXPECT_EQ(server_->counts().reserved_stops, 1u);
}

TEST_F(ApiTest, StopsSentSlowlyDoNotHoldTheReservedPath) {
  // 200 connections of 127.0.0.1 that each started an emergency stop and send a byte of a header
  // every 100 ms: its share is served (each request ends at its 3 s deadline), the others wait
  // on the reserved path, which reads them all without waiting on any.
  ASSERT_GE(raise_open_files(2048), 1024u);
  ServerLimits limits;
  limits.first_byte_timeout = 10s;  // the whole request on the reserved path (default 2 s)
  start(kToken, limits);
  SlowClients slow(port_, 200, 100ms, "POST /api/estop HTTP/1.1\r\n");
  ASSERT_TRUE(wait_until(
      [&] {
        const ServerCounts c = server_->counts();
        return c.open == 32 && c.waiting == 64 && c.peer_refused == 104;
      },
      10s))
      << server_->counts().open << " open, " << server_->counts().waiting << " waiting, "
      << server_->counts().peer_refused << " refused";
  const auto sent = std::chrono::steady_clock::now();
  const auto [status, answer] = post("/api/estop", R"({"reason": "slow flood"})");
  const double answered_ms = ms_since(sent);
  std::printf("emergency stop answered in %.1f ms beside 200 slow stops of 127.0.0.1\n",
              answered_ms);
  EXPECT_EQ(status, 200) << answer.dump();
  EXPECT_LT(answered_ms, 1000.0);
  ASSERT_EQ(actions_.stops.size(), 1u) << "only the whole stop was sent";
  EXPECT_EQ(actions_.stops[0], std::make_tuple(true, std::string(), std::string("slow flood")));
  EXPECT_EQ(server_->counts().reserved_stops, 1u);
}

TEST_F(ApiTest, OneAddressGetsItsShareAndASilentConnectionIsClosedAtTheFirstByteTimeout) {
  ServerLimits limits;
  limits.max_connections_per_peer = 2;
  limits.first_byte_timeout = 1500ms;
  start(kToken, limits);
  const auto opened = std::chrono::steady_clock::now();
  RawConnection a(port_);
  RawConnection b(port_);
  ASSERT_TRUE(wait_until([&] { return server_->counts().open == 2; }, 1s));
  // A third of 127.0.0.1 is refused as soon as it sends.
  RawConnection c(port_);
  ASSERT_TRUE(c.send("GET /api/state HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n"));
  bool closed = false;
  const std::string answer = c.receive(500ms, &closed);
  EXPECT_TRUE(closed);
  EXPECT_TRUE(has(answer, "HTTP/1.1 503 Service Unavailable")) << answer;
  EXPECT_TRUE(has(answer,
                  "the console serves at most 2 connections of one address (127.0.0.1) "
                  "at once"))
      << answer;
  EXPECT_EQ(server_->counts().peer_refused, 1u);
  EXPECT_EQ(server_->counts().refused, 0u);
  // Another address is served beside them.
  RawConnection d(port_, "127.0.0.2");
  ASSERT_TRUE(d.connected());
  ASSERT_TRUE(wait_until([&] { return server_->counts().open == 3; }, 1s));
  // One more of 127.0.0.1 that sends nothing waits on the reserved path.
  RawConnection e(port_);
  ASSERT_TRUE(wait_until([&] { return server_->counts().waiting == 1; }, 1s));

  // Every connection that sent nothing is closed about first_byte_timeout after it came: the
  // served ones without an answer, the one on the reserved path with 503.
  for (RawConnection* silent : {&a, &b, &d, &e}) {
    closed = false;
    const std::string got = silent->receive(3s, &closed);
    EXPECT_TRUE(closed);
    EXPECT_EQ(got.empty(), silent != &e) << got;
  }
  const double closed_ms = ms_since(opened);
  std::printf(
      "4 silent connections closed %.0f ms after the first came (first_byte_timeout "
      "1500 ms)\n",
      closed_ms);
  EXPECT_GE(closed_ms, 1450.0);
  EXPECT_LT(closed_ms, 3000.0);
  EXPECT_TRUE(wait_until([&] { return server_->counts().silent == 4; }, 500ms))
      << server_->counts().silent;
  EXPECT_EQ(server_->counts().peer_refused, 2u);
  EXPECT_EQ(server_->counts().open, 0u);
  EXPECT_EQ(server_->counts().waiting, 0u);
  // A place freed serves again.
  EXPECT_EQ(get("/api/state").first, 200);
}
