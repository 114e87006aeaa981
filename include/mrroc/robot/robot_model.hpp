#pragma once
/// @file
/// A robot's model as the controller needs it: axes, joint names, joint limits (from the URDF),
/// velocity/acceleration limits, synchronisation positions and the kinematics' parameters (from
/// parameters.toml). Every key of parameters.toml is read by some code; an unknown key is an error.

#include <array>
#include <filesystem>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "mrroc/robot/limit_violation.hpp"

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
  /// Link lengths [m] of the kinematic models, for a solver that takes its geometry from this file
  /// (`solver_link_lengths`; solver "irb6": d1, a2, a3, d5). Entry 0 is kinematic model 0, the
  /// lengths under [robot.kinematics]; entry 1, when the file has [robot.kinematics.calibrated],
  /// is model 1, those lengths (one the table leaves out keeps its model-0 value). Each entry holds
  /// one value per name, in the order of `solver_link_lengths`. Empty for the other solvers.
  std::vector<std::vector<double>> link_lengths;

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
  /// "joint 2 (upper_arm) target 0.81 rad exceeds upper limit 0.70 rad"; (code bad_argument) for
  /// the wrong number of values or one that is not a finite number.
  void check_joint_limits(std::span<const double> q, const char* what = "target") const;
  /// The same check as a value (the first joint outside its limits, in the order
  /// check_joint_limits reports them); allocation-free.
  [[nodiscard]] LimitViolation joint_limit_violation(std::span<const double> q) const noexcept;
};

/// The link lengths [m] that kinematics solver `solver` takes from [robot.kinematics] (and
/// [robot.kinematics.calibrated]) of parameters.toml, in order: "irb6" -> d1, a2, a3, d5; empty for
/// every other solver (they take their geometry from the URDF).
std::span<const char* const> solver_link_lengths(std::string_view solver);

/// Largest link length [m] parameters.toml may give (no link of a cell's robot is longer).
inline constexpr double kMaxLinkLength = 10.0;
/// Largest difference between a calibrated link length and its nominal value, as a fraction of
/// the nominal value: a calibration corrects small errors of a unit, not its design.
inline constexpr double kMaxCalibrationChange = 0.10;

/// Loads `folder/parameters.toml` and the URDF it names.
/// @throws ConfigError naming the file and line: a TOML syntax error, an unknown key (naming the
///   known ones, see `check_robot_parameter_keys`), a value of the wrong type, a missing key, a
///   link length that is not a finite number in (0, kMaxLinkLength] m or a calibrated one that
///   differs from the nominal by more than kMaxCalibrationChange.
RobotModel load_robot_model(const std::filesystem::path& folder);

/// Checks that `file` (a robot's parameters.toml) holds only keys some code reads: [robot] name,
/// axes, joint_names, urdf, mjcf, synchro_joint_positions, max_joint_velocity,
/// max_joint_acceleration; [robot.kinematics] solver, models, correctors and the solver's link
/// lengths with [robot.kinematics.calibrated]; [robot.transmission] coupling.
/// @throws ConfigError "file:line: error: unknown key 'tool' in [robot] (known: ...)", or for a
///   TOML syntax error.
void check_robot_parameter_keys(const std::filesystem::path& file);

}  // namespace mrroc
