#pragma once
/// @file
/// Generic forward and inverse kinematics of any robot from its URDF, with orocos KDL.
///
/// The URDF is turned into a KDL tree (kdl_parser) and the chain from the `base` link to the
/// `tip` link is taken; its movable joints (revolute, continuous, prismatic; in chain order) are
/// the solver's joints, with the URDF's limits. Units: m and rad.
///
/// Forward kinematics: `ChainFkSolverPos_recursive` (the tip frame in the base frame).
///
/// Inverse kinematics: `ChainIkSolverPos_LMA` (Levenberg-Marquardt on the weighted pose error
/// with task-space weights (1, 1, 1, w, w, w), w = `KdlSolverOptions::orientation_weight` [m/rad]).
/// Being a least-squares method, it also works for arms with fewer than 6 joints (the 5-axis
/// IRb-6) when the requested orientation is reachable; for an unreachable one it ends at the pose
/// of smallest weighted error, which is then refused. A solution is accepted when
///   - the pose residual is within the tolerances (position [m], orientation angle [rad]), and
///   - every joint is inside its URDF limits (a revolute joint is first shifted by whole turns
///     into its limits when that is possible; a continuous joint is shifted by whole turns to be
///     nearest the seed).
/// The first attempt starts at `seed` (normally the current joints, so that the solution is the
/// one nearest the robot's configuration); when it fails, up to `KdlSolverOptions::restarts`
/// further attempts start from fixed pseudo-random joint vectors spread over the joint ranges (the
/// same sequence on every call, so results are reproducible).
///
/// Thread safety: `forward` and `inverse` are const and build their KDL solvers per call, so one
/// KdlSolver may be used from several threads.

#include <cstddef>
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include <Eigen/Geometry>

namespace mrroc::kinematics {

/// Tuning of `KdlSolver::inverse` (defaults suit arms of 0.5 .. 3 m reach).
struct KdlSolverOptions {
  double position_tolerance = 1e-6;     ///< largest accepted position residual [m]
  double orientation_tolerance = 1e-6;  ///< largest accepted orientation residual [rad]
  /// Task-space weight of the rotation error relative to the position error [m/rad].
  double orientation_weight = 0.5;
  int max_iterations = 500;  ///< per attempt
  int restarts = 32;         ///< further attempts from spread seeds after a failed first one
};

class KdlSolver {
 public:
  /// Loads `urdf` and takes the chain from link `base` to link `tip`.
  /// @throws ConfigError naming the file: file missing, URDF that does not parse, KDL tree that
  ///   cannot be built, no chain between the links (the links of the file are listed), a movable
  ///   joint without limits (revolute, prismatic).
  KdlSolver(const std::filesystem::path& urdf, const std::string& base, const std::string& tip,
            KdlSolverOptions options = {});
  ~KdlSolver();
  KdlSolver(KdlSolver&&) noexcept;
  KdlSolver& operator=(KdlSolver&&) noexcept;
  KdlSolver(const KdlSolver&) = delete;
  KdlSolver& operator=(const KdlSolver&) = delete;

  /// Number of movable joints of the chain.
  [[nodiscard]] std::size_t joint_count() const;
  /// Names of the movable joints in chain order.
  [[nodiscard]] const std::vector<std::string>& joint_names() const;
  /// URDF limits [rad or m]; -inf/+inf for continuous joints.
  [[nodiscard]] const std::vector<double>& lower_limits() const;
  [[nodiscard]] const std::vector<double>& upper_limits() const;
  [[nodiscard]] const KdlSolverOptions& options() const;

  /// Tip frame in the base frame.
  /// @throws CommandError (code edp::error_code::bad_argument) when `q` has the wrong size or a
  ///   value that is not finite.
  [[nodiscard]] Eigen::Isometry3d forward(const std::vector<double>& q) const;

  /// Joints that put the tip frame at `target` (in the base frame), starting from `seed`.
  /// @throws CommandError (code edp::error_code::out_of_limits) when no attempt converged:
  ///   "inverse kinematics did not converge: residual 0.532000 m, 0.120000 rad (tolerance 1e-06 m,
  ///   1e-06 rad; 9 attempts)", or when every converged solution leaves the joint limits:
  ///   "inverse kinematics: solution outside the joint limits: joint 2 (elbow) 1.523000 rad exceeds
  ///   upper limit 1.221730 rad"; (code bad_argument) for a seed of the wrong size or a value that
  ///   is not finite.
  [[nodiscard]] std::vector<double> inverse(const Eigen::Isometry3d& target,
                                            const std::vector<double>& seed) const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace mrroc::kinematics
