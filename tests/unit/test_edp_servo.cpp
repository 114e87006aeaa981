// The EDP's servo loop and command interpreter on the real MuJoCo plugin (no LCM): the MRROC++
// state machine, synchronisation, limits refused before anything moves, macro-steps that follow
// each other without an idle servo step, and no heap allocation inside the servo cycle.
#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <map>
#include <new>
#include <thread>

#include "command_interpreter.hpp"
#include "edp_parts.hpp"
#include "mrroc/edp/arm_kinematics.hpp"
#include "mrroc/edp/hardware.hpp"
#include "mrroc/kinematics/pose.hpp"
#include "mrroc/robot/robot_model.hpp"
#include "servo_loop.hpp"

// Allocation counting: every operator new on the watched thread is counted.
#include "heap_counter.hpp"

using namespace mrroc;
using namespace mrroc::edp;

namespace {

constexpr double kPeriod = 0.002;

class EdpTest : public ::testing::Test {
 protected:
  void SetUp() override {
    model_ = test::stock_model("irb6");
    hardware_ = test::configured_hardware(model_, "mujoco", kPeriod);
    kinematics_ = make_arm_kinematics(model_);
    servo_ = std::make_unique<ServoLoop>(*hardware_, model_, kPeriod);
    servo_->set_limit_guard(kinematics_.get());
    if (lock_step_) servo_->set_lock_step(true, successor_wait_s_);
    servo_->set_lookahead(lookahead_);
    servo_->enable_trace(20000);
    servo_->start();
    interpreter_ = std::make_unique<CommandInterpreter>(*servo_, model_, *kinematics_, kPeriod);
  }
  void TearDown() override {
    g_heap.watched = std::thread::id{};
    servo_->stop();
  }

  Reply exec(const Instruction& in) { return interpreter_->execute(in); }
  Reply query() {
    Instruction q;
    q.type = InstructionType::query;
    return exec(q);
  }
  Reply synchronise() {
    Instruction s;
    s.type = InstructionType::synchro;
    EXPECT_EQ(exec(s).type, ReplyType::acknowledge);
    return query();
  }
  /// Servo steps for a move from rest where everything queued ends to rest at `q` within 80 % of
  /// every joint's velocity and acceleration limits (the EDP refuses macro-steps beyond them), at
  /// least `at_least`.
  int steps_to(const std::vector<double>& q, int at_least) const {
    return std::max(at_least,
                    test::rest_to_rest_steps(model_, servo_->planned_end(), q, kPeriod, 0.8));
  }

  /// Runs test::cruise on joint `joint` (SET, then QUERY, each SET read `early` steps before
  /// its end, the last one after its stop); `late` is called after each QUERY with the index of
  /// the macro-step.
  template <typename Late>
  void run_cruise(std::size_t joint, double velocity, int ramp_steps, int steps, int segments,
                  int early, Late late) {
    std::vector<double> q = model_.synchro_joint_positions;
    const auto plan = test::cruise(q[joint], velocity, ramp_steps, steps, segments, kPeriod);
    for (std::size_t k = 0; k < plan.size(); ++k) {
      q[joint] = plan[k].first;
      const int n = plan[k].second;
      const int value = k + 1 == plan.size() ? n + 1 : n - early;
      ASSERT_EQ(exec(set_joints(q, n, value)).type, ReplyType::acknowledge) << "macro-step " << k;
      const Reply r = query();
      ASSERT_EQ(r.type, ReplyType::data) << "macro-step " << k << ": " << r.error_text;
      late(k);
    }
  }

  /// The column's commanded velocity in every servo step of the trace after `first_cycle` [rad/s].
  std::vector<double> column_velocities(std::int64_t first_cycle) const {
    const auto trace = servo_->trace();
    std::vector<double> v;
    for (std::size_t i = 1; i < trace.size(); ++i)
      if (trace[i].cycle > first_cycle)
        v.push_back((trace[i].desired[0] - trace[i - 1].desired[0]) / kPeriod);
    return v;
  }

  /// Of the `steps` servo steps of the column's motion after `first_cycle` (from the first step
  /// that moves, `skip` steps later), how many were commanded at a velocity other than `velocity`
  /// [rad/s]; all of them when the trace holds fewer.
  int steps_off_velocity(std::int64_t first_cycle, int steps, double velocity, int skip = 0) const {
    const std::vector<double> v = column_velocities(first_cycle);
    std::size_t start = 0;
    while (start < v.size() && v[start] == 0.0) ++start;
    start += static_cast<std::size_t>(skip);
    if (start + static_cast<std::size_t>(steps) > v.size()) return steps;
    int off = 0;
    for (std::size_t i = start; i < start + static_cast<std::size_t>(steps); ++i)
      if (std::abs(v[i] - velocity) > 1e-9) ++off;
    return off;
  }

  static Instruction set_joints(std::vector<double> q, int steps, int value_in_step_no,
                                MotionType motion = MotionType::absolute) {
    return test::set_joints_instruction(std::move(q), steps, value_in_step_no, motion);
  }

