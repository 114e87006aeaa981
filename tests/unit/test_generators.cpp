// The stock generators, run as Move runs them (first_step, then execute + next_step until it
// returns false) against a fake EDP that reaches every target exactly: joint/motor
// interpolation, Cartesian lines and arcs, guarded moves and pass-through. IRb-6 model; poses
// near the synchronisation pose (0, -pi/2, 0, 0, 0).
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <functional>
#include <numbers>
#include <string>
#include <thread>
#include <vector>

#include "mrroc/core/error.hpp"
#include "mrroc/ecp/conditions.hpp"
#include "mrroc/ecp/generators/cartesian_path.hpp"
#include "mrroc/ecp/generators/errors.hpp"
#include "mrroc/ecp/generators/guarded_move.hpp"
#include "mrroc/ecp/generators/interpolation.hpp"
#include "mrroc/ecp/generators/motion_profile.hpp"
#include "mrroc/ecp/generators/pass_through.hpp"
#include "mrroc/edp/arm_kinematics.hpp"
#include "mrroc/kinematics/pose.hpp"
#include "mrroc/robot/robot_model.hpp"

using namespace mrroc;
using edp::ArmRepresentation;

namespace {

const RobotModel& model() {
  static const RobotModel m = load_robot_model(std::string(MRROC_SOURCE_DIR) + "/robots/irb6");
  return m;
}

std::vector<double> synchro() { return model().synchro_joint_positions; }

bool contains(const std::string& text, const std::string& part) {
  return text.find(part) != std::string::npos;
}

/// An EDP that executes every SET ARM exactly (the interpolation inside the macro-step is not
/// simulated): the robot image's joints become the target's joints.
class FakeEdp {
 public:
  FakeEdp() : kinematics_(edp::make_arm_kinematics(model())) {}

  void execute(ecp::RobotImage& image) {
    const edp::Instruction& c = image.command;
    ASSERT_TRUE(c.type == edp::InstructionType::set || c.type == edp::InstructionType::set_get);
    ASSERT_NE(c.set & edp::item::arm, 0);
    if ((c.set & edp::item::model) != 0)
      kinematics_->select_model(c.kinematic_model_no, c.corrector_no);
    if ((c.set & edp::item::tool) != 0)
      kinematics_->set_tool(kinematics::from_vector(c.tool, c.tool_type));
    std::vector<double> q;
    switch (c.set_arm_type) {
      case ArmRepresentation::joint:
        q = c.arm;
        if (c.motion_type == edp::MotionType::relative)
          for (std::size_t j = 0; j < q.size(); ++j) q[j] += image.desired_joints[j];
        break;
      case ArmRepresentation::motor: q = kinematics_->joints_from_motors(c.arm); break;
      default:
        q = kinematics_->inverse(kinematics::from_vector(c.arm, c.set_arm_type),
                                 image.desired_joints);
        break;
    }
    const double dt = c.motion_steps * 0.002;
    image.joint_velocities.resize(q.size());
    for (std::size_t j = 0; j < q.size(); ++j)
      image.joint_velocities[j] = (q[j] - image.desired_joints[j]) / dt;
    image.desired_joints = q;
    image.joints = q;
    image.servo_cycle += c.motion_steps;
  }

 private:
  std::unique_ptr<edp::ArmKinematics> kinematics_;
};

struct Executed {
  std::vector<edp::Instruction> commands;
  std::vector<std::vector<double>> joints;  // after each command
};

/// Runs `g` as Move does. `after` sees the image after each exchange.
Executed run(ecp::Generator& g, const std::vector<double>& start,
             const std::function<void(const ecp::RobotImage&)>& after = {}) {
  FakeEdp edp;
  ecp::RobotImage image;
  image.desired_joints = start;
  image.joints = start;
  Executed r;
  if (!g.first_step(image, {})) return r;
  do {
    r.commands.push_back(image.command);
    edp.execute(image);
    r.joints.push_back(image.desired_joints);
    if (after) after(image);
  } while (g.next_step(image, {}));
  return r;
}

std::vector<std::vector<double>> arms(const Executed& r) {
  std::vector<std::vector<double>> out;
  for (const auto& c : r.commands) out.push_back(c.arm);
  return out;
}

/// Largest per-macro-step |mean velocity| / limit and |change of it per macro-step| / limit,
/// starting and ending at rest.
struct Ratios {
  double velocity = 0.0;
  double acceleration = 0.0;
};
Ratios rate_ratios(const std::vector<double>& start, const std::vector<std::vector<double>>& xs,
                   double dt, const std::vector<double>& max_velocity,
                   const std::vector<double>& max_acceleration) {
  Ratios r;
  std::vector<double> previous = start;
  std::vector<double> previous_velocity(start.size(), 0.0);
  for (std::size_t k = 0; k <= xs.size(); ++k) {
    for (std::size_t j = 0; j < start.size(); ++j) {
      const double v = k < xs.size() ? (xs[k][j] - previous[j]) / dt : 0.0;
      r.velocity = std::max(r.velocity, std::abs(v) / max_velocity[j]);
      r.acceleration =
          std::max(r.acceleration, std::abs(v - previous_velocity[j]) / dt / max_acceleration[j]);
      previous_velocity[j] = v;
    }
    if (k < xs.size()) previous = xs[k];
  }
  return r;
}

std::vector<double> scaled(const std::vector<double>& v, double k) {
  std::vector<double> out = v;
  for (double& x : out) x *= k;
  return out;
}

Eigen::Isometry3d synchro_frame() { return edp::make_arm_kinematics(model())->forward(synchro()); }

Eigen::Vector3d position_of(const edp::Instruction& c) {
  return kinematics::from_vector(c.arm, c.set_arm_type).translation();
}

}  // namespace

// ---------------------------------------------------------------------------------------------
// Motion profiles

TEST(MotionProfile, TrapezoidCruisesWhenLongAndIsATriangleWhenShort) {
  // Unit distance, v = 0.5 1/s, a = 1 1/s^2: ramps cover v^2/a = 0.25 < 1 -> cruise.
  const auto long_move = ecp::MotionProfile::fastest(ecp::ProfileShape::trapezoidal, 0.5, 1.0);
  EXPECT_NEAR(long_move.duration(), 1.0 / 0.5 + 0.5 / 1.0, 1e-12);
  EXPECT_NEAR(long_move.cruise_duration(), 1.5, 1e-12);
  EXPECT_NEAR(long_move.peak_velocity(), 0.5, 1e-12);
  EXPECT_NEAR(long_move.velocity(1.0), 0.5, 1e-12);
  // v = 2 1/s, a = 1 1/s^2: v^2/a = 4 > 1 -> triangle with peak sqrt(a) = 1 at t = 1 s.
  const auto short_move = ecp::MotionProfile::fastest(ecp::ProfileShape::trapezoidal, 2.0, 1.0);
  EXPECT_NEAR(short_move.duration(), 2.0, 1e-12);
  EXPECT_EQ(short_move.cruise_duration(), 0.0);
  EXPECT_NEAR(short_move.peak_velocity(), 1.0, 1e-12);
  EXPECT_NEAR(short_move.position(1.0), 0.5, 1e-12);
  for (const auto& p : {long_move, short_move}) {
    EXPECT_EQ(p.position(0.0), 0.0);
    EXPECT_EQ(p.position(p.duration()), 1.0);
    // Continuous position, velocity within the limit, monotonic.
    double previous = 0.0;
    for (int i = 1; i <= 1000; ++i) {
      const double t = p.duration() * i / 1000.0;
      EXPECT_GE(p.position(t), previous - 1e-15);
      EXPECT_LE(p.position(t) - previous, p.peak_velocity() * p.duration() / 1000.0 + 1e-12);
      previous = p.position(t);
    }
  }
}

