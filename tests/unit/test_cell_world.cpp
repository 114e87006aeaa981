/// @file
/// The axis emulator's cell world (emu/cell_world.hpp) and scene files (emu/scene.hpp):
/// composition of several robots into one MuJoCo world, their physics and the scene errors.

#include <algorithm>
#include <array>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <new>
#include <stdexcept>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <mujoco/mujoco.h>

#include "cell_world.hpp"
#include "mrroc/core/error.hpp"
#include "mrroc/edp/arm_kinematics.hpp"
#include "mrroc/kinematics/irb6.hpp"
#include "mrroc/kinematics/pose.hpp"
#include "mrroc/robot/robot_model.hpp"
#include "mrroc/sim/mujoco_support.hpp"
#include "scene.hpp"

#ifndef MRROC_SOURCE_DIR
#error "MRROC_SOURCE_DIR must be defined (absolute path of the source tree)"
#endif

#include "heap_counter.hpp"

namespace {

namespace fs = std::filesystem;
using mrroc::ConfigError;
using mrroc::emu::CellWorld;
using mrroc::emu::FramePose;
using mrroc::emu::Scene;

fs::path source_dir() { return fs::path(MRROC_SOURCE_DIR); }
fs::path scene_file(const char* name) { return source_dir() / "configs" / "scenes" / name; }

Eigen::Isometry3d isometry(const FramePose& pose) {
  Eigen::Isometry3d frame = Eigen::Isometry3d::Identity();
  frame.translation() = Eigen::Vector3d(pose.position[0], pose.position[1], pose.position[2]);
  frame.linear() = Eigen::Quaterniond(pose.quaternion[0], pose.quaternion[1], pose.quaternion[2],
                                      pose.quaternion[3])
                       .toRotationMatrix();
  return frame;
}

/// Largest difference between two frames: |dp| [m] and the largest rotation matrix entry.
double frame_error(const Eigen::Isometry3d& a, const Eigen::Isometry3d& b) {
  return std::max((a.translation() - b.translation()).norm(),
                  (a.linear() - b.linear()).cwiseAbs().maxCoeff());
}

std::vector<double> actuators(const CellWorld& world, std::size_t k) {
  std::vector<double> a(world.axis_count(k));
  EXPECT_TRUE(world.actuator_positions(k, a));
  return a;
}

/// A scratch folder of its own (mkdtemp), removed at the end of the test.
class ScratchDir {
 public:
  ScratchDir() {
    std::string pattern = (fs::temp_directory_path() / "mrroc_cell_XXXXXX").string();
    if (::mkdtemp(pattern.data()) == nullptr) throw std::runtime_error("mkdtemp failed");
    path_ = pattern;
  }
  ~ScratchDir() { fs::remove_all(path_); }
  ScratchDir(const ScratchDir&) = delete;
  ScratchDir& operator=(const ScratchDir&) = delete;
  [[nodiscard]] const fs::path& path() const { return path_; }
  fs::path write(const std::string& name, const std::string& text) const {
    const fs::path file = path_ / name;
    fs::create_directories(file.parent_path());
    std::ofstream(file) << text;
    return file;
  }

