/// @file
/// The generic URDF kinematics (mrroc::kinematics::KdlSolver) on the IRb-6 (5 axes) and the RNT
/// (6 axes): FK(IK(x)) = x on random reachable poses, unreachable poses and limits give
/// CommandError(out_of_limits), URDF problems give ConfigError naming the file.
///
/// Random numbers are seeded from the environment variable MRROC_TEST_SEED (default below); the
/// seed is printed with every failure.

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <numbers>
#include <random>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <unistd.h>

#include "mrroc/core/error.hpp"
#include "mrroc/kinematics/kdl_solver.hpp"
#include "mrroc/msg/edp_instruction.hpp"

#ifndef MRROC_SOURCE_DIR
#error "MRROC_SOURCE_DIR must be defined (absolute path of the source tree)"
#endif

namespace {

using mrroc::CommandError;
using mrroc::ConfigError;
using mrroc::kinematics::KdlSolver;
namespace error_code = mrroc::edp::error_code;

constexpr double kPi = std::numbers::pi;

std::filesystem::path robots() { return std::filesystem::path(MRROC_SOURCE_DIR) / "robots"; }

std::uint32_t test_seed() {
  if (const char* env = std::getenv("MRROC_TEST_SEED"); env != nullptr && *env != '\0') {
    return static_cast<std::uint32_t>(std::strtoul(env, nullptr, 10));
  }
  return 20240607U;
}

std::string seed_text(std::uint32_t seed) { return "MRROC_TEST_SEED=" + std::to_string(seed); }

std::string text(const std::vector<double>& q) {
  std::string out = "(";
  for (std::size_t i = 0; i < q.size(); ++i) {
    out += (i == 0 ? "" : ", ") + std::to_string(q[i]);
  }
  return out + ")";
}

/// Random joints within the limits, `margin` [rad] inside each end.
std::vector<double> random_joints(const KdlSolver& solver, std::mt19937& rng, double margin) {
  std::vector<double> q(solver.joint_count());
  for (std::size_t i = 0; i < q.size(); ++i) {
    q[i] = std::uniform_real_distribution<double>(solver.lower_limits()[i] + margin,
                                                  solver.upper_limits()[i] - margin)(rng);
  }
  return q;
}

/// A seed near `q`: each joint moved by up to `spread` [rad], kept inside the limits.
std::vector<double> nearby(const KdlSolver& solver, const std::vector<double>& q, std::mt19937& rng,
                           double spread) {
  std::vector<double> seed(q.size());
  for (std::size_t i = 0; i < q.size(); ++i) {
    seed[i] = std::clamp(q[i] + std::uniform_real_distribution<double>(-spread, spread)(rng),
                         solver.lower_limits()[i], solver.upper_limits()[i]);
  }
  return seed;
}

struct Residual {
  double position;     // m
  double orientation;  // rad
};

Residual residual(const Eigen::Isometry3d& a, const Eigen::Isometry3d& b) {
  const Eigen::AngleAxisd r(a.linear().transpose() * b.linear());
  return {(a.translation() - b.translation()).norm(), std::abs(r.angle())};
}

struct RoundTripStats {
  int poses = 0;
  int solved = 0;
  double worst_position = 0.0;
  double worst_orientation = 0.0;
  std::string first_failure;
};

/// FK(IK(FK(q))) = FK(q) on `count` random q; the IK seed is `seed_of(q)`.
template <typename SeedOf>
RoundTripStats round_trip(const KdlSolver& solver, std::mt19937& rng, int count, double margin,
                          SeedOf seed_of) {
  RoundTripStats stats;
  for (int k = 0; k < count; ++k) {
    const std::vector<double> q = random_joints(solver, rng, margin);
    const Eigen::Isometry3d target = solver.forward(q);
    const std::vector<double> seed = seed_of(q);
    ++stats.poses;
    try {
      const std::vector<double> solution = solver.inverse(target, seed);
      const Residual r = residual(solver.forward(solution), target);
      stats.worst_position = std::max(stats.worst_position, r.position);
      stats.worst_orientation = std::max(stats.worst_orientation, r.orientation);
      if (r.position <= solver.options().position_tolerance &&
          r.orientation <= solver.options().orientation_tolerance) {
        ++stats.solved;
      } else if (stats.first_failure.empty()) {
        stats.first_failure = "q = " + text(q) + ": residual " + std::to_string(r.position) +
                              " m, " + std::to_string(r.orientation) + " rad";
      }
    } catch (const CommandError& e) {
      if (stats.first_failure.empty()) {
        stats.first_failure = "q = " + text(q) + ", seed " + text(seed) + ": " + e.what();
      }
    }
  }
  return stats;
}

void report(const char* robot, const char* seeds, const RoundTripStats& s) {
  std::printf("%s, %s: %d / %d solved (%.1f %%), worst residual %.3e m, %.3e rad\n", robot, seeds,
              s.solved, s.poses, 100.0 * s.solved / s.poses, s.worst_position, s.worst_orientation);
}

// ---- IRb-6 (5 axes): position and reachable orientation. ----

class Irb6Kdl : public ::testing::Test {
 protected:
  KdlSolver solver_{robots() / "irb6" / "irb6.urdf", "base_link", "flange"};
};

TEST_F(Irb6Kdl, ChainAndLimitsComeFromTheUrdf) {
  ASSERT_EQ(solver_.joint_count(), 5U);
  const std::vector<std::string> names = {"column", "lower_arm", "upper_arm", "wrist_pitch",
                                          "wrist_roll"};
  EXPECT_EQ(solver_.joint_names(), names);
  EXPECT_NEAR(solver_.lower_limits()[1], -130.0 * kPi / 180.0, 1e-12);
  EXPECT_NEAR(solver_.upper_limits()[1], -50.0 * kPi / 180.0, 1e-12);
  // Synchronisation pose: flange at (a3 + d5, 0, d1 + a2) with z along world x.
  const Eigen::Isometry3d flange = solver_.forward({0.0, -kPi / 2, 0.0, 0.0, 0.0});
  EXPECT_NEAR(flange.translation().x(), 0.86, 1e-12);
  EXPECT_NEAR(flange.translation().y(), 0.0, 1e-12);
  EXPECT_NEAR(flange.translation().z(), 1.155, 1e-12);
  EXPECT_NEAR(flange.linear()(0, 2), 1.0, 1e-12);
}

TEST_F(Irb6Kdl, InverseOfForwardOnRandomPosesFromANearbySeed) {
  const std::uint32_t seed = test_seed();
  SCOPED_TRACE(seed_text(seed));
  std::mt19937 rng(seed);
  const RoundTripStats stats = round_trip(
      solver_, rng, 600, 0.0, [&](const auto& q) { return nearby(solver_, q, rng, 0.3); });
  report("irb6", "seed = q +- 0.3 rad", stats);
  EXPECT_EQ(stats.solved, stats.poses) << stats.first_failure;
  EXPECT_LE(stats.worst_position, 1e-6);
  EXPECT_LE(stats.worst_orientation, 1e-6);
}

TEST_F(Irb6Kdl, InverseOfForwardOnRandomPosesFromTheSynchronisationPose) {
  const std::uint32_t seed = test_seed() + 1U;
  SCOPED_TRACE(seed_text(seed - 1U));
  std::mt19937 rng(seed);
  const std::vector<double> synchro = {0.0, -kPi / 2, 0.0, 0.0, 0.0};
  const RoundTripStats stats =
      round_trip(solver_, rng, 500, 0.0, [&](const auto&) { return synchro; });
  report("irb6", "seed = synchronisation pose", stats);
  EXPECT_EQ(stats.solved, stats.poses) << stats.first_failure;
}

TEST_F(Irb6Kdl, UnreachableOrientationOfAFiveAxisArmIsRefused) {
  // Turn a reachable frame about the world vertical through the flange: the approach axis leaves
  // the arm plane, which a 5-axis arm cannot follow.
  const std::vector<double> q = {0.2, -1.4, 0.3, 0.4, 0.5};
  Eigen::Isometry3d target = solver_.forward(q);
  target.linear() =
      Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitZ()).toRotationMatrix() * target.linear();
  try {
    (void)solver_.inverse(target, q);
    FAIL() << "an orientation out of the arm plane was accepted";
  } catch (const CommandError& e) {
    std::printf("%s\n", e.what());
    EXPECT_EQ(e.code(), error_code::out_of_limits);
    EXPECT_NE(std::string(e.what()).find("did not converge"), std::string::npos) << e.what();
  }
}

