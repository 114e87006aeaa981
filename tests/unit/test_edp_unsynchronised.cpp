// Motion before synchronisation (docs/edp.md, "Motion before synchronisation"): an EDP whose
// robot is not synchronised accepts RELATIVE MOTOR and JOINT moves only, each joint's change at
// most [robot.edp] unsynchronised_max_move, planned and stopped within the reduced velocity and
// acceleration limits, through the same command interpreter and servo loop as every motion;
// absolute and Cartesian moves stay refused; SYNCHRO starts from wherever the robot then stands.
// The IRb-6 in MuJoCo powers on 0.05 rad above its synchronisation pose: every axis' switch
// (input i) is pressed, as for an arm parked on its switches.
#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <thread>

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
  Edp() {
    model_ = test::stock_model("irb6");
    hardware_ = test::configured_hardware(model_, "mujoco", kPeriod);
    kinematics_ = make_arm_kinematics(model_);
    servo_ = std::make_unique<ServoLoop>(*hardware_, model_, kPeriod);
    servo_->set_limit_guard(kinematics_.get());
    servo_->set_unsynchronised_limits(limits_);
    servo_->enable_trace(20000);
    servo_->start();
    interpreter_ = std::make_unique<CommandInterpreter>(*servo_, model_, *kinematics_, kPeriod);
  }
  ~Edp() { servo_->stop(); }
  Edp(const Edp&) = delete;
  Edp& operator=(const Edp&) = delete;

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
  /// SET ARM of `values` in `type` and `motion`, `steps` servo steps, read after the stop.
  static Instruction set_arm(ArmRepresentation type, MotionType motion, std::vector<double> values,
                             int steps) {
    Instruction in = test::set_joints_instruction(std::move(values), steps, steps + 1, motion);
    in.set_arm_type = type;
    return in;
  }
  /// Steps of the shortest rest-to-rest move by `change` within the reduced limits.
  int reduced_steps(const std::vector<double>& change) const {
    const std::vector<double> zero(change.size(), 0.0);
    EXPECT_EQ(limits_.velocity_fraction, limits_.acceleration_fraction);
    return test::rest_to_rest_steps(model_, zero, change, kPeriod, limits_.velocity_fraction);
  }
  /// Waits until the robot is at rest, and the servo loop has run its first cycles (its first
  /// reading, inputs included, comes with them).
  bool wait_stopped(double seconds) {
    const auto until = std::chrono::steady_clock::now() +
                       std::chrono::milliseconds(static_cast<int>(seconds * 1000));
    while ((!servo_->stopped() || servo_->latest().cycle < 5) &&
           std::chrono::steady_clock::now() < until)
      std::this_thread::sleep_for(std::chrono::milliseconds(1));
    return servo_->stopped() && servo_->latest().cycle >= 5;
  }
  /// Commanded velocities of the unsynchronised cycles of the trace from cycle `from` on
  /// (raw axis positions) [rad/s].
  std::vector<AxisArray> velocities(std::int64_t from) const {
    std::vector<AxisArray> out;
    const auto trace = servo_->trace();
    for (std::size_t k = 1; k < trace.size(); ++k) {
      if (trace[k].cycle < from || trace[k].synchronised || trace[k - 1].synchronised) continue;
      AxisArray v{};
      for (std::size_t j = 0; j < model_.axes(); ++j)
        v[j] = (trace[k].desired[j] - trace[k - 1].desired[j]) / kPeriod;
      out.push_back(v);
    }
    return out;
  }
  /// The largest commanded velocity and acceleration of joint `j` in `v`.
  static std::pair<double, double> peaks(const std::vector<AxisArray>& v, std::size_t j) {
    double speed = 0.0;
    double acceleration = 0.0;
    for (std::size_t k = 0; k < v.size(); ++k) {
      speed = std::max(speed, std::abs(v[k][j]));
      if (k > 0) acceleration = std::max(acceleration, std::abs(v[k][j] - v[k - 1][j]) / kPeriod);
    }
    return {speed, acceleration};
  }
  [[nodiscard]] double reduced_velocity(std::size_t j) const {
    return model_.max_velocity[j] * limits_.velocity_fraction;
  }
  [[nodiscard]] double reduced_acceleration(std::size_t j) const {
    return model_.max_acceleration[j] * limits_.acceleration_fraction;
  }
  /// The switches as GET INPUTS reads them through the EDP (bit i: axis i's switch pressed).
  std::uint32_t inputs() {
    Instruction get;
    get.type = InstructionType::get;
    get.get = item::inputs;
    EXPECT_EQ(exec(get).type, ReplyType::acknowledge);
    const Reply r = query();
    EXPECT_EQ(r.type, ReplyType::data) << r.error_text;
    return r.input_values;
  }

  UnsynchronisedLimits limits_{};  // the defaults of [robot.edp]: 0.1, 0.1, 0.1 rad
  RobotModel model_;
  std::unique_ptr<Hardware> hardware_;
  std::unique_ptr<ServoLoop> servo_;
  std::unique_ptr<ArmKinematics> kinematics_;
  std::unique_ptr<CommandInterpreter> interpreter_;
};

