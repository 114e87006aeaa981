// EDP safety: emergency stop and a lost ECP bring the robot to a standstill within its
// acceleration limits and hold it; plugin faults (a fault status or an exception) hold the
// robot, refuse motion, and are reset by SYNCHRO.
#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <cmath>
#include <mutex>
#include <optional>
#include <thread>
#include <vector>

#include "command_interpreter.hpp"
#include "edp_parts.hpp"
#include "mrroc/edp/arm_kinematics.hpp"
#include "mrroc/edp/hardware.hpp"
#include "mrroc/robot/robot_model.hpp"
#include "servo_loop.hpp"

using namespace mrroc;
using namespace mrroc::edp;

namespace {

constexpr double kPeriod = 0.002;

class Edp {
 public:
  explicit Edp(const std::string& plugin, Params params = {}) {
    model_ = test::stock_model("irb6");
    hardware_ = test::configured_hardware(model_, plugin, kPeriod, std::move(params));
    kinematics_ = make_arm_kinematics(model_);
    servo_ = std::make_unique<ServoLoop>(*hardware_, model_, kPeriod);
    servo_->set_limit_guard(kinematics_.get());
    servo_->enable_trace(20000);
    servo_->start();
    interpreter_ = std::make_unique<CommandInterpreter>(*servo_, model_, *kinematics_, kPeriod);
  }
  ~Edp() { servo_->stop(); }

  Reply exec(const Instruction& in) { return interpreter_->execute(in); }
  Reply query() {
    Instruction q;
    q.type = InstructionType::query;
    return exec(q);
  }
  Reply synchronise() {
    Instruction s;
    s.type = InstructionType::synchro;
    const Reply r = exec(s);
    if (r.type == ReplyType::error) return r;
    return query();
  }
  Reply set_joints(std::vector<double> q, int steps, int value) {
    return exec(test::set_joints_instruction(std::move(q), steps, value));
  }
  /// Commanded joint velocities of the trace from cycle `from` on [rad/s].
  std::vector<std::vector<double>> velocities(std::int64_t from) {
    std::vector<std::vector<double>> out;
    const auto trace = servo_->trace();
    for (std::size_t i = 1; i < trace.size(); ++i) {
      if (trace[i].cycle < from || !trace[i].synchronised || !trace[i - 1].synchronised) continue;
      std::vector<double> v(model_.axes());
      for (std::size_t j = 0; j < v.size(); ++j)
        v[j] = (trace[i].desired[j] - trace[i - 1].desired[j]) / kPeriod;
      out.push_back(v);
    }
    return out;
  }

  /// Rest-to-rest SET to `q` in the fewest servo steps the joints' limits allow.
  Reply set_joints_at_rest(const std::vector<double>& q) {
    const int steps = test::rest_to_rest_steps(model_, servo_->planned_end(), q, kPeriod);
    return set_joints(q, steps, steps + 1);
  }

  /// Moves from rest to `q` (joint 0 must change) in one macro-step of `steps` servo steps whose
  /// reading, in step steps-1, promises a successor (with none queued, the EDP ends it at its
  /// mean velocity); never sends one and waits 0.5 s. Returns the commanded velocities from the
  /// macro-step's last step on (the stopping ramp and the hold after it); empty when the motion
  /// was refused or never ran.
  std::vector<std::vector<double>> move_without_successor(const std::vector<double>& q, int steps) {
    // From rest: the reply to SYNCHRO can come a cycle before its last, tiny correction has been
    // commanded (seen under AddressSanitizer), which would count as the macro-step's first step.
    const auto rest_deadline = std::chrono::steady_clock::now() + std::chrono::seconds(2);
    while (!servo_->stopped() && std::chrono::steady_clock::now() < rest_deadline)
      std::this_thread::sleep_for(std::chrono::milliseconds(1));
    if (!servo_->stopped()) {
      ADD_FAILURE() << "the robot did not come to rest within 2 s";
      return {};
    }
    const std::int64_t at = servo_->latest().cycle;
    if (set_joints(q, steps, steps - 1).type != ReplyType::acknowledge) return {};
    const Reply r = query();
    if (r.type != ReplyType::data) {
      ADD_FAILURE() << r.error_text;
      return {};
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(500));
    const auto v = velocities(at);
    std::size_t first = 0;
    while (first < v.size() && v[first][0] == 0.0) ++first;
    const auto last = first + static_cast<std::size_t>(steps) - 1;
    if (last + 1 >= v.size()) return {};
    return {v.begin() + static_cast<long>(last), v.end()};
  }

  RobotModel model_;
  std::unique_ptr<Hardware> hardware_;
  std::unique_ptr<ServoLoop> servo_;
  std::unique_ptr<ArmKinematics> kinematics_;
  std::unique_ptr<CommandInterpreter> interpreter_;
};

/// Checks a deceleration: no step changes a joint's velocity by more than its maximum
/// acceleration allows, and the robot ends at rest. Returns the number of cycles to rest.
int check_stop(const std::vector<std::vector<double>>& v, const RobotModel& model) {
  int to_rest = -1;
  for (std::size_t k = 1; k < v.size(); ++k) {
    bool rest = true;
    for (std::size_t j = 0; j < model.axes(); ++j) {
      EXPECT_LE(std::abs(v[k][j] - v[k - 1][j]), model.max_acceleration[j] * kPeriod * 1.0001)
          << "cycle " << k << " joint " << j;
      rest = rest && v[k][j] == 0.0;
    }
    if (rest && to_rest < 0) to_rest = static_cast<int>(k);
  }
  EXPECT_GE(to_rest, 0) << "never came to rest";
  for (std::size_t k = static_cast<std::size_t>(std::max(to_rest, 0)); k < v.size(); ++k)
    for (double x : v[k]) EXPECT_EQ(x, 0.0) << "moved again while held";
  return to_rest;
}

}  // namespace