TEST(MotionProfile, QuinticAndStretchedDurations) {
  const auto q = ecp::MotionProfile::fastest(ecp::ProfileShape::quintic, 1.0, 100.0);
  EXPECT_NEAR(q.duration(), 1.875, 1e-12);  // velocity-bound
  EXPECT_NEAR(q.position(q.duration() / 2), 0.5, 1e-12);
  const auto stretched =
      ecp::MotionProfile::with_duration(ecp::ProfileShape::trapezoidal, 0.5, 1.0, 4.0);
  EXPECT_NEAR(stretched.duration(), 4.0, 1e-12);
  EXPECT_LT(stretched.peak_velocity(), 0.5);
  // Stretched from 2.5 s: velocity times 2.5 / 4, acceleration times its square.
  EXPECT_NEAR(stretched.peak_velocity(), 0.5 * 2.5 / 4.0, 1e-12);
  EXPECT_NEAR(stretched.peak_acceleration(), 2.5 * 2.5 / 16.0, 1e-12);
  EXPECT_NEAR(stretched.cruise_duration(), 1.5 * 4.0 / 2.5, 1e-12);
  EXPECT_NEAR(stretched.position(4.0 - 1e-9), 1.0, 1e-8);
  EXPECT_THROW(ecp::MotionProfile::with_duration(ecp::ProfileShape::quintic, 1.0, 1.0, 1.0), Error);
  EXPECT_THROW(ecp::MotionProfile::fastest(ecp::ProfileShape::quintic, 0.0, 1.0), Error);
}

// ---------------------------------------------------------------------------------------------
// Joint and motor interpolation

class InterpolationProfiles
    : public ::testing::TestWithParam<std::tuple<ArmRepresentation, ecp::ProfileShape>> {};

TEST_P(InterpolationProfiles, RespectLimitsFinishTogetherAndEndExactly) {
  const auto [representation, shape] = GetParam();
  const RobotModel& m = model();
  const auto kin = edp::make_arm_kinematics(m);
  ecp::InterpolationOptions options;
  options.representation = representation;
  options.profile = shape;
  options.velocity_scale = 0.8;
  options.acceleration_scale = 0.6;
  const std::vector<double> goal_joints = {0.4, -1.4, 0.2, 0.3, -0.4};
  const bool motor = representation == ArmRepresentation::motor;
  const std::vector<double> goal = motor ? kin->motors_from_joints(goal_joints) : goal_joints;
  const std::vector<double> start = motor ? kin->motors_from_joints(synchro()) : synchro();

  ecp::InterpolationGenerator g(m, {ecp::Waypoint{goal}}, options);
  const Executed r = run(g, synchro());
  ASSERT_GT(r.commands.size(), 20U);
  const double dt = options.motion_steps * options.servo_period_s;
  const auto xs = arms(r);

  for (const auto& c : r.commands) {
    EXPECT_EQ(c.set_arm_type, representation);
    EXPECT_EQ(c.motion_type, edp::MotionType::absolute);
  }
  EXPECT_EQ(xs.back(), goal) << "final pose not exact";
  for (std::size_t j = 0; j < goal_joints.size(); ++j)
    EXPECT_NEAR(r.joints.back()[j], goal_joints[j], 1e-9);

  // Limits in the interpolated coordinates: the model's (scaled); for motors times the
  // transmission ratio at the start.
  std::vector<double> vmax = scaled(m.max_velocity, options.velocity_scale);
  std::vector<double> amax = scaled(m.max_acceleration, options.acceleration_scale);
  if (motor) {
    for (std::size_t j = 0; j < vmax.size(); ++j) {
      std::vector<double> a = synchro();
      std::vector<double> b = synchro();
      a[j] -= 1e-6;
      b[j] += 1e-6;
      const double ratio =
          std::abs(kin->motors_from_joints(b)[j] - kin->motors_from_joints(a)[j]) / 2e-6;
      vmax[j] *= ratio;
      amax[j] *= ratio;
    }
  }
  const Ratios own = rate_ratios(start, xs, dt, vmax, amax);
  EXPECT_LE(own.velocity, 1.0 + 1e-6);
  EXPECT_LE(own.acceleration, 1.0 + 1e-6);
  EXPECT_GT(own.velocity, 0.3) << "the motion should use a good part of its limits";
  // Whatever the coordinates, the joints stay within the model's limits.
  const Ratios joints = rate_ratios(synchro(), r.joints, dt, m.max_velocity, m.max_acceleration);
  EXPECT_LE(joints.velocity, 1.0 + 1e-9);
  EXPECT_LE(joints.acceleration, 1.0 + 1e-9);

  // Synchronised: every axis has covered the same fraction of its distance at every macro-step.
  for (const auto& x : xs) {
    const double s0 = (x[0] - start[0]) / (goal[0] - start[0]);
    for (std::size_t j = 1; j < x.size(); ++j)
      EXPECT_NEAR((x[j] - start[j]) / (goal[j] - start[j]), s0, 1e-9) << "axis " << j;
  }
  // Seamless macro-steps, the last one read after the stop.
  for (std::size_t k = 0; k + 1 < r.commands.size(); ++k)
    EXPECT_EQ(r.commands[k].value_in_step_no, ecp::early_reading_step(options.motion_steps));
  EXPECT_EQ(r.commands.back().value_in_step_no, options.motion_steps + 1);
}

INSTANTIATE_TEST_SUITE_P(All, InterpolationProfiles,
                         ::testing::Combine(::testing::Values(ArmRepresentation::joint,
                                                              ArmRepresentation::motor),
                                            ::testing::Values(ecp::ProfileShape::trapezoidal,
                                                              ecp::ProfileShape::quintic)));

