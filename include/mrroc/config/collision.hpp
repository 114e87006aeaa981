#pragma once
/// @file
/// The cell's collision section of a process-set file (`[collision]`, docs/configs.md): whether
/// the EDPs guard their commands against collisions, the clearance they keep, the fixed objects
/// of the cell and the contacts that are allowed. Plain values; the EDP's collision guard
/// (edp/collision_guard.hpp) builds its geometry from them.

#include <array>
#include <string>
#include <vector>

#include "mrroc/core/error.hpp"

namespace mrroc {

/// Clearance every robot keeps from the cell and from itself when none is configured [m].
inline constexpr double kDefaultCollisionClearance = 0.01;
/// The largest clearance accepted [m].
inline constexpr double kMaxCollisionClearance = 0.5;

/// A fixed object of the cell (`[[collision.object]]`): a box.
struct CollisionObject {
  std::string name;                   ///< unique among the objects, e.g. "table"
  std::array<double, 3> half_size{};  ///< half-sizes along the box's axes [m], each > 0
  /// Pose of the box centre in the cell: x, y, z [m] and a rotation vector [rad] (the same
  /// frame as a robot's `base`).
  std::array<double, 6> pose{};
  SourceLocation where;
};

/// A contact that is allowed (`allow` of `[collision]`): two bodies that may come closer than
/// the clearance, e.g. a gripper and the object it holds. Each side is a fixed object's name or
/// "<robot>/<link>", a link (body of the robot's MJCF model) of a `[[robot]]`.
struct AllowedContact {
  std::string first;
  std::string second;
  SourceLocation where;
};

struct CollisionConfig {
  /// The EDPs check every SET ARM against collisions: on when the set has a `[collision]`
  /// section (unless it says `enabled = false`), off when it has none.
  bool enabled = false;
  double clearance_m = kDefaultCollisionClearance;  ///< 0 < clearance <= kMaxCollisionClearance
  std::vector<CollisionObject> objects;
  std::vector<AllowedContact> allowed;
  SourceLocation where;          ///< the [collision] table (file only when the set has none)
  SourceLocation enabled_where;  ///< its `enabled` key, else the table (file only: no table)
};

}  // namespace mrroc