// ---- RNT (6 axes), tool frame. ----

class RntKdl : public ::testing::Test {
 protected:
  KdlSolver solver_{robots() / "rnt" / "rnt.urdf", "base_link", "tool"};
};

TEST_F(RntKdl, ChainAndLimitsComeFromTheUrdf) {
  ASSERT_EQ(solver_.joint_count(), 6U);
  const std::vector<std::string> names = {"waist",       "shoulder",  "elbow",
                                          "wrist_pitch", "wrist_yaw", "wrist_roll"};
  EXPECT_EQ(solver_.joint_names(), names);
  EXPECT_NEAR(solver_.upper_limits()[2], 70.0 * kPi / 180.0, 1e-12);
  // Synchronisation pose: tool pointing down 0.25 m below the wrist centre (0.5, 0, 1.1).
  const Eigen::Isometry3d tool = solver_.forward({0.0, 0.0, 0.0, kPi / 2, 0.0, 0.0});
  EXPECT_NEAR(tool.translation().x(), 0.5, 1e-12);
  EXPECT_NEAR(tool.translation().y(), 0.0, 1e-12);
  EXPECT_NEAR(tool.translation().z(), 0.85, 1e-12);
  EXPECT_NEAR(tool.linear()(2, 2), -1.0, 1e-12);
}

