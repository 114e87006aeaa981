// The latched and confirmed emergency stop (mrroc-launch holds the latch, the EDP's own listener
// follows it, mrroc-ui confirms from robot_state_t) and one process set per LCM URL: real sets
// started by mrroc-launch in the test's own network namespace (scripts/netns-run).
#include <gtest/gtest.h>

#include <atomic>
#include <cmath>
#include <map>
#include <mutex>
#include <regex>
#include <thread>

#include "mrroc/comm/bus.hpp"
#include "mrroc/comm/edge.hpp"
#include "mrroc/comm/messages.hpp"
#include "mrroc/comm/sync_annotations.hpp"
#include "mrroc/config/process_set.hpp"
#include "mrroc/core/time.hpp"
#include "mrroc/msg/emergency_stop.hpp"
#include "mrroc/msg/launch.hpp"
#include "mrroc/msg/robot_state.hpp"
#include "mrroc_lcm/robot_state_t.hpp"
#include "operator_helpers.hpp"

using namespace mrroc::test;

namespace {

constexpr const char* kUrl = "udpm://239.255.76.67:7667?ttl=0";

std::string ui() { return (kBin / "mrroc-ui").string(); }

/// The robot_state_t of irb6, as they arrive.
class States {
 public:
  States() : bus_(kUrl) {
    bus_.subscribe<States*>(
        mrroc::channels::robot_state("irb6"),
        +[](const lcm::ReceiveBuffer* b, const std::string&, States* self) {
          mrroc_lcm::robot_state_t s;
          if (!mrroc::comm::detail::decode_received(b, s)) return;
          std::lock_guard lock(self->mutex_);
          self->all_.push_back(s);
        },
        this);
    bus_.start();
  }
  // The bus thread delivers into all_: stop it before the members go.
  ~States() { bus_.stop(); }
  States(const States&) = delete;
  States& operator=(const States&) = delete;
  std::vector<mrroc_lcm::robot_state_t> since(std::size_t from) {
    std::lock_guard lock(mutex_);
    return {all_.begin() + static_cast<std::ptrdiff_t>(std::min(from, all_.size())), all_.end()};
  }
  std::size_t count() {
    std::lock_guard lock(mutex_);
    return all_.size();
  }

 private:
  mrroc::comm::Bus bus_;
  std::mutex mutex_;
  std::vector<mrroc_lcm::robot_state_t> all_;
};

double max_joint_change(const std::vector<mrroc_lcm::robot_state_t>& states) {
  double worst = 0;
  if (states.empty()) return worst;
  for (const auto& s : states)
    for (std::size_t i = 0; i < s.q.size(); ++i)
      worst = std::max(worst, std::abs(s.q[i] - states.front().q[i]));
  return worst;
}

/// tests/operator/configs/long-irb6.toml in a folder of its own, its task started by the
/// operator, with `edp_options` (lines) added to [robot.edp].
fs::path idle_irb6_config(const std::string& name, const std::string& edp_options) {
  std::string text = slurp(kSource / "tests/operator/configs/long-irb6.toml");
  text.replace(text.find("\"../../../robots/irb6\""), 22,
               "\"" + (kSource / "robots/irb6").string() + "\"");
  text.replace(text.find("task = \"start_and_wait\""), 23,
               "task = \"start_and_wait\"\nstart = \"operator\"");
  if (!edp_options.empty())
    text.replace(text.find("servo_period_ms = 2.0"), 21, "servo_period_ms = 2.0\n" + edp_options);
  const fs::path config = temp_dir(name) / "estop.toml";
  std::ofstream(config) << text;
  return config;
}

}  // namespace

