#pragma once
/// @file
/// The linear coupling between a robot's joint coordinates q (the serial-equivalent chain of its
/// URDF) and the positions a of its actuator joints (what the motors drive): a = M q, with M an
/// n x n invertible matrix (n = number of axes; identity unless `[robot.transmission] coupling`
/// of parameters.toml declares one). Velocities transform the same way. Example (RNT
/// parallelogram): the elbow drive turns the absolute forearm angle a2 = q1 + q2.

#include <cstddef>
#include <filesystem>
#include <vector>

#include "mrroc/sim/robot_parameters.hpp"

namespace mrroc::sim {

class Coupling {
 public:
  /// No axes.
  Coupling() = default;
  /// The identity on n axes.
  explicit Coupling(std::size_t axes);

  /// M from `parameters.coupling` (identity when absent).
  /// @throws ConfigError at `parameters.coupling_where` when M is not axes x axes ("must be a
  ///   6 x 6 matrix (one row and one column per actuator of 'model')") or is singular.
  static Coupling from_parameters(const RobotParameters& parameters, std::size_t axes,
                                  const std::filesystem::path& model);

  [[nodiscard]] std::size_t axes() const noexcept { return axes_; }
  /// M, row-major axes x axes.
  [[nodiscard]] const std::vector<double>& matrix() const noexcept { return matrix_; }
  /// M^-1, row-major axes x axes.
  [[nodiscard]] const std::vector<double>& inverse() const noexcept { return inverse_; }
  /// True when M is not the identity.
  [[nodiscard]] bool coupled() const noexcept { return coupled_; }
  /// True when row `axis` of M is the unit row (actuator joint `axis` is joint `axis`).
  [[nodiscard]] bool unit_row(std::size_t axis) const noexcept;

  /// a = M q. `q` and `a` hold axes() values each and must not overlap. No allocation.
  void actuators_from_joints(const double* q, double* a) const noexcept;
  /// q = M^-1 a. `a` and `q` hold axes() values each and must not overlap. No allocation.
  void joints_from_actuators(const double* a, double* q) const noexcept;
  /// q_axis = (M^-1 a)_axis. No allocation.
  [[nodiscard]] double joint_from_actuators(const double* a, std::size_t axis) const noexcept;

 private:
  std::size_t axes_ = 0;
  bool coupled_ = false;
  std::vector<double> matrix_;
  std::vector<double> inverse_;
};

}  // namespace mrroc::sim