bool contains(const std::string& text, const std::string& part) {
  return text.find(part) != std::string::npos;
}

}  // namespace

// A relative JOINT move of the column and one of the upper arm, then a MOTOR move of the column,
// before SYNCHRO: each moves its axis by what was asked (the MOTOR change through the column's
// harmonic drive, ratio 158, direction -1) with the commanded velocity and acceleration measured
// from the servo trace at or below the reduced limits, and close to them (the shortest move
// they allow).
TEST(EdpUnsynchronised, RelativeMovesKeepTheReducedLimits) {
  Edp edp;
  ASSERT_FALSE(edp.servo_->synchronised());
  ASSERT_TRUE(edp.wait_stopped(1.0));
  const std::vector<double> start = edp.servo_->planned_end();
  const std::int64_t from = edp.servo_->latest().cycle;

  std::vector<double> change(edp.model_.axes(), 0.0);
  change[0] = -0.1;
  change[2] = 0.06;
  int steps = edp.reduced_steps(change);
  Reply r = edp.exec(Edp::set_arm(ArmRepresentation::joint, MotionType::relative, change, steps));
  ASSERT_EQ(r.type, ReplyType::acknowledge) << r.error_text;
  r = edp.query();
  ASSERT_EQ(r.type, ReplyType::data) << r.error_text;
  EXPECT_FALSE(r.synchronised);
  for (std::size_t j = 0; j < edp.model_.axes(); ++j)
    EXPECT_NEAR(r.desired_joints[j], start[j] + change[j], 1e-12) << "joint " << j;
  EXPECT_NEAR(r.joints[0], start[0] + change[0], 5e-3) << "the column did not follow";

  const auto v = edp.velocities(from);
  for (std::size_t j : {0U, 2U}) {
    const auto [speed, acceleration] = Edp::peaks(v, j);
    std::printf("joint %zu: peak %.4f rad/s (limit %.4f), %.4f rad/s^2 (limit %.4f) in %d steps\n",
                j, speed, edp.reduced_velocity(j), acceleration, edp.reduced_acceleration(j),
                steps);
    EXPECT_LE(speed, edp.reduced_velocity(j) * (1 + 1e-9)) << "joint " << j;
    EXPECT_LE(acceleration, edp.reduced_acceleration(j) * (1 + 1e-6)) << "joint " << j;
  }
  // The column's move is the longer one: it uses nearly all of its reduced limits.
  const auto [column_speed, column_acceleration] = Edp::peaks(v, 0);
  EXPECT_GT(std::max(column_speed / edp.reduced_velocity(0),
                     column_acceleration / edp.reduced_acceleration(0)),
            0.9);

  // MOTOR: the column's motor by +10 rad turns the column by -10 / 158 rad.
  ASSERT_TRUE(edp.wait_stopped(1.0));
  std::vector<double> motors(edp.model_.axes(), 0.0);
  motors[0] = 10.0;
  change.assign(edp.model_.axes(), 0.0);
  change[0] = -10.0 / 158.0;
  steps = edp.reduced_steps(change);
  const double before = edp.servo_->planned_end()[0];
  r = edp.exec(Edp::set_arm(ArmRepresentation::motor, MotionType::relative, motors, steps));
  ASSERT_EQ(r.type, ReplyType::acknowledge) << r.error_text;
  r = edp.query();
  ASSERT_EQ(r.type, ReplyType::data) << r.error_text;
  EXPECT_NEAR(r.desired_joints[0], before - 10.0 / 158.0, 1e-12);
  const auto [speed, acceleration] = Edp::peaks(edp.velocities(from), 0);
  EXPECT_LE(speed, edp.reduced_velocity(0) * (1 + 1e-9));
  EXPECT_LE(acceleration, edp.reduced_acceleration(0) * (1 + 1e-6));
}