TEST_F(RntKdl, InverseOfForwardOnRandomPosesFromANearbySeed) {
  const std::uint32_t seed = test_seed() + 2U;
  SCOPED_TRACE(seed_text(seed - 2U));
  std::mt19937 rng(seed);
  const RoundTripStats stats = round_trip(
      solver_, rng, 600, 0.0, [&](const auto& q) { return nearby(solver_, q, rng, 0.3); });
  report("rnt", "seed = q +- 0.3 rad", stats);
  EXPECT_EQ(stats.solved, stats.poses) << stats.first_failure;
  EXPECT_LE(stats.worst_position, 1e-6);
  EXPECT_LE(stats.worst_orientation, 1e-6);
}

TEST_F(RntKdl, InverseOfForwardOnRandomPosesFromTheSynchronisationPose) {
  const std::uint32_t seed = test_seed() + 3U;
  SCOPED_TRACE(seed_text(seed - 3U));
  std::mt19937 rng(seed);
  const std::vector<double> synchro = {0.0, 0.0, 0.0, kPi / 2, 0.0, 0.0};
  const RoundTripStats stats =
      round_trip(solver_, rng, 500, 0.0, [&](const auto&) { return synchro; });
  report("rnt", "seed = synchronisation pose", stats);
  EXPECT_EQ(stats.solved, stats.poses) << stats.first_failure;
}

TEST_F(RntKdl, UnreachablePositionGivesTheResidual) {
  const std::vector<double> seed = {0.0, 0.0, 0.0, kPi / 2, 0.0, 0.0};
  Eigen::Isometry3d target = solver_.forward(seed);
  target.translation() = Eigen::Vector3d(2.5, 0.0, 0.6);  // 1.5 m beyond the reach
  try {
    (void)solver_.inverse(target, seed);
    FAIL() << "a target 2.5 m away was accepted";
  } catch (const CommandError& e) {
    const std::string what = e.what();
    std::printf("%s\n", what.c_str());
    EXPECT_EQ(e.code(), error_code::out_of_limits);
    EXPECT_NE(what.find("did not converge"), std::string::npos) << what;
    EXPECT_NE(what.find(" m, "), std::string::npos) << what;
    EXPECT_NE(what.find(" rad"), std::string::npos) << what;
  }
}

TEST_F(RntKdl, SolutionOutsideTheJointLimitsNamesTheJoint) {
  // Elbow at 80 deg (limit 70): the wrist centre is then reachable only with the elbow beyond its
  // limit (the mirrored arm needs the waist at 180 deg, beyond 160).
  const std::vector<double> q = {0.0, 0.2, 80.0 * kPi / 180.0, 0.3, 0.1, 0.2};
  const Eigen::Isometry3d target = solver_.forward(q);
  try {
    (void)solver_.inverse(target, {0.0, 0.2, 1.2, 0.3, 0.1, 0.2});
    FAIL() << "a pose needing the elbow at 80 deg was accepted";
  } catch (const CommandError& e) {
    const std::string what = e.what();
    std::printf("%s\n", what.c_str());
    EXPECT_EQ(e.code(), error_code::out_of_limits);
    EXPECT_NE(what.find("joint 2 (elbow)"), std::string::npos) << what;
    EXPECT_NE(what.find("exceeds upper limit 1.221730 rad"), std::string::npos) << what;
  }
}

