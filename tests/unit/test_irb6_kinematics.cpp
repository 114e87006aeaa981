/// @file
/// IRb-6 kinematics (mrroc::robots::irb6): transmissions, limits, analytic forward kinematics
/// against KDL on irb6.urdf, analytic inverse kinematics, the 5-axis orientation rule, kinematic
/// models, tool and local corrector. Randomized tests take their seed from MRROC_TEST_SEED
/// (printed on failure).

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <numbers>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <toml++/toml.h>
#include <urdf_parser/urdf_parser.h>
#include <kdl/chain.hpp>
#include <kdl/chainfksolverpos_recursive.hpp>
#include <kdl/frames.hpp>
#include <kdl/jntarray.hpp>
#include <kdl/tree.hpp>
#include <kdl_parser/kdl_parser.hpp>

#include "mrroc/core/error.hpp"
#include "mrroc/edp/arm_kinematics.hpp"
#include "mrroc/kinematics/irb6.hpp"
#include "mrroc/kinematics/pose.hpp"
#include "mrroc/msg/edp_instruction.hpp"
#include "mrroc/robot/robot_model.hpp"

#ifndef MRROC_SOURCE_DIR
#error "MRROC_SOURCE_DIR must be defined (absolute path of the source tree)"
#endif

namespace {

namespace irb6 = mrroc::robots::irb6;
using irb6::Irb6Geometry;
using irb6::JointPosition;
using irb6::kAxes;
using irb6::MotorPosition;
using mrroc::edp::error_code::bad_argument;
using mrroc::edp::error_code::out_of_limits;

constexpr double kPi = std::numbers::pi;
constexpr int kSamples = 2000;

constexpr double deg(double d) { return d * kPi / 180.0; }

std::filesystem::path robot_dir() {
  return std::filesystem::path(MRROC_SOURCE_DIR) / "robots" / "irb6";
}

/// The kinematic models robots/irb6/parameters.toml gives (0 nominal, 1 calibrated).
const std::vector<Irb6Geometry>& file_models() {
  static const std::vector<Irb6Geometry> models =
      irb6::kinematic_models(mrroc::load_robot_model(robot_dir()));
  return models;
}
Irb6Geometry nominal() { return file_models().at(irb6::kNominalModel); }
Irb6Geometry calibrated() { return file_models().at(irb6::kCalibratedModel); }

std::uint32_t test_seed() {
  if (const char* env = std::getenv("MRROC_TEST_SEED"); env != nullptr && *env != '\0') {
    return static_cast<std::uint32_t>(std::strtoul(env, nullptr, 10));
  }
  return 20240607U;
}

std::string seed_trace(std::uint32_t seed) { return "MRROC_TEST_SEED=" + std::to_string(seed); }

std::string figure(double x) {
  std::array<char, 32> text{};
  std::snprintf(text.data(), text.size(), "%.3e", x);
  return text.data();
}

std::string show(const std::array<double, kAxes>& v) {
  std::array<char, 160> text{};
  std::snprintf(text.data(), text.size(), "(%.17g, %.17g, %.17g, %.17g, %.17g)", v[0], v[1], v[2],
                v[3], v[4]);
  return text.data();
}

double uniform(std::mt19937& rng, double lo, double hi) {
  return std::uniform_real_distribution<double>(lo, hi)(rng);
}

bool linkage_ok(const JointPosition& q) {
  const double fed = q[1] + q[2] + kPi / 2;
  return q[1] >= irb6::kLowerArmScrew.min_angle && q[1] <= irb6::kLowerArmScrew.max_angle &&
         fed >= irb6::kUpperArmScrew.min_angle && fed <= irb6::kUpperArmScrew.max_angle;
}

/// Joints uniformly within the joint limits, shrunk by `margin` [rad], and within the linkage
/// ranges (rejection sampling).
JointPosition random_joints(std::mt19937& rng, double margin = 0.0) {
  for (;;) {
    JointPosition q{};
    for (std::size_t i = 0; i < kAxes; ++i)
      q[i] = uniform(rng, irb6::kJointLowerLimits[i] + margin, irb6::kJointUpperLimits[i] - margin);
    const double fed = q[1] + q[2] + kPi / 2;
    if (linkage_ok(q) && fed >= irb6::kUpperArmScrew.min_angle + margin) return q;
  }
}

MotorPosition random_motors(std::mt19937& rng) {
  MotorPosition m{};
  for (std::size_t i = 0; i < kAxes; ++i)
    m[i] = uniform(rng, irb6::kMotorLowerLimits[i], irb6::kMotorUpperLimits[i]);
  return m;
}

double max_difference(const std::array<double, kAxes>& a, const std::array<double, kAxes>& b) {
  double out = 0.0;
  for (std::size_t i = 0; i < kAxes; ++i) out = std::max(out, std::abs(a[i] - b[i]));
  return out;
}

double position_error(const Eigen::Isometry3d& a, const Eigen::Isometry3d& b) {
  return (a.translation() - b.translation()).cwiseAbs().maxCoeff();
}
double rotation_error(const Eigen::Isometry3d& a, const Eigen::Isometry3d& b) {
  return (a.linear() - b.linear()).cwiseAbs().maxCoeff();
}

Eigen::Isometry3d translation(double x, double y, double z) {
  Eigen::Isometry3d f = Eigen::Isometry3d::Identity();
  f.translation() = Eigen::Vector3d(x, y, z);
  return f;
}

Eigen::Vector3d random_unit_vector(std::mt19937& rng) {
  std::normal_distribution<double> normal;
  Eigen::Vector3d v;
  do {
    v = Eigen::Vector3d(normal(rng), normal(rng), normal(rng));
  } while (v.norm() < 1e-6);
  return v.normalized();
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

template <typename F>
std::string command_error_text(F&& f) {
  try {
    f();
  } catch (const mrroc::CommandError& e) {
    return e.what();
  }
  return "(no CommandError)";
}

std::filesystem::path urdf_path() {
  return std::filesystem::path(MRROC_SOURCE_DIR) / "robots" / "irb6" / "irb6.urdf";
}

// ---------------------------------------------------------------------------------------------
// Transmissions

TEST(Irb6Transmission, SynchroMotorPositionsGiveTheSynchroJointsExactly) {
  const JointPosition q = irb6::joints_from_motors(irb6::kSynchroMotorPositions);
  for (std::size_t i = 0; i < kAxes; ++i) {
    EXPECT_EQ(q[i], irb6::kSynchroJointPositions[i]) << "joint " << i;
  }
  EXPECT_EQ(q[1], -kPi / 2);
  const MotorPosition m = irb6::motors_from_joints(irb6::kSynchroJointPositions);
  for (std::size_t i = 0; i < kAxes; ++i) {
    EXPECT_EQ(m[i], irb6::kSynchroMotorPositions[i]) << "motor " << i;
  }
}

TEST(Irb6Transmission, RatiosAtTheSynchroPose) {
  // d motor / d joint by central differences: the harmonic drives are linear; the ball screws
  // give about 173.7 (lower arm) and 175.1 (upper arm) there (robots/irb6/README.md).
  const double h = 1e-6;
  std::array<double, kAxes> ratio{};
  for (std::size_t i = 0; i < kAxes; ++i) {
    JointPosition plus = irb6::kSynchroJointPositions;
    JointPosition minus = irb6::kSynchroJointPositions;
    plus[i] += h;
    minus[i] -= h;
    ratio[i] = (irb6::motors_from_joints(plus)[i] - irb6::motors_from_joints(minus)[i]) / (2 * h);
  }
  EXPECT_NEAR(ratio[0], -158.0, 1e-6);
  EXPECT_NEAR(ratio[1], 173.7, 0.05);
  // The upper-arm screw drives q1 + q2 + pi/2: moving q2 alone moves only motor 2.
  EXPECT_NEAR(ratio[2], 175.1, 0.05);
  EXPECT_NEAR(ratio[3], -128.0, 1e-6);
  EXPECT_NEAR(ratio[4], -76.8, 1e-6);
  RecordProperty("lower_arm_ratio_at_synchro", figure(ratio[1]));
  RecordProperty("upper_arm_ratio_at_synchro", figure(ratio[2]));
}

TEST(Irb6Transmission, CouplingsOfTheUpperArmScrewAndTheWristRoll) {
  JointPosition q = irb6::kSynchroJointPositions;
  const MotorPosition m0 = irb6::motors_from_joints(q);
  // Moving the lower arm alone changes the angle fed to the upper-arm screw.
  q[1] += 0.1;
  const MotorPosition m1 = irb6::motors_from_joints(q);
  EXPECT_GT(std::abs(m1[2] - m0[2]), 1.0);
  // Holding q1 + q2 constant keeps the upper-arm motor still.
  q[2] -= 0.1;
  EXPECT_NEAR(irb6::motors_from_joints(q)[2], m0[2], 1e-9);

  // Turning the pitch motor alone turns the roll joint; turning both together does not.
  MotorPosition m = irb6::kSynchroMotorPositions;
  m[3] += 128.0;
  JointPosition j = irb6::joints_from_motors(m);
  EXPECT_NEAR(j[3], -1.0, 1e-12);
  EXPECT_NEAR(j[4], 128.0 / 76.8, 1e-12);
  m[4] += 128.0;
  j = irb6::joints_from_motors(m);
  EXPECT_NEAR(j[3], -1.0, 1e-12);
  EXPECT_NEAR(j[4], 0.0, 1e-12);
}

TEST(Irb6Transmission, MotorToJointToMotorOverTheMotorRanges) {
  const std::uint32_t seed = test_seed();
  SCOPED_TRACE(seed_trace(seed));
  std::mt19937 rng(seed);
  double worst = 0.0;
  std::vector<MotorPosition> samples;
  for (int n = 0; n < kSamples; ++n) samples.push_back(random_motors(rng));
  samples.push_back(irb6::kMotorLowerLimits);
  samples.push_back(irb6::kMotorUpperLimits);
  for (const MotorPosition& m : samples) {
    // Every motor position within the motor limits is inside the linkage ranges.
    const JointPosition q = irb6::joints_from_motors(m);
    const MotorPosition back = irb6::motors_from_joints(q);
    const double err = max_difference(m, back);
    worst = std::max(worst, err);
    ASSERT_LT(err, 1e-9) << "motors " << show(m);
  }
  RecordProperty("worst_motor_roundtrip_rad", figure(worst));
}

TEST(Irb6Transmission, JointToMotorToJointOverTheJointRanges) {
  const std::uint32_t seed = test_seed();
  SCOPED_TRACE(seed_trace(seed));
  std::mt19937 rng(seed + 1U);
  double worst = 0.0;
  for (int n = 0; n < kSamples; ++n) {
    const JointPosition q = random_joints(rng);
    const JointPosition back = irb6::joints_from_motors(irb6::motors_from_joints(q));
    const double err = max_difference(q, back);
    worst = std::max(worst, err);
    ASSERT_LT(err, 1e-12) << "joints " << show(q);
  }
  RecordProperty("worst_joint_roundtrip_rad", figure(worst));
}

TEST(Irb6Transmission, OutOfRangeMotorsAndJointsAreRefused) {
  // Screw far too long: no triangle.
  MotorPosition m = irb6::kSynchroMotorPositions;
  m[1] = 1000.0;
  expect_command_error([&] { (void)irb6::joints_from_motors(m); }, out_of_limits,
                       "motor 1 (lower_arm) position 1000.0 rad: ball-screw length");
  m = irb6::kSynchroMotorPositions;
  m[2] = -120.0;
  expect_command_error([&] { (void)irb6::joints_from_motors(m); }, out_of_limits,
                       "has no linkage triangle solution (the upper-arm linkage spans 101.444 .. "
                       "381.444 mm)");
  // Triangle solvable (-49.3 deg), but below the -45 deg linkage limit.
  m[2] = -111.5;
  expect_command_error([&] { (void)irb6::joints_from_motors(m); }, out_of_limits,
                       "motor 2 (upper_arm) position -111.5 rad gives q1 + q2 + pi/2 = -0.8");
  expect_command_error([&] { (void)irb6::joints_from_motors(m); }, out_of_limits,
                       "below the upper-arm linkage limit -0.785398 rad");
  m = irb6::kSynchroMotorPositions;
  m[4] = std::nan("");
  expect_command_error([&] { (void)irb6::joints_from_motors(m); }, bad_argument,
                       "motor 4 (wrist_roll) position nan is not a finite number");

  // Both joints inside their own limits, the pair outside the upper-arm linkage.
  JointPosition q = irb6::kSynchroJointPositions;
  q[1] = deg(-130);
  q[2] = deg(-25);
  EXPECT_EQ(command_error_text([&] { (void)irb6::motors_from_joints(q); }),
            "joint 2 (upper_arm) position: q1 + q2 + pi/2 = -1.134464 rad is below the upper-arm "
            "linkage limit -0.785398 rad");
  EXPECT_EQ(command_error_text([&] { irb6::check_joint_limits(q); }),
            "joint 2 (upper_arm) target: q1 + q2 + pi/2 = -1.134464 rad is below the upper-arm "
            "linkage limit -0.785398 rad");
  q = irb6::kSynchroJointPositions;
  q[1] = deg(30);
  expect_command_error([&] { (void)irb6::motors_from_joints(q); }, out_of_limits,
                       "joint 1 (lower_arm) position: q1 = 0.523599 rad exceeds the lower-arm "
                       "linkage limit 0.436332 rad");
}

// ---------------------------------------------------------------------------------------------
// Limits

TEST(Irb6Limits, JointLimitTableEqualsTheUrdf) {
  const auto model = urdf::parseURDFFile(urdf_path().string());
  ASSERT_TRUE(model) << urdf_path();
  for (std::size_t i = 0; i < kAxes; ++i) {
    const auto joint = model->getJoint(irb6::kJointNames[i]);
    ASSERT_TRUE(joint && joint->limits) << irb6::kJointNames[i];
    EXPECT_NEAR(joint->limits->lower, irb6::kJointLowerLimits[i], 1e-12) << irb6::kJointNames[i];
    EXPECT_NEAR(joint->limits->upper, irb6::kJointUpperLimits[i], 1e-12) << irb6::kJointNames[i];
  }
}

TEST(Irb6Limits, JointLimitMessagesNameTheJoint) {
  JointPosition q = irb6::kSynchroJointPositions;
  EXPECT_NO_THROW(irb6::check_joint_limits(q));
  q[2] = 0.81;
  EXPECT_EQ(command_error_text([&] { irb6::check_joint_limits(q); }),
            "joint 2 (upper_arm) target 0.810000 rad exceeds upper limit 0.698132 rad");
  q[2] = 0.0;
  q[3] = -1.6;
  EXPECT_EQ(command_error_text([&] { irb6::check_joint_limits(q, "position"); }),
            "joint 3 (wrist_pitch) position -1.600000 rad is below lower limit -1.570796 rad");
  q[3] = std::nan("");
  expect_command_error([&] { irb6::check_joint_limits(q); }, bad_argument,
                       "joint 3 (wrist_pitch) target nan is not a finite number");
}

TEST(Irb6Limits, MotorLimitMessagesNameTheMotor) {
  MotorPosition m = irb6::kSynchroMotorPositions;
  EXPECT_NO_THROW(irb6::check_motor_limits(m));
  m[2] = 101.2;
  EXPECT_EQ(command_error_text([&] { irb6::check_motor_limits(m); }),
            "motor 2 (upper_arm) position 101.2 rad exceeds upper limit 100.0 rad");
  m[2] = 0.0;
  m[0] = -471.5;
  EXPECT_EQ(command_error_text([&] { irb6::check_motor_limits(m, "target"); }),
            "motor 0 (column) target -471.5 rad is below lower limit -470.0 rad");
  m[0] = 0.0;
  m[4] = 490.25;
  expect_command_error([&] { irb6::check_motor_limits(m); }, out_of_limits,
                       "motor 4 (wrist_roll) position 490.25 rad exceeds upper limit 490.0 rad");
}

TEST(Irb6Limits, FixedSizeFromValues) {
  const std::vector<double> four = {0, 0, 0, 0};
  EXPECT_EQ(command_error_text([&] { (void)irb6::axes_from_values(four, "joint target"); }),
            "joint target has 4 values, the IRb-6 has 5 axes");
  const std::vector<double> five = {1, 2, 3, 4, 5};
  const auto a = irb6::axes_from_values(five, "joint target");
  EXPECT_EQ(a[4], 5.0);
}

// ---------------------------------------------------------------------------------------------
// Forward kinematics

class Irb6Kdl : public ::testing::Test {
 protected:
  void SetUp() override {
    const auto model = urdf::parseURDFFile(urdf_path().string());
    ASSERT_TRUE(model) << urdf_path();
    KDL::Tree tree;
    ASSERT_TRUE(kdl_parser::treeFromUrdfModel(*model, tree));
    ASSERT_TRUE(tree.getChain("base_link", "flange", chain_));
    ASSERT_EQ(chain_.getNrOfJoints(), kAxes);
  }

  Eigen::Isometry3d kdl_fk(const JointPosition& q) const {
    KDL::ChainFkSolverPos_recursive solver(chain_);
    KDL::JntArray joints(kAxes);
    for (unsigned int i = 0; i < kAxes; ++i) joints(i) = q[i];
    KDL::Frame frame;
    EXPECT_GE(solver.JntToCart(joints, frame), 0);
    Eigen::Isometry3d out = Eigen::Isometry3d::Identity();
    for (int r = 0; r < 3; ++r) {
      for (int c = 0; c < 3; ++c) out.linear()(r, c) = frame.M(r, c);
      out.translation()(r) = frame.p(r);
    }
    return out;
  }

  KDL::Chain chain_;
};

TEST_F(Irb6Kdl, AnalyticForwardKinematicsEqualsKdlOnTheUrdf) {
  const std::uint32_t seed = test_seed();
  SCOPED_TRACE(seed_trace(seed));
  std::mt19937 rng(seed + 2U);
  std::vector<JointPosition> poses;
  for (int n = 0; n < kSamples; ++n) {
    // Beyond the joint limits too: the formula holds everywhere.
    JointPosition q{};
    for (double& x : q) x = uniform(rng, -kPi, kPi);
    poses.push_back(n % 2 == 0 ? q : random_joints(rng));
  }
  poses.push_back(irb6::kSynchroJointPositions);
  double worst_position = 0.0;
  double worst_rotation = 0.0;
  for (const JointPosition& q : poses) {
    const Eigen::Isometry3d analytic = irb6::forward_kinematics(q, nominal());
    const Eigen::Isometry3d kdl = kdl_fk(q);
    worst_position = std::max(worst_position, position_error(analytic, kdl));
    worst_rotation = std::max(worst_rotation, rotation_error(analytic, kdl));
    ASSERT_LT(position_error(analytic, kdl), 1e-9) << "q = " << show(q);
    ASSERT_LT(rotation_error(analytic, kdl), 1e-9) << "q = " << show(q);
  }
  RecordProperty("worst_fk_vs_kdl_position_m", figure(worst_position));
  RecordProperty("worst_fk_vs_kdl_rotation", figure(worst_rotation));
}

TEST(Irb6Forward, HandCheckedPoses) {
  // Synchronisation pose: lower arm up, upper arm and wrist along +x, approach +x, flange x down.
  const Eigen::Isometry3d sync = irb6::forward_kinematics(irb6::kSynchroJointPositions, nominal());
  EXPECT_LT((sync.translation() - Eigen::Vector3d(0.86, 0.0, 1.155)).norm(), 1e-15);
  EXPECT_LT((sync.linear().col(2) - Eigen::Vector3d::UnitX()).norm(), 1e-15);
  EXPECT_LT((sync.linear().col(0) + Eigen::Vector3d::UnitZ()).norm(), 1e-15);
  // Wrist pitched -90 deg: flange d5 above the wrist, approach up.
  const Eigen::Isometry3d up =
      irb6::forward_kinematics({0.0, -kPi / 2, 0.0, -kPi / 2, 0.0}, nominal());
  EXPECT_LT((up.translation() - Eigen::Vector3d(0.67, 0.0, 1.345)).norm(), 1e-15);
  EXPECT_LT((up.linear().col(2) - Eigen::Vector3d::UnitZ()).norm(), 1e-15);
  // The default gripper: 0.25 m along the approach.
  const Eigen::Isometry3d tip = irb6::forward_kinematics(irb6::kSynchroJointPositions, nominal(),
                                                         translation(0.0, 0.0, 0.25));
  EXPECT_LT((tip.translation() - Eigen::Vector3d(1.11, 0.0, 1.155)).norm(), 1e-15);
}

/// The flange chain (base_link -> flange) of irb6.urdf with its four length origins replaced: the
/// column height d1 (origin of joint lower_arm), a2 (upper_arm), a3 (wrist_pitch) and d5
/// (flange_joint), written as the URDF writes them.
KDL::Chain urdf_chain_with_lengths(double d1, double a2, double a3, double d5) {
  std::ifstream in(urdf_path());
  std::stringstream text;
  text << in.rdbuf();
  std::string urdf = text.str();
  const auto replace = [&](const std::string& from, const std::string& to) {
    const std::size_t at = urdf.find(from);
    EXPECT_NE(at, std::string::npos) << from;
    EXPECT_EQ(urdf.find(from, at + 1), std::string::npos) << from << " is not unique";
    if (at != std::string::npos) urdf.replace(at, from.size(), to);
  };
  const auto number = [](double x) {
    std::array<char, 32> t{};
    std::snprintf(t.data(), t.size(), "%.17g", x);
    return std::string(t.data());
  };
  replace(R"(<origin xyz="0 0 0.70" rpy="0 0 0"/>)",
          R"(<origin xyz="0 0 )" + number(d1) + R"(" rpy="0 0 0"/>)");
  replace(R"(<origin xyz="0.455 0 0" rpy="0 1.5707963267948966 0"/>)",
          R"(<origin xyz=")" + number(a2) + R"( 0 0" rpy="0 1.5707963267948966 0"/>)");
  replace(R"(<origin xyz="0.67 0 0" rpy="0 0 0"/>)",
          R"(<origin xyz=")" + number(a3) + R"( 0 0" rpy="0 0 0"/>)");
  replace(R"(<origin xyz="0.19 0 0" rpy="0 1.5707963267948966 0"/>)",
          R"(<origin xyz=")" + number(d5) + R"( 0 0" rpy="0 1.5707963267948966 0"/>)");
  KDL::Chain chain;
  const auto model = urdf::parseURDF(urdf);
  EXPECT_TRUE(model);
  KDL::Tree tree;
  if (model && kdl_parser::treeFromUrdfModel(*model, tree)) {
    EXPECT_TRUE(tree.getChain("base_link", "flange", chain));
  }
  EXPECT_EQ(chain.getNrOfJoints(), kAxes);
  return chain;
}

Eigen::Isometry3d chain_fk(const KDL::Chain& chain, const JointPosition& q) {
  KDL::ChainFkSolverPos_recursive solver(chain);
  KDL::JntArray joints(kAxes);
  for (unsigned int i = 0; i < kAxes; ++i) joints(i) = q[i];
  KDL::Frame frame;
  EXPECT_GE(solver.JntToCart(joints, frame), 0);
  Eigen::Isometry3d out = Eigen::Isometry3d::Identity();
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) out.linear()(r, c) = frame.M(r, c);
    out.translation()(r) = frame.p(r);
  }
  return out;
}

