/// @file
/// The IRb-6 models (robots/irb6/irb6.urdf and irb6.xml) against the closed-form forward
/// kinematics and joint limits of the IRb-6 (column, lower arm, upper arm, wrist pitch, wrist
/// roll).

#include <array>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <numbers>
#include <random>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <mujoco/mujoco.h>
#include <urdf_parser/urdf_parser.h>
#include <kdl/chain.hpp>
#include <kdl/chainfksolverpos_recursive.hpp>
#include <kdl/frames.hpp>
#include <kdl/jntarray.hpp>
#include <kdl/tree.hpp>
#include <kdl_parser/kdl_parser.hpp>

#ifndef MRROC_SOURCE_DIR
#error "MRROC_SOURCE_DIR must be defined (absolute path of the source tree)"
#endif

namespace {

constexpr double kPi = std::numbers::pi;
constexpr std::size_t kAxes = 5;
using Joints = std::array<double, kAxes>;

// Nominal lengths [m].
constexpr double kD1 = 0.70;
constexpr double kA2 = 0.455;
constexpr double kA3 = 0.67;
constexpr double kD5 = 0.19;

const std::array<std::string, kAxes> kJointNames = {"column", "lower_arm", "upper_arm",
                                                    "wrist_pitch", "wrist_roll"};

constexpr double deg(double d) { return d * kPi / 180.0; }

// Joint limits from the robot facts [rad].
const std::array<std::array<double, 2>, kAxes> kLimits = {{{deg(-170), deg(170)},
                                                           {deg(-130), deg(-50)},
                                                           {deg(-25), deg(40)},
                                                           {deg(-90), deg(92)},
                                                           {deg(-165), deg(168)}}};

std::filesystem::path robot_dir() {
  return std::filesystem::path(MRROC_SOURCE_DIR) / "robots" / "irb6";
}

/// Closed-form flange position with the internal angles q1' = q1, q2' = q2 + q1 + pi/2,
/// q3' = q3 + q2'.
std::array<double, 3> closed_form(const Joints& q) {
  const double t1 = q[1];
  const double t2 = q[2] + t1 + kPi / 2;
  const double t3 = q[3] + t2;
  const double r = kA2 * std::cos(t1) + kA3 * std::cos(t2) + kD5 * std::cos(t3);
  return {std::cos(q[0]) * r, std::sin(q[0]) * r,
          kD1 - kA2 * std::sin(t1) - kA3 * std::sin(t2) - kD5 * std::sin(t3)};
}

std::uint32_t test_seed() {
  if (const char* env = std::getenv("MRROC_TEST_SEED"); env != nullptr && *env != '\0') {
    return static_cast<std::uint32_t>(std::strtoul(env, nullptr, 10));
  }
  return 20240607U;
}

std::vector<Joints> random_joints(std::uint32_t seed, std::size_t count) {
  std::mt19937 rng(seed);
  std::vector<Joints> out(count);
  for (auto& q : out) {
    for (std::size_t i = 0; i < kAxes; ++i) {
      q[i] = std::uniform_real_distribution<double>(kLimits[i][0], kLimits[i][1])(rng);
    }
  }
  return out;
}

class Irb6Urdf : public ::testing::Test {
 protected:
  void SetUp() override {
    const auto path = robot_dir() / "irb6.urdf";
    urdf_ = urdf::parseURDFFile(path.string());
    ASSERT_TRUE(urdf_) << "cannot parse " << path;
    ASSERT_TRUE(kdl_parser::treeFromUrdfModel(*urdf_, tree_)) << "kdl_parser failed on " << path;
    ASSERT_TRUE(tree_.getChain("base_link", "flange", chain_));
    ASSERT_EQ(chain_.getNrOfJoints(), kAxes);
  }

  KDL::Frame fk(const Joints& q) const {
    KDL::ChainFkSolverPos_recursive solver(chain_);
    KDL::JntArray joints(kAxes);
    for (std::size_t i = 0; i < kAxes; ++i) {
      joints(static_cast<unsigned int>(i)) = q[i];
    }
    KDL::Frame frame;
    EXPECT_GE(solver.JntToCart(joints, frame), 0);
    return frame;
  }