TEST(EdpSafety, EmergencyStopDeceleratesWithinLimitsAndHolds) {
  Edp edp("mujoco");
  ASSERT_EQ(edp.synchronise().type, ReplyType::data);
  std::vector<double> q = edp.model_.synchro_joint_positions;
  // 1 rad in 1.4 s from rest to rest: the column accelerates at 2.04 rad/s^2 (limit 3) for 0.7 s.
  q[0] = 1.0;
  ASSERT_EQ(edp.set_joints(q, 700, 701).type, ReplyType::acknowledge);
  std::this_thread::sleep_for(std::chrono::milliseconds(400));
  const std::int64_t at = edp.servo_->latest().cycle;
  edp.servo_->emergency_stop();
  std::this_thread::sleep_for(std::chrono::milliseconds(800));
  const auto v = edp.velocities(at - 5);
  ASSERT_FALSE(v.empty());
  EXPECT_GT(v[0][0], 0.6) << "the column was not moving fast when stopped";
  const int cycles = check_stop(v, edp.model_);
  // About 0.8 rad/s at 3 rad/s^2 needs about 135 cycles of 2 ms, counted from the fastest cycle
  // (the stop is acted on a few cycles after `at`, later on a busy host).
  std::size_t peak = 0;
  for (std::size_t k = 1; k < v.size(); ++k)
    if (v[k][0] > v[peak][0]) peak = k;
  EXPECT_LE(cycles - static_cast<int>(peak), static_cast<int>(v[peak][0] / (3.0 * kPeriod)) + 2);
  std::printf("standstill %d servo steps after the emergency stop\n", cycles);
  EXPECT_TRUE(edp.servo_->stopped());
  // The QUERY of the interrupted motion reports an error (its macro-step never ended), and
  // no motion is accepted until the release.
  EXPECT_EQ(edp.query().type, ReplyType::error);
  Reply r = edp.set_joints(edp.model_.synchro_joint_positions, 100, 101);
  EXPECT_EQ(r.error_code, error_code::emergency_stop) << r.error_text;
  edp.servo_->release_emergency_stop();
  r = edp.set_joints_at_rest(edp.model_.synchro_joint_positions);
  ASSERT_EQ(r.type, ReplyType::acknowledge) << r.error_text;
  r = edp.query();
  EXPECT_EQ(r.type, ReplyType::data) << r.error_text;
}

// The binary outputs take their safe state in the first servo cycle after an ENGAGE (the lines
// configured as kept stay), SET OUTPUTS and SET SERVO are refused while it holds, and a release
// restores nothing. The mujoco plugin reads outputs 0..15 back on inputs 16..31, one cycle later.
TEST(EdpSafety, EmergencyStopPutsTheOutputsInTheirSafeStateAndAReleaseRestoresNothing) {
  Edp edp("mujoco");
  edp.servo_->set_stop_outputs(/*safe=*/0x4, /*kept=*/0x2);
  const auto outputs_read_back = [&](std::uint32_t want) -> std::optional<std::int64_t> {
    const auto until = std::chrono::steady_clock::now() + std::chrono::seconds(2);
    while (std::chrono::steady_clock::now() < until) {
      const Reading r = edp.servo_->latest();
      if ((r.inputs >> 16U) == want) return r.cycle;
      std::this_thread::sleep_for(std::chrono::microseconds(200));
    }
    return std::nullopt;
  };
  Instruction set_outputs;
  set_outputs.type = InstructionType::set;
  set_outputs.set = item::outputs;
  set_outputs.output_values = 0x3;
  ASSERT_EQ(edp.exec(set_outputs).type, ReplyType::acknowledge);
  ASSERT_EQ(edp.query().type, ReplyType::data);
  ASSERT_TRUE(outputs_read_back(0x3).has_value());

  const std::int64_t before = edp.servo_->latest().cycle;
  edp.servo_->emergency_stop();
  // Every cycle planned after this one sees the stop.
  const std::int64_t after = edp.servo_->latest().cycle;
  // Line 0 off (safe 0), line 1 kept on, line 2 on (safe 1): written in the cycle after the
  // stop at the latest (the trace's outputs are those each cycle wrote), read back after it.
  ASSERT_TRUE(outputs_read_back(0x6).has_value()) << "the outputs never took their safe state";
  std::int64_t written = -1;
  for (const TraceSample& t : edp.servo_->trace())
    if (t.cycle > before && t.outputs == 0x6) {
      written = t.cycle;
      break;
    }
  EXPECT_GE(written, before + 1);
  EXPECT_LE(written, after + 1) << "stop between cycles " << before << " and " << after;

  set_outputs.output_values = 0x1;
  Reply r = edp.exec(set_outputs);
  EXPECT_EQ(r.error_code, error_code::emergency_stop);
  EXPECT_NE(r.error_text.find("SET OUTPUTS refused: emergency stop engaged"), std::string::npos)
      << r.error_text;
  Instruction set_servo;
  set_servo.type = InstructionType::set;
  set_servo.set = item::servo;
  set_servo.servo_algorithm.assign(edp.model_.axes(), 1);
  set_servo.servo_parameters_no.assign(edp.model_.axes(), 0);
  r = edp.exec(set_servo);
  EXPECT_EQ(r.error_code, error_code::emergency_stop);
  EXPECT_NE(r.error_text.find("SET SERVO refused: emergency stop engaged"), std::string::npos)
      << r.error_text;

  edp.servo_->release_emergency_stop();
  const std::int64_t released = edp.servo_->latest().cycle;
  while (edp.servo_->latest().cycle < released + 20)
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  EXPECT_EQ(edp.servo_->latest().inputs >> 16U, 0x6U) << "a release must restore nothing";
  ASSERT_EQ(edp.exec(set_outputs).type, ReplyType::acknowledge);
  ASSERT_EQ(edp.query().type, ReplyType::data);
  EXPECT_TRUE(outputs_read_back(0x1).has_value());
}

