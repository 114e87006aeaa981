/// @file
/// The axis emulator's raw sensor devices (emu/sensors.hpp) and the scene's contact keys
/// (emu/scene.hpp): the wrist strain gauges on the IRb-6's probe (its weight, pressing onto the
/// table), the range finders, the conveyor's encoder and the emulated camera (region, latency,
/// noise), publication on LCM (memq://) at the devices' rates, and the configuration errors.

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <new>
#include <numbers>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <mujoco/mujoco.h>
#include <lcm/lcm-cpp.hpp>

#include "cell_world.hpp"
#include "mrroc/comm/auth.hpp"
#include "mrroc/comm/codec.hpp"
#include "mrroc/core/error.hpp"
#include "mrroc/kinematics/irb6.hpp"
#include "mrroc/robot/robot_model.hpp"
#include "scene.hpp"
#include "sensors.hpp"

#ifndef MRROC_SOURCE_DIR
#error "MRROC_SOURCE_DIR must be defined (absolute path of the source tree)"
#endif

#include "heap_counter.hpp"

namespace {

namespace fs = std::filesystem;
namespace irb6 = mrroc::robots::irb6;
using mrroc::ConfigError;
using mrroc::emu::CellWorld;
using mrroc::emu::FramePose;
using mrroc::emu::RawSamplePublisher;
using mrroc::emu::Scene;
using mrroc::emu::SensorDevices;

constexpr double kPi = std::numbers::pi;
constexpr double kGravity = 9.81;
constexpr double kProbeMass = 0.5;      // kg (sensing.toml)
constexpr double kProbeRadius = 0.02;   // m
constexpr double kProbeReach = 0.15;    // m, sphere centre from the flange along its z axis
constexpr double kTableTop = 0.40;      // m
constexpr double kTouchX = 0.75;        // m
constexpr double kStiffness = 20000.0;  // N/m
constexpr std::int64_t kEpochUtime = 1'700'000'000'000'000;  // the tests' wall clock at t = 0

fs::path scene_file(const char* name) {
  return fs::path(MRROC_SOURCE_DIR) / "configs" / "scenes" / name;
}

std::int64_t wall_utime(const CellWorld& world) {
  return kEpochUtime + std::llround(world.time() * 1e6);
}

/// The IRb-6's kinematic model 0 (robots/irb6/parameters.toml).
irb6::Irb6Geometry irb6_nominal() {
  static const irb6::Irb6Geometry geometry =
      irb6::kinematic_models(
          mrroc::load_robot_model(fs::path(MRROC_SOURCE_DIR) / "robots" / "irb6"))
          .at(irb6::kNominalModel);
  return geometry;
}

/// Joints that put the probe's lowest point `height` above the table top at (kTouchX, 0), the
/// tool pointing straight down (negative: pressed into the table).
irb6::JointPosition probe_pose(double height) {
  Eigen::Isometry3d flange = Eigen::Isometry3d::Identity();
  flange.linear() = Eigen::AngleAxisd(kPi, Eigen::Vector3d::UnitY()).toRotationMatrix();
  flange.translation() =
      Eigen::Vector3d(kTouchX, 0.0, kTableTop + height + kProbeRadius + kProbeReach);
  return irb6::inverse_kinematics(flange, irb6::kSynchroJointPositions, irb6_nominal());
}

/// The sensing scene with the IRb-6 powered on at `q`.
Scene sensing_scene(const irb6::JointPosition& q) {
  Scene scene = mrroc::emu::load_scene(scene_file("sensing.toml"));
  scene.robots.at(0).initial_joint_positions = std::vector<double>(q.begin(), q.end());
  return scene;
}

void run(CellWorld& world, SensorDevices* sensors, double seconds) {
  const long steps = std::lround(seconds / world.timestep());
  for (long i = 0; i < steps; ++i) {
    ASSERT_TRUE(world.step()) << world.fault_text();
    if (sensors != nullptr) (void)sensors->update(world, wall_utime(world));
  }
}

/// Penetration of the probe into the table [m] (0 without contact).
double probe_penetration(const CellWorld& world) {
  const mjModel* m = world.model();
  const mjData* d = world.data();
  const int probe = mj_name2id(m, mjOBJ_GEOM, "probe");
  const int table = mj_name2id(m, mjOBJ_GEOM, "table");
  double depth = 0.0;
  for (int c = 0; c < d->ncon; ++c) {
    const mjContact& con = d->contact[c];
    if ((con.geom1 == probe && con.geom2 == table) || (con.geom1 == table && con.geom2 == probe))
      depth = std::max(depth, -con.dist);
  }
  return depth;
}

/// The wrench in volts back to N and N m with the default gauge matrix and sensing.toml's offset.
std::array<double, 6> calibrated(const SensorDevices& sensors, std::size_t i) {
  const mrroc::emu::SensorConfig& c = sensors.config(i);
  Eigen::Matrix<double, 6, 6> g;
  Eigen::Matrix<double, 6, 1> v;
  for (int r = 0; r < 6; ++r) {
    for (int k = 0; k < 6; ++k) g(r, k) = c.gauge_matrix[static_cast<std::size_t>(6 * r + k)];
    v(r) = sensors.sample(i).values[static_cast<std::size_t>(r)] -
           c.offset[static_cast<std::size_t>(r)];
  }
  const Eigen::Matrix<double, 6, 1> w = g.inverse() * v;
  return {w(0), w(1), w(2), w(3), w(4), w(5)};
}

/// A scratch folder of its own (mkdtemp), removed at the end of the test.
class ScratchDir {
 public:
  ScratchDir() {
    std::string pattern = (fs::temp_directory_path() / "mrroc_sensors_XXXXXX").string();
    if (::mkdtemp(pattern.data()) == nullptr) throw std::runtime_error("mkdtemp failed");
    path_ = pattern;
  }
  ~ScratchDir() { fs::remove_all(path_); }
  ScratchDir(const ScratchDir&) = delete;
  ScratchDir& operator=(const ScratchDir&) = delete;
  fs::path write(const std::string& name, const std::string& text) const {
    const fs::path file = path_ / name;
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

// ---- The probe and the wrist force/torque sensor ----

TEST(EmuSensors, ProbeHangingAboveTheTableWeighsItsMassInTheSensorFrame) {
  const irb6::JointPosition q = probe_pose(0.01);
  std::printf("  probe 1 cm above the table: q = (%.4f, %.4f, %.4f, %.4f, %.4f) rad\n", q[0], q[1],
              q[2], q[3], q[4]);
  CellWorld world(sensing_scene(q));
  ASSERT_FALSE(world.robot(0).coupled);
  SensorDevices sensors(scene_file("sensing.toml"), world);
  ASSERT_EQ(sensors.size(), 3U);
  for (std::size_t i = 0; i < sensors.size(); ++i)
    std::printf("  %s\n", sensors.describe(i).c_str());
  run(world, &sensors, 0.5);

  const mrroc::emu::FramePose probe = world.body_pose("probe");
  std::printf("  probe centre at (%.4f, %.4f, %.4f) m\n", probe.position[0], probe.position[1],
              probe.position[2]);
  EXPECT_NEAR(probe.position[0], kTouchX, 1e-4);
  EXPECT_NEAR(probe.position[2], kTableTop + 0.01 + kProbeRadius, 1e-4);
  EXPECT_EQ(probe_penetration(world), 0.0);

  // The tool points down: the sensor frame's z axis is the world's -z, the weight is +z.
  const std::size_t wrist = sensors.index("irb6_wrist");
  const std::array<double, 6> w = sensors.wrench(wrist);
  const std::array<double, 6> expected = {0.0, 0.0, kProbeMass * kGravity, 0.0, 0.0, 0.0};
  for (std::size_t k = 0; k < 6; ++k) EXPECT_NEAR(w[k], expected[k], 1e-3) << "component " << k;
  // Volts: G w + offset + noise (0.0002 V): calibrated back within 5 sigma of the noise.
  const std::array<double, 6> back = calibrated(sensors, wrist);
  for (std::size_t k = 0; k < 6; ++k) EXPECT_NEAR(back[k], w[k], 0.15) << "component " << k;
  EXPECT_EQ(sensors.sample(wrist).names[2], "g2");
  EXPECT_EQ(sensors.sample(wrist).units[2], "V");

  // Sensor frame = flange site.
  const mrroc::emu::FramePose frame = sensors.sensor_pose(world, wrist);
  const mrroc::emu::FramePose flange = world.site_pose("irb6/flange");
  for (std::size_t k = 0; k < 3; ++k) EXPECT_NEAR(frame.position[k], flange.position[k], 1e-9);
  EXPECT_NEAR(std::abs(frame.quaternion[0] * flange.quaternion[0] +
                       frame.quaternion[1] * flange.quaternion[1] +
                       frame.quaternion[2] * flange.quaternion[2] +
                       frame.quaternion[3] * flange.quaternion[3]),
              1.0, 1e-9);

  // Range finders: the beside-the-probe one sees the table 0.18 m below the flange plane, the
  // table's own sees the probe 1 cm above it.
  const std::size_t range = sensors.index("irb6_range");
  const std::size_t table_ir = sensors.index("table_ir");
  EXPECT_TRUE(sensors.sample(range).valid);
  EXPECT_NEAR(sensors.sample(range).values[0], flange.position[2] - kTableTop, 1e-3);
  EXPECT_NEAR(sensors.sample(range).values[0], 0.18, 1e-3);
  EXPECT_TRUE(sensors.sample(table_ir).valid);
  EXPECT_NEAR(sensors.sample(table_ir).values[0], 0.01, 1e-3);
  std::printf("  irb6_range %.5f m, table_ir %.5f m\n", sensors.sample(range).values[0],
              sensors.sample(table_ir).values[0]);
}

TEST(EmuSensors, PressingTheProbeIntoTheTableGrowsTheForceAtTheSpringsStiffness) {
  CellWorld world(sensing_scene(probe_pose(0.01)));
  SensorDevices sensors(scene_file("sensing.toml"), world);
  const std::size_t wrist = sensors.index("irb6_wrist");
  run(world, &sensors, 0.3);
  const double weight = kProbeMass * kGravity;
  double previous = 0.0;
  for (const double commanded : {0.0005, 0.001, 0.002, 0.003, 0.005}) {
    const irb6::JointPosition q = probe_pose(-commanded);
    ASSERT_TRUE(world.set_targets(0, q));
    run(world, &sensors, 1.0);
    const std::array<double, 6> w = sensors.wrench(wrist);
    const double normal = weight - w[2];  // the table pushes the probe back along the tool: -z
    const double penetration = probe_penetration(world);
    std::printf(
        "  commanded %.1f mm: penetration %.4f mm, normal force %.3f N: %.3f N/mm of "
        "penetration, %.3f N/mm of command; fx %.4f fy %.4f tx %.5f ty %.5f tz %.5f\n",
        commanded * 1e3, penetration * 1e3, normal, normal / penetration * 1e-3,
        normal / commanded * 1e-3, w[0], w[1], w[3], w[4], w[5]);
    // The contact spring exactly; against the command, in series with the arm's servo
    // stiffness (about 270 N/mm along the tool here): 18.6 N/mm.
    EXPECT_NEAR(normal / penetration, kStiffness, 0.001 * kStiffness);
    EXPECT_NEAR(normal / commanded, kStiffness, 0.10 * kStiffness);
    EXPECT_GT(normal, previous);
    previous = normal;
    // A force along the tool axis: hardly any tangential force (friction against the arm's
    // slightly tilted compliance), no torque about the flange but its moment.
    EXPECT_NEAR(w[0], 0.0, 0.002 * normal);
    EXPECT_NEAR(w[1], 0.0, 0.002 * normal);
    EXPECT_NEAR(w[3], 0.0, 1e-6);
    EXPECT_NEAR(w[4], -w[0] * (kProbeReach + kProbeRadius), 1e-3 * normal);
    EXPECT_NEAR(w[5], 0.0, 1e-6);
  }
}

TEST(EmuSensors, SamplingTheGaugesLeavesThePhysicsAsItIs) {
  // Two worlds pressing the probe into the table, one sampled at 500 Hz (which solves the
  // constraint forces between steps), one not: the same states (to round-off: the extra solve
  // changes the solver's warm start).
  CellWorld sampled(sensing_scene(probe_pose(0.01)));
  CellWorld plain(sensing_scene(probe_pose(0.01)));
  SensorDevices sensors(scene_file("sensing.toml"), sampled);
  ASSERT_TRUE(sampled.set_targets(0, probe_pose(-0.002)));
  ASSERT_TRUE(plain.set_targets(0, probe_pose(-0.002)));
  run(sampled, &sensors, 0.5);
  run(plain, nullptr, 0.5);
  const mjModel* m = sampled.model();
  for (int i = 0; i < m->nq; ++i)
    EXPECT_NEAR(sampled.data()->qpos[i], plain.data()->qpos[i], 1e-12);
  for (int i = 0; i < m->nv; ++i)
    EXPECT_NEAR(sampled.data()->qvel[i], plain.data()->qvel[i], 1e-12);
  EXPECT_GT(probe_penetration(plain), 0.001);
}

// ---- Conveyor: encoder and camera ----

TEST(EmuSensors, EncoderIsTheBeltsActuatorPosition) {
  CellWorld world(scene_file("conveyor-pick.toml"));
  SensorDevices sensors(scene_file("conveyor-pick.toml"), world);
  const std::size_t encoder = sensors.index("belt_encoder");
  const std::size_t conveyor = world.robot_index("conveyor");
  std::printf("  %s\n", sensors.describe(encoder).c_str());
  std::vector<double> target(1, 0.05);
  std::vector<double> belt(1);
  int samples = 0;
  for (int i = 0; i < 2000; ++i) {
    target[0] = std::min(1.0, target[0] + 0.0005);  // 0.5 m/s
    ASSERT_TRUE(world.set_targets(conveyor, target));
    ASSERT_TRUE(world.step());
    for (const std::size_t device : sensors.update(world, wall_utime(world))) {
      if (device != encoder) continue;
      ASSERT_TRUE(world.actuator_positions(conveyor, belt));
      EXPECT_EQ(sensors.sample(encoder).values[0], belt[0]);
      EXPECT_EQ(sensors.sample(encoder).sample_no, samples);
      EXPECT_EQ(sensors.sample(encoder).sample_utime, wall_utime(world));
      ++samples;
    }
  }
  EXPECT_EQ(samples, 1000);  // 500 Hz for 2 s
  EXPECT_EQ(sensors.sample(encoder).units[0], "m");
  EXPECT_GT(belt[0], 0.9);
}

TEST(EmuSensors, CameraSeesThePartOnlyInItsRegionLateByItsLatencyWithItsNoise) {
  CellWorld world(scene_file("conveyor-pick.toml"));
  SensorDevices sensors(scene_file("conveyor-pick.toml"), world);
  const std::size_t camera = sensors.index("cell_camera");
  const mrroc::emu::SensorConfig& config = sensors.config(camera);
  std::printf("  %s\n", sensors.describe(camera).c_str());
  const std::size_t conveyor = world.robot_index("conveyor");
  const int part = world.body_id("part");
  ASSERT_GT(part, 0);

  // The part's true position at every step, by time.
  std::map<std::int64_t, std::array<double, 3>> truth;
  const auto inside = [&](const std::array<double, 3>& x) {
    const auto& r = config.region;
    return x[0] >= r[0] && x[0] <= r[1] && x[1] >= r[2] && x[1] <= r[3] && x[2] >= r[4] &&
           x[2] <= r[5];
  };
  std::vector<double> target(1, 0.05);
  int published = 0, visible = 0, entered_at = -1, left_at = -1;
  std::vector<double> errors;
  std::int64_t last_no = -1;
  // 0.3 m/s from s = 0.05 to 2.0 (through the region x 0.15..0.55, s 1.45..1.85), then hold at
  // s = 1.65 (inside) for the noise statistics.
  const auto advance = [&](int steps, bool moving, double hold) {
    for (int i = 0; i < steps; ++i) {
      target[0] = moving ? std::min(1.99, target[0] + 0.0003) : hold;
      ASSERT_TRUE(world.set_targets(conveyor, target));
      ASSERT_TRUE(world.step());
      const std::int64_t now = wall_utime(world);
      const mrroc::emu::FramePose p = world.body_pose(part);
      truth[now] = p.position;
      for (const std::size_t device : sensors.update(world, now)) {
        if (device != camera) continue;
        const mrroc::vsp::RawSample& s = sensors.sample(camera);
        ++published;
        EXPECT_EQ(s.sample_no, last_no + 1);
        last_no = s.sample_no;
        // Published 50 ms after it was taken; taken at a step.
        EXPECT_EQ(now - s.sample_utime, 50000);
        const auto taken = truth.find(s.sample_utime);
        ASSERT_NE(taken, truth.end()) << "sample time " << s.sample_utime << " is no step";
        EXPECT_EQ(s.valid, inside(taken->second)) << "x = " << taken->second[0];
        if (!s.valid) continue;
        ++visible;
        if (entered_at < 0) entered_at = published;
        left_at = published;
        for (std::size_t k = 0; k < 3; ++k) errors.push_back(s.values[k] - taken->second[k]);
        EXPECT_NEAR(s.values[3], 1.0, 1e-9);  // the part does not turn
      }
    }
  };
  advance(6500, true, 0.0);
  const int passing = visible;
  std::printf("  moving: %d samples, %d with the part seen\n", published, passing);
  // 0.40 m of region at 0.3 m/s: 1.33 s, 40 samples at 30 Hz.
  EXPECT_NEAR(passing, 40, 2);
  errors.clear();
  advance(2000, false, 1.65);  // settle
  errors.clear();
  advance(15000, false, 1.65);
  double sum = 0.0, squares = 0.0;
  for (const double e : errors) {
    sum += e;
    squares += e * e;
  }
  const double n = static_cast<double>(errors.size());
  const double mean = sum / n;
  const double std_dev = std::sqrt(squares / n - mean * mean);
  std::printf("  holding: %zu position values, mean error %.5f m, std %.5f m (noise %.4f m)\n",
              errors.size(), mean, std_dev, config.noise);
  EXPECT_NEAR(std_dev, config.noise, 0.2 * config.noise);
  EXPECT_NEAR(mean, 0.0, 0.2 * config.noise);
  // 30 Hz in simulated time.
  EXPECT_NEAR(published, (6500 + 2000 + 15000) * 0.001 * 30.0, 2.0);
}

TEST(EmuSensors, CameraLatencyShowsAMovingPartWhereItWas) {
  CellWorld world(scene_file("conveyor-pick.toml"));
  SensorDevices sensors(scene_file("conveyor-pick.toml"), world);
  const std::size_t camera = sensors.index("cell_camera");
  const std::size_t conveyor = world.robot_index("conveyor");
  std::vector<double> target(1, 1.50);
  // Start inside the region, then move at 0.2 m/s: the published x lags by 0.2 * 0.05 = 1 cm.
  ASSERT_TRUE(world.set_targets(conveyor, target));
  run(world, nullptr, 3.0);
  int checked = 0;
  for (int i = 0; i < 1500; ++i) {
    target[0] += 0.0002;
    ASSERT_TRUE(world.set_targets(conveyor, target));
    ASSERT_TRUE(world.step());
    for (const std::size_t device : sensors.update(world, wall_utime(world))) {
      if (device != camera || i < 500 || !sensors.sample(camera).valid) continue;
      const double x_now = world.body_pose("part").position[0];
      const double lag = x_now - sensors.sample(camera).values[0];
      EXPECT_NEAR(lag, 0.2 * 0.050, 0.008) << "at step " << i;  // 4 sigma of the noise
      ++checked;
    }
  }
  EXPECT_GT(checked, 20);
}

TEST(EmuSensors, ConveyorPickIrb6ReachesOverThePartWhereTheCameraSeesIt) {
  CellWorld world(scene_file("conveyor-pick.toml"));
  SensorDevices sensors(scene_file("conveyor-pick.toml"), world);
  const mrroc::emu::SensorConfig& camera = sensors.config(sensors.index("cell_camera"));
  const std::array<double, 6>& base = world.robot(world.robot_index("irb6")).base;
  const double part_y = world.body_pose("part").position[1];
  const double part_z = world.body_pose("part").position[2];
  EXPECT_GT(part_y, camera.region[2]);
  EXPECT_LT(part_y, camera.region[3]);
  EXPECT_GT(part_z, camera.region[4]);
  EXPECT_LT(part_z, camera.region[5]);
  // A 0.25 m gripper pointing down, its tip 5 cm above the part's top and at its centre, over
  // the whole region along the belt.
  for (const double x :
       {camera.region[0], 0.5 * (camera.region[0] + camera.region[1]), camera.region[1]}) {
    for (const double tip : {part_z + 0.03 + 0.05, part_z}) {
      Eigen::Isometry3d flange = Eigen::Isometry3d::Identity();
      flange.linear() = (Eigen::AngleAxisd(std::atan2(part_y, x), Eigen::Vector3d::UnitZ()) *
                         Eigen::AngleAxisd(kPi, Eigen::Vector3d::UnitY()))
                            .toRotationMatrix();
      flange.translation() = Eigen::Vector3d(x - base[0], part_y - base[1], tip + 0.25 - base[2]);
      irb6::JointPosition q{};
      EXPECT_NO_THROW(
          q = irb6::inverse_kinematics(flange, irb6::kSynchroJointPositions, irb6_nominal()))
          << "x " << x << " tip " << tip;
      std::printf("  gripper tip at (%.2f, %.2f, %.3f): q = (%.3f, %.3f, %.3f, %.3f, %.3f)\n", x,
                  part_y, tip, q[0], q[1], q[2], q[3], q[4]);
    }
  }
}

// ---- Publication ----

struct Received {
  std::map<std::string, std::vector<mrroc_lcm::raw_sensor_t>> by_channel;
  // A plain function with the object as context: LCM's pointer-to-member dispatch trips
  // UndefinedBehaviorSanitizer (as in comm/request_reply.hpp).
  static void on(const lcm::ReceiveBuffer*, const std::string& channel,
                 const mrroc_lcm::raw_sensor_t* message, Received* self) {
    self->by_channel[channel].push_back(*message);
  }
};

namespace {
/// Steps the world `steps` times, publishing the samples that are due after each step and
/// delivering them; returns the allocations made while sampling and publishing.
long publish_steps(int steps, lcm::LCM& lcm, CellWorld& world, SensorDevices& sensors,
                   RawSamplePublisher& publisher) {
  long allocations = 0;
  for (int i = 0; i < steps; ++i) {
    EXPECT_TRUE(world.step());
    const std::int64_t now = wall_utime(world);
    g_heap.allocations = 0;
    g_heap.counting = true;
    for (const std::size_t device : sensors.update(world, now))
      (void)publisher.publish(device, sensors.sample(device), now);
    g_heap.counting = false;
    allocations += g_heap.allocations;
    while (lcm.handleTimeout(0) > 0) {
    }
  }
  return allocations;
}
}  // namespace

TEST(EmuSensors, PublishedSamplesCountAtTheirRatesWithoutAllocating) {
  lcm::LCM lcm("memq://");
  ASSERT_TRUE(lcm.good());
  Received received;
  lcm.subscribeFunction<mrroc_lcm::raw_sensor_t, Received*>("mrroc/raw/.*", &Received::on,
                                                            &received);
  CellWorld world(sensing_scene(probe_pose(0.01)));
  SensorDevices sensors(scene_file("sensing.toml"), world);
  RawSamplePublisher publisher(lcm, sensors, "test#1");
  EXPECT_EQ(publish_steps(1000, lcm, world, sensors, publisher), 0);
  EXPECT_EQ(publisher.failed(), 0U);
  const std::map<std::string, int> rates = {
      {"mrroc/raw/irb6_wrist", 500}, {"mrroc/raw/irb6_range", 50}, {"mrroc/raw/table_ir", 50}};
  for (const auto& [channel, rate] : rates) {
    const auto& messages = received.by_channel[channel];
    EXPECT_EQ(static_cast<int>(messages.size()), rate) << channel;  // in 1 s of simulated time
    for (std::size_t k = 0; k < messages.size(); ++k) {
      const mrroc::vsp::RawSample s = mrroc::comm::decode(messages[k]);
      EXPECT_EQ(s.sample_no, static_cast<std::int64_t>(k)) << channel;
      EXPECT_EQ(messages[k].header.sender, "test#1");
      EXPECT_EQ(int{messages[k].header.kind}, int{mrroc_lcm::header_t::BROADCAST});
      EXPECT_EQ(messages[k].header.utime, s.sample_utime);
      // Sample k was taken at (k + 1) periods.
      EXPECT_EQ(s.sample_utime, kEpochUtime + (static_cast<std::int64_t>(k) + 1) * 1000000 / rate)
          << channel;
    }
    ASSERT_FALSE(messages.empty());
    EXPECT_EQ("mrroc/raw/" + messages.back().device, channel);
  }
  const auto& wrist = received.by_channel["mrroc/raw/irb6_wrist"];
  ASSERT_FALSE(wrist.empty());
  EXPECT_EQ(wrist.back().n, 6);
  EXPECT_EQ(wrist.back().names[5], "g5");
  EXPECT_EQ(wrist.back().units[0], "V");
}

// With the set's key every sample is signed for its own channel (as comm::sign does), still
// without allocating in mrroc's code: a VSP with the key accepts each once, on its channel only.
TEST(EmuSensors, SignedSamplesVerifyOnTheirChannelWithoutAllocating) {
  lcm::LCM lcm("memq://");
  ASSERT_TRUE(lcm.good());
  Received received;
  lcm.subscribeFunction<mrroc_lcm::raw_sensor_t, Received*>("mrroc/raw/.*", &Received::on,
                                                            &received);
  const std::vector<std::uint8_t> key(32, 9);
  mrroc::comm::Authenticator receiver(key);  // started before anything is signed
  mrroc::comm::Authenticator signer(key);
  CellWorld world(sensing_scene(probe_pose(0.01)));
  SensorDevices sensors(scene_file("sensing.toml"), world);
  RawSamplePublisher publisher(lcm, sensors, "test#1", &signer);
  EXPECT_EQ(publish_steps(200, lcm, world, sensors, publisher), 0);
  EXPECT_EQ(publisher.failed(), 0U);
  std::size_t checked = 0;
  for (const auto& [channel, messages] : received.by_channel) {
    for (const auto& m : messages) {
      EXPECT_EQ(m.header.auth_len, 32);
      EXPECT_EQ(mrroc::comm::verify(receiver, m, "mrroc/raw/elsewhere"),
                mrroc::comm::Authenticator::Verdict::bad_tag);
      EXPECT_EQ(mrroc::comm::verify(receiver, m, channel), mrroc::comm::Authenticator::Verdict::ok)
          << channel;
      EXPECT_EQ(mrroc::comm::verify(receiver, m, channel),
                mrroc::comm::Authenticator::Verdict::replayed);
      ++checked;
    }
  }
  EXPECT_GT(checked, 100U);
}

// ---- Scene contact keys ----

TEST(EmuSensors, ObjectContactKeysReachTheModel) {
  const CellWorld world(scene_file("sensing.toml"));
  const mjModel* m = world.model();
  const int probe = mj_name2id(m, mjOBJ_GEOM, "probe");
  const int table = mj_name2id(m, mjOBJ_GEOM, "table");
  ASSERT_GE(probe, 0);
  ASSERT_GE(table, 0);
  EXPECT_EQ(m->geom_priority[probe], 1);
  EXPECT_EQ(m->geom_priority[table], 0);
  EXPECT_DOUBLE_EQ(m->geom_friction[3 * probe], 0.2);
  EXPECT_EQ(m->geom_contype[table], 1);
  EXPECT_EQ(m->geom_solimp[mjNIMP * probe], m->geom_solimp[mjNIMP * probe + 1]);
  EXPECT_GT(m->geom_solimp[mjNIMP * probe], 0.0);
  EXPECT_LT(m->geom_solimp[mjNIMP * probe], 0.1);
  // The stiffness form is converted (per unit mass, so much smaller than 20000) and shown.
  EXPECT_LT(m->geom_solref[mjNREF * probe], 0.0);
  EXPECT_GT(m->geom_solref[mjNREF * probe], -20000.0);
  EXPECT_NE(world.composed_xml().find("solref: 20000 N/m, 400 N s/m"), std::string::npos);

  ScratchDir dir;
  const std::string head =
      "[scene]\n[[scene.robot]]\nname = \"irb6\"\nmodel = \"" MRROC_SOURCE_DIR "/robots/irb6\"\n";
  const fs::path ghost = dir.write("ghost.toml", head +
                                                     "[[scene.object]]\nname = \"ghost\"\ntype = "
                                                     "\"sphere\"\nsize = [0.1]\npos = [1, 0, "
                                                     "0.1]\nmass = 1\ncontact = false\n");
  const CellWorld ghost_world(ghost);
  const int g = mj_name2id(ghost_world.model(), mjOBJ_GEOM, "ghost");
  EXPECT_EQ(ghost_world.model()->geom_contype[g], 0);
  EXPECT_EQ(ghost_world.model()->geom_conaffinity[g], 0);

  const auto object = [&](const std::string& keys) {
    return dir.write("object.toml", head +
                                        "[[scene.object]]\nname = \"thing\"\ntype = \"sphere\"\n"
                                        "size = [0.1]\npos = [1, 0, 0.1]\nmass = 1\n" +
                                        keys);
  };
  // Line 11 is the first key after `mass`.
  EXPECT_NE(config_error([&] {
              (void)mrroc::emu::load_scene(object("solref = [0.02, -1]\n"));
            }).find("object.toml:11: error: 'solref' = [0.02, -1] mixes MuJoCo's two forms"),
            std::string::npos);
  EXPECT_NE(config_error([&] {
              (void)mrroc::emu::load_scene(object("friction = [0.0]\n"));
            }).find("object.toml:11: error: 'friction' sliding coefficient must be > 0"),
            std::string::npos);
  EXPECT_NE(config_error([&] {
              (void)mrroc::emu::load_scene(object("friction = [1, 0.1, 0.1, 0.1]\n"));
            }).find("object.toml:11: error: 'friction' must be 1 to 3"),
            std::string::npos);
  EXPECT_NE(config_error([&] {
              (void)mrroc::emu::load_scene(object("contact = false\nsolref = [-1000, -10]\n"));
            })
                .find("object.toml:12: error: 'solref' has no effect on object 'thing' with "
                      "contact = false"),
            std::string::npos);
  EXPECT_NE(config_error([&] {
              (void)CellWorld(object("attach = \"world\"\nsolref = [-1000, -10]\n"));
            }).find("object.toml:12: error: object 'thing' does not move"),
            std::string::npos);
  // A free ball on a spring contact (1000 N/mm, 10 N s/m) settles on the floor at m g / k.
  CellWorld ball(object("solref = [-1000, -10]\nfriction = [0.5]\n"));
  run(ball, nullptr, 3.0);
  const double sunk = 0.1 - ball.body_pose("thing").position[2];
  std::printf("  1 kg ball on a 1000 N/m contact: sunk %.4f mm (m g / k = %.4f mm)\n", sunk * 1e3,
              kGravity / 1000.0 * 1e3);
  EXPECT_NEAR(sunk, kGravity / 1000.0, 1e-3 * kGravity / 1000.0);
}

// ---- Device configuration errors ----

TEST(EmuSensors, ConfigErrorsNameTheFileLineAndDevice) {
  ScratchDir dir;
  const std::string head =
      "[scene]\n"          // 1
      "[[scene.robot]]\n"  // 2
      "name = \"irb6\"\n"  // 3
      "model = \"" MRROC_SOURCE_DIR
      "/robots/irb6\"\n"    // 4
      "[[scene.sensor]]\n"  // 5
      "name = \"s\"\n";     // 6
  CellWorld world(dir.write("world.toml",
                            "[scene]\n[[scene.robot]]\nname = \"irb6\"\nmodel = \"" MRROC_SOURCE_DIR
                            "/robots/irb6\"\n"));
  const auto error = [&](const std::string& keys) {
    const fs::path file = dir.write("s.toml", head + keys);
    return config_error([&] { (void)SensorDevices(file, world); });
  };
  const auto has = [](const std::string& text, const std::string& part) {
    EXPECT_NE(text.find(part), std::string::npos) << text << "\n  lacks: " << part;
  };
  has(error("type = \"range\"\nbody = \"irb6/roll_link\"\nbeam = 2\n"),
      "s.toml:9: error: sensor 's': unknown key 'beam' in [[scene.sensor]] of type range");
  has(error("type = \"range\"\nbody = \"irb6/wrist\"\n"),
      "s.toml:8: error: sensor 's': body 'irb6/wrist' is not in the scene");
  has(error("type = \"range\"\n"), "s.toml:5: error: sensor 's': missing key 'body'");
  has(error("type = \"sonar\"\n"),
      "s.toml:7: error: sensor 's': 'type' = \"sonar\" is not strain_gauges");
  has(error("type = \"strain_gauges\"\nbody = \"irb6/roll_link\"\ngauge_matrix = [[1, 0]]\n"),
      "s.toml:9: error: sensor 's': 'gauge_matrix' must be 6 rows of 6 numbers");
  has(error("type = \"strain_gauges\"\nbody = \"irb6/roll_link\"\ngauge_matrix = [[1, 0, 0, 0, "
            "0, 0], [0, 1, 0, 0, 0, 0], [0, 0, 1, 0, 0, 0], [0, 0, 0, 1, 0, 0], [0, 0, 0, 0, 1, "
            "0], [1, 0, 0, 0, 0, 0]]\n"),
      "s.toml:9: error: sensor 's': 'gauge_matrix' is singular");
  has(error("type = \"strain_gauges\"\nbody = \"irb6/roll_link\"\ngauge_matrix = [[1, 0, 0, 0, "
            "0, 0], [0, 1, 0, 0, 0, 0], [0, 0, 1, 0, 0, 0], [0, 0, 0, 1, 0, 0], [0, 0, 0, 0, 1, "
            "0], [0, 0, 0, 0, \"x\", 1]]\n"),
      "s.toml:9: error: sensor 's': every value of 'gauge_matrix' must be a finite number");
  has(error("type = \"encoder\"\nrobot = \"irb6\"\naxis = \"elbow\"\n"),
      "s.toml:9: error: sensor 's': robot 'irb6' has no axis 'elbow' (axes: column, lower_arm");
  has(error("type = \"encoder\"\nrobot = \"irb6\"\naxis = 5\n"),
      "s.toml:9: error: sensor 's': robot 'irb6' has no axis 5");
  has(error("type = \"encoder\"\nrobot = \"rnt\"\naxis = 0\n"),
      "s.toml:8: error: sensor 's': cell 'world': no robot named 'rnt'");
  has(error("type = \"encoder\"\nrobot = \"irb6\"\naxis = 0\nrate_hz = 2000\n"),
      "s.toml:10: error: sensor 's': 'rate_hz' = 2000 Hz must be > 0 and at most the physics "
      "rate 1000 Hz");
  has(error("type = \"camera\"\nobjects = [\"part\"]\nregion = [0, 1, 0, 1, 0, 1]\n"),
      "s.toml:8: error: sensor 's': object 'part' is not a body of the scene");
  has(error("type = \"camera\"\nobjects = [\"irb6/roll_link\"]\nregion = [0, 1, 1, 0, 0, 1]\n"),
      "s.toml:9: error: sensor 's': 'region' y range 1 .. 0 m is empty");
  has(error("type = \"encoder\"\nrobot = \"irb6\"\naxis = 0\nnoise = -1\n"),
      "s.toml:10: error: sensor 's': 'noise' = -1");
  has(error("type = \"encoder\"\nrobot = \"irb6\"\naxis = 0\n[[scene.sensor]]\nname = \"s\"\n"
            "type = \"encoder\"\nrobot = \"irb6\"\naxis = 1\n"),
      "s.toml:10: error: duplicate sensor name 's' (first used at ");
  has(error("type = \"grasp\"\nobject = \"irb6/roll_link\"\n"),
      "s.toml:8: error: sensor 's': cell 'world': no grasped object named 'irb6/roll_link' "
      "(objects with grasps: none)");
  has(error("type = \"grasp\"\n"), "s.toml:5: error: sensor 's': missing key 'object'");
  // A device on the world is fine (it sees every geom, the floor included).
  const fs::path ok = dir.write("ok.toml", head +
                                               "type = \"range\"\nbody = \"world\"\npos = [2, "
                                               "0, 1]\nrotation = [3.141592653589793, 0, 0]\n");
  SensorDevices on_world(ok, world);
  for (int i = 0; i < 30; ++i) {
    ASSERT_TRUE(world.step());
    (void)on_world.update(world, wall_utime(world));
  }
  EXPECT_TRUE(on_world.sample(0).valid);
  EXPECT_NEAR(on_world.sample(0).values[0], 1.0, 1e-9);  // down to the floor
}

TEST(EmuSensors, GraspDeviceIsTheBarsGripAsTheCellWorldMeasuresIt) {
  // two-irb6.toml's bar_grip, its arms at power-on (nowhere near the bar): open grips.
  CellWorld world(scene_file("two-irb6.toml"));
  SensorDevices sensors(scene_file("two-irb6.toml"), world);
  const std::size_t i = sensors.index("bar_grip");
  EXPECT_EQ(sensors.config(i).type, mrroc::emu::SensorType::grasp);
  EXPECT_EQ(sensors.config(i).rate_hz, 500.0);
  EXPECT_NE(sensors.describe(i).find("grip on object 'bar' by left/flange, right/flange"),
            std::string::npos)
      << sensors.describe(i);
  const std::vector<std::string> names = {"internal", "x",   "y",        "z",   "engaged0", "fx0",
                                          "fy0",      "fz0", "engaged1", "fx1", "fy1",      "fz1"};
  EXPECT_EQ(sensors.sample(i).names, names);
  EXPECT_EQ(sensors.sample(i).units[0], "N");
  int published = 0;
  for (int s = 0; s < 100; ++s) {
    ASSERT_TRUE(world.step()) << world.fault_text();
    for (const std::size_t ready : sensors.update(world, wall_utime(world)))
      published += ready == i ? 1 : 0;
  }
  EXPECT_EQ(published, 50);  // 500 Hz for 0.1 s
  const auto& v = sensors.sample(i).values;
  EXPECT_EQ(v[0], 0.0);
  EXPECT_NEAR(v[1], 1.0, 1e-3);  // the bar on its table
  EXPECT_NEAR(v[3], 1.10, 1e-3);
  EXPECT_EQ(v[4], 0.0);
  EXPECT_EQ(v[8], 0.0);
  EXPECT_EQ(v[7], 0.0) << "an open grip exerts no force";
}

TEST(EmuSensors, EngravingDeviceIsTheCutAsTheCellWorldMeasuresIt) {
  // engrave.toml's engraving: the RNT at its power-on pose, the tip far above the board.
  CellWorld world(scene_file("engrave.toml"));
  SensorDevices sensors(scene_file("engrave.toml"), world);
  const std::size_t i = sensors.index("engraving");
  EXPECT_EQ(sensors.config(i).type, mrroc::emu::SensorType::engraving);
  EXPECT_EQ(sensors.config(i).rate_hz, 500.0);
  EXPECT_EQ(sensors.config(i).cutter, "rnt/tool");
  EXPECT_NE(sensors.describe(i).find("engraving of board 'board' by 'rnt/tool'"), std::string::npos)
      << sensors.describe(i);
  const std::vector<std::string> names = {"x", "y", "depth", "cutting", "force"};
  EXPECT_EQ(sensors.sample(i).names, names);
  const std::vector<std::string> units = {"m", "m", "m", "", "N"};
  EXPECT_EQ(sensors.sample(i).units, units);
  int published = 0;
  long allocations = 0;
  for (int s = 0; s < 100; ++s) {
    ASSERT_TRUE(world.step()) << world.fault_text();
    const std::int64_t now = wall_utime(world);
    g_heap.allocations = 0;
    g_heap.counting = true;
    const auto ready = sensors.update(world, now);
    g_heap.counting = false;
    allocations += g_heap.allocations;
    for (const std::size_t device : ready) published += device == i ? 1 : 0;
  }
  EXPECT_EQ(allocations, 0) << "sampling the engraving allocated";
  EXPECT_EQ(published, 50);  // 500 Hz for 0.1 s
  const auto& v = sensors.sample(i).values;
  const mrroc::emu::CutReading& cut = world.cut_reading(world.cut_index("board"));
  // The tip in the board's frame: the tool site's world position less the board's centre.
  const FramePose tip = world.site_pose("rnt/tool");
  EXPECT_NEAR(v[0], tip.position[0] - 0.60, 1e-12);
  EXPECT_NEAR(v[1], tip.position[1], 1e-12);
  EXPECT_NEAR(v[2], 0.20 - tip.position[2], 1e-12);
  EXPECT_EQ(v[2], cut.depth);
  EXPECT_LT(v[2], -0.1) << "power-on holds the cutter far above the board";
  EXPECT_EQ(v[3], 0.0);
  EXPECT_EQ(v[4], 0.0) << "no force out of the board";
}

TEST(EmuSensors, EngravingDeviceNamesAnExistingCut) {
  ScratchDir dir;
  std::ifstream in(scene_file("engrave.toml"));
  std::stringstream contents;
  contents << in.rdbuf();
  std::string scene = contents.str();
  scene = scene.substr(0, scene.find("[[scene.sensor]]"));
  const std::string model = "\"../../robots/rnt\"";
  scene.replace(scene.find(model), model.size(), "\"" MRROC_SOURCE_DIR "/robots/rnt\"");
  const fs::path world_file = dir.write("world.toml", scene);
  CellWorld world(world_file);
  const auto error = [&](const std::string& keys) {
    const fs::path file = dir.write(
        "s.toml", scene + "[[scene.sensor]]\nname = \"s\"\ntype = \"engraving\"\n" + keys);
    return config_error([&] { (void)SensorDevices(file, world); });
  };
  const auto has = [](const std::string& text, const std::string& part) {
    EXPECT_NE(text.find(part), std::string::npos) << text << "\n  lacks: " << part;
  };
  has(error(""), "error: sensor 's': missing key 'object' (a board with [[scene.object.cutter]]");
  has(error("object = \"table\"\n"),
      "error: sensor 's': cell 'engrave': no cut of object 'table' (cuts: 'board' by 'rnt/tool')");
  has(error("object = \"board\"\ncutter = \"rnt/flange\"\n"),
      "error: sensor 's': cell 'engrave': no cut of object 'board' by 'rnt/flange'");
  has(error("object = \"board\"\nbody = \"world\"\n"),
      "unknown key 'body' in [[scene.sensor]] of type engraving (allowed: name, type, rate_hz, "
      "noise, seed, object, cutter)");
  EXPECT_EQ(
      SensorDevices(dir.write("ok.toml", scene + "[[scene.sensor]]\nname = \"s\"\ntype = "
                                                 "\"engraving\"\nobject = \"board\"\ncutter = "
                                                 "\"rnt/tool\"\n"),
                    world)
          .size(),
      1U);
}

}  // namespace
