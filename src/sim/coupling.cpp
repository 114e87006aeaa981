#include "mrroc/sim/coupling.hpp"

#include <Eigen/Dense>

#include "mrroc/core/error.hpp"
#include "mrroc/sim/mujoco_support.hpp"

namespace mrroc::sim {
namespace {

using RowMatrix = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

/// y = matrix x; a plain copy for the identity (exact, also for non-finite values).
void multiply(const std::vector<double>& matrix, bool identity, std::size_t n, const double* x,
              double* y) noexcept {
  if (identity) {
    for (std::size_t i = 0; i < n; ++i) y[i] = x[i];
    return;
  }
  for (std::size_t r = 0; r < n; ++r) {
    double sum = 0.0;
    for (std::size_t c = 0; c < n; ++c) sum += matrix[r * n + c] * x[c];
    y[r] = sum;
  }
}

}  // namespace

Coupling::Coupling(std::size_t axes)
    : axes_(axes), matrix_(axes * axes, 0.0), inverse_(axes * axes, 0.0) {
  for (std::size_t i = 0; i < axes; ++i) {
    matrix_[i * axes + i] = 1.0;
    inverse_[i * axes + i] = 1.0;
  }
}

Coupling Coupling::from_parameters(const RobotParameters& parameters, std::size_t axes,
                                   const std::filesystem::path& model) {
  Coupling out(axes);
  if (!parameters.coupling) return out;
  const auto& rows = *parameters.coupling;
  bool square = rows.size() == axes;
  for (const auto& row : rows) square = square && row.size() == axes;
  if (!square) {
    throw ConfigError(parameters.coupling_where,
                      "robot.transmission.coupling must be a " + std::to_string(axes) + " x " +
                          std::to_string(axes) +
                          " matrix (one row and one column per actuator of " + quoted(model) + ")");
  }
  const auto n = static_cast<Eigen::Index>(axes);
  RowMatrix m(n, n);
  for (Eigen::Index r = 0; r < n; ++r)
    for (Eigen::Index c = 0; c < n; ++c)
      m(r, c) = rows[static_cast<std::size_t>(r)][static_cast<std::size_t>(c)];
  const Eigen::JacobiSVD<Eigen::MatrixXd> svd(m);
  const Eigen::VectorXd singular = svd.singularValues();
  const double rcond = singular(singular.size() - 1) / singular(0);
  if (!(rcond > 1e-9)) {
    throw ConfigError(parameters.coupling_where,
                      "robot.transmission.coupling is singular (smallest / largest "
                      "singular value " +
                          format_number(rcond) + "): joints cannot be computed from the actuators");
  }
  const RowMatrix inverse = m.inverse();
  out.coupled_ = !m.isIdentity(0.0);
  out.matrix_.assign(m.data(), m.data() + m.size());
  out.inverse_.assign(inverse.data(), inverse.data() + inverse.size());
  return out;
}

bool Coupling::unit_row(std::size_t axis) const noexcept {
  for (std::size_t c = 0; c < axes_; ++c)
    if (matrix_[axis * axes_ + c] != (c == axis ? 1.0 : 0.0)) return false;
  return true;
}

void Coupling::actuators_from_joints(const double* q, double* a) const noexcept {
  multiply(matrix_, !coupled_, axes_, q, a);
}

void Coupling::joints_from_actuators(const double* a, double* q) const noexcept {
  multiply(inverse_, !coupled_, axes_, a, q);
}

double Coupling::joint_from_actuators(const double* a, std::size_t axis) const noexcept {
  if (!coupled_) return a[axis];
  double sum = 0.0;
  for (std::size_t c = 0; c < axes_; ++c) sum += inverse_[axis * axes_ + c] * a[c];
  return sum;
}

}  // namespace mrroc::sim