TEST(Interpolation, TrapezoidCruisesOnLongMovesAndIsATriangleOnShortOnes) {
  const RobotModel& m = model();
  ecp::InterpolationOptions options;
  options.profile = ecp::ProfileShape::trapezoidal;  // column: 0.75 rad/s, 1.5 rad/s^2
  const double dt = options.motion_steps * options.servo_period_s;
  const double vmax = m.max_velocity[0] * options.velocity_scale;

  const auto velocities = [&](double distance) {
    std::vector<double> goal = synchro();
    goal[0] = distance;
    ecp::InterpolationGenerator g(m, {ecp::Waypoint{goal}}, options);
    const Executed r = run(g, synchro());
    std::vector<double> v;
    double previous = 0.0;
    for (const auto& c : r.commands) {
      v.push_back((c.arm[0] - previous) / dt);
      previous = c.arm[0];
    }
    return std::make_pair(v, g.plan().segments.at(0).profile->cruise_duration());
  };

  // 2 rad: ramps of 0.5 s cover 0.375 rad; about 2.2 s at the cruise velocity.
  const auto [long_v, long_cruise] = velocities(2.0);
  const double long_peak = *std::max_element(long_v.begin(), long_v.end());
  EXPECT_LE(long_peak, vmax * (1 + 1e-9));
  EXPECT_GT(long_peak, vmax * 0.99);
  const auto at_cruise = std::count_if(long_v.begin(), long_v.end(),
                                       [&](double v) { return v > long_peak * (1 - 1e-9); });
  EXPECT_GT(at_cruise, 100) << "expected a cruise phase of about 2.2 s";
  EXPECT_GT(long_cruise, 2.0);

  // 0.05 rad: the ramps would need 0.375 rad: a triangle peaking at sqrt(1.5 * 0.05) rad/s.
  const auto [short_v, short_cruise] = velocities(0.05);
  const double short_peak = *std::max_element(short_v.begin(), short_v.end());
  EXPECT_LT(short_peak, std::sqrt(1.5 * 0.05) * 1.0001);
  EXPECT_LT(short_peak, 0.5 * vmax);
  EXPECT_EQ(short_cruise, 0.0) << "rounding to whole macro-steps keeps the triangle";
  const auto near_peak = std::count_if(short_v.begin(), short_v.end(),
                                       [&](double v) { return v > short_peak * 0.97; });
  EXPECT_LE(near_peak, 3);
  // Rises, then falls.
  const auto top = std::max_element(short_v.begin(), short_v.end()) - short_v.begin();
  for (auto k = 1; k <= top; ++k)
    EXPECT_GE(short_v[static_cast<std::size_t>(k)], short_v[static_cast<std::size_t>(k - 1)]);
  for (auto k = top + 1; k < static_cast<long>(short_v.size()); ++k)
    EXPECT_LE(short_v[static_cast<std::size_t>(k)], short_v[static_cast<std::size_t>(k - 1)]);
}

TEST(Interpolation, WaypointsDurationsDwellsAndRelativeMoves) {
  const RobotModel& m = model();
  ecp::InterpolationOptions options;
  const double dt = options.motion_steps * options.servo_period_s;
  const std::vector<double> a = {0.2, -1.5, 0.1, 0.0, 0.3};
  ecp::Waypoint second{a, 0.0, 1.0, false};
  second.duration_s = 1.5;                                           // dwell at `a` for 1.5 s
  ecp::Waypoint back{{-0.2, 0.1, -0.1, 0.0, -0.3}, 0.0, 0.5, true};  // relative, half speed
  ecp::InterpolationGenerator g(m, {ecp::Waypoint{a}, second, back}, options);
  const Executed r = run(g, synchro());
  const ecp::MotionPlan& plan = g.plan();
  ASSERT_EQ(plan.segments.size(), 3U);
  EXPECT_EQ(plan.segments[1].macro_steps, static_cast<std::size_t>(std::ceil(1.5 / dt - 1e-9)));
  EXPECT_FALSE(plan.segments[1].profile.has_value());
  for (std::size_t k = 0; k < plan.segments[1].macro_steps; ++k)
    EXPECT_EQ(r.commands[plan.segments[1].first_macro_step + k].arm, a);
  for (std::size_t j = 0; j < a.size(); ++j)
    EXPECT_NEAR(r.commands.back().arm[j], a[j] + back.position[j], 1e-15);

  // Half speed is the same motion taking twice as long (rounded to macro-steps).
  ecp::InterpolationGenerator full(m, {ecp::Waypoint{{0.0, -1.4, 0.0, 0.0, 0.0}}}, options);
  ecp::InterpolationGenerator half(m, {ecp::Waypoint{{0.0, -1.4, 0.0, 0.0, 0.0}, 0.0, 0.5}},
                                   options);
  const auto t_full = full.plan_from(synchro()).segments[0].profile->duration();
  const auto t_half = half.plan_from(synchro()).segments[0].profile->duration();
  EXPECT_NEAR(t_half, 2 * t_full, dt);

  // An explicit duration is kept (rounded up to whole macro-steps) ...
  ecp::InterpolationGenerator slow(m, {ecp::Waypoint{{0.0, -1.4, 0.0, 0.0, 0.0}, 3.0}}, options);
  EXPECT_NEAR(slow.plan_from(synchro()).duration_s(), 3.0, 1e-9);
  // ... but one shorter than the limits allow is refused.
  ecp::InterpolationGenerator fast(m, {ecp::Waypoint{{0.0, -1.4, 0.0, 0.0, 0.0}, 0.05}}, options);
  try {
    (void)fast.plan_from(synchro());
    FAIL() << "accepted 0.05 s";
  } catch (const CommandError& e) {
    EXPECT_TRUE(contains(e.what(), "segment 1")) << e.what();
    EXPECT_TRUE(contains(e.what(), "duration 0.05 s is shorter")) << e.what();
  }
}

TEST(PlannedMotion, ResumeRejoinsThePlanAtTheEndOfTheInterruptedSegment) {
  // A late macro-step: the EDP's stopping ramp left the robot off the plan, at rest, and the
  // planned continuation was refused. resume() moves the robot from rest to rest back to the end
  // of the segment it was in (JOINT, within half of the limits) and the plan goes on unchanged.
  const RobotModel& m = model();
  ecp::InterpolationOptions options;
  const double dt = options.motion_steps * options.servo_period_s;
  const std::vector<double> a = {0.4, -1.4, 0.1, 0.2, 0.5};
  const std::vector<double> b = {-0.2, -1.6, -0.1, 0.0, 0.0};
  ecp::InterpolationGenerator g(m, {ecp::Waypoint{a}, ecp::Waypoint{b}}, options);
  const ecp::MotionPlan original = g.plan_from(synchro());
  const std::size_t first_segment = original.segments.at(0).macro_steps;
  ASSERT_GT(first_segment, 10U);

  FakeEdp edp;
  ecp::RobotImage image;
  image.desired_joints = synchro();
  image.joints = synchro();
  ASSERT_TRUE(g.first_step(image, {}));
  for (std::size_t k = 0; k < first_segment / 2; ++k) {
    edp.execute(image);
    ASSERT_TRUE(g.next_step(image, {}));
  }
  // The command now waiting was "refused"; the ramp stopped the robot a little past the last
  // target it reached.
  std::vector<double> stopped = image.desired_joints;
  for (std::size_t j = 0; j < stopped.size(); ++j)
    stopped[j] += 0.5 * image.joint_velocities[j] * dt;
  image.desired_joints = stopped;
  image.joints = stopped;
  image.joint_velocities.assign(stopped.size(), 0.0);
  ASSERT_TRUE(g.resume(image, {}));

  // The move back: every command up to the one whose target is the segment's end, `a`.
  std::vector<edp::Instruction> commands;
  std::vector<std::vector<double>> rejoin;
  bool rejoining = true;
  bool more = true;
  while (more) {
    commands.push_back(image.command);
    edp.execute(image);
    if (rejoining) rejoin.push_back(image.desired_joints);
    rejoining = rejoining && commands.back().arm != a;
    more = g.next_step(image, {});
  }
  ASSERT_GE(rejoin.size(), 2U) << "a rest-to-rest move of at least two macro-steps";
  EXPECT_EQ(rejoin.back(), a) << "back exactly at the end of the interrupted segment";
  const Ratios r = rate_ratios(stopped, rejoin, dt, m.max_velocity, m.max_acceleration);
  EXPECT_LE(r.velocity, 0.5 + 1e-9);
  EXPECT_LE(r.acceleration, 0.5 + 1e-9) << "quintic within half the limits";
  std::printf("rejoin: %zu macro-steps, velocity %.3f and acceleration %.3f of the limits\n",
              rejoin.size(), r.velocity, r.acceleration);
  // The second segment as planned, target by target.
  ASSERT_EQ(commands.size() - rejoin.size(), original.size() - first_segment);
  for (std::size_t k = rejoin.size(); k < commands.size(); ++k)
    EXPECT_EQ(commands[k].arm, original.targets[first_segment + k - rejoin.size()]);
  EXPECT_EQ(image.desired_joints, b);
  EXPECT_EQ(commands.back().value_in_step_no, options.motion_steps + 1) << "the last reads at rest";

  // Nothing sent yet, or everything sent: nothing to resume.
  ecp::InterpolationGenerator fresh(m, {ecp::Waypoint{a}}, options);
  ecp::RobotImage idle;
  idle.desired_joints = synchro();
  EXPECT_FALSE(fresh.resume(idle, {}));
  EXPECT_FALSE(g.resume(image, {}));
}