TEST(Irb6Forward, KinematicModelOneMovesTheToolByTheCalibratedDifference) {
  // The lengths as parameters.toml writes them, read here with the TOML parser alone.
  const toml::table file = toml::parse_file((robot_dir() / "parameters.toml").string());
  const auto length = [&](const char* table, const char* key) {
    const auto v = table == nullptr ? file["robot"]["kinematics"][key].value<double>()
                                    : file["robot"]["kinematics"][table][key].value<double>();
    EXPECT_TRUE(v.has_value()) << key;
    return v.value_or(0.0);
  };
  const double d1 = length(nullptr, "d1");
  const double a2 = length(nullptr, "a2");
  const double a3 = length(nullptr, "a3");
  const double d5 = length(nullptr, "d5");
  // The calibrated table leaves d1 out: it keeps its nominal value.
  EXPECT_FALSE(file["robot"]["kinematics"]["calibrated"]["d1"].node());
  const double a2c = length("calibrated", "a2");
  const double a3c = length("calibrated", "a3");
  const double d5c = length("calibrated", "d5");
  // The calibration changes each length by millimetres.
  EXPECT_GT(std::abs(a2c - a2), 1e-3);
  EXPECT_GT(std::abs(a3c - a3), 1e-3);
  EXPECT_GT(std::abs(d5c - d5), 1e-4);
  const KDL::Chain urdf_nominal = urdf_chain_with_lengths(d1, a2, a3, d5);
  const KDL::Chain urdf_calibrated = urdf_chain_with_lengths(d1, a2c, a3c, d5c);

  // The kinematics the EDP and the ECP build from the file, with the gripper as tool.
  const mrroc::RobotModel model = mrroc::load_robot_model(robot_dir());
  const auto k0 = mrroc::edp::make_arm_kinematics(model);
  const auto k1 = mrroc::edp::make_arm_kinematics(model);
  ASSERT_EQ(k1->model_count(), 2);
  const Eigen::Isometry3d gripper = translation(0.0, 0.0, 0.25);
  k0->set_tool(gripper);
  k1->set_tool(gripper);
  k1->select_model(irb6::kCalibratedModel, 0);
  EXPECT_EQ(k1->model_no(), irb6::kCalibratedModel);
  expect_command_error([&] { k1->select_model(2, 0); }, bad_argument,
                       "kinematic model 2 does not exist for the IRb-6");

  // At the synchronisation pose the tool point is (a3 + d5 + 0.25, 0, d1 + a2): by hand, model 1
  // moves it by (da3 + dd5, 0, da2).
  const std::vector<double> sync(irb6::kSynchroJointPositions.begin(),
                                 irb6::kSynchroJointPositions.end());
  const Eigen::Vector3d moved = k1->forward(sync).translation() - k0->forward(sync).translation();
  EXPECT_NEAR(moved.x(), (a3c - a3) + (d5c - d5), 1e-12);
  EXPECT_NEAR(moved.y(), 0.0, 1e-15);
  EXPECT_NEAR(moved.z(), a2c - a2, 1e-12);
  EXPECT_GT(moved.norm(), 4e-3);

  // Everywhere: the difference equals that of the URDF chains with the two sets of lengths.
  const std::uint32_t seed = test_seed();
  SCOPED_TRACE(seed_trace(seed));
  std::mt19937 rng(seed + 3U);
  double worst = 0.0;
  double smallest_move = 1.0;
  for (int n = 0; n < kSamples; ++n) {
    const JointPosition q = random_joints(rng);
    const std::vector<double> qv(q.begin(), q.end());
    const Eigen::Isometry3d t0 = k0->forward(qv);
    const Eigen::Isometry3d t1 = k1->forward(qv);
    const Eigen::Vector3d expected = (chain_fk(urdf_calibrated, q) * gripper).translation() -
                                     (chain_fk(urdf_nominal, q) * gripper).translation();
    const Eigen::Vector3d got = t1.translation() - t0.translation();
    worst = std::max(worst, (got - expected).norm());
    smallest_move = std::min(smallest_move, got.norm());
    ASSERT_LT((got - expected).norm(), 1e-9) << "q = " << show(q);
    // Orientation does not depend on the lengths.
    ASSERT_LT(rotation_error(t0, t1), 1e-15) << "q = " << show(q);
    // The EDP's model 1 reaches its own frames back.
    const std::vector<double> back = k1->inverse(t1, qv);
    JointPosition solved{};
    std::copy(back.begin(), back.end(), solved.begin());
    ASSERT_LT(max_difference(solved, q), 1e-9) << "q = " << show(q);
  }
  EXPECT_GT(smallest_move, 1e-3);
  RecordProperty("worst_model1_move_vs_urdf_m", figure(worst));
  RecordProperty("smallest_model1_move_m", figure(smallest_move));
}

