#pragma once
/// @file
/// The cell emulator's scene objects and their poses in the world (scene_objects_t and
/// scene_object_t, channel mrroc/scene/objects), broadcast by mrroc-axis-emu about 30 times a
/// second for the web console's 3D view. Units: m; quaternions (w, x, y, z).

#include <array>
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

namespace mrroc {

/// The shape of a scene object (the numbers of scene_object_t's constants).
enum class SceneObjectShape : std::int8_t { box = 1, sphere = 2, cylinder = 3, capsule = 4 };

/// One object: what the scene file says of it and where it is.
struct SceneObjectPose {
  std::string name;
  SceneObjectShape shape = SceneObjectShape::box;
  /// [m] MuJoCo geom size: box half-sizes x y z (3 values); sphere radius (1); cylinder and
  /// capsule radius, half-length along the local z (2).
  std::vector<double> size;
  std::array<double, 4> rgba = {0.8, 0.3, 0.2, 1.0};
  std::string attach;  ///< body it is fixed to; "" when free
  /// Its pose in the frame of `attach` as the scene file gives it [m], (w, x, y, z); a free
  /// body: its initial pose in the world.
  std::array<double, 3> local_position{};
  std::array<double, 4> local_quaternion = {1.0, 0.0, 0.0, 0.0};
  std::array<double, 3> position{};                         ///< [m] in the world
  std::array<double, 4> quaternion = {1.0, 0.0, 0.0, 0.0};  ///< w x y z
};

/// Every object of the scene at one moment.
struct SceneObjects {
  std::string scene;        ///< the scene's name
  double sim_time_s = 0.0;  ///< simulated time of the poses [s]
  std::vector<SceneObjectPose> objects;
};

/// The number of size values of a shape: 3 for a box, 1 for a sphere, 2 otherwise.
constexpr std::size_t scene_object_size_count(SceneObjectShape shape) noexcept {
  return shape == SceneObjectShape::box ? 3 : shape == SceneObjectShape::sphere ? 1 : 2;
}

}  // namespace mrroc