// The same move in fewer steps, within the robot's full limits but not the reduced ones, is
// refused when it is due to start, naming the reduced limit; nothing moves.
TEST(EdpUnsynchronised, AMoveFasterThanTheReducedLimitsIsRefused) {
  Edp edp;
  ASSERT_TRUE(edp.wait_stopped(1.0));
  const std::vector<double> start = edp.servo_->planned_end();
  std::vector<double> change(edp.model_.axes(), 0.0);
  change[0] = -0.1;
  const std::vector<double> zero(change.size(), 0.0);
  const int steps = test::rest_to_rest_steps(edp.model_, zero, change, kPeriod, 1.0);
  ASSERT_LT(steps, edp.reduced_steps(change));
  ASSERT_EQ(
      edp.exec(Edp::set_arm(ArmRepresentation::joint, MotionType::relative, change, steps)).type,
      ReplyType::acknowledge);
  const Reply r = edp.query();
  ASSERT_EQ(r.type, ReplyType::error);
  EXPECT_TRUE(r.error_code == error_code::too_fast || r.error_code == error_code::too_abrupt)
      << r.error_code << ": " << r.error_text;
  EXPECT_TRUE(contains(r.error_text, "joint 0 would ")) << r.error_text;
  EXPECT_TRUE(contains(r.error_text,
                       "(before SYNCHRO: 0.10 of the velocity and 0.10 of the "
                       "acceleration limits, [robot.edp] unsynchronised_*)"))
      << r.error_text;
  EXPECT_TRUE(contains(r.error_text, "0.300 rad/s^2") || contains(r.error_text, "0.150 rad/s"))
      << r.error_text;
  const Reading now = edp.servo_->latest();
  for (std::size_t j = 0; j < edp.model_.axes(); ++j)
    EXPECT_EQ(now.desired[j], start[j]) << "joint " << j;
}

// Absolute moves and Cartesian moves need the position: refused before SYNCHRO with the error
// that says what is allowed; nothing moves and no QUERY is due.
TEST(EdpUnsynchronised, AbsoluteAndCartesianMovesAreRefused) {
  Edp edp;
  ASSERT_TRUE(edp.wait_stopped(1.0));
  const std::vector<double> start = edp.servo_->planned_end();
  const std::vector<double> zero(edp.model_.axes(), 0.0);
  const std::vector<double> frame = {1, 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0.01};
  const std::vector<double> xyz_aa = {0, 0, 0.01, 0, 0, 0};
  struct Case {
    ArmRepresentation type;
    MotionType motion;
    std::vector<double> values;
    std::string text;
  };
  const Case cases[] = {
      {ArmRepresentation::joint, MotionType::absolute, edp.model_.synchro_joint_positions,
       "SET ARM JOINT ABSOLUTE refused"},
      {ArmRepresentation::motor, MotionType::absolute, zero, "SET ARM MOTOR ABSOLUTE refused"},
      {ArmRepresentation::frame, MotionType::relative, frame, "SET ARM FRAME RELATIVE refused"},
      {ArmRepresentation::frame, MotionType::absolute, frame, "SET ARM FRAME ABSOLUTE refused"},
      {ArmRepresentation::xyz_angle_axis, MotionType::relative, xyz_aa,
       "SET ARM XYZ_ANGLE_AXIS RELATIVE refused"},
  };
  for (const Case& c : cases) {
    const Reply r = edp.exec(Edp::set_arm(c.type, c.motion, c.values, 500));
    EXPECT_EQ(r.type, ReplyType::error) << c.text;
    EXPECT_EQ(r.error_code, error_code::not_synchronised) << r.error_text;
    EXPECT_TRUE(contains(r.error_text, c.text)) << r.error_text;
    EXPECT_TRUE(contains(r.error_text,
                         "robot not synchronised (its position is unknown: send "
                         "SYNCHRO first; before it only RELATIVE MOTOR and JOINT "
                         "moves are allowed, at reduced limits)"))
        << r.error_text;
    EXPECT_FALSE(r.synchronised);
  }
  EXPECT_EQ(edp.query().error_code, error_code::query_unexpected);
  std::this_thread::sleep_for(std::chrono::milliseconds(50));
  const Reading now = edp.servo_->latest();
  for (std::size_t j = 0; j < edp.model_.axes(); ++j)
    EXPECT_EQ(now.desired[j], start[j]) << "joint " << j;
}