// ---------------------------------------------------------------------------------------------
// Inverse kinematics

TEST(Irb6Inverse, RoundTripsOnRandomReachablePoses) {
  const std::uint32_t seed = test_seed();
  SCOPED_TRACE(seed_trace(seed));
  std::mt19937 rng(seed + 4U);
  double worst_joint = 0.0;
  double worst_position = 0.0;
  double worst_rotation = 0.0;
  for (const Irb6Geometry& g : {nominal(), calibrated()}) {
    for (int n = 0; n < kSamples; ++n) {
      const JointPosition q = random_joints(rng);
      // A seed far from the answer: the solution within the limits is unique.
      const JointPosition seed_joints = random_joints(rng);
      const Eigen::Isometry3d x = irb6::forward_kinematics(q, g);
      const JointPosition solved = irb6::inverse_kinematics(x, seed_joints, g);
      const double joint_err = max_difference(solved, q);
      const Eigen::Isometry3d again = irb6::forward_kinematics(solved, g);
      worst_joint = std::max(worst_joint, joint_err);
      worst_position = std::max(worst_position, position_error(again, x));
      worst_rotation = std::max(worst_rotation, rotation_error(again, x));
      ASSERT_LT(joint_err, 1e-9) << "q = " << show(q) << ", IK gave " << show(solved);
      ASSERT_LT(position_error(again, x), 1e-12) << "q = " << show(q);
      ASSERT_LT(rotation_error(again, x), 1e-12) << "q = " << show(q);
    }
  }
  RecordProperty("worst_ik_joint_error_rad", figure(worst_joint));
  RecordProperty("worst_fk_ik_position_error_m", figure(worst_position));
  RecordProperty("worst_fk_ik_rotation_error", figure(worst_rotation));
}