TEST(EdpSafety, LostEcpBringsTheRobotToAStandstill) {
  Edp edp("mujoco");
  ASSERT_EQ(edp.synchronise().type, ReplyType::data);
  std::vector<double> q = edp.model_.synchro_joint_positions;
  // To 0.2 rad/s in 120 steps (2.5 rad/s^2 at most), with the reading one step early: a
  // successor is promised ... and never sent. The macro-step, then a ramp down, not a dead stop.
  q[0] = 0.048;
  const auto tail = edp.move_without_successor(q, 120);
  ASSERT_FALSE(tail.empty());
  EXPECT_EQ(edp.servo_->lost_successors(), 1);
  const int cycles = check_stop(tail, edp.model_);
  EXPECT_GT(cycles, 10) << "stopped dead instead of decelerating";
  EXPECT_TRUE(edp.servo_->stopped());
  // The ECP may carry on afterwards.
  ASSERT_EQ(edp.set_joints_at_rest(edp.model_.synchro_joint_positions).type,
            ReplyType::acknowledge);
  EXPECT_EQ(edp.query().type, ReplyType::data);
}

TEST(EdpSafety, StoppingRampKeepsTheDirectionOfTheMotion) {
  // Two joints at different speeds (column 0.2 rad/s, shoulder -0.08 rad/s, reached in one
  // macro-step of 120 steps); the successor never comes. The ramp scales both velocities by one
  // factor: their ratio stays that of the motion, so the arm stops on the straight continuation
  // of its path in joint space.
  Edp edp("mujoco");
  ASSERT_EQ(edp.synchronise().type, ReplyType::data);
  std::vector<double> q = edp.model_.synchro_joint_positions;
  q[0] += 0.048;
  q[1] -= 0.0192;
  const auto tail = edp.move_without_successor(q, 120);
  ASSERT_FALSE(tail.empty());
  EXPECT_EQ(edp.servo_->lost_successors(), 1);
  const int cycles = check_stop(tail, edp.model_);
  EXPECT_GT(cycles, 10) << "stopped dead instead of decelerating";
  int ramp_steps = 0;
  for (std::size_t k = 1; k < tail.size() && tail[k][0] != 0.0; ++k) {
    EXPECT_NEAR(tail[k][1] / tail[k][0], -0.4, 1e-6) << "ramp step " << k << " turned off the path";
    for (std::size_t j = 2; j < tail[k].size(); ++j) EXPECT_EQ(tail[k][j], 0.0);
    ++ramp_steps;
  }
  EXPECT_GT(ramp_steps, 10);
  // The column is the joint that limits the ramp: it decelerates at its own maximum.
  EXPECT_NEAR(tail[1][0] - tail[2][0], edp.model_.max_acceleration[0] * kPeriod, 1e-6);
}

// After a late successor the ramp leaves the robot past its last target. The macro-step the ECP
// had planned next (a short step further along the old path) would now have to come back at
// several times the velocity limit: the EDP refuses it at its start, names the joint, the
// velocity and the limit, and the robot holds; a macro-step planned from where it stands is
// accepted.
TEST(EdpSafety, AMacroStepTooFastFromWhereARampLeftTheRobotIsRefused) {
  Edp edp("mujoco");
  ASSERT_EQ(edp.synchronise().type, ReplyType::data);
  std::vector<double> q = edp.model_.synchro_joint_positions;
  const double start = q[4];
  // The wrist roll from rest to 1.875 rad/s (limit 3) in 400 steps (7 rad/s^2 at most, limit 8),
  // read early: successor promised.
  q[4] = start + 1.5;
  ASSERT_EQ(edp.set_joints(q, 400, 397).type, ReplyType::acknowledge);
  const Reply moving = edp.query();
  ASSERT_EQ(moving.type, ReplyType::data) << moving.error_text;
  std::this_thread::sleep_for(std::chrono::milliseconds(600));  // the successor never comes
  ASSERT_EQ(edp.servo_->lost_successors(), 1);
  const double stopped_at = edp.servo_->latest().desired[4];
  EXPECT_GT(stopped_at, q[4] + 0.2) << "1.875 rad/s at 8 rad/s^2 overshoots by 0.22 rad";
  // The old plan's next step: 0.0375 rad further than the last target (10 steps at 1.875
  // rad/s), i.e. ~0.18 rad back.
  std::vector<double> planned = q;
  planned[4] = q[4] + 0.0375;
  ASSERT_EQ(edp.set_joints(planned, 10, 7).type, ReplyType::acknowledge);
  const Reply refused = edp.query();
  EXPECT_EQ(refused.type, ReplyType::error);
  EXPECT_EQ(refused.error_code, error_code::too_fast);
  EXPECT_NE(refused.error_text.find("SET refused: joint 4 would move at"), std::string::npos)
      << refused.error_text;
  EXPECT_NE(refused.error_text.find("above its limit of 3.000 rad/s"), std::string::npos)
      << refused.error_text;
  EXPECT_NE(refused.error_text.find("starting where a stopping ramp left the robot"),
            std::string::npos)
      << refused.error_text;
  std::this_thread::sleep_for(std::chrono::milliseconds(100));
  EXPECT_DOUBLE_EQ(edp.servo_->latest().desired[4], stopped_at) << "the robot did not hold";
  // From where it stands, within the limit: accepted.
  planned[4] = stopped_at - 0.05;
  ASSERT_EQ(edp.set_joints(planned, 100, 101).type, ReplyType::acknowledge);
  const Reply ok = edp.query();
  EXPECT_EQ(ok.type, ReplyType::data) << ok.error_text;
  // No commanded velocity ever exceeded a limit.
  for (const auto& v : edp.velocities(0))
    for (std::size_t j = 0; j < v.size(); ++j)
      EXPECT_LE(std::abs(v[j]), edp.model_.max_velocity[j] * 1.0001) << "joint " << j;
}

