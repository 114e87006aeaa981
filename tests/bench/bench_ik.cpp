// B3: the IRb-6's analytic inverse kinematics against KDL's Levenberg-Marquardt solver
// (ChainIkSolverPos_LMA through mrroc::kinematics::KdlSolver) on the same URDF chain
// (robots/irb6/irb6.urdf, base_link .. flange) and the same random reachable poses.
//
// Poses: joints drawn uniformly inside the joint limits and the ball-screw linkage ranges (every
// pose the arm can reach), flange frame = forward kinematics. Both solvers get the same seed for
// a pose: the pose's joints moved by up to +-0.3 rad each (the robot's current joints near its
// target, as in the EDP). A solve succeeds when it returns joints inside the limits whose flange
// frame is within 1e-6 m and 1e-6 rad of the target. Every solve is timed on its own
// (steady_clock around the call), the two solvers alternating pose by pose.
//
// For orientation, the same is repeated on fewer poses with the synchronisation pose as the seed
// of every solve (a far seed), and KDL once more with the exact answer as its seed (the fixed
// cost of one call).
//
// Usage: bench_ik [poses] [rng-seed]   (default 20000 poses, seed 1)
// Prints "RESULT B3 ..." (per-solve p50/p99 in us of both solvers and their success rates).
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <numbers>
#include <random>
#include <string>
#include <vector>

#include "bench_args.hpp"
#include "mrroc/core/error.hpp"
#include "mrroc/kinematics/irb6.hpp"
#include "mrroc/kinematics/kdl_solver.hpp"
#include "mrroc/robot/robot_model.hpp"

namespace {

namespace irb6 = mrroc::robots::irb6;
using Clock = std::chrono::steady_clock;
constexpr double kTolerance = 1e-6;  // m and rad

double percentile(std::vector<double> v, double p) {
  if (v.empty()) return 0.0;
  std::sort(v.begin(), v.end());
  return v[static_cast<std::size_t>(p * static_cast<double>(v.size() - 1))];
}

/// The IRb-6's kinematic model 0, from robots/irb6/parameters.toml.
const irb6::Irb6Geometry& nominal() {
  static const irb6::Irb6Geometry geometry =
      irb6::kinematic_models(
          mrroc::load_robot_model(std::string(MRROC_SOURCE_DIR) + "/robots/irb6"))
          .at(irb6::kNominalModel);
  return geometry;
}

bool linkage_ok(const irb6::JointPosition& q) {
  const double fed = q[1] + q[2] + std::numbers::pi / 2;
  return q[1] >= irb6::kLowerArmScrew.min_angle && q[1] <= irb6::kLowerArmScrew.max_angle &&
         fed >= irb6::kUpperArmScrew.min_angle && fed <= irb6::kUpperArmScrew.max_angle;
}

irb6::JointPosition random_reachable_joints(std::mt19937& rng) {
  for (;;) {
    irb6::JointPosition q{};
    for (std::size_t i = 0; i < irb6::kAxes; ++i)
      q[i] = std::uniform_real_distribution<double>(irb6::kJointLowerLimits[i],
                                                    irb6::kJointUpperLimits[i])(rng);
    if (linkage_ok(q)) return q;
  }
}

irb6::JointPosition nearby(const irb6::JointPosition& q, std::mt19937& rng, double spread) {
  irb6::JointPosition s{};
  for (std::size_t i = 0; i < irb6::kAxes; ++i)
    s[i] = std::clamp(q[i] + std::uniform_real_distribution<double>(-spread, spread)(rng),
                      irb6::kJointLowerLimits[i], irb6::kJointUpperLimits[i]);
  return s;
}

/// True when `q` is inside the joint limits and reaches `target` within the tolerances.
bool reaches(const irb6::JointPosition& q, const Eigen::Isometry3d& target) {
  for (std::size_t i = 0; i < irb6::kAxes; ++i)
    if (!(q[i] >= irb6::kJointLowerLimits[i] - 1e-9 && q[i] <= irb6::kJointUpperLimits[i] + 1e-9))
      return false;
  const Eigen::Isometry3d reached = irb6::forward_kinematics(q, nominal());
  const Eigen::AngleAxisd rotation(reached.linear().transpose() * target.linear());
  return (reached.translation() - target.translation()).norm() <= kTolerance &&
         std::abs(rotation.angle()) <= kTolerance;
}

struct SolverRun {
  std::vector<double> times_us;
  int solved = 0;
  std::string first_failure;
};

double elapsed_us(Clock::time_point t0, Clock::time_point t1) {
  return std::chrono::duration<double, std::micro>(t1 - t0).count();
}

}  // namespace

