// The EDP's acceleration limit (edp/motion_blend.hpp, docs/edp.md "Acceleration"): every
// macro-step joins the previous one's velocity and ends exactly at its target; one that would
// need more than a joint's acceleration (or velocity) limit is refused before anything moves, with
// a text naming joint, value, unit and limit. The stock time scalings pass every boundary.
#include <fmt/format.h>
#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <string>
#include <thread>
#include <vector>

#include "command_interpreter.hpp"
#include "edp_parts.hpp"
#include "motion_blend.hpp"
#include "mrroc/ecp/generators/motion_profile.hpp"
#include "mrroc/ecp/robot.hpp"
#include "servo_loop.hpp"

using namespace mrroc;
using namespace mrroc::edp;

namespace {

constexpr double kPeriod = 0.002;

/// Runs a chain of macro-steps (targets of joint 0, others fixed) through plan_blend as the servo
/// loop does, with `known` successors queued at each start (0: none known), and returns the
/// largest |acceleration| and |velocity| of the servo steps, measured by differences of positions
/// [rad/s^2, rad/s]; `refused` tells whether a macro-step was refused.
struct ChainResult {
  double max_acceleration = 0;
  double max_velocity = 0;
  bool refused = false;
  std::string why;
  double end_velocity = 0;
};

ChainResult run_chain(const RobotModel& model, const std::vector<std::vector<double>>& targets,
                      int steps, bool successors_known, double start = 0.0) {
  ChainResult out;
  const std::size_t axes = model.axes();
  std::vector<MacroStep> chain(targets.size());
  for (std::size_t k = 0; k < targets.size(); ++k) {
    for (std::size_t i = 0; i < axes; ++i) chain[k].target[i] = targets[k][i];
    chain[k].steps = steps;
    chain[k].value_in_step_no = k + 1 < targets.size() ? steps - 3 : steps + 1;
    chain[k].id = k + 1;
  }
  AxisArray at{};
  for (std::size_t i = 0; i < axes; ++i) at[i] = i == 0 ? start : targets[0][i];
  AxisArray v{};
  std::vector<double> samples{at[0]};
  for (std::size_t k = 0; k < chain.size(); ++k) {
    BlendInput in;
    in.start = &at;
    in.velocity = &v;
    in.step = &chain[k];
    std::vector<const MacroStep*> following;
    for (std::size_t f = k + 1; successors_known && f < chain.size() && f < k + 8; ++f)
      following.push_back(&chain[f]);
    in.following = following;
    in.period_s = kPeriod;
    AxisArray end{};
    char why[384] = {};
    if (plan_blend(in, model, axes, end, why) != BlendRefusal::none) {
      out.refused = true;
      out.why = why;
      return out;
    }
    const double duration = steps * kPeriod;
    for (int s = 1; s <= steps; ++s)
      samples.push_back(s == steps ? chain[k].target[0]
                                   : blend_position(at[0], chain[k].target[0], v[0], end[0],
                                                    duration, double(s) / steps));
    at = chain[k].target;
    v = end;
  }
  out.end_velocity = v[0];
  samples.push_back(samples.back());  // at rest after the last macro-step
  for (std::size_t k = 1; k + 1 < samples.size(); ++k) {
    out.max_velocity = std::max(out.max_velocity, std::abs(samples[k] - samples[k - 1]) / kPeriod);
    out.max_acceleration =
        std::max(out.max_acceleration,
                 std::abs(samples[k + 1] - 2 * samples[k] + samples[k - 1]) / (kPeriod * kPeriod));
  }
  return out;
}

/// Joint-0 targets every `steps` servo steps of a profile moving joint 0 by `distance`.
std::vector<std::vector<double>> profile_targets(const RobotModel& model, ecp::ProfileShape shape,
                                                 double distance, double scale, int steps) {
  const double v = model.max_velocity[0] * scale / distance;
  const double a = model.max_acceleration[0] * scale / distance;
  const auto profile = ecp::MotionProfile::fastest(shape, v, a);
  const double dt = steps * kPeriod;
  const int n = static_cast<int>(std::ceil(profile.duration() / dt - 1e-9));
  std::vector<std::vector<double>> out;
  for (int k = 1; k <= n; ++k) {
    std::vector<double> q = model.synchro_joint_positions;
    q[0] = distance * profile.position(k * dt);
    out.push_back(q);
  }
  return out;
}

}  // namespace

