#include "mrroc/edp/path_check.hpp"

#include <fmt/format.h>

#include <array>
#include <string>
#include <vector>

#include "mrroc/core/error.hpp"
#include "mrroc/msg/edp_instruction.hpp"

namespace mrroc::edp {

namespace {

/// q_k of the path: the one formula both the check and the text of its refusal use.
void path_point(std::span<const double> from, std::span<const double> to, int k, int steps,
                std::span<double> q) {
  const double s = static_cast<double>(k) / steps;
  for (std::size_t i = 0; i < q.size(); ++i) q[i] = from[i] + (to[i] - from[i]) * s;
}

LimitViolation scan(const ArmKinematics& kinematics, std::span<const double> from,
                    std::span<const double> to, int steps, std::span<double> q,
                    std::span<double> m) {
  if (LimitViolation v = kinematics.joint_limit_violation(to)) return v;  // step 0: the target
  if (from.size() != to.size())
    return {LimitKind::invalid, 0, static_cast<double>(from.size()),
            static_cast<double>(to.size())};
  for (int k = 1; k <= steps; ++k) {
    path_point(from, to, k, steps, q);
    LimitViolation v = kinematics.joint_limit_violation(q);
    if (!v) {
      kinematics.motors_from_joints(q, m);  // inside the joint limits: does not throw
      v = kinematics.motor_limit_violation(m);
    }
    if (v) {
      v.step = k;
      return v;
    }
  }
  return {};
}

}  // namespace

LimitViolation find_path_limit_violation(const ArmKinematics& kinematics,
                                         std::span<const double> from, std::span<const double> to,
                                         int steps) {
  const std::size_t axes = to.size();
  if (axes <= kPathCheckMaxAxes) {
    std::array<double, kPathCheckMaxAxes> q{};
    std::array<double, kPathCheckMaxAxes> m{};
    return scan(kinematics, from, to, steps, std::span(q.data(), axes), std::span(m.data(), axes));
  }
  std::vector<double> q(axes);
  std::vector<double> m(axes);
  return scan(kinematics, from, to, steps, q, m);
}

void throw_path_limit_violation(const ArmKinematics& kinematics, std::span<const double> from,
                                std::span<const double> to, int steps, const char* step_name,
                                const LimitViolation& v) {
  const std::string what =
      v.step == 0 ? std::string("target") : fmt::format("{} {} of {}", step_name, v.step, steps);
  if (v.step == 0) {
    kinematics.check_joint_limits(to, "target");
  } else if (from.size() == to.size()) {
    std::vector<double> q(to.size());
    path_point(from, to, v.step, steps, q);
    kinematics.check_joint_limits(q, what.c_str());
    kinematics.check_motor_limits(kinematics.motors_from_joints(q), what.c_str());
  }
  if (v.kind == LimitKind::invalid)
    throw CommandError(error_code::bad_argument,
                       fmt::format("the path from {} values to {} values cannot be checked",
                                   from.size(), to.size()));
  // Not reached while the values and the kinematics' checks agree.
  throw CommandError(
      error_code::out_of_limits,
      fmt::format("{} {} {} {:.6f} {} its {} limit {:.6f}",
                  v.kind == LimitKind::motor ? "motor" : "joint", v.axis, what, v.value,
                  v.above() ? "exceeds" : "is below", v.above() ? "upper" : "lower", v.limit));
}

void check_straight_path(const ArmKinematics& kinematics, std::span<const double> from,
                         std::span<const double> to, int steps, const char* step_name) {
  const LimitViolation v = find_path_limit_violation(kinematics, from, to, steps);
  if (v) throw_path_limit_violation(kinematics, from, to, steps, step_name, v);
}

}  // namespace mrroc::edp