TEST(Irb6Inverse, SynchroPoseAndJointLimitCorners) {
  const JointPosition seed = irb6::kSynchroJointPositions;
  const JointPosition sync = irb6::inverse_kinematics(
      irb6::forward_kinematics(irb6::kSynchroJointPositions, nominal()), seed, nominal());
  EXPECT_LT(max_difference(sync, irb6::kSynchroJointPositions), 1e-14);
  // Every corner of the joint box that the linkage allows.
  int corners = 0;
  for (int bits = 0; bits < 32; ++bits) {
    JointPosition q{};
    for (std::size_t i = 0; i < kAxes; ++i)
      q[i] = (bits >> i) & 1 ? irb6::kJointUpperLimits[i] : irb6::kJointLowerLimits[i];
    if (!linkage_ok(q)) continue;
    ++corners;
    const JointPosition solved =
        irb6::inverse_kinematics(irb6::forward_kinematics(q, nominal()), seed, nominal());
    EXPECT_LT(max_difference(solved, q), 1e-9) << "corner " << show(q);
  }
  EXPECT_GE(corners, 16);
}

TEST(Irb6Inverse, WristCentreStaysInFrontOfTheColumnAxis) {
  // The reason the column angle is never ambiguous: over the joint and linkage limits the wrist
  // centre is at least 0.18 m from the column axis (on the arm's side).
  const std::uint32_t seed = test_seed();
  SCOPED_TRACE(seed_trace(seed));
  std::mt19937 rng(seed + 5U);
  double nearest = 1.0;
  for (const Irb6Geometry& g : {nominal(), calibrated()}) {
    for (int n = 0; n < kSamples; ++n) {
      const JointPosition q = random_joints(rng);
      const double reach = g.a2 * std::cos(q[1]) + g.a3 * std::cos(q[1] + q[2] + kPi / 2);
      nearest = std::min(nearest, reach);
    }
  }
  EXPECT_GT(nearest, 0.18);
  RecordProperty("nearest_wrist_centre_to_column_axis_m", figure(nearest));
}