int main(int argc, char** argv) {
  if (mrroc::bench::help_requested(
          argc, argv,
          "Usage: bench_ik [POSES [SEED]]\n"
          "B3: IRb-6 analytic inverse kinematics against KDL LMA on POSES (default 20000) random\n"
          "reachable poses drawn with SEED (default 1). Prints RESULT B3 and NOTE lines.\n"))
    return 0;
  const int poses = argc > 1 ? static_cast<int>(mrroc::bench::whole_number(
                                   "bench_ik", "POSES", argv[1], 1, 100000000, "poses"))
                             : 20000;
  const unsigned rng_seed = argc > 2 ? static_cast<unsigned>(mrroc::bench::whole_number(
                                           "bench_ik", "SEED", argv[2], 0, 4294967295L, "(seed)"))
                                     : 1U;
  const mrroc::kinematics::KdlSolver kdl(std::string(MRROC_SOURCE_DIR) + "/robots/irb6/irb6.urdf",
                                         "base_link", "flange");
  std::mt19937 rng(rng_seed);

  // Warm-up (page faults, caches), not counted.
  for (int k = 0; k < 50; ++k) {
    const irb6::JointPosition q = random_reachable_joints(rng);
    const Eigen::Isometry3d target = irb6::forward_kinematics(q, nominal());
    try {
      (void)irb6::inverse_kinematics(target, q, nominal());
      (void)kdl.inverse(target, std::vector<double>(q.begin(), q.end()));
    } catch (const mrroc::Error&) {
    }
  }

  SolverRun analytic;
  SolverRun lma;
  SolverRun lma_exact_seed;  // seed = the answer: KDL's fixed cost per call
  analytic.times_us.reserve(static_cast<std::size_t>(poses));
  lma.times_us.reserve(static_cast<std::size_t>(poses));
  for (int k = 0; k < poses; ++k) {
    const irb6::JointPosition q = random_reachable_joints(rng);
    const Eigen::Isometry3d target = irb6::forward_kinematics(q, nominal());
    const irb6::JointPosition seed = nearby(q, rng, 0.3);
    {
      const auto t0 = Clock::now();
      try {
        const irb6::JointPosition s = irb6::inverse_kinematics(target, seed, nominal());
        const auto t1 = Clock::now();
        analytic.times_us.push_back(elapsed_us(t0, t1));
        if (reaches(s, target))
          ++analytic.solved;
        else if (analytic.first_failure.empty())
          analytic.first_failure = "residual too large";
      } catch (const mrroc::Error& e) {
        analytic.times_us.push_back(elapsed_us(t0, Clock::now()));
        if (analytic.first_failure.empty()) analytic.first_failure = e.what();
      }
    }
    {
      const std::vector<double> kdl_seed(seed.begin(), seed.end());
      const auto t0 = Clock::now();
      try {
        const std::vector<double> s = kdl.inverse(target, kdl_seed);
        const auto t1 = Clock::now();
        lma.times_us.push_back(elapsed_us(t0, t1));
        irb6::JointPosition sq{};
        std::copy(s.begin(), s.end(), sq.begin());
        if (reaches(sq, target))
          ++lma.solved;
        else if (lma.first_failure.empty())
          lma.first_failure = "residual too large";
      } catch (const mrroc::Error& e) {
        lma.times_us.push_back(elapsed_us(t0, Clock::now()));
        if (lma.first_failure.empty()) lma.first_failure = e.what();
      }
    }
    if (k < 2000) {
      const std::vector<double> exact(q.begin(), q.end());
      const auto t0 = Clock::now();
      try {
        (void)kdl.inverse(target, exact);
        ++lma_exact_seed.solved;
      } catch (const mrroc::Error&) {
      }
      lma_exact_seed.times_us.push_back(elapsed_us(t0, Clock::now()));
    }
  }

  // Far seed: the synchronisation pose for every solve.
  SolverRun far_analytic;
  SolverRun far_lma;
  const std::vector<double> synchro(irb6::kSynchroJointPositions.begin(),
                                    irb6::kSynchroJointPositions.end());
  for (int k = 0; k < std::min(poses, 2000); ++k) {
    const irb6::JointPosition q = random_reachable_joints(rng);
    const Eigen::Isometry3d target = irb6::forward_kinematics(q, nominal());
    auto t0 = Clock::now();
    try {
      const irb6::JointPosition s =
          irb6::inverse_kinematics(target, irb6::kSynchroJointPositions, nominal());
      if (reaches(s, target)) ++far_analytic.solved;
    } catch (const mrroc::Error&) {
    }
    far_analytic.times_us.push_back(elapsed_us(t0, Clock::now()));
    t0 = Clock::now();
    try {
      const std::vector<double> s = kdl.inverse(target, synchro);
      irb6::JointPosition sq{};
      std::copy(s.begin(), s.end(), sq.begin());
      if (reaches(sq, target)) ++far_lma.solved;
    } catch (const mrroc::Error&) {
    }
    far_lma.times_us.push_back(elapsed_us(t0, Clock::now()));
  }

  auto rate = [&](const SolverRun& r) {
    return 100.0 * r.solved / static_cast<double>(r.times_us.size());
  };
  std::printf(
      "B3 inverse kinematics, %d random reachable poses (rng seed %u), seed = pose +- 0.3 "
      "rad\n",
      poses, rng_seed);
  std::printf(
      "  KDL LMA (baseline): p50 %.2f us, p99 %.2f us, max %.1f us, %d solved "
      "(%.3f %%)\n",
      percentile(lma.times_us, 0.5), percentile(lma.times_us, 0.99), percentile(lma.times_us, 1.0),
      lma.solved, rate(lma));
  if (!lma.first_failure.empty())
    std::printf("    first KDL failure: %s\n", lma.first_failure.c_str());
  std::printf("  IRb-6 analytic:     p50 %.2f us, p99 %.2f us, max %.1f us, %d solved (%.3f %%)\n",
              percentile(analytic.times_us, 0.5), percentile(analytic.times_us, 0.99),
              percentile(analytic.times_us, 1.0), analytic.solved, rate(analytic));
  if (!analytic.first_failure.empty())
    std::printf("    first analytic failure: %s\n", analytic.first_failure.c_str());
  std::printf(
      "  KDL LMA with the exact answer as seed (fixed cost of one call): p50 %.2f us, "
      "p99 %.2f us\n",
      percentile(lma_exact_seed.times_us, 0.5), percentile(lma_exact_seed.times_us, 0.99));
  std::printf(
      "  seed = synchronisation pose, %zu poses: KDL p50 %.2f us, p99 %.2f us, %.3f %% "
      "solved; analytic p50 %.2f us, p99 %.2f us, %.3f %% solved\n",
      far_lma.times_us.size(), percentile(far_lma.times_us, 0.5),
      percentile(far_lma.times_us, 0.99), rate(far_lma), percentile(far_analytic.times_us, 0.5),
      percentile(far_analytic.times_us, 0.99), rate(far_analytic));
  std::printf(
      "NOTE B3 %d random reachable poses (joints uniform in the joint limits and linkage "
      "ranges), the same seed for both solvers: the pose's joints +- 0.3 rad; success = "
      "joints inside the limits reaching the frame within 1e-6 m and 1e-6 rad. KDL LMA "
      "(KdlSolver defaults: 500 iterations, 32 restarts) solved %.3f %%, the analytic "
      "solver %.3f %%. With the synchronisation pose as a far seed (%zu poses): KDL p50 "
      "%.1f us, p99 %.1f us, %.3f %% solved; analytic p50 %.2f us, %.3f %% solved. KDL "
      "with the exact answer as seed still costs p50 %.1f us per call (KdlSolver builds "
      "its KDL solvers on every call).\n",
      poses, rate(lma), rate(analytic), far_lma.times_us.size(), percentile(far_lma.times_us, 0.5),
      percentile(far_lma.times_us, 0.99), rate(far_lma), percentile(far_analytic.times_us, 0.5),
      rate(far_analytic), percentile(lma_exact_seed.times_us, 0.5));
  std::printf(
      "RESULT B3 baseline_p50=%.3f baseline_p99=%.3f value_p50=%.3f value_p99=%.3f "
      "baseline_success=%.3f value_success=%.3f samples=%d unit=us\n",
      percentile(lma.times_us, 0.5), percentile(lma.times_us, 0.99),
      percentile(analytic.times_us, 0.5), percentile(analytic.times_us, 0.99), rate(lma),
      rate(analytic), poses);
  return 0;
}
