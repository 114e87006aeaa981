/// @file
/// The RNT models (robots/rnt: rnt.urdf, rnt.xml, parameters.toml) and its transmissions
/// (mrroc/kinematics/rnt.hpp): URDF via KDL and the closed-loop MJCF via MuJoCo agree on the
/// flange and tool frames, limits agree everywhere, the board is reachable with the tool pointing
/// down, and the motor <-> joint maps are exact inverses.
///
/// Random numbers are seeded from the environment variable MRROC_TEST_SEED (default below); the
/// seed is printed with every failure.

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <numbers>
#include <random>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <mujoco/mujoco.h>
#include <toml++/toml.h>
#include <urdf_parser/urdf_parser.h>

#include "mrroc/config/params.hpp"
#include "mrroc/core/error.hpp"
#include "mrroc/edp/hardware.hpp"
#include "mrroc/kinematics/kdl_solver.hpp"
#include "mrroc/kinematics/rnt.hpp"
#include "mrroc/msg/edp_instruction.hpp"
#include "mrroc/robot/robot_model.hpp"
#include "plugins/mujoco_hardware.hpp"

#ifndef MRROC_SOURCE_DIR
#error "MRROC_SOURCE_DIR must be defined (absolute path of the source tree)"
#endif

namespace {

namespace rnt = mrroc::robots::rnt;
using mrroc::CommandError;
using mrroc::kinematics::KdlSolver;
namespace error_code = mrroc::edp::error_code;

constexpr double kPi = std::numbers::pi;
constexpr std::size_t kAxes = rnt::kAxes;
using Joints = rnt::JointPosition;

std::filesystem::path robot_dir() {
  return std::filesystem::path(MRROC_SOURCE_DIR) / "robots" / "rnt";
}

std::uint32_t test_seed() {
  if (const char* env = std::getenv("MRROC_TEST_SEED"); env != nullptr && *env != '\0') {
    return static_cast<std::uint32_t>(std::strtoul(env, nullptr, 10));
  }
  return 20240607U;
}

std::string seed_text(std::uint32_t seed) { return "MRROC_TEST_SEED=" + std::to_string(seed); }

std::vector<double> vec(const Joints& q) { return {q.begin(), q.end()}; }

/// Random joints within the joint limits; with `forearm_range`, also with the absolute forearm
/// pitch q1 + q2 inside the elbow drive's range (what the real machine can reach).
Joints random_joints(std::mt19937& rng, bool forearm_range) {
  const double lo = rnt::kMotorLowerLimits[2] / rnt::kGearRatios[2];
  const double hi = rnt::kMotorUpperLimits[2] / rnt::kGearRatios[2];
  for (;;) {
    Joints q{};
    for (std::size_t i = 0; i < kAxes; ++i) {
      q[i] = std::uniform_real_distribution<double>(rnt::kJointLowerLimits[i],
                                                    rnt::kJointUpperLimits[i])(rng);
    }
    if (!forearm_range || (q[1] + q[2] >= lo && q[1] + q[2] <= hi)) return q;
  }
}

/// The MJCF model with its data; sets the closed-loop state for serial joints q by construction.
class RntMjcf {
 public:
  RntMjcf() {
    const auto path = robot_dir() / "rnt.xml";
    std::array<char, 1024> error{};
    model_ = mj_loadXML(path.c_str(), nullptr, error.data(), static_cast<int>(error.size()));
    if (model_ == nullptr) {
      ADD_FAILURE() << path << ": " << error.data();
      return;
    }
    data_ = mj_makeData(model_);
  }
  ~RntMjcf() {
    if (data_ != nullptr) mj_deleteData(data_);
    if (model_ != nullptr) mj_deleteModel(model_);
  }
  RntMjcf(const RntMjcf&) = delete;
  RntMjcf& operator=(const RntMjcf&) = delete;

  [[nodiscard]] const mjModel* model() const { return model_; }
  [[nodiscard]] mjData* data() const { return data_; }
  [[nodiscard]] int joint(const char* name) const { return mj_name2id(model_, mjOBJ_JOINT, name); }
  [[nodiscard]] double& qpos(const char* name) const {
    return data_->qpos[model_->jnt_qposadr[joint(name)]];
  }

