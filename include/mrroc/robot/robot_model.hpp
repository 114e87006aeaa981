#pragma once
/// @file
/// A robot's model as the controller needs it: axes, joint names, joint limits (from the URDF),
/// velocity/acceleration limits and synchronisation positions (from parameters.toml).

#include <array>
#include <filesystem>
#include <string>
#include <vector>

namespace mrroc {

/// The file of a robot model folder that describes the robot (robots/<name>/parameters.toml).
inline constexpr const char* kRobotParametersFile = "parameters.toml";

struct RobotModel {
  std::string name;
  std::filesystem::path folder;
  std::filesystem::path urdf;  ///< absolute path
  std::filesystem::path mjcf;  ///< absolute path
  std::vector<std::string> joint_names;
  std::vector<double> lower_limits;             ///< [rad]
  std::vector<double> upper_limits;             ///< [rad]
  std::vector<double> max_velocity;             ///< [rad/s]
  std::vector<double> max_acceleration;         ///< [rad/s^2]
  std::vector<double> synchro_joint_positions;  ///< [rad]
  /// Per joint: true for a prismatic joint (its values are in m, m/s, m/s^2 where the others are
  /// in rad), from the URDF's joint type.
  std::vector<bool> prismatic;
  /// Kinematics solver name ([robot.kinematics] solver), empty: joint-only.
  std::string kinematics;
  /// Local correctors of the kinematic model ([robot.kinematics] correctors), each a frame as
  /// x, y, z [m] and a rotation vector [rad]; corrector number i+1 is correctors[i].
  std::vector<std::array<double, 6>> correctors;
  /// URDF files of the kinematic models ([robot.kinematics] models; absolute paths), model i is
  /// kinematic_models[i]; empty: the solver's own models.
  std::vector<std::filesystem::path> kinematic_models;

  /// Linear transmission between joint coordinates q and the motors' axis coordinates a:
  /// a = coupling q ([robot.transmission] coupling, n x n, row by row); empty: identity.
  std::vector<std::vector<double>> coupling;
  [[nodiscard]] std::size_t axes() const { return joint_names.size(); }
  /// `folder`/parameters.toml.
  [[nodiscard]] std::filesystem::path parameters_file() const {
    return folder / kRobotParametersFile;
  }
  /// "m" for a prismatic joint, else "rad".
  [[nodiscard]] const char* unit(std::size_t joint) const {
    return joint < prismatic.size() && prismatic[joint] ? "m" : "rad";
  }

  /// Checks one joint vector. @throws CommandError (code out_of_limits) such as
  /// "joint 2 (upper_arm) target 0.81 rad exceeds upper limit 0.70 rad".
  void check_joint_limits(const std::vector<double>& q, const char* what = "target") const;
};

/// Loads `folder/parameters.toml` and the URDF it names.
/// @throws ConfigError naming the file (and line, for TOML errors).
RobotModel load_robot_model(const std::filesystem::path& folder);

}  // namespace mrroc
