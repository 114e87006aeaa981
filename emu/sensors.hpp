#pragma once
/// @file
/// The scene's raw sensor devices: receptors sampled from the cell world's physics and published
/// as `raw_sensor_t` on `mrroc/raw/<device>` (the channels the VSPs read, vsp/plugins). Read from
/// the scene file's `[[scene.sensor]]` tables (docs/hil.md, "Raw sensor devices"):
///
///     [[scene.sensor]]
///     name = "irb6_wrist"           # device name (channel mrroc/raw/<name>), unique
///     type = "strain_gauges"        # strain_gauges | range | encoder | camera | grasp |
///                                   #   engraving
///     rate_hz = 500                 # optional: samples per second of simulated time
///     noise = 0.0002                # optional: std of Gaussian noise, in the values' unit
///     seed = 7                      # optional: noise seed (default: from the name)
///     body = "irb6/roll_link"       # strain_gauges, range: the body it is mounted on
///     pos = [0.19, 0.0, 0.0]        #   m, sensor frame origin in that body
///     rotation = [0.0, 1.5708, 0.0] #   rotation vector [rad] of the sensor frame in that body
///     gauge_matrix = [[...], ...]   # strain_gauges: 6 x 6, V per N / per N m
///     offset = [0, 0, 0, 0, 0, 0]   #   V
///     max_range = 4.0               # range: m
///     robot = "conveyor"            # encoder: robot and
///     axis = "belt"                 #   axis (name or 0-based index)
///     objects = ["part"]            # camera: bodies it looks for, in order
///     region = [x0, x1, y0, y1, z0, z1]  # its field of view in the world [m]
///     latency_ms = 50               #   publication delay [ms]
///     object = "bar"                # grasp: an object with [[scene.object.grasp]] entries;
///                                   #   engraving: a board with [[scene.object.cutter]] entries
///     cutter = "rnt/tool"           # engraving, optional: the cutter's site (default: the
///                                   #   board's only cutter)
///
/// The devices, their values and units:
///   - strain_gauges (default 500 Hz): a 6-axis wrist force/torque sensor of six strain-gauge
///     bridges, values g0..g5 [V] = G w + offset + noise. w = (fx, fy, fz [N], tx, ty, tz [N m])
///     is the load on the sensor's outboard side, in the sensor frame and about its origin: the
///     sum of every contact force acting on a geom of a body outboard of the sensor (the strict
///     descendants of `body`: objects attached to it, further links) from a body that is not
///     outboard, plus the weight of the outboard bodies (gravity at their centres of mass), plus
///     the pull of every object held by an engaged grasp whose gripper is `body` or outboard of
///     it (the opposite of the force the grasp's weld exerts on the object, at the gripper
///     frame; the weld's torque rows are not counted), plus the cutting resistance of every cut
///     whose cutter is outboard and board is not (at the cutter tip; or the opposite, for a
///     board outboard). It is the static load: inertial forces
///     are not included. A tool pointing down with a weight
///     m g gives fz = +m g; pressing it onto a table makes fz smaller (the table pushes the tool
///     back towards the sensor, along -z). Default G = diag(0.01, 0.01, 0.01, 0.1, 0.1, 0.1)
///     (I + X) with the cross-coupling X[i][i+1 mod 6] = 0.02, X[i][i-1 mod 6] = -0.01
///     (`default_gauge_matrix()`); the VSP's force_torque plugin calibrates with G^-1.
///   - range (default 50 Hz): an ultrasonic/infrared range finder; beam along the sensor frame's
///     +z from its origin (a ray: the cone is ignored); value "distance" [m] to the nearest
///     visible geom (robot links included, the mounting body's own geoms excluded; a sensor on
///     "world" sees every geom); valid = 0 when nothing is within max_range.
///   - encoder (default 500 Hz): value "position" [m or rad], the axis' actuator joint position.
///   - camera (default 30 Hz): an EMULATED object-pose camera (no image processing): values x, y,
///     z [m] (+ noise), qw, qx, qy, qz of the first listed object whose body origin is inside
///     `region`; valid = 0 (values 0 and the identity) when none is. Each sample is published
///     latency_ms of simulated time after it was taken.
///   - grasp (default 500 Hz): the grip on an object held by grippers (scene.hpp, "Grasps"):
///     values "internal" [N], the object's internal force (CellWorld::internal_force, + noise);
///     "x", "y", "z" [m], its position in the world; then for each of its grasps i (scene
///     order) "engaged<i>" (1 or 0) and "fx<i>", "fy<i>", "fz<i>" [N] (+ noise), the force its
///     gripper exerts on the object, world frame. Values of the last physics step.
///   - engraving (default 500 Hz): a cut of a board (scene.hpp, "Cutting"; CellWorld, "Cutting"):
///     values "x", "y" [m], the cutter tip in the board's frame (its origin is the board's
///     centre, z up through the top face); "depth" [m], the tip below the top face (negative
///     above it); "cutting" (1 or 0: below the face and inside its rectangle); "force" [N], the
///     magnitude of the cutting resistance (+ noise while cutting; 0 while not). Values of the
///     current state, as the next physics step applies them. The emulator prints each cut's
///     groove at exit (strokes, cut length, largest depth and force).
/// sample_no counts each device's samples from 0. sample_utime is the wall clock when the sample
/// is taken (= when it is published), for the camera the publication time minus the latency.
/// Rates count simulated time (so they hold in lock-step too); a device samples at the first
/// physics step at or after each due time, at most once per step.
///
/// Errors are `ConfigError`s "file:line: error: sensor 'x': ..." (unknown key, unknown body,
/// robot, axis or object, a bad matrix, a rate above the physics rate, ...).
#include <array>
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <random>
#include <span>
#include <string>
#include <vector>

