#pragma once
/// @file
/// Generic Cartesian kinematics of a serial arm from its URDF alone (no robot-specific code):
/// the kinematics the EDP and ECP use for a robot whose parameters.toml names no solver
/// (`make_arm_kinematics`, include/mrroc/edp/arm_kinematics.hpp), through `KdlSolver`.
///
/// The chain: from the URDF's root link to link `flange` when the URDF has one, else to the child
/// link of the robot's last joint. Its movable joints must be the robot's `joint_names`, in the
/// same order (`find_serial_chain` says why not).
///
/// Frames: tool frame = corrector * FK_model(q) * tool, in the robot base frame [m], as for the
/// stock robots. Kinematic model i is the i-th URDF of `[robot.kinematics] models` (default: the
/// robot's URDF alone); local corrector i (1, 2, ...) is `[robot.kinematics] correctors[i - 1]`.
///
/// Inverse kinematics: `KdlSolver::inverse` (Levenberg-Marquardt seeded with the current joints,
/// then restarts), within the selected model's URDF limits; the solution is then checked against
/// the robot's joint limits (`RobotModel::check_joint_limits`). An unreachable pose is refused
/// with `CommandError` (out_of_limits) naming the target, its distance from the first joint
/// and the arm's reach (`reach()`), and the residual; a solution outside a limit names the joint,
/// the value, the unit and the limit.

#include <cstddef>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Geometry>

#include "mrroc/kinematics/kdl_solver.hpp"
#include "mrroc/robot/robot_model.hpp"

namespace mrroc::kinematics {

/// Links delimiting the serial chain of a robot's joints in its URDF.
struct SerialChain {
  std::string base;  ///< the URDF's root link
  std::string tip;   ///< `flange`, or the child link of the last joint
};

/// The serial chain carrying exactly `model.joint_names` (in order) in `model.urdf`, or nullopt
/// with the reason in `why_not` (file that does not parse, a joint missing, a branch, joints in
/// another order, ...). Does not throw.
std::optional<SerialChain> find_serial_chain(const RobotModel& model, std::string& why_not);

/// The arm's kinematics from its URDF(s). Not thread-safe (the selection of model, corrector and
/// tool is state); `forward` and `inverse` are const.
class UrdfArm {
 public:
  /// @throws ConfigError naming the file when the robot's URDF has no serial chain of its joints
  ///   (the reason), or a kinematic model's URDF has a chain with other joints.
  explicit UrdfArm(const RobotModel& model, KdlSolverOptions options = {});

  [[nodiscard]] const SerialChain& chain() const { return chain_; }
  /// Bound of the tip's distance from the first movable joint's origin (a point of its axis,
  /// fixed in the base frame) over all joint values: the sum of the joint offsets after that
  /// joint, selected model [m].
  [[nodiscard]] double reach() const;

  [[nodiscard]] int model_count() const { return static_cast<int>(solvers_.size()); }
  [[nodiscard]] int corrector_count() const {
    return 1 + static_cast<int>(model_.correctors.size());
  }
  /// @throws CommandError (bad_argument) naming the number and the range.
  void select(int model_no, int corrector_no);

  void set_tool(const Eigen::Isometry3d& tool) { tool_ = tool; }
  [[nodiscard]] const Eigen::Isometry3d& tool() const { return tool_; }

  /// Tool frame of joints `q`. @throws CommandError (bad_argument) for a wrong size or a value
  ///   that is not finite.
  [[nodiscard]] Eigen::Isometry3d forward(const std::vector<double>& q) const;
  /// Joints putting the tool frame at `target`, nearest the configuration `seed`.
  /// @throws CommandError (out_of_limits) when unreachable or outside a joint limit, naming why;
  ///   (bad_argument) for a seed of the wrong size or a target that is not finite.
  [[nodiscard]] std::vector<double> inverse(const Eigen::Isometry3d& target,
                                            const std::vector<double>& seed) const;

 private:
  [[nodiscard]] const KdlSolver& solver() const {
    return solvers_[static_cast<std::size_t>(model_no_)];
  }

  const RobotModel& model_;
  SerialChain chain_;
  std::vector<KdlSolver> solvers_;
  std::vector<double> reach_;                       ///< per model [m]
  std::vector<Eigen::Vector3d> first_axis_origin_;  ///< per model, base frame [m]
  int model_no_ = 0;
  Eigen::Isometry3d corrector_ = Eigen::Isometry3d::Identity();
  Eigen::Isometry3d tool_ = Eigen::Isometry3d::Identity();
};

}  // namespace mrroc::kinematics