  urdf::ModelInterfaceSharedPtr urdf_;
  KDL::Tree tree_;
  KDL::Chain chain_;
};

TEST_F(Irb6Urdf, ChainJointsAreTheFiveAxesInOrder) {
  std::vector<std::string> names;
  for (const auto& segment : chain_.segments) {
    if (segment.getJoint().getType() != KDL::Joint::None) {
      names.push_back(segment.getJoint().getName());
    }
  }
  ASSERT_EQ(names.size(), kAxes);
  for (std::size_t i = 0; i < kAxes; ++i) {
    EXPECT_EQ(names[i], kJointNames[i]);
  }
}

TEST_F(Irb6Urdf, JointLimitsEqualTheRobotFacts) {
  for (std::size_t i = 0; i < kAxes; ++i) {
    const auto joint = urdf_->getJoint(kJointNames[i]);
    ASSERT_TRUE(joint) << kJointNames[i];
    EXPECT_EQ(joint->type, urdf::Joint::REVOLUTE) << kJointNames[i];
    ASSERT_TRUE(joint->limits) << kJointNames[i];
    EXPECT_NEAR(joint->limits->lower, kLimits[i][0], 1e-6) << kJointNames[i];
    EXPECT_NEAR(joint->limits->upper, kLimits[i][1], 1e-6) << kJointNames[i];
    EXPECT_GT(joint->limits->velocity, 0.0) << kJointNames[i];
  }
}

TEST_F(Irb6Urdf, SynchronisationPoseByHand) {
  // q = (0, -pi/2, 0, 0, 0): q1' = -pi/2 (c1 = 0, s1 = -1), q2' = 0, q3' = 0, so
  // p = (a2*0 + a3 + d5, 0, d1 + a2) = (0.86, 0, 1.155): lower arm up, upper arm and wrist along
  // +x.
  const Joints sync = {0.0, -kPi / 2, 0.0, 0.0, 0.0};
  const auto expected = closed_form(sync);
  EXPECT_NEAR(expected[0], kA3 + kD5, 1e-15);
  EXPECT_NEAR(expected[1], 0.0, 1e-15);
  EXPECT_NEAR(expected[2], kD1 + kA2, 1e-15);

  const KDL::Frame frame = fk(sync);
  EXPECT_NEAR(frame.p.x(), 0.86, 1e-9);
  EXPECT_NEAR(frame.p.y(), 0.0, 1e-9);
  EXPECT_NEAR(frame.p.z(), 1.155, 1e-9);
  // Flange z axis = approach direction (+x of the world here); flange x axis points down.
  const KDL::Vector z = frame.M.UnitZ();
  const KDL::Vector x = frame.M.UnitX();
  EXPECT_NEAR(z.x(), 1.0, 1e-12);
  EXPECT_NEAR(x.z(), -1.0, 1e-12);
}

TEST_F(Irb6Urdf, OtherPosesByHand) {
  struct Case {
    Joints q;
    std::array<double, 3> p;
  };
  const std::array<Case, 4> cases = {{
      // Column turned +90 deg: the arm points along +y.
      {{kPi / 2, -kPi / 2, 0.0, 0.0, 0.0}, {0.0, 0.86, 1.155}},
      // Wrist pitched -90 deg: the flange is d5 above the wrist.
      {{0.0, -kPi / 2, 0.0, -kPi / 2, 0.0}, {0.67, 0.0, 1.155 + 0.19}},
      // Lower arm at -50 deg (leaning forward), upper arm / wrist horizontal (q2 = -40 deg).
      {{0.0, deg(-50), deg(-40), 0.0, 1.0},
       {0.455 * std::cos(deg(-50)) + 0.86, 0.0, 0.70 - 0.455 * std::sin(deg(-50))}},
      // Wrist roll does not move the flange origin.
      {{0.3, -kPi / 2, 0.0, 0.0, 2.5}, {0.86 * std::cos(0.3), 0.86 * std::sin(0.3), 1.155}},
  }};
  for (const auto& c : cases) {
    const KDL::Frame frame = fk(c.q);
    EXPECT_NEAR(frame.p.x(), c.p[0], 1e-9);
    EXPECT_NEAR(frame.p.y(), c.p[1], 1e-9);
    EXPECT_NEAR(frame.p.z(), c.p[2], 1e-9);
  }
}

TEST_F(Irb6Urdf, ForwardKinematicsEqualsClosedFormOnRandomPoses) {
  const std::uint32_t seed = test_seed();
  SCOPED_TRACE("MRROC_TEST_SEED=" + std::to_string(seed));
  double worst = 0.0;
  for (const Joints& q : random_joints(seed, 2000)) {
    const KDL::Frame frame = fk(q);
    const auto p = closed_form(q);
    const double err = std::max(
        {std::abs(frame.p.x() - p[0]), std::abs(frame.p.y() - p[1]), std::abs(frame.p.z() - p[2])});
    worst = std::max(worst, err);
    ASSERT_LT(err, 1e-9) << "q = (" << q[0] << ", " << q[1] << ", " << q[2] << ", " << q[3] << ", "
                         << q[4] << ")";
  }
  RecordProperty("worst_position_error_m", std::to_string(worst));
}

class Irb6Mjcf : public Irb6Urdf {
 protected:
  void SetUp() override {
    Irb6Urdf::SetUp();
    const auto path = robot_dir() / "irb6.xml";
    std::array<char, 1024> error{};
    model_ = mj_loadXML(path.c_str(), nullptr, error.data(), static_cast<int>(error.size()));
    ASSERT_NE(model_, nullptr) << path << ": " << error.data();
    data_ = mj_makeData(model_);
    ASSERT_NE(data_, nullptr);
  }
  void TearDown() override {
    if (data_ != nullptr) {
      mj_deleteData(data_);
    }
    if (model_ != nullptr) {
      mj_deleteModel(model_);
    }
  }