TEST(EdpAcceleration, RestToRestNeedsTimeAndTheRefusalSaysHowMuch) {
  const RobotModel model = test::stock_model("irb6");
  std::vector<double> q = model.synchro_joint_positions;
  q[0] = 0.2;  // the column, 3 rad/s^2: as one macro-step from rest to rest
  const int shortest =
      shortest_rest_to_rest_steps(0.2, model.max_velocity[0], model.max_acceleration[0], kPeriod);
  EXPECT_EQ(shortest, static_cast<int>(std::ceil(2 * std::sqrt(0.2 / 3.0) / kPeriod - 1e-9)));
  const ChainResult fast = run_chain(model, {q}, shortest - 1, true);
  ASSERT_TRUE(fast.refused);
  EXPECT_NE(fast.why.find("joint 0 would accelerate at"), std::string::npos) << fast.why;
  EXPECT_NE(fast.why.find("above its limit of 3.000 rad/s^2"), std::string::npos) << fast.why;
  EXPECT_NE(fast.why.find(fmt::format("it needs at least {} steps", shortest)), std::string::npos)
      << fast.why;
  const ChainResult ok = run_chain(model, {q}, shortest, true);
  ASSERT_FALSE(ok.refused) << ok.why;
  EXPECT_LE(ok.max_acceleration, model.max_acceleration[0] * 1.0001);
  EXPECT_GT(ok.max_acceleration, model.max_acceleration[0] * 0.9);  // it was needed
}

TEST(EdpAcceleration, ReversalAtTheVelocityLimitIsRefused) {
  const RobotModel model = test::stock_model("irb6");
  // +v_max for 20 ms, then -v_max: the join needs 2 v_max / 20 ms * ... far above the limit.
  const double v = model.max_velocity[0];
  std::vector<double> a = model.synchro_joint_positions, b = a;
  a[0] = v * 0.02;
  b[0] = 0.0;
  const ChainResult r = run_chain(model, {a, b}, 10, true);
  ASSERT_TRUE(r.refused);
  EXPECT_NE(r.why.find("joint 0 would accelerate at"), std::string::npos) << r.why;
}

TEST(EdpAcceleration, PrismaticJointsSpeakMetres) {
  const RobotModel model = test::stock_model("conveyor");
  ASSERT_EQ(model.unit(0), std::string("m"));
  const ChainResult r = run_chain(model, {{0.05}}, 100, true);  // 0.25 m/s, 7.5 m/s^2
  ASSERT_TRUE(r.refused);
  EXPECT_NE(r.why.find("m/s^2, above its limit of 1.000 m/s^2"), std::string::npos) << r.why;
}

// The stock time scalings, sampled into macro-steps of 2..50 servo steps, with the successors
// known (a lookahead of 8) up to 0.8 of the limits for the trapezoid (whose corners no boundary
// meets) and 0.95 for the quintic, or not known (lookahead 1) up to 0.3 and 0.4 (docs/edp.md,
// "Acceleration"): no boundary is refused, and the EDP's servo steps stay within the limits.
TEST(EdpAcceleration, StockProfilesPassEveryBoundary) {
  const RobotModel model = test::stock_model("irb6");
  struct Case {
    ecp::ProfileShape shape;
    double scale;
    bool known;
  };
  int chains = 0;
  for (const Case c :
       {Case{ecp::ProfileShape::trapezoidal, 0.8, true},
        Case{ecp::ProfileShape::trapezoidal, 0.3, false},
        Case{ecp::ProfileShape::quintic, 0.95, true}, Case{ecp::ProfileShape::quintic, 0.4, false}})
    for (double distance = 0.001; distance < 2.5; distance *= 1.3)
      for (const int steps : {2, 5, 10, 20, 50}) {
        const auto targets = profile_targets(model, c.shape, distance, c.scale, steps);
        const ChainResult r = run_chain(model, targets, steps, c.known);
        SCOPED_TRACE(fmt::format("{} {:.4f} rad scale {} steps {} successor {}",
                                 ecp::to_string(c.shape), distance, c.scale, steps,
                                 c.known ? "known" : "unknown"));
        ASSERT_FALSE(r.refused) << r.why;
        EXPECT_LE(r.max_velocity, model.max_velocity[0] * (1 + 1e-6));
        EXPECT_LE(r.max_acceleration,
                  model.max_acceleration[0] * (1 + 2e-6))  // the EDP rounds by 1e-6
            << fmt::format("{:.9f}", r.max_acceleration);
        EXPECT_EQ(r.end_velocity, 0.0);
        ++chains;
      }
  EXPECT_EQ(chains, 4 * 30 * 5);
}