// A move larger than unsynchronised_max_move on any joint is refused, naming the axis, the
// value, the unit and the bound (in joint units, also for a MOTOR move); a wrong size or a NaN
// is refused as for every move.
TEST(EdpUnsynchronised, AMoveLargerThanTheBoundIsRefused) {
  Edp edp;
  ASSERT_TRUE(edp.wait_stopped(1.0));
  std::vector<double> change(edp.model_.axes(), 0.0);
  change[1] = -0.15;
  Reply r = edp.exec(Edp::set_arm(ArmRepresentation::joint, MotionType::relative, change, 2000));
  EXPECT_EQ(r.error_code, error_code::out_of_limits) << r.error_text;
  EXPECT_TRUE(contains(r.error_text,
                       "SET ARM JOINT RELATIVE refused before SYNCHRO: axis 1 (lower_arm) would "
                       "move -0.1500 rad, more than the 0.1000 rad one move may take before "
                       "synchronisation ([robot.edp] unsynchronised_max_move; the joint limits "
                       "cannot be checked while the position is unknown)"))
      << r.error_text;
  // The column's motor by 20 rad: 20 / 158 = 0.1266 rad of the column.
  std::vector<double> motors(edp.model_.axes(), 0.0);
  motors[0] = 20.0;
  r = edp.exec(Edp::set_arm(ArmRepresentation::motor, MotionType::relative, motors, 2000));
  EXPECT_EQ(r.error_code, error_code::out_of_limits) << r.error_text;
  EXPECT_TRUE(contains(r.error_text,
                       "SET ARM MOTOR RELATIVE refused before SYNCHRO: axis 0 "
                       "(column) would move -0.1266 rad (from the motor changes "
                       "[20.0000, 0.0000, 0.0000, 0.0000, 0.0000] rad), more than "
                       "the 0.1000 rad"))
      << r.error_text;
  change.assign(3, 0.01);
  r = edp.exec(Edp::set_arm(ArmRepresentation::joint, MotionType::relative, change, 100));
  EXPECT_EQ(r.error_code, error_code::bad_argument) << r.error_text;
  change.assign(edp.model_.axes(), 0.0);
  change[3] = std::nan("");
  r = edp.exec(Edp::set_arm(ArmRepresentation::joint, MotionType::relative, change, 100));
  EXPECT_EQ(r.error_code, error_code::bad_argument) << r.error_text;
  EXPECT_EQ(edp.query().error_code, error_code::query_unexpected);
}

// The emergency stop during a move before SYNCHRO brakes it within the reduced acceleration
// limit to a standstill short of its target and holds; after the release, SYNCHRO succeeds.
TEST(EdpUnsynchronised, EmergencyStopStopsTheMoveThenSynchroSucceeds) {
  Edp edp;
  ASSERT_TRUE(edp.wait_stopped(1.0));
  const double start = edp.servo_->planned_end()[0];
  std::vector<double> change(edp.model_.axes(), 0.0);
  change[0] = -0.1;
  const int steps = edp.reduced_steps(change);  // about 1.3 s
  ASSERT_EQ(
      edp.exec(Edp::set_arm(ArmRepresentation::joint, MotionType::relative, change, steps)).type,
      ReplyType::acknowledge);
  std::this_thread::sleep_for(std::chrono::milliseconds(500));
  const std::int64_t at = edp.servo_->latest().cycle;
  edp.servo_->emergency_stop();
  ASSERT_TRUE(edp.wait_stopped(2.0)) << "not at rest 2 s after the emergency stop";
  std::this_thread::sleep_for(std::chrono::milliseconds(100));
  const auto v = edp.velocities(at - 2);
  ASSERT_GT(v.size(), 10U);
  EXPECT_GT(std::abs(v[0][0]), 0.3 * edp.reduced_velocity(0)) << "not moving when stopped";
  std::size_t rest = v.size();
  for (std::size_t k = 1; k < v.size(); ++k) {
    EXPECT_LE(std::abs(v[k][0] - v[k - 1][0]), edp.reduced_acceleration(0) * kPeriod * 1.0001)
        << "cycle " << k;
    if (rest == v.size() && v[k][0] == 0.0) rest = k;
  }
  ASSERT_LT(rest, v.size()) << "never came to rest";
  for (std::size_t k = rest; k < v.size(); ++k) EXPECT_EQ(v[k][0], 0.0) << "moved while held";
  std::printf("at rest %zu servo steps after the emergency stop\n", rest);
  const double stood = edp.servo_->latest().desired[0];
  EXPECT_LT(std::abs(stood - start), 0.09) << "the move ran on to its target";
  EXPECT_GT(std::abs(stood - start), 0.005) << "the move never ran";

  Reply r = edp.query();
  EXPECT_EQ(r.error_code, error_code::emergency_stop) << r.error_text;
  r = edp.exec(Edp::set_arm(ArmRepresentation::joint, MotionType::relative, change, steps));
  EXPECT_EQ(r.error_code, error_code::emergency_stop) << r.error_text;
  edp.servo_->release_emergency_stop();
  r = edp.synchronise();
  ASSERT_EQ(r.type, ReplyType::data) << r.error_text;
  EXPECT_TRUE(r.synchronised);
  for (std::size_t j = 0; j < edp.model_.axes(); ++j)
    EXPECT_NEAR(r.joints[j], edp.model_.synchro_joint_positions[j], 2e-3) << "joint " << j;
}

