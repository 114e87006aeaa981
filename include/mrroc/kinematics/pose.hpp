#pragma once
/// @file
/// Conversions between a Cartesian frame (`Eigen::Isometry3d`) and the arm/tool representations
/// of EDP instructions and replies (`edp::ArmRepresentation`), and relative motion.
///
/// Units: positions in m, angles in rad. A frame maps coordinates in the child frame (end
/// effector, tool) to coordinates in the parent frame (base, flange): p_parent = R p_child + t.
///
/// Canonical outputs (what `to_vector` / `*_from_rotation` return):
/// - FRAME: the 3x4 matrix [R | p] row by row: r00 r01 r02 px r10 r11 r12 py r20 r21 r22 pz.
/// - XYZ_EULER_ZYZ: x y z alpha beta gamma with R = Rz(alpha) Ry(beta) Rz(gamma),
///   beta in [0, pi], alpha and gamma in (-pi, pi]. At the singular cases (sin beta below
///   `kEulerSingularity`) beta is exactly 0 or pi, alpha = 0 and the whole rotation about z is in
///   gamma: beta = 0 gives R = Rz(gamma); beta = pi gives R = Ry(pi) Rz(gamma) = Rz(-gamma) Ry(pi).
///   (So (a, 0, g) comes back as (0, 0, a + g) and (a, pi, g) as (0, pi, g - a), wrapped.)
/// - XYZ_ANGLE_AXIS: x y z rx ry rz, the rotation vector axis * angle with angle in [0, pi];
///   angle 0 gives the zero vector. At angle pi (axis and -axis are the same rotation; applied when
///   the angle is within about 1e-13 rad of pi) the sign is canonical: the first of the axis
///   components x, y, z whose magnitude exceeds `kAxisSignThreshold` is positive.
///
/// Inputs are accepted more widely: any finite Euler angles and any finite rotation vector (also
/// with an angle above pi); a FRAME's rotation must be orthonormal within a tolerance and is then
/// projected onto the nearest rotation matrix.

#include <array>
#include <cstddef>
#include <span>
#include <vector>

#include <Eigen/Geometry>

#include "mrroc/msg/edp_instruction.hpp"

namespace mrroc::kinematics {

/// Largest accepted |R^T R - I| entry (and |det R - 1|) of a FRAME given as 12 values.
inline constexpr double kRotationTolerance = 1e-6;
/// sin(beta) below which the Euler Z-Y-Z extraction treats beta as 0 or pi (alpha = 0).
inline constexpr double kEulerSingularity = 1e-12;
/// Axis components with a magnitude up to this do not decide the canonical sign at angle pi.
inline constexpr double kAxisSignThreshold = 1e-9;

inline constexpr std::size_t kFrameValues = 12;        ///< FRAME
inline constexpr std::size_t kXyzEulerZyzValues = 6;   ///< XYZ_EULER_ZYZ
inline constexpr std::size_t kXyzAngleAxisValues = 6;  ///< XYZ_ANGLE_AXIS

/// The 12 values of a frame: [R | p] row by row.
std::array<double, kFrameValues> frame_to_values(const Eigen::Isometry3d& frame);

/// A frame from 12 values [R | p] row by row. The rotation part is checked (finite,
/// max |R^T R - I| <= tolerance, |det R - 1| <= tolerance) and then projected onto the nearest
/// rotation matrix (polar decomposition), so the result is orthonormal to machine precision.
/// @throws CommandError (code edp::error_code::bad_argument) naming the problem and the value:
///   wrong number of values, a value that is not finite, a rotation that is not orthonormal or
///   is a reflection.
Eigen::Isometry3d frame_from_values(std::span<const double> values,
                                    double tolerance = kRotationTolerance);

/// Checks that `rotation` is a rotation matrix within `tolerance` and returns the nearest exact
/// rotation matrix. `what` names the quantity in the error text.
/// @throws CommandError (code edp::error_code::bad_argument) as `frame_from_values`.
Eigen::Matrix3d checked_rotation(const Eigen::Matrix3d& rotation,
                                 double tolerance = kRotationTolerance,
                                 const char* what = "frame rotation");

/// Euler Z-Y-Z angles (alpha, beta, gamma) [rad] of a rotation matrix, canonical as described in
/// the file comment: beta in [0, pi], alpha and gamma in (-pi, pi], alpha = 0 when singular.
/// Precondition: `rotation` is orthonormal.
Eigen::Vector3d euler_zyz_from_rotation(const Eigen::Matrix3d& rotation);

/// R = Rz(alpha) Ry(beta) Rz(gamma) for any angles [rad].
Eigen::Matrix3d rotation_from_euler_zyz(const Eigen::Vector3d& alpha_beta_gamma);

/// The rotation vector axis * angle [rad], angle in [0, pi], canonical as described in the file
/// comment. Extraction goes through the quaternion (Shepperd's method), so it is accurate near
/// angle 0 and near angle pi. Precondition: `rotation` is orthonormal.
Eigen::Vector3d rotation_vector_from_rotation(const Eigen::Matrix3d& rotation);

/// The rotation by |v| [rad] about v / |v|; the identity for v = 0.
Eigen::Matrix3d rotation_from_rotation_vector(const Eigen::Vector3d& rotation_vector);

/// Geodesic distance between two rotations: the angle [rad, 0..pi] of a^T b.
double rotation_distance(const Eigen::Matrix3d& a, const Eigen::Matrix3d& b);

/// Number of values of a Cartesian representation: 12 (FRAME), 6 (XYZ_EULER_ZYZ,
/// XYZ_ANGLE_AXIS).
/// @throws CommandError (code edp::error_code::bad_argument) for JOINT and MOTOR.
std::size_t representation_size(edp::ArmRepresentation representation);

/// Writes the canonical values of `frame` in `representation` to `out` (no allocation).
/// @throws CommandError (code edp::error_code::bad_argument) for JOINT/MOTOR or when `out` does
///   not have exactly `representation_size(representation)` elements.
void to_values(const Eigen::Isometry3d& frame, edp::ArmRepresentation representation,
               std::span<double> out);

/// The frame given by `values` in `representation` (no allocation).
/// @throws CommandError (code edp::error_code::bad_argument) for JOINT/MOTOR, a wrong number of
///   values (the text names the expected size), a value that is not finite, or (FRAME) a
///   rotation that is not orthonormal within `kRotationTolerance`.
Eigen::Isometry3d from_values(std::span<const double> values,
                              edp::ArmRepresentation representation);

/// `to_values` into a new vector of `representation_size(representation)` elements.
/// @throws CommandError (code edp::error_code::bad_argument) for JOINT/MOTOR.
std::vector<double> to_vector(const Eigen::Isometry3d& frame,
                              edp::ArmRepresentation representation);

/// `from_values` of a vector. @throws CommandError as `from_values`.
Eigen::Isometry3d from_vector(const std::vector<double>& values,
                              edp::ArmRepresentation representation);

/// The goal of a RELATIVE Cartesian command: `base * delta`. A relative command is expressed in
/// the current end-effector frame (`base`): `delta`'s translation is along the end effector's own
/// axes and its rotation is about axes through the end-effector origin, in end-effector
/// coordinates. (An ABSOLUTE command is `delta` itself, in the base frame.)
Eigen::Isometry3d compose_relative(const Eigen::Isometry3d& base, const Eigen::Isometry3d& delta);

}  // namespace mrroc::kinematics