#include <lcm/lcm-cpp.hpp>

#include "cell_world.hpp"
#include "mrroc/config/params.hpp"
#include "mrroc/msg/sensor_reading.hpp"
#include "mrroc_lcm/raw_sensor_t.hpp"

namespace mrroc::comm {
class Authenticator;
}  // namespace mrroc::comm

namespace mrroc::emu {

enum class SensorType { strain_gauges, range, encoder, camera, grasp, engraving };

/// "strain_gauges", ...
const char* sensor_type_name(SensorType type) noexcept;

/// 6 x 6, row-major [V per N or per N m].
using GaugeMatrix = std::array<double, 36>;

/// diag(0.01, 0.01, 0.01, 0.1, 0.1, 0.1) (I + X), X[i][i+1 mod 6] = 0.02, X[i][i-1 mod 6] = -0.01.
GaugeMatrix default_gauge_matrix() noexcept;

/// One device as configured.
struct SensorConfig {
  std::string name;
  SensorType type = SensorType::strain_gauges;
  double rate_hz = 0.0;
  double noise = 0.0;  ///< std [V, m or rad]
  std::uint64_t seed = 0;
  std::string body;                  ///< strain_gauges, range: mounting body ("world" allowed)
  std::array<double, 3> position{};  ///< [m] in `body`
  std::array<double, 3> rotation{};  ///< rotation vector [rad] in `body`
  GaugeMatrix gauge_matrix = default_gauge_matrix();
  std::array<double, 6> offset{};    ///< [V]
  double max_range = 4.0;            ///< [m]
  std::string robot;                 ///< encoder
  std::size_t axis = 0;              ///< encoder
  std::vector<std::string> objects;  ///< camera
  std::array<double, 6> region{};    ///< camera: xmin xmax ymin ymax zmin zmax [m]
  double latency_s = 0.05;           ///< camera
  std::string object;                ///< grasp, engraving
  std::string cutter;                ///< engraving: the cutter's site
  SourceLocation where;              ///< of the [[scene.sensor]] table
};

/// Reads the `[[scene.sensor]]` tables of `scene_file` and checks them against `world` (bodies,
/// robots, axes, objects exist; rates at most the physics rate). None: an empty list.
/// @throws ConfigError "file:line: error: sensor 'x': ...".
std::vector<SensorConfig> read_sensor_configs(const std::filesystem::path& scene_file,
                                              const CellWorld& world);

/// The devices of a cell, sampled from its world.
///
/// Real time: update(), sample() and wrench() neither allocate nor throw (everything is sized at
/// construction).
class SensorDevices {
 public:
  /// @throws ConfigError as read_sensor_configs() (for configs that name unknown bodies ...).
  SensorDevices(std::vector<SensorConfig> configs, const CellWorld& world);
  /// read_sensor_configs(scene_file, world), then as above.
  SensorDevices(const std::filesystem::path& scene_file, const CellWorld& world);
  ~SensorDevices();
  SensorDevices(const SensorDevices&) = delete;
  SensorDevices& operator=(const SensorDevices&) = delete;