  bool lock_step_ = false;
  double successor_wait_s_ = 1.0;
  int lookahead_ = 1;  // the paper's single successor
  RobotModel model_;
  std::unique_ptr<Hardware> hardware_;
  std::unique_ptr<ServoLoop> servo_;
  std::unique_ptr<ArmKinematics> kinematics_;
  std::unique_ptr<CommandInterpreter> interpreter_;
};

/// The same EDP with its simulation lock-step ([robot.edp] lock_step = true).
class EdpLockStepTest : public EdpTest {
 protected:
  void SetUp() override {
    lock_step_ = true;
    successor_wait_s_ = 0.5;
    EdpTest::SetUp();
  }
};

/// The same EDP with the lookahead of a stock config ([robot.edp] lookahead, default 8): a client
/// that answers each reading at once stays seven macro-steps (140 ms of 20 ms macro-steps) ahead
/// of the servo loop, so a busy or instrumented host does not make the robot stop between them.
class EdpDefaultLookaheadTest : public EdpTest {
 protected:
  void SetUp() override {
    lookahead_ = 8;
    EdpTest::SetUp();
  }
};

}  // namespace

TEST_F(EdpTest, StateMachineErrors) {
  // QUERY with nothing due.
  Reply r = query();
  EXPECT_EQ(r.type, ReplyType::error);
  EXPECT_EQ(r.error_code, error_code::query_unexpected);
  // Motion before SYNCHRO.
  r = exec(set_joints(model_.synchro_joint_positions, 10, 11));
  EXPECT_EQ(r.error_code, error_code::not_synchronised) << r.error_text;
  EXPECT_FALSE(r.synchronised);
  // SYNCHRO, then another instruction before its QUERY.
  Instruction s;
  s.type = InstructionType::synchro;
  EXPECT_EQ(exec(s).type, ReplyType::acknowledge);
  Instruction get;
  get.type = InstructionType::get;
  get.get = item::arm;
  r = exec(get);
  EXPECT_EQ(r.error_code, error_code::query_expected) << r.error_text;
  r = query();
  ASSERT_EQ(r.type, ReplyType::data) << r.error_text;
  EXPECT_TRUE(r.synchronised);
  for (std::size_t j = 0; j < model_.axes(); ++j)
    EXPECT_NEAR(r.joints[j], model_.synchro_joint_positions[j], 2e-3) << "joint " << j;
  // Second SYNCHRO.
  r = exec(s);
  EXPECT_EQ(r.error_code, error_code::already_synchronised);
  // GET works and needs its QUERY.
  EXPECT_EQ(exec(get).type, ReplyType::acknowledge);
  EXPECT_EQ(query().type, ReplyType::data);
}

TEST_F(EdpTest, SynchronisationFindsTheSwitchEdges) {
  const Reply r = synchronise();
  ASSERT_EQ(r.type, ReplyType::data) << r.error_text;
  // Settle, then the measured pose is the synchronisation pose: the offset found at the switch
  // edge is right to within one search step (0.1 rad/s * 2 ms) plus servo lag.
  std::this_thread::sleep_for(std::chrono::milliseconds(300));
  const Reading now = servo_->latest();
  for (std::size_t j = 0; j < model_.axes(); ++j)
    EXPECT_NEAR(now.joints[j], model_.synchro_joint_positions[j], 5e-4) << "joint " << j;
}

TEST_F(EdpTest, LimitsAreRefusedBeforeAnythingMoves) {
  ASSERT_EQ(synchronise().type, ReplyType::data);
  const Reading before = servo_->latest();
  std::vector<double> q = model_.synchro_joint_positions;
  q[2] = 0.81;  // upper arm upper limit is 40 deg = 0.698 rad
  Reply r = exec(set_joints(q, 10, 11));
  EXPECT_EQ(r.type, ReplyType::error);
  EXPECT_EQ(r.error_code, error_code::out_of_limits);
  EXPECT_NE(
      r.error_text.find("joint 2 (upper_arm) target 0.810000 rad exceeds upper limit 0.698132 rad"),
      std::string::npos)
      << r.error_text;
  // Relative motion is checked on its absolute target too.
  r = exec(set_joints({0, -1.0, 0, 0, 0}, 10, 11, MotionType::relative));
  EXPECT_EQ(r.error_code, error_code::out_of_limits) << r.error_text;
  // Bad macro-step arguments.
  EXPECT_EQ(exec(set_joints(model_.synchro_joint_positions, 0, 1)).error_code,
            error_code::bad_argument);
  EXPECT_EQ(exec(set_joints(model_.synchro_joint_positions, 10, 12)).error_code,
            error_code::bad_argument);
  EXPECT_EQ(exec(set_joints({0, 0}, 10, 11)).error_code, error_code::bad_argument);
  std::vector<double> nan = model_.synchro_joint_positions;
  nan[0] = std::nan("");
  EXPECT_EQ(exec(set_joints(nan, 10, 11)).error_code, error_code::bad_argument);
  // Nothing was commanded: the desired pose did not change, and no QUERY is due.
  std::this_thread::sleep_for(std::chrono::milliseconds(50));
  const Reading after = servo_->latest();
  for (std::size_t j = 0; j < model_.axes(); ++j) EXPECT_EQ(after.desired[j], before.desired[j]);
  EXPECT_EQ(query().error_code, error_code::query_unexpected);
}

