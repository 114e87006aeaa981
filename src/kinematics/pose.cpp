#include "mrroc/kinematics/pose.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <numbers>

#include <Eigen/SVD>

#include "mrroc/core/error.hpp"

namespace mrroc::kinematics {

namespace {

constexpr double kPi = std::numbers::pi;

// |w| of the unit quaternion below which the rotation angle counts as pi (w = cos(angle / 2),
// so this is an angle within 1e-13 rad of pi) and the axis sign is made canonical.
constexpr double kHalfTurnQuaternionW = 5e-14;

constexpr std::array<const char*, kFrameValues> kFrameNames = {
    "r00", "r01", "r02", "x", "r10", "r11", "r12", "y", "r20", "r21", "r22", "z"};
constexpr std::array<const char*, kXyzEulerZyzValues> kEulerNames = {"x",     "y",    "z",
                                                                     "alpha", "beta", "gamma"};
constexpr std::array<const char*, kXyzAngleAxisValues> kAngleAxisNames = {"x",  "y",  "z",
                                                                          "rx", "ry", "rz"};

[[noreturn]] void bad_argument(const std::string& text) {
  throw CommandError(edp::error_code::bad_argument, text);
}

// Maps an angle from atan2 ([-pi, pi]) into (-pi, pi].
double half_open(double angle) { return angle <= -kPi ? angle + 2.0 * kPi : angle; }

void check_finite(std::span<const double> values, const char* representation,
                  std::span<const char* const> names) {
  for (std::size_t i = 0; i < values.size(); ++i) {
    if (!std::isfinite(values[i]))
      bad_argument(fmt::format("{} value {} ({}) is not a finite number: {}", representation, i,
                               names[i], values[i]));
  }
}

void check_size(std::size_t got, edp::ArmRepresentation representation) {
  const std::size_t expected = representation_size(representation);
  if (got != expected)
    bad_argument(
        fmt::format("{} needs {} values, got {}", edp::to_string(representation), expected, got));
}

}  // namespace

std::array<double, kFrameValues> frame_to_values(const Eigen::Isometry3d& frame) {
  std::array<double, kFrameValues> out{};
  for (Eigen::Index row = 0; row < 3; ++row) {
    for (Eigen::Index col = 0; col < 4; ++col) {
      out[static_cast<std::size_t>(4 * row + col)] = frame.matrix()(row, col);
    }
  }
  return out;
}

Eigen::Matrix3d checked_rotation(const Eigen::Matrix3d& rotation, double tolerance,
                                 const char* what) {
  if (!rotation.allFinite()) bad_argument(fmt::format("{} is not finite", what));
  const double orthonormality =
      (rotation.transpose() * rotation - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff();
  if (!(orthonormality <= tolerance))
    bad_argument(
        fmt::format("{} is not orthonormal: max |R^T R - I| = {:.3g} exceeds the "
                    "tolerance {:.3g}",
                    what, orthonormality, tolerance));
  const double det = rotation.determinant();
  if (!(std::abs(det - 1.0) <= tolerance))
    bad_argument(fmt::format("{} is not a rotation: det R = {:.6g} (must be 1 within {:.3g}{})",
                             what, det, tolerance, det < 0.0 ? "; a reflection" : ""));
  // Nearest rotation matrix in the Frobenius norm: U V^T of the SVD (det > 0 was checked).
  const Eigen::JacobiSVD<Eigen::Matrix3d> svd(rotation, Eigen::ComputeFullU | Eigen::ComputeFullV);
  return svd.matrixU() * svd.matrixV().transpose();
}

Eigen::Isometry3d frame_from_values(std::span<const double> values, double tolerance) {
  check_size(values.size(), edp::ArmRepresentation::frame);
  check_finite(values, "FRAME", kFrameNames);
  Eigen::Matrix3d rotation;
  Eigen::Vector3d translation;
  for (Eigen::Index row = 0; row < 3; ++row) {
    for (Eigen::Index col = 0; col < 3; ++col) {
      rotation(row, col) = values[static_cast<std::size_t>(4 * row + col)];
    }
    translation(row) = values[static_cast<std::size_t>(4 * row + 3)];
  }
  Eigen::Isometry3d frame = Eigen::Isometry3d::Identity();
  frame.linear() = checked_rotation(rotation, tolerance, "FRAME rotation");
  frame.translation() = translation;
  return frame;
}

Eigen::Vector3d euler_zyz_from_rotation(const Eigen::Matrix3d& r) {
  // R = Rz(a) Ry(b) Rz(g): third column = (ca sb, sa sb, cb).
  const double sin_beta = std::hypot(r(0, 2), r(1, 2));
  const bool singular = sin_beta < kEulerSingularity;
  // Singular: beta is exactly 0 or pi (an error of at most kEulerSingularity), alpha = 0.
  const double beta = singular ? (r(2, 2) > 0.0 ? 0.0 : kPi) : std::atan2(sin_beta, r(2, 2));
  const double alpha = singular ? 0.0 : std::atan2(r(1, 2), r(0, 2));
  // gamma from Rz(-alpha) R = Ry(b) Rz(g), whose second row is (sg, cg, 0). Its entries are O(1),
  // so gamma stays consistent with the alpha actually chosen even when sin(beta) is tiny and alpha
  // itself is poorly determined; the product Rz(alpha) Ry(beta) Rz(gamma) stays accurate.
  const double ca = std::cos(alpha);
  const double sa = std::sin(alpha);
  const double gamma = std::atan2(-sa * r(0, 0) + ca * r(1, 0), -sa * r(0, 1) + ca * r(1, 1));
  return {half_open(alpha), beta, half_open(gamma)};
}

Eigen::Matrix3d rotation_from_euler_zyz(const Eigen::Vector3d& abg) {
  const double ca = std::cos(abg(0));
  const double sa = std::sin(abg(0));
  const double cb = std::cos(abg(1));
  const double sb = std::sin(abg(1));
  const double cg = std::cos(abg(2));
  const double sg = std::sin(abg(2));
  Eigen::Matrix3d r;
  r << ca * cb * cg - sa * sg, -ca * cb * sg - sa * cg, ca * sb,  //
      sa * cb * cg + ca * sg, -sa * cb * sg + ca * cg, sa * sb,   //
      -sb * cg, sb * sg, cb;
  return r;
}

Eigen::Vector3d rotation_vector_from_rotation(const Eigen::Matrix3d& rotation) {
  const Eigen::Quaterniond q(rotation);  // Shepperd's method: robust for every angle
  double w = q.w();
  Eigen::Vector3d v = q.vec();
  if (w < 0.0) {
    w = -w;
    v = -v;
  }
  const double n = v.norm();
  if (n == 0.0) return Eigen::Vector3d::Zero();
  // atan2 keeps full relative accuracy near 0 (no 1 - cos cancellation) and near pi.
  const double angle = 2.0 * std::atan2(n, w);
  Eigen::Vector3d axis = v / n;
  if (w < kHalfTurnQuaternionW) {
    for (Eigen::Index i = 0; i < 3; ++i) {
      if (std::abs(axis(i)) > kAxisSignThreshold) {
        if (axis(i) < 0.0) axis = -axis;
        break;
      }
    }
  }
  return axis * angle;
}

Eigen::Matrix3d rotation_from_rotation_vector(const Eigen::Vector3d& rotation_vector) {
  const double angle = rotation_vector.norm();
  if (angle == 0.0) return Eigen::Matrix3d::Identity();
  return Eigen::AngleAxisd(angle, rotation_vector / angle).toRotationMatrix();
}

double rotation_distance(const Eigen::Matrix3d& a, const Eigen::Matrix3d& b) {
  const Eigen::Quaterniond q(a.transpose() * b);
  return 2.0 * std::atan2(q.vec().norm(), std::abs(q.w()));
}

std::size_t representation_size(edp::ArmRepresentation representation) {
  switch (representation) {
    case edp::ArmRepresentation::frame: return kFrameValues;
    case edp::ArmRepresentation::xyz_euler_zyz: return kXyzEulerZyzValues;
    case edp::ArmRepresentation::xyz_angle_axis: return kXyzAngleAxisValues;
    case edp::ArmRepresentation::joint:
    case edp::ArmRepresentation::motor: break;
  }
  bad_argument(
      fmt::format("{} is not a Cartesian representation (expected FRAME, "
                  "XYZ_EULER_ZYZ or XYZ_ANGLE_AXIS)",
                  edp::to_string(representation)));
}

void to_values(const Eigen::Isometry3d& frame, edp::ArmRepresentation representation,
               std::span<double> out) {
  check_size(out.size(), representation);
  if (representation == edp::ArmRepresentation::frame) {
    const auto values = frame_to_values(frame);
    std::copy(values.begin(), values.end(), out.begin());
    return;
  }
  const Eigen::Vector3d p = frame.translation();
  const Eigen::Vector3d r = representation == edp::ArmRepresentation::xyz_euler_zyz
                                ? euler_zyz_from_rotation(frame.linear())
                                : rotation_vector_from_rotation(frame.linear());
  out[0] = p(0);
  out[1] = p(1);
  out[2] = p(2);
  out[3] = r(0);
  out[4] = r(1);
  out[5] = r(2);
}

Eigen::Isometry3d from_values(std::span<const double> values,
                              edp::ArmRepresentation representation) {
  check_size(values.size(), representation);
  if (representation == edp::ArmRepresentation::frame) return frame_from_values(values);
  const bool euler = representation == edp::ArmRepresentation::xyz_euler_zyz;
  check_finite(values, edp::to_string(representation),
               euler ? std::span<const char* const>(kEulerNames)
                     : std::span<const char* const>(kAngleAxisNames));
  const Eigen::Vector3d r(values[3], values[4], values[5]);
  Eigen::Isometry3d frame = Eigen::Isometry3d::Identity();
  frame.linear() = euler ? rotation_from_euler_zyz(r) : rotation_from_rotation_vector(r);
  frame.translation() = Eigen::Vector3d(values[0], values[1], values[2]);
  return frame;
}

std::vector<double> to_vector(const Eigen::Isometry3d& frame,
                              edp::ArmRepresentation representation) {
  std::vector<double> out(representation_size(representation));
  to_values(frame, representation, out);
  return out;
}

Eigen::Isometry3d from_vector(const std::vector<double>& values,
                              edp::ArmRepresentation representation) {
  return from_values(std::span<const double>(values), representation);
}

Eigen::Isometry3d compose_relative(const Eigen::Isometry3d& base, const Eigen::Isometry3d& delta) {
  return base * delta;
}

}  // namespace mrroc::kinematics