TEST(Irb6Inverse, ToolAndLocalCorrector) {
  const std::uint32_t seed = test_seed();
  SCOPED_TRACE(seed_trace(seed));
  std::mt19937 rng(seed + 6U);
  irb6::Irb6Kinematics k(nominal());
  k.geometry = calibrated();
  k.tool = translation(0.0, 0.0, 0.25);  // the gripper
  // A small correction on the base side: 2 mm and 3 mrad.
  k.corrector = translation(0.002, -0.001, 0.0015);
  k.corrector.linear() = Eigen::AngleAxisd(0.003, Eigen::Vector3d(1, 2, 3).normalized()).matrix();
  double worst = 0.0;
  for (int n = 0; n < kSamples; ++n) {
    const JointPosition q = random_joints(rng);
    const Eigen::Isometry3d target = k.forward(q);
    // Where the corrector and the tool apply.
    ASSERT_LT((target.matrix() -
               (k.corrector * irb6::forward_kinematics(q, k.geometry) * k.tool).matrix())
                  .cwiseAbs()
                  .maxCoeff(),
              1e-15);
    ASSERT_LT(
        (k.flange(q).matrix() - (k.corrector * irb6::forward_kinematics(q, k.geometry)).matrix())
            .cwiseAbs()
            .maxCoeff(),
        1e-15);
    const JointPosition solved = k.inverse(target, irb6::kSynchroJointPositions);
    worst = std::max(worst, max_difference(solved, q));
    ASSERT_LT(max_difference(solved, q), 1e-9) << "q = " << show(q);
  }
  RecordProperty("worst_ik_with_tool_and_corrector_rad", figure(worst));
  // The corrector changes the answer by about its size.
  irb6::Irb6Kinematics plain = k;
  plain.corrector = Eigen::Isometry3d::Identity();
  const JointPosition q = {0.3, deg(-80), deg(10), deg(20), 0.5};
  const JointPosition uncorrected = plain.inverse_nearest(k.forward(q), q).joints;
  EXPECT_GT(max_difference(uncorrected, q), 5e-4);
}