TEST_F(EdpTest, ReadingComesInTheRequestedStep) {
  ASSERT_EQ(synchronise().type, ReplyType::data);
  std::vector<double> q = model_.synchro_joint_positions;
  // 0.02 rad in 80 steps from rest, read in step 5 (a successor is promised): with no successor
  // queued yet the EDP ends it at its mean velocity, 0.125 rad/s; in between the column
  // accelerates uniformly in each half (edp::blend_position).
  q[0] = 0.02;
  ASSERT_EQ(exec(set_joints(q, 80, 5)).type, ReplyType::acknowledge);
  Reply r = query();
  ASSERT_EQ(r.type, ReplyType::data) << r.error_text;
  EXPECT_EQ(r.step_no, 5);
  EXPECT_NEAR(r.desired_joints[0], blend_position(0.0, 0.02, 0.0, 0.125, 80 * kPeriod, 5.0 / 80.0),
              1e-12);
  // Let the motion end (from 0.125 rad/s to rest): motion_steps + 1 reads after the stop, at the
  // target.
  q[0] = 0.04;
  ASSERT_EQ(exec(set_joints(q, 80, 81)).type, ReplyType::acknowledge);
  r = query();
  ASSERT_EQ(r.type, ReplyType::data) << r.error_text;
  EXPECT_EQ(r.step_no, 81);
  EXPECT_DOUBLE_EQ(r.desired_joints[0], 0.04);
  // Relative motion from the last target.
  const int steps = steps_to({0.05, q[1], q[2], q[3], q[4]}, 10);
  ASSERT_EQ(exec(set_joints({0.01, 0, 0, 0, 0}, steps, steps + 1, MotionType::relative)).type,
            ReplyType::acknowledge);
  r = query();
  ASSERT_EQ(r.type, ReplyType::data) << r.error_text;
  EXPECT_NEAR(r.desired_joints[0], 0.05, 1e-12);
}

TEST_F(EdpDefaultLookaheadTest, ConsecutiveMacroStepsHaveNoIdleServoStep) {
  ASSERT_EQ(synchronise().type, ReplyType::data);
  constexpr int kSteps = 10;
  constexpr int kSegments = 40;
  constexpr int kRamp = 60;  // from rest to 0.1 rad/s: 2.5 rad/s^2 at most (limit 3)
  // A constant-velocity joint motion (0.1 rad/s on the column) cut into macro-steps, between a
  // macro-step that accelerates to it and one that brings the column to rest; each SET goes out
  // as soon as the reading that answers the previous one arrives, as a generator does (with the
  // default lookahead that reading is seven macro-steps old, so the SET has 140 ms of margin; at
  // lookahead 1 it would have 6 ms, which an instrumented build on a busy host misses).
  const std::int64_t first_cycle = servo_->latest().cycle;
  run_cruise(0, 0.1, kRamp, kSteps, kSegments, 3, [](std::size_t) {});
  std::this_thread::sleep_for(std::chrono::milliseconds(200));  // the last macro-step's stop
  // Every servo step of the cruise at the commanded velocity but the last macro-step's, which
  // the EDP blends into the slower macro-step it sees queued behind it.
  const int off = steps_off_velocity(first_cycle, kSteps * (kSegments - 1), 0.1, kRamp);
  EXPECT_EQ(off, 0) << "servo steps with a velocity other than the commanded 0.1 rad/s";
  // And no idle servo step anywhere between the first step that moves and the last.
  const std::vector<double> v = column_velocities(first_cycle);
  const auto first = std::find_if(v.begin(), v.end(), [](double x) { return x != 0.0; });
  const auto last = std::find_if(v.rbegin(), v.rend(), [](double x) { return x != 0.0; }).base();
  ASSERT_LT(first, last);
  EXPECT_EQ(std::count(first, last, 0.0), 0) << "idle servo steps within the motion";
  EXPECT_EQ(last - first, 2 * kRamp + kSteps * kSegments) << "servo steps from start to rest";
  std::printf("%d macro-steps, %d servo steps at 0.1 rad/s, %td moving steps, none idle\n",
              kSegments, kSteps * (kSegments - 1), last - first);
}

TEST_F(EdpDefaultLookaheadTest, ServoCycleDoesNotAllocate) {
  std::this_thread::sleep_for(std::chrono::milliseconds(20));
  g_heap.watched = servo_->servo_thread_id();
  g_heap.allocations = 0;
  ASSERT_EQ(synchronise().type, ReplyType::data);  // synchronisation runs in the servo cycle
  // 20 macro-steps of the shoulder at 0.05 rad/s, each read one step early, between a
  // macro-step that accelerates to it and one that brings it to rest.
  run_cruise(1, 0.05, 60, 10, 20, 1, [](std::size_t) {});
  const std::int64_t cycles = servo_->latest().cycle;
  g_heap.watched = std::thread::id{};
  EXPECT_EQ(g_heap.allocations.load(), 0) << "heap allocations in the servo thread";
  EXPECT_GT(cycles, 200);
  const TimingStats t = servo_->timing();
  std::printf("servo: %lld cycles, lateness p50 %.1f us p99 %.1f us, %lld overruns (%s)\n",
              static_cast<long long>(t.cycles), t.lateness_p50_us, t.lateness_p99_us,
              static_cast<long long>(t.overruns), t.scheduling.c_str());
}