TEST(Interpolation, RefusesTargetsAndPathsOutsideTheLimitsBeforeMoving) {
  const RobotModel& m = model();
  try {
    ecp::InterpolationGenerator g(m, ecp::to_waypoints({synchro(), {0.0, -0.5, 0.0, 0.0, 0.0}}));
    FAIL() << "accepted lower arm at -0.5 rad";
  } catch (const CommandError& e) {
    EXPECT_EQ(e.code(), edp::error_code::out_of_limits);
    EXPECT_TRUE(contains(e.what(), "joint 1 (lower_arm) waypoint 2 -0.500000 rad exceeds upper"))
        << e.what();
  }
  EXPECT_THROW(ecp::InterpolationGenerator(m, ecp::to_waypoints({{0.0, -1.5}})), CommandError);
  EXPECT_THROW(ecp::InterpolationGenerator(m, ecp::to_waypoints({{0.0, -1.5, NAN, 0.0, 0.0}})),
               CommandError);
  ecp::InterpolationOptions bad;
  bad.representation = ArmRepresentation::frame;
  EXPECT_THROW(ecp::InterpolationGenerator(m, {}, bad), Error);
  bad = {};
  bad.motion_steps = 1;
  EXPECT_THROW(ecp::InterpolationGenerator(m, {}, bad), Error);
  bad = {};
  bad.max_velocity = {1.0, 1.0};
  EXPECT_THROW(ecp::InterpolationGenerator(m, {}, bad), Error);

  // Both ends inside the joint limits, but the upper arm's motor leaves its range on the way
  // (q1 = -1.2 with q2 = 0.3): refused in first_step, nothing commanded.
  ecp::InterpolationGenerator g(m, ecp::to_waypoints({{0.0, -1.2, 0.3, 0.0, 0.0}}));
  ecp::RobotImage image;
  image.desired_joints = synchro();
  try {
    (void)g.first_step(image, {});
    FAIL() << "accepted a path outside the motor range";
  } catch (const CommandError& e) {
    EXPECT_EQ(e.code(), edp::error_code::out_of_limits);
    const std::string text = e.what();
    EXPECT_TRUE(contains(text, "JOINT interpolation, segment 1 (to waypoint 1): macro-step "))
        << text;
    EXPECT_TRUE(contains(text, "motor 2 (upper_arm)")) << text;
  }
  EXPECT_EQ(image.command.type, edp::InstructionType::query) << "a command was prepared";

  // A relative waypoint is checked once the start is known.
  ecp::InterpolationGenerator relative(m, {ecp::Waypoint{{0.0, 0.0, 0.0, 0.0, 3.5}, 0, 1, true}});
  try {
    (void)relative.plan_from(synchro());
    FAIL();
  } catch (const CommandError& e) {
    EXPECT_TRUE(contains(e.what(), "joint 4 (wrist_roll)")) << e.what();
  }
}

TEST(Interpolation, MotorCoordinatesKeepTheCoupledJointsWithinTheirLimits) {
  // Moving the lower-arm motor alone turns the lower arm and, through the upper-arm linkage,
  // the upper arm the other way; at full scale the derived motor limits would let the joints
  // run too fast, so the generator slows the motion down.
  const RobotModel& m = model();
  const auto kin = edp::make_arm_kinematics(m);
  ecp::InterpolationOptions options;
  options.representation = ArmRepresentation::motor;
  options.velocity_scale = 1.0;
  options.acceleration_scale = 1.0;
  options.profile = ecp::ProfileShape::trapezoidal;
  std::vector<double> goal = kin->motors_from_joints(synchro());
  goal[1] += 60.0;
  ecp::InterpolationGenerator g(m, {ecp::Waypoint{goal}}, options);
  const Executed r = run(g, synchro());
  const double dt = options.motion_steps * options.servo_period_s;
  const Ratios joints = rate_ratios(synchro(), r.joints, dt, m.max_velocity, m.max_acceleration);
  EXPECT_LE(joints.velocity, 1.0 + 1e-9);
  EXPECT_LE(joints.acceleration, 1.0 + 1e-9);
  EXPECT_GT(std::max(joints.velocity, joints.acceleration), 0.9) << "needlessly slow";
  EXPECT_EQ(r.commands.back().arm, goal);

  // Explicit motor limits [rad/s, rad/s^2] are used as given.
  options.max_velocity = {50, 50, 50, 50, 50};
  options.max_acceleration = {100, 100, 100, 100, 100};
  ecp::InterpolationGenerator slow(m, {ecp::Waypoint{goal}}, options);
  const Executed rs = run(slow, synchro());
  const Ratios motors = rate_ratios(kin->motors_from_joints(synchro()), arms(rs), dt,
                                    options.max_velocity, options.max_acceleration);
  EXPECT_LE(motors.velocity, 1.0 + 1e-9);
  EXPECT_GT(motors.velocity, 0.99);
}

// ---------------------------------------------------------------------------------------------
// Cartesian paths

