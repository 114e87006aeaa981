/// @file
/// The emulated drives' digital input lines wired to the physics of a scene (emu/drives.hpp,
/// [[scene.robot.drives.input]]): configuration errors at their file and line, the light
/// barrier of conveyor-pick.toml switching as the belt carries the part through it, grasp and
/// loop-back wires (with a real Cia402Drive's output lines), `invert`, and evaluation without
/// allocation.

#include <linux/can.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <Eigen/Geometry>

#include "cell_world.hpp"
#include "drives.hpp"
#include "mrroc/can/canopen.hpp"
#include "mrroc/can/cia402_drive.hpp"
#include "mrroc/core/error.hpp"
#include "mrroc/edp/arm_kinematics.hpp"
#include "mrroc/kinematics/irb6.hpp"
#include "mrroc/kinematics/pose.hpp"
#include "mrroc/robot/robot_model.hpp"
#include "scene.hpp"

#ifndef MRROC_SOURCE_DIR
#error "MRROC_SOURCE_DIR must be defined (absolute path of the source tree)"
#endif

#include "heap_counter.hpp"

namespace {

namespace fs = std::filesystem;
namespace co = mrroc::can::canopen;
using mrroc::ConfigError;
using mrroc::emu::CellWorld;
using mrroc::emu::RobotDrives;

fs::path source_dir() { return fs::path(MRROC_SOURCE_DIR); }
fs::path scene_file(const char* name) { return source_dir() / "configs" / "scenes" / name; }

/// A scratch folder of its own (mkdtemp), removed at the end of the test.
class ScratchDir {
 public:
  ScratchDir() {
    std::string pattern = (fs::temp_directory_path() / "mrroc_inputs_XXXXXX").string();
    if (::mkdtemp(pattern.data()) == nullptr) throw std::runtime_error("mkdtemp failed");
    path_ = pattern;
  }
  ~ScratchDir() { fs::remove_all(path_); }
  ScratchDir(const ScratchDir&) = delete;
  ScratchDir& operator=(const ScratchDir&) = delete;
  [[nodiscard]] fs::path write(const std::string& name, const std::string& text) const {
    const fs::path file = path_ / name;
    std::ofstream(file) << text;
    return file;
  }