// Synchronisation is motion too: the search speeds up to its slow velocity, slows down to rest
// after the switch, and the approach to the synchronisation pose goes from rest to rest, every
// servo step within half the joint's acceleration limit (the EDP's own trace).
TEST(EdpAcceleration, SynchronisationStaysWithinTheLimits) {
  const RobotModel model = test::stock_model("irb6");
  auto hardware = test::configured_hardware(model, "mujoco", kPeriod);
  ServoLoop servo(*hardware, model, kPeriod);
  servo.enable_trace(20000);
  servo.start();
  servo.begin_synchronisation();
  ASSERT_TRUE(servo.wait_synchronised(30.0));
  servo.stop();
  const auto trace = servo.trace();
  ASSERT_GT(trace.size(), 10U);
  std::size_t checked = 0;
  for (std::size_t k = 2; k + 1 < trace.size(); ++k) {
    // Skip where the setpoints change from raw axis to joint coordinates (the flag of a sample is
    // that of the start of its cycle).
    if (trace[k + 1].synchronised != trace[k - 2].synchronised) continue;
    for (std::size_t j = 0; j < model.axes(); ++j) {
      const double a =
          (trace[k].desired[j] - 2 * trace[k - 1].desired[j] + trace[k - 2].desired[j]) /
          (kPeriod * kPeriod);
      EXPECT_LE(std::abs(a), 0.5 * model.max_acceleration[j] * (1 + 1e-6))
          << "cycle " << trace[k].cycle << " joint " << j;
      ++checked;
    }
  }
  EXPECT_GT(checked, 100U);
  const auto last = servo.latest();
  for (std::size_t j = 0; j < model.axes(); ++j)
    EXPECT_NEAR(last.desired[j], model.synchro_joint_positions[j], 1e-12) << "joint " << j;
}

// A console jog (a RELATIVE rest-to-rest macro-step of ecp::rest_to_rest_steps, fraction 0.25,
// the largest jog step 0.2 rad, and on the conveyor 0.2 m) through the command interpreter: the
// EDP's own trace shows every servo step within that fraction of the velocity and acceleration
// limits, and the joint ends exactly where the jog said.
TEST(EdpAcceleration, AJogIsAProfileWithinTheLimits) {
  for (const char* robot : {"irb6", "conveyor"}) {
    const RobotModel model = test::stock_model(robot);
    auto hardware = test::configured_hardware(model, "mujoco", kPeriod);
    auto kinematics = make_arm_kinematics(model);
    ServoLoop servo(*hardware, model, kPeriod);
    servo.set_limit_guard(kinematics.get());
    servo.enable_trace(60000);
    servo.start();
    CommandInterpreter interpreter(servo, model, *kinematics, kPeriod);
    Instruction sync;
    sync.type = InstructionType::synchro;
    sync.with_query = true;
    ASSERT_EQ(interpreter.execute(sync).type, ReplyType::data);
    constexpr double kFraction = 0.25;
    for (std::size_t axis = 0; axis < model.axes(); ++axis) {
      std::vector<double> delta(model.axes(), 0.0);
      delta[axis] =
          model.synchro_joint_positions[axis] + 0.2 < model.upper_limits[axis] ? 0.2 : -0.2;
      const int steps = ecp::rest_to_rest_steps(model, delta, kFraction, kPeriod, 0.1);
      const auto before = servo.planned_end();
      const std::int64_t from = servo.latest().cycle;
      Instruction jog = test::set_joints_instruction(delta, steps, steps + 1, MotionType::relative);
      jog.with_query = true;
      const Reply r = interpreter.execute(jog);
      ASSERT_EQ(r.type, ReplyType::data) << robot << " axis " << axis << ": " << r.error_text;
      EXPECT_NEAR(r.desired_joints[axis], before[axis] + delta[axis], 1e-12);
      const auto trace = servo.trace();
      double vmax = 0, amax = 0;
      for (std::size_t k = 2; k < trace.size(); ++k) {
        if (trace[k - 2].cycle < from) continue;
        const double v = (trace[k].desired[axis] - trace[k - 1].desired[axis]) / kPeriod;
        const double a =
            (trace[k].desired[axis] - 2 * trace[k - 1].desired[axis] + trace[k - 2].desired[axis]) /
            (kPeriod * kPeriod);
        vmax = std::max(vmax, std::abs(v));
        amax = std::max(amax, std::abs(a));
      }
      EXPECT_LE(vmax, kFraction * model.max_velocity[axis] * (1 + 1e-6)) << robot << " " << axis;
      EXPECT_LE(amax, kFraction * model.max_acceleration[axis] * (1 + 1e-6))
          << robot << " " << axis;
      EXPECT_GT(amax, 0.0) << robot << " " << axis;
      std::printf("%s axis %zu: jog of %+.1f %s in %d steps, peak %.3f %s/s, %.3f %s/s^2\n", robot,
                  axis, delta[axis], model.unit(axis), steps, vmax, model.unit(axis), amax,
                  model.unit(axis));
    }
    servo.stop();
  }
}