TEST(EstopLatch, UnconfirmedStopIsLoudAndARestartedEdpStaysStoppedUntilRelease) {
  const fs::path config = idle_irb6_config(
      "estop", "restart = \"on-failure\"\nmax_restarts = 2\nrestart_backoff_s = 0.5");
  States states;
  Background launch({launcher(), config.string()});
  ASSERT_TRUE(launch.wait_for("task running", 60s)) << launch.output();
  ASSERT_TRUE(has(launch.output(), "emergency stop released (heard after")) << launch.output();

  // A stop that reaches no robot (sent on another LCM URL, as if every datagram were lost):
  // nobody stops, and mrroc-ui says so (exit 4).
  {
    std::string text = slurp(config);
    text.replace(text.find(kUrl), std::string(kUrl).size(), "udpm://239.255.76.67:7668?ttl=0");
    const fs::path elsewhere = config.parent_path() / "elsewhere.toml";
    std::ofstream(elsewhere) << text;
    auto [lost_code, lost] = run({ui(), "estop", "--config", elsewhere.string()});
    std::printf("%s", lost.c_str());
    EXPECT_EQ(lost_code, 4) << lost;
    EXPECT_TRUE(has(lost, "NOT CONFIRMED by irb6 within 500 ms")) << lost;
    EXPECT_TRUE(has(lost, "NOT LATCHED")) << lost;
    const auto recent = states.since(states.count() > 5 ? states.count() - 5 : 0);
    ASSERT_FALSE(recent.empty()) << "no robot_state_t of irb6 heard";
    EXPECT_FALSE(recent.back().estop);
  }

  // The confirmed path: exit 0, confirmed from the robot's state, latched by the launcher.
  auto [code, out] = run({ui(), "estop", "--config", config.string(), "--reason", "test stop"});
  std::printf("%s", out.c_str());
  EXPECT_EQ(code, 0) << out;
  EXPECT_TRUE(has(out, "confirmed by irb6 (")) << out;
  EXPECT_TRUE(has(out, "latched by launch#")) << out;
  EXPECT_TRUE(launch.wait_for("emergency stop ENGAGED for irb6 (test stop, from ui#", 5s));

  // kill -9 the EDP: the launcher restarts it under the engaged stop; it starts stopped.
  const pid_t old_edp = launch.pid_of("edp/irb6");
  ASSERT_GT(old_edp, 0);
  const std::size_t from_line = launch.line_count();
  ASSERT_EQ(::kill(old_edp, SIGKILL), 0);
  ASSERT_TRUE(launch.wait_for("edp/irb6 ready again", 30s, from_line)) << launch.output();
  EXPECT_TRUE(launch.wait_for("emergency stop ENGAGED (latched: test stop", 1s, from_line))
      << launch.output();
  const std::size_t from_state = states.count();
  // START: the task's ECP asks the new EDP to synchronise (move): refused.
  auto [start_code, start_out] = run({ui(), "start", "--config", config.string()});
  EXPECT_EQ(start_code, 0) << start_out;
  EXPECT_TRUE(launch.wait_for("SYNCHRO refused: emergency stop engaged", 10s, from_line))
      << launch.output();
  std::this_thread::sleep_for(1s);
  const auto all_states = states.since(0);
  ASSERT_FALSE(all_states.empty()) << "no robot_state_t of irb6 heard";
  std::vector<mrroc_lcm::robot_state_t> held;
  for (const auto& s : states.since(from_state))
    if (s.header.sender != all_states.front().header.sender) held.push_back(s);
  ASSERT_GT(held.size(), 40u) << "states of the restarted EDP";
  double worst = max_joint_change(held);
  bool always_stopped = true, never_synchronised = true;
  for (const auto& s : held) {
    always_stopped = always_stopped && s.estop;
    never_synchronised = never_synchronised && !s.synchronised;
  }
  std::printf("restarted EDP under the stop: %zu states, max joint change %.2e rad\n", held.size(),
              worst);
  EXPECT_TRUE(always_stopped);
  EXPECT_TRUE(never_synchronised);
  EXPECT_LT(worst, 1e-9);

  // Release (confirmed), START again: the robot synchronises and moves.
  auto [release_code, release_out] = run({ui(), "release", "--config", config.string()});
  std::printf("%s", release_out.c_str());
  EXPECT_EQ(release_code, 0) << release_out;
  EXPECT_TRUE(has(release_out, "confirmed by irb6 (")) << release_out;
  const std::size_t from_moving = states.count();
  auto [again_code, again_out] = run({ui(), "start", "--config", config.string()});
  EXPECT_EQ(again_code, 0) << again_out;
  const auto until = Clock::now() + 30s;
  double moved = 0;
  while (Clock::now() < until && moved < 0.1) {
    std::this_thread::sleep_for(100ms);
    const auto after = states.since(from_moving);
    if (!after.empty()) moved = max_joint_change(after);
  }
  std::printf("after the release the robot moved %.3f rad\n", moved);
  EXPECT_GE(moved, 0.1) << launch.output();
  (void)run({ui(), "terminate", "--config", config.string()});
  EXPECT_NE(launch.wait(60s), -1);
  EXPECT_EQ(leftovers(), "");
}

