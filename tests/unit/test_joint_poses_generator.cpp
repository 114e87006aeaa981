// The stock joint-poses generator: reaches every pose exactly, respects velocity and acceleration
// limits, starts and stops smoothly, uses the paper's value_in_step_no pattern, and refuses poses
// outside the limits before anything moves.
#include <gtest/gtest.h>

#include <cmath>

#include "mrroc/core/error.hpp"
#include "mrroc/ecp/generators/joint_poses.hpp"
#include "mrroc/robot/robot_model.hpp"

using namespace mrroc;

namespace {

struct Plan {
  std::vector<std::vector<double>> targets;  // one per macro-step
  std::vector<int> value_in_step_no;
};

/// Runs the generator as Move would, with an EDP that reaches every target exactly.
Plan run(ecp::JointPosesGenerator& g, std::vector<double> start) {
  ecp::RobotImage image;
  image.desired_joints = std::move(start);
  Plan plan;
  if (!g.first_step(image, {})) return plan;
  do {
    EXPECT_EQ(image.command.type, edp::InstructionType::set);
    EXPECT_EQ(image.command.set_arm_type, edp::ArmRepresentation::joint);
    EXPECT_EQ(image.command.motion_type, edp::MotionType::absolute);
    plan.targets.push_back(image.command.arm);
    plan.value_in_step_no.push_back(image.command.value_in_step_no);
    image.desired_joints = image.command.arm;
    image.joints = image.command.arm;
  } while (g.next_step(image, {}));
  return plan;
}

RobotModel model() {
  return load_robot_model((std::filesystem::path(MRROC_SOURCE_DIR) / "robots" / "irb6").string());
}

}  // namespace

TEST(JointPosesGenerator, ReachesPosesWithinLimitsSmoothly) {
  const RobotModel m = model();
  ecp::JointPosesOptions options;
  options.velocity_scale = 0.6;
  options.acceleration_scale = 0.6;
  options.motion_steps = 10;
  const std::vector<std::vector<double>> poses = {
      {0.6, -1.35, 0.15, 0.5, 1.0}, {-0.5, -1.8, -0.2, -0.6, -1.2}, m.synchro_joint_positions};
  ecp::JointPosesGenerator g(m, poses, options);
  const Plan plan = run(g, m.synchro_joint_positions);
  ASSERT_GT(plan.targets.size(), 10U);
  const double dt = options.motion_steps * options.servo_period_s;

  // Every pose is reached exactly at the end of its segment (velocity zero there).
  std::size_t pose = 0;
  for (std::size_t k = 0; k < plan.targets.size() && pose < poses.size(); ++k)
    if (plan.targets[k] == poses[pose]) ++pose;
  EXPECT_EQ(pose, poses.size()) << "not every pose was visited exactly";
  EXPECT_EQ(plan.targets.back(), poses.back());

  std::vector<double> previous = m.synchro_joint_positions;
  std::vector<double> previous_velocity(m.axes(), 0.0);
  for (std::size_t k = 0; k < plan.targets.size(); ++k) {
    m.check_joint_limits(plan.targets[k]);  // throws if any macro-step leaves the limits
    for (std::size_t j = 0; j < m.axes(); ++j) {
      const double v = (plan.targets[k][j] - previous[j]) / dt;
      const double a = (v - previous_velocity[j]) / dt;
      EXPECT_LE(std::abs(v), m.max_velocity[j] * options.velocity_scale * 1.0001)
          << "macro-step " << k << " joint " << j;
      // Mean velocities over macro-steps differ by at most the peak acceleration times dt
      // (plus the discretisation of the quintic profile).
      EXPECT_LE(std::abs(a), m.max_acceleration[j] * options.acceleration_scale * 1.05)
          << "macro-step " << k << " joint " << j;
      previous_velocity[j] = v;
    }
    previous = plan.targets[k];
  }

  // value_in_step_no: early for seamless macro-steps, after the stop for the last one.
  for (std::size_t k = 0; k + 1 < plan.value_in_step_no.size(); ++k)
    EXPECT_EQ(plan.value_in_step_no[k], ecp::early_reading_step(options.motion_steps));
  EXPECT_EQ(plan.value_in_step_no.back(), options.motion_steps + 1);
}