TEST(CartesianPath, LineStaysOnTheSegmentWithSlerpedOrientation) {
  const RobotModel& m = model();
  const Eigen::Isometry3d start = synchro_frame();
  Eigen::Isometry3d end = start;
  end.translation() += Eigen::Vector3d(-0.1, 0.0, -0.1);
  // Pitch about the base y axis (the wrist-pitch axis at q0 = 0): reachable for 5 axes.
  end.linear() = Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitY()) * start.linear();
  ecp::CartesianOptions options;
  options.profile = ecp::ProfileShape::trapezoidal;
  ecp::CartesianPathGenerator g(m, {ecp::CartesianSegment::line_to(end)}, options);
  const Executed r = run(g, synchro());
  ASSERT_GT(r.commands.size(), 20U);

  // The first command also sets the tool and kinematic model the path was checked with.
  EXPECT_NE(r.commands[0].set & edp::item::tool, 0);
  EXPECT_NE(r.commands[0].set & edp::item::model, 0);
  EXPECT_EQ(r.commands[1].set, edp::item::arm);

  const Eigen::Vector3d p0 = start.translation();
  const Eigen::Vector3d p1 = end.translation();
  const double length = (p1 - p0).norm();
  const Eigen::Quaterniond q0(start.linear());
  const Eigen::Quaterniond q1(end.linear());
  const double dt = options.motion_steps * options.servo_period_s;
  double previous_s = 0.0;
  double previous_speed = 0.0;
  for (std::size_t k = 0; k < r.commands.size(); ++k) {
    const auto& c = r.commands[k];
    EXPECT_EQ(c.set_arm_type, ArmRepresentation::frame);
    const Eigen::Isometry3d f = kinematics::from_vector(c.arm, c.set_arm_type);
    const Eigen::Vector3d p = f.translation();
    const double s = (p - p0).dot(p1 - p0) / (length * length);
    const Eigen::Vector3d on_line = p0 + s * (p1 - p0);
    EXPECT_LT((p - on_line).norm(), 1e-9) << "macro-step " << k;
    EXPECT_GE(s, previous_s - 1e-12);
    EXPECT_LE(s, 1.0 + 1e-12);
    const Eigen::Matrix3d expected = q0.slerp(s, q1).toRotationMatrix();
    EXPECT_LT(kinematics::rotation_distance(f.linear(), expected), 1e-9) << "macro-step " << k;
    const double speed = (s - previous_s) * length / dt;
    EXPECT_LE(speed, options.max_linear_velocity * (1 + 1e-9));
    EXPECT_LE(std::abs(speed - previous_speed) / dt, options.max_linear_acceleration * (1 + 1e-9));
    EXPECT_LE((s - previous_s) * 0.3 / dt, options.max_angular_velocity * (1 + 1e-9));
    previous_s = s;
    previous_speed = speed;
  }
  EXPECT_EQ(r.commands.back().arm, kinematics::to_vector(end, ArmRepresentation::frame));
  EXPECT_GT(previous_speed, 0.0);
  EXPECT_LE(previous_speed / dt, options.max_linear_acceleration * (1 + 1e-9));  // to rest

  // The fake EDP's inverse kinematics (seeded like the EDP's) gives the generator's joints, and
  // they respect the joint velocity and acceleration limits.
  ASSERT_EQ(g.plan().joints.size(), r.joints.size());
  for (std::size_t k = 0; k < r.joints.size(); ++k)
    for (std::size_t j = 0; j < 5; ++j) EXPECT_NEAR(g.plan().joints[k][j], r.joints[k][j], 1e-12);
  const Ratios joints = rate_ratios(synchro(), r.joints, dt, m.max_velocity, m.max_acceleration);
  EXPECT_LE(joints.velocity, 1.0);
  EXPECT_LE(joints.acceleration, 1.0);
}

TEST(CartesianPath, OtherRepresentationsAndLineBy) {
  const RobotModel& m = model();
  ecp::CartesianOptions options;
  options.representation = ArmRepresentation::xyz_angle_axis;
  options.set_tool_and_model = false;
  ecp::CartesianPathGenerator g(m,
                                {ecp::CartesianSegment::line_by({0.0, 0.0, -0.05}),
                                 ecp::CartesianSegment::line_by({-0.05, 0.0, 0.0})},
                                options);
  const Executed r = run(g, synchro());
  EXPECT_EQ(r.commands[0].set, edp::item::arm);
  EXPECT_EQ(g.plan().segments.size(), 2U);
  const Eigen::Isometry3d start = synchro_frame();
  const Eigen::Isometry3d last =
      kinematics::from_vector(r.commands.back().arm, ArmRepresentation::xyz_angle_axis);
  EXPECT_LT((last.translation() - (start.translation() + Eigen::Vector3d(-0.05, 0, -0.05))).norm(),
            1e-12);
  EXPECT_LT(kinematics::rotation_distance(last.linear(), start.linear()), 1e-12);
}

TEST(CartesianPath, ThreePointArcStaysOnItsCircle) {
  const RobotModel& m = model();
  const Eigen::Isometry3d start = synchro_frame();
  // A circle of radius 0.1 m in the arm plane (x-z) with its centre 0.1 m behind the flange;
  // from the start (angle 0) through -45 deg to -90 deg (downwards).
  const double radius = 0.1;
  const Eigen::Vector3d centre = start.translation() + Eigen::Vector3d(-radius, 0.0, 0.0);
  const auto on_circle = [&](double angle) {
    return Eigen::Vector3d(centre + radius * Eigen::Vector3d(std::cos(angle), 0, std::sin(angle)));
  };
  Eigen::Isometry3d end = start;
  end.translation() = on_circle(-std::numbers::pi / 2);
  end.linear() = Eigen::AngleAxisd(0.2, Eigen::Vector3d::UnitY()) * start.linear();

  const ecp::CircleArc arc =
      ecp::CircleArc::through(start.translation(), on_circle(-0.7), end.translation());
  EXPECT_LT((arc.centre - centre).norm(), 1e-12);
  EXPECT_NEAR(arc.radius, radius, 1e-12);
  EXPECT_NEAR(arc.angle, std::numbers::pi / 2, 1e-12);

  ecp::CartesianPathGenerator g(m, {ecp::CartesianSegment::arc_through(on_circle(-0.7), end)},
                                ecp::CartesianOptions{});
  const Executed r = run(g, synchro());
  ASSERT_GT(r.commands.size(), 20U);
  double previous_angle = 0.0;
  for (std::size_t k = 0; k < r.commands.size(); ++k) {
    const Eigen::Vector3d p = position_of(r.commands[k]);
    EXPECT_NEAR((p - centre).norm(), radius, 1e-9) << "macro-step " << k;
    EXPECT_NEAR(p.y(), 0.0, 1e-9);
    const double angle = std::atan2(p.z() - centre.z(), p.x() - centre.x());
    EXPECT_LE(angle, previous_angle + 1e-12) << "not monotonic at macro-step " << k;
    EXPECT_GE(angle, -std::numbers::pi / 2 - 1e-9);
    previous_angle = angle;
  }
  EXPECT_EQ(r.commands.back().arm, kinematics::to_vector(end, ArmRepresentation::frame));

  EXPECT_THROW((void)ecp::CircleArc::through({0, 0, 0}, {1, 0, 0}, {2, 0, 0}), CommandError);
  ecp::CartesianPathGenerator collinear(
      m,
      {ecp::CartesianSegment::arc_through(start.translation() + Eigen::Vector3d(-0.1, 0, 0),
                                          Eigen::Isometry3d(Eigen::Translation3d(
                                              start.translation() + Eigen::Vector3d(-0.2, 0, 0))) *
                                              Eigen::Isometry3d(start.linear()))});
  try {
    (void)collinear.plan_from(synchro());
    FAIL();
  } catch (const CommandError& e) {
    EXPECT_TRUE(contains(e.what(), "segment 1 (three-point arc)")) << e.what();
    EXPECT_TRUE(contains(e.what(), "collinear")) << e.what();
  }
}