// No time a sender writes may gate a release: a forged ENGAGE stamped with the largest time, an
// operator's RELEASE, then an ENGAGE the latch never hears (the launcher stopped while its socket
// overflows, as on a flooded group): the latch keeps announcing RELEASED, and the EDP stays
// stopped until an operator releases it.
TEST(EstopLatch, AForgedTimeAndAnEngageTheLatchMissedLeaveTheEdpStopped) {
  const fs::path config = idle_irb6_config("estop-forged", "");
  States states;
  Background launch({launcher(), config.string()});
  ASSERT_TRUE(launch.wait_for("task running", 60s)) << launch.output();
  ASSERT_TRUE(has(launch.output(), "emergency stop released (heard after")) << launch.output();

  // 1. A forged ENGAGE (no key, a made-up sender) with utime = INT64_MAX: it stops (any ENGAGE
  //    may) and the latch holds it.
  {
    mrroc::comm::Bus forger(kUrl);
    mrroc::EmergencyStop forged;
    forged.action = mrroc::EstopAction::engage;
    forged.reason = "forged";
    forged.command_id = INT64_MAX;
    mrroc::comm::broadcast(forger, mrroc::channels::emergency_stop,
                           mrroc::comm::Envelope{INT64_MAX, "forger#1", INT64_MAX}, forged);
  }
  ASSERT_TRUE(launch.wait_for("emergency stop ENGAGED for irb6 (forged, from forger#1", 5s))
      << launch.output();
  // 2. The operator's RELEASE: confirmed and latched.
  auto [release_code, release_out] = run({ui(), "release", "--config", config.string()});
  std::printf("%s", release_out.c_str());
  ASSERT_EQ(release_code, 0) << release_out;
  ASSERT_TRUE(has(release_out, "latched by launch#")) << release_out;

  // 3. An ENGAGE the latch never hears: the launcher is stopped and its sockets' buffers are
  //    filled (5000 LCM messages on a channel nobody reads) before the stop is sent.
  const pid_t launcher_pid = launch.pid();
  ASSERT_EQ(::kill(launcher_pid, SIGSTOP), 0);
  {
    mrroc::comm::Bus flood(kUrl);
    // Small datagrams: a socket's buffer (208 KiB) takes one more datagram while it is below its
    // limit, so large ones leave room for the small ENGAGE after them.
    const std::vector<std::uint8_t> junk(300, 0x55);
    for (int i = 0; i < 5000; ++i)
      flood.lcm().publish("flood", junk.data(), static_cast<unsigned>(junk.size()));
  }
  std::this_thread::sleep_for(300ms);  // the running processes read the flood away
  auto [missed_code, missed_out] =
      run({ui(), "estop", "--config", config.string(), "--reason", "missed by the latch"});
  std::printf("%s", missed_out.c_str());
  ASSERT_EQ(::kill(launcher_pid, SIGCONT), 0);
  // The EDP obeyed it; no latch named it: mrroc-ui says the stop is not latched (exit 4).
  EXPECT_EQ(missed_code, 4) << missed_out;
  EXPECT_TRUE(has(missed_out, "confirmed by irb6 (")) << missed_out;
  EXPECT_TRUE(has(missed_out, "NOT LATCHED")) << missed_out;
  const std::size_t from_state = states.count();
  std::this_thread::sleep_for(1500ms);  // ten announcements of RELEASED
  ASSERT_FALSE(has(launch.output(), "ENGAGED for irb6 (missed by the latch"))
      << "the latch heard the ENGAGE after all: the flood did not fill its socket\n"
      << launch.output();
  const auto held = states.since(from_state);
  ASSERT_GT(held.size(), 40u);
  std::size_t released = 0;
  for (const auto& s : held) released += s.estop ? 0 : 1;
  EXPECT_EQ(released, 0u) << "of " << held.size()
                          << " states in 1.5 s after the stop the latch missed\n"
                          << launch.output();

  // 4. Only an operator's RELEASE ends it.
  auto [again_code, again_out] = run({ui(), "release", "--config", config.string()});
  std::printf("%s", again_out.c_str());
  EXPECT_EQ(again_code, 0) << again_out;
  EXPECT_TRUE(has(again_out, "confirmed by irb6 (")) << again_out;
  (void)run({ui(), "terminate", "--config", config.string()});
  EXPECT_NE(launch.wait(60s), -1);
  EXPECT_EQ(leftovers(), "");
}

