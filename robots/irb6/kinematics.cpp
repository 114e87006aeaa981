#include <fmt/format.h>
#include <fmt/ranges.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <string>

#include "mrroc/core/error.hpp"
#include "mrroc/kinematics/irb6.hpp"
#include "mrroc/msg/edp_instruction.hpp"
#include "mrroc/robot/robot_model.hpp"

namespace mrroc::robots::irb6 {

namespace {

constexpr double kPi = std::numbers::pi;
constexpr double kHalfPi = std::numbers::pi / 2;

// Horizontal distance [m] below which a point counts as on the column axis.
constexpr double kOnColumnAxis = 1e-9;
// Slack on |cos(elbow)| <= 1 for round-off at full stretch.
constexpr double kElbowSlack = 1e-12;

[[noreturn]] void out_of_limits(const std::string& text) {
  throw CommandError(edp::error_code::out_of_limits, text);
}
[[noreturn]] void bad_argument(const std::string& text) {
  throw CommandError(edp::error_code::bad_argument, text);
}

// Shortest round-trip text of a number, always with a decimal point: 101.2, 100.0, 1e+20.
std::string number(double x) {
  std::string s = fmt::format("{}", x);
  if (s.find_first_of(".eEn") == std::string::npos) s += ".0";
  return s;
}

// Maps an angle into (-pi, pi].
double wrap(double angle) {
  const double r = std::remainder(angle, 2.0 * kPi);
  return r <= -kPi ? r + 2.0 * kPi : r;
}

// A ball-screw linkage with the constants derived from its figures.
struct Screw {
  const ScrewLinkage* figures;
  const char* name;           // "lower-arm" / "upper-arm"
  const char* fed_angle;      // "q1" / "q1 + q2 + pi/2"
  std::size_t axis;           // 1 / 2
  double radius;              // hypot(mu, nu) [mm^2]
  double phase;               // atan2(nu, mu) [rad]
  double synchro_fed_angle;   // fed angle at the synchronisation pose [rad]
  double triangle_at_l0;      // triangle angle for l0 [rad]
  double length_at_triangle;  // triangle length at triangle_at_l0 (= l0 up to round-off) [mm]