TEST_F(EdpTest, ServoAlgorithmOutputsAndTiming) {
  ASSERT_EQ(synchronise().type, ReplyType::data);
  Instruction in;
  in.type = InstructionType::set_get;
  in.set = item::servo | item::outputs;
  in.get = item::servo | item::inputs | item::timing;
  in.servo_algorithm.assign(model_.axes(), 0);
  in.servo_parameters_no.assign(model_.axes(), 0);
  in.output_values = 0x5;
  ASSERT_EQ(exec(in).type, ReplyType::acknowledge);
  Reply r = query();
  ASSERT_EQ(r.type, ReplyType::data) << r.error_text;
  EXPECT_EQ(r.servo_algorithm.size(), model_.axes());
  EXPECT_GT(r.servo_cycles, 100);
  EXPECT_DOUBLE_EQ(r.servo_period_us, 2000.0);
  EXPECT_GE(r.lateness_p99_us, r.lateness_p50_us);
  EXPECT_GE(r.lateness_max_us, r.lateness_p99_us);
  // An algorithm the plugin does not have is refused, naming the axis.
  in.type = InstructionType::set;
  in.set = item::servo;
  in.servo_algorithm[3] = 7;
  r = exec(in);
  EXPECT_EQ(r.error_code, error_code::bad_argument);
  EXPECT_NE(r.error_text.find("axis 3 (wrist_pitch): servo algorithm 7"), std::string::npos)
      << r.error_text;
  // Unknown items are refused by name.
  Instruction inputs;
  inputs.type = InstructionType::set;
  inputs.set = item::inputs;
  r = exec(inputs);
  EXPECT_EQ(r.error_code, error_code::bad_argument);
  EXPECT_NE(r.error_text.find("SET takes ARM, TOOL, MODEL, SERVO, OUTPUTS"), std::string::npos);
}

TEST_F(EdpTest, EveryServoStepStaysInsideTheLimits) {
  ASSERT_EQ(synchronise().type, ReplyType::data);
  // Drive every joint as far towards one end of its range as the EDP accepts (it refuses any
  // path that would leave a joint, linkage or motor limit), back to the synchronisation pose,
  // then towards the other end.
  const double deg = std::acos(-1.0) / 180.0;
  for (double side : {1.0, -1.0}) {
    bool moved = false;
    for (double fraction = 0.95; fraction >= 0.2 && !moved; fraction -= 0.05) {
      std::vector<double> q(model_.axes());
      for (std::size_t j = 0; j < q.size(); ++j) {
        const double mid = 0.5 * (model_.lower_limits[j] + model_.upper_limits[j]);
        const double half = 0.5 * (model_.upper_limits[j] - model_.lower_limits[j]);
        q[j] = mid + side * fraction * half;
      }
      q[2] = std::max(q[2], -44.0 * deg - 90.0 * deg - q[1]);  // upper-arm linkage range
      const int steps = steps_to(q, 500);
      const Reply r = exec(set_joints(q, steps, steps + 1));
      if (r.type == ReplyType::error) {
        EXPECT_EQ(r.error_code, error_code::out_of_limits) << r.error_text;
        continue;
      }
      ASSERT_EQ(query().type, ReplyType::data);
      std::printf("side %+.0f: %.0f%% of the joint ranges accepted\n", side, fraction * 100);
      moved = true;
    }
    ASSERT_TRUE(moved);
    const int home_steps = steps_to(model_.synchro_joint_positions, 300);
    ASSERT_EQ(exec(set_joints(model_.synchro_joint_positions, home_steps, home_steps + 1)).type,
              ReplyType::acknowledge);
    ASSERT_EQ(query().type, ReplyType::data);
  }
  const auto trace = servo_->trace();
  ASSERT_GT(trace.size(), 1000U);
  std::size_t checked = 0;
  for (const auto& t : trace) {
    if (!t.synchronised) continue;  // raw encoder positions before SYNCHRO
    const std::vector<double> desired(t.desired.begin(),
                                      t.desired.begin() + static_cast<long>(model_.axes()));
    const std::vector<double> measured(t.measured.begin(),
                                       t.measured.begin() + static_cast<long>(model_.axes()));
    for (const auto* q : {&desired, &measured}) {
      EXPECT_NO_THROW(kinematics_->check_joint_limits(*q, "trace")) << "cycle " << t.cycle;
      EXPECT_NO_THROW(kinematics_->check_motor_limits(kinematics_->motors_from_joints(*q), "trace"))
          << "cycle " << t.cycle;
    }
    ++checked;
  }
  std::printf("%zu servo steps checked against the joint, linkage and motor limits\n", checked);
}

TEST_F(EdpTest, LinkageLimitIsCheckedOnThePath) {
  ASSERT_EQ(synchronise().type, ReplyType::data);
  // Each joint inside its own range, but q1 + q2 + 90 deg = -63.5 deg is outside the upper-arm
  // screw's linkage range.
  const double deg = std::acos(-1.0) / 180.0;
  const Reply r = exec(set_joints({0.0, -129.2 * deg, -24.3 * deg, 0.0, 0.0}, 100, 101));
  EXPECT_EQ(r.type, ReplyType::error);
  EXPECT_EQ(r.error_code, error_code::out_of_limits);
  EXPECT_NE(r.error_text.find("upper_arm"), std::string::npos) << r.error_text;
  std::printf("refused: %s\n", r.error_text.c_str());
}