  mjModel* model_ = nullptr;
  mjData* data_ = nullptr;
};

TEST_F(Irb6Mjcf, JointsAndActuatorsMatchTheUrdf) {
  ASSERT_EQ(model_->njnt, static_cast<int>(kAxes));
  ASSERT_EQ(model_->nq, static_cast<int>(kAxes));
  ASSERT_EQ(model_->nu, static_cast<int>(kAxes));
  for (int j = 0; j < model_->njnt; ++j) {
    const auto i = static_cast<std::size_t>(j);
    const char* name = mj_id2name(model_, mjOBJ_JOINT, j);
    ASSERT_NE(name, nullptr);
    EXPECT_EQ(std::string(name), kJointNames[i]);
    EXPECT_EQ(model_->jnt_type[j], mjJNT_HINGE);
    EXPECT_TRUE(model_->jnt_limited[j]);
    const auto joint = urdf_->getJoint(kJointNames[i]);
    ASSERT_TRUE(joint && joint->limits);
    EXPECT_NEAR(model_->jnt_range[2 * j], joint->limits->lower, 1e-12) << name;
    EXPECT_NEAR(model_->jnt_range[2 * j + 1], joint->limits->upper, 1e-12) << name;
    EXPECT_GT(model_->dof_armature[model_->jnt_dofadr[j]], 0.0) << name;
    EXPECT_GT(model_->dof_damping[model_->jnt_dofadr[j]], 0.0) << name;

    // One position actuator with the same name, driving this joint, ctrlrange = joint range.
    const int a = mj_name2id(model_, mjOBJ_ACTUATOR, name);
    ASSERT_GE(a, 0) << name;
    EXPECT_EQ(model_->actuator_trntype[a], mjTRN_JOINT);
    EXPECT_EQ(model_->actuator_trnid[2 * a], j);
    EXPECT_TRUE(model_->actuator_ctrllimited[a]);
    EXPECT_NEAR(model_->actuator_ctrlrange[2 * a], joint->limits->lower, 1e-12) << name;
    EXPECT_NEAR(model_->actuator_ctrlrange[2 * a + 1], joint->limits->upper, 1e-12) << name;
  }
  EXPECT_DOUBLE_EQ(model_->opt.timestep, 0.001);
}

TEST_F(Irb6Mjcf, MassesAndCentresOfMassMatchTheUrdf) {
  // Body i + 1 of the MJCF is the child link of joint i.
  for (std::size_t i = 0; i < kAxes; ++i) {
    const auto joint = urdf_->getJoint(kJointNames[i]);
    ASSERT_TRUE(joint);
    const auto link = urdf_->getLink(joint->child_link_name);
    ASSERT_TRUE(link && link->inertial) << joint->child_link_name;
    const int b = mj_name2id(model_, mjOBJ_BODY, joint->child_link_name.c_str());
    ASSERT_GE(b, 0) << joint->child_link_name;
    EXPECT_NEAR(model_->body_mass[b], link->inertial->mass, 1e-12);
    EXPECT_NEAR(model_->body_ipos[3 * b], link->inertial->origin.position.x, 1e-12);
    EXPECT_NEAR(model_->body_ipos[3 * b + 1], link->inertial->origin.position.y, 1e-12);
    EXPECT_NEAR(model_->body_ipos[3 * b + 2], link->inertial->origin.position.z, 1e-12);
  }
}

TEST_F(Irb6Mjcf, FlangeSiteEqualsKdlOnRandomPoses) {
  const int site = mj_name2id(model_, mjOBJ_SITE, "flange");
  ASSERT_GE(site, 0);
  const std::uint32_t seed = test_seed() + 1U;
  SCOPED_TRACE("MRROC_TEST_SEED=" + std::to_string(seed - 1U));
  std::vector<Joints> poses = random_joints(seed, 2000);
  poses.push_back({0.0, -kPi / 2, 0.0, 0.0, 0.0});
  for (const Joints& q : poses) {
    for (int j = 0; j < static_cast<int>(kAxes); ++j) {
      data_->qpos[model_->jnt_qposadr[j]] = q[static_cast<std::size_t>(j)];
    }
    mj_kinematics(model_, data_);
    const KDL::Frame frame = fk(q);
    const mjtNum* p = data_->site_xpos + 3 * site;
    const mjtNum* r = data_->site_xmat + 9 * site;  // row-major, columns = site axes
    ASSERT_NEAR(p[0], frame.p.x(), 1e-9);
    ASSERT_NEAR(p[1], frame.p.y(), 1e-9);
    ASSERT_NEAR(p[2], frame.p.z(), 1e-9);
    for (int row = 0; row < 3; ++row) {
      for (int col = 0; col < 3; ++col) {
        ASSERT_NEAR(r[3 * row + col], frame.M(row, col), 1e-9)
            << "rotation (" << row << ", " << col << ")";
      }
    }
  }
}

}  // namespace