TEST_F(RntKdl, BadArgumentsAreRefused) {
  try {
    (void)solver_.forward({0.0, 0.0});
    FAIL();
  } catch (const CommandError& e) {
    EXPECT_EQ(e.code(), error_code::bad_argument);
  }
  try {
    (void)solver_.inverse(Eigen::Isometry3d::Identity(), {0.0, 0.0, std::nan(""), 0.0, 0.0, 0.0});
    FAIL();
  } catch (const CommandError& e) {
    EXPECT_EQ(e.code(), error_code::bad_argument);
    EXPECT_NE(std::string(e.what()).find("elbow"), std::string::npos) << e.what();
  }
}

// ---- Without restarts: how often the first attempt from a far seed succeeds. ----

TEST(KdlSolverFirstAttempt, SuccessRateFromTheSynchronisationPose) {
  mrroc::kinematics::KdlSolverOptions single;
  single.restarts = 0;
  struct Robot {
    const char* name;
    std::filesystem::path urdf;
    const char* tip;
    std::vector<double> synchro;
  };
  const std::vector<Robot> robots_under_test = {
      {"irb6", robots() / "irb6" / "irb6.urdf", "flange", {0.0, -kPi / 2, 0.0, 0.0, 0.0}},
      {"rnt", robots() / "rnt" / "rnt.urdf", "tool", {0.0, 0.0, 0.0, kPi / 2, 0.0, 0.0}},
  };
  const std::uint32_t seed = test_seed() + 4U;
  SCOPED_TRACE(seed_text(seed - 4U));
  for (const Robot& robot : robots_under_test) {
    const KdlSolver solver(robot.urdf, "base_link", robot.tip, single);
    std::mt19937 rng(seed);
    const RoundTripStats stats =
        round_trip(solver, rng, 500, 0.0, [&](const auto&) { return robot.synchro; });
    report(robot.name, "no restarts, seed = synchronisation pose", stats);
    // Far seeds often converge to a solution outside the limits (another arm configuration):
    // that is what the restarts are for.
    EXPECT_GT(stats.solved, 200) << robot.name;
  }
}

// ---- Loading errors name the file. ----

TEST(KdlSolverLoading, MissingFileNamesTheFile) {
  const auto path = robots() / "rnt" / "no_such.urdf";
  try {
    KdlSolver solver(path, "base_link", "tool");
    FAIL();
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find(path.string()), std::string::npos) << e.what();
  }
}

TEST(KdlSolverLoading, UnknownLinkNamesTheFileAndTheLinks) {
  const auto path = robots() / "rnt" / "rnt.urdf";
  try {
    KdlSolver solver(path, "base_link", "no_such_link");
    FAIL();
  } catch (const ConfigError& e) {
    const std::string what = e.what();
    std::printf("%s\n", what.c_str());
    EXPECT_NE(what.find(path.string()), std::string::npos) << what;
    EXPECT_NE(what.find("no_such_link"), std::string::npos) << what;
    EXPECT_NE(what.find("tool"), std::string::npos) << what;
  }
}

TEST(KdlSolverLoading, UrdfThatDoesNotParseNamesTheFile) {
  const auto path = std::filesystem::temp_directory_path() /
                    ("mrroc_bad_" + std::to_string(::getpid()) + ".urdf");
  {
    std::ofstream out(path);
    out << "<robot name=\"bad\"><link name=\"a\"/><joint name=\"j\" type=\"revolute\">"
           "<parent link=\"a\"/><child link=\"missing\"/></joint></robot>\n";
  }
  try {
    KdlSolver solver(path, "a", "missing");
    FAIL();
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find(path.string()), std::string::npos) << e.what();
  }
  std::filesystem::remove(path);
}

}  // namespace