TEST(CartesianPath, ArcAboutTheColumnAxisTurnsOnlyTheColumn) {
  const RobotModel& m = model();
  ecp::CartesianOptions options;
  options.profile = ecp::ProfileShape::trapezoidal;
  ecp::CartesianPathGenerator g(
      m, {ecp::CartesianSegment::arc_about({0, 0, 0}, {0, 0, 1}, 0.4, true)}, options);
  const Executed r = run(g, synchro());
  ASSERT_GT(r.commands.size(), 10U);
  const Eigen::Vector3d p0 = synchro_frame().translation();
  for (std::size_t k = 0; k < r.commands.size(); ++k) {
    const Eigen::Vector3d p = position_of(r.commands[k]);
    EXPECT_NEAR(std::hypot(p.x(), p.y()), p0.x(), 1e-9);
    EXPECT_NEAR(p.z(), p0.z(), 1e-9);
    for (std::size_t j = 1; j < 5; ++j)
      EXPECT_NEAR(r.joints[k][j], synchro()[j], 1e-9) << "macro-step " << k << " joint " << j;
  }
  EXPECT_NEAR(r.joints.back()[0], 0.4, 1e-9);
  // Linear speed on the circle and angular speed both within their limits.
  const double dt = options.motion_steps * options.servo_period_s;
  double previous = 0.0;
  for (const auto& q : r.joints) {
    EXPECT_LE((q[0] - previous) / dt * p0.x(), options.max_linear_velocity * (1 + 1e-9));
    EXPECT_LE((q[0] - previous) / dt, options.max_angular_velocity * (1 + 1e-9));
    previous = q[0];
  }

  // Without turning the orientation the approach leaves the arm plane: refused at once.
  ecp::CartesianPathGenerator fixed(
      m, {ecp::CartesianSegment::arc_about({0, 0, 0}, {0, 0, 1}, 0.4, false)});
  try {
    (void)fixed.plan_from(synchro());
    FAIL();
  } catch (const CommandError& e) {
    EXPECT_TRUE(contains(e.what(), "segment 1 (arc about an axis): macro-step ")) << e.what();
    EXPECT_TRUE(contains(e.what(), "orientation not reachable by a 5-axis arm")) << e.what();
  }
  EXPECT_THROW(
      ecp::CartesianPathGenerator(m, {ecp::CartesianSegment::arc_about({0, 0, 0}, {0, 0, 0}, 0.4)}),
      CommandError);
}

TEST(CartesianPath, RefusesUnreachableAndLimitViolatingPathsBeforeTheFirstCommand) {
  const RobotModel& m = model();
  const Eigen::Isometry3d start = synchro_frame();
  struct Case {
    const char* name;
    ecp::CartesianSegment segment;
    ecp::CartesianOptions options;
    std::vector<std::string> expected;  // parts of the message
  };
  std::vector<Case> cases;
  {  // sideways: the approach would leave the arm plane at once
    Eigen::Isometry3d end = start;
    end.translation() += Eigen::Vector3d(0.0, 0.1, 0.0);
    cases.push_back({"sideways",
                     ecp::CartesianSegment::line_to(end),
                     {},
                     {"segment 1 (line): macro-step 1 of ", "orientation not reachable"}});
  }
  {  // up: the upper arm leaves its joint limit on the way
    Eigen::Isometry3d end = start;
    end.translation() += Eigen::Vector3d(0.0, 0.0, 0.3);
    cases.push_back({"up",
                     ecp::CartesianSegment::line_to(end),
                     {},
                     {"segment 1 (line): macro-step 182 of 282",
                      "joint 2 (upper_arm) inverse kinematics solution -0.43",
                      "is below lower limit -0.436332 rad"}});
  }
  {  // towards the column: the lower-arm motor leaves its range between two targets
    Eigen::Isometry3d end = start;
    end.translation() += Eigen::Vector3d(-0.4, 0.0, 0.0);
    cases.push_back({"in",
                     ecp::CartesianSegment::line_to(end),
                     {},
                     {"segment 1 (line): macro-step 223 of 375", "motor 1 (lower_arm) servo step",
                      "is below lower limit -110.0 rad"}});
  }
  {  // a fast pitch of the tool about its own origin: the arm must swing too fast
    Eigen::Isometry3d end = start;
    end.linear() = Eigen::AngleAxisd(0.5, Eigen::Vector3d::UnitY()) * start.linear();
    ecp::CartesianOptions fast;
    fast.max_angular_velocity = 10.0;
    fast.max_angular_acceleration = 100.0;
    cases.push_back({"fast pitch",
                     ecp::CartesianSegment::line_to(end),
                     fast,
                     {"segment 1 (line): macro-step 1 of 9: joint 2 (upper_arm) acceleration",
                      "exceeds the limit 2.000000 rad/s^2"}});
    ecp::CartesianOptions slow_joints;
    slow_joints.joint_velocity_scale = 0.05;
    cases.push_back({"pitch, joint velocity",
                     ecp::CartesianSegment::line_to(end),
                     slow_joints,
                     {"segment 1 (line): macro-step 11 of 94: joint 3 (wrist_pitch) velocity 0.10",
                      "rad/s exceeds the limit 0.100000 rad/s"}});
  }
  for (const Case& c : cases) {
    ecp::CartesianPathGenerator g(m, {c.segment}, c.options);
    ecp::RobotImage image;
    image.desired_joints = synchro();
    try {
      (void)g.first_step(image, {});
      ADD_FAILURE() << c.name << ": accepted";
    } catch (const CommandError& e) {
      EXPECT_EQ(e.code(), edp::error_code::out_of_limits) << c.name;
      for (const auto& part : c.expected)
        EXPECT_TRUE(contains(e.what(), part)) << c.name << ": '" << part << "' not in\n"
                                              << e.what();
    }
    EXPECT_EQ(image.command.type, edp::InstructionType::query) << c.name << ": commanded";
  }
}

TEST(CartesianPath, RefusesBadArguments) {
  const RobotModel& m = model();
  ecp::CartesianOptions bad;
  bad.max_linear_velocity = 0.0;
  EXPECT_THROW(ecp::CartesianPathGenerator(m, {}, bad), Error);
  bad = {};
  bad.representation = ArmRepresentation::joint;
  EXPECT_THROW(ecp::CartesianPathGenerator(m, {}, bad), Error);
  bad = {};
  bad.corrector_no = 7;
  EXPECT_THROW(ecp::CartesianPathGenerator(m, {}, bad), CommandError);
  auto segment = ecp::CartesianSegment::line_by({0, 0, -0.01});
  segment.velocity_scale = 2.0;
  EXPECT_THROW(ecp::CartesianPathGenerator(m, {segment}), CommandError);
  Eigen::Isometry3d skewed = synchro_frame();
  skewed.linear()(0, 0) = 0.5;
  EXPECT_THROW(ecp::CartesianPathGenerator(m, {ecp::CartesianSegment::line_to(skewed)}),
               CommandError);
  ecp::CartesianPathGenerator nothing(m, {ecp::CartesianSegment::line_by({0, 0, 0})});
  EXPECT_TRUE(run(nothing, synchro()).commands.empty());
}

// ---------------------------------------------------------------------------------------------
// Guarded moves