TEST_F(EdpTest, EveryArmRepresentationReachesTheSamePose) {
  ASSERT_EQ(synchronise().type, ReplyType::data);
  const std::vector<double> q = {0.3, -1.3, 0.2, -0.4, 0.7};
  const int steps = steps_to(q, 200);
  ASSERT_EQ(exec(set_joints(q, steps, steps + 1)).type, ReplyType::acknowledge);
  ASSERT_EQ(query().type, ReplyType::data);
  // Let the servos settle on the target first: the readings below are taken one after the other,
  // and must all see the same measured pose (a slow instrumented build still lags at step 201).
  std::this_thread::sleep_for(std::chrono::milliseconds(1500));
  // Read the pose back in every representation.
  std::map<ArmRepresentation, std::vector<double>> pose;
  for (ArmRepresentation rep :
       {ArmRepresentation::joint, ArmRepresentation::motor, ArmRepresentation::frame,
        ArmRepresentation::xyz_euler_zyz, ArmRepresentation::xyz_angle_axis}) {
    Instruction get;
    get.type = InstructionType::get;
    get.get = item::arm;
    get.get_arm_type = rep;
    ASSERT_EQ(exec(get).type, ReplyType::acknowledge);
    const Reply r = query();
    ASSERT_EQ(r.type, ReplyType::data) << to_string(rep) << ": " << r.error_text;
    EXPECT_EQ(r.arm_type, rep);
    pose[rep] = r.arm;
  }
  EXPECT_EQ(pose[ArmRepresentation::frame].size(), 12U);
  EXPECT_EQ(pose[ArmRepresentation::xyz_euler_zyz].size(), 6U);
  // Move away, then come back to the pose given in each representation: the desired joints must
  // equal the measured pose it was read from (to the servo's small tracking error).
  for (ArmRepresentation rep :
       {ArmRepresentation::motor, ArmRepresentation::frame, ArmRepresentation::xyz_euler_zyz,
        ArmRepresentation::xyz_angle_axis}) {
    const std::vector<double> away = {0.0, -1.5, 0.0, 0.0, 0.0};
    const int out = steps_to(away, 300);
    ASSERT_EQ(exec(set_joints(away, out, out + 1)).type, ReplyType::acknowledge);
    ASSERT_EQ(query().type, ReplyType::data);
    const int in = steps_to(pose[ArmRepresentation::joint], 300);
    Instruction back = set_joints(pose[rep], in, in + 1);
    back.set_arm_type = rep;
    const Reply accepted = exec(back);
    ASSERT_EQ(accepted.type, ReplyType::acknowledge)
        << to_string(rep) << ": " << accepted.error_text;
    const Reply r = query();
    ASSERT_EQ(r.type, ReplyType::data);
    for (std::size_t j = 0; j < q.size(); ++j)
      EXPECT_NEAR(r.desired_joints[j], pose[ArmRepresentation::joint][j], 1e-9)
          << to_string(rep) << " joint " << j;
  }
}

TEST_F(EdpTest, RelativeCartesianMoveIsInTheToolFrame) {
  ASSERT_EQ(synchronise().type, ReplyType::data);
  std::this_thread::sleep_for(std::chrono::milliseconds(300));  // settle after synchronisation
  // Tool: a 0.25 m gripper along the flange z axis.
  Instruction tool;
  tool.type = InstructionType::set_get;
  tool.set = item::tool;
  tool.get = item::tool | item::arm | item::model;
  tool.get_arm_type = ArmRepresentation::frame;
  tool.tool_type = ArmRepresentation::xyz_angle_axis;
  tool.tool = {0, 0, 0.25, 0, 0, 0};
  ASSERT_EQ(exec(tool).type, ReplyType::acknowledge);
  Reply r = query();
  ASSERT_EQ(r.type, ReplyType::data) << r.error_text;
  EXPECT_EQ(r.tool, tool.tool);
  const std::vector<double> before = r.arm;  // tool frame, 3x4 row-major
  // 2 cm along the tool's own z axis (the approach direction).
  // (Within the joints' acceleration limits: the joint target the EDP will compute, from rest
  // to rest within 80 % of the limits.)
  const Eigen::Isometry3d goal = kinematics::from_vector(before, ArmRepresentation::frame) *
                                 Eigen::Translation3d(0.0, 0.0, 0.02);
  const int steps = steps_to(kinematics_->inverse(goal, servo_->planned_end()), 100);
  Instruction step = set_joints({0, 0, 0.02, 0, 0, 0}, steps, steps + 1, MotionType::relative);
  step.set_arm_type = ArmRepresentation::xyz_angle_axis;
  ASSERT_EQ(exec(step).type, ReplyType::acknowledge) << steps << " steps";
  const Reply moved = query();
  ASSERT_EQ(moved.type, ReplyType::data) << moved.error_text;
  std::this_thread::sleep_for(std::chrono::milliseconds(300));
  Instruction get;
  get.type = InstructionType::get;
  get.get = item::arm;
  get.get_arm_type = ArmRepresentation::frame;
  ASSERT_EQ(exec(get).type, ReplyType::acknowledge);
  r = query();
  ASSERT_EQ(r.type, ReplyType::data);
  // Displacement = 0.02 * (third column of R).
  for (int row = 0; row < 3; ++row) {
    const double expected = before[static_cast<std::size_t>(row * 4 + 3)] +
                            0.02 * before[static_cast<std::size_t>(row * 4 + 2)];
    EXPECT_NEAR(r.arm[static_cast<std::size_t>(row * 4 + 3)], expected, 2e-4) << "row " << row;
  }
}

