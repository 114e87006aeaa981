/// @file
/// Frame <-> representation conversions of mrroc::kinematics (FRAME, XYZ_EULER_ZYZ,
/// XYZ_ANGLE_AXIS), with randomized round trips (seed from MRROC_TEST_SEED, printed on failure)
/// and exact tests of the singular cases.

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <numbers>
#include <random>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "mrroc/core/error.hpp"
#include "mrroc/kinematics/pose.hpp"
#include "mrroc/msg/edp_instruction.hpp"

namespace {

namespace kin = mrroc::kinematics;
using mrroc::edp::ArmRepresentation;

constexpr double kPi = std::numbers::pi;
constexpr int kSamples = 2000;

std::uint32_t test_seed() {
  if (const char* env = std::getenv("MRROC_TEST_SEED"); env != nullptr && *env != '\0') {
    return static_cast<std::uint32_t>(std::strtoul(env, nullptr, 10));
  }
  return 20240607U;
}

std::string seed_trace(std::uint32_t seed) { return "MRROC_TEST_SEED=" + std::to_string(seed); }

/// A measured figure for the test report (scientific notation).
std::string figure(double x) {
  std::array<char, 32> text{};
  std::snprintf(text.data(), text.size(), "%.3e", x);
  return text.data();
}

/// |a - b| modulo 2 pi.
double angle_difference(double a, double b) { return std::abs(std::remainder(a - b, 2.0 * kPi)); }

double uniform(std::mt19937& rng, double lo, double hi) {
  return std::uniform_real_distribution<double>(lo, hi)(rng);
}

Eigen::Vector3d random_unit_vector(std::mt19937& rng) {
  std::normal_distribution<double> normal;
  Eigen::Vector3d v;
  do {
    v = Eigen::Vector3d(normal(rng), normal(rng), normal(rng));
  } while (v.norm() < 1e-6);
  return v.normalized();
}

/// Uniformly distributed rotation (normalised 4-D Gaussian quaternion).
Eigen::Matrix3d random_rotation(std::mt19937& rng) {
  std::normal_distribution<double> normal;
  Eigen::Quaterniond q(normal(rng), normal(rng), normal(rng), normal(rng));
  return q.normalized().toRotationMatrix();
}

Eigen::Isometry3d random_frame(std::mt19937& rng) {
  Eigen::Isometry3d f = Eigen::Isometry3d::Identity();
  f.linear() = random_rotation(rng);
  f.translation() = Eigen::Vector3d(uniform(rng, -2, 2), uniform(rng, -2, 2), uniform(rng, -2, 2));
  return f;
}

double frame_error(const Eigen::Isometry3d& a, const Eigen::Isometry3d& b) {
  return (a.matrix() - b.matrix()).cwiseAbs().maxCoeff();
}

/// The axis sign rule at angle pi: the first component above the threshold is positive.
Eigen::Vector3d canonical_half_turn_axis(Eigen::Vector3d axis) {
  for (Eigen::Index i = 0; i < 3; ++i) {
    if (std::abs(axis(i)) > kin::kAxisSignThreshold) {
      if (axis(i) < 0.0) axis = -axis;
      break;
    }
  }
  return axis;
}

/// Runs `f` and checks that it throws CommandError with `code` and a text containing `part`.
template <typename F>
void expect_command_error(F&& f, int code, const std::string& part) {
  try {
    f();
    ADD_FAILURE() << "no CommandError; expected one containing \"" << part << "\"";
  } catch (const mrroc::CommandError& e) {
    EXPECT_EQ(e.code(), code) << e.what();
    EXPECT_NE(std::string(e.what()).find(part), std::string::npos)
        << "\"" << e.what() << "\" does not contain \"" << part << "\"";
  }
}

// ---------------------------------------------------------------------------------------------
// FRAME

TEST(PoseFrame, ValuesAreTheRowMajor3x4Matrix) {
  Eigen::Isometry3d f = Eigen::Isometry3d::Identity();
  f.linear() = Eigen::AngleAxisd(kPi / 2, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  f.translation() = Eigen::Vector3d(1.0, 2.0, 3.0);
  const auto v = kin::frame_to_values(f);
  const std::vector<double> expected = {0, -1, 0, 1, 1, 0, 0, 2, 0, 0, 1, 3};
  for (std::size_t i = 0; i < v.size(); ++i) EXPECT_NEAR(v[i], expected[i], 1e-15) << i;
}

TEST(PoseFrame, RandomRoundTrips) {
  const std::uint32_t seed = test_seed();
  SCOPED_TRACE(seed_trace(seed));
  std::mt19937 rng(seed);
  double worst_frame = 0.0;
  double worst_values = 0.0;
  for (int n = 0; n < kSamples; ++n) {
    const Eigen::Isometry3d f = random_frame(rng);
    const std::vector<double> values = kin::to_vector(f, ArmRepresentation::frame);
    ASSERT_EQ(values.size(), 12U);
    const Eigen::Isometry3d back = kin::from_vector(values, ArmRepresentation::frame);
    worst_frame = std::max(worst_frame, frame_error(f, back));
    const std::vector<double> again = kin::to_vector(back, ArmRepresentation::frame);
    for (std::size_t i = 0; i < values.size(); ++i)
      worst_values = std::max(worst_values, std::abs(values[i] - again[i]));
    // The accepted rotation is orthonormal to machine precision.
    ASSERT_LT((back.linear().transpose() * back.linear() - Eigen::Matrix3d::Identity())
                  .cwiseAbs()
                  .maxCoeff(),
              1e-14);
  }
  EXPECT_LT(worst_frame, 1e-14);
  EXPECT_LT(worst_values, 1e-14);
  RecordProperty("worst_frame_roundtrip", figure(worst_frame));
}

TEST(PoseFrame, SlightlyNonOrthonormalRotationIsAcceptedAndRepaired) {
  const std::uint32_t seed = test_seed();
  SCOPED_TRACE(seed_trace(seed));
  std::mt19937 rng(seed);
  for (int n = 0; n < kSamples; ++n) {
    const Eigen::Isometry3d f = random_frame(rng);
    auto values = kin::frame_to_values(f);
    // Perturb every rotation entry by up to 1e-7 (like values printed with 7 digits).
    for (std::size_t i : {0U, 1U, 2U, 4U, 5U, 6U, 8U, 9U, 10U})
      values[i] += uniform(rng, -1e-7, 1e-7);
    const Eigen::Isometry3d back = kin::frame_from_values(values);
    ASSERT_LT((back.linear().transpose() * back.linear() - Eigen::Matrix3d::Identity())
                  .cwiseAbs()
                  .maxCoeff(),
              1e-14);
    ASSERT_NEAR(back.linear().determinant(), 1.0, 1e-14);
    ASSERT_LT(frame_error(f, back), 1e-6);
  }
}

TEST(PoseFrame, InvalidValuesAreRefusedWithTheProblemNamed) {
  using mrroc::edp::error_code::bad_argument;
  const auto good = kin::frame_to_values(Eigen::Isometry3d::Identity());
  auto values = std::vector<double>(good.begin(), good.end());

  auto scaled = values;
  scaled[0] = 1.01;
  expect_command_error([&] { (void)kin::from_vector(scaled, ArmRepresentation::frame); },
                       bad_argument, "FRAME rotation is not orthonormal: max |R^T R - I| = 0.0201");

  auto reflection = values;
  reflection[10] = -1.0;  // diag(1, 1, -1)
  expect_command_error([&] { (void)kin::from_vector(reflection, ArmRepresentation::frame); },
                       bad_argument, "det R = -1");

  auto not_finite = values;
  not_finite[5] = std::nan("");
  expect_command_error([&] { (void)kin::from_vector(not_finite, ArmRepresentation::frame); },
                       bad_argument, "FRAME value 5 (r11) is not a finite number: nan");
  auto infinite_position = values;
  infinite_position[7] = HUGE_VAL;
  expect_command_error([&] { (void)kin::from_vector(infinite_position, ArmRepresentation::frame); },
                       bad_argument, "FRAME value 7 (y) is not a finite number: inf");

  auto short_vector = values;
  short_vector.pop_back();
  expect_command_error([&] { (void)kin::from_vector(short_vector, ArmRepresentation::frame); },
                       bad_argument, "FRAME needs 12 values, got 11");

  // A looser tolerance accepts the scaled matrix (and repairs it).
  const Eigen::Isometry3d repaired = kin::frame_from_values(scaled, 0.05);
  EXPECT_NEAR(repaired.linear().determinant(), 1.0, 1e-14);
}

// ---------------------------------------------------------------------------------------------
// XYZ_EULER_ZYZ

TEST(PoseEulerZyz, MatchesTheDefinition) {
  const Eigen::Vector3d abg(0.3, 1.1, -2.0);
  const Eigen::Matrix3d expected = (Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitZ()) *
                                    Eigen::AngleAxisd(1.1, Eigen::Vector3d::UnitY()) *
                                    Eigen::AngleAxisd(-2.0, Eigen::Vector3d::UnitZ()))
                                       .toRotationMatrix();
  EXPECT_LT((kin::rotation_from_euler_zyz(abg) - expected).cwiseAbs().maxCoeff(), 1e-15);
  const Eigen::Vector3d back = kin::euler_zyz_from_rotation(expected);
  EXPECT_NEAR(back(0), 0.3, 1e-14);
  EXPECT_NEAR(back(1), 1.1, 1e-14);
  EXPECT_NEAR(back(2), -2.0, 1e-14);
}

TEST(PoseEulerZyz, FrameToEulerToFrameOnRandomFrames) {
  const std::uint32_t seed = test_seed();
  SCOPED_TRACE(seed_trace(seed));
  std::mt19937 rng(seed + 1U);
  double worst = 0.0;
  for (int n = 0; n < kSamples; ++n) {
    const Eigen::Isometry3d f = random_frame(rng);
    const std::vector<double> v = kin::to_vector(f, ArmRepresentation::xyz_euler_zyz);
    ASSERT_EQ(v.size(), 6U);
    // Canonical ranges.
    ASSERT_GT(v[3], -kPi);
    ASSERT_LE(v[3], kPi);
    ASSERT_GE(v[4], 0.0);
    ASSERT_LE(v[4], kPi);
    ASSERT_GT(v[5], -kPi);
    ASSERT_LE(v[5], kPi);
    const Eigen::Isometry3d back = kin::from_vector(v, ArmRepresentation::xyz_euler_zyz);
    const double err = frame_error(f, back);
    worst = std::max(worst, err);
    ASSERT_LT(err, 1e-14) << "alpha, beta, gamma = " << v[3] << ", " << v[4] << ", " << v[5];
  }
  RecordProperty("worst_euler_frame_roundtrip", figure(worst));
}

TEST(PoseEulerZyz, CanonicalEulerToFrameToEulerOnRandomValues) {
  const std::uint32_t seed = test_seed();
  SCOPED_TRACE(seed_trace(seed));
  std::mt19937 rng(seed + 2U);
  double worst = 0.0;
  for (int n = 0; n < kSamples; ++n) {
    // Away from the singularities (handled exactly below); near them alpha is ill-conditioned
    // (error ~ 1e-16 / sin(beta)).
    const std::vector<double> v = {uniform(rng, -1, 1),
                                   uniform(rng, -1, 1),
                                   uniform(rng, -1, 1),
                                   uniform(rng, -kPi, kPi),
                                   uniform(rng, 1e-4, kPi - 1e-4),
                                   uniform(rng, -kPi, kPi)};
    const std::vector<double> back = kin::to_vector(
        kin::from_vector(v, ArmRepresentation::xyz_euler_zyz), ArmRepresentation::xyz_euler_zyz);
    double err = 0.0;
    for (std::size_t i = 0; i < 3; ++i) err = std::max(err, std::abs(v[i] - back[i]));
    for (std::size_t i = 3; i < 6; ++i) err = std::max(err, angle_difference(v[i], back[i]));
    worst = std::max(worst, err);
    ASSERT_LT(err, 1e-10) << "alpha, beta, gamma = " << v[3] << ", " << v[4] << ", " << v[5];
  }
  RecordProperty("worst_euler_value_roundtrip", figure(worst));
}

TEST(PoseEulerZyz, SingularBetaZeroPutsEverythingInGamma) {
  const std::uint32_t seed = test_seed();
  SCOPED_TRACE(seed_trace(seed));
  std::mt19937 rng(seed + 3U);
  for (int n = 0; n < kSamples; ++n) {
    const double alpha = uniform(rng, -kPi, kPi);
    const double gamma = uniform(rng, -kPi, kPi);
    const Eigen::Matrix3d r = kin::rotation_from_euler_zyz(Eigen::Vector3d(alpha, 0.0, gamma));
    const Eigen::Vector3d e = kin::euler_zyz_from_rotation(r);
    ASSERT_EQ(e(0), 0.0);
    ASSERT_EQ(e(1), 0.0);
    ASSERT_LT(angle_difference(e(2), alpha + gamma), 1e-14);
    ASSERT_LT((kin::rotation_from_euler_zyz(e) - r).cwiseAbs().maxCoeff(), 1e-15);
  }
  // Exact: the identity and a pure z rotation.
  EXPECT_TRUE(kin::euler_zyz_from_rotation(Eigen::Matrix3d::Identity()).isZero(0.0));
  const Eigen::Vector3d e =
      kin::euler_zyz_from_rotation(Eigen::AngleAxisd(0.7, Eigen::Vector3d::UnitZ()).matrix());
  EXPECT_EQ(e(0), 0.0);
  EXPECT_EQ(e(1), 0.0);
  EXPECT_NEAR(e(2), 0.7, 1e-15);
}

TEST(PoseEulerZyz, SingularBetaPiPutsEverythingInGamma) {
  const std::uint32_t seed = test_seed();
  SCOPED_TRACE(seed_trace(seed));
  std::mt19937 rng(seed + 4U);
  for (int n = 0; n < kSamples; ++n) {
    const double alpha = uniform(rng, -kPi, kPi);
    const double gamma = uniform(rng, -kPi, kPi);
    const Eigen::Matrix3d r = kin::rotation_from_euler_zyz(Eigen::Vector3d(alpha, kPi, gamma));
    const Eigen::Vector3d e = kin::euler_zyz_from_rotation(r);
    // Rz(a) Ry(pi) Rz(g) = Ry(pi) Rz(g - a).
    ASSERT_EQ(e(0), 0.0);
    ASSERT_EQ(e(1), kPi);
    ASSERT_LT(angle_difference(e(2), gamma - alpha), 1e-14);
    ASSERT_LT((kin::rotation_from_euler_zyz(e) - r).cwiseAbs().maxCoeff(), 1e-15);
  }
  // Exact: a half turn about y.
  const Eigen::Matrix3d half_turn = Eigen::Vector3d(-1.0, 1.0, -1.0).asDiagonal();
  const Eigen::Vector3d e = kin::euler_zyz_from_rotation(half_turn);
  EXPECT_EQ(e(0), 0.0);
  EXPECT_EQ(e(1), kPi);
  EXPECT_EQ(e(2), 0.0);
}

TEST(PoseEulerZyz, NearSingularFramesStillRoundTrip) {
  const std::uint32_t seed = test_seed();
  SCOPED_TRACE(seed_trace(seed));
  std::mt19937 rng(seed + 5U);
  for (const double beta :
       {1e-15, 1e-13, 1e-11, 1e-9, 1e-6, kPi - 1e-6, kPi - 1e-9, kPi - 1e-11, kPi - 1e-13}) {
    for (int n = 0; n < kSamples / 10; ++n) {
      const Eigen::Matrix3d r = kin::rotation_from_euler_zyz(
          Eigen::Vector3d(uniform(rng, -kPi, kPi), beta, uniform(rng, -kPi, kPi)));
      const Eigen::Vector3d e = kin::euler_zyz_from_rotation(r);
      ASSERT_LT((kin::rotation_from_euler_zyz(e) - r).cwiseAbs().maxCoeff(), 2e-12)
          << "beta = " << beta;
      // Below kEulerSingularity beta is snapped to 0 or pi.
      ASSERT_NEAR(e(1), beta, beta < 1e-12 || beta > kPi - 1e-12 ? 1e-12 : 1e-15)
          << "beta = " << beta;
    }
  }
}

// ---------------------------------------------------------------------------------------------
// XYZ_ANGLE_AXIS

TEST(PoseAngleAxis, FrameToRotationVectorToFrameOnRandomFrames) {
  const std::uint32_t seed = test_seed();
  SCOPED_TRACE(seed_trace(seed));
  std::mt19937 rng(seed + 6U);
  double worst = 0.0;
  for (int n = 0; n < kSamples; ++n) {
    const Eigen::Isometry3d f = random_frame(rng);
    const std::vector<double> v = kin::to_vector(f, ArmRepresentation::xyz_angle_axis);
    ASSERT_EQ(v.size(), 6U);
    ASSERT_LE(Eigen::Vector3d(v[3], v[4], v[5]).norm(), kPi);
    const Eigen::Isometry3d back = kin::from_vector(v, ArmRepresentation::xyz_angle_axis);
    const double err = frame_error(f, back);
    worst = std::max(worst, err);
    ASSERT_LT(err, 1e-14);
  }
  RecordProperty("worst_angle_axis_frame_roundtrip", figure(worst));
}

TEST(PoseAngleAxis, CanonicalRotationVectorToFrameAndBack) {
  const std::uint32_t seed = test_seed();
  SCOPED_TRACE(seed_trace(seed));
  std::mt19937 rng(seed + 7U);
  double worst = 0.0;
  for (int n = 0; n < kSamples; ++n) {
    const Eigen::Vector3d axis = random_unit_vector(rng);
    const double angle = uniform(rng, 0.0, kPi - 1e-6);
    const Eigen::Vector3d v = axis * angle;
    const Eigen::Vector3d back =
        kin::rotation_vector_from_rotation(kin::rotation_from_rotation_vector(v));
    const double err = (back - v).cwiseAbs().maxCoeff();
    worst = std::max(worst, err);
    ASSERT_LT(err, 1e-14) << "angle " << angle;
  }
  RecordProperty("worst_rotation_vector_roundtrip", figure(worst));
}

TEST(PoseAngleAxis, AngleZeroIsTheZeroVector) {
  EXPECT_TRUE(kin::rotation_vector_from_rotation(Eigen::Matrix3d::Identity()).isZero(0.0));
  EXPECT_TRUE(kin::rotation_from_rotation_vector(Eigen::Vector3d::Zero()).isIdentity(0.0));
  const std::vector<double> v =
      kin::to_vector(Eigen::Isometry3d::Identity(), ArmRepresentation::xyz_angle_axis);
  for (double x : v) EXPECT_EQ(x, 0.0);
  // Tiny angles keep their relative accuracy.
  const std::uint32_t seed = test_seed();
  SCOPED_TRACE(seed_trace(seed));
  std::mt19937 rng(seed + 8U);
  for (int n = 0; n < kSamples; ++n) {
    const Eigen::Vector3d v_small = random_unit_vector(rng) * std::pow(10.0, uniform(rng, -12, -3));
    const Eigen::Vector3d back =
        kin::rotation_vector_from_rotation(kin::rotation_from_rotation_vector(v_small));
    ASSERT_LT((back - v_small).norm(), 1e-9 * v_small.norm() + 1e-17);
  }
}

TEST(PoseAngleAxis, AnglePiHasTheCanonicalAxisSign) {
  const std::uint32_t seed = test_seed();
  SCOPED_TRACE(seed_trace(seed));
  std::mt19937 rng(seed + 9U);
  double worst = 0.0;
  for (int n = 0; n < kSamples; ++n) {
    const Eigen::Vector3d axis = random_unit_vector(rng);
    const Eigen::Vector3d canonical = canonical_half_turn_axis(axis) * kPi;
    // Both signs give the same rotation and the same canonical vector.
    for (const double sign : {1.0, -1.0}) {
      const Eigen::Vector3d back =
          kin::rotation_vector_from_rotation(kin::rotation_from_rotation_vector(sign * axis * kPi));
      const double err = (back - canonical).cwiseAbs().maxCoeff();
      worst = std::max(worst, err);
      ASSERT_LT(err, 1e-12) << "axis " << axis.transpose() << " sign " << sign;
    }
  }
  // Exact half turns about the coordinate axes (also with -0.0 and rounding noise).
  const Eigen::Matrix3d about_x = Eigen::Vector3d(1.0, -1.0, -1.0).asDiagonal();
  const Eigen::Matrix3d about_y = Eigen::Vector3d(-1.0, 1.0, -1.0).asDiagonal();
  const Eigen::Matrix3d about_z = Eigen::Vector3d(-1.0, -1.0, 1.0).asDiagonal();
  EXPECT_LT((kin::rotation_vector_from_rotation(about_x) - Eigen::Vector3d(kPi, 0, 0)).norm(),
            1e-15);
  EXPECT_LT((kin::rotation_vector_from_rotation(about_y) - Eigen::Vector3d(0, kPi, 0)).norm(),
            1e-15);
  EXPECT_LT((kin::rotation_vector_from_rotation(about_z) - Eigen::Vector3d(0, 0, kPi)).norm(),
            1e-15);
  const Eigen::Vector3d minus_y = kin::rotation_vector_from_rotation(
      Eigen::AngleAxisd(kPi, -Eigen::Vector3d::UnitY()).toRotationMatrix());
  EXPECT_LT((minus_y - Eigen::Vector3d(0, kPi, 0)).norm(), 1e-15);
  RecordProperty("worst_half_turn_roundtrip", figure(worst));
}

TEST(PoseAngleAxis, AngleJustBelowPiKeepsItsAxisSign) {
  const std::uint32_t seed = test_seed();
  SCOPED_TRACE(seed_trace(seed));
  std::mt19937 rng(seed + 10U);
  double worst = 0.0;
  for (const double angle : {kPi - 1e-9, kPi - 1e-7, kPi - 1e-11}) {
    for (int n = 0; n < kSamples; ++n) {
      const Eigen::Vector3d v = random_unit_vector(rng) * angle;  // either sign
      const Eigen::Vector3d back =
          kin::rotation_vector_from_rotation(kin::rotation_from_rotation_vector(v));
      const double err = (back - v).cwiseAbs().maxCoeff();
      worst = std::max(worst, err);
      ASSERT_LT(err, 1e-14) << "angle pi - " << kPi - angle;
    }
  }
  RecordProperty("worst_near_half_turn_roundtrip", figure(worst));
}

TEST(PoseAngleAxis, RotationVectorsLongerThanPiAreAcceptedAndCanonicalised) {
  const Eigen::Vector3d axis = Eigen::Vector3d(1.0, 2.0, -2.0) / 3.0;
  const Eigen::Vector3d back =
      kin::rotation_vector_from_rotation(kin::rotation_from_rotation_vector(axis * 4.0));
  EXPECT_LT((back - (-axis) * (2.0 * kPi - 4.0)).norm(), 1e-14);
  const Eigen::Vector3d full_turn =
      kin::rotation_vector_from_rotation(kin::rotation_from_rotation_vector(axis * 2.0 * kPi));
  EXPECT_LT(full_turn.norm(), 1e-14);
}

// ---------------------------------------------------------------------------------------------
// Representation dispatch, relative motion, distance

TEST(PoseRepresentation, SizesAndNonCartesianRepresentations) {
  using mrroc::edp::error_code::bad_argument;
  EXPECT_EQ(kin::representation_size(ArmRepresentation::frame), 12U);
  EXPECT_EQ(kin::representation_size(ArmRepresentation::xyz_euler_zyz), 6U);
  EXPECT_EQ(kin::representation_size(ArmRepresentation::xyz_angle_axis), 6U);
  const Eigen::Isometry3d f = Eigen::Isometry3d::Identity();
  for (const auto r : {ArmRepresentation::joint, ArmRepresentation::motor}) {
    const std::string name = mrroc::edp::to_string(r);
    expect_command_error([&] { (void)kin::to_vector(f, r); }, bad_argument,
                         name + " is not a Cartesian representation");
    expect_command_error([&] { (void)kin::from_vector(std::vector<double>(6, 0.0), r); },
                         bad_argument, name + " is not a Cartesian representation");
  }
  expect_command_error(
      [&] {
        (void)kin::from_vector({0, 0, 0, 0, 0}, ArmRepresentation::xyz_euler_zyz);
      },
      bad_argument, "XYZ_EULER_ZYZ needs 6 values, got 5");
  expect_command_error(
      [&] {
        (void)kin::from_vector(std::vector<double>(12, 0.0), ArmRepresentation::xyz_angle_axis);
      },
      bad_argument, "XYZ_ANGLE_AXIS needs 6 values, got 12");
  expect_command_error(
      [&] {
        (void)kin::from_vector({0, 0, 0, 0, std::nan(""), 0}, ArmRepresentation::xyz_euler_zyz);
      },
      bad_argument, "XYZ_EULER_ZYZ value 4 (beta) is not a finite number");
  expect_command_error(
      [&] {
        (void)kin::from_vector({0, HUGE_VAL, 0, 0, 0, 0}, ArmRepresentation::xyz_angle_axis);
      },
      bad_argument, "XYZ_ANGLE_AXIS value 1 (y) is not a finite number");
  std::array<double, 5> too_small{};
  expect_command_error([&] { kin::to_values(f, ArmRepresentation::frame, too_small); },
                       bad_argument, "FRAME needs 12 values, got 5");
}

TEST(PoseRepresentation, AllRepresentationsDescribeTheSameFrame) {
  const std::uint32_t seed = test_seed();
  SCOPED_TRACE(seed_trace(seed));
  std::mt19937 rng(seed + 11U);
  for (int n = 0; n < kSamples; ++n) {
    const Eigen::Isometry3d f = random_frame(rng);
    const Eigen::Isometry3d via_euler = kin::from_vector(
        kin::to_vector(f, ArmRepresentation::xyz_euler_zyz), ArmRepresentation::xyz_euler_zyz);
    const Eigen::Isometry3d via_axis = kin::from_vector(
        kin::to_vector(f, ArmRepresentation::xyz_angle_axis), ArmRepresentation::xyz_angle_axis);
    const Eigen::Isometry3d via_frame = kin::from_vector(
        kin::to_vector(via_euler, ArmRepresentation::frame), ArmRepresentation::frame);
    ASSERT_LT(frame_error(via_euler, via_axis), 1e-14);
    ASSERT_LT(frame_error(via_frame, f), 1e-14);
  }
}

TEST(PoseRelative, DeltaIsExpressedInTheEndEffectorFrame) {
  // End effector turned +90 deg about z: its x axis is the base's y axis.
  Eigen::Isometry3d base = Eigen::Isometry3d::Identity();
  base.linear() = Eigen::AngleAxisd(kPi / 2, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  base.translation() = Eigen::Vector3d(1.0, 0.0, 0.5);
  Eigen::Isometry3d delta = Eigen::Isometry3d::Identity();
  delta.translation() = Eigen::Vector3d(0.1, 0.0, 0.0);
  const Eigen::Isometry3d goal = kin::compose_relative(base, delta);
  EXPECT_LT((goal.translation() - Eigen::Vector3d(1.0, 0.1, 0.5)).norm(), 1e-15);
  EXPECT_LT((goal.linear() - base.linear()).norm(), 1e-15);

  // A rotation about the end effector's own x axis (= base y) keeps the origin.
  Eigen::Isometry3d turn = Eigen::Isometry3d::Identity();
  turn.linear() = Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitX()).toRotationMatrix();
  const Eigen::Isometry3d turned = kin::compose_relative(base, turn);
  EXPECT_LT((turned.translation() - base.translation()).norm(), 1e-15);
  const Eigen::Matrix3d expected =
      Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitY()).toRotationMatrix() * base.linear();
  EXPECT_LT((turned.linear() - expected).norm(), 1e-15);