  /// Serial joints = q, elbow drive = q1 + q2 (absolute forearm pitch), coupler = -q2: the
  /// parallelogram closes by construction.
  void set(const Joints& q) const {
    for (std::size_t i = 0; i < kAxes; ++i) qpos(rnt::kJointNames[i]) = q[i];
    qpos("elbow_drive") = q[1] + q[2];
    qpos("coupler") = -q[2];
    mj_kinematics(model_, data_);
  }

  /// Distance between the two anchors of the `parallelogram` connect constraint [m].
  [[nodiscard]] double loop_violation() const {
    const int e = mj_name2id(model_, mjOBJ_EQUALITY, "parallelogram");
    const mjtNum* anchors = model_->eq_data + mjNEQDATA * e;
    std::array<mjtNum, 3> p1{};
    std::array<mjtNum, 3> p2{};
    const int b1 = model_->eq_obj1id[e];
    const int b2 = model_->eq_obj2id[e];
    mju_mulMatVec(p1.data(), data_->xmat + 9 * b1, anchors, 3, 3);
    mju_addTo3(p1.data(), data_->xpos + 3 * b1);
    mju_mulMatVec(p2.data(), data_->xmat + 9 * b2, anchors + 3, 3, 3);
    mju_addTo3(p2.data(), data_->xpos + 3 * b2);
    return mju_dist3(p1.data(), p2.data());
  }

  [[nodiscard]] Eigen::Isometry3d site(const char* name) const {
    const int s = mj_name2id(model_, mjOBJ_SITE, name);
    Eigen::Isometry3d frame = Eigen::Isometry3d::Identity();
    for (int r = 0; r < 3; ++r) {
      frame.translation()(r) = data_->site_xpos[3 * s + r];
      for (int c = 0; c < 3; ++c) frame.linear()(r, c) = data_->site_xmat[9 * s + 3 * r + c];
    }
    return frame;
  }

