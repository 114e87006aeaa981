#pragma once
/// @file
/// The scene objects' poses on LCM: `ObjectPosePublisher` sends every object of the cell's scene
/// (`[[scene.object]]`: its shape, size, colour, attach, and its world pose as MuJoCo has it) as
/// one scene_objects_t on `mrroc/scene/objects` (include/mrroc/msg/scene_objects.hpp), about 30
/// times a second of wall-clock time, for the web console's 3D view. The pose of an object is
/// the world pose of its MuJoCo body (its geom's centre: compose_scene puts the geom at the
/// body's origin); free objects move with the physics, attached ones with their body.

#include <cstdint>
#include <string>
#include <vector>

#include <lcm/lcm-cpp.hpp>

#include "cell_world.hpp"
#include "mrroc/msg/scene_objects.hpp"
#include "mrroc_lcm/scene_objects_t.hpp"
#include "scene.hpp"

namespace mrroc::comm {
class Authenticator;
}  // namespace mrroc::comm

namespace mrroc::emu {

/// Sends the scene's objects and their poses. The message and its encode buffers are made at
/// construction, so update() and publish() do not allocate in mrroc's code (LCM's transport and
/// OpenSSL may). With an authenticator (the set's key), each message is signed for its channel
/// as comm::sign does (the console checks it).
class ObjectPosePublisher {
 public:
  /// Period of the publication [us of wall-clock time]: 30 a second.
  static constexpr std::int64_t kPeriodUs = 33'333;

  /// The objects of `scene` (its [[scene.object]] tables, in order), found in `world` (built
  /// from the same scene). `sender` goes into header.sender (e.g. "emu#1234"); `auth` may be
  /// null (no key). @throws Error naming an object that has no body in `world`.
  ObjectPosePublisher(lcm::LCM& lcm, const Scene& scene, const CellWorld& world,
                      const std::string& sender, comm::Authenticator* auth = nullptr);

  /// The message as the scene file describes the objects: shapes, sizes, colours, attach.
  [[nodiscard]] static SceneObjects describe(const Scene& scene);

  [[nodiscard]] std::size_t size() const noexcept { return bodies_.size(); }
  /// Fills the message with the world's current poses and `wall_utime` [us since the epoch].
  const mrroc_lcm::scene_objects_t& fill(const CellWorld& world, std::int64_t wall_utime) noexcept;
  /// After a physics step: when kPeriodUs have passed since the last publication (or none was
  /// made), fills and publishes. Returns false when LCM refused a message that was due.
  bool update(const CellWorld& world, std::int64_t wall_utime) noexcept;
  /// Fills and publishes now. Returns false when LCM refused it (or signing failed).
  bool publish(const CellWorld& world, std::int64_t wall_utime) noexcept;

  [[nodiscard]] std::uint64_t published() const noexcept { return published_; }
  [[nodiscard]] std::uint64_t failed() const noexcept { return failed_; }

 private:
  lcm::LCM& lcm_;
  comm::Authenticator* auth_;
  std::string channel_;
  mrroc_lcm::scene_objects_t message_;
  std::vector<int> bodies_;                   ///< per object: its MuJoCo body id
  std::vector<std::uint8_t> buffer_;          ///< what goes out
  std::vector<std::uint8_t> unsigned_bytes_;  ///< with a key: the message with an empty tag
  std::vector<std::uint8_t> mac_input_;       ///< with a key: Authenticator::mac's scratch
  std::int64_t next_utime_ = 0;
  std::int64_t seq_ = 0;
  std::uint64_t published_ = 0;
  std::uint64_t failed_ = 0;
};

}  // namespace mrroc::emu
