/// @file
/// Transmissions of the RNT (see include/mrroc/kinematics/rnt.hpp and robots/rnt/README.md).

#include <fmt/format.h>

#include <cmath>
#include <string>

#include "mrroc/core/error.hpp"
#include "mrroc/kinematics/rnt.hpp"
#include "mrroc/msg/edp_instruction.hpp"

namespace mrroc::robots::rnt {

namespace {

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

template <typename Array>
void check_finite(const Array& values, const char* kind, const char* what) {
  for (std::size_t i = 0; i < kAxes; ++i) {
    if (!std::isfinite(values[i]))
      bad_argument(fmt::format("{} {} ({}) {} {} is not a finite number", kind, i, kJointNames[i],
                               what, values[i]));
  }
}

}  // namespace

ActuatorPosition actuators_from_joints(const JointPosition& q) {
  ActuatorPosition a{};
  for (std::size_t r = 0; r < kAxes; ++r) {
    double sum = 0.0;
    for (std::size_t c = 0; c < kAxes; ++c) sum += kCoupling[r][c] * q[c];
    a[r] = sum;
  }
  return a;
}

JointPosition joints_from_actuators(const ActuatorPosition& a) {
  // C is the identity except row 2 (a2 = q1 + q2): its inverse is q2 = a2 - a1.
  JointPosition q = a;
  q[2] = a[2] - a[1];
  return q;
}

MotorPosition motors_from_joints(const JointPosition& joints) {
  check_finite(joints, "joint", "value");
  const ActuatorPosition a = actuators_from_joints(joints);
  MotorPosition m{};
  for (std::size_t i = 0; i < kAxes; ++i) m[i] = kGearRatios[i] * a[i];
  return m;
}

JointPosition joints_from_motors(const MotorPosition& motors) {
  check_finite(motors, "motor", "position");
  ActuatorPosition a{};
  for (std::size_t i = 0; i < kAxes; ++i) a[i] = motors[i] / kGearRatios[i];
  return joints_from_actuators(a);
}

LimitViolation motor_limit_violation(const MotorPosition& m) noexcept {
  for (std::size_t i = 0; i < kAxes; ++i)
    if (!std::isfinite(m[i])) return {LimitKind::invalid, i, m[i], 0.0};
  for (std::size_t i = 0; i < kAxes; ++i) {
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

LimitViolation limit_violation(const JointPosition& q) noexcept {
  for (std::size_t i = 0; i < kAxes; ++i)
    if (!std::isfinite(q[i])) return {LimitKind::invalid, i, q[i], 0.0};
  for (std::size_t i = 0; i < kAxes; ++i) {
    if (q[i] > kJointUpperLimits[i]) return {LimitKind::joint, i, q[i], kJointUpperLimits[i]};
    if (q[i] < kJointLowerLimits[i]) return {LimitKind::joint, i, q[i], kJointLowerLimits[i]};
  }
  return motor_limit_violation(motors_from_joints(q));  // finite: does not throw
}

void check_limits(const JointPosition& q, const char* what) {
  const LimitViolation v = limit_violation(q);
  const std::size_t j = v.axis;
  if (v.kind == LimitKind::none) return;
  if (v.kind == LimitKind::invalid)
    bad_argument(
        fmt::format("joint {} ({}) {} {} is not a finite number", j, kJointNames[j], what, q[j]));
  if (v.kind == LimitKind::joint)
    out_of_limits(fmt::format("joint {} ({}) {} {:.6f} rad {} {:.6f} rad", j, kJointNames[j], what,
                              q[j], v.above() ? "exceeds upper limit" : "is below lower limit",
                              v.limit));
  const MotorPosition m = motors_from_joints(q);
  try {
    check_motor_limits(m, what);
  } catch (const CommandError& e) {
    // Motor 2 is the parallelogram's limit: say which joint combination it bounds.
    const bool forearm = (m[2] > kMotorUpperLimits[2] || m[2] < kMotorLowerLimits[2]);
    bool earlier = false;
    for (std::size_t i = 0; i < 2; ++i)
      earlier = earlier || m[i] > kMotorUpperLimits[i] || m[i] < kMotorLowerLimits[i];
    if (!forearm || earlier) throw;
    const bool above = m[2] > kMotorUpperLimits[2];
    const double limit = (above ? kMotorUpperLimits[2] : kMotorLowerLimits[2]) / kGearRatios[2];
    throw CommandError(e.code(), fmt::format("{} (absolute forearm pitch shoulder + elbow = "
                                             "{:.6f} rad, limit {:.6f} rad)",
                                             e.what(), q[1] + q[2], limit));
  }
}

}  // namespace mrroc::robots::rnt