TEST(EdpSafety, AMacroStepFasterThanTheVelocityLimitIsRefused) {
  Edp edp("mock");
  ASSERT_EQ(edp.synchronise().type, ReplyType::data);
  std::vector<double> q = edp.model_.synchro_joint_positions;
  q[0] += 0.4;  // 0.4 rad in 0.2 s: 2 rad/s, the column's limit is 1.5 rad/s
  ASSERT_EQ(edp.set_joints(q, 100, 101).type, ReplyType::acknowledge);
  const Reply r = edp.query();
  EXPECT_EQ(r.error_code, error_code::too_fast);
  EXPECT_EQ(r.error_text,
            "SET refused: joint 0 would move at 2.000 rad/s, above its limit of 1.500 rad/s (from "
            "0.0000 to 0.4000 rad in 100 steps of 2.0 ms); the robot holds");
  EXPECT_DOUBLE_EQ(edp.servo_->latest().desired[0], edp.model_.synchro_joint_positions[0]);
}

TEST(EdpSafety, MockPluginMirrorsCommands) {
  Edp edp("mock");
  ASSERT_EQ(edp.synchronise().type, ReplyType::data);
  std::vector<double> q = {0.2, -1.4, 0.1, 0.3, -0.5};
  ASSERT_EQ(edp.set_joints_at_rest(q).type, ReplyType::acknowledge);
  const Reply r = edp.query();
  ASSERT_EQ(r.type, ReplyType::data);
  for (std::size_t j = 0; j < q.size(); ++j) EXPECT_NEAR(r.joints[j], q[j], 1e-9);
}

class PluginFaults : public ::testing::TestWithParam<const char*> {};

TEST_P(PluginFaults, FaultHoldsRefusesAndSynchroResets) {
  Params params;
  // The plugin counts its reads from activation; synchronisation takes 394 of them. The fault
  // comes 1.2 s later, in the middle of a 5 s motion, however late the SET arrives within that.
  params.set("fault_after_cycles", std::int64_t{1000}, {});
  params.set("fault", std::string(GetParam()), {});
  Edp edp("faulty", params);
  ASSERT_EQ(edp.synchronise().type, ReplyType::data);
  ASSERT_LT(edp.servo_->latest().cycle, 900) << "synchronisation took longer than the test assumes";
  // A long motion, interrupted by the fault.
  std::vector<double> q = edp.model_.synchro_joint_positions;
  q[0] = 0.5;
  const Reply set = edp.set_joints(q, 2500, 2501);
  ASSERT_EQ(set.type, ReplyType::acknowledge) << set.error_text;
  Reply r = edp.query();
  EXPECT_EQ(r.type, ReplyType::error);
  EXPECT_EQ(r.error_code, error_code::hardware_fault) << r.error_text;
  ASSERT_TRUE(edp.servo_->faulted());
  std::printf("fault (%s): %s\n", GetParam(), edp.servo_->fault_text().c_str());
  const std::string expected = std::string(GetParam()) == "throw"
                                   ? "plugin threw in read(): injected exception"
                                   : "injected drive fault";
  EXPECT_NE(edp.servo_->fault_text().find(expected), std::string::npos);
  // Held and refusing motion.
  r = edp.set_joints(edp.model_.synchro_joint_positions, 100, 101);
  EXPECT_EQ(r.error_code, error_code::hardware_fault);
  EXPECT_NE(r.error_text.find("SYNCHRO resets"), std::string::npos) << r.error_text;
  // SYNCHRO resets the fault and synchronises again; motion works afterwards.
  r = edp.synchronise();
  ASSERT_EQ(r.type, ReplyType::data) << r.error_text;
  EXPECT_TRUE(r.synchronised);
  EXPECT_FALSE(edp.servo_->faulted());
  ASSERT_EQ(edp.set_joints_at_rest(q).type, ReplyType::acknowledge);
  r = edp.query();
  ASSERT_EQ(r.type, ReplyType::data) << r.error_text;
  EXPECT_NEAR(r.joints[0], 0.5, 1e-9);
}