 private:
  fs::path path_;
};

/// The exception text of `f()`, which must throw ConfigError.
template <typename F>
std::string config_error(F&& f) {
  try {
    f();
  } catch (const ConfigError& e) {
    std::printf("  %s\n", e.what());
    return e.what();
  }
  ADD_FAILURE() << "no ConfigError";
  return {};
}

// ---- Composition ----

TEST(CellWorld, TwoIrb6SceneComposesWithPrefixedNames) {
  const CellWorld world(scene_file("two-irb6.toml"));
  const mjModel* m = world.model();
  EXPECT_EQ(world.name(), "two-irb6");
  ASSERT_EQ(world.robot_count(), 2U);
  EXPECT_EQ(world.robot(0).name, "left");
  EXPECT_EQ(world.robot(1).name, "right");
  EXPECT_EQ(world.robot_index("right"), 1U);
  EXPECT_THROW((void)world.robot_index("middle"), mrroc::Error);
  EXPECT_DOUBLE_EQ(world.timestep(), 0.001);
  const std::vector<std::string> axes = {"column", "lower_arm", "upper_arm", "wrist_pitch",
                                         "wrist_roll"};
  for (std::size_t k = 0; k < 2; ++k) {
    EXPECT_EQ(world.robot(k).axis_names, axes);
    EXPECT_FALSE(world.robot(k).coupled);
  }
  EXPECT_EQ(m->nu, 10);
  for (const char* name : {"left/column", "right/column", "left/wrist_roll", "right/upper_arm"}) {
    EXPECT_GE(mj_name2id(m, mjOBJ_JOINT, name), 0) << name;
    EXPECT_GE(mj_name2id(m, mjOBJ_ACTUATOR, name), 0) << name;
  }
  for (const char* name : {"left", "right", "left/column_link", "right/roll_link", "bar", "table"})
    EXPECT_GE(world.body_id(name), 0) << name;
  EXPECT_GE(world.site_id("right/flange"), 0);
  EXPECT_EQ(mj_name2id(m, mjOBJ_JOINT, "column"), -1) << "every robot name is prefixed";
  EXPECT_EQ(world.body_id("column_link"), -1);
  EXPECT_THROW((void)world.body_pose("nothing"), mrroc::Error);
  // One floor and one light for the scene; the robots' own are dropped.
  int planes = 0;
  for (int g = 0; g < m->ngeom; ++g) planes += m->geom_type[g] == mjGEOM_PLANE ? 1 : 0;
  EXPECT_EQ(planes, 1);
  EXPECT_EQ(m->nlight, 1);
  // The robot's defaults apply to its elements only: the arm is visual only, the bar collides.
  EXPECT_EQ(m->geom_contype[mj_name2id(m, mjOBJ_GEOM, "left/lower_arm_geom")], 0);
  EXPECT_EQ(m->geom_contype[mj_name2id(m, mjOBJ_GEOM, "bar")], 1);
  EXPECT_NE(world.composed_xml().find("name=\"left/column_link\""), std::string::npos);
  EXPECT_NE(world.composed_xml().find("childclass=\"right/main\""), std::string::npos);
}

TEST(CellWorld, FlangesAreWhereTheBasePosesSay) {
  Scene scene = mrroc::emu::load_scene(scene_file("two-irb6.toml"));
  const std::vector<std::vector<double>> poses = {{0.3, -1.4, 0.2, -0.5, 1.0},
                                                  {-1.0, -1.9, 0.5, 0.8, -2.0}};
  // The robot alone, from its own MJCF file.
  std::string error;
  const mrroc::sim::ModelPtr alone = mrroc::sim::load_mjcf(
      (source_dir() / "robots" / "irb6" / "irb6.xml").string(), nullptr, error);
  ASSERT_TRUE(alone) << error;
  const mrroc::sim::DataPtr alone_data(mj_makeData(alone.get()));
  const int alone_flange = mj_name2id(alone.get(), mjOBJ_SITE, "flange");
  for (const auto& q : poses) {
    scene.robots[0].initial_joint_positions = q;
    scene.robots[1].initial_joint_positions = q;
    const CellWorld world(scene);
    for (std::size_t k = 0; k < 2; ++k) {
      const auto& base_values = world.robot(k).base;
      const Eigen::Isometry3d base = mrroc::kinematics::from_values(
          base_values, mrroc::edp::ArmRepresentation::xyz_angle_axis);
      std::vector<double> joints(5);
      ASSERT_TRUE(world.joint_positions(k, joints));
      EXPECT_EQ(joints, q);
      const Eigen::Isometry3d flange = isometry(world.site_pose(world.robot(k).name + "/flange"));
      // mrroc's analytic kinematics of the IRb-6, moved to the base.
      mrroc::robots::irb6::JointPosition jq{};
      std::copy(q.begin(), q.end(), jq.begin());
      const Eigen::Isometry3d expected =
          base * mrroc::robots::irb6::forward_kinematics(
                     jq, mrroc::robots::irb6::kinematic_models(
                             mrroc::load_robot_model(source_dir() / "robots" / "irb6"))
                             .at(mrroc::robots::irb6::kNominalModel));
      EXPECT_LT(frame_error(flange, expected), 1e-9) << world.robot(k).name;
      // The single-robot MuJoCo model, moved to the base.
      for (int j = 0; j < 5; ++j)
        alone_data->qpos[alone->jnt_qposadr[j]] = q[static_cast<std::size_t>(j)];
      mj_kinematics(alone.get(), alone_data.get());
      FramePose alone_pose;
      const auto site = static_cast<std::size_t>(alone_flange);
      std::copy(alone_data->site_xpos + 3 * site, alone_data->site_xpos + 3 * site + 3,
                alone_pose.position.begin());
      mju_mat2Quat(alone_pose.quaternion.data(), alone_data->site_xmat + 9 * site);
      EXPECT_LT(frame_error(flange, base * isometry(alone_pose)), 1e-12) << world.robot(k).name;
    }
    // The right robot's base: 2 m along x, turned by pi about z.
    const FramePose right = world.body_pose("right");
    EXPECT_NEAR(right.position[0], 2.0, 1e-15);
    EXPECT_NEAR(std::abs(right.quaternion[3]), 1.0, 1e-15);
  }
}

// ---- Physics ----

TEST(CellWorld, HoldingThePowerOnPoseKeepsTheArmsStillWithoutAllocating) {
  CellWorld world(scene_file("two-irb6.toml"));
  const std::vector<double> left0 = actuators(world, 0);
  const std::vector<double> right0 = actuators(world, 1);
  for (std::size_t i = 0; i < 5; ++i) {
    EXPECT_DOUBLE_EQ(left0[i], world.robot(0).power_on_actuator_positions[i]);
    // Default power-on pose: synchronisation pose + 0.05 rad.
    EXPECT_NEAR(left0[i], world.robot(0).synchro_joint_positions[i] + 0.05, 1e-15);
  }
  const FramePose bar0 = world.body_pose("bar");
  const int bar = world.body_id("bar");
  std::array<double, 5> a{};
  std::array<double, 5> v{};
  std::array<double, 5> f{};
  std::array<double, 5> q{};
  double worst = 0.0;
  g_heap.allocations = 0;
  for (int s = 0; s < 2000; ++s) {
    g_heap.counting = true;
    const bool targets_ok = world.set_targets(0, left0) && world.set_targets(1, right0) &&
                            world.set_velocity_feed_forward(1, std::array<double, 5>{});
    const bool ok = world.step();
    const bool read_ok = world.actuator_positions(0, a) && world.actuator_velocities(1, v) &&
                         world.actuator_forces(0, f) && world.joint_positions(1, q) &&
                         world.synchro_switch(0, 2);
    const FramePose pose = world.body_pose(bar);
    const FramePose flange = world.site_pose(world.site_id("left/flange"));
    g_heap.counting = false;
    ASSERT_TRUE(targets_ok && ok && read_ok) << world.fault_text();
    (void)pose;
    (void)flange;
    for (std::size_t k = 0; k < 2; ++k) {
      const std::vector<double> now = actuators(world, k);
      const std::vector<double>& start = k == 0 ? left0 : right0;
      for (std::size_t i = 0; i < 5; ++i) worst = std::max(worst, std::abs(now[i] - start[i]));
    }
  }
  EXPECT_EQ(g_heap.allocations.load(), 0) << "set_targets/step/readings allocated on the heap";
  EXPECT_NEAR(world.time(), 2.0, 1e-9);
  std::printf("largest axis drift over 2 s holding the power-on pose: %.3e rad\n", worst);
  EXPECT_LT(worst, 1e-6);
  // The drives hold the arm against gravity: the lower arm's force is the gravity feed-forward.
  EXPECT_GT(std::abs(f[1]), 10.0);
  // The free bar rests on the table.
  const FramePose bar1 = world.body_pose("bar");
  EXPECT_NEAR(bar1.position[0], bar0.position[0], 1e-3);
  EXPECT_NEAR(bar1.position[2], bar0.position[2], 2e-3);
  EXPECT_GT(bar1.position[2], 0.8);
}

TEST(CellWorld, ATargetStepMovesOnlyThatRobotsAxis) {
  CellWorld world(scene_file("two-irb6.toml"));
  const std::vector<double> left0 = actuators(world, 0);
  const std::vector<double> right0 = actuators(world, 1);
  std::vector<double> target = left0;
  target[2] += 0.1;  // left upper arm
  ASSERT_TRUE(world.set_targets(0, target));
  const FramePose right_flange0 = world.site_pose("right/flange");
  for (int s = 0; s < 1500; ++s) ASSERT_TRUE(world.step()) << world.fault_text();
  const std::vector<double> left1 = actuators(world, 0);
  const std::vector<double> right1 = actuators(world, 1);
  EXPECT_NEAR(left1[2], target[2], 1e-4);
  for (std::size_t i = 0; i < 5; ++i) {
    if (i != 2) {
      EXPECT_NEAR(left1[i], left0[i], 1e-4) << "left axis " << i;
    }
    EXPECT_NEAR(right1[i], right0[i], 1e-12) << "right axis " << i;
  }
  EXPECT_LT(frame_error(isometry(world.site_pose("right/flange")), isometry(right_flange0)), 1e-12);
  // Refused commands change nothing.
  EXPECT_FALSE(world.set_targets(0, std::vector<double>(4, 0.0)));
  EXPECT_FALSE(world.set_targets(2, left0));
  target[1] = std::nan("");
  EXPECT_FALSE(world.set_targets(0, target));
  std::vector<double> out(4);
  EXPECT_FALSE(world.actuator_positions(0, out));
  // reset() goes back to the power-on state (without allocating).
  g_heap.allocations = 0;
  g_heap.counting = true;
  world.reset();
  g_heap.counting = false;
  EXPECT_EQ(g_heap.allocations.load(), 0);
  EXPECT_EQ(world.time(), 0.0);
  EXPECT_EQ(actuators(world, 0), left0);
}

TEST(CellWorld, SynchroSwitchesOpenBelowTheSynchroPositions) {
  CellWorld world(scene_file("irb6.toml"));
  ASSERT_EQ(world.robot_count(), 1U);
  for (std::size_t i = 0; i < 5; ++i) EXPECT_TRUE(world.synchro_switch(0, i)) << "axis " << i;
  std::vector<double> target = actuators(world, 0);
  target[0] -= 0.1;  // column to synchro - 0.05 rad
  ASSERT_TRUE(world.set_targets(0, target));
  std::vector<double> velocities(5, 0.0);
  velocities[0] = -0.1;
  ASSERT_TRUE(world.set_velocity_feed_forward(0, velocities));
  ASSERT_TRUE(world.set_velocity_feed_forward(0, std::vector<double>(5, 0.0)));
  for (int s = 0; s < 1000; ++s) ASSERT_TRUE(world.step()) << world.fault_text();
  EXPECT_FALSE(world.synchro_switch(0, 0));
  EXPECT_TRUE(world.synchro_switch(0, 1));
  EXPECT_FALSE(world.synchro_switch(0, 7));
  EXPECT_FALSE(world.synchro_switch(3, 0));
}

TEST(CellWorld, CellSceneClosesTheRntLoopAndCarriesThePartOnTheBelt) {
  Scene scene = mrroc::emu::load_scene(scene_file("cell.toml"));
  for (const bool given_pose : {false, true}) {
    if (given_pose) scene.robots[2].initial_joint_positions = {0.2, 0.4, -0.3, 1.2, 0.1, 0.0};
    CellWorld world(scene);
    ASSERT_EQ(world.robot_count(), 3U);
    const std::size_t rnt = world.robot_index("rnt");
    const std::size_t conveyor = world.robot_index("conveyor");
    const mjModel* m = world.model();
    const mjData* d = world.data();
    EXPECT_TRUE(world.robot(rnt).coupled);
    EXPECT_EQ(world.axis_count(conveyor), 1U);
    EXPECT_TRUE(world.robot(conveyor).linear[0]);
    const int loop = mj_name2id(m, mjOBJ_EQUALITY, "rnt/parallelogram");
    ASSERT_GE(loop, 0);
    EXPECT_LT(mrroc::sim::equality_violation(d, loop, 1), 1e-9) << "loop closed at power-on";
    std::vector<double> q(6);
    ASSERT_TRUE(world.joint_positions(rnt, q));
    const std::vector<double>& expected = given_pose ? *scene.robots[2].initial_joint_positions
                                                     : world.robot(rnt).power_on_joint_positions;
    for (std::size_t i = 0; i < 6; ++i) EXPECT_NEAR(q[i], expected[i], 1e-12) << "rnt axis " << i;
    // The serial elbow joint (passive) is where the coupling says.
    EXPECT_NEAR(d->qpos[m->jnt_qposadr[mj_name2id(m, mjOBJ_JOINT, "rnt/elbow")]], q[2], 1e-9);

    // Hold everything, move the belt 0.5 m: the part travels with it along -y of the cell.
    const FramePose part0 = world.body_pose("part");
    const std::vector<double> rnt0 = actuators(world, rnt);
    std::vector<double> belt = actuators(world, conveyor);
    belt[0] += 0.5;
    ASSERT_TRUE(world.set_targets(conveyor, belt));
    double worst_loop = 0.0;
    for (int s = 0; s < 2500; ++s) {
      ASSERT_TRUE(world.step()) << world.fault_text();
      worst_loop = std::max(worst_loop, mrroc::sim::equality_violation(d, loop, 1));
    }
    const FramePose part1 = world.body_pose("part");
    EXPECT_NEAR(part1.position[1] - part0.position[1], -0.5, 1e-3);
    EXPECT_NEAR(part1.position[0], part0.position[0], 1e-6);
    EXPECT_NEAR(part1.position[2], part0.position[2], 1e-6);
    const std::vector<double> rnt1 = actuators(world, rnt);
    for (std::size_t i = 0; i < 6; ++i) EXPECT_NEAR(rnt1[i], rnt0[i], 1e-6) << "rnt axis " << i;
    std::printf("rnt loop violation while holding: %.3e m\n", worst_loop);
    EXPECT_LT(worst_loop, 1e-4);
  }
}

TEST(CellWorld, UnstableRobotIsAFaultNamingItUntilReset) {
  const ScratchDir dir;
  // A stiff servo on a tiny mass, explicitly integrated: it diverges within a few steps.
  dir.write("wobbly/wobbly.xml",
            "<mujoco model='wobbly'><compiler angle='radian'/><option timestep='0.001'/>"
            "<worldbody><body name='slider'><joint name='j' type='slide' axis='1 0 0'/>"
            "<geom type='sphere' size='0.01' mass='0.0005'/></body></worldbody>"
            "<actuator><position name='j' joint='j' kp='2e6'/></actuator></mujoco>");
  dir.write("wobbly/parameters.toml",
            "[robot]\nmjcf = \"wobbly.xml\"\nsynchro_joint_positions = [0.0]\n");
  const fs::path scene = dir.write("scene.toml", R"([scene]
name = "shaky"
[[scene.robot]]
name = "irb6"
model = ")" + (source_dir() / "robots" / "irb6").string() +
                                                     R"("
[[scene.robot]]
name = "wobbly"
model = "wobbly"
gravity_compensation = false
)");
  CellWorld world(scene);
  ASSERT_TRUE(world.set_targets(1, std::vector<double>{1.0}));
  const auto previous = mju_user_warning;
  mju_user_warning = [](const char*) {};
  bool ok = true;
  for (int s = 0; s < 2000 && ok; ++s) ok = world.step();
  mju_user_warning = previous;
  EXPECT_FALSE(ok);
  EXPECT_TRUE(world.faulted());
  const std::string text = world.fault_text();
  std::printf("fault text: %s\n", text.c_str());
  EXPECT_NE(text.find("cell 'shaky' unstable"), std::string::npos) << text;
  EXPECT_NE(text.find("robot 'wobbly'"), std::string::npos) << text;
  EXPECT_NE(text.find("axis 0 'j'"), std::string::npos) << text;
  EXPECT_FALSE(world.step()) << "latched";
  world.reset();
  EXPECT_FALSE(world.faulted());
  EXPECT_TRUE(world.step());
}

TEST(SceneFile, AssetsDefaultsSensorsAndTendonsArePrefixedPerRobot) {
  // One model used twice: every name and reference must become the robot's own.
  const ScratchDir dir;
  dir.write("gizmo/meshes/tetra.obj",
            "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n");
  dir.write("gizmo/gizmo.xml", R"(<mujoco model="gizmo">
  <compiler angle="radian" meshdir="meshes"/>
  <option timestep="0.001"/>
  <default>
    <default class="shiny"><geom material="steel" contype="0" conaffinity="0"/></default>
  </default>
  <asset>
    <texture name="grid" type="2d" builtin="checker" width="8" height="8" rgb1="0 0 0" rgb2="1 1 1"/>
    <material name="steel" texture="grid"/>
    <mesh file="tetra.obj"/>
  </asset>
  <worldbody>
    <light name="sun" pos="0 0 3" dir="0 0 -1"/>
    <geom name="ground" type="plane" size="1 1 0.1"/>
    <body name="arm">
      <joint name="swing" axis="0 0 1" damping="10"/>
      <geom name="shell" class="shiny" type="mesh" mesh="tetra" mass="1"/>
      <site name="tip" pos="0.5 0 0"/>
    </body>
  </worldbody>
  <tendon><fixed name="spring"><joint joint="swing" coef="1"/></fixed></tendon>
  <actuator><position name="swing" joint="swing" kp="100"/></actuator>
  <sensor>
    <jointpos name="angle" joint="swing"/>
    <framepos name="tip_position" objtype="site" objname="tip"/>
  </sensor>
  <contact><exclude body1="arm" body2="world"/></contact>
</mujoco>
)");
  dir.write("gizmo/parameters.toml",
            "[robot]\nmjcf = \"gizmo.xml\"\njoint_names = [\"swing\"]\n"
            "synchro_joint_positions = [0.0]\n");
  const fs::path scene = dir.write("scene.toml", R"([scene]
[[scene.robot]]
name = "a"
model = "gizmo"
[[scene.robot]]
name = "b"
model = "gizmo"
base = [1.0, 0.0, 0.0, 0.0, 0.0, 0.0]
)");
  const CellWorld world(scene);
  const mjModel* m = world.model();
  EXPECT_EQ(m->nlight, 1);
  EXPECT_EQ(m->nmesh, 2);
  for (const char* robot : {"a", "b"}) {
    const std::string p = std::string(robot) + "/";
    const int shell = mj_name2id(m, mjOBJ_GEOM, (p + "shell").c_str());
    ASSERT_GE(shell, 0) << robot;
    EXPECT_EQ(m->geom_dataid[shell], mj_name2id(m, mjOBJ_MESH, (p + "tetra").c_str())) << robot;
    EXPECT_EQ(m->geom_matid[shell], mj_name2id(m, mjOBJ_MATERIAL, (p + "steel").c_str()));
    EXPECT_EQ(m->geom_contype[shell], 0) << "class 'shiny' of the robot";
    EXPECT_EQ(m->mat_texid[m->geom_matid[shell]],
              mj_name2id(m, mjOBJ_TEXTURE, (p + "grid").c_str()));
    const int sensor = mj_name2id(m, mjOBJ_SENSOR, (p + "tip_position").c_str());
    ASSERT_GE(sensor, 0);
    EXPECT_EQ(m->sensor_objid[sensor], world.site_id(p + "tip"));
    EXPECT_GE(mj_name2id(m, mjOBJ_TENDON, (p + "spring").c_str()), 0);
  }
  // The robots' "world" is their base body.
  ASSERT_EQ(m->nexclude, 2);
  // Both sites sit where their bases put them.
  EXPECT_NEAR(world.site_pose("b/tip").position[0] - world.site_pose("a/tip").position[0], 1.0,
              1e-12);
}

// ---- Scene file errors ----

TEST(SceneFile, ErrorsNameTheFileTheLineAndTheProblem) {
  const ScratchDir dir;
  const std::string irb6 = (source_dir() / "robots" / "irb6").string();
  const auto parse = [&](const std::string& text) {
    return config_error([&] { (void)mrroc::emu::parse_scene(text, dir.path() / "bad.toml"); });
  };
  const std::string head = "[scene]\nname = \"bad\"\n[[scene.robot]]\nname = \"left\"\n";
  std::string what = parse(head + "model = \"" + irb6 + "\"\ncolour = \"red\"\n");
  EXPECT_NE(what.find("bad.toml:6: error: unknown key 'colour'"), std::string::npos) << what;
  what = parse("[scene]\nstep = 0.001\n");
  EXPECT_NE(what.find("bad.toml:2: error: unknown key 'step' in [scene]"), std::string::npos);
  what = parse(head + "model = \"../no/such/robot\"\n");
  EXPECT_NE(what.find("bad.toml:5: error: model folder"), std::string::npos) << what;
  EXPECT_NE(what.find("not found"), std::string::npos) << what;
  what = parse(head + "model = \"" + irb6 + "\"\nbase = [1.0, 2.0]\n");
  EXPECT_NE(what.find("bad.toml:6: error: 'base' must be [x, y, z, rx, ry, rz]"), std::string::npos)
      << what;
  EXPECT_NE(what.find("2 values"), std::string::npos) << what;
  what = parse(head + "model = \"" + irb6 + "\"\n[[scene.robot]]\nname = \"left\"\nmodel = \"" +
               irb6 + "\"\n");
  EXPECT_NE(what.find("bad.toml:6: error: duplicate robot name 'left' (first used at "),
            std::string::npos)
      << what;
  what =
      parse("[scene]\ntimestep = 0.5\n[[scene.robot]]\nname = \"a\"\nmodel = \"" + irb6 + "\"\n");
  EXPECT_NE(what.find("bad.toml:2: error: 'timestep' = 0.5 s is outside"), std::string::npos)
      << what;
  what = parse(head + "model = \"" + irb6 +
               "\"\n[[scene.object]]\nname = \"ball\"\n"
               "type = \"sphere\"\nsize = [0.1, 0.2]\npos = [0, 0, 1]\nmass = 1.0\n");
  EXPECT_NE(what.find("bad.toml:9: error: 'size' must be [radius] (m)"), std::string::npos) << what;
  what = parse(head + "model = \"" + irb6 + "\"\n[[scene.object]]\nname = \"left\"\n");
  EXPECT_NE(what.find("bad.toml:6: error: missing key 'type' in [scene.object]"), std::string::npos)
      << what;
  what = parse("[scene]\nname = \"x\"\n[[scene.robot]]\nname = \"le/ft\"\n");
  EXPECT_NE(what.find("bad.toml:4: error: 'name' = \"le/ft\" must be a non-empty name"),
            std::string::npos)
      << what;
  what = parse("[scene\n");
  EXPECT_NE(what.find("bad.toml:1: error:"), std::string::npos) << what;
  what = config_error([&] { (void)mrroc::emu::load_scene(dir.path() / "missing.toml"); });
  EXPECT_NE(what.find("missing.toml:0: error: cannot read"), std::string::npos) << what;
}

TEST(SceneFile, CompositionAndPowerOnErrorsNameTheSceneLineAndTheFile) {
  const ScratchDir dir;
  const std::string irb6 = (source_dir() / "robots" / "irb6").string();
  const std::string conveyor = (source_dir() / "robots" / "conveyor").string();
  const auto world_error = [&](const std::string& text) {
    const fs::path file = dir.write("scene.toml", text);
    return config_error([&] { const CellWorld world(file); });
  };
  const std::string head = "[scene]\nname = \"bad\"\n[[scene.robot]]\nname = \"left\"\n";
  // A given power-on pose of the wrong size, or outside a range.
  std::string what =
      world_error(head + "model = \"" + irb6 + "\"\ninitial_joint_positions = [0.0, -1.5]\n");
  EXPECT_NE(what.find("scene.toml:6: error: initial_joint_positions has 2 values for 5 axes"),
            std::string::npos)
      << what;
  what = world_error(head + "model = \"" + irb6 +
                     "\"\ninitial_joint_positions = [0.0, 0.0, 0.0, 0.0, 0.0]\n");
  EXPECT_NE(what.find("scene.toml:6: error: initial_joint_positions[1] = 0 rad is outside the "
                      "range"),
            std::string::npos)
      << what;
  EXPECT_NE(what.find("joint 'left/lower_arm'"), std::string::npos) << what;
  // An object attached to a body that does not exist.
  what = world_error(head + "model = \"" + irb6 +
                     "\"\n[[scene.object]]\nname = \"box\"\n"
                     "type = \"box\"\nsize = [0.1, 0.1, 0.1]\npos = [0, 0, 1]\nmass = 1.0\n"
                     "attach = \"left/no_such_link\"\n");
  EXPECT_NE(what.find("scene.toml:6: error: object 'box': attach = \"left/no_such_link\" names no "
                      "body"),
            std::string::npos)
      << what;
  // A model whose compiler measures angles in degrees.
  {
    std::ifstream in(source_dir() / "robots" / "conveyor" / "conveyor.xml");
    std::string xml((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    const std::string radian = "<compiler angle=\"radian\"/>";
    ASSERT_NE(xml.find(radian), std::string::npos);
    dir.write("degree/belt.xml", std::string(xml).replace(xml.find(radian), radian.size(),
                                                          "<compiler angle=\"degree\"/>"));
    dir.write("degree/parameters.toml",
              "[robot]\nmjcf = \"belt.xml\"\n"
              "synchro_joint_positions = [0.0]\n");
    std::string gravity = xml;
    gravity.replace(gravity.find("0 0 -9.81"), 9, "0 0 -9.80");
    dir.write("moon/belt.xml", gravity);
    dir.write("moon/parameters.toml",
              "[robot]\nmjcf = \"belt.xml\"\n"
              "synchro_joint_positions = [0.0]\n");
    std::string include = xml;
    include.replace(include.find("<worldbody>"), 11, "<include file=\"more.xml\"/><worldbody>");
    dir.write("include/belt.xml", include);
    dir.write("include/more.xml",
              "<mujoco><custom><numeric name=\"n\" data=\"1\"/></custom></mujoco>");
    dir.write("include/parameters.toml",
              "[robot]\nmjcf = \"belt.xml\"\n"
              "synchro_joint_positions = [0.0]\n");
  }
  what = world_error(head + "model = \"" + irb6 +
                     "\"\n[[scene.robot]]\nname = \"belt\"\n"
                     "model = \"degree\"\n");
  EXPECT_NE(
      what.find("scene.toml:6: error: robot 'belt': '" +
                (dir.path() / "degree" / "belt.xml").string() + "': <compiler angle> is 'degree'"),
      std::string::npos)
      << what;
  what = world_error(head + "model = \"" + irb6 +
                     "\"\n[[scene.robot]]\nname = \"belt\"\n"
                     "model = \"moon\"\n");
  EXPECT_NE(what.find("scene.toml:6: error: robot 'belt': <option> gravity of '" +
                      (dir.path() / "moon" / "belt.xml").string() +
                      "' differs from that of robot 'left'"),
            std::string::npos)
      << what;
  what = world_error(head + "model = \"" + irb6 +
                     "\"\n[[scene.robot]]\nname = \"belt\"\n"
                     "model = \"include\"\n");
  EXPECT_NE(what.find("scene.toml:6: error: robot 'belt':"), std::string::npos) << what;
  EXPECT_NE(what.find("<include> is not supported"), std::string::npos) << what;
  // A model folder without parameters.toml, and an MJCF override that does not exist.
  dir.write("bare/readme.txt", "no parameters here\n");
  what = world_error(head + "model = \"bare\"\n");
  EXPECT_NE(what.find("scene.toml:3: error: robot 'left': robot parameter file"), std::string::npos)
      << what;
  what = world_error(head + "model = \"" + conveyor + "\"\nmjcf = \"no_such.xml\"\n");
  EXPECT_NE(what.find("scene.toml:3: error: robot 'left': cannot load MJCF model"),
            std::string::npos)
      << what;
}

TEST(SceneFile, TheRobotsMjcfCanBeOverridden) {
  const ScratchDir dir;
  const fs::path scene =
      dir.write("scene.toml", "[scene]\n[[scene.robot]]\nname = \"belt\"\nmodel = \"" +
                                  (source_dir() / "robots" / "conveyor").string() +
                                  "\"\nmjcf = \"conveyor.xml\"\nbase = [0, 0, 0.1, 0, 0, 0]\n");
  const CellWorld world(scene);
  EXPECT_EQ(world.name(), "scene");  // default: the file's stem
  EXPECT_EQ(world.robot(0).mjcf, source_dir() / "robots" / "conveyor" / "conveyor.xml");
  EXPECT_NEAR(world.body_pose("belt/belt_link").position[2], 0.85, 1e-12);
  EXPECT_EQ(world.robot(0).axis_names, std::vector<std::string>{"belt"});
  EXPECT_DOUBLE_EQ(world.robot(0).target_ranges[0].upper, 2.0);
}

// ---- Grasps ----

/// carry_bar's grip of robot k (0 left, 1 right) for the bar centre `centre`, in the robot's
/// base frame (mp/tasks/carry_bar.cpp), as joints.
std::vector<double> grip_joints(const CellWorld& world, std::size_t k,
                                const Eigen::Vector3d& centre, double shift_x = 0.0) {
  const double side = k == 0 ? 1.0 : -1.0;
  Eigen::Isometry3d grip = Eigen::Isometry3d::Identity();
  grip.linear().col(0) = Eigen::Vector3d(0, 0, -1);
  grip.linear().col(2) = Eigen::Vector3d(side, 0, 0);
  grip.linear().col(1) = grip.linear().col(2).cross(grip.linear().col(0));
  grip.translation() =
      centre - side * 0.2 * Eigen::Vector3d::UnitX() + shift_x * Eigen::Vector3d::UnitX();
  const Eigen::Isometry3d base = mrroc::kinematics::from_values(
      world.robot(k).base, mrroc::edp::ArmRepresentation::xyz_angle_axis);
  mrroc::robots::irb6::JointPosition seed{0.0, -1.5, 0.0, 0.0, 0.0};
  static const mrroc::robots::irb6::Irb6Geometry nominal = mrroc::robots::irb6::kinematic_models(
      mrroc::load_robot_model(source_dir() / "robots" / "irb6"))[0];
  const auto q = mrroc::robots::irb6::inverse_kinematics(base.inverse() * grip, seed, nominal);
  return {q.begin(), q.end()};
}

TEST(CellWorld, GraspsHoldTheBarUnstrainedAndAnOffsetStrainsItAsTheStiffnessSays) {
  Scene scene = mrroc::emu::load_scene(scene_file("two-irb6.toml"));
  ASSERT_EQ(scene.objects.at(1).grasps.size(), 2U);
  const double stiffness = scene.objects[1].grasps[0].stiffness;
  // Power on with both flanges at their grips of the bar 5 mm above where it lies: both grips
  // close at once and lift it off the table.
  const Eigen::Vector3d centre(1.0, 0.0, 1.105);
  {
    const CellWorld probe(scene);
    for (std::size_t k = 0; k < 2; ++k)
      scene.robots[k].initial_joint_positions = grip_joints(probe, k, centre);
  }
  CellWorld world(scene);
  ASSERT_EQ(world.grasp_count(), 2U);
  EXPECT_EQ(world.grasp(0).gripper, "left/flange");
  EXPECT_EQ(world.grasp(1).object, "bar");
  ASSERT_EQ(world.held_object_count(), 1U);
  EXPECT_EQ(world.held_object_index("bar"), 0U);
  EXPECT_THROW((void)world.held_object_index("table"), mrroc::Error);
  EXPECT_FALSE(world.grasp_engaged(0));
  EXPECT_NEAR(world.grasp_offset(0), 0.005, 2e-4) << "the bar lies 5 mm below the grip";
  const std::vector<double> left = actuators(world, 0);
  const std::vector<double> right = actuators(world, 1);
  g_heap.allocations = 0;
  g_heap.counting = true;
  bool ok = true;
  for (int s = 0; s < 1000; ++s) ok = ok && world.step();
  g_heap.counting = false;
  ASSERT_TRUE(ok) << world.fault_text();
  EXPECT_EQ(g_heap.allocations.load(), 0) << "grasps allocated in step()";
  ASSERT_TRUE(world.grasp_engaged(0) && world.grasp_engaged(1));
  EXPECT_LT(world.grasp_engaged_at(0), 0.05);  // once the arms have settled at power-on
  // Held 5 mm above the table, the weight shared: each grip pulls half of it up, nothing else.
  EXPECT_NEAR(world.body_pose("bar").position[2], centre.z(), 2e-4);
  const double weight = 9.81 * 1.0;
  for (std::size_t g = 0; g < 2; ++g) {
    const auto f = world.grasp_force(g);
    std::printf("grip %zu holding the bar: force [%.4f, %.4f, %.4f] N, offset %.2e m\n", g, f[0],
                f[1], f[2], world.grasp_offset(g));
    EXPECT_NEAR(f[2], weight / 2, 0.05) << g;
    EXPECT_NEAR(f[0], 0.0, 0.5) << g;
    EXPECT_NEAR(world.grasp_offset(g), weight / 2 / stiffness, 2e-5) << g;
  }
  const double unstrained = world.internal_force(0);
  std::printf("internal force, unstrained: %.4f N (peak %.4f N while closing)\n", unstrained,
              world.peak_internal_force(0));
  EXPECT_LT(unstrained, 0.5);  // 0.35 N: the arms' sag under the bar, mirrored along x
  // The right robot's grip moved along x by 1 and 2 mm towards the left one: both grips squeeze
  // the bar; each is off its grasp frame by about half the offset (the arms are far stiffer).
  std::vector<double> forces;
  for (const double offset : {0.001, 0.002}) {
    ASSERT_TRUE(world.set_targets(1, grip_joints(world, 1, centre, -offset)));
    for (int s = 0; s < 1000; ++s) ASSERT_TRUE(world.step()) << world.fault_text();
    const double internal = world.internal_force(0);
    const double predicted = stiffness * offset / 2;
    const auto f = world.grasp_force(0);
    std::printf(
        "right grip %.0f mm off: internal force %.1f N (stiffness * offset / 2 = %.1f N), left "
        "grip force x %.1f N, grips off their frames %.3f and %.3f mm\n",
        offset * 1e3, internal, predicted, f[0], world.grasp_offset(0) * 1e3,
        world.grasp_offset(1) * 1e3);
    EXPECT_NEAR(internal, predicted, 0.25 * predicted) << offset;
    // Statically exact: each grip's force is its stiffness times how far it is off its frame.
    EXPECT_NEAR(std::abs(f[0]), stiffness * world.grasp_offset(0), 0.02 * std::abs(f[0]));
    EXPECT_GT(f[0], 0.0) << "the left grip pushes the bar back towards +x";
    forces.push_back(internal);
  }
  EXPECT_NEAR(forces[1] / forces[0], 2.0, 0.1) << "linear in the offset";
  EXPECT_GE(world.peak_internal_force(0), forces[1]);
  // reset() opens the grips.
  world.reset();
  EXPECT_FALSE(world.grasp_engaged(0));
  EXPECT_EQ(world.peak_internal_force(0), 0.0);
  (void)left;
  (void)right;
}

TEST(SceneFile, GraspErrorsNameTheKeyAndTheLimit) {
  const ScratchDir dir;
  const std::string irb6 = (source_dir() / "robots" / "irb6").string();
  const std::string head = "[scene]\n[[scene.robot]]\nname = \"left\"\nmodel = \"" + irb6 +
                           "\"\n[[scene.object]]\nname = \"bar\"\ntype = \"box\"\nsize = [0.2, "
                           "0.02, 0.02]\npos = [1, 0, 1]\nmass = 1.0\n";
  const auto error = [&](const std::string& text) -> std::string {
    try {
      const CellWorld world(dir.write("scene.toml", head + text));
    } catch (const ConfigError& e) {
      return e.what();
    }
    return {};
  };
  EXPECT_NE(error("[[scene.object.grasp]]\nat = [0, 0, 0]\n").find("give exactly one of 'site'"),
            std::string::npos);
  EXPECT_NE(error("[[scene.object.grasp]]\nsite = \"left/hand\"\nat = [0, 0, 0]\n")
                .find("site 'left/hand' is not in the scene"),
            std::string::npos);
  EXPECT_NE(error("[[scene.object.grasp]]\nbody = \"bar\"\nat = [0, 0, 0]\n")
                .find("which is not a robot's"),
            std::string::npos);
  EXPECT_NE(error("[[scene.object.grasp]]\nsite = \"left/flange\"\n").find("missing key 'at'"),
            std::string::npos);
  EXPECT_NE(error("[[scene.object.grasp]]\nsite = \"left/flange\"\nat = [0, 0, 0]\nstiffness = "
                  "-5\n")
                .find("'stiffness' = -5 N/m is outside the accepted range"),
            std::string::npos);
  EXPECT_NE(error("[[scene.object.grasp]]\nsite = \"left/flange\"\nat = [0, 0, 0]\ngrip = 1\n")
                .find("unknown key 'grip' in [scene.object.grasp]"),
            std::string::npos);
  EXPECT_EQ(error("[[scene.object.grasp]]\nbody = \"left/roll_link\"\npos = [0.19, 0, 0]\nat = "
                  "[0, 0, 0]\n"),
            "");
}

// ---- Cutting ----

/// The RNT of configs/scenes/engrave.toml (base at the world's origin) with its cutter: joints
/// that put the cutter tip at a point, pointing down as over the board's centre.
class RntCutter {
 public:
  RntCutter()
      : model_(mrroc::load_robot_model(source_dir() / "robots" / "rnt")),
        kinematics_(mrroc::edp::make_arm_kinematics(model_)) {
    Eigen::Isometry3d tool = Eigen::Isometry3d::Identity();
    tool.translation() = Eigen::Vector3d(0.0, 0.0, 0.15);  // the MJCF's site `tool`
    kinematics_->set_tool(tool);
    down_ = kinematics_->forward(seed_).linear();
  }
  /// Joints q with the tip at `tip` [m], nearest to the last ones.
  std::vector<double> joints(const Eigen::Vector3d& tip) {
    Eigen::Isometry3d target = Eigen::Isometry3d::Identity();
    target.linear() = down_;
    target.translation() = tip;
    seed_ = kinematics_->inverse(target, seed_);
    return seed_;
  }
  /// Actuator positions a = M q of the cell's robot 0.
  static std::vector<double> actuators(const CellWorld& world, const std::vector<double>& q) {
    const std::vector<double>& m = world.robot(0).coupling;
    std::vector<double> a(q.size(), 0.0);
    for (std::size_t i = 0; i < q.size(); ++i)
      for (std::size_t j = 0; j < q.size(); ++j) a[i] += m[i * q.size() + j] * q[j];
    return a;
  }

 private:
  mrroc::RobotModel model_;
  std::unique_ptr<mrroc::edp::ArmKinematics> kinematics_;
  std::vector<double> seed_ = {0.0, 0.8190, 0.2630, 0.4887, 0.0, 0.0};  // tip over the centre
  Eigen::Matrix3d down_;
};

/// Drives robot 0's tip along `path(t)` [m] for `duration` [s] (position targets and velocity
/// feed-forward of each step); `each` sees the world after every step. Counts heap allocations
/// of the world's calls into `allocations`.
template <typename Path, typename Each>
void drive_tip(CellWorld& world, RntCutter& rnt, Path path, double duration, Each each,
               long& allocations) {
  const double dt = world.timestep();
  const int steps = static_cast<int>(std::lround(duration / dt));
  std::vector<double> a = RntCutter::actuators(world, rnt.joints(path(0.0)));
  for (int s = 1; s <= steps; ++s) {
    const std::vector<double> next = RntCutter::actuators(world, rnt.joints(path(s * dt)));
    std::vector<double> v(next.size());
    for (std::size_t i = 0; i < v.size(); ++i) v[i] = (next[i] - a[i]) / dt;
    a = next;
    g_heap.allocations = 0;
    g_heap.counting = true;
    const bool ok =
        world.set_targets(0, a) && world.set_velocity_feed_forward(0, v) && world.step();
    const mrroc::emu::CutReading& reading = world.cut_reading(0);
    const mrroc::emu::CutSummary& summary = world.cut_summary(0);
    const auto groove = world.groove(0);
    g_heap.counting = false;
    allocations += g_heap.allocations.load();
    (void)reading;
    (void)summary;
    (void)groove;
    ASSERT_TRUE(ok) << world.fault_text();
    each(s * dt);
  }
}

/// A straight move from `from` to `to` [m] in `duration` [s]: constant acceleration over the
/// first and last quarter, constant speed between (4/3 of the mean speed).
auto straight(const Eigen::Vector3d& from, const Eigen::Vector3d& to, double duration) {
  return [=](double t) {
    const double u = std::clamp(t / duration, 0.0, 1.0);
    // s(u) for a trapezoidal speed over quarters; s(1) = 1.
    const double peak = 4.0 / 3.0;
    double s = 0.0;
    if (u < 0.25) {
      s = 0.5 * peak / 0.25 * u * u;
    } else if (u < 0.75) {
      s = 0.5 * peak * 0.25 + peak * (u - 0.25);
    } else {
      const double r = 1.0 - u;
      s = 1.0 - 0.5 * peak / 0.25 * r * r;
    }
    return Eigen::Vector3d(from + s * (to - from));
  };
}

TEST(CellWorld, TheCutterMeetsTheBoardsResistanceAndLeavesItsGroove) {
  Scene scene = mrroc::emu::load_scene(scene_file("engrave.toml"));
  ASSERT_EQ(scene.objects.at(0).cutters.size(), 1U);
  const double k = scene.objects[0].cutters[0].specific_force;
  const double radius = scene.objects[0].cutters[0].radius;
  constexpr double kDepth = 0.002;
  constexpr double kSurface = 0.20;                     // the board's top face [m]
  const double side_force = k * kDepth * 2.0 * radius;  // along the board at 2 mm depth
  const double end_force = k * M_PI * radius * radius;  // plunging
  // The same 20 mm move along +y at 2 mm depth and 10 mm above the board, from power-on there.
  const Eigen::Vector3d start(0.60, -0.02, kSurface - kDepth);
  const Eigen::Vector3d end(0.60, 0.0, kSurface - kDepth);
  const Eigen::Vector3d above(0.0, 0.0, kDepth + 0.01);
  constexpr double kMove = 0.6;  // s: cruising at 0.044 m/s from 0.15 s to 0.45 s
  struct Run {
    std::vector<double> waist_force;  ///< per step of the move [N m]
    std::vector<double> force_y;      ///< the reading's force along the move [N]
    std::vector<double> force_norm;
  };
  long allocations = 0;
  Run cut;
  Run free;
  for (Run* run : {&free, &cut}) {
    const Eigen::Vector3d lift = run == &free ? above : Eigen::Vector3d::Zero();
    RntCutter rnt;
    scene.robots[0].initial_joint_positions = rnt.joints(start + lift);
    CellWorld world(scene);
    ASSERT_EQ(world.cut_count(), 1U);
    EXPECT_EQ(world.cut(0).cutter, "rnt/tool");
    EXPECT_EQ(world.cut_index("board"), 0U);
    EXPECT_EQ(world.cut_index("board", "rnt/tool"), 0U);
    EXPECT_THROW((void)world.cut_index("table"), mrroc::Error);
    EXPECT_THROW((void)world.cut_index("board", "rnt/flange"), mrroc::Error);
    const mrroc::emu::CutReading& now = world.cut_reading(0);
    if (run == &cut) {
      // At power-on the tip is 2 mm deep at (0, -0.02) of the board's frame, and still.
      EXPECT_TRUE(now.cutting);
      EXPECT_NEAR(now.depth, kDepth, 1e-6);
      EXPECT_NEAR(now.tip[0], 0.0, 1e-6);
      EXPECT_NEAR(now.tip[1], -0.02, 1e-6);
      EXPECT_NEAR(now.tip[2], 0.01 - kDepth, 1e-6);
      EXPECT_EQ(now.force_norm, 0.0);
      EXPECT_EQ(world.cut_summary(0).strokes, 1);
    } else {
      EXPECT_FALSE(now.cutting);
      EXPECT_NEAR(now.depth, -0.01, 1e-6);
    }
    std::array<double, 6> f{};
    drive_tip(
        world, rnt, straight(start + lift, end + lift, kMove), kMove,
        [&](double t) {
          ASSERT_TRUE(world.actuator_forces(0, f));
          run->waist_force.push_back(f[0]);
          run->force_y.push_back(now.force[1]);
          run->force_norm.push_back(now.force_norm);
          if (run == &cut) {
            ASSERT_TRUE(now.cutting) << "t = " << t;
            ASSERT_NEAR(now.depth, kDepth, 2e-4) << "t = " << t;
          }
        },
        allocations);
    if (HasFatalFailure()) return;
    if (run == &free) {
      EXPECT_EQ(world.cut_summary(0).strokes, 0);
      EXPECT_TRUE(world.groove(0).empty());
      continue;
    }
    // Lift out, then plunge 20 mm further along at 0.05 m/s (mean) from 5 mm above.
    const Eigen::Vector3d up = end + Eigen::Vector3d(0.0, 0.0, kDepth + 0.005);
    drive_tip(
        world, rnt, straight(end, up, 0.3), 0.3, [](double) {}, allocations);
    if (HasFatalFailure()) return;
    EXPECT_FALSE(now.cutting);
    EXPECT_EQ(now.force_norm, 0.0);
    const mrroc::emu::CutSummary first = world.cut_summary(0);
    const std::vector<mrroc::emu::GroovePoint> groove(world.groove(0).begin(),
                                                      world.groove(0).end());
    const Eigen::Vector3d over(0.60, 0.02, kSurface + 0.005);
    drive_tip(
        world, rnt, straight(up, over, 0.5), 0.5, [](double) {}, allocations);
    double plunge_force = 0.0;
    drive_tip(
        world, rnt, straight(over, over - Eigen::Vector3d(0, 0, 0.005 + kDepth), 0.28), 0.28,
        [&](double) { plunge_force = std::max(plunge_force, now.force[2]); }, allocations);
    if (HasFatalFailure()) return;
    EXPECT_EQ(world.cut_summary(0).strokes, 2);
    EXPECT_NEAR(plunge_force, end_force, 0.05 * end_force)
        << "plunging at 0.033 m/s (peak), above the creep speed: the end face's resistance";
    std::printf("plunge: largest upward resistance %.1f N (k pi r^2 = %.1f N)\n", plunge_force,
                end_force);

    // The first groove: where the tip went, 2 mm deep, 20 mm long.
    std::printf(
        "first groove: %d stroke, %.2f mm long, %.3f mm deep at most, peak force %.1f N, "
        "%zu points\n",
        first.strokes, first.length * 1e3, first.max_depth * 1e3, first.peak_force, groove.size());
    EXPECT_EQ(first.strokes, 1);
    EXPECT_NEAR(first.length, 0.020, 5e-4);
    EXPECT_NEAR(first.max_depth, kDepth, 2e-4);
    ASSERT_GE(groove.size(), 80U) << "a point every 0.2 mm (+ one step) of 20 mm";
    EXPECT_LE(groove.size(), 101U);
    EXPECT_NEAR(groove.front().y, -0.02, 1e-5);
    EXPECT_NEAR(groove.back().y, 0.0, 5e-4);
    for (const mrroc::emu::GroovePoint& g : groove) {
      EXPECT_EQ(g.stroke, 0);
      EXPECT_NEAR(g.x, 0.0, 2e-4);
      EXPECT_GE(g.y, -0.0201);
      EXPECT_LE(g.y, 0.0005);
      EXPECT_GT(g.depth, 0.0);
      EXPECT_LE(g.depth, kDepth + 2e-4);
    }
    world.reset();
    EXPECT_EQ(world.cut_summary(0).strokes, 1) << "powered on in the board";
    EXPECT_EQ(world.groove(0).size(), 1U);
    EXPECT_EQ(world.cut_summary(0).length, 0.0);
  }
  EXPECT_EQ(allocations, 0) << "cutting allocated in step() or the readings";

  // While cruising, the reading's force opposes the motion with k * depth * 2 r, and the waist
  // drive pushes through it: its torque exceeds that of the same move in the air by the
  // resistance's moment about the waist axis, x * |F| (x = 0.60 m).
  const auto steps = static_cast<double>(cut.force_y.size());
  const auto from = static_cast<std::size_t>(0.2 / kMove * steps);
  const auto to = static_cast<std::size_t>(0.4 / kMove * steps);
  double extra = 0.0;
  double force = 0.0;
  for (std::size_t i = from; i < to; ++i) {
    EXPECT_NEAR(cut.force_y[i], -cut.force_norm[i], 0.02 * side_force) << i;
    EXPECT_NEAR(cut.force_norm[i], side_force, 0.05 * side_force) << i;
    EXPECT_EQ(free.force_norm[i], 0.0);
    extra += cut.waist_force[i] - free.waist_force[i];
    force += cut.force_norm[i];
  }
  extra /= static_cast<double>(to - from);
  force /= static_cast<double>(to - from);
  std::printf(
      "cruising 2 mm deep: resistance %.2f N (k d 2r = %.2f N); waist torque %.2f N m "
      "above the move in the air (x |F| = %.2f N m)\n",
      force, side_force, extra, 0.60 * force);
  EXPECT_NEAR(extra, 0.60 * force, 0.1 * 0.60 * force);
}

TEST(SceneFile, CutterErrorsNameTheKeyAndTheLimit) {
  const ScratchDir dir;
  const std::string rnt = (source_dir() / "robots" / "rnt").string();
  const std::string head =
      "[scene]\n[[scene.robot]]\nname = \"rnt\"\nmodel = \"" + rnt +
      "\"\n[[scene.object]]\nname = \"board\"\npos = [0.6, 0, 0.19]\nmass = 1.0\n";
  const auto error = [&](const std::string& text) -> std::string {
    try {
      const CellWorld world(dir.write("scene.toml", head + text));
    } catch (const ConfigError& e) {
      return e.what();
    }
    return {};
  };
  const std::string cutter = "[[scene.object.cutter]]\nsite = \"rnt/tool\"\nradius = 0.004\n";
  EXPECT_NE(error("type = \"box\"\nsize = [0.15, 0.2, 0.01]\n" + cutter)
                .find("a board to cut must be fixed"),
            std::string::npos);
  EXPECT_NE(error("type = \"cylinder\"\nsize = [0.2, 0.01]\nattach = \"world\"\n" + cutter)
                .find("only a box (a board, cut on its top face) can be cut, not a cylinder"),
            std::string::npos);
  const std::string board = "type = \"box\"\nsize = [0.15, 0.2, 0.01]\nattach = \"world\"\n";
  EXPECT_NE(error(board + "[[scene.object.cutter]]\nradius = 0.004\n").find("missing key 'site'"),
            std::string::npos);
  EXPECT_NE(
      error(board + "[[scene.object.cutter]]\nsite = \"rnt/tool\"\n").find("missing key 'radius'"),
      std::string::npos);
  EXPECT_NE(error(board + cutter + "specific_force = 0\n")
                .find("'specific_force' = 0 N/m^2 is outside the accepted range 1 .. 1000000000"),
            std::string::npos);
  EXPECT_NE(error(board + "[[scene.object.cutter]]\nsite = \"rnt/tool\"\nradius = 0.5\n")
                .find("'radius' = 0.5 m is outside the accepted range"),
            std::string::npos);
  EXPECT_NE(error(board + cutter + "depth = 1\n")
                .find("unknown key 'depth' in "
                      "[scene.object.cutter]"),
            std::string::npos);
  EXPECT_NE(error(board + "[[scene.object.cutter]]\nsite = \"rnt/drill\"\nradius = 0.004\n")
                .find("cutter of object 'board': site 'rnt/drill' is not in the scene"),
            std::string::npos);
  EXPECT_EQ(error(board + cutter), "");
}

// ---- Performance (printed, not asserted) ----

TEST(CellWorld, StepTime) {
  for (const char* name : {"irb6.toml", "two-irb6.toml", "cell.toml"}) {
    const auto built = std::chrono::steady_clock::now();
    CellWorld world(scene_file(name));
    const double build_time =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - built).count();
    constexpr int kSteps = 5000;
    const auto started = std::chrono::steady_clock::now();
    for (int s = 0; s < kSteps; ++s) ASSERT_TRUE(world.step()) << world.fault_text();
    const double elapsed =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count();
    std::printf(
        "%-14s nq %2d nv %2d nu %2d: %.1f us per step of %.0f us (%d steps), built in "
        "%.1f ms\n",
        name, world.model()->nq, world.model()->nv, world.model()->nu, elapsed / kSteps * 1e6,
        world.timestep() * 1e6, kSteps, build_time * 1e3);
  }
}

}  // namespace