TEST_F(EdpTest, UnreachableOrientationAndModelSelection) {
  ASSERT_EQ(synchronise().type, ReplyType::data);
  Instruction get;
  get.type = InstructionType::get;
  get.get = item::arm;
  get.get_arm_type = ArmRepresentation::xyz_angle_axis;
  ASSERT_EQ(exec(get).type, ReplyType::acknowledge);
  const Reply here = query();
  ASSERT_EQ(here.type, ReplyType::data);
  // Same position, orientation turned 0.3 rad about the world z axis: a 5-axis arm cannot yaw
  // its approach out of the arm plane.
  Instruction yaw = set_joints(here.arm, 100, 101);
  yaw.set_arm_type = ArmRepresentation::xyz_angle_axis;
  yaw.arm[3] = 0.0;
  yaw.arm[4] = 0.0;
  yaw.arm[5] = 0.0;
  Eigen::Isometry3d frame = kinematics::from_vector(here.arm, ArmRepresentation::xyz_angle_axis);
  frame.linear() =
      Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitZ()).toRotationMatrix() * frame.linear();
  yaw.arm = kinematics::to_vector(frame, ArmRepresentation::xyz_angle_axis);
  yaw.arm[0] = here.arm[0];
  yaw.arm[1] = here.arm[1];
  Reply r = exec(yaw);
  EXPECT_EQ(r.error_code, error_code::out_of_limits);
  EXPECT_NE(r.error_text.find("orientation not reachable by a 5-axis arm"), std::string::npos)
      << r.error_text;
  // Kinematic model 1 (calibrated) and corrector 1 exist; model 2 does not.
  Instruction model;
  model.type = InstructionType::set_get;
  model.set = item::model;
  model.get = item::model;
  model.kinematic_model_no = 1;
  model.corrector_no = 1;
  ASSERT_EQ(exec(model).type, ReplyType::acknowledge);
  r = query();
  EXPECT_EQ(r.kinematic_model_no, 1);
  EXPECT_EQ(r.corrector_no, 1);
  model.kinematic_model_no = 2;
  r = exec(model);
  EXPECT_EQ(r.error_code, error_code::bad_argument) << r.error_text;
  // A refused SET changed nothing: still model 1.
  Instruction check;
  check.type = InstructionType::get;
  check.get = item::model;
  ASSERT_EQ(exec(check).type, ReplyType::acknowledge);
  EXPECT_EQ(query().kinematic_model_no, 1);
}

/// Hardware with 16 binary output lines (as the `can` plugin on a robot of two or more drives):
/// axes that follow their setpoints exactly, and the outputs it was given.
class SixteenOutputLines final : public Hardware {
 public:
  explicit SixteenOutputLines(std::size_t axes) : positions_(axes, 0.0) {}
  [[nodiscard]] std::string name() const override { return "sixteen-lines"; }
  [[nodiscard]] std::size_t axis_count() const override { return positions_.size(); }
  void configure(const HardwareSetup&) override {}
  void activate() override {}
  void deactivate() override {}
  CycleStatus read(std::span<AxisFeedback> out) override {
    for (std::size_t i = 0; i < out.size(); ++i) out[i] = {positions_[i], 0.0, false};
    return CycleStatus::ok;
  }
  CycleStatus write(std::span<const double> setpoints) override {
    std::copy(setpoints.begin(), setpoints.end(), positions_.begin());
    return CycleStatus::ok;
  }
  [[nodiscard]] bool binary_io() const override { return true; }
  [[nodiscard]] std::uint32_t output_lines() const override { return 0xFFFFU; }
  void write_outputs(std::uint32_t values) override { outputs = values; }
  std::atomic<std::uint32_t> outputs{0};

 private:
  std::vector<double> positions_;
};

TEST(EdpBinaryIo, OutputsOnLinesThatDoNotExistAreRefusedNamingTheLine) {
  const RobotModel model = test::stock_model("irb6");
  SixteenOutputLines hardware(model.axes());
  auto kinematics = make_arm_kinematics(model);
  ServoLoop servo(hardware, model, kPeriod);
  servo.start();
  CommandInterpreter interpreter(servo, model, *kinematics, kPeriod);
  Instruction io;
  io.type = InstructionType::set;
  io.set = item::outputs;
  io.output_values = 0x18001;  // lines 0, 15 and 16: 16 does not exist
  Reply r = interpreter.execute(io);
  EXPECT_EQ(r.type, ReplyType::error);
  EXPECT_EQ(r.error_code, error_code::bad_argument);
  EXPECT_EQ(r.error_text,
            "SET OUTPUTS 0x18001 refused: output line 16 does not exist (plugin 'sixteen-lines' "
            "has lines 0xffff)");
  std::this_thread::sleep_for(std::chrono::milliseconds(20));
  EXPECT_EQ(hardware.outputs.load(), 0U);  // nothing was written
  io.output_values = 0x8001;
  r = interpreter.execute(io);
  EXPECT_EQ(r.type, ReplyType::acknowledge) << r.error_text;
  for (int i = 0; i < 100 && hardware.outputs.load() != 0x8001U; ++i)
    std::this_thread::sleep_for(std::chrono::milliseconds(2));
  EXPECT_EQ(hardware.outputs.load(), 0x8001U);
  servo.stop();
}