TEST(Irb6Inverse, UnreachableOrientationIsRefusedWithTheDeviation) {
  // Synchro pose, approach horizontal along +x; turn the orientation 0.12 rad about the vertical
  // through the flange: the approach leaves the arm plane by exactly 0.12 rad.
  const Eigen::Isometry3d sync = irb6::forward_kinematics(irb6::kSynchroJointPositions, nominal());
  Eigen::Isometry3d turned = sync;
  turned.linear() = Eigen::AngleAxisd(0.12, Eigen::Vector3d::UnitZ()).matrix() * sync.linear();
  const JointPosition seed = irb6::kSynchroJointPositions;
  EXPECT_EQ(command_error_text([&] { (void)irb6::inverse_kinematics(turned, seed, nominal()); }),
            "orientation not reachable by a 5-axis arm: approach deviates 0.12 rad from the arm "
            "plane (tolerance 1e-06 rad)");
  expect_command_error([&] { (void)irb6::inverse_kinematics(turned, seed, nominal()); },
                       out_of_limits, "orientation not reachable by a 5-axis arm");
  // inverse_nearest turns it back.
  const irb6::NearestSolution nearest = irb6::inverse_nearest(turned, seed, nominal());
  EXPECT_NEAR(nearest.deviation, 0.12, 1e-12);
  EXPECT_LT(max_difference(nearest.joints, irb6::kSynchroJointPositions), 1e-12);
  // A deviation below the tolerance is accepted.
  turned.linear() = Eigen::AngleAxisd(5e-7, Eigen::Vector3d::UnitZ()).matrix() * sync.linear();
  EXPECT_NO_THROW((void)irb6::inverse_kinematics(turned, seed, nominal()));
  // Approach perpendicular to the arm plane: the seed's approach is taken.
  turned.linear() = Eigen::AngleAxisd(kPi / 2, Eigen::Vector3d::UnitZ()).matrix() * sync.linear();
  const irb6::NearestSolution perpendicular = irb6::inverse_nearest(turned, seed, nominal());
  EXPECT_NEAR(perpendicular.deviation, kPi / 2, 1e-12);
  EXPECT_LT(max_difference(perpendicular.joints, irb6::kSynchroJointPositions), 1e-12);
}