  [[nodiscard]] std::size_t size() const noexcept { return devices_.size(); }
  [[nodiscard]] const SensorConfig& config(std::size_t i) const;
  /// Index of the device named `name`. @throws Error listing the devices when unknown.
  [[nodiscard]] std::size_t index(const std::string& name) const;
  /// One line for the emulator's console: "sensor 'irb6_wrist': strain gauges on ...".
  [[nodiscard]] std::string describe(std::size_t i) const;

  /// After a physics step: takes every sample that is due at world.time() and returns the devices
  /// whose sample is to be published now (their sample(i)), in device order. `wall_utime` is now
  /// [us since the epoch]. Strain gauges make the world solve its constraint forces
  /// (CellWorld::solve_constraint_forces). The span stays valid until the next call.
  std::span<const std::size_t> update(CellWorld& world, std::int64_t wall_utime) noexcept;
  /// The sample of device i that update() returned last.
  [[nodiscard]] const vsp::RawSample& sample(std::size_t i) const noexcept;
  /// The noise-free wrench (fx, fy, fz [N], tx, ty, tz [N m]) behind strain-gauge device i's
  /// last sample, in its sensor frame (zeros for other devices).
  [[nodiscard]] std::array<double, 6> wrench(std::size_t i) const noexcept;
  /// World pose of a mounted device's sensor frame (strain_gauges, range) as of the world's
  /// current state.
  [[nodiscard]] FramePose sensor_pose(const CellWorld& world, std::size_t i) const noexcept;

 private:
  struct Device;
  std::vector<std::unique_ptr<Device>> devices_;
  std::vector<std::size_t> ready_;
  std::vector<std::string> world_grippers_;  ///< per grasp of the world: its gripper
  double timestep_ = 0.001;
};

/// Sends raw samples as raw_sensor_t on mrroc/raw/<device>: messages, channels and encode
/// buffers are made at construction, so publish() does not allocate in mrroc's code (LCM's
/// transport and OpenSSL may). With an authenticator (the set's key), every sample is signed
/// for its channel as comm::sign does (the VSP checks it).
class RawSamplePublisher {
 public:
  /// `sender` goes into header.sender (e.g. "emu#1234"); `auth` may be null (no key).
  RawSamplePublisher(lcm::LCM& lcm, const SensorDevices& devices, const std::string& sender,
                     comm::Authenticator* auth = nullptr);
  /// Publishes device i's sample with header.utime = `wall_utime`. Returns false when LCM
  /// refused it.
  bool publish(std::size_t i, const vsp::RawSample& sample, std::int64_t wall_utime) noexcept;
  [[nodiscard]] std::uint64_t published() const noexcept { return published_; }
  [[nodiscard]] std::uint64_t failed() const noexcept { return failed_; }

 private:
  struct Channel {
    std::string name;
    mrroc_lcm::raw_sensor_t message;
    std::vector<std::uint8_t> buffer;          ///< what goes out
    std::vector<std::uint8_t> unsigned_bytes;  ///< with a key: the message with an empty tag
    std::vector<std::uint8_t> mac_input;       ///< with a key: Authenticator::mac's scratch
  };
  lcm::LCM& lcm_;
  comm::Authenticator* auth_;
  std::vector<Channel> channels_;
  std::uint64_t published_ = 0;
  std::uint64_t failed_ = 0;
};

}  // namespace mrroc::emu