INSTANTIATE_TEST_SUITE_P(StatusAndException, PluginFaults, ::testing::Values("status", "throw"));

/// Axes that follow their setpoints exactly and home themselves; a reset's activate() and the
/// homing each take 300 ms and note the thread they run on, and every cycle call made while one
/// of them runs is counted.
class SlowRecovery final : public Hardware {
 public:
  explicit SlowRecovery(std::vector<double> home)
      : positions_(home.size(), 0.0), home_(std::move(home)) {}
  [[nodiscard]] std::string name() const override { return "slow-recovery"; }
  [[nodiscard]] std::size_t axis_count() const override { return positions_.size(); }
  void configure(const HardwareSetup&) override {}
  void activate() override {
    if (activations_++ > 0) recover();  // the first is the EDP's start
    fail = false;
  }
  void deactivate() override {}
  CycleStatus read(std::span<AxisFeedback> out) override {
    if (recovering_.load()) ++calls_during_recovery;
    for (std::size_t i = 0; i < out.size(); ++i) out[i] = {positions_[i], 0.0, false};
    return fail.load() ? CycleStatus::fault : CycleStatus::ok;
  }
  CycleStatus write(std::span<const double> setpoints) override {
    if (recovering_.load()) ++calls_during_recovery;
    std::copy(setpoints.begin(), setpoints.end(), positions_.begin());
    return CycleStatus::ok;
  }
  [[nodiscard]] std::uint32_t self_homing_axes() const override {
    return (1U << positions_.size()) - 1U;
  }
  void home_axes() override {
    recover();
    positions_ = home_;  // every axis at its home point, which is its synchronisation position
  }
  [[nodiscard]] std::string fault_text() const override { return "injected drive fault"; }
  [[nodiscard]] bool binary_io() const override { return true; }
  [[nodiscard]] std::uint32_t read_inputs() const override { return 0xA5U; }
  [[nodiscard]] std::vector<std::thread::id> recovery_threads() const {
    std::lock_guard lock(mutex_);
    return recovery_threads_;
  }

  std::atomic<bool> fail{false};
  std::atomic<int> calls_during_recovery{0};

 private:
  void recover() {
    {
      std::lock_guard lock(mutex_);
      recovery_threads_.push_back(std::this_thread::get_id());
    }
    recovering_ = true;
    std::this_thread::sleep_for(std::chrono::milliseconds(300));
    recovering_ = false;
  }

  std::vector<double> positions_;
  std::vector<double> home_;
  int activations_ = 0;
  std::atomic<bool> recovering_{false};
  mutable std::mutex mutex_;
  std::vector<std::thread::id> recovery_threads_;
};

// The hardware's own homing at SYNCHRO and the reset after a fault block for as long as the
// devices take (SDO transfers, a homing run): they run on the EDP's recovery thread, never on the
// real-time servo thread, and no read() or write() is made while one runs.
TEST(EdpRecovery, AHomingAndAResetRunOffTheServoThreadAndNoCycleCallsThePluginMeanwhile) {
  const RobotModel model = test::stock_model("irb6");
  SlowRecovery hw(model.synchro_joint_positions);
  ServoLoop servo(hw, model, kPeriod);
  servo.start();
  const std::thread::id servo_thread = servo.servo_thread_id();
  // SYNCHRO by the hardware's homing.
  auto t0 = std::chrono::steady_clock::now();
  servo.begin_synchronisation();
  ASSERT_TRUE(servo.wait_synchronised(5.0)) << servo.fault_text();
  const double homing_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  // A fault, then its reset (SYNCHRO while faulted).
  hw.fail = true;
  for (int i = 0; i < 500 && !servo.faulted(); ++i)
    std::this_thread::sleep_for(std::chrono::milliseconds(2));
  ASSERT_TRUE(servo.faulted());
  t0 = std::chrono::steady_clock::now();
  ASSERT_TRUE(servo.reset_fault(2.0)) << servo.fault_text();
  const double reset_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  // The loop reads again after it.
  const std::int64_t cycle = servo.latest().cycle;
  std::this_thread::sleep_for(std::chrono::milliseconds(50));
  EXPECT_GT(servo.latest().cycle, cycle + 5);
  servo.stop();
  std::printf("homing %.3f s, reset %.3f s\n", homing_s, reset_s);
  EXPECT_GE(homing_s, 0.3);
  EXPECT_GE(reset_s, 0.3);
  const auto threads = hw.recovery_threads();
  ASSERT_EQ(threads.size(), 2U);
  for (const auto& t : threads) {
    EXPECT_NE(t, servo_thread) << "a recovery ran on the servo thread";
    EXPECT_NE(t, std::this_thread::get_id());
  }
  EXPECT_EQ(hw.calls_during_recovery.load(), 0) << "read() or write() while a recovery ran";
}

// The first reading, taken when the loop starts, has the inputs too: a GET INPUTS that comes
// before the first cycle gets them, not 0.
TEST(EdpRecovery, TheFirstReadingBeforeAnyCycleHasTheInputs) {
  const RobotModel model = test::stock_model("irb6");
  SlowRecovery hw(model.synchro_joint_positions);
  ServoLoop servo(hw, model, kPeriod);
  servo.start_stepped();
  EXPECT_EQ(servo.latest().inputs, 0xA5U);
  servo.stop();
}

