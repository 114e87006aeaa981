// B10: the cost of the EDP's collision guard (edp/collision_guard.hpp) per macro-step, for the
// two-IRb-6 cell of configs/tight-bar.toml (its [collision] section: floor, table, clearance
// 0.01 m, allowed pairs), against the macro-step's own period and against the limit check the
// command interpreter already runs on the same macro-step (joint and motor limits at every servo
// step, CommandInterpreter::check_path), measured in the same run.
//
// Macro-steps: 10 servo steps of 2 ms (the set's motion_steps and servo period: 20 ms), from a
// start drawn uniformly inside the joint limits and the motor limits, every joint moving at
// `share` of its velocity limit (default 1: the most poses the guard samples) in a random
// direction; those whose end leaves the limits are drawn again. Each robot's guard ("left",
// "right") checks half of them. Every check is timed on its own (steady_clock around the call);
// a macro-step the guard refuses (the path meets the floor, the table or the robot itself) is
// timed too (it ends at the first pose that fails) and counted.
//
// Usage: bench_collision [macro-steps] [rng-seed]   (default 20000, seed 1)
// Prints "RESULT B10 ..." (p50/p99 per macro-step in us of the guard and of the limit check, the
// macro-step period, poses per macro-step and refusals) and NOTE lines.
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include "bench_args.hpp"
#include "collision_guard.hpp"
#include "mrroc/config/process_set.hpp"
#include "mrroc/core/error.hpp"
#include "mrroc/edp/arm_kinematics.hpp"
#include "mrroc/robot/robot_model.hpp"

namespace {

using Clock = std::chrono::steady_clock;
constexpr int kSteps = 10;         // servo steps per macro-step (configs/tight-bar.toml)
constexpr double kPeriod = 0.002;  // s, servo period

double percentile(std::vector<double> v, double p) {
  if (v.empty()) return 0.0;
  std::sort(v.begin(), v.end());
  return v[static_cast<std::size_t>(p * static_cast<double>(v.size() - 1))];
}

double micros(Clock::duration d) { return std::chrono::duration<double, std::micro>(d).count(); }

bool within_limits(const mrroc::edp::ArmKinematics& k, const std::vector<double>& q) {
  try {
    k.check_joint_limits(q, "pose");
    k.check_motor_limits(k.motors_from_joints(q), "pose");
  } catch (const mrroc::Error&) {
    return false;
  }
  return true;
}

}  // namespace