TEST(EdpWithoutBinaryIo, OutputsAndInputsAreRefusedNotIgnored) {
  // The mock plugin has no binary lines: SET OUTPUTS and GET INPUTS are
  // refused as not supported, naming the plugin, and nothing else of the instruction is done.
  const RobotModel model = test::stock_model("irb6");
  auto hardware = test::configured_hardware(model, "mock", kPeriod);
  ASSERT_FALSE(hardware->binary_io());
  auto kinematics = make_arm_kinematics(model);
  ServoLoop servo(*hardware, model, kPeriod);
  servo.start();
  CommandInterpreter interpreter(servo, model, *kinematics, kPeriod);
  Instruction io;
  io.type = InstructionType::set_get;
  io.set = item::outputs | item::servo;
  io.get = item::arm;
  io.output_values = 0x1;
  io.servo_algorithm.assign(model.axes(), 0);
  io.servo_parameters_no.assign(model.axes(), 0);
  Reply r = interpreter.execute(io);
  EXPECT_EQ(r.type, ReplyType::error);
  EXPECT_EQ(r.error_code, error_code::not_supported);
  EXPECT_EQ(r.error_text, "SET OUTPUTS refused: plugin 'mock' has no binary inputs or outputs");
  Instruction in;
  in.type = InstructionType::get;
  in.get = item::inputs;
  r = interpreter.execute(in);
  EXPECT_EQ(r.error_code, error_code::not_supported);
  EXPECT_EQ(r.error_text, "GET INPUTS refused: plugin 'mock' has no binary inputs or outputs");
  // The rest of the protocol goes on: a GET of the arm is answered.
  in.get = item::arm;
  EXPECT_EQ(interpreter.execute(in).type, ReplyType::acknowledge);
  Instruction q;
  q.type = InstructionType::query;
  EXPECT_EQ(interpreter.execute(q).type, ReplyType::data);
  servo.stop();
}

TEST_F(EdpTest, ServoParameterSetsChangeTheStiffnessAndIoLoopsBack) {
  ASSERT_EQ(synchronise().type, ReplyType::data);
  // Outputs 0b1010 come back on inputs 16..19; inputs 0..4 are the synchronisation switches.
  Instruction io;
  io.type = InstructionType::set_get;
  io.set = item::outputs;
  io.get = item::inputs;
  io.output_values = 0xA;
  ASSERT_EQ(exec(io).type, ReplyType::acknowledge);
  ASSERT_EQ(query().type, ReplyType::data);
  std::this_thread::sleep_for(std::chrono::milliseconds(20));
  Instruction in;
  in.type = InstructionType::get;
  in.get = item::inputs;
  ASSERT_EQ(exec(in).type, ReplyType::acknowledge);
  Reply r = query();
  EXPECT_EQ((r.input_values >> 16) & 0xFU, 0xAU) << std::hex << r.input_values;

  // Track the same fast joint move with the soft and the stiff parameter set: the soft servo
  // lags more. The column accelerates to 0.5 rad/s (300 steps, 2.5 rad/s^2 at most), cruises at
  // it for 200 steps, read half way (the lag measured at constant velocity), and comes to rest
  // in 150 steps.
  bool forward = true;
  auto lag_with = [&](std::int8_t set, std::int8_t algorithm = 0) {
    Instruction servo;
    servo.type = InstructionType::set;
    servo.set = item::servo;
    servo.servo_algorithm.assign(model_.axes(), algorithm);
    servo.servo_parameters_no.assign(model_.axes(), set);
    EXPECT_EQ(exec(servo).type, ReplyType::acknowledge);
    EXPECT_EQ(query().type, ReplyType::data);
    // Alternate direction so each run moves the column 0.575 rad and back.
    const double sign = forward ? 1.0 : -1.0;
    const auto plan = test::cruise(servo_->planned_end()[0], sign * 0.5, 300, 200, 1, kPeriod);
    forward = !forward;
    std::vector<double> q = model_.synchro_joint_positions;
    q[0] = plan[0].first;
    EXPECT_EQ(exec(set_joints(q, plan[0].second, plan[0].second - 3)).type, ReplyType::acknowledge);
    EXPECT_EQ(query().type, ReplyType::data);
    q[0] = plan[1].first;
    EXPECT_EQ(exec(set_joints(q, plan[1].second, plan[1].second / 2)).type, ReplyType::acknowledge);
    const Reply mid = query();
    if (mid.type != ReplyType::data || mid.servo_parameters_no.empty()) {
      ADD_FAILURE() << "no reading at the constant velocity: " << mid.error_text;
      return 0.0;
    }
    EXPECT_EQ(mid.servo_parameters_no[0], set);
    EXPECT_EQ(mid.servo_algorithm[0], algorithm);
    const double lag = std::abs(mid.desired_joints[0] - mid.joints[0]);
    q[0] = plan[2].first;
    EXPECT_EQ(exec(set_joints(q, plan[2].second, plan[2].second + 1)).type,
              ReplyType::acknowledge);  // to rest
    EXPECT_EQ(query().type, ReplyType::data);
    std::this_thread::sleep_for(std::chrono::milliseconds(100));  // settle
    return lag;
  };
  const double soft = lag_with(1);
  const double stiff = lag_with(2);
  const double nominal = lag_with(0, 0);
  const double feed_forward = lag_with(0, 1);
  std::printf(
      "tracking lag at 0.5 rad/s: soft %.5f rad, stiff %.5f rad, nominal %.5f rad, "
      "nominal with velocity feed-forward %.5f rad\n",
      soft, stiff, nominal, feed_forward);
  EXPECT_GT(soft, stiff * 1.5);
  EXPECT_LT(feed_forward, nominal * 0.5) << "velocity feed-forward must reduce the lag";
}