TEST(EdpSafety, StoppingRampNeverLeavesALimit) {
  Edp edp("mujoco");
  ASSERT_EQ(edp.synchronise().type, ReplyType::data);
  // Find, by bisection, where the lower and upper arm moving down together first meet a limit
  // (joint, linkage or motor: whichever binds), then stop 0.02 rad before it.
  const std::vector<double> sync = edp.model_.synchro_joint_positions;
  const std::vector<double> direction = {0.0, -1.0, -1.0, 0.0, 0.0};
  auto along = [&](double t) {
    std::vector<double> q = sync;
    for (std::size_t j = 0; j < q.size(); ++j) q[j] += t * direction[j];
    return q;
  };
  double inside = 0.0;
  double outside = 2.0;
  ASSERT_FALSE(edp.kinematics_->within_limits(along(outside)));
  for (int i = 0; i < 60; ++i) {
    const double mid = 0.5 * (inside + outside);
    (edp.kinematics_->within_limits(along(mid)) ? inside : outside) = mid;
  }
  const std::vector<double> near_limit = along(inside - 0.02);
  const std::vector<double> away = along(inside - 0.42);
  Reply r = edp.set_joints_at_rest(away);
  ASSERT_EQ(r.type, ReplyType::acknowledge) << r.error_text;
  ASSERT_EQ(edp.query().type, ReplyType::data);
  const std::int64_t from = edp.servo_->latest().cycle;
  // Towards the limit, from rest to 0.5 rad/s in 400 steps (1.875 rad/s^2 at most, limit 2),
  // promising a successor that never comes: the ramp alone would carry the arm 0.06 rad further,
  // past the limit.
  r = edp.set_joints(near_limit, 400, 399);
  ASSERT_EQ(r.type, ReplyType::acknowledge) << r.error_text;
  r = edp.query();
  ASSERT_EQ(r.type, ReplyType::data) << r.error_text;
  std::this_thread::sleep_for(std::chrono::milliseconds(600));
  EXPECT_EQ(edp.servo_->lost_successors(), 1);
  EXPECT_TRUE(edp.servo_->stopped());
  int checked = 0;
  for (const auto& t : edp.servo_->trace()) {
    if (t.cycle < from) continue;
    ++checked;
    const std::vector<double> desired(t.desired.begin(), t.desired.begin() + 5);
    EXPECT_TRUE(edp.kinematics_->within_limits(desired)) << "cycle " << t.cycle;
  }
  EXPECT_GT(checked, 200);
  // The ramp was cut short at the limit: the arm stands within one ramp step of it.
  const Reading now = edp.servo_->latest();
  const double reached = sync[1] - now.desired[1];
  EXPECT_NEAR(reached, inside, 0.01);
  std::printf("limit at %.4f rad along the path; stopped at %.4f rad\n", inside, reached);
}

// The acceleration limits through the real command interpreter and servo loop: a macro-step that
// would need more than a joint's acceleration limit is refused before it starts (error
// too_abrupt, naming joint, value, unit and limit) whichever way its target was given; one
// within the limits runs with every servo step inside them and ends exactly at its target.

namespace {

/// The largest |acceleration| (second difference / period^2) and |velocity| of each joint over
/// the servo steps of `trace` from cycle `from` on, each checked against the joint's limits.
struct Peaks {
  std::vector<double> acceleration, velocity;
};
Peaks check_trace_within_limits(const std::vector<TraceSample>& trace, std::int64_t from,
                                const RobotModel& model) {
  Peaks p{std::vector<double>(model.axes()), std::vector<double>(model.axes())};
  int checked = 0;
  for (std::size_t i = 2; i < trace.size(); ++i) {
    if (trace[i - 2].cycle < from) continue;
    ++checked;
    for (std::size_t j = 0; j < model.axes(); ++j) {
      const double v = (trace[i].desired[j] - trace[i - 1].desired[j]) / kPeriod;
      const double before = (trace[i - 1].desired[j] - trace[i - 2].desired[j]) / kPeriod;
      const double a = (v - before) / kPeriod;
      EXPECT_LE(std::abs(a), model.max_acceleration[j] * (1 + 2e-6))
          << "joint " << j << " cycle " << trace[i].cycle;
      EXPECT_LE(std::abs(v), model.max_velocity[j] * (1 + 2e-6))
          << "joint " << j << " cycle " << trace[i].cycle;
      p.acceleration[j] = std::max(p.acceleration[j], std::abs(a));
      p.velocity[j] = std::max(p.velocity[j], std::abs(v));
    }
  }
  EXPECT_GT(checked, 10) << "the trace holds no motion";
  return p;
}

/// Checks that the desired pose stayed where it was at cycle `from` (the robot did not move).
void expect_held(const std::vector<TraceSample>& trace, std::int64_t from) {
  const TraceSample* first = nullptr;
  int held = 0;
  for (const auto& t : trace) {
    if (t.cycle < from) continue;
    if (!first) first = &t;
    for (std::size_t j = 0; j < t.desired.size(); ++j)
      EXPECT_EQ(t.desired[j], first->desired[j]) << "joint " << j << " moved at cycle " << t.cycle;
    ++held;
  }
  EXPECT_GT(held, 10);
}

void expect_too_abrupt(const Reply& r, const std::string& joint) {
  EXPECT_EQ(r.type, ReplyType::error);
  EXPECT_EQ(r.error_code, error_code::too_abrupt) << r.error_text;
  EXPECT_NE(r.error_text.find(joint + " would accelerate at "), std::string::npos) << r.error_text;
  EXPECT_NE(r.error_text.find(" rad/s^2, above its limit of "), std::string::npos) << r.error_text;
}

}  // namespace

