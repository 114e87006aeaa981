// The EDP's lookahead and its servo thread's independence: macro-steps queued ahead of the
// servo loop carry a trajectory across a client that stalls for longer than a macro-step (the
// same stall with the paper's single successor stops the robot), the last macro-step of a motion
// is still answered after its stop, one exchange (with_query) gives what SET + QUERY gives, a
// refused macro-step takes everything queued behind it along, and an emergency stop, state
// reads and submissions never wait for a plugin's write() (a simulation step).
#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <cstdio>
#include <cstring>
#include <future>
#include <mutex>
#include <string>
#include <thread>

#include <pthread.h>
#include <sched.h>

#include "command_interpreter.hpp"
#include "edp_parts.hpp"
#include "macro_step_queue.hpp"
#include "mrroc/edp/arm_kinematics.hpp"
#include "mrroc/edp/hardware.hpp"
#include "mrroc/robot/robot_model.hpp"
#include "servo_loop.hpp"

using namespace mrroc;
using namespace mrroc::edp;

namespace {

constexpr double kPeriod = 0.002;

// A build instrumented by AddressSanitizer or ThreadSanitizer (scripts/test's later stages).
#if defined(__SANITIZE_ADDRESS__) || defined(__SANITIZE_THREAD__)
constexpr bool kInstrumented = true;
#elif defined(__has_feature)
#if __has_feature(address_sanitizer) || __has_feature(thread_sanitizer)
constexpr bool kInstrumented = true;
#else
constexpr bool kInstrumented = false;
#endif
#else
constexpr bool kInstrumented = false;
#endif

TEST(MacroStepQueue, KeepsOrderWrapsAroundAndKnowsWhenFull) {
  MacroStepQueue q;
  EXPECT_TRUE(q.empty());
  std::uint64_t next_in = 1;
  std::uint64_t next_out = 1;
  // Three times round the ring, half full on average.
  for (int round = 0; round < 3 * static_cast<int>(MacroStepQueue::kCapacity); ++round) {
    while (q.size() < MacroStepQueue::kCapacity / 2) {
      MacroStep m;
      m.id = next_in++;
      q.push(m);
    }
    EXPECT_EQ(q.front().id, next_out);
    EXPECT_EQ(q.back().id, next_in - 1);
    EXPECT_EQ(q.pop().id, next_out++);
  }
  while (!q.full()) {
    MacroStep m;
    m.id = next_in++;
    q.push(m);
  }
  EXPECT_EQ(q.size(), MacroStepQueue::kCapacity);
  EXPECT_EQ(q.at(q.size() - 1).id, next_in - 1);
  q.clear();
  EXPECT_TRUE(q.empty());
}

/// The mujoco plugin as hardware that keeps its own clock (simulated() false, as drives): the
/// servo loop makes up the periods it misses. Its write() can hold the servo thread once.
class ClockedHardware final : public Hardware {
 public:
  explicit ClockedHardware(std::unique_ptr<Hardware> inner) : inner_(std::move(inner)) {}
  std::string name() const override { return "clocked"; }
  std::size_t axis_count() const override { return inner_->axis_count(); }
  void configure(const HardwareSetup& setup) override { inner_->configure(setup); }
  void activate() override { inner_->activate(); }
  void deactivate() override { inner_->deactivate(); }
  CycleStatus read(std::span<AxisFeedback> out) override { return inner_->read(out); }
  CycleStatus write(std::span<const double> setpoints) override {
    const CycleStatus status = inner_->write(setpoints);
    if (const int ms = stall_ms_.exchange(0); ms > 0)
      std::this_thread::sleep_for(std::chrono::milliseconds(ms));
    return status;
  }
  /// The next write() holds the servo thread `ms` milliseconds.
  void stall_once(int ms) { stall_ms_ = ms; }