  const std::uint32_t seed = test_seed();
  SCOPED_TRACE(seed_trace(seed));
  std::mt19937 rng(seed + 12U);
  for (int n = 0; n < kSamples; ++n) {
    const Eigen::Isometry3d b = random_frame(rng);
    const Eigen::Isometry3d d = random_frame(rng);
    const Eigen::Isometry3d g = kin::compose_relative(b, d);
    ASSERT_LT((g.translation() - (b.translation() + b.linear() * d.translation())).norm(), 1e-14);
    ASSERT_LT((g.linear() - b.linear() * d.linear()).norm(), 1e-14);
    // Going back: base^-1 * goal is the delta.
    ASSERT_LT(frame_error(b.inverse() * g, d), 1e-13);
  }
}

TEST(PoseDistance, GeodesicAngleIsAccurateForSmallAndLargeAngles) {
  const std::uint32_t seed = test_seed();
  SCOPED_TRACE(seed_trace(seed));
  std::mt19937 rng(seed + 13U);
  for (int n = 0; n < kSamples; ++n) {
    const Eigen::Matrix3d a = random_rotation(rng);
    const double angle = n % 2 == 0 ? std::pow(10.0, uniform(rng, -12, 0)) : uniform(rng, 0, kPi);
    const Eigen::Matrix3d b =
        a * Eigen::AngleAxisd(angle, random_unit_vector(rng)).toRotationMatrix();
    ASSERT_NEAR(kin::rotation_distance(a, b), angle, 1e-15 + 1e-10 * angle) << angle;
  }
}

}  // namespace