TEST(EdpAcceleration, AJointSetFromStandstillAtTheVelocityLimitIsRefusedAndNothingMoves) {
  Edp edp("mujoco");
  ASSERT_EQ(edp.synchronise().type, ReplyType::data);
  std::this_thread::sleep_for(std::chrono::milliseconds(20));
  const std::int64_t from = edp.servo_->latest().cycle;
  // The column to 1.5 rad/s (its velocity limit) times 20 ms in 10 steps, from rest to rest:
  // 4 * 1.5 / 0.02 = 300 rad/s^2 against a limit of 3; 100 steps would do (2 sqrt(0.03 / 3)).
  std::vector<double> q = edp.model_.synchro_joint_positions;
  q[0] = edp.model_.max_velocity[0] * 10 * kPeriod;
  ASSERT_EQ(shortest_rest_to_rest_steps(q[0], edp.model_.max_velocity[0],
                                        edp.model_.max_acceleration[0], kPeriod),
            100);
  ASSERT_EQ(edp.set_joints(q, 10, 11).type, ReplyType::acknowledge);
  const Reply r = edp.query();
  expect_too_abrupt(r, "joint 0");
  EXPECT_EQ(r.error_text,
            "SET refused: joint 0 would accelerate at 300.000 rad/s^2, above its limit of 3.000 "
            "rad/s^2 (from rest at 0.0000 to rest at 0.0300 rad in 10 steps of 2.0 ms; it needs "
            "at least 100 steps); the robot holds");
  std::this_thread::sleep_for(std::chrono::milliseconds(100));
  expect_held(edp.servo_->trace(), from);
  EXPECT_TRUE(edp.servo_->stopped());
  // The same move in the steps the refusal names is accepted and ends at its target.
  ASSERT_EQ(edp.set_joints(q, 100, 101).type, ReplyType::acknowledge);
  const Reply ok = edp.query();
  ASSERT_EQ(ok.type, ReplyType::data) << ok.error_text;
  EXPECT_EQ(ok.desired_joints[0], q[0]);
}

TEST(EdpAcceleration, TheShortestRestToRestMoveKeepsEveryServoStepWithinTheLimits) {
  Edp edp("mujoco");
  ASSERT_EQ(edp.synchronise().type, ReplyType::data);
  const std::int64_t from = edp.servo_->latest().cycle;
  // The column 0.5 rad (limited by its acceleration: 409 steps), then the wrist roll 1.2 rad
  // (limited by its velocity: 400 steps), each in the fewest steps
  // edp::shortest_rest_to_rest_steps allows.
  std::vector<double> q = edp.model_.synchro_joint_positions;
  for (const auto& [joint, distance] : {std::pair<std::size_t, double>{0, 0.5}, {4, 1.2}}) {
    q[joint] += distance;
    const int steps = shortest_rest_to_rest_steps(distance, edp.model_.max_velocity[joint],
                                                  edp.model_.max_acceleration[joint], kPeriod);
    const Reply accepted = edp.set_joints(q, steps, steps + 1);
    ASSERT_EQ(accepted.type, ReplyType::acknowledge) << accepted.error_text;
    const Reply r = edp.query();
    ASSERT_EQ(r.type, ReplyType::data) << "joint " << joint << ": " << r.error_text;
    for (std::size_t j = 0; j < q.size(); ++j)
      EXPECT_EQ(r.desired_joints[j], q[j]) << "joint " << j << " did not end at its target";
  }
  std::this_thread::sleep_for(std::chrono::milliseconds(20));
  const Peaks p = check_trace_within_limits(edp.servo_->trace(), from, edp.model_);
  std::printf("peaks: column %.4f rad/s^2 %.4f rad/s, wrist roll %.4f rad/s^2 %.4f rad/s\n",
              p.acceleration[0], p.velocity[0], p.acceleration[4], p.velocity[4]);
  // The limit that binds is reached (the motion is the shortest), not only respected.
  EXPECT_GT(p.acceleration[0], 0.97 * edp.model_.max_acceleration[0]);
  EXPECT_GT(p.velocity[4], 0.97 * edp.model_.max_velocity[4]);
  EXPECT_EQ(edp.servo_->latest().desired[0], q[0]);
  EXPECT_EQ(edp.servo_->latest().desired[4], q[4]);
}

