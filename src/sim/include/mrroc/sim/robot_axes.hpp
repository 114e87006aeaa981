#pragma once
/// @file
/// A robot's axes inside a MuJoCo model, and its power-on state: shared by the `mujoco` EDP
/// plugin (one robot per model) and the axis emulator's cell world (several robots in one model,
/// each robot's names prefixed with "<robot>/").
///
/// Axes are actuators: axis i is the model's actuator `first + i`, a position servo on one hinge
/// or slide joint (its *actuator joint*, position a_i). The robot's joint coordinates q (the
/// serial-equivalent chain of its URDF) follow from a = M q (`Coupling`). Other joints of the
/// robot are passive; they may belong to closed kinematic loops that the model closes with
/// equality constraints.
///
/// Joint ranges: an axis' range is that of the model joint with the axis' name when there is one
/// (for a coupled axis, normally its passive serial joint), else that of its actuator joint when
/// the axis is uncoupled. The power-on pose must lie in those ranges and M q in the actuator
/// joints' ranges. Setting up the power-on state (`close_loops`) holds the actuator joints at M q
/// and solves the equality constraints for the passive joints; `check_power_on_state` then
/// checks the loops, the passive joints' ranges and that a joint named like a coupled axis is at
/// that axis' position (so that the coupling matches the model).
///
/// Units: rad for hinge joints, m for slide joints.

#include <cstddef>
#include <filesystem>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include <mujoco/mujoco.h>

#include "mrroc/sim/coupling.hpp"

namespace mrroc::sim {

/// Offset of the default power-on pose from the synchronisation pose on every axis [rad or m].
inline constexpr double kDefaultPowerOnOffset = 0.05;
/// Largest equality-constraint violation accepted after closing the loops at power-on [m or rad].
inline constexpr double kLoopClosureTolerance = 1e-9;
/// Largest coupling error accepted between a coupled axis and the joint of the same name [rad].
inline constexpr double kCouplingTolerance = 1e-6;
/// An equality-constraint violation above this during a simulation is a fault [m or rad].
inline constexpr double kLoopOpenFault = 2e-2;

/// Who speaks in error messages, and the files they are about.
struct ModelContext {
  std::string who;                        ///< message prefix, e.g. "mujoco"
  std::filesystem::path mjcf;             ///< the robot's MJCF file
  std::filesystem::path parameters_file;  ///< its parameters.toml
};

/// The pose q at power-on: given by a configuration, or the default (synchronisation pose +
/// `kDefaultPowerOnOffset` on every axis, clamped into the axis' range).
struct PowerOnRequest {
  std::optional<std::vector<double>> given;  ///< [rad or m]
  SourceLocation given_where;                ///< where the given pose is written
};

/// One robot's axes in a model.
struct RobotAxes {
  std::string prefix;              ///< of the robot's names in the model ("" or "left/")
  std::vector<int> actuator;       ///< actuator id of axis i
  std::vector<int> joint;          ///< actuator joint id of axis i
  std::vector<int> qpos_adr;       ///< of the actuator joint
  std::vector<int> dof_adr;        ///< of the actuator joint
  std::vector<std::string> names;  ///< actuator name (else its joint's) without the prefix
  // Set by plan_power_on():
  Coupling coupling;
  std::vector<int> range_joint;            ///< joint whose range is the axis' range, -1: none
  std::vector<double> synchro;             ///< q at the synchronisation switches
  std::vector<double> power_on;            ///< q at power-on
  std::vector<double> power_on_actuators;  ///< a = M q at power-on

  [[nodiscard]] std::size_t size() const noexcept { return actuator.size(); }
};

/// @throws HardwareError "<who>: model '<mjcf>': joint 'x' is neither a hinge nor a slide joint
///   (only those are supported)" for the first such joint of `joints`.
void check_hinge_or_slide(const mjModel* m, std::span<const int> joints,
                          const ModelContext& context);

/// Maps actuators first .. first+count-1 to axes (each must drive its own joint).
/// @throws HardwareError naming the model and the actuator or joint.
RobotAxes map_axes(const mjModel* m, int first, int count, const std::string& prefix,
                   const ModelContext& context);

/// @throws HardwareError when `joint_names` (robot.joint_names, when listed) differ from the axis
///   names.
void check_axis_names(const RobotAxes& axes,
                      const std::optional<std::vector<std::string>>& joint_names,
                      const ModelContext& context);

/// Sets the coupling, range joints, synchronisation pose and the power-on pose of `axes`
/// (`synchro_source` names where `synchro` comes from, for messages).
/// @throws ConfigError (a given pose: wrong size, not finite, outside a range) at
///   `request.given_where`; HardwareError for the default pose or a synchronisation pose of the
///   wrong size.
void plan_power_on(const mjModel* m, RobotAxes& axes, Coupling coupling,
                   std::vector<double> synchro, const std::string& synchro_source,
                   const PowerOnRequest& request, const ModelContext& context);

/// Closes the model's kinematic loops: with the actuator joints at `actuator_qpos` held at
/// `targets`, moves every other hinge and slide degree of freedom (Gauss-Newton on the equality
/// constraints, in continuation steps from the current state of `d`) until the constraints hold.
/// Returns the remaining violation [m or rad]. Allocates (configuration time only).
double close_loops(const mjModel* m, mjData* d, std::span<const int> actuator_qpos,
                   std::span<const double> targets);

/// Checks the state `d` set up by close_loops() for one robot: `violation` (of the robot's
/// equality constraints) within kLoopClosureTolerance, the robot's passive joints (those of
/// `robot_joints` that no axis drives) inside their ranges, and joints named like coupled axes
/// at those axes' positions.
/// @throws ConfigError (given pose) or HardwareError (default pose, coupling mismatch).
void check_power_on_state(const mjModel* m, const mjData* d, const RobotAxes& axes,
                          std::span<const int> robot_joints, double violation,
                          const PowerOnRequest& request, const ModelContext& context);

}  // namespace mrroc::sim