 private:
  std::unique_ptr<Hardware> inner_;
  std::atomic<int> stall_ms_{0};
};

/// The calling thread at SCHED_FIFO `priority` (where the system grants it) until destroyed.
class RealTimeThread {
 public:
  explicit RealTimeThread(int priority) {
    pthread_getschedparam(pthread_self(), &policy_, &param_);
    sched_param sp{};
    sp.sched_priority = priority;
    const int err = pthread_setschedparam(pthread_self(), SCHED_FIFO, &sp);
    set_ = err == 0;
    text_ = set_ ? "SCHED_FIFO " + std::to_string(priority)
                 : "SCHED_OTHER (SCHED_FIFO refused: " + std::string(std::strerror(err)) + ")";
  }
  ~RealTimeThread() {
    if (set_) pthread_setschedparam(pthread_self(), policy_, &param_);
  }
  RealTimeThread(const RealTimeThread&) = delete;
  RealTimeThread& operator=(const RealTimeThread&) = delete;
  const std::string& policy() const { return text_; }

 private:
  int policy_ = SCHED_OTHER;
  sched_param param_{};
  bool set_ = false;
  std::string text_;
};

class Lookahead : public ::testing::Test {
 protected:
  void start(int depth, bool keeps_time = false) {
    model_ = test::stock_model("irb6");
    hardware_ = test::configured_hardware(model_, "mujoco", kPeriod);
    if (keeps_time) {
      auto clocked = std::make_unique<ClockedHardware>(std::move(hardware_));
      clocked_ = clocked.get();
      hardware_ = std::move(clocked);
    }
    kinematics_ = make_arm_kinematics(model_);
    servo_ = std::make_unique<ServoLoop>(*hardware_, model_, kPeriod);
    servo_->set_limit_guard(kinematics_.get());
    servo_->set_lookahead(depth);
    servo_->enable_trace(20000);
    servo_->start();
    interpreter_ = std::make_unique<CommandInterpreter>(*servo_, model_, *kinematics_, kPeriod);
    Instruction s;
    s.type = InstructionType::synchro;
    s.with_query = true;
    ASSERT_EQ(interpreter_->execute(s).type, ReplyType::data);
  }
  void TearDown() override {
    if (servo_) servo_->stop();
  }

  static Instruction set_joints(std::vector<double> q, int steps, int value, bool with_query) {
    Instruction in = test::set_joints_instruction(std::move(q), steps, value);
    in.with_query = with_query;
    return in;
  }

  /// Column velocities [rad/s] commanded from the first moving step after `from` on.
  std::vector<double> column_velocities(std::int64_t from) const {
    const auto trace = servo_->trace();
    std::vector<double> v;
    for (std::size_t i = 1; i < trace.size(); ++i)
      if (trace[i].cycle > from)
        v.push_back((trace[i].desired[0] - trace[i - 1].desired[0]) / kPeriod);
    std::size_t first = 0;
    while (first < v.size() && v[first] == 0.0) ++first;
    return {v.begin() + static_cast<std::ptrdiff_t>(first), v.end()};
  }

  ClockedHardware* clocked_ = nullptr;

  struct StallRun {
    int off = -1;         ///< cruise servo steps commanded at a velocity other than 0.1 rad/s
    int refused_at = -1;  ///< the first macro-step (0: the first ramp) whose reply was an error
    Reply refusal;        ///< that reply
  };

  /// A constant-velocity column motion (0.1 rad/s) of `segments` macro-steps of 10 servo steps
  /// (20 ms), one exchange each, read 3 steps early, between a macro-step of 60 steps that
  /// accelerates to it from rest and one that brings the column to rest (test::cruise); the
  /// client stalls `stall_ms` before cruise macro-step `stall_at`. Stops at the first refusal.
  /// `off` counts the servo steps of the cruise but its last macro-step.
  StallRun run_with_stall(int segments, int stall_at, int stall_ms) {
    constexpr int kSteps = 10;
    constexpr int kRamp = 60;
    const std::int64_t from = servo_->latest().cycle;
    std::vector<double> q = model_.synchro_joint_positions;
    const auto plan = test::cruise(q[0], 0.1, kRamp, kSteps, segments, kPeriod);
    StallRun run;
    for (std::size_t k = 0; k < plan.size(); ++k) {
      if (static_cast<int>(k) == stall_at)
        std::this_thread::sleep_for(std::chrono::milliseconds(stall_ms));
      q[0] = plan[k].first;
      const int n = plan[k].second;
      const int value = k + 1 == plan.size() ? n + 1 : n - 3;
      const Reply r = interpreter_->execute(set_joints(q, n, value, true));
      if (r.type != ReplyType::data) {
        run.refused_at = static_cast<int>(k);
        run.refusal = r;
        break;
      }
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(200));
    const std::vector<double> v = column_velocities(from);
    // The cruise but its last macro-step, which the EDP may already blend into the final
    // deceleration when it sees that coming in its lookahead.
    run.off = 0;
    for (std::size_t i = kRamp; i < kRamp + static_cast<std::size_t>(kSteps * (segments - 1)); ++i)
      if (i >= v.size() || std::abs(v[i] - 0.1) > 1e-9) ++run.off;
    return run;
  }