TEST(Irb6Inverse, NearestReachableOrientationOnRandomPoses) {
  const std::uint32_t seed = test_seed();
  SCOPED_TRACE(seed_trace(seed));
  std::mt19937 rng(seed + 7U);
  double worst_position = 0.0;
  double worst_deviation_mismatch = 0.0;
  int refused = 0;
  for (int n = 0; n < kSamples; ++n) {
    // Margins keep the nearest solution within the limits.
    const JointPosition q = random_joints(rng, 0.15);
    const Eigen::Isometry3d reachable = irb6::forward_kinematics(q, nominal());
    const double turn = uniform(rng, 1e-5, 0.1);
    Eigen::Isometry3d target = reachable;
    target.linear() =
        Eigen::AngleAxisd(turn, random_unit_vector(rng)).matrix() * reachable.linear();

    const irb6::NearestSolution nearest = irb6::inverse_nearest(target, q, nominal());
    const Eigen::Isometry3d reached = irb6::forward_kinematics(nearest.joints, nominal());
    // The flange position is kept, the frame reached is the one reported, its orientation is
    // `deviation` away from the request and no farther than the reachable frame we started from.
    worst_position = std::max(worst_position, position_error(reached, target));
    ASSERT_LT(position_error(reached, target), 1e-12);
    ASSERT_LT(position_error(reached, nearest.frame), 1e-12);
    ASSERT_LT(rotation_error(reached, nearest.frame), 1e-12);
    const double distance = mrroc::kinematics::rotation_distance(reached.linear(), target.linear());
    worst_deviation_mismatch =
        std::max(worst_deviation_mismatch, std::abs(distance - nearest.deviation));
    ASSERT_NEAR(distance, nearest.deviation, 1e-9);
    ASSERT_LE(nearest.deviation, turn + 1e-12);
    // The exact inverse refuses it exactly when the deviation exceeds the tolerance.
    if (nearest.deviation > irb6::kOrientationTolerance) {
      ++refused;
      expect_command_error([&] { (void)irb6::inverse_kinematics(target, q, nominal()); },
                           out_of_limits, "orientation not reachable by a 5-axis arm");
    }
  }
  EXPECT_GT(refused, kSamples / 2);
  RecordProperty("worst_nearest_position_error_m", figure(worst_position));
  RecordProperty("worst_nearest_deviation_mismatch_rad", figure(worst_deviation_mismatch));
}