TEST(GuardedMove, JointMoveStopsWithinOneMacroStepOfTheCondition) {
  const RobotModel& m = model();
  const ecp::GuardedMotion motion{0.1, 0.5, 0.3};  // rad/s, rad/s^2, rad
  ecp::InterpolationOptions options;
  const double dt = options.motion_steps * options.servo_period_s;
  const double contact = 0.12;  // rad of the column
  const std::vector<double>* seen = nullptr;
  auto g = ecp::GuardedMoveGenerator::along_axes(
      m, {2.0, 0.0, 0.0, 0.0, 0.0}, motion,
      [&] { return seen != nullptr && (*seen)[0] >= contact; }, options);
  ecp::RobotImage last;
  const Executed r = run(g, synchro(), [&](const ecp::RobotImage& image) {
    last = image;
    seen = &last.desired_joints;
  });
  EXPECT_TRUE(g.condition_met());
  ASSERT_GE(r.joints.size(), 2U);
  const double final_q = r.joints.back()[0];
  const double before = r.joints[r.joints.size() - 2][0];
  EXPECT_GE(final_q, contact);
  EXPECT_LT(before, contact);
  EXPECT_LE(final_q - contact, motion.speed * dt * (1 + 1e-9)) << "more than one macro-step late";
  EXPECT_NEAR(g.distance(), final_q, 1e-12);
  for (const auto& q : r.joints)
    for (std::size_t j = 1; j < 5; ++j) EXPECT_EQ(q[j], synchro()[j]);
  // The speed along the direction stays within the guarded speed.
  double previous = 0.0;
  for (const auto& q : r.joints) {
    EXPECT_LE((q[0] - previous) / dt, motion.speed * (1 + 1e-9));
    previous = q[0];
  }
}

TEST(GuardedMove, ARobotConditionReadsTheImageOfTheMacroStepJustDone) {
  // The column's commanded position passing 0.12 rad ends the move: the condition reads it from
  // the robot image the generator hands it, not from a copy the test keeps.
  class ColumnPast : public ecp::RobotCondition {
   public:
    explicit ColumnPast(double q) : q_(q) {}
    bool holds(const ecp::RobotImage& robot, const ecp::SensorList&) override {
      ++checks;
      return !robot.desired_joints.empty() && robot.desired_joints[0] >= q_;
    }
    int checks = 0;

   private:
    double q_;
  };
  const RobotModel& m = model();
  const ecp::GuardedMotion motion{0.1, 0.5, 0.3};  // rad/s, rad/s^2, rad
  ColumnPast past(0.12);
  auto g = ecp::GuardedMoveGenerator::along_axes(m, {1.0, 0.0, 0.0, 0.0, 0.0}, motion, past);
  const Executed r = run(g, synchro());
  EXPECT_TRUE(g.condition_met());
  ASSERT_GE(r.joints.size(), 2U);
  EXPECT_GE(r.joints.back()[0], 0.12);
  EXPECT_LT(r.joints[r.joints.size() - 2][0], 0.12);
  // Checked before the first command and after every macro-step.
  EXPECT_EQ(past.checks, static_cast<int>(r.joints.size()) + 1);
  // Without the robot image it cannot decide, and says so.
  EXPECT_THROW((void)past.check({}), mrroc::Error);
}

TEST(GuardedMove, StopsRightAfterTheMacroStepInWhichTheConditionBecameTrue) {
  const RobotModel& m = model();
  for (const std::size_t true_after : {1U, 7U, 20U}) {
    std::size_t executed = 0;
    auto g = ecp::GuardedMoveGenerator::along_axes(m, {0, 0, 0, 1, 0}, {0.2, 1.0, 0.5},
                                                   [&] { return executed >= true_after; });
    const Executed r = run(g, synchro(), [&](const ecp::RobotImage&) { ++executed; });
    EXPECT_EQ(r.commands.size(), true_after);
    EXPECT_TRUE(g.condition_met());
  }
  // Already true: nothing moves.
  auto g = ecp::GuardedMoveGenerator::along_axes(m, {0, 0, 0, 1, 0}, {}, [] { return true; });
  EXPECT_TRUE(run(g, synchro()).commands.empty());
  EXPECT_TRUE(g.condition_met());
}

TEST(GuardedMove, ThrowsWhenTheDistanceRunsOut) {
  const RobotModel& m = model();
  const ecp::GuardedMotion motion{0.05, 0.5, 0.02};
  auto g = ecp::GuardedMoveGenerator::along_axes(m, {0, 0, -1, 0, 0}, motion, [] { return false; });
  std::size_t commands = 0;
  try {
    (void)run(g, synchro(), [&](const ecp::RobotImage&) { ++commands; });
    FAIL() << "no error at the end of the distance";
  } catch (const ecp::GuardedMoveExhausted& e) {
    EXPECT_NEAR(e.distance(), 0.02, 1e-12);
    EXPECT_TRUE(contains(e.what(), "the maximum distance 0.02 rad")) << e.what();
  }
  EXPECT_FALSE(g.condition_met());
  EXPECT_EQ(commands, g.plan().size());
  EXPECT_NEAR(g.plan().joints.back()[2], -0.02, 1e-15);

  // The path to the maximum distance is checked before the first command.
  auto far = ecp::GuardedMoveGenerator::along_axes(m, {0, 0, -1, 0, 0}, {0.05, 0.5, 1.0},
                                                   [] { return false; });
  ecp::RobotImage image;
  image.desired_joints = synchro();
  EXPECT_THROW((void)far.first_step(image, {}), CommandError);
  EXPECT_EQ(image.command.type, edp::InstructionType::query);
  EXPECT_THROW(ecp::GuardedMoveGenerator::along_axes(m, {0, 0, 0, 0, 0}, {}, [] { return false; }),
               CommandError);
  EXPECT_THROW(
      ecp::GuardedMoveGenerator::along_axes(m, {1, 0, 0, 0, 0}, {0, 1, 1}, [] { return false; }),
      Error);
  EXPECT_THROW(
      ecp::GuardedMoveGenerator::along_axes(m, {1, 0, 0, 0, 0}, {}, std::function<bool()>{}),
      Error);
}

TEST(GuardedMove, CartesianMoveDownUntilASensorThreshold) {
  const RobotModel& m = model();
  const double z0 = synchro_frame().translation().z();
  double z = z0;
  // A contact sensor: the tool touches a surface 25 mm below the start.
  ecp::SensorThresholdCondition contact([&] { return z0 - z; }, 0.025);
  const ecp::GuardedMotion motion{0.02, 0.2, 0.1};  // m/s, m/s^2, m
  ecp::CartesianOptions options;
  const double dt = options.motion_steps * options.servo_period_s;
  auto g = ecp::GuardedMoveGenerator::along_line(m, {0, 0, -3}, motion, contact, options);
  const auto kin = edp::make_arm_kinematics(m);
  const Executed r = run(g, synchro(), [&](const ecp::RobotImage& image) {
    z = kin->forward(image.desired_joints).translation().z();
  });
  EXPECT_TRUE(g.condition_met());
  const double depth = z0 - position_of(r.commands.back()).z();
  EXPECT_GE(depth, 0.025 - 1e-12);
  EXPECT_LE(depth - 0.025, motion.speed * dt * (1 + 1e-9));
  EXPECT_NEAR(g.distance(), depth, 1e-12);
  for (const auto& c : r.commands) {
    const Eigen::Vector3d p = position_of(c);
    EXPECT_NEAR(p.x(), synchro_frame().translation().x(), 1e-12);
    EXPECT_NEAR(p.y(), 0.0, 1e-12);
  }

  // Never touching: the move ends at 0.1 m with the error.
  z = z0;
  ecp::SensorThresholdCondition never([] { return 0.0; }, 1.0);
  auto g2 = ecp::GuardedMoveGenerator::along_line(m, {0, 0, -1}, motion, never, options);
  EXPECT_THROW((void)run(g2, synchro()), ecp::GuardedMoveExhausted);
  EXPECT_NEAR(g2.distance(), 0.1, 1e-12);
}