 private:
  fs::path path_;
};

std::string read_text(const fs::path& file) {
  std::ifstream in(file);
  std::stringstream text;
  text << in.rdbuf();
  return text.str();
}

/// The input lines of robot k's axes now, with `outputs` as its drives' output lines.
std::vector<std::uint8_t> inputs_of(const RobotDrives& wiring, const CellWorld& world,
                                    const std::vector<std::uint8_t>& outputs) {
  std::vector<std::uint8_t> inputs(wiring.nodes.size(), 0xA5);
  EXPECT_TRUE(mrroc::emu::evaluate_inputs(wiring, world, outputs, inputs));
  return inputs;
}

bool bit(std::uint8_t lines, int k) { return ((lines >> k) & 1U) != 0; }

// ---- Configuration errors ----

TEST(EmuInputs, ConfigErrorsNameTheFileLineKeyAndLimit) {
  const ScratchDir dir;
  const std::string head =
      "[scene]\n"                   // 1
      "[[scene.object]]\n"          // 2
      "name = \"bar\"\n"            // 3
      "type = \"box\"\n"            // 4
      "size = [0.2, 0.02, 0.02]\n"  // 5
      "pos = [1, 0, 1]\n"           // 6
      "mass = 1.0\n"                // 7
      "[[scene.object.grasp]]\n"    // 8
      "site = \"irb6/flange\"\n"    // 9
      "at = [0, 0, 0]\n"            // 10
      "[[scene.robot]]\n"           // 11
      "name = \"irb6\"\n"           // 12
      "model = \"" MRROC_SOURCE_DIR
      "/robots/irb6\"\n"                 // 13
      "[[scene.robot.drives.input]]\n";  // 14
  const CellWorld world(dir.write("world.toml", head.substr(0, head.rfind("[[scene.robot.dr"))));
  const auto error = [&](const std::string& keys) -> std::string {
    const fs::path file = dir.write("s.toml", head + keys);
    try {
      (void)mrroc::emu::read_drive_wiring(file, world, {});
    } catch (const ConfigError& e) {
      std::printf("  %s\n", e.what());
      return e.what();
    }
    ADD_FAILURE() << "no ConfigError for\n" << keys;
    return {};
  };
  const auto has = [](const std::string& text, const std::string& part) {
    EXPECT_NE(text.find(part), std::string::npos) << text << "\n  lacks: " << part;
  };
  const std::string at = "s.toml:";
  const std::string who = ": error: robot 'irb6', [[scene.robot.drives.input]]: ";
  const std::string loop = "source = \"output\"\nfrom_axis = 0\nfrom_line = 0\n";  // 15..17
  has(error(loop + "axis = 0\nline = 0\nwire = 1\n"),
      at + "20" + who +
          "unknown key 'wire' (allowed: axis, line, source, invert, from_axis, "
          "from_line)");
  has(error(loop + "axis = \"waist\"\nline = 0\n"),
      at + "18" + who +
          "'axis' = \"waist\": robot 'irb6' has no axis 'waist' (axes: column, lower_arm, "
          "upper_arm, wrist_pitch, wrist_roll)");
  has(error(loop + "axis = 5\nline = 0\n"),
      at + "18" + who + "'axis' = 5: robot 'irb6' has no axis 5 (axes 0..4: column");
  has(error(loop + "axis = 0\nline = 8\n"), at + "19" + who + "'line' = 8 is outside 0..7");
  has(error(loop + "axis = 0\nline = \"a\"\n"),
      at + "19" + who + "'line' must be an integer in 0..7");
  has(error("source = \"output\"\nfrom_axis = \"roll\"\nfrom_line = 0\naxis = 0\nline = 0\n"),
      at + "16" + who + "'from_axis' = \"roll\": robot 'irb6' has no axis 'roll'");
  has(error("source = \"output\"\nfrom_axis = 0\nfrom_line = -1\naxis = 0\nline = 0\n"),
      at + "17" + who + "'from_line' = -1 is outside 0..7");
  has(error(loop + "axis = 0\nline = 0\ninvert = 1\n"),
      at + "20" + who + "'invert' must be true or false");
  has(error(loop + "axis = 0\nline = 0\nregion = [0, 1, 0, 1, 0, 1]\n"),
      at + "20" + who +
          "'region' is a key of source \"presence\", not of \"output\" (its keys: from_axis, "
          "from_line)");
  has(error("source = \"grasp\"\nobject = \"bar\"\naxis = 0\nline = 0\nfrom_line = 0\n"),
      at + "19" + who + "'from_line' is a key of source \"output\", not of \"grasp\"");
  has(error("source = \"light\"\naxis = 0\nline = 0\n"),
      at + "15" + who + "'source' = \"light\" is not presence, grasp or output");
  has(error("axis = 0\nline = 0\n"), at + "14" + who + "missing key 'source'");
  has(error("source = \"output\"\nfrom_axis = 0\naxis = 0\nline = 0\n"),
      at + "14" + who + "missing key 'from_line'");
  has(error("source = \"output\"\nfrom_axis = 0\nfrom_line = 0\nline = 0\n"),
      at + "14" + who + "missing key 'axis'");
  // Presence.
  const std::string presence = "source = \"presence\"\naxis = 0\nline = 0\n";  // 15..17
  has(error(presence + "object = \"part\"\nregion = [0, 1, 0, 1, 0, 1]\n"),
      at + "18" + who + "'object' = \"part\" is not a body of the scene");
  has(error(presence + "object = \"bar\"\n"), at + "14" + who + "missing key 'region'");
  has(error(presence + "object = \"bar\"\nregion = [0, 1, 1, 0, 0, 1]\n"),
      at + "19" + who + "'region' y range 1 .. 0 m is empty");
  has(error(presence + "object = \"bar\"\nregion = [0, 1, 0, 1, 0.5, 0.5]\n"),
      at + "19" + who + "'region' z range 0.5 .. 0.5 m is empty");
  has(error(presence + "object = \"bar\"\nregion = [0, 1, 0, 1]\n"),
      at + "19" + who + "'region' must be [x0, x1, y0, y1, z0, z1] (m, world frame) (4 values)");
  has(error(presence + "object = \"bar\"\nregion = [0, 1, 0, 1, 0, \"top\"]\n"),
      at + "19" + who + "every value of 'region' must be a finite number [m]");
  // Grasp.
  const std::string grasp = "source = \"grasp\"\naxis = 0\nline = 0\n";  // 15..17
  has(error(grasp + "object = \"irb6/roll_link\"\n"),
      at + "18" + who +
          "cell 'world': no grasped object named 'irb6/roll_link' (objects with grasps: bar)");
  has(error(grasp + "object = \"bar\"\ngrasp = 1\n"),
      at + "19" + who + "'grasp' = 1 is outside 0..0: object 'bar' has 1 [[scene.object.grasp]]");
  has(error(grasp + "object = \"bar\"\ngrasp = -1\n"), at + "19" + who + "'grasp' = -1 is outside");
  has(error(grasp), at + "14" + who + "missing key 'object'");
  // The same line twice: the second wire's line.
  has(error(loop + "axis = 0\nline = 3\n[[scene.robot.drives.input]]\n" + grasp.substr(0, 17) +
            "axis = \"column\"\nline = 3\nobject = \"bar\"\n"),
      at + "23" + who + "'line' = 3: input line 3 of axis 'column' is wired twice (first at ");
  has(error(loop + "axis = 0\nline = 3\n[[scene.robot.drives.input]]\n" + grasp.substr(0, 17) +
            "axis = \"column\"\nline = 3\nobject = \"bar\"\n"),
      "s.toml:14)");
  // [scene.robot.drives] knows `input`, and `input` is a list of tables.
  const std::string drives =
      head.substr(0, head.rfind("[[scene.robot.dr")) + "[scene.robot.drives]\n";  // 14
  const auto drives_error = [&](const std::string& keys) -> std::string {
    try {
      (void)mrroc::emu::read_drive_wiring(dir.write("d.toml", drives + keys), world, {});
    } catch (const ConfigError& e) {
      std::printf("  %s\n", e.what());
      return e.what();
    }
    ADD_FAILURE() << "no ConfigError for\n" << keys;
    return {};
  };
  has(drives_error("inputs = []\n"),
      "d.toml:15: error: unknown key 'inputs' in [scene.robot.drives] (allowed: bus, nodes, "
      "counts_per_unit, current_limit, eds, input)");
  has(drives_error("input = 3\n"),
      "d.toml:15: error: robot 'irb6': 'input' must be [[scene.robot.drives.input]] tables");
  // And a good one: each source, by name and by index.
  const fs::path good =
      dir.write("good.toml", head + loop + "axis = 0\nline = 7\ninvert = true\n" +
                                 "[[scene.robot.drives.input]]\n" + grasp +
                                 "object = \"bar\"\ngrasp = 0\n[[scene.robot.drives.input]]\n" +
                                 presence.substr(0, 20) + "axis = \"wrist_roll\"\nline = 0\n" +
                                 "object = \"bar\"\nregion = [0.9, 1.1, -0.1, 0.1, 0, 2]\n");
  const std::vector<RobotDrives> wiring = mrroc::emu::read_drive_wiring(good, world, {});
  ASSERT_EQ(wiring.at(0).inputs.size(), 3U);
  const auto& in = wiring[0].inputs;
  EXPECT_EQ(in[0].source, mrroc::emu::InputSource::output);
  EXPECT_TRUE(in[0].invert);
  EXPECT_EQ(in[0].line, 7);
  EXPECT_EQ(in[1].grasp, 0);
  EXPECT_EQ(in[1].grasps, std::vector<std::size_t>{0});
  EXPECT_EQ(in[2].axis, 4U);
  EXPECT_EQ(in[2].body, world.body_id("bar"));
  EXPECT_EQ(in[2].where.line, 27);
  EXPECT_EQ(mrroc::emu::describe_input(world.robot(0), in[0]),
            "robot 'irb6' axis 'column' input 7: not output 0 of axis 'column'");
  EXPECT_EQ(mrroc::emu::describe_input(world.robot(0), in[1]),
            "robot 'irb6' axis 'column' input 0: grasp 0 of 'bar' engaged");
  EXPECT_EQ(mrroc::emu::describe_input(world.robot(0), in[2]),
            "robot 'irb6' axis 'wrist_roll' input 0: presence of 'bar' in x 0.90..1.10 y "
            "-0.10..0.10 z 0.00..2.00 m");
  // The bar (pos [1, 0, 1]) is in the region; nothing engaged; output 0 off (inverted: on).
  const std::vector<std::uint8_t> lines = inputs_of(wiring[0], world, {0, 0, 0, 0, 0});
  EXPECT_EQ(lines, (std::vector<std::uint8_t>{0x80, 0, 0, 0, 0x01}));
  // Wrong sizes: refused, untouched.
  std::vector<std::uint8_t> few(4, 0xA5);
  EXPECT_FALSE(mrroc::emu::evaluate_inputs(wiring[0], world, few, few));
  EXPECT_EQ(few[0], 0xA5);
}

// ---- conveyor-pick.toml's light barrier ----

TEST(EmuInputs, LightBarrierSeesThePartWhereTheBeltGeometryPutsIt) {
  const fs::path file = scene_file("conveyor-pick.toml");
  CellWorld world(file);
  const std::vector<RobotDrives> wiring = mrroc::emu::read_drive_wiring(file, world, {});
  const std::size_t irb6 = world.robot_index("irb6");
  const std::size_t belt = world.robot_index("conveyor");
  ASSERT_EQ(wiring[irb6].inputs.size(), 2U);
  EXPECT_EQ(mrroc::emu::describe_input(world.robot(irb6), wiring[irb6].inputs[0]),
            "robot 'irb6' axis 'column' input 0: presence of 'part' in x 0.35..0.45 y "
            "-0.75..-0.55 z 0.70..1.00 m");
  EXPECT_TRUE(wiring[belt].inputs.empty());
  // The barrier's x range 0.35 .. 0.45 m, as belt positions (part at x = s - 1.30 m).
  constexpr double kEnter = 0.35 + 1.30;
  constexpr double kLeave = 0.45 + 1.30;
  const int part = world.body_id("part");
  const std::vector<std::uint8_t> outputs(world.axis_count(irb6), 0);
  std::vector<std::uint8_t> inputs(world.axis_count(irb6), 0);
  std::array<double, 1> s{};
  ASSERT_TRUE(world.actuator_positions(belt, s));
  EXPECT_NEAR(world.body_pose(part).position[0], s[0] - 1.30, 1e-9);
  ASSERT_TRUE(mrroc::emu::evaluate_inputs(wiring[irb6], world, outputs, inputs));
  EXPECT_FALSE(bit(inputs[0], 0)) << "the part starts at s = " << s[0] << " m";
  // The belt forth to 1.90 m and back to 1.50 m, its targets on a trapezoidal profile (0.4 m/s,
  // 0.5 m/s^2: inside the belt's 0.5 m/s and 1.0 m/s^2) with their velocity as feed-forward; the
  // line evaluated after every step, without allocating.
  constexpr double kSpeed = 0.4;         // m/s
  constexpr double kAcceleration = 0.5;  // m/s^2
  const double dt = world.timestep();
  double target = s[0];
  double previous = s[0];
  double max_travel = 0.0;            // largest belt travel in one step [m]
  double max_speed = 0.0;             // of the belt [m/s]
  double max_acceleration = 0.0;      // of the belt, over 10 ms [m/s^2]
  std::vector<double> speeds;         // the belt's, per step [m/s]
  std::vector<double> on_at, off_at;  // belt positions where the line switched
  std::vector<double> z_on;           // the part's height while on [m]
  bool was_on = false;
  long allocations = 0;
  for (const double goal : {1.90, 1.50}) {
    const double direction = goal > target ? 1.0 : -1.0;
    double v = 0.0;  // the targets' speed [m/s]
    for (int step = 0; step < 20000 && (v > 0.0 || std::abs(s[0] - goal) > 1e-4); ++step) {
      const double left = std::abs(goal - target);
      v = std::min({v + kAcceleration * dt, kSpeed, std::sqrt(2.0 * kAcceleration * left)});
      if (v * dt >= left) {
        target = goal;
        v = 0.0;
      } else {
        target += direction * v * dt;
      }
      const std::array<double, 1> targets{target};
      const std::array<double, 1> feed_forward{direction * v};
      ASSERT_TRUE(world.set_targets(belt, targets));
      ASSERT_TRUE(world.set_velocity_feed_forward(belt, feed_forward));
      ASSERT_TRUE(world.step()) << world.fault_text();
      ASSERT_TRUE(world.actuator_positions(belt, s));
      g_heap.allocations = 0;
      g_heap.counting = true;
      const bool ok = mrroc::emu::evaluate_inputs(wiring[irb6], world, outputs, inputs);
      g_heap.counting = false;
      allocations += g_heap.allocations;
      ASSERT_TRUE(ok);
      max_travel = std::max(max_travel, std::abs(s[0] - previous));
      std::array<double, 1> speed{};
      ASSERT_TRUE(world.actuator_velocities(belt, speed));
      speeds.push_back(speed[0]);
      max_speed = std::max(max_speed, std::abs(speed[0]));
      if (speeds.size() > 10)
        max_acceleration = std::max(
            max_acceleration, std::abs(speeds.back() - speeds[speeds.size() - 11]) / (10 * dt));
      const bool on = bit(inputs[0], 0);
      EXPECT_EQ(inputs[0] & ~1U, 0U) << "only line 0 is wired to the physics";
      if (on && !was_on) on_at.push_back(s[0]);
      if (!on && was_on) off_at.push_back(s[0]);
      if (on) z_on.push_back(world.body_pose(part).position[2]);
      was_on = on;
      previous = s[0];
    }
    EXPECT_NEAR(s[0], goal, 1e-3) << "the belt arrived";
  }
  std::printf(
      "belt: largest acceleration %.3f m/s^2; largest travel per step %.3f mm (%.3f m/s); line 0 "
      "on at s = %.5f, %.5f m, "
      "off at s = %.5f, %.5f m; part height while on %.4f .. %.4f m; %ld allocations\n",
      max_acceleration, max_travel * 1e3, max_speed, on_at.empty() ? NAN : on_at[0],
      on_at.size() < 2 ? NAN : on_at[1], off_at.empty() ? NAN : off_at[0],
      off_at.size() < 2 ? NAN : off_at[1],
      z_on.empty() ? NAN : *std::min_element(z_on.begin(), z_on.end()),
      z_on.empty() ? NAN : *std::max_element(z_on.begin(), z_on.end()), allocations);
  EXPECT_GT(max_speed, 0.9 * kSpeed) << "the belt moved at its speed";
  EXPECT_LT(max_speed, 0.5) << "within the belt's velocity limit";
  EXPECT_LT(max_acceleration, 1.0) << "within the belt's acceleration limit";
  ASSERT_EQ(on_at.size(), 2U) << "in once on the way forth, once on the way back";
  ASSERT_EQ(off_at.size(), 2U);
  // Forth: on at the barrier's near edge, off past its far edge; back: the reverse. Each
  // within the belt's travel in the step that crossed it.
  EXPECT_GE(on_at[0], kEnter);
  EXPECT_LE(on_at[0], kEnter + max_travel);
  EXPECT_GT(off_at[0], kLeave);
  EXPECT_LE(off_at[0], kLeave + max_travel);
  EXPECT_LE(on_at[1], kLeave);
  EXPECT_GE(on_at[1], kLeave - max_travel);
  EXPECT_LT(off_at[1], kEnter);
  EXPECT_GE(off_at[1], kEnter - max_travel);
  EXPECT_FALSE(was_on) << "the part ends at s = 1.50 m, before the barrier";
  ASSERT_FALSE(z_on.empty());
  EXPECT_GT(*std::min_element(z_on.begin(), z_on.end()), 0.70);
  EXPECT_LT(*std::max_element(z_on.begin(), z_on.end()), 1.00);
  EXPECT_EQ(allocations, 0) << "evaluate_inputs allocated";
}

// ---- conveyor-pick.toml's loop-back wire through a real drive ----

TEST(EmuInputs, LoopBackFollowsTheDrivesOutputLine) {
  const fs::path file = scene_file("conveyor-pick.toml");
  const CellWorld world(file);
  const std::vector<RobotDrives> wiring = mrroc::emu::read_drive_wiring(file, world, {});
  const std::size_t irb6 = world.robot_index("irb6");
  const RobotDrives& w = wiring[irb6];
  EXPECT_EQ(mrroc::emu::describe_input(world.robot(irb6), w.inputs[1]),
            "robot 'irb6' axis 'column' input 1: output 0 of axis 'column'");
  // The column's drive, as mrroc-axis-emu makes it; the master sets its outputs by SDO.
  mrroc::can::DriveConfig config;
  config.node = static_cast<std::uint8_t>(w.nodes[0]);
  std::vector<can_frame> sent;
  mrroc::can::Cia402Drive drive(config, [&](const can_frame& f) { sent.push_back(f); });
  const std::size_t n = world.axis_count(irb6);
  std::vector<std::uint8_t> outputs(n, 0);
  std::vector<std::uint8_t> inputs(n, 0);
  std::array<double, 5> position{};
  ASSERT_TRUE(world.actuator_positions(irb6, position));
  const auto sample = [&] {
    return mrroc::can::AxisSample{position[0], 0.0, 0.0, false, inputs[0]};
  };
  drive.power_on(sample(), 0.0);
  const auto write = [&](std::uint8_t sub, std::uint32_t value) {
    co::SdoRequest request;
    request.write = true;
    request.index = co::od::kDigitalOutputs;
    request.subindex = sub;
    request.value = value;
    request.size = 4;
    drive.on_frame(co::encode_request(config.node, request), 0.0);
  };
  const auto cycle = [&] {
    outputs[0] = drive.output_lines();
    EXPECT_TRUE(mrroc::emu::evaluate_inputs(w, world, outputs, inputs));
    drive.update(sample(), 0.0);
    return (drive.digital_inputs() & co::kUserLineMask) >> co::kUserLineShift;
  };
  EXPECT_EQ(cycle(), 0U) << "outputs off at power-on";
  write(1, 1U << co::kUserLineShift);  // output 0 on, but not under the mask
  EXPECT_EQ(cycle(), 0U) << "masked";
  write(2, co::kUserLineMask);
  EXPECT_EQ(drive.output_lines(), 0x01);
  EXPECT_EQ(cycle(), 0x02U) << "input 1 follows output 0";
  write(1, 0x3EU << co::kUserLineShift);  // outputs 1..5 on, 0 off
  EXPECT_EQ(cycle(), 0U) << "only output 0 is wired";
  write(1, 0xFFU << co::kUserLineShift);
  EXPECT_EQ(cycle(), 0x02U);
  EXPECT_EQ(inputs, (std::vector<std::uint8_t>{0x02, 0, 0, 0, 0}));
}

// ---- Grasp wires and invert (two-irb6.toml's bar) ----

/// carry_bar's grip of robot k for the bar centre `centre` (as test_cell_world), as joints.
std::vector<double> grip_joints(const CellWorld& world, std::size_t k,
                                const Eigen::Vector3d& centre) {
  const double side = k == 0 ? 1.0 : -1.0;
  Eigen::Isometry3d grip = Eigen::Isometry3d::Identity();
  grip.linear().col(0) = Eigen::Vector3d(0, 0, -1);
  grip.linear().col(2) = Eigen::Vector3d(side, 0, 0);
  grip.linear().col(1) = grip.linear().col(2).cross(grip.linear().col(0));
  grip.translation() = centre - side * 0.2 * Eigen::Vector3d::UnitX();
  const Eigen::Isometry3d base = mrroc::kinematics::from_values(
      world.robot(k).base, mrroc::edp::ArmRepresentation::xyz_angle_axis);
  const mrroc::robots::irb6::JointPosition seed{0.0, -1.5, 0.0, 0.0, 0.0};
  static const mrroc::robots::irb6::Irb6Geometry nominal = mrroc::robots::irb6::kinematic_models(
      mrroc::load_robot_model(source_dir() / "robots" / "irb6"))[0];
  const auto q = mrroc::robots::irb6::inverse_kinematics(base.inverse() * grip, seed, nominal);
  return {q.begin(), q.end()};
}

TEST(EmuInputs, GraspWiresFollowTheGripsAndInvertTurnsThemOver) {
  // two-irb6.toml with wires into the left robot's drives (its model paths made absolute).
  std::string text = read_text(scene_file("two-irb6.toml"));
  const std::string model = "model = \"../../robots/irb6\"\n";
  const std::string absolute = "model = \"" + (source_dir() / "robots" / "irb6").string() + "\"\n";
  for (std::size_t at = text.find(model); at != std::string::npos; at = text.find(model))
    text.replace(at, model.size(), absolute);
  const std::string left_base =
      "base = [0.0, 0.0, 0.0, 0.0, 0.0, 0.0]  # x y z [m], rotation "
      "vector [rad]\n";
  const std::size_t at = text.find(left_base);
  ASSERT_NE(at, std::string::npos);
  text.insert(at + left_base.size(),
              "[[scene.robot.drives.input]]\naxis = \"column\"\nline = 0\nsource = \"grasp\"\n"
              "object = \"bar\"\n"
              "[[scene.robot.drives.input]]\naxis = \"column\"\nline = 1\nsource = \"grasp\"\n"
              "object = \"bar\"\ngrasp = 1\n"
              "[[scene.robot.drives.input]]\naxis = \"column\"\nline = 2\nsource = \"grasp\"\n"
              "object = \"bar\"\ngrasp = 0\ninvert = true\n"
              "[[scene.robot.drives.input]]\naxis = 1\nline = 7\nsource = \"output\"\n"
              "from_axis = \"column\"\nfrom_line = 3\n"
              "[[scene.robot.drives.input]]\naxis = 1\nline = 6\nsource = \"output\"\n"
              "from_axis = \"column\"\nfrom_line = 3\ninvert = true\n");
  const ScratchDir dir;
  const fs::path file = dir.write("two-irb6.toml", text);
  // The left flange powers on at its grip of the bar, 5 mm above where the bar lies; the right
  // robot at its default pose, far from its grip.
  mrroc::emu::Scene scene = mrroc::emu::load_scene(file);
  const Eigen::Vector3d centre(1.0, 0.0, 1.105);
  {
    const CellWorld probe(scene);
    scene.robots.at(0).initial_joint_positions = grip_joints(probe, 0, centre);
  }
  CellWorld world(scene);
  const std::vector<RobotDrives> wiring = mrroc::emu::read_drive_wiring(file, world, {});
  ASSERT_EQ(wiring.at(0).inputs.size(), 5U);
  EXPECT_TRUE(wiring.at(1).inputs.empty());
  EXPECT_EQ(wiring[0].inputs[0].grasps, (std::vector<std::size_t>{0, 1}));
  EXPECT_EQ(mrroc::emu::describe_input(world.robot(0), wiring[0].inputs[2]),
            "robot 'left' axis 'column' input 2: not grasp 0 of 'bar' engaged");
  std::vector<std::uint8_t> outputs(5, 0);
  // Open grips: line 0 (any) and 1 (the right grip) off, line 2 (not the left grip) on; output
  // 3 of the column off: axis 1's line 7 off, its inverted line 6 on.
  EXPECT_EQ(inputs_of(wiring[0], world, outputs), (std::vector<std::uint8_t>{0x04, 0x40, 0, 0, 0}));
  long allocations = 0;
  bool ok = true;
  for (int s = 0; s < 500 && ok; ++s) {
    ok = world.step();
    g_heap.allocations = 0;
    g_heap.counting = true;
    std::array<std::uint8_t, 5> lines{};
    (void)mrroc::emu::evaluate_inputs(wiring[0], world, outputs, lines);
    g_heap.counting = false;
    allocations += g_heap.allocations;
  }
  ASSERT_TRUE(ok) << world.fault_text();
  EXPECT_EQ(allocations, 0);
  ASSERT_TRUE(world.grasp_engaged(0)) << "the left grip closed";
  ASSERT_FALSE(world.grasp_engaged(1)) << "the right grip is far away";
  std::printf("left grip engaged at t = %.3f s; bar at z = %.4f m\n", world.grasp_engaged_at(0),
              world.body_pose("bar").position[2]);
  EXPECT_GT(world.body_pose("bar").position[2], 1.10) << "held off the table";
  outputs[0] = 0x08;  // the column's output 3 on
  EXPECT_EQ(inputs_of(wiring[0], world, outputs), (std::vector<std::uint8_t>{0x01, 0x80, 0, 0, 0}));
  outputs[0] = 0xF7;  // every output but 3
  EXPECT_EQ(inputs_of(wiring[0], world, outputs), (std::vector<std::uint8_t>{0x01, 0x40, 0, 0, 0}));
  // reset() opens the grips again.
  world.reset();
  EXPECT_EQ(inputs_of(wiring[0], world, outputs), (std::vector<std::uint8_t>{0x04, 0x40, 0, 0, 0}));
}

}  // namespace
