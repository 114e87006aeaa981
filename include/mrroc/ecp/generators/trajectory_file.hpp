#pragma once
/// @file
/// Teach-in trajectory files: a plain-text list of poses in one arm representation, each with an
/// optional duration or velocity scale (format: docs/generators.md, "Trajectory files").
///
///     # mrroc trajectory v1 representation=JOINT axes=5 robot=irb6
///     # column lower_arm upper_arm wrist_pitch wrist_roll [rad]
///     0 -1.5707963267948966 0 0 0
///     0.2 -1.4 0.1 0 0.5 duration=2.5
///     0.2 -1.4 0.1 0 0.5 duration=1       # a dwell of 1 s
///     0 -1.5707963267948966 0 0 0 velocity_scale=0.5

#include <cstddef>
#include <filesystem>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "mrroc/msg/edp_instruction.hpp"

namespace mrroc::ecp {

/// One taught pose.
struct TrajectoryPoint {
  /// The pose in the file's representation: one value per axis (JOINT [rad], MOTOR [rad]) or the
  /// representation's values (FRAME 12, XYZ_EULER_ZYZ 6, XYZ_ANGLE_AXIS 6; m and rad).
  std::vector<double> values;
  std::optional<double> duration_s = std::nullopt;      ///< [s], > 0: duration of the move here
  std::optional<double> velocity_scale = std::nullopt;  ///< (0, 1]: of the playback's limits

  bool operator==(const TrajectoryPoint&) const = default;
};

struct TrajectoryFile {
  /// Highest format version this code reads and the one it writes.
  static constexpr int kVersion = 1;

  edp::ArmRepresentation representation = edp::ArmRepresentation::joint;
  std::size_t axes = 0;  ///< the robot's number of axes (1..64)
  std::string robot;     ///< the robot model's name; empty: not recorded
  std::vector<TrajectoryPoint> points;

  /// Values each point has: `axes` for JOINT and MOTOR, else the representation's size.
  [[nodiscard]] std::size_t values_per_point() const;

  /// Reads a file. @throws ConfigError "file:line: error: ..." naming the offending value and
  ///   what was expected (also for a file that cannot be opened: "file: error: ...").
  static TrajectoryFile load(const std::filesystem::path& path);
  /// Parses `text`; `name` stands for the file name in errors. @throws ConfigError as load.
  static TrajectoryFile parse(std::string_view text, const std::string& name = "<text>");

  /// The file's text (values printed with the shortest decimal form that reads back exactly, so
  /// save + load is lossless). @throws Error when the trajectory is inconsistent (a point's size,
  ///   a value not finite, a duration or scale out of range) naming the point.
  [[nodiscard]] std::string to_text() const;
  /// Writes `to_text()` to `path` (through a temporary file renamed over it).
  /// @throws Error naming the path when it cannot be written, or as to_text.
  void save(const std::filesystem::path& path) const;

  bool operator==(const TrajectoryFile&) const = default;
};

/// Parses a representation name as written in files and messages ("JOINT", "MOTOR", "FRAME",
/// "XYZ_EULER_ZYZ", "XYZ_ANGLE_AXIS"); nothing for anything else.
std::optional<edp::ArmRepresentation> representation_from_string(std::string_view name);

}  // namespace mrroc::ecp