TEST(OneSetPerUrl, ASecondLaunchAndASecondEdpRefuseAndTheFirstSetFinishes) {
  const fs::path dir = temp_dir("oneset");
  std::string text = slurp(kSource / "configs/demo-irb6.toml");
  text.replace(text.find("\"../robots/irb6\""), 16,
               "\"" + (kSource / "robots/irb6").string() + "\"");
  const fs::path config = dir / "demo-irb6.toml";
  std::ofstream(config) << text;
  Background first({launcher(), config.string()});
  ASSERT_TRUE(first.wait_for("task running", 60s)) << first.output();
  const pid_t first_launcher = first.pid();

  const auto t0 = Clock::now();
  auto [code, out] = run({launcher(), config.string()}, 30s);
  std::printf("second launch (%.2f s): exit %d\n%s", seconds(Clock::now() - t0), code, out.c_str());
  EXPECT_EQ(code, 2) << out;
  EXPECT_TRUE(has(out, "mrroc-launch: refusing to start set 'demo-irb6' (" + config.string() +
                           "): another process set runs on LCM " + kUrl + ": a launcher (pid " +
                           std::to_string(first_launcher) + ", "))
      << out;
  EXPECT_TRUE(has(out, "runs set 'demo-irb6' from " + config.string())) << out;
  EXPECT_TRUE(has(out, "the EDP of robot irb6 ('edp/irb6#")) << out;
  EXPECT_TRUE(has(out, "nothing started")) << out;
  EXPECT_FALSE(has(out, "mrroc-launch: started")) << out;

  // An EDP of the same robot started by hand refuses too (before it says anything).
  auto [edp_code, edp_out] =
      run({(kBin / "mrroc-edp").string(), "--config", config.string(), "--robot", "irb6"}, 30s);
  std::printf("second EDP: exit %d\n%s", edp_code, edp_out.c_str());
  EXPECT_EQ(edp_code, 2) << edp_out;
  EXPECT_TRUE(has(edp_out, "another EDP of robot 'irb6' is running on LCM")) << edp_out;

  // The first set is not disturbed: it visits its three poses and finishes.
  EXPECT_EQ(first.wait(120s), 0) << first.output();
  const std::string all = first.output();
  EXPECT_TRUE(has(all, "pose 3/3 reached")) << all;
  for (const char* bad : {"refused", "timed out", "dropped a message"})
    EXPECT_FALSE(has(all, bad)) << bad << "\n" << all;
  // A fatal report of the EDP: the SRP's line, or the EDP's own when the SRP is not running.
  EXPECT_FALSE(std::regex_search(all, std::regex("edp/irb6:? +fatal"))) << all;
  EXPECT_EQ(leftovers(), "");
}

