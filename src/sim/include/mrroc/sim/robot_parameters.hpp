#pragma once
/// @file
/// What the simulations (the `mujoco` EDP plugin, the axis emulator's cell world) read from a
/// robot's `robots/<name>/parameters.toml`: the `[robot]` table's MJCF file name, synchronisation
/// pose, joint names and the linear coupling a = M q of `[robot.transmission]`.

#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "mrroc/core/error.hpp"

namespace mrroc::sim {

struct RobotParameters {
  std::filesystem::path path;  ///< the file read
  /// robot.mjcf: MJCF file name relative to the model folder.
  std::optional<std::string> mjcf;
  /// robot.synchro_joint_positions: joint pose q at the synchronisation switches [rad or m].
  std::optional<std::vector<double>> synchro;
  /// robot.joint_names: the axis names, in axis order.
  std::optional<std::vector<std::string>> joint_names;
  /// robot.transmission.coupling, row by row (a = M q), and where it is written.
  std::optional<std::vector<std::vector<double>>> coupling;
  SourceLocation coupling_where;
};

/// Reads the keys above; the file's other keys are read by `load_robot_model`, and a key no code
/// reads is refused (`check_robot_parameter_keys`).
/// @throws ConfigError "file:line: error: ..." on a TOML syntax error, an unknown key (naming the
///   known ones) or a value of the wrong type (naming the key and the expected type and unit).
RobotParameters read_robot_parameters(const std::filesystem::path& path);

}  // namespace mrroc::sim