TEST(JointPosesGenerator, StartsAndEndsAtRest) {
  const RobotModel m = model();
  ecp::JointPosesGenerator g(m, {{1.0, -1.5708, 0.0, 0.0, 0.0}});
  const Plan plan = run(g, m.synchro_joint_positions);
  ASSERT_GT(plan.targets.size(), 20U);
  const double total = 1.0;
  const double first = plan.targets.front()[0] - 0.0;
  const double last = plan.targets.back()[0] - plan.targets[plan.targets.size() - 2][0];
  double largest = 0;
  for (std::size_t k = 1; k < plan.targets.size(); ++k)
    largest = std::max(largest, plan.targets[k][0] - plan.targets[k - 1][0]);
  EXPECT_LT(first, 0.05 * largest);
  EXPECT_LT(last, 0.05 * largest);
  EXPECT_GT(largest, total / static_cast<double>(plan.targets.size()));  // bell-shaped profile
}

TEST(JointPosesGenerator, DurationFollowsTheLimits) {
  // A quintic move of 1 rad at 1 rad/s peak needs 1.875 s; with 100 rad/s^2 it is velocity-bound.
  EXPECT_NEAR(ecp::JointPosesGenerator::segment_duration(1.0, 1.0, 100.0), 1.875, 1e-12);
  // Acceleration-bound: sqrt(5.7735 * 1 / 1) s.
  EXPECT_NEAR(ecp::JointPosesGenerator::segment_duration(1.0, 100.0, 1.0),
              std::sqrt(5.773502691896258), 1e-12);
  EXPECT_DOUBLE_EQ(ecp::JointPosesGenerator::scaling(0.0), 0.0);
  EXPECT_DOUBLE_EQ(ecp::JointPosesGenerator::scaling(1.0), 1.0);
  EXPECT_DOUBLE_EQ(ecp::JointPosesGenerator::scaling(0.5), 0.5);
}

TEST(JointPosesGenerator, RefusesPosesOutsideLimitsBeforeMoving) {
  const RobotModel m = model();
  try {
    ecp::JointPosesGenerator g(m, {{0.0, -1.5708, 0.0, 0.0, 0.0}, {0.0, -0.5, 0.0, 0.0, 0.0}});
    FAIL() << "accepted lower arm at -0.5 rad";
  } catch (const CommandError& e) {
    EXPECT_EQ(e.code(), edp::error_code::out_of_limits);
    const std::string text = e.what();
    EXPECT_NE(text.find("joint 1 (lower_arm) pose 2 -0.500000 rad exceeds upper limit"),
              std::string::npos)
        << text;
  }
  EXPECT_THROW(ecp::JointPosesGenerator(m, {{0.0, -1.5}}), CommandError);
  ecp::JointPosesOptions bad;
  bad.motion_steps = 1;
  EXPECT_THROW(ecp::JointPosesGenerator(m, {m.synchro_joint_positions}, bad), Error);
  bad = {};
  bad.velocity_scale = 1.5;
  EXPECT_THROW(ecp::JointPosesGenerator(m, {m.synchro_joint_positions}, bad), Error);
}

TEST(JointPosesGenerator, NoPosesNoMotion) {
  const RobotModel m = model();
  ecp::JointPosesGenerator g(m, {});
  EXPECT_TRUE(run(g, m.synchro_joint_positions).targets.empty());
}

TEST(JointPosesGenerator, RefusesAPathThatLeavesTheMotorRangeBeforeMoving) {
  const RobotModel m = model();
  // Both poses are inside the joint limits, but the upper arm's ball screw needs more than its
  // motor range (100 rad) for q1 = -1.2 rad with q2 = 0.3 rad.
  try {
    ecp::JointPosesGenerator g(m, {m.synchro_joint_positions, {0.0, -1.2, 0.3, 0.0, 0.0}});
    FAIL() << "accepted a path outside the motor range";
  } catch (const CommandError& e) {
    EXPECT_EQ(e.code(), edp::error_code::out_of_limits);
    EXPECT_NE(std::string(e.what()).find("motor 2 (upper_arm) path from pose 1 to 2"),
              std::string::npos)
        << e.what();
  }
  // The path from the current pose to the first pose is checked before the first command.
  ecp::JointPosesGenerator g(m, {{0.0, -1.2, 0.3, 0.0, 0.0}});
  ecp::RobotImage image;
  image.desired_joints = m.synchro_joint_positions;
  EXPECT_THROW(g.first_step(image, {}), CommandError);
  EXPECT_EQ(image.command.type, edp::InstructionType::query) << "a command was prepared";
}