// With a key, what is not signed with it cannot keep a set from starting: a stranger on the URL
// sends a launcher's table and robot_state_t of the set's robot, unsigned, all the time the set
// starts. The launcher says it ignored them, the EDP starts (its own check for another EDP
// ignores them too) and the task finishes.
TEST(OneSetPerUrl, UnauthenticatedTablesAndStatesDoNotBlockAKeyedSet) {
  const fs::path dir = temp_dir("keyed-oneset");
  const fs::path key = dir / "set.key";
  std::ofstream(key) << "00112233445566778899aabbccddeeff00112233445566778899aabbccddeeff\n";
  fs::permissions(key, fs::perms::owner_read | fs::perms::owner_write, fs::perm_options::replace);
  std::string text = slurp(kSource / "configs/demo-irb6.toml");
  text.replace(text.find("\"../robots/irb6\""), 16,
               "\"" + (kSource / "robots/irb6").string() + "\"");
  text.replace(text.find("[system]\n"), 9, "[system]\nauth_key_file = \"" + key.string() + "\"\n");
  const fs::path config = dir / "demo-irb6.toml";
  std::ofstream(config) << text;

  mrroc::comm::Bus stranger(kUrl);  // no key
  stranger.start();
  std::atomic<bool> forging{true};
  std::thread forger([&] {
    mrroc::launch::LaunchStatus table;
    table.set_name = "demo-irb6";
    table.config_file = config.string();
    table.state = "running";
    table.launcher_pid = 4242;
    mrroc::RobotState state;
    state.robot = "irb6";
    state.servo_period_s = 0.002;
    state.q.assign(5, 0.0);
    state.dq.assign(5, 0.0);
    state.q_desired.assign(5, 0.0);
    for (std::int64_t seq = 1; forging.load(); ++seq) {
      const mrroc::comm::Envelope header{mrroc::now_utime(), "stranger#1", seq};
      mrroc::comm::broadcast(stranger, mrroc::channels::launch_status, header, table);
      state.servo_step = seq;
      mrroc::comm::broadcast(stranger, mrroc::channels::robot_state("irb6"), header, state);
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
  });
  Background set({launcher(), config.string()});
  // Through the launcher's listen and the EDP's start.
  const bool running = set.wait_for("task running", 60s).has_value();
  forging.store(false);
  forger.join();
  stranger.stop();
  ASSERT_TRUE(running) << set.output();
  EXPECT_EQ(set.wait(120s), 0) << set.output();
  const std::string out = set.output();
  EXPECT_FALSE(has(out, "refusing to start")) << out;
  EXPECT_FALSE(has(out, "another EDP of robot")) << out;
  EXPECT_TRUE(has(out, "mrroc-launch: warning: unauthenticated messages on LCM " +
                           std::string(kUrl) +
                           ", not signed with the set's key (ignored: they "
                           "do not keep the set from starting): "))
      << out;
  EXPECT_TRUE(has(out, "a launcher's table (set 'demo-irb6') from 'stranger#1'")) << out;
  EXPECT_TRUE(has(out, "the state of robot irb6 from 'stranger#1'")) << out;
  EXPECT_TRUE(has(out, "pose 3/3 reached")) << out;
  EXPECT_EQ(leftovers(), "");
  fs::remove_all(dir);
}

// With a key, mrroc-ui needs it as the console does: the same commands from a copy of the config
// without the key (what anyone on the network can send) start nothing and release nothing,
// while the operator's, signed with the key, do. A stop is taken from anybody.
TEST(EstopLatch, CommandsWithoutTheKeyAreRefusedByAKeyedSet) {
  const fs::path config = idle_irb6_config("keyed-commands", "");
  const fs::path key = config.parent_path() / "set.key";
  std::ofstream(key) << "0123456789abcdef0123456789abcdef0123456789abcdef0123456789abcdef\n";
  fs::permissions(key, fs::perms::owner_read | fs::perms::owner_write, fs::perm_options::replace);
  const std::string text = slurp(config);
  std::string keyed = text;
  keyed.replace(keyed.find("[system]\n"), 9,
                "[system]\nauth_key_file = \"" + key.string() + "\"\n");
  std::ofstream(config) << keyed;
  const fs::path stranger = config.parent_path() / "no-key.toml";
  std::ofstream(stranger) << text;

  States states;
  Background launch({launcher(), config.string()});
  ASSERT_TRUE(launch.wait_for("task running", 60s)) << launch.output();

  // START without the key: the MP drops it (no answer), the task stays IDLE.
  auto [start_code, start_out] =
      run({ui(), "start", "--config", stranger.string(), "--timeout", "1"});
  EXPECT_EQ(start_code, 3) << start_out;
  EXPECT_TRUE(has(start_out, "no MP answers")) << start_out;
  auto [status_code, status_out] = run({ui(), "status", "--config", config.string()});
  EXPECT_EQ(status_code, 0) << status_out;
  EXPECT_TRUE(has(status_out, "IDLE, runs 0")) << status_out;

  // A stop from anybody is obeyed; its release only with the key.
  auto [stop_code, stop_out] = run({ui(), "estop", "--config", stranger.string()});
  EXPECT_TRUE(has(stop_out, "confirmed by irb6 (")) << stop_out;
  auto [release_code, release_out] = run({ui(), "release", "--config", stranger.string()});
  EXPECT_EQ(release_code, 4) << release_out;
  EXPECT_TRUE(has(release_out, "NOT CONFIRMED by irb6")) << release_out;
  std::this_thread::sleep_for(std::chrono::milliseconds(300));
  const auto recent = states.since(states.count() > 3 ? states.count() - 3 : 0);
  ASSERT_FALSE(recent.empty()) << "no robot_state_t of irb6 heard";
  EXPECT_TRUE(recent.back().estop) << "a release without the key released the stop";
  auto [keyed_code, keyed_out] = run({ui(), "release", "--config", config.string()});
  EXPECT_EQ(keyed_code, 0) << keyed_out;
  EXPECT_TRUE(has(keyed_out, "confirmed by irb6 (")) << keyed_out;

  // The operator's START, signed with the key, runs the task.
  auto [ok_code, ok_out] = run({ui(), "start", "--config", config.string()});
  EXPECT_EQ(ok_code, 0) << ok_out;
  EXPECT_TRUE(has(ok_out, "START accepted")) << ok_out;
  EXPECT_TRUE(launch.wait_for("task 'start_and_wait' finished", 120s)) << launch.output();
  auto [end_code, end_out] = run({ui(), "terminate", "--config", config.string()});
  EXPECT_EQ(end_code, 0) << end_out;
  EXPECT_EQ(launch.wait(60s), 0) << launch.output();
  EXPECT_EQ(leftovers(), "");
  fs::remove_all(config.parent_path());
}