 private:
  mjModel* model_ = nullptr;
  mjData* data_ = nullptr;
};

/// Largest entry of |a - b| over translation and rotation matrix.
double frame_difference(const Eigen::Isometry3d& a, const Eigen::Isometry3d& b) {
  return std::max((a.translation() - b.translation()).cwiseAbs().maxCoeff(),
                  (a.linear() - b.linear()).cwiseAbs().maxCoeff());
}

// ---- URDF ----

TEST(RntUrdf, ChainJointsAndLimitsAreTheDocumentedOnes) {
  const KdlSolver solver(robot_dir() / "rnt.urdf", "base_link", "tool");
  ASSERT_EQ(solver.joint_count(), kAxes);
  for (std::size_t i = 0; i < kAxes; ++i) {
    EXPECT_EQ(solver.joint_names()[i], rnt::kJointNames[i]);
    EXPECT_NEAR(solver.lower_limits()[i], rnt::kJointLowerLimits[i], 1e-12) << i;
    EXPECT_NEAR(solver.upper_limits()[i], rnt::kJointUpperLimits[i], 1e-12) << i;
  }
  // The robot model the EDP loads reads the same names and limits.
  const mrroc::RobotModel model = mrroc::load_robot_model(robot_dir());
  ASSERT_EQ(model.axes(), kAxes);
  for (std::size_t i = 0; i < kAxes; ++i) {
    EXPECT_EQ(model.joint_names[i], rnt::kJointNames[i]);
    EXPECT_NEAR(model.lower_limits[i], rnt::kJointLowerLimits[i], 1e-12) << i;
    EXPECT_NEAR(model.upper_limits[i], rnt::kJointUpperLimits[i], 1e-12) << i;
    EXPECT_NEAR(model.synchro_joint_positions[i], rnt::kSynchroJointPositions[i], 1e-15) << i;
  }
}

TEST(RntUrdf, PosesByHand) {
  const KdlSolver flange(robot_dir() / "rnt.urdf", "base_link", "flange");
  const KdlSolver tool(robot_dir() / "rnt.urdf", "base_link", "tool");
  struct Case {
    Joints q;
    Eigen::Vector3d flange;
    Eigen::Vector3d approach;  // flange z axis
  };
  const double r = rnt::kA3 + rnt::kD6;  // forearm + wrist along the forearm
  const std::array<Case, 5> cases = {{
      // Zero pose: upper arm up, forearm and wrist horizontal along +x.
      {{0, 0, 0, 0, 0, 0}, {r, 0, rnt::kD1 + rnt::kA2}, {1, 0, 0}},
      // Synchronisation pose: tool pointing down from the wrist centre (a3, 0, d1 + a2).
      {rnt::kSynchroJointPositions, {rnt::kA3, 0, rnt::kD1 + rnt::kA2 - rnt::kD6}, {0, 0, -1}},
      // Waist +90 deg: the arm along +y.
      {{kPi / 2, 0, 0, 0, 0, 0}, {0, r, rnt::kD1 + rnt::kA2}, {0, 1, 0}},
      // Shoulder +90 deg with elbow -90 deg: upper arm horizontal, forearm absolute pitch 0.
      {{0, kPi / 2, -kPi / 2, 0, 0, 0}, {rnt::kA2 + r, 0, rnt::kD1}, {1, 0, 0}},
      // Wrist yaw +90 deg turns the approach axis to +y about the wrist centre.
      {{0, 0, 0, 0, kPi / 2, 0.7}, {rnt::kA3, rnt::kD6, rnt::kD1 + rnt::kA2}, {0, 1, 0}},
  }};
  for (const Case& c : cases) {
    const Eigen::Isometry3d f = flange.forward(vec(c.q));
    EXPECT_LT((f.translation() - c.flange).norm(), 1e-12) << f.translation().transpose();
    EXPECT_LT((f.linear().col(2) - c.approach).norm(), 1e-12) << f.linear();
    // The tool (cutter tip) is 0.15 m further along the approach axis.
    const Eigen::Isometry3d t = tool.forward(vec(c.q));
    EXPECT_LT((t.translation() - (c.flange + rnt::kCutterLength * c.approach)).norm(), 1e-12);
    EXPECT_LT((t.linear() - f.linear()).norm(), 1e-12);
  }
}

// ---- MJCF ----

TEST(RntMjcfModel, JointsActuatorsAndLimitsMatchTheUrdf) {
  const RntMjcf mjcf;
  const mjModel* m = mjcf.model();
  ASSERT_NE(m, nullptr);
  const auto urdf = urdf::parseURDFFile((robot_dir() / "rnt.urdf").string());
  ASSERT_TRUE(urdf);
  ASSERT_EQ(m->njnt, 8);
  ASSERT_EQ(m->nu, static_cast<int>(kAxes));
  ASSERT_EQ(m->neq, 1);
  EXPECT_EQ(m->eq_type[0], mjEQ_CONNECT);
  EXPECT_DOUBLE_EQ(m->opt.timestep, 0.001);
  for (std::size_t i = 0; i < kAxes; ++i) {
    const char* name = rnt::kJointNames[i];
    const int j = mjcf.joint(name);
    ASSERT_GE(j, 0) << name;
    EXPECT_EQ(m->jnt_type[j], mjJNT_HINGE) << name;
    ASSERT_TRUE(m->jnt_limited[j]) << name;
    const auto joint = urdf->getJoint(name);
    ASSERT_TRUE(joint && joint->limits) << name;
    EXPECT_NEAR(m->jnt_range[2 * j], joint->limits->lower, 1e-12) << name;
    EXPECT_NEAR(m->jnt_range[2 * j + 1], joint->limits->upper, 1e-12) << name;

    // Actuator i is named like axis i; it drives the same-named joint except for the elbow,
    // whose actuator drives the parallelogram crank (absolute forearm pitch).
    const int a = static_cast<int>(i);
    EXPECT_EQ(std::string(mj_id2name(m, mjOBJ_ACTUATOR, a)), name);
    EXPECT_EQ(m->actuator_trntype[a], mjTRN_JOINT);
    const int driven = m->actuator_trnid[2 * a];
    EXPECT_EQ(driven, i == 2 ? mjcf.joint("elbow_drive") : j) << name;
    EXPECT_TRUE(m->actuator_ctrllimited[a]);
    EXPECT_NEAR(m->actuator_ctrlrange[2 * a], m->jnt_range[2 * driven], 1e-15) << name;
    EXPECT_NEAR(m->actuator_ctrlrange[2 * a + 1], m->jnt_range[2 * driven + 1], 1e-15) << name;
    EXPECT_GT(m->dof_armature[m->jnt_dofadr[driven]], 0.0) << name;
    EXPECT_GT(m->dof_damping[m->jnt_dofadr[driven]], 0.0) << name;
  }
  // The elbow drive's range is the elbow motor's range through its gear: the limit of q1 + q2.
  const int drive = mjcf.joint("elbow_drive");
  EXPECT_NEAR(m->jnt_range[2 * drive], rnt::kMotorLowerLimits[2] / rnt::kGearRatios[2], 1e-15);
  EXPECT_NEAR(m->jnt_range[2 * drive + 1], rnt::kMotorUpperLimits[2] / rnt::kGearRatios[2], 1e-15);
  // The serial elbow and the coupler are passive: no actuator, no armature.
  for (const char* passive : {"elbow", "coupler"}) {
    const int j = mjcf.joint(passive);
    for (int a = 0; a < m->nu; ++a) EXPECT_NE(m->actuator_trnid[2 * a], j) << passive;
    EXPECT_EQ(m->dof_armature[m->jnt_dofadr[j]], 0.0) << passive;
  }
}

TEST(RntMjcfModel, MassesAndCentresOfMassMatchTheUrdf) {
  const RntMjcf mjcf;
  const mjModel* m = mjcf.model();
  ASSERT_NE(m, nullptr);
  const auto urdf = urdf::parseURDFFile((robot_dir() / "rnt.urdf").string());
  ASSERT_TRUE(urdf);
  for (const char* name : rnt::kJointNames) {
    const auto joint = urdf->getJoint(name);
    ASSERT_TRUE(joint);
    const auto link = urdf->getLink(joint->child_link_name);
    ASSERT_TRUE(link && link->inertial) << joint->child_link_name;
    const int b = mj_name2id(m, mjOBJ_BODY, joint->child_link_name.c_str());
    ASSERT_GE(b, 0) << joint->child_link_name;
    EXPECT_NEAR(m->body_mass[b], link->inertial->mass, 1e-12);
    EXPECT_NEAR(m->body_ipos[3 * b], link->inertial->origin.position.x, 1e-12);
    EXPECT_NEAR(m->body_ipos[3 * b + 1], link->inertial->origin.position.y, 1e-12);
    EXPECT_NEAR(m->body_ipos[3 * b + 2], link->inertial->origin.position.z, 1e-12);
  }
}

TEST(RntMjcfModel, FlangeAndToolEqualKdlOnRandomPosesWithTheLoopClosed) {
  const RntMjcf mjcf;
  ASSERT_NE(mjcf.model(), nullptr);
  const KdlSolver flange(robot_dir() / "rnt.urdf", "base_link", "flange");
  const KdlSolver tool(robot_dir() / "rnt.urdf", "base_link", "tool");
  const std::uint32_t seed = test_seed();
  SCOPED_TRACE(seed_text(seed));
  std::mt19937 rng(seed);
  double worst = 0.0;
  double worst_loop = 0.0;
  for (int k = 0; k < 2000; ++k) {
    const Joints q = k == 0 ? rnt::kSynchroJointPositions : random_joints(rng, false);
    mjcf.set(q);
    const double loop = mjcf.loop_violation();
    const double df = frame_difference(mjcf.site("flange"), flange.forward(vec(q)));
    const double dt = frame_difference(mjcf.site("tool"), tool.forward(vec(q)));
    worst = std::max({worst, df, dt});
    worst_loop = std::max(worst_loop, loop);
    ASSERT_LT(loop, 1e-12) << "the parallelogram does not close at k = " << k;
    ASSERT_LT(df, 1e-9) << "flange, k = " << k;
    ASSERT_LT(dt, 1e-9) << "tool, k = " << k;
  }
  std::printf(
      "URDF (KDL) vs MJCF (MuJoCo), 2000 poses: largest difference %.3e (m or rotation "
      "entry), largest loop violation %.3e m\n",
      worst, worst_loop);
}

TEST(RntMjcfModel, LoopClosedBySolvingGivesTheSameFrames) {
  // The mujoco EDP plugin closes the loop itself (Gauss-Newton on the equality constraint) from
  // the joint pose it is given.
  const KdlSolver tool(robot_dir() / "rnt.urdf", "base_link", "tool");
  const std::uint32_t seed = test_seed() + 1U;
  SCOPED_TRACE(seed_text(seed - 1U));
  std::mt19937 rng(seed);
  double worst = 0.0;
  for (int k = 0; k < 40; ++k) {
    const Joints q = random_joints(rng, true);
    mrroc::edp::HardwareSetup setup;
    setup.robot = "rnt";
    setup.model_dir = robot_dir();
    setup.servo_period_s = 0.002;
    setup.params = mrroc::Params(mrroc::SourceLocation{"test.toml", 1});
    setup.params.set("initial_joint_positions", vec(q), mrroc::SourceLocation{"test.toml", 2});
    mrroc::edp::MujocoHardware hw;
    hw.configure(setup);
    const mjModel* m = hw.model();
    const mjData* d = hw.data();
    const int s = mj_name2id(m, mjOBJ_SITE, "tool");
    Eigen::Isometry3d frame = Eigen::Isometry3d::Identity();
    for (int r = 0; r < 3; ++r) {
      frame.translation()(r) = d->site_xpos[3 * s + r];
      for (int c = 0; c < 3; ++c) frame.linear()(r, c) = d->site_xmat[9 * s + 3 * r + c];
    }
    const double diff = frame_difference(frame, tool.forward(vec(q)));
    worst = std::max(worst, diff);
    ASSERT_LT(diff, 1e-9) << "k = " << k;
    ASSERT_LT(hw.equality_violation(), 1e-9) << "k = " << k;
  }
  std::printf("loop closed by the plugin, 40 poses: largest difference to KDL %.3e\n", worst);
}

// ---- parameters.toml ----

TEST(RntParameters, AgreeWithTheTransmissionModel) {
  // parameters.toml gives the coupling (read by the MuJoCo plugin and the emulator); the gear
  // ratios and motor limits are rnt.hpp's.
  const toml::table file = toml::parse_file((robot_dir() / "parameters.toml").string());
  const toml::array* coupling = file["robot"]["transmission"]["coupling"].as_array();
  ASSERT_NE(coupling, nullptr);
  ASSERT_EQ(coupling->size(), kAxes);
  for (std::size_t r = 0; r < kAxes; ++r) {
    const toml::array* row = (*coupling)[r].as_array();
    ASSERT_NE(row, nullptr);
    ASSERT_EQ(row->size(), kAxes);
    for (std::size_t c = 0; c < kAxes; ++c) {
      EXPECT_EQ((*row)[c].value<double>().value_or(-1.0), rnt::kCoupling[r][c]) << r << c;
    }
  }
  for (std::size_t i = 0; i < kAxes; ++i) {
    // The synchronisation motor positions are gear ratio x coupling x synchronisation joints.
    double drive = 0.0;
    for (std::size_t c = 0; c < kAxes; ++c)
      drive += rnt::kCoupling[i][c] * rnt::kSynchroJointPositions[c];
    EXPECT_NEAR(rnt::kSynchroMotorPositions[i], rnt::kGearRatios[i] * drive, 1e-12) << i;
    // Motor limits lie outside gear ratio x joint limits, except motor 2 (elbow) whose range is
    // the real limit of q1 + q2.
    if (i != 2) {
      const double a = rnt::kGearRatios[i] * rnt::kJointLowerLimits[i];
      const double b = rnt::kGearRatios[i] * rnt::kJointUpperLimits[i];
      EXPECT_LE(rnt::kMotorLowerLimits[i], std::min(a, b)) << i;
      EXPECT_GE(rnt::kMotorUpperLimits[i], std::max(a, b)) << i;
    }
  }
}

// ---- The board ----

struct Board {
  Eigen::Vector3d centre;  // centre of the top surface [m]
  double depth;            // along base x [m]
  double width;            // along base y [m]
};

/// The board of README.md ("Workspace: the board"): top surface centred at (0.60, 0, 0.20) m in
/// the base frame, 0.30 m along base x by 0.40 m along base y.
Board board_from_readme() { return Board{{0.60, 0.0, 0.20}, 0.30, 0.40}; }

TEST(RntWorkspace, BoardIsReachableWithTheToolPointingDown) {
  const Board board = board_from_readme();
  const KdlSolver tool(robot_dir() / "rnt.urdf", "base_link", "tool");
  // Tool z down; tool x along -x of the base (its orientation at the synchronisation pose).
  Eigen::Matrix3d down;
  down << -1, 0, 0, 0, 1, 0, 0, 0, -1;
  std::array<double, kAxes> low{};
  std::array<double, kAxes> high{};
  low.fill(1e9);
  high.fill(-1e9);
  double worst = 0.0;
  int points = 0;
  // Corners first, then a 5 cm grid; 5 mm into the board (engraving), on it, 5 cm above it.
  std::vector<Eigen::Vector2d> xy;
  for (const double sx : {-0.5, 0.5}) {
    for (const double sy : {-0.5, 0.5}) xy.emplace_back(sx * board.depth, sy * board.width);
  }
  for (int ix = 0; ix <= 6; ++ix) {
    for (int iy = 0; iy <= 8; ++iy) {
      xy.emplace_back(-0.15 + 0.05 * ix, -0.20 + 0.05 * iy);
    }
  }
  for (const Eigen::Vector2d& p : xy) {
    for (const double dz : {-0.005, 0.0, 0.05}) {
      Eigen::Isometry3d target = Eigen::Isometry3d::Identity();
      target.linear() = down;
      target.translation() = board.centre + Eigen::Vector3d(p.x(), p.y(), dz);
      SCOPED_TRACE("tool at " + std::to_string(target.translation().x()) + ", " +
                   std::to_string(target.translation().y()) + ", " +
                   std::to_string(target.translation().z()));
      std::vector<double> q;
      ASSERT_NO_THROW(q = tool.inverse(target, vec(rnt::kSynchroJointPositions)));
      const Eigen::Isometry3d reached = tool.forward(q);
      worst = std::max(worst, frame_difference(reached, target));
      Joints joints{};
      std::copy(q.begin(), q.end(), joints.begin());
      // Joint limits, and the motor limits (the parallelogram's q1 + q2 range among them).
      ASSERT_NO_THROW(rnt::check_limits(joints));
      for (std::size_t i = 0; i < kAxes; ++i) {
        low[i] = std::min(low[i], q[i]);
        high[i] = std::max(high[i], q[i]);
      }
      ++points;
    }
  }
  EXPECT_LT(worst, 1e-9);
  std::printf("board: %d tool poses reachable (worst frame error %.2e); joint ranges used:\n",
              points, worst);
  for (std::size_t i = 0; i < kAxes; ++i) {
    std::printf("  %-12s %8.2f .. %8.2f deg (limits %8.2f .. %8.2f deg)\n", rnt::kJointNames[i],
                low[i] * 180 / kPi, high[i] * 180 / kPi, rnt::kJointLowerLimits[i] * 180 / kPi,
                rnt::kJointUpperLimits[i] * 180 / kPi);
  }
}

// ---- Transmission ----

TEST(RntTransmission, MotorJointMotorAndJointMotorJointAreIdentities) {
  const std::uint32_t seed = test_seed() + 2U;
  SCOPED_TRACE(seed_text(seed - 2U));
  std::mt19937 rng(seed);
  for (int k = 0; k < 1000; ++k) {
    const Joints q = random_joints(rng, false);
    const Joints back = rnt::joints_from_motors(rnt::motors_from_joints(q));
    for (std::size_t i = 0; i < kAxes; ++i) ASSERT_NEAR(back[i], q[i], 1e-13) << i;

    rnt::MotorPosition m{};
    for (std::size_t i = 0; i < kAxes; ++i) {
      m[i] = std::uniform_real_distribution<double>(rnt::kMotorLowerLimits[i],
                                                    rnt::kMotorUpperLimits[i])(rng);
    }
    const rnt::MotorPosition m_back = rnt::motors_from_joints(rnt::joints_from_motors(m));
    for (std::size_t i = 0; i < kAxes; ++i) ASSERT_NEAR(m_back[i], m[i], 1e-11) << i;
  }
}

TEST(RntTransmission, ParallelogramCouplingByHand) {
  // Shoulder 0.3 rad, elbow 0.2 rad relative to the upper arm: the elbow drive turns the
  // absolute forearm pitch 0.5 rad, i.e. the elbow motor 160 * 0.5 = 80 rad.
  const rnt::MotorPosition m = rnt::motors_from_joints({0.0, 0.3, 0.2, 0.0, 0.0, 0.0});
  EXPECT_DOUBLE_EQ(m[1], 160.0 * 0.3);
  EXPECT_DOUBLE_EQ(m[2], 160.0 * 0.5);
  // Turning only the shoulder motor keeps the forearm's absolute pitch: the elbow joint turns
  // the other way.
  const Joints q = rnt::joints_from_motors({0.0, 16.0, 0.0, 0.0, 0.0, 0.0});
  EXPECT_DOUBLE_EQ(q[1], 0.1);
  EXPECT_DOUBLE_EQ(q[2], -0.1);
  // Signs: the waist, wrist pitch and wrist roll motors turn the other way.
  const rnt::MotorPosition signs = rnt::motors_from_joints({1, 0, 0, 1, 1, 1});
  EXPECT_EQ(signs[0], -160.0);
  EXPECT_EQ(signs[3], -100.0);
  EXPECT_EQ(signs[4], 100.0);
  EXPECT_EQ(signs[5], -80.0);
}

TEST(RntTransmission, SynchronisationPoseMapsBothWays) {
  const rnt::MotorPosition m = rnt::motors_from_joints(rnt::kSynchroJointPositions);
  const Joints q = rnt::joints_from_motors(rnt::kSynchroMotorPositions);
  for (std::size_t i = 0; i < kAxes; ++i) {
    EXPECT_NEAR(m[i], rnt::kSynchroMotorPositions[i], 1e-12) << i;
    EXPECT_NEAR(q[i], rnt::kSynchroJointPositions[i], 1e-15) << i;
  }
  EXPECT_NO_THROW(rnt::check_motor_limits(m));
  EXPECT_NO_THROW(rnt::check_limits(rnt::kSynchroJointPositions));
}

TEST(RntTransmission, MotorLimitErrorsNameMotorValueAndLimit) {
  rnt::MotorPosition m = rnt::kSynchroMotorPositions;
  m[2] = 305.5;
  try {
    rnt::check_motor_limits(m);
    FAIL();
  } catch (const CommandError& e) {
    EXPECT_EQ(e.code(), error_code::out_of_limits);
    EXPECT_STREQ(e.what(), "motor 2 (elbow) position 305.5 rad exceeds upper limit 305.0 rad");
  }
  m = rnt::kSynchroMotorPositions;
  m[0] = -451.0;
  try {
    rnt::check_motor_limits(m);
    FAIL();
  } catch (const CommandError& e) {
    EXPECT_EQ(e.code(), error_code::out_of_limits);
    EXPECT_STREQ(e.what(), "motor 0 (waist) position -451.0 rad is below lower limit -450.0 rad");
  }
  m[0] = std::nan("");
  try {
    rnt::check_motor_limits(m);
    FAIL();
  } catch (const CommandError& e) {
    EXPECT_EQ(e.code(), error_code::bad_argument);
  }
}

TEST(RntTransmission, ForearmPitchBeyondTheParallelogramRangeIsRefused) {
  // Both joints inside their limits, but q1 + q2 = 2.0 rad > 1.90625 rad.
  try {
    rnt::check_limits({0.0, 1.3, 0.7, 0.0, 0.0, 0.0});
    FAIL();
  } catch (const CommandError& e) {
    const std::string what = e.what();
    std::printf("%s\n", what.c_str());
    EXPECT_EQ(e.code(), error_code::out_of_limits);
    EXPECT_NE(what.find("motor 2 (elbow) target 320.0 rad exceeds upper limit 305.0 rad"),
              std::string::npos)
        << what;
    EXPECT_NE(what.find("absolute forearm pitch"), std::string::npos) << what;
  }
  try {
    rnt::check_limits({0.0, 0.0, 1.3, 0.0, 0.0, 0.0});
    FAIL();
  } catch (const CommandError& e) {
    EXPECT_STREQ(e.what(), "joint 2 (elbow) target 1.300000 rad exceeds upper limit 1.221730 rad");
  }
}

}  // namespace