  // l^2 = s + mu cos(t) + nu sin(-t) = s + radius cos(t + phase); the solution used has
  // t + phase in [-pi, 0], where l grows with t.
  [[nodiscard]] double triangle_angle(double cosine) const { return -phase - std::acos(cosine); }
  [[nodiscard]] double triangle_length(double t) const {
    const ScrewLinkage& f = *figures;
    return std::sqrt(f.s + f.mu * std::cos(t) + f.nu * std::sin(-t));
  }
};

Screw make_screw(const ScrewLinkage& f, const char* name, const char* fed_angle, std::size_t axis,
                 double synchro_fed_angle) {
  Screw s{
      &f,  name, fed_angle, axis, std::hypot(f.mu, f.nu), std::atan2(f.nu, f.mu), synchro_fed_angle,
      0.0, 0.0};
  s.triangle_at_l0 = s.triangle_angle((f.synchro_length * f.synchro_length - f.s) / s.radius);
  s.length_at_triangle = s.triangle_length(s.triangle_at_l0);
  return s;
}

const Screw& lower_screw() {
  static const Screw screw =
      make_screw(kLowerArmScrew, "lower-arm", "q1", 1, kSynchroJointPositions[1]);
  return screw;
}
const Screw& upper_screw() {
  static const Screw screw =
      make_screw(kUpperArmScrew, "upper-arm", "q1 + q2 + pi/2", 2,
                 kSynchroJointPositions[1] + kSynchroJointPositions[2] + kHalfPi);
  return screw;
}

constexpr double kMmPerMotorRad = kScrewLead / (2.0 * kPi);

// Fed angle [rad] from the motor position; checks the triangle and the linkage range.
double fed_angle_from_motor(const Screw& screw, double motor) {
  const ScrewLinkage& f = *screw.figures;
  const double length =
      (motor - kSynchroMotorPositions[screw.axis]) * kMmPerMotorRad + f.synchro_length;
  const double cosine = (length * length - f.s) / screw.radius;
  if (!(length > 0.0 && cosine >= -1.0 && cosine <= 1.0))
    out_of_limits(fmt::format(
        "motor {} ({}) position {} rad: ball-screw length {:.3f} mm has no linkage triangle "
        "solution (the {} linkage spans {:.3f} .. {:.3f} mm)",
        screw.axis, kJointNames[screw.axis], number(motor), length, screw.name,
        std::sqrt(f.s - screw.radius), std::sqrt(f.s + screw.radius)));
  // Offsets relative to l0 make the synchronisation position exact.
  const double angle =
      screw.synchro_fed_angle + (screw.triangle_angle(cosine) - screw.triangle_at_l0);
  if (angle < f.min_angle || angle > f.max_angle)
    out_of_limits(fmt::format(
        "motor {} ({}) position {} rad gives {} = {:.6f} rad, {} the {} linkage limit {:.6f} rad",
        screw.axis, kJointNames[screw.axis], number(motor), screw.fed_angle, angle,
        angle < f.min_angle ? "below" : "above", screw.name,
        angle < f.min_angle ? f.min_angle : f.max_angle));
  return angle;
}

// Checks a fed angle against the linkage range, naming the joint.
void check_linkage(const Screw& screw, double angle, const char* what) {
  const ScrewLinkage& f = *screw.figures;
  if (angle < f.min_angle)
    out_of_limits(fmt::format(
        "joint {} ({}) {}: {} = {:.6f} rad is below the {} linkage limit {:.6f} rad", screw.axis,
        kJointNames[screw.axis], what, screw.fed_angle, angle, screw.name, f.min_angle));
  if (angle > f.max_angle)
    out_of_limits(fmt::format(
        "joint {} ({}) {}: {} = {:.6f} rad exceeds the {} linkage limit {:.6f} rad", screw.axis,
        kJointNames[screw.axis], what, screw.fed_angle, angle, screw.name, f.max_angle));
}

double motor_from_fed_angle(const Screw& screw, double angle) {
  const double triangle = screw.triangle_at_l0 + (angle - screw.synchro_fed_angle);
  return kSynchroMotorPositions[screw.axis] +
         (screw.triangle_length(triangle) - screw.length_at_triangle) / kMmPerMotorRad;
}

// Solutions this close outside a joint limit are put onto it (round-off of targets at a limit).
constexpr double kLimitRoundOff = 1e-9;

// Puts joints within kLimitRoundOff of a limit onto it; false if a joint or linkage limit is
// exceeded by more.
bool within_limits(JointPosition& q) {
  for (std::size_t i = 0; i < kAxes; ++i) {
    if (!(q[i] >= kJointLowerLimits[i] - kLimitRoundOff &&
          q[i] <= kJointUpperLimits[i] + kLimitRoundOff))
      return false;
    q[i] = std::clamp(q[i], kJointLowerLimits[i], kJointUpperLimits[i]);
  }
  const double upper_fed = q[1] + q[2] + kHalfPi;
  return q[1] >= kLowerArmScrew.min_angle && q[1] <= kLowerArmScrew.max_angle &&
         upper_fed >= kUpperArmScrew.min_angle && upper_fed <= kUpperArmScrew.max_angle;
}

// The flange frame turned (about the pivot) so that its approach lies in the arm plane.
struct PlaneProjection {
  Eigen::Isometry3d flange;
  double deviation;
};

PlaneProjection project_to_arm_plane(const Eigen::Isometry3d& flange, const JointPosition& seed,
                                     double pivot) {
  const Eigen::Matrix3d& rotation = flange.linear();
  const Eigen::Vector3d approach = rotation.col(2);
  const Eigen::Vector3d pivot_point = flange.translation() + pivot * approach;

  // Normal of the arm plane (horizontal): from the pivot, else from the approach, else the seed.
  Eigen::Vector3d normal;
  const double pivot_off_axis = std::hypot(pivot_point.x(), pivot_point.y());
  const double approach_horizontal = std::hypot(approach.x(), approach.y());
  if (pivot_off_axis > kOnColumnAxis) {
    normal = Eigen::Vector3d(-pivot_point.y(), pivot_point.x(), 0.0) / pivot_off_axis;
  } else if (approach_horizontal > kOnColumnAxis) {
    normal = Eigen::Vector3d(-approach.y(), approach.x(), 0.0) / approach_horizontal;
  } else {
    normal = Eigen::Vector3d(-std::sin(seed[0]), std::cos(seed[0]), 0.0);
  }

  const double across = approach.dot(normal);
  if (across == 0.0) return {flange, 0.0};
  Eigen::Vector3d in_plane = approach - across * normal;
  const double along = in_plane.norm();
  const double deviation = std::atan2(std::abs(across), along);
  if (along < 1e-12) {
    // Approach perpendicular to the plane: every in-plane direction is equally near; take the
    // seed's approach (projected), or straight down.
    const double seed_pitch = seed[1] + seed[2] + kHalfPi + seed[3];
    const Eigen::Vector3d seed_approach(std::cos(seed[0]) * std::cos(seed_pitch),
                                        std::sin(seed[0]) * std::cos(seed_pitch),
                                        -std::sin(seed_pitch));
    in_plane = seed_approach - seed_approach.dot(normal) * normal;
    if (in_plane.norm() < 1e-12) in_plane = -Eigen::Vector3d::UnitZ();
  }
  const Eigen::Vector3d target_approach = in_plane.normalized();
  const Eigen::Quaterniond turn = Eigen::Quaterniond::FromTwoVectors(approach, target_approach);
  Eigen::Isometry3d projected = Eigen::Isometry3d::Identity();
  projected.linear() = turn.toRotationMatrix() * rotation;
  projected.translation() = pivot_point - pivot * target_approach;
  return {projected, deviation};
}

// Joints for a flange frame whose approach lies in the plane of column angle q0, with the elbow
// on the given side (+1: the IRb-6's, q2 + pi/2 in (0, pi)). False if the wrist centre is out of
// reach.
bool solve_in_plane(const Eigen::Isometry3d& flange, const Irb6Geometry& g, double q0,
                    double elbow_side, JointPosition& q, double& wrist_distance) {
  const Eigen::Matrix3d& r = flange.linear();
  const Eigen::Vector3d approach = r.col(2);
  const Eigen::Vector3d wrist = flange.translation() - g.d5 * approach;
  const double c0 = std::cos(q0);
  const double s0 = std::sin(q0);
  // Wrist centre in the arm plane: x forward from the column axis, y down from the lower-arm
  // axis, so that (x, y) = a2 (cos t1, sin t1) + a3 (cos t2, sin t2).
  const double x = c0 * wrist.x() + s0 * wrist.y();
  const double y = g.d1 - wrist.z();
  wrist_distance = std::hypot(x, y);
  const double cos_elbow = (x * x + y * y - g.a2 * g.a2 - g.a3 * g.a3) / (2.0 * g.a2 * g.a3);
  if (!(std::abs(cos_elbow) <= 1.0 + kElbowSlack)) return false;
  const double elbow = elbow_side * std::acos(std::clamp(cos_elbow, -1.0, 1.0));  // t2 - t1
  const double t1 =
      std::atan2(y, x) - std::atan2(g.a3 * std::sin(elbow), g.a2 + g.a3 * std::cos(elbow));
  const double t2 = t1 + elbow;
  const double t3 = std::atan2(-approach.z(), c0 * approach.x() + s0 * approach.y());
  // R = Rz(q0) Ry(t3) Rx(q4) Ry(pi/2): the second row of Rz(-q0) R is (sin q4, cos q4, 0).
  const double roll = std::atan2(-s0 * r(0, 0) + c0 * r(1, 0), -s0 * r(0, 1) + c0 * r(1, 1));
  q = {wrap(q0), wrap(t1), wrap(elbow - kHalfPi), wrap(t3 - t2), wrap(roll)};
  return true;
}

JointPosition solve(const Eigen::Isometry3d& flange, const JointPosition& seed,
                    const Irb6Geometry& g) {
  const Eigen::Vector3d wrist = flange.translation() - g.d5 * flange.linear().col(2);
  const double wrist_off_axis = std::hypot(wrist.x(), wrist.y());
  const double azimuth =
      wrist_off_axis > kOnColumnAxis ? std::atan2(wrist.y(), wrist.x()) : seed[0];
  struct Choice {
    double q0;
    double elbow_side;
  };
  // The first one is the IRb-6's configuration (wrist centre in front, elbow as in the model).
  const std::array<Choice, 4> choices = {
      {{azimuth, 1.0}, {azimuth, -1.0}, {wrap(azimuth + kPi), 1.0}, {wrap(azimuth + kPi), -1.0}}};
  JointPosition best{};
  double best_distance = std::numeric_limits<double>::infinity();
  JointPosition primary{};
  double wrist_distance = 0.0;
  bool primary_reachable = false;
  for (std::size_t i = 0; i < choices.size(); ++i) {
    JointPosition q{};
    double distance_to_axis = 0.0;
    const bool reachable =
        solve_in_plane(flange, g, choices[i].q0, choices[i].elbow_side, q, distance_to_axis);
    if (i == 0) {
      primary = q;
      primary_reachable = reachable;
      wrist_distance = distance_to_axis;
    }
    if (!reachable || !within_limits(q)) continue;
    double distance = 0.0;
    for (std::size_t j = 0; j < kAxes; ++j) distance += (q[j] - seed[j]) * (q[j] - seed[j]);
    if (distance < best_distance) {
      best_distance = distance;
      best = q;
    }
  }
  if (best_distance < std::numeric_limits<double>::infinity()) return best;
  if (!primary_reachable)
    out_of_limits(fmt::format(
        "position not reachable: wrist centre {:.6f} m from the lower-arm axis, the arm reaches "
        "{:.6f} .. {:.6f} m",
        wrist_distance, std::abs(g.a3 - g.a2), g.a2 + g.a3));
  check_joint_limits(primary, "inverse kinematics solution");
  // Not reached: the primary solution failed within_limits, so the check above threw.
  out_of_limits("inverse kinematics: no solution within the joint limits");
}

void check_frame(const Eigen::Isometry3d& frame, const JointPosition& seed) {
  if (!frame.matrix().allFinite()) bad_argument("inverse kinematics: target frame is not finite");
  for (std::size_t i = 0; i < kAxes; ++i) {
    if (!std::isfinite(seed[i]))
      bad_argument(
          fmt::format("inverse kinematics: seed joint {} ({}) is not finite", i, kJointNames[i]));
  }
}

}  // namespace

std::array<double, kAxes> axes_from_values(std::span<const double> values, const char* what) {
  if (values.size() != kAxes)
    bad_argument(
        fmt::format("{} has {} values, the IRb-6 has {} axes", what, values.size(), kAxes));
  std::array<double, kAxes> out{};
  std::copy(values.begin(), values.end(), out.begin());
  return out;
}

JointPosition joints_from_motors(const MotorPosition& motors) {
  for (std::size_t i = 0; i < kAxes; ++i) {
    if (!std::isfinite(motors[i]))
      bad_argument(fmt::format("motor {} ({}) position {} is not a finite number", i,
                               kJointNames[i], motors[i]));
  }
  const MotorPosition& m0 = kSynchroMotorPositions;
  const JointPosition& q0 = kSynchroJointPositions;
  JointPosition q{};
  q[0] = kHarmonicDirection * (motors[0] - m0[0]) / kColumnRatio + q0[0];
  q[1] = fed_angle_from_motor(lower_screw(), motors[1]);
  q[2] = fed_angle_from_motor(upper_screw(), motors[2]) - q[1] - kHalfPi;
  const double pitch_motor = motors[3] - m0[3];
  q[3] = kHarmonicDirection * pitch_motor / kWristPitchRatio + q0[3];
  // The roll drive passes the pitch axis: only the roll motor's motion relative to the pitch
  // motor turns the roll joint.
  q[4] = kHarmonicDirection * ((motors[4] - m0[4]) - pitch_motor) / kWristRollRatio + q0[4];
  return q;
}

MotorPosition motors_from_joints(const JointPosition& joints) {
  for (std::size_t i = 0; i < kAxes; ++i) {
    if (!std::isfinite(joints[i]))
      bad_argument(fmt::format("joint {} ({}) position {} is not a finite number", i,
                               kJointNames[i], joints[i]));
  }
  const Screw& lower = lower_screw();
  const Screw& upper = upper_screw();
  const double upper_fed = joints[1] + joints[2] + kHalfPi;
  check_linkage(lower, joints[1], "position");
  check_linkage(upper, upper_fed, "position");
  const MotorPosition& m0 = kSynchroMotorPositions;
  const JointPosition& q0 = kSynchroJointPositions;
  MotorPosition m{};
  // kHarmonicDirection is +-1, so dividing by it is multiplying by it.
  m[0] = m0[0] + kHarmonicDirection * kColumnRatio * (joints[0] - q0[0]);
  m[1] = motor_from_fed_angle(lower, joints[1]);
  m[2] = motor_from_fed_angle(upper, upper_fed);
  const double pitch_motor = kHarmonicDirection * kWristPitchRatio * (joints[3] - q0[3]);
  m[3] = m0[3] + pitch_motor;
  m[4] = m0[4] + pitch_motor + kHarmonicDirection * kWristRollRatio * (joints[4] - q0[4]);
  return m;
}

LimitViolation joint_limit_violation(const JointPosition& q) noexcept {
  for (std::size_t i = 0; i < kAxes; ++i) {
    if (!std::isfinite(q[i])) return {LimitKind::invalid, i, q[i], 0.0};
    if (q[i] > kJointUpperLimits[i]) return {LimitKind::joint, i, q[i], kJointUpperLimits[i]};
    if (q[i] < kJointLowerLimits[i]) return {LimitKind::joint, i, q[i], kJointLowerLimits[i]};
  }
  const double fed[2] = {q[1], q[1] + q[2] + kHalfPi};
  const ScrewLinkage* linkage[2] = {&kLowerArmScrew, &kUpperArmScrew};
  for (std::size_t k = 0; k < 2; ++k) {
    if (fed[k] < linkage[k]->min_angle)
      return {LimitKind::linkage, k + 1, fed[k], linkage[k]->min_angle};
    if (fed[k] > linkage[k]->max_angle)
      return {LimitKind::linkage, k + 1, fed[k], linkage[k]->max_angle};
  }
  return {};
}

void check_joint_limits(const JointPosition& q, const char* what) {
  const LimitViolation v = joint_limit_violation(q);
  const std::size_t i = v.axis;
  switch (v.kind) {
    case LimitKind::none: return;
    case LimitKind::invalid:
      bad_argument(
          fmt::format("joint {} ({}) {} {} is not a finite number", i, kJointNames[i], what, q[i]));
    case LimitKind::linkage: {
      const Screw& screw = i == 1 ? lower_screw() : upper_screw();
      out_of_limits(
          fmt::format("joint {} ({}) {}: {} = {:.6f} rad {} the {} linkage limit {:.6f} rad",
                      screw.axis, kJointNames[screw.axis], what, screw.fed_angle, v.value,
                      v.above() ? "exceeds" : "is below", screw.name, v.limit));
    }
    default:
      out_of_limits(
          fmt::format("joint {} ({}) {} {:.6f} rad {} {:.6f} rad", i, kJointNames[i], what, q[i],
                      v.above() ? "exceeds upper limit" : "is below lower limit", v.limit));
  }
}

LimitViolation motor_limit_violation(const MotorPosition& m) noexcept {
  for (std::size_t i = 0; i < kAxes; ++i) {
    if (!std::isfinite(m[i])) return {LimitKind::invalid, i, m[i], 0.0};
    if (m[i] > kMotorUpperLimits[i]) return {LimitKind::motor, i, m[i], kMotorUpperLimits[i]};
    if (m[i] < kMotorLowerLimits[i]) return {LimitKind::motor, i, m[i], kMotorLowerLimits[i]};
  }
  return {};
}

void check_motor_limits(const MotorPosition& m, const char* what) {
  const LimitViolation v = motor_limit_violation(m);
  const std::size_t i = v.axis;
  if (v.kind == LimitKind::none) return;
  if (v.kind == LimitKind::invalid)
    bad_argument(
        fmt::format("motor {} ({}) {} {} is not a finite number", i, kJointNames[i], what, m[i]));
  out_of_limits(
      fmt::format("motor {} ({}) {} {} rad {} {} rad", i, kJointNames[i], what, number(m[i]),
                  v.above() ? "exceeds upper limit" : "is below lower limit", number(v.limit)));
}

std::vector<Irb6Geometry> kinematic_models(const RobotModel& model) {
  const auto names = solver_link_lengths("irb6");
  std::vector<Irb6Geometry> out;
  for (const std::vector<double>& l : model.link_lengths) {
    if (l.size() != names.size()) break;
    out.push_back({l[0], l[1], l[2], l[3]});  // d1, a2, a3, d5
  }
  if (out.empty() || out.size() != model.link_lengths.size())
    throw ConfigError(SourceLocation::whole_file(model.parameters_file().string()),
                      fmt::format("robot '{}' has no IRb-6 link lengths ({} [m] under "
                                  "[robot.kinematics], read with solver = \"irb6\"; its solver is "
                                  "\"{}\")",
                                  model.name, fmt::join(names, ", "), model.kinematics));
  return out;
}

Eigen::Isometry3d forward_kinematics(const JointPosition& q, const Irb6Geometry& g) {
  const double t1 = q[1];
  const double t2 = q[1] + kHalfPi + q[2];
  const double t3 = t2 + q[3];
  const double c0 = std::cos(q[0]);
  const double s0 = std::sin(q[0]);
  const double c1 = std::cos(t1);
  const double s1 = std::sin(t1);
  const double c2 = std::cos(t2);
  const double s2 = std::sin(t2);
  const double c3 = std::cos(t3);
  const double s3 = std::sin(t3);
  const double c4 = std::cos(q[4]);
  const double s4 = std::sin(q[4]);

  // Ry(t3) Rx(q4) Ry(pi/2) = [[-s3 c4, s3 s4, c3], [s4, c4, 0], [-c3 c4, c3 s4, -s3]],
  // then Rz(q0) in front.
  const Eigen::Vector3d row0(-s3 * c4, s3 * s4, c3);
  const Eigen::Vector3d row1(s4, c4, 0.0);
  Eigen::Isometry3d frame = Eigen::Isometry3d::Identity();
  frame.linear().row(0) = (c0 * row0 - s0 * row1).transpose();
  frame.linear().row(1) = (s0 * row0 + c0 * row1).transpose();
  frame.linear().row(2) = Eigen::RowVector3d(-c3 * c4, c3 * s4, -s3);
  const double reach = g.a2 * c1 + g.a3 * c2 + g.d5 * c3;
  frame.translation() =
      Eigen::Vector3d(c0 * reach, s0 * reach, g.d1 - g.a2 * s1 - g.a3 * s2 - g.d5 * s3);
  return frame;
}

Eigen::Isometry3d forward_kinematics(const JointPosition& q, const Irb6Geometry& geometry,
                                     const Eigen::Isometry3d& tool) {
  return forward_kinematics(q, geometry) * tool;
}

JointPosition inverse_kinematics(const Eigen::Isometry3d& flange, const JointPosition& seed,
                                 const Irb6Geometry& geometry, double orientation_tolerance,
                                 double pivot) {
  check_frame(flange, seed);
  const PlaneProjection projection = project_to_arm_plane(flange, seed, pivot);
  if (!(projection.deviation <= orientation_tolerance))
    out_of_limits(
        fmt::format("orientation not reachable by a 5-axis arm: approach deviates {:.3g} "
                    "rad from the arm plane (tolerance {:.3g} rad)",
                    projection.deviation, orientation_tolerance));
  return solve(projection.flange, seed, geometry);
}

NearestSolution inverse_nearest(const Eigen::Isometry3d& flange, const JointPosition& seed,
                                const Irb6Geometry& geometry, double pivot) {
  check_frame(flange, seed);
  const PlaneProjection projection = project_to_arm_plane(flange, seed, pivot);
  NearestSolution out;
  out.joints = solve(projection.flange, seed, geometry);
  out.deviation = projection.deviation;
  out.frame = projection.flange;
  return out;
}

Eigen::Isometry3d Irb6Kinematics::flange(const JointPosition& q) const {
  return corrector * forward_kinematics(q, geometry);
}

Eigen::Isometry3d Irb6Kinematics::forward(const JointPosition& q) const {
  return corrector * forward_kinematics(q, geometry) * tool;
}

JointPosition Irb6Kinematics::inverse(const Eigen::Isometry3d& target,
                                      const JointPosition& seed) const {
  const Eigen::Isometry3d model_flange = corrector.inverse() * target * tool.inverse();
  return inverse_kinematics(model_flange, seed, geometry, orientation_tolerance,
                            tool.translation().z());
}

NearestSolution Irb6Kinematics::inverse_nearest(const Eigen::Isometry3d& target,
                                                const JointPosition& seed) const {
  const Eigen::Isometry3d model_flange = corrector.inverse() * target * tool.inverse();
  NearestSolution out = irb6::inverse_nearest(model_flange, seed, geometry, tool.translation().z());
  out.frame = corrector * out.frame * tool;
  return out;
}

}  // namespace mrroc::robots::irb6