  RobotModel model_;
  std::unique_ptr<Hardware> hardware_;
  std::unique_ptr<ServoLoop> servo_;
  std::unique_ptr<ArmKinematics> kinematics_;
  std::unique_ptr<CommandInterpreter> interpreter_;
};

TEST_F(Lookahead, AQueueOfEightCarriesTheMotionAcrossA60MsClientStall) {
  start(8);
  const StallRun run = run_with_stall(40, 20, 60);
  EXPECT_EQ(run.refused_at, -1) << run.refusal.error_text;
  EXPECT_EQ(run.off, 0) << "servo steps off the commanded 0.1 rad/s";
  EXPECT_EQ(servo_->lost_successors(), 0);
}

TEST_F(Lookahead, WithTheSingleSuccessorTheSameStallStopsTheRobot) {
  // The paper's depth 1: 60 ms of client silence is longer than the 6 ms its reading leaves.
  // The robot ramps down; the plan's next macro-steps, which assume it kept its 0.1 rad/s, are
  // then too abrupt from where the ramp left it (refused, the robot holds).
  if (kInstrumented)
    GTEST_SKIP()
        << "a real-time case: the paper's depth 1 leaves the client 6 ms per macro-step, "
           "which an instrumented build's SET (5-20 times slower) does not keep on a "
           "shared host (it ran dry at macro-step 16 under ASan, 8 under TSan, before "
           "the stall at 20); it runs in the uninstrumented build, and the lost-successor "
           "path runs under the sanitizers in EdpSafety.LostEcpBringsTheRobotToAStandstill";
  start(1);
  // The client is a thread the host schedules: at SCHED_OTHER beside CI's other tests it once
  // missed the 6 ms at macro-step 10, and the robot stopped before the stall this case is about.
  // An ECP that must keep depth 1's window runs at a real-time priority (its `priority`); so
  // does the client here, below the servo thread's 80.
  const RealTimeThread client(50);
  std::printf("client thread: %s\n", client.policy().c_str());
  const StallRun run = run_with_stall(40, 20, 60);
  EXPECT_GT(run.off, 0);
  EXPECT_GE(servo_->lost_successors(), 1);
  EXPECT_GE(run.refused_at, 20);
  if (run.refused_at >= 0) {
    EXPECT_EQ(run.refusal.error_code, error_code::too_abrupt) << run.refusal.error_text;
    EXPECT_NE(run.refusal.error_text.find("rad/s^2"), std::string::npos) << run.refusal.error_text;
  }
  EXPECT_TRUE(servo_->stopped());
}

TEST_F(Lookahead, RepliesRunAheadByTheDepthAndTheLastOneComesAfterTheStop) {
  start(4);
  std::vector<double> q = model_.synchro_joint_positions;
  const double q0 = q[0];
  const std::int64_t before = servo_->latest().cycle;
  // The column at 0.1 rad/s: macro-step 1 accelerates to it from rest in 60 steps (it ends at
  // its mean velocity: its successors have the same one), 2..4 keep it for 10 steps each and
  // the last brings it to rest in 40 steps.
  constexpr int kFirst = 60;
  const double first = 0.1 * kFirst * kPeriod;
  // The first three replies do not wait for the robot: macro-steps 1..3 sit in the queue. They
  // carry the latest reading: the robot where it stands, synchronised.
  for (int k = 1; k <= 3; ++k) {
    q[0] = q0 + first + 0.002 * (k - 1);
    const int steps = k == 1 ? kFirst : 10;
    const Reply r = interpreter_->execute(set_joints(q, steps, 7, true));
    ASSERT_EQ(r.type, ReplyType::data) << r.error_text;
    // Macro-step 1 starts in the cycle after its submission and reads in its step 7.
    EXPECT_LT(r.servo_cycle, before + 7) << "reply " << k << " waited for the servo loop";
    EXPECT_TRUE(r.synchronised);
    ASSERT_EQ(r.joints.size(), model_.axes());
    for (std::size_t j = 0; j < model_.axes(); ++j)
      EXPECT_NEAR(r.joints[j], model_.synchro_joint_positions[j], 0.01) << "reply " << k;
  }
  // The fourth is answered by the reading of macro-step 1 (3 places before it) in its step 7:
  // from rest towards 0.1 rad/s, accelerating uniformly (edp::blend_position).
  q[0] = q0 + first + 0.006;
  Reply r = interpreter_->execute(set_joints(q, 10, 7, true));
  ASSERT_EQ(r.type, ReplyType::data) << r.error_text;
  EXPECT_EQ(r.step_no, 7);
  EXPECT_NEAR(r.desired_joints[0],
              blend_position(q0, q0 + first, 0.0, 0.1, kFirst * kPeriod, 7.0 / kFirst), 1e-12);
  EXPECT_EQ(r.macro_steps_ahead, 4);
  // The last one promises no successor: its reply is its own reading, after the stop.
  q[0] = q0 + first + 0.006 + 0.05 * 40 * kPeriod;
  r = interpreter_->execute(set_joints(q, 40, 41, true));
  ASSERT_EQ(r.type, ReplyType::data) << r.error_text;
  EXPECT_EQ(r.step_no, 41);
  EXPECT_DOUBLE_EQ(r.desired_joints[0], q[0]);
  EXPECT_EQ(r.macro_steps_ahead, 0);
  EXPECT_EQ(servo_->lost_successors(), 0);
}

TEST_F(Lookahead, AQueryThatComesLateGetsTheReadingOfItsOwnMacroStep) {
  // The client is held up 50 ms (2.5 macro-steps) mid-cruise: when its next exchanges come, the
  // macro-steps their replies are due at have passed their reading steps, and later ones have
  // read since. Each reply must still be the reading of its own macro-step at its own step (7),
  // as the replies of the other robots of a group are: a later reading would put this robot
  // further along its path than they are (two carriers read 0.3-2 mm apart).
  start(4);
  constexpr int kSteps = 10;
  constexpr int kRamp = 60;
  constexpr int kSegments = 30;
  constexpr int kStallAt = 15;
  std::vector<double> q = model_.synchro_joint_positions;
  const auto plan = test::cruise(q[0], 0.1, kRamp, kSteps, kSegments, kPeriod);
  int checked = 0;
  for (std::size_t k = 0; k + 1 < plan.size(); ++k) {
    if (static_cast<int>(k) == kStallAt) std::this_thread::sleep_for(std::chrono::milliseconds(50));
    q[0] = plan[k].first;
    const Reply r = interpreter_->execute(set_joints(q, plan[k].second, plan[k].second - 3, true));
    ASSERT_EQ(r.type, ReplyType::data) << "macro-step " << k << ": " << r.error_text;
    // Replies run 3 macro-steps ahead (depth 4): reply k reads macro-step k - 3. Cruise ones
    // (1.. before the last two, which may blend into the end) at constant velocity: step 7 of
    // macro-step m stands 7 tenths of the way from plan[m - 1] to plan[m].
    const int m = static_cast<int>(k) - 3;
    if (m < 2 || m > kSegments - 2) continue;
    EXPECT_EQ(r.step_no, kSteps - 3) << "reply " << k;
    const auto at = static_cast<std::size_t>(m);
    const double expected = plan[at - 1].first + 0.7 * (plan[at].first - plan[at - 1].first);
    EXPECT_NEAR(r.desired_joints[0], expected, 1e-9)
        << "reply " << k << " (macro-step " << m << (k >= kStallAt ? ", after the stall" : "")
        << ") is the reading of another servo step";
    ++checked;
  }
  EXPECT_GE(checked, kSegments - 4);
  EXPECT_EQ(servo_->lost_successors(), 0);
}

TEST_F(Lookahead, OneExchangeAnswersAsSetThenQuery) {
  start(1);
  std::vector<double> q = model_.synchro_joint_positions;
  const double q0 = q[0];
  // 0.02 rad in 80 steps from rest, read in step 5: no successor is queued when it starts, so
  // the EDP ends it at its mean velocity (0.125 rad/s), accelerating uniformly in each half.
  q[0] = q0 + 0.02;
  const Reply one = interpreter_->execute(set_joints(q, 80, 5, true));
  ASSERT_EQ(one.type, ReplyType::data) << one.error_text;
  EXPECT_EQ(one.step_no, 5);
  EXPECT_NEAR(one.desired_joints[0],
              blend_position(q0, q0 + 0.02, 0.0, 0.125, 80 * kPeriod, 5.0 / 80.0), 1e-12);
  // The paper's pair on the same interpreter: ACKNOWLEDGE, then the reading for the QUERY (the
  // column keeps its 0.125 rad/s: a straight line).
  q[0] = q0 + 0.04;
  ASSERT_EQ(interpreter_->execute(set_joints(q, 80, 5, false)).type, ReplyType::acknowledge);
  Instruction query;
  query.type = InstructionType::query;
  const Reply two = interpreter_->execute(query);
  ASSERT_EQ(two.type, ReplyType::data) << two.error_text;
  EXPECT_EQ(two.step_no, 5);
  EXPECT_NEAR(two.desired_joints[0],
              blend_position(q0 + 0.02, q0 + 0.04, 0.125, 0.125, 80 * kPeriod, 5.0 / 80.0), 1e-12);
  EXPECT_NEAR(two.desired_joints[0], q0 + 0.02 + 0.02 * 5.0 / 80.0, 1e-12);
  // with_query leaves no QUERY due: a QUERY now is unexpected (the last macro-step brings the
  // column to rest, 0.01 rad further).
  q[0] = q0 + 0.05;
  const Reply last = interpreter_->execute(set_joints(q, 80, 81, true));
  ASSERT_EQ(last.type, ReplyType::data) << last.error_text;
  EXPECT_EQ(interpreter_->execute(query).error_code, error_code::query_unexpected);
}

TEST_F(Lookahead, AServoThreadHeldOnClockedHardwareMakesUpTheMissedStepsWithinTheLimits) {
  // Drives keep their own clock: when the servo thread is held 30 ms mid-motion (a host stall),
  // the motion makes up the 15 servo steps it missed by running a little faster, within the
  // limits, instead of lagging behind its plan (and behind a robot it moves with) to the end.
  start(8, true);
  std::vector<double> q = model_.synchro_joint_positions;
  const double cruise = 0.1;  // rad/s
  const auto plan = test::cruise(q[0], cruise, 60, 10, 60, kPeriod);
  int planned_steps = 0;
  for (const auto& [target, steps] : plan) planned_steps += steps;
  const std::int64_t from = servo_->latest().cycle;
  for (std::size_t k = 0; k < plan.size(); ++k) {
    if (k == 20) clocked_->stall_once(30);
    q[0] = plan[k].first;
    const int n = plan[k].second;
    const int value = k + 1 == plan.size() ? n + 1 : n - 3;
    const Reply r = interpreter_->execute(set_joints(q, n, value, true));
    ASSERT_EQ(r.type, ReplyType::data) << k << ": " << r.error_text;
  }
  std::this_thread::sleep_for(std::chrono::milliseconds(100));
  EXPECT_EQ(servo_->lost_successors(), 0);
  const std::vector<double> v = column_velocities(from);
  int moving = 0;
  for (std::size_t i = 0; i < v.size(); ++i)
    if (v[i] != 0.0) moving = static_cast<int>(i) + 1;
  // The fastest of the cruise (the ramps from and to rest excepted: their cubic blends peak
  // above the cruise as planned) and the hardest change of velocity of the whole motion.
  double fastest = 0.0;
  double hardest = 0.0;
  for (std::size_t i = 0; i < v.size(); ++i) {
    if (i > 70 && static_cast<int>(i) < moving - 80) fastest = std::max(fastest, std::abs(v[i]));
    if (i > 0) hardest = std::max(hardest, std::abs(v[i] - v[i - 1]) / kPeriod);
  }
  std::printf(
      "held 30 ms: %lld steps made up; %d cycles in motion for %d planned steps; fastest %.4f "
      "rad/s (cruise %.1f), hardest %.3f rad/s^2 (limit %.1f)\n",
      static_cast<long long>(servo_->caught_up_steps()), moving, planned_steps, fastest, cruise,
      hardest, model_.max_acceleration[0]);
  EXPECT_GE(servo_->caught_up_steps(), 12);
  // Back on its time line: the motion ended the missed periods sooner than planned (12 of the
  // 14; a slow build may miss more periods, and make them up too).
  EXPECT_LE(moving, planned_steps - 12);
  EXPECT_GT(fastest, cruise * 1.1) << "no catch-up seen in the cruise";
  EXPECT_LE(fastest, cruise * 1.25 + 1e-9);
  EXPECT_LE(hardest, model_.max_acceleration[0] + 1e-9);
}

TEST_F(Lookahead, ARefusedMacroStepTakesTheQueueBehindItAlongAndIsReportedOnce) {
  start(4);
  std::vector<double> q = model_.synchro_joint_positions;
  const double q0 = q[0];
  // A motion from rest to 0.5 rad/s on the column in 300 steps (2.5 rad/s^2 at most; limit 3)
  // whose successor never comes: the ramp carries the column 0.042 rad past the target.
  q[0] = q0 + 0.15;
  // (A motion from rest first waits up to 0.2 s for the successors its client may send.)
  const Reply first = interpreter_->execute(set_joints(q, 300, 297, true));
  ASSERT_EQ(first.type, ReplyType::data) << first.error_text;
  const auto give_up = std::chrono::steady_clock::now() + std::chrono::seconds(3);
  while (servo_->lost_successors() == 0 && std::chrono::steady_clock::now() < give_up)
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  std::this_thread::sleep_for(std::chrono::milliseconds(200));  // the ramp ends (0.17 s)
  ASSERT_EQ(servo_->lost_successors(), 1);
  // The planned continuation (0.75 rad/s) is too abrupt from where the ramp left the robot (at
  // rest, 0.04 rad past the target). With a lookahead of 4 the first three replies come before
  // the first of them is due to start (and refused); the refusal reaches the client in the
  // reply to the fourth at the latest.
  for (int k = 1; k <= 4; ++k) {
    q[0] = q0 + 0.15 + 0.03 * k;
    const Reply r = interpreter_->execute(set_joints(q, 20, 17, true));
    if (r.type == ReplyType::error) {
      EXPECT_EQ(r.error_code, error_code::too_abrupt) << r.error_text;
      EXPECT_NE(r.error_text.find("rad/s^2"), std::string::npos) << r.error_text;
      EXPECT_NE(r.error_text.find("starting where a stopping ramp left the robot"),
                std::string::npos)
          << r.error_text;
      break;
    }
    ASSERT_LT(k, 4) << "four macro-steps accepted from where the ramp left the robot";
  }
  std::this_thread::sleep_for(std::chrono::milliseconds(100));
  EXPECT_TRUE(servo_->stopped());
  // Reported once: a new plan from where the robot stands is accepted.
  const std::vector<double> here = servo_->planned_end();
  q = here;
  q[0] -= 0.01;
  const int steps = test::rest_to_rest_steps(model_, here, q, kPeriod);
  const Reply r = interpreter_->execute(set_joints(q, steps, steps + 1, true));
  EXPECT_EQ(r.type, ReplyType::data) << r.error_text;
}

TEST_F(Lookahead, AWaivedSuccessorEndsInAPlannedStopNotALostOne) {
  start(4);
  std::vector<double> q = model_.synchro_joint_positions;
  const double q0 = q[0];
  // The column to 0.1 rad/s in 60 steps, then two macro-steps of 10 at it.
  for (int k = 1; k <= 3; ++k) {
    q[0] = q0 + 0.012 + 0.002 * (k - 1);
    const Reply r = interpreter_->execute(set_joints(q, k == 1 ? 60 : 10, 7, true));
    ASSERT_EQ(r.type, ReplyType::data) << r.error_text;
  }
  // The task pauses: no macro-step follows the three queued.
  Instruction get;
  get.type = InstructionType::get;
  get.get = item::arm;
  get.no_successor = true;
  get.with_query = true;
  ASSERT_EQ(interpreter_->execute(get).type, ReplyType::data);
  std::this_thread::sleep_for(std::chrono::milliseconds(500));
  EXPECT_TRUE(servo_->stopped());
  EXPECT_EQ(servo_->planned_stops(), 1);
  EXPECT_EQ(servo_->lost_successors(), 0);
  // A motion after the pause that again runs dry without a word is a lost successor.
  // (From rest to 0.0625 rad/s in 40 steps: 1.6 rad/s^2.)
  q[0] = servo_->planned_end()[0] + 0.005;
  const Reply again = interpreter_->execute(set_joints(q, 40, 37, true));
  ASSERT_EQ(again.type, ReplyType::data) << again.error_text;
  std::this_thread::sleep_for(std::chrono::milliseconds(500));
  EXPECT_EQ(servo_->planned_stops(), 1);
  EXPECT_EQ(servo_->lost_successors(), 1);
}

/// Mirrors its setpoints (the axes are where they were told to be); its write() can be held
/// at a gate, as a long simulation step would hold it.
class GatedHardware : public Hardware {
 public:
  explicit GatedHardware(std::size_t axes) : axes_(axes), position_(axes, 0.0) {}
  std::string name() const override { return "gated"; }
  std::size_t axis_count() const override { return axes_; }
  void configure(const HardwareSetup&) override {}
  void activate() override {}
  void deactivate() override {}
  CycleStatus read(std::span<AxisFeedback> out) override {
    std::lock_guard lock(mutex_);
    for (std::size_t i = 0; i < axes_; ++i) out[i].position = position_[i];
    return CycleStatus::ok;
  }
  CycleStatus write(std::span<const double> setpoints) override {
    std::unique_lock lock(mutex_);
    for (std::size_t i = 0; i < axes_; ++i) position_[i] = setpoints[i];
    if (close_) {
      inside_ = true;
      cv_.notify_all();
      cv_.wait(lock, [&] { return !close_; });
      inside_ = false;
    }
    return CycleStatus::ok;
  }
  void close_gate() {
    std::lock_guard lock(mutex_);
    close_ = true;
  }
  bool wait_inside(std::chrono::milliseconds timeout) {
    std::unique_lock lock(mutex_);
    return cv_.wait_for(lock, timeout, [&] { return inside_; });
  }
  void open_gate() {
    std::lock_guard lock(mutex_);
    close_ = false;
    cv_.notify_all();
  }

 private:
  std::size_t axes_;
  std::vector<double> position_;
  std::mutex mutex_;
  std::condition_variable cv_;
  bool close_ = false;
  bool inside_ = false;
};

TEST(ServoLoopThreads, NothingWaitsForAPluginWrite) {
  const RobotModel model = test::stock_model("irb6");
  GatedHardware hardware(model.axes());
  ServoLoop servo(hardware, model, kPeriod);
  servo.start();
  hardware.close_gate();
  ASSERT_TRUE(hardware.wait_inside(std::chrono::seconds(2)));
  // The servo thread is inside write() (a simulation step that does not end): every call from
  // another thread still returns.
  auto calls = std::async(std::launch::async, [&] {
    (void)servo.latest();
    (void)servo.stopped();
    (void)servo.moving();
    (void)servo.take_timing_window();
    servo.emergency_stop();
    return servo.emergency_stopped();
  });
  const bool returned = calls.wait_for(std::chrono::seconds(2)) == std::future_status::ready;
  hardware.open_gate();
  ASSERT_TRUE(returned) << "a call waited for the plugin's write()";
  EXPECT_TRUE(calls.get());
  servo.stop();
}

}  // namespace