TEST(EdpAcceleration, AReversalIsRefusedAndTheMovingRobotIsBroughtToRestWithinItsLimits) {
  Edp edp("mujoco");
  ASSERT_EQ(edp.synchronise().type, ReplyType::data);
  const std::int64_t from = edp.servo_->latest().cycle;
  // The column from rest to +0.9 rad/s in one macro-step of 550 steps (it accelerates at
  // 2.45 rad/s^2 to 1.35 rad/s half way and ends at its mean velocity, as it promises a
  // successor), then a macro-step back at -0.9 rad/s: 2 * 1.8 / 0.02 = 180 rad/s^2.
  std::vector<double> q = edp.model_.synchro_joint_positions;
  const double start = q[0];
  q[0] = start + 0.9 * 550 * kPeriod;
  const double forward_end = q[0];
  ASSERT_EQ(edp.set_joints(q, 550, 547).type, ReplyType::acknowledge);
  const Reply moving = edp.query();
  ASSERT_EQ(moving.type, ReplyType::data) << moving.error_text;
  q[0] -= 0.9 * 10 * kPeriod;
  ASSERT_EQ(edp.set_joints(q, 10, 7).type, ReplyType::acknowledge);
  const Reply r = edp.query();
  expect_too_abrupt(r, "joint 0");
  EXPECT_NE(r.error_text.find("above its limit of 3.000 rad/s^2 (from 0.9000 rad/s to a mean of "
                              "-0.9000 rad/s in 10 steps of 2.0 ms)"),
            std::string::npos)
      << r.error_text;
  EXPECT_NE(r.error_text.find("; the robot is brought to rest within its acceleration limits"),
            std::string::npos)
      << r.error_text;
  std::this_thread::sleep_for(std::chrono::milliseconds(600));
  EXPECT_TRUE(edp.servo_->stopped());
  EXPECT_EQ(edp.servo_->lost_successors(), 0);
  const auto trace = edp.servo_->trace();
  const Peaks p = check_trace_within_limits(trace, from, edp.model_);
  EXPECT_GT(p.velocity[0], 1.3);
  // It stopped on its way (never turned back), 0.9^2 / 6 = 0.135 rad past the forward target,
  // and stands still.
  double previous = start;
  for (const auto& t : trace) {
    if (t.cycle < from) continue;
    EXPECT_GE(t.desired[0], previous) << "turned back at cycle " << t.cycle;
    previous = t.desired[0];
  }
  EXPECT_NEAR(previous - forward_end, 0.9 * 0.9 / 6.0, 0.01);
  // The column's velocity in the servo steps around the refusal.
  for (std::size_t i = 1; i < trace.size(); ++i)
    if (trace[i].cycle >= from && trace[i - 1].desired[0] < forward_end &&
        trace[i].desired[0] >= forward_end)
      for (std::size_t k = i - 1; k <= i + 3 && k < trace.size(); ++k)
        std::printf("cycle %lld: column at %.6f rad, %.4f rad/s\n",
                    static_cast<long long>(trace[k].cycle), trace[k].desired[0],
                    (trace[k].desired[0] - trace[k - 1].desired[0]) / kPeriod);
  const auto v = edp.velocities(trace.back().cycle - 20);
  for (const auto& s : v) EXPECT_EQ(s[0], 0.0) << "not at rest";
}

TEST(EdpAcceleration, RelativeAndCartesianMovesFromStandstillAreRefusedTheSameWay) {
  Edp edp("mujoco");
  ASSERT_EQ(edp.synchronise().type, ReplyType::data);
  std::this_thread::sleep_for(std::chrono::milliseconds(20));
  const std::int64_t from = edp.servo_->latest().cycle;
  // RELATIVE: the column +0.03 rad in 10 steps from rest.
  Reply r =
      edp.exec(test::set_joints_instruction({0.03, 0, 0, 0, 0}, 10, 11, MotionType::relative));
  ASSERT_EQ(r.type, ReplyType::acknowledge) << r.error_text;
  r = edp.query();
  expect_too_abrupt(r, "joint 0");
  EXPECT_NE(r.error_text.find("(from rest at 0.0000 to rest at 0.0300 rad in 10 steps of 2.0 ms; "
                              "it needs at least 100 steps); the robot holds"),
            std::string::npos)
      << r.error_text;
  // XYZ_EULER_ZYZ: the tool 2 mm along x in 10 steps from rest.
  Instruction get;
  get.type = InstructionType::get;
  get.get = item::arm;
  get.get_arm_type = ArmRepresentation::xyz_euler_zyz;
  ASSERT_EQ(edp.exec(get).type, ReplyType::acknowledge);
  const Reply here = edp.query();
  ASSERT_EQ(here.type, ReplyType::data) << here.error_text;
  ASSERT_EQ(here.arm.size(), 6U);
  Instruction cartesian = test::set_joints_instruction(here.arm, 10, 11);
  cartesian.set_arm_type = ArmRepresentation::xyz_euler_zyz;
  cartesian.arm[0] += 0.002;
  r = edp.exec(cartesian);
  ASSERT_EQ(r.type, ReplyType::acknowledge) << r.error_text;
  r = edp.query();
  EXPECT_EQ(r.error_code, error_code::too_abrupt) << r.error_text;
  EXPECT_NE(r.error_text.find(" would accelerate at "), std::string::npos) << r.error_text;
  EXPECT_NE(r.error_text.find(" rad/s^2, above its limit of "), std::string::npos) << r.error_text;
  EXPECT_NE(r.error_text.find("; the robot holds"), std::string::npos) << r.error_text;
  std::printf("refused: %s\n", r.error_text.c_str());
  std::this_thread::sleep_for(std::chrono::milliseconds(50));
  expect_held(edp.servo_->trace(), from);
  // The same Cartesian move in enough steps is accepted.
  cartesian.motion_steps = 200;
  cartesian.value_in_step_no = 201;
  ASSERT_EQ(edp.exec(cartesian).type, ReplyType::acknowledge);
  r = edp.query();
  EXPECT_EQ(r.type, ReplyType::data) << r.error_text;
}