int main(int argc, char** argv) {
  if (mrroc::bench::help_requested(
          argc, argv,
          "Usage: bench_collision [MACRO_STEPS] [SEED]\n"
          "B10: the collision guard's time per macro-step for the two-IRb-6 cell of\n"
          "configs/tight-bar.toml, against the macro-step period and the limit check of the same\n"
          "macro-step. MACRO_STEPS random macro-steps (default 20000), seed SEED (default 1).\n"
          "Prints RESULT B10 and NOTE lines.\n"))
    return 0;
  const long count = argc > 1 ? mrroc::bench::whole_number("bench_collision", "macro-step count",
                                                           argv[1], 10, 10000000, "macro-steps")
                              : 20000;
  const auto seed = static_cast<unsigned>(
      argc > 2 ? mrroc::bench::whole_number("bench_collision", "seed", argv[2], 0, 1L << 31, "")
               : 1);
  const double share = 1.0;

  const mrroc::ProcessSetConfig set =
      mrroc::load_process_set(std::string(MRROC_SOURCE_DIR) + "/configs/tight-bar.toml");
  struct Robot {
    mrroc::RobotModel model;
    std::unique_ptr<mrroc::edp::ArmKinematics> kinematics;
    std::unique_ptr<mrroc::edp::CollisionGuard> guard;
  };
  // The kinematics keep a reference to their model: each robot stays where it is built.
  std::vector<std::unique_ptr<Robot>> robots;
  std::string describe;
  for (const mrroc::RobotConfig& rc : set.robots) {
    auto robot = std::make_unique<Robot>();
    Robot& r = *robot;
    r.model = mrroc::load_robot_model(rc.model_dir);
    r.kinematics = mrroc::edp::make_arm_kinematics(r.model);
    std::string why_not;
    r.guard = mrroc::edp::CollisionGuard::make(r.model, rc, set.collision, r.model.mjcf, why_not);
    if (!r.guard) {
      std::fprintf(stderr, "bench_collision: robot '%s': collision guard %s\n", rc.name.c_str(),
                   why_not.c_str());
      return 1;
    }
    if (describe.empty()) describe = r.guard->describe();
    robots.push_back(std::move(robot));
  }

  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  std::vector<double> guard_us, passed_us, limits_us;
  guard_us.reserve(static_cast<std::size_t>(count));
  limits_us.reserve(static_cast<std::size_t>(count));
  long refused = 0, poses = 0;
  std::string first_refusal;
  for (long n = 0; n < count; ++n) {
    Robot& r = *robots[static_cast<std::size_t>(n) % robots.size()];
    const mrroc::RobotModel& m = r.model;
    std::vector<double> start(m.axes()), target(m.axes());
    do {
      for (std::size_t j = 0; j < m.axes(); ++j) {
        start[j] = m.lower_limits[j] + unit(rng) * (m.upper_limits[j] - m.lower_limits[j]);
        const double sign = unit(rng) < 0.5 ? -1.0 : 1.0;
        target[j] = start[j] + sign * share * m.max_velocity[j] * kSteps * kPeriod;
      }
    } while (!within_limits(*r.kinematics, start) || !within_limits(*r.kinematics, target));

    // The limit check of CommandInterpreter::check_path on the same macro-step.
    auto t0 = Clock::now();
    std::vector<double> q(m.axes());
    for (int k = 1; k <= kSteps; ++k) {
      for (std::size_t j = 0; j < q.size(); ++j)
        q[j] = start[j] + (target[j] - start[j]) * k / kSteps;
      const std::string what = "step " + std::to_string(k);
      r.kinematics->check_joint_limits(q, what.c_str());
      r.kinematics->check_motor_limits(r.kinematics->motors_from_joints(q), what.c_str());
    }
    limits_us.push_back(micros(Clock::now() - t0));

    const long before = r.guard->poses_checked();
    bool ok = true;
    t0 = Clock::now();
    try {
      r.guard->check_path(start, target, kSteps);
    } catch (const mrroc::CommandError& e) {
      ok = false;
      if (first_refusal.empty()) first_refusal = e.what();
    }
    const double us = micros(Clock::now() - t0);
    guard_us.push_back(us);
    if (ok) passed_us.push_back(us);
    refused += ok ? 0 : 1;
    poses += r.guard->poses_checked() - before;
  }

  const double period_us = kSteps * kPeriod * 1e6;
  const double g50 = percentile(guard_us, 0.5), g99 = percentile(guard_us, 0.99);
  std::printf(
      "NOTE B10 %ld random macro-steps of %d servo steps of %.0f ms (%.0f ms) of the two IRb-6 of "
      "configs/tight-bar.toml, half per robot, every joint at %.0f %% of its velocity limit from a "
      "start uniform in the joint and motor limits (seed %u); %s. Poses checked per macro-step: "
      "%.2f on average (the start, the sampled servo steps and the end). Refused: %ld (the path "
      "meets the floor, the table or the robot itself; timed up to the refusal), e.g. \"%s\". "
      "Passed macro-steps alone: p50 %.1f / p99 %.1f us. Baseline: the interpreter's joint and "
      "motor limit check of the same macro-step at every servo step, p50 %.1f / p99 %.1f us.\n",
      count, kSteps, kPeriod * 1e3, period_us / 1e3, share * 100, seed, describe.c_str(),
      static_cast<double>(poses) / static_cast<double>(count), refused, first_refusal.c_str(),
      percentile(passed_us, 0.5), percentile(passed_us, 0.99), percentile(limits_us, 0.5),
      percentile(limits_us, 0.99));
  std::printf(
      "RESULT B10 value_p50=%.2f value_p99=%.2f baseline_p50=%.2f baseline_p99=%.2f "
      "period_us=%.0f share_p99=%.5f poses=%.2f refused=%ld samples=%ld\n",
      g50, g99, percentile(limits_us, 0.5), percentile(limits_us, 0.99), period_us, g99 / period_us,
      static_cast<double>(poses) / static_cast<double>(count), refused, count);
  return 0;
}
