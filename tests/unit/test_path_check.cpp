// The limit check of a macro-step's straight joint-space path (mrroc/edp/path_check.hpp), the one
// the EDP's command interpreter and the ECP's planned motions use: no heap allocation while a path
// passes, even at the largest motion_steps (100000, the most a SET may have); the first limit a
// path leaves as a value (kind, axis, value, limit, step); and the refusal's text as the
// kinematics' own checks word it, the same as the step-by-step loop it replaced (kept below as the
// reference) gives, for the IRb-6 (joint, linkage and motor limits) and the RNT (its
// parallelogram's limit on q1 + q2).
#include <gtest/gtest.h>

#include <cstdio>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include "edp_parts.hpp"
#include "heap_counter.hpp"
#include "mrroc/core/error.hpp"
#include "mrroc/ecp/generators/planned_motion.hpp"
#include "mrroc/edp/arm_kinematics.hpp"
#include "mrroc/edp/path_check.hpp"
#include "mrroc/kinematics/irb6.hpp"

using namespace mrroc;

namespace {

constexpr int kMostMotionSteps = 100000;  // the largest motion_steps of a SET

/// The check as both sides wrote it before: every step formats its name and converts to motors
/// into a new vector. Returns the refusal's text ("" when the path passes) and its step (0: the
/// target).
struct Reference {
  std::string text;
  int step = -1;
};
Reference reference_check(const edp::ArmKinematics& k, const std::vector<double>& from,
                          const std::vector<double>& to, int steps, const char* step_name) {
  Reference r;
  try {
    r.step = 0;
    k.check_joint_limits(to, "target");
    std::vector<double> q(to.size());
    for (int s = 1; s <= steps; ++s) {
      r.step = s;
      const double f = static_cast<double>(s) / steps;
      for (std::size_t i = 0; i < q.size(); ++i) q[i] = from[i] + (to[i] - from[i]) * f;
      const std::string what = fmt::format("{} {} of {}", step_name, s, steps);
      k.check_joint_limits(q, what.c_str());
      k.check_motor_limits(k.motors_from_joints(q), what.c_str());
    }
    r.step = -1;
  } catch (const CommandError& e) {
    r.text = e.what();
  }
  return r;
}

std::string refusal(const edp::ArmKinematics& k, const std::vector<double>& from,
                    const std::vector<double>& to, int steps, const char* step_name) {
  try {
    edp::check_straight_path(k, from, to, steps, step_name);
  } catch (const CommandError& e) {
    return e.what();
  }
  return {};
}

/// Heap allocations on this thread while `f` runs.
template <typename F>
long allocations_in(F&& f) {
  g_heap.allocations = 0;
  t_heap_counting = true;
  f();
  t_heap_counting = false;
  return g_heap.allocations.load();
}

class PathCheck : public ::testing::Test {
 protected:
  RobotModel model_ = test::stock_model("irb6");
  std::unique_ptr<edp::ArmKinematics> kinematics_ = edp::make_arm_kinematics(model_);
  const std::vector<double> synchro_ = {0.0, -1.5707963267948966, 0.0, 0.0, 0.0};
};

TEST_F(PathCheck, APathInsideTheLimitsAllocatesNothingAtTheLargestMotionSteps) {
  const std::vector<double> to = {0.8, -1.3, 0.2, 0.5, -1.0};
  LimitViolation v;
  const long found = allocations_in(
      [&] { v = edp::find_path_limit_violation(*kinematics_, synchro_, to, kMostMotionSteps); });
  EXPECT_FALSE(v) << "joint " << v.axis << " at step " << v.step;
  EXPECT_EQ(found, 0) << "heap allocations in find_path_limit_violation";
  const long edp_side = allocations_in(
      [&] { edp::check_straight_path(*kinematics_, synchro_, to, kMostMotionSteps, "step"); });
  EXPECT_EQ(edp_side, 0) << "heap allocations in check_straight_path";
  const long ecp_side = allocations_in(
      [&] { ecp::detail::check_macro_step_path(*kinematics_, synchro_, to, kMostMotionSteps); });
  EXPECT_EQ(ecp_side, 0) << "heap allocations in the ECP's check_macro_step_path";
  Reference r;
  const long before = allocations_in(
      [&] { r = reference_check(*kinematics_, synchro_, to, kMostMotionSteps, "step"); });
  EXPECT_EQ(r.step, -1) << r.text;
  std::printf(
      "one SET of %d steps: %ld heap allocations in the check (%ld in the step-by-step loop "
      "above)\n",
      kMostMotionSteps, edp_side, before);
}

TEST_F(PathCheck, ATargetBeyondAJointLimitIsReportedAsTheTarget) {
  const std::vector<double> to = {0.0, -1.5707963267948966, 0.81, 0.0, 0.0};
  const LimitViolation v = edp::find_path_limit_violation(*kinematics_, synchro_, to, 1000);
  EXPECT_EQ(v.kind, LimitKind::joint);
  EXPECT_EQ(v.axis, 2U);
  EXPECT_EQ(v.step, 0);
  EXPECT_DOUBLE_EQ(v.value, 0.81);
  EXPECT_DOUBLE_EQ(v.limit, robots::irb6::kJointUpperLimits[2]);
  EXPECT_EQ(refusal(*kinematics_, synchro_, to, 1000, "step"),
            "joint 2 (upper_arm) target 0.810000 rad exceeds upper limit 0.698132 rad");
}

// A path that starts beyond a limit (where a stopping ramp may leave the robot) leaves it in its
// first step; the text names the step as the loop it replaced did.
TEST_F(PathCheck, AStepBeyondAJointLimitIsReportedWithItsStepValueAndLimit) {
  const std::vector<double> from = {0.0, -1.5707963267948966, 0.75, 0.0, 0.0};
  const std::vector<double> to = {0.0, -1.5707963267948966, 0.5, 0.0, 0.0};
  const LimitViolation v = edp::find_path_limit_violation(*kinematics_, from, to, 1000);
  EXPECT_EQ(v.kind, LimitKind::joint);
  EXPECT_EQ(v.axis, 2U);
  EXPECT_EQ(v.step, 1);
  EXPECT_DOUBLE_EQ(v.value, 0.75 + (0.5 - 0.75) * (1.0 / 1000));
  EXPECT_DOUBLE_EQ(v.limit, robots::irb6::kJointUpperLimits[2]);
  EXPECT_EQ(refusal(*kinematics_, from, to, 1000, "step"),
            "joint 2 (upper_arm) step 1 of 1000 0.749750 rad exceeds upper limit 0.698132 rad");
  // The same path from inside the limits passes.
  const std::vector<double> inside = {0.0, -1.5707963267948966, 0.6, 0.0, 0.0};
  const LimitViolation none = edp::find_path_limit_violation(*kinematics_, inside, to, 1000);
  EXPECT_FALSE(none) << refusal(*kinematics_, inside, to, 1000, "step");
}

// Random paths from the synchronisation pose, many of them leaving a joint, linkage or motor
// limit on the way: the same step and the same text as the loop the function replaced, and a
// value and limit that say the same as the text.
void expect_as_the_loop_did(const edp::ArmKinematics& k, const std::vector<double>& start,
                            unsigned seed, int* kinds) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> offset(-1.2, 1.2);
  std::uniform_int_distribution<int> steps_of(1, 400);
  for (int n = 0; n < 400; ++n) {
    std::vector<double> from = start;
    std::vector<double> to = start;
    for (std::size_t i = 0; i < to.size(); ++i) {
      to[i] += offset(rng);
      from[i] += 0.1 * offset(rng);
    }
    const int steps = steps_of(rng);
    const Reference r = reference_check(k, from, to, steps, "servo step");
    const LimitViolation v = edp::find_path_limit_violation(k, from, to, steps);
    ASSERT_EQ(static_cast<bool>(v), r.step >= 0)
        << "seed " << seed << ", path " << n << ": " << r.text;
    if (!v) continue;
    ++kinds[static_cast<int>(v.kind)];
    EXPECT_EQ(v.step, r.step) << "seed " << seed << ", path " << n << ": " << r.text;
    EXPECT_EQ(refusal(k, from, to, steps, "servo step"), r.text)
        << "seed " << seed << ", path " << n;
    EXPECT_NE(r.text.find(fmt::format(" {} ", v.axis)), std::string::npos) << r.text;
    if (v.kind == LimitKind::joint || v.kind == LimitKind::linkage) {
      EXPECT_NE(r.text.find(fmt::format("{:.6f}", v.value)), std::string::npos) << r.text;
    }
  }
}

TEST_F(PathCheck, FindsWhatTheStepByStepLoopFoundOnTheIrb6) {
  int kinds[5] = {};
  expect_as_the_loop_did(*kinematics_, synchro_, 20261128U, kinds);
  std::printf(
      "irb6: %d paths outside a joint limit, %d outside a linkage range, %d outside a "
      "motor limit\n",
      kinds[2], kinds[3], kinds[4]);
  EXPECT_GT(kinds[2], 0);
  EXPECT_GT(kinds[3] + kinds[4], 0);
}

TEST(PathCheckRnt, FindsWhatTheStepByStepLoopFoundOnTheRnt) {
  const RobotModel model = test::stock_model("rnt");
  const auto kinematics = edp::make_arm_kinematics(model);
  int kinds[5] = {};
  expect_as_the_loop_did(*kinematics, model.synchro_joint_positions, 7U, kinds);
  std::printf("rnt: %d paths outside a joint limit, %d outside a motor limit\n", kinds[2],
              kinds[4]);
  EXPECT_GT(kinds[2] + kinds[4], 0);
}

}  // namespace