TEST_F(EdpLockStepTest, SimulatedTimeWaitsForALateSuccessor) {
  EXPECT_TRUE(hardware_->simulated());
  ASSERT_EQ(synchronise().type, ReplyType::data);
  EXPECT_NE(servo_->timing().scheduling.find("lock-step"), std::string::npos);
  // Cycles back to back at a real-time priority would keep a core from the rest of the host.
  EXPECT_NE(servo_->timing().scheduling.find("SCHED_OTHER"), std::string::npos);
  EXPECT_EQ(test::threads_with_real_time_policy(), 0);
  constexpr int kSteps = 10;
  constexpr int kSegments = 12;
  constexpr int kRamp = 60;
  const std::int64_t first_cycle = servo_->latest().cycle;
  // 0.1 rad/s on the column between a macro-step that accelerates to it and one that brings it
  // to rest; each read in the last step but one: a real-time loop would need the successor
  // within one servo period.
  const std::size_t last = kSegments + 1;
  run_cruise(0, 0.1, kRamp, kSteps, kSegments, 1, [&](std::size_t k) {
    if (k > 0 && k < last && k % 3 == 0) {
      // The successor comes 20 servo periods late: simulated time stands still meanwhile.
      const std::int64_t cycle = servo_->latest().cycle;
      std::this_thread::sleep_for(std::chrono::duration<double>(20 * kPeriod));
      EXPECT_EQ(servo_->latest().cycle, cycle) << "simulated time went on without a successor";
    }
  });
  EXPECT_EQ(servo_->lost_successors(), 0);
  // Every servo step of the cruise at the commanded velocity: no idle step, no ramp.
  EXPECT_EQ(steps_off_velocity(first_cycle, kSteps * kSegments, 0.1, kRamp), 0)
      << "servo steps with a velocity other than the commanded 0.1 rad/s";
  // The robot followed in simulated time.
  std::this_thread::sleep_for(std::chrono::milliseconds(100));
  EXPECT_NEAR(servo_->latest().joints[0], servo_->planned_end()[0], 2e-3);
}

TEST_F(EdpLockStepTest, ASuccessorThatNeverComesStopsTheRobotWithinItsLimits) {
  ASSERT_EQ(synchronise().type, ReplyType::data);
  std::vector<double> q = model_.synchro_joint_positions;
  q[0] = 0.02;  // from rest to 0.25 rad/s in 80 steps (1.6 rad/s^2), a successor promised
  const std::int64_t from = servo_->latest().cycle;
  ASSERT_EQ(exec(set_joints(q, 80, 79)).type, ReplyType::acknowledge);
  ASSERT_EQ(query().type, ReplyType::data);
  // No successor: after the successor wait (0.5 s of wall time) the loop ramps down.
  for (int i = 0; i < 300 && !servo_->stopped(); ++i)
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  EXPECT_TRUE(servo_->stopped());
  EXPECT_EQ(servo_->lost_successors(), 1);
  const auto trace = servo_->trace();
  for (std::size_t i = 2; i < trace.size(); ++i) {
    if (trace[i - 2].cycle < from) continue;
    const double v = (trace[i].desired[0] - trace[i - 1].desired[0]) / kPeriod;
    const double before = (trace[i - 1].desired[0] - trace[i - 2].desired[0]) / kPeriod;
    EXPECT_LE(std::abs(v), model_.max_velocity[0] + 1e-9);
    EXPECT_LE(std::abs(v - before) / kPeriod, model_.max_acceleration[0] * (1 + 2e-6))
        << "cycle " << trace[i].cycle;
  }
  // The next macro-step starts from where the ramp left the robot.
  q[0] = 0.05;
  const int steps = steps_to(q, 20);
  ASSERT_EQ(exec(set_joints(q, steps, steps + 1)).type, ReplyType::acknowledge);
  const Reply r = query();
  ASSERT_EQ(r.type, ReplyType::data) << r.error_text;
  EXPECT_NEAR(r.desired_joints[0], 0.05, 1e-12);
}

TEST_F(EdpLockStepTest, IdleLoopStillHoldsAndAnswers) {
  // Idle, the loop runs a holding cycle once a period: readings stay fresh.
  const std::int64_t c0 = servo_->latest().cycle;
  std::this_thread::sleep_for(std::chrono::milliseconds(100));
  EXPECT_GT(servo_->latest().cycle, c0);
  EXPECT_EQ(synchronise().type, ReplyType::data);
  EXPECT_TRUE(servo_->synchronised());
}