TEST(Irb6Inverse, NearestWithAToolKeepsTheToolPoint) {
  const std::uint32_t seed = test_seed();
  SCOPED_TRACE(seed_trace(seed));
  std::mt19937 rng(seed + 8U);
  irb6::Irb6Kinematics k(nominal());
  k.tool = translation(0.0, 0.0, 0.25);
  for (int n = 0; n < kSamples; ++n) {
    const JointPosition q = random_joints(rng, 0.15);
    Eigen::Isometry3d target = k.forward(q);
    const double turn = uniform(rng, 1e-5, 0.05);
    target.linear() = Eigen::AngleAxisd(turn, random_unit_vector(rng)).matrix() * target.linear();
    const irb6::NearestSolution nearest = k.inverse_nearest(target, q);
    const Eigen::Isometry3d reached = k.forward(nearest.joints);
    ASSERT_LT(position_error(reached, target), 1e-12);
    ASSERT_LT(rotation_error(reached, nearest.frame), 1e-12);
    ASSERT_LE(nearest.deviation, turn + 1e-12);
    ASSERT_NEAR(mrroc::kinematics::rotation_distance(reached.linear(), target.linear()),
                nearest.deviation, 1e-9);
  }
}

TEST(Irb6Inverse, TargetsOutsideTheJointLimitsNameTheJoint) {
  struct Case {
    JointPosition q;
    std::string part;
  };
  const std::vector<Case> cases = {
      {{deg(175), deg(-90), 0.0, 0.0, 0.0},
       "joint 0 (column) inverse kinematics solution 3.054326 rad exceeds upper limit 2.967060 "
       "rad"},
      {{deg(-175), deg(-90), 0.0, 0.0, 0.0},
       "joint 0 (column) inverse kinematics solution -3.0543"},
      {{0.0, deg(-135), deg(10), 0.0, 0.0},
       "joint 1 (lower_arm) inverse kinematics solution -2.3561"},
      {{0.0, deg(-45), deg(10), 0.0, 0.0},
       "joint 1 (lower_arm) inverse kinematics solution -0.7853"},
      {{0.0, deg(-90), deg(45), 0.0, 0.0},
       "joint 2 (upper_arm) inverse kinematics solution 0.7853"},
      {{0.0, deg(-60), deg(-30), 0.0, 0.0},
       "joint 2 (upper_arm) inverse kinematics solution -0.5235"},
      {{0.0, deg(-90), 0.0, deg(95), 0.0},
       "joint 3 (wrist_pitch) inverse kinematics solution 1.6580"},
      {{0.0, deg(-90), 0.0, deg(-95), 0.0},
       "joint 3 (wrist_pitch) inverse kinematics solution -1.6580"},
      {{0.0, deg(-90), 0.0, 0.0, deg(170)},
       "joint 4 (wrist_roll) inverse kinematics solution 2.9670"},
      {{0.0, deg(-90), 0.0, 0.0, deg(-170)},
       "joint 4 (wrist_roll) inverse kinematics solution -2.9670"},
      {{0.0, deg(-125), deg(-20), 0.0, 0.0},
       "joint 2 (upper_arm) inverse kinematics solution: q1 + q2 + pi/2 = -0.959931 rad is below "
       "the upper-arm linkage limit -0.785398 rad"},
  };
  for (const Case& c : cases) {
    expect_command_error(
        [&] {
          (void)irb6::inverse_kinematics(irb6::forward_kinematics(c.q, nominal()),
                                         irb6::kSynchroJointPositions, nominal());
        },
        out_of_limits, c.part);
  }
  // Out of reach.
  Eigen::Isometry3d far = irb6::forward_kinematics(irb6::kSynchroJointPositions, nominal());
  far.translation() = Eigen::Vector3d(2.0, 0.0, 0.7);  // wrist centre 1.81 m ahead of the axis
  expect_command_error(
      [&] { (void)irb6::inverse_kinematics(far, irb6::kSynchroJointPositions, nominal()); },
      out_of_limits,
      "position not reachable: wrist centre 1.810000 m from the lower-arm axis, the arm reaches "
      "0.215000 .. 1.125000 m");
  // Flange on the column axis with a vertical approach: the wrist centre is on the axis too, the
  // column angle comes from the seed, and the IRb-6 cannot put its wrist there.
  Eigen::Isometry3d on_axis =
      irb6::forward_kinematics({0.0, -kPi / 2, 0.0, -kPi / 2, 0.0}, nominal());
  on_axis.translation() = Eigen::Vector3d(0.0, 0.0, 1.5);
  for (const double column : {-1.0, 0.0, 2.0}) {
    const JointPosition seed = {column, -kPi / 2, 0.0, 0.0, 0.0};
    expect_command_error([&] { (void)irb6::inverse_kinematics(on_axis, seed, nominal()); },
                         out_of_limits, "inverse kinematics solution");
    expect_command_error([&] { (void)irb6::inverse_nearest(on_axis, seed, nominal()); },
                         out_of_limits, "inverse kinematics solution");
  }
  // Not finite.
  far.translation().x() = std::nan("");
  expect_command_error(
      [&] { (void)irb6::inverse_kinematics(far, irb6::kSynchroJointPositions, nominal()); },
      bad_argument, "target frame is not finite");
}

}  // namespace