// ---------------------------------------------------------------------------------------------
// Pass-through

namespace {
edp::Instruction joint_pose(std::vector<double> q, int steps = 10) {
  edp::Instruction in;
  in.type = edp::InstructionType::set;
  in.set = edp::item::arm;
  in.set_arm_type = ArmRepresentation::joint;
  in.motion_steps = steps;
  in.value_in_step_no = steps - 1;
  in.arm = std::move(q);
  return in;
}

void expect_same(const edp::Instruction& a, const edp::Instruction& b) {
  EXPECT_EQ(a.type, b.type);
  EXPECT_EQ(a.set, b.set);
  EXPECT_EQ(a.get, b.get);
  EXPECT_EQ(a.set_arm_type, b.set_arm_type);
  EXPECT_EQ(a.get_arm_type, b.get_arm_type);
  EXPECT_EQ(a.motion_type, b.motion_type);
  EXPECT_EQ(a.motion_steps, b.motion_steps);
  EXPECT_EQ(a.value_in_step_no, b.value_in_step_no);
  EXPECT_EQ(a.arm, b.arm);
  EXPECT_EQ(a.tool, b.tool);
}
}  // namespace

TEST(PassThrough, ForwardsExactlyWhatItIsGiven) {
  const RobotModel& m = model();
  std::vector<edp::Instruction> poses;
  for (int k = 1; k <= 30; ++k) {
    std::vector<double> q = synchro();
    q[0] = 0.003 * k;
    q[4] = -0.002 * k;
    poses.push_back(joint_pose(q, 8));
  }
  poses.back().value_in_step_no = 9;
  edp::Instruction frame = joint_pose({});
  frame.type = edp::InstructionType::set_get;
  frame.get = edp::item::arm;
  frame.set_arm_type = ArmRepresentation::frame;
  {
    std::vector<double> q = synchro();
    q[0] = 0.1;
    const auto f =
        kinematics::to_vector(edp::make_arm_kinematics(m)->forward(q), ArmRepresentation::frame);
    frame.arm.assign(f.begin(), f.end());
  }
  poses.push_back(frame);
  edp::Instruction relative = joint_pose({0.0, 0.0, 0.0, 0.0, 0.01});
  relative.motion_type = edp::MotionType::relative;
  poses.push_back(relative);

  std::size_t next = 0;
  ecp::PassThroughGenerator g(m, [&]() -> std::optional<edp::Instruction> {
    if (next == poses.size()) return std::nullopt;
    return poses[next++];
  });
  const Executed r = run(g, synchro());
  ASSERT_EQ(r.commands.size(), poses.size());
  for (std::size_t k = 0; k < poses.size(); ++k) expect_same(r.commands[k], poses[k]);
  EXPECT_EQ(g.forwarded(), poses.size());
}

TEST(PassThrough, RefusesMalformedPoses) {
  const RobotModel& m = model();
  struct Case {
    const char* name;
    std::function<void(edp::Instruction&)> spoil;
    const char* expected;
  };
  const std::vector<Case> cases = {
      {"short", [](auto& in) { in.arm.pop_back(); }, "JOINT arm has 4 values, 5 expected"},
      {"nan", [](auto& in) { in.arm[2] = NAN; }, "JOINT arm value 2 is not a finite number"},
      {"get", [](auto& in) { in.type = edp::InstructionType::get; },
       "instruction type GET is not SET or SET_GET"},
      {"no arm", [](auto& in) { in.set = edp::item::tool; }, "does not set the arm"},
      {"steps", [](auto& in) { in.motion_steps = 0; }, "motion_steps 0 is outside 1..100000"},
      {"value_in_step_no", [](auto& in) { in.value_in_step_no = 12; },
       "value_in_step_no 12 is outside 1..11"},
      {"representation", [](auto& in) { in.set_arm_type = ArmRepresentation::motor; },
       "MOTOR is not accepted here"},
      {"limit", [](auto& in) { in.arm[1] = -0.5; }, "joint 1 (lower_arm) target -0.500000 rad"},
      {"frame size",
       [](auto& in) {
         in.set_arm_type = ArmRepresentation::frame;
         in.arm.assign(11, 0.0);
       },
       "FRAME arm has 11 values, 12 expected"},
  };
  for (const Case& c : cases) {
    std::vector<edp::Instruction> poses = {joint_pose(synchro()), joint_pose(synchro())};
    c.spoil(poses[1]);
    std::size_t next = 0;
    ecp::PassThroughOptions options;
    options.representations = {ArmRepresentation::joint, ArmRepresentation::frame};
    ecp::PassThroughGenerator g(
        m,
        [&]() -> std::optional<edp::Instruction> {
          if (next == poses.size()) return std::nullopt;
          return poses[next++];
        },
        options);
    std::size_t executed = 0;
    try {
      (void)run(g, synchro(), [&](const ecp::RobotImage&) { ++executed; });
      ADD_FAILURE() << c.name << ": accepted";
    } catch (const CommandError& e) {
      EXPECT_TRUE(contains(e.what(), "pass-through pose 2: ")) << c.name << ": " << e.what();
      EXPECT_TRUE(contains(e.what(), c.expected)) << c.name << ": " << e.what();
    }
    EXPECT_EQ(executed, 1U) << c.name;
  }
}

TEST(PassThrough, QueueFromAnotherThread) {
  const RobotModel& m = model();
  ecp::InstructionQueue queue;
  std::vector<edp::Instruction> poses;
  for (int k = 1; k <= 50; ++k) {
    std::vector<double> q = synchro();
    q[3] = 0.002 * k;
    poses.push_back(joint_pose(q));
  }
  std::thread producer([&] {
    for (const auto& p : poses) {
      queue.push(p);
      std::this_thread::sleep_for(std::chrono::microseconds(200));
    }
    queue.close();
  });
  ecp::PassThroughGenerator g(m, queue, std::chrono::milliseconds(2000));
  const Executed r = run(g, synchro());
  producer.join();
  ASSERT_EQ(r.commands.size(), poses.size());
  for (std::size_t k = 0; k < poses.size(); ++k) expect_same(r.commands[k], poses[k]);
  EXPECT_THROW(queue.push(poses[0]), Error);

  // A producer that falls behind: TimeoutError.
  ecp::InstructionQueue slow;
  ecp::PassThroughGenerator waiting(m, slow, std::chrono::milliseconds(20));
  ecp::RobotImage image;
  image.desired_joints = synchro();
  EXPECT_THROW((void)waiting.first_step(image, {}), TimeoutError);
}