// An arm parked on its switches: the column moved off its switch by a relative JOINT move
// before SYNCHRO, and the switch input reads released; SYNCHRO is refused while a move still
// runs (its reading came early: the missing successor's stopping ramp keeps the reduced limits
// too), then searches from where the column stands (upwards now) and finds the same pose.
TEST(EdpUnsynchronised, MoveOffTheSwitchThenSynchronise) {
  Edp edp;
  ASSERT_TRUE(edp.wait_stopped(1.0));
  const std::uint32_t pressed = edp.inputs();
  ASSERT_EQ(pressed & 0x1FU, 0x1FU) << "every switch pressed at power-on";

  // Off the switch in two moves; the first answers in its first step, so SYNCHRO comes while
  // it runs.
  std::vector<double> change(edp.model_.axes(), 0.0);
  change[0] = -0.04;
  const int steps = edp.reduced_steps(change);
  Instruction early = Edp::set_arm(ArmRepresentation::joint, MotionType::relative, change, steps);
  early.value_in_step_no = 1;
  ASSERT_EQ(edp.exec(early).type, ReplyType::acknowledge);
  ASSERT_EQ(edp.query().type, ReplyType::data);
  Instruction synchro;
  synchro.type = InstructionType::synchro;
  Reply r = edp.exec(synchro);
  EXPECT_EQ(r.error_code, error_code::bad_argument) << r.error_text;
  EXPECT_TRUE(contains(r.error_text, "SYNCHRO refused: the robot is still moving")) << r.error_text;
  ASSERT_TRUE(edp.wait_stopped(5.0));
  // The first move promised a successor that never came: it ended moving and a stopping ramp
  // brought the column to rest, the whole of it within the reduced limits.
  EXPECT_EQ(edp.servo_->lost_successors(), 1);
  const auto [speed, acceleration] = Edp::peaks(edp.velocities(0), 0);
  EXPECT_GT(speed, 0.0);
  EXPECT_LE(speed, edp.reduced_velocity(0) * (1 + 1e-9));
  EXPECT_LE(acceleration, edp.reduced_acceleration(0) * (1 + 1e-6));
  EXPECT_EQ(edp.inputs() & 0x1U, 0x1U) << "0.04 rad down, the column is still on its switch";
  ASSERT_EQ(
      edp.exec(Edp::set_arm(ArmRepresentation::joint, MotionType::relative, change, steps)).type,
      ReplyType::acknowledge);
  ASSERT_EQ(edp.query().type, ReplyType::data);
  ASSERT_TRUE(edp.wait_stopped(1.0));
  std::this_thread::sleep_for(std::chrono::milliseconds(100));
  const std::uint32_t after = edp.inputs();
  EXPECT_EQ(after & 0x1U, 0U) << "the column's switch still reads pressed";
  EXPECT_EQ(after & 0x1EU, 0x1EU) << "the other axes left their switches";

  r = edp.synchronise();
  ASSERT_EQ(r.type, ReplyType::data) << r.error_text;
  EXPECT_TRUE(r.synchronised);
  std::this_thread::sleep_for(std::chrono::milliseconds(300));
  const Reading now = edp.servo_->latest();
  for (std::size_t j = 0; j < edp.model_.axes(); ++j)
    EXPECT_NEAR(now.joints[j], edp.model_.synchro_joint_positions[j], 5e-4) << "joint " << j;
  // Synchronised, the robot's own limits apply again: an absolute move is accepted.
  std::vector<double> q = edp.model_.synchro_joint_positions;
  q[0] += 0.05;
  const int full_steps =
      test::rest_to_rest_steps(edp.model_, edp.servo_->planned_end(), q, kPeriod);
  r = edp.exec(Edp::set_arm(ArmRepresentation::joint, MotionType::absolute, q, full_steps));
  ASSERT_EQ(r.type, ReplyType::acknowledge) << r.error_text;
  EXPECT_EQ(edp.query().type, ReplyType::data);
}
