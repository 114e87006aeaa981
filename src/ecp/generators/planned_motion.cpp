#include "mrroc/ecp/generators/planned_motion.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <limits>

#include "mrroc/core/error.hpp"
#include "mrroc/edp/path_check.hpp"

namespace mrroc::ecp {

PlannedMotionGenerator::PlannedMotionGenerator(const RobotModel& model)
    : model_(model), kinematics_(edp::make_arm_kinematics(model)) {}

MotionPlan PlannedMotionGenerator::plan_from(const std::vector<double>& start_joints) const {
  if (start_joints.size() != model_.axes())
    throw Error(
        fmt::format("motion start has {} joint values, robot '{}' has {} axes (read the "
                    "robot state first)",
                    start_joints.size(), model_.name, model_.axes()));
  return make_plan(start_joints);
}

bool PlannedMotionGenerator::first_step(RobotImage& robot, const SensorList&) {
  // Plan into a local first: a refused plan leaves the previous one and the command untouched.
  MotionPlan plan = plan_from(robot.desired_joints);
  plan_ = std::move(plan);
  sent_ = 0;
  rejoin_.clear();
  rejoin_sent_ = 0;
  if (plan_.targets.empty()) return false;
  command(robot);
  return true;
}

bool PlannedMotionGenerator::next_step(RobotImage& robot, const SensorList&) {
  if (rejoin_sent_ >= rejoin_.size() && sent_ >= plan_.targets.size()) return false;
  command(robot);
  return true;
}

bool PlannedMotionGenerator::resume(RobotImage& robot, const SensorList&) {
  const std::size_t n = plan_.targets.size();
  if (sent_ == 0 || n == 0 || robot.desired_joints.size() != model_.axes()) return false;
  if (rejoin_sent_ < rejoin_.size()) {
    // Interrupted while rejoining: rejoin again from here to the same segment end.
  } else if (sent_ >= n) {
    return false;
  }
  // The segment of the last plan target sent; it ends at rest at its last target.
  const std::size_t last = sent_ - 1;
  std::size_t end = n - 1;
  for (const PlannedSegment& s : plan_.segments)
    if (last >= s.first_macro_step && last < s.first_macro_step + s.macro_steps) {
      end = s.first_macro_step + s.macro_steps - 1;
      break;
    }
  const std::vector<double>& from = robot.desired_joints;
  const std::vector<double>& to = plan_.joints.at(end);
  // The slowest axis sets the duration: axis j moving by d_j needs ds/dt <= f v_j / d_j and
  // d2s/dt2 <= f a_j / d_j.
  constexpr double kFraction = 0.5;
  double max_sv = std::numeric_limits<double>::infinity();
  double max_sa = std::numeric_limits<double>::infinity();
  for (std::size_t j = 0; j < from.size(); ++j) {
    const double d = std::abs(to[j] - from[j]);
    if (d < 1e-12) continue;
    max_sv = std::min(max_sv, kFraction * model_.max_velocity[j] / d);
    max_sa = std::min(max_sa, kFraction * model_.max_acceleration[j] / d);
  }
  rejoin_.clear();
  rejoin_sent_ = 0;
  if (std::isfinite(max_sv)) {
    const MotionProfile profile = MotionProfile::fastest(ProfileShape::quintic, max_sv, max_sa);
    const double macro_s = plan_.macro_step_s();
    const auto steps =
        std::max<std::size_t>(2, static_cast<std::size_t>(std::ceil(profile.duration() / macro_s)));
    const MotionProfile timed = MotionProfile::with_duration(ProfileShape::quintic, max_sv, max_sa,
                                                             static_cast<double>(steps) * macro_s);
    std::vector<double> previous = from;
    for (std::size_t k = 1; k <= steps; ++k) {
      const double s = timed.position(static_cast<double>(k) * macro_s);
      std::vector<double> q(from.size());
      for (std::size_t j = 0; j < q.size(); ++j) q[j] = from[j] + (to[j] - from[j]) * s;
      if (k == steps) q = to;
      try {
        detail::check_macro_step_path(*kinematics_, previous, q, plan_.motion_steps);
      } catch (...) {
        detail::rethrow_with_context("move back onto the planned path: ");
      }
      previous = q;
      rejoin_.push_back(std::move(q));
    }
  }
  sent_ = end + 1;
  if (rejoin_.empty() && sent_ >= n) return false;
  command(robot);
  return true;
}

void PlannedMotionGenerator::command(RobotImage& robot) {
  edp::Instruction& c = robot.command;
  c = edp::Instruction{};
  if (rejoin_sent_ < rejoin_.size()) {
    c.type = edp::InstructionType::set;
    c.set = edp::item::arm;
    c.set_arm_type = edp::ArmRepresentation::joint;
    c.motion_type = edp::MotionType::absolute;
    c.motion_steps = plan_.motion_steps;
    const bool last = rejoin_sent_ + 1 == rejoin_.size() && sent_ >= plan_.targets.size();
    c.value_in_step_no = last ? plan_.motion_steps + 1 : early_reading_step(plan_.motion_steps);
    c.arm = rejoin_[rejoin_sent_++];
    return;
  }
  c.type = edp::InstructionType::set;
  c.set = edp::item::arm;
  c.set_arm_type = plan_.representation;
  c.motion_type = edp::MotionType::absolute;
  c.motion_steps = plan_.motion_steps;
  const bool last = sent_ + 1 == plan_.targets.size();
  c.value_in_step_no = last ? plan_.motion_steps + 1 : early_reading_step(plan_.motion_steps);
  c.arm = plan_.targets[sent_];
  if (sent_ == 0 && plan_.first_command_sets != 0) {
    c.set = static_cast<std::uint8_t>(c.set | plan_.first_command_sets);
    if ((plan_.first_command_sets & edp::item::tool) != 0) {
      c.tool_type = edp::ArmRepresentation::frame;
      c.tool = plan_.tool;
    }
    c.kinematic_model_no = plan_.kinematic_model_no;
    c.corrector_no = plan_.corrector_no;
  }
  ++sent_;
}

namespace detail {

void check_macro_step_path(const edp::ArmKinematics& kinematics, const std::vector<double>& from,
                           const std::vector<double>& to, int motion_steps) {
  // The EDP's command interpreter checks with the same function: a plan that passes here is not
  // refused there (for the same kinematic model and tool).
  edp::check_straight_path(kinematics, from, to, motion_steps, "servo step");
}

JointRates joint_rates(const std::vector<double>& before,
                       const std::vector<std::vector<double>>& joints, std::size_t first,
                       std::size_t count, double macro_step_s,
                       const std::vector<double>& max_velocity,
                       const std::vector<double>& max_acceleration) {
  JointRates r;
  const std::size_t axes = before.size();
  std::vector<double> previous_velocity(axes, 0.0);
  for (std::size_t k = first; k <= first + count; ++k) {
    for (std::size_t j = 0; j < axes; ++j) {
      double v = 0.0;  // at rest after the last macro-step
      if (k < first + count) {
        const double from = k == first ? before[j] : joints[k - 1][j];
        v = (joints[k][j] - from) / macro_step_s;
      }
      const double a = (v - previous_velocity[j]) / macro_step_s;
      const double velocity_ratio = std::abs(v) / max_velocity[j];
      const double acceleration_ratio = std::abs(a) / max_acceleration[j];
      if (velocity_ratio > r.velocity_ratio) {
        r.velocity_ratio = velocity_ratio;
        r.velocity_step = k;
        r.velocity_axis = j;
        r.velocity = v;
      }
      if (acceleration_ratio > r.acceleration_ratio) {
        r.acceleration_ratio = acceleration_ratio;
        r.acceleration_step = k;
        r.acceleration_axis = j;
        r.acceleration = a;
      }
      previous_velocity[j] = v;
    }
  }
  return r;
}

void rethrow_with_context(const std::string& prefix) {
  try {
    throw;
  } catch (const CommandError& e) {
    throw CommandError(e.code(), prefix + e.what());
  }
}

void check_macro_step_options(int motion_steps, double servo_period_s, const char* generator) {
  if (motion_steps < 2 || motion_steps > 1000)
    throw Error(fmt::format("{}: motion_steps {} is outside 2..1000", generator, motion_steps));
  if (!(std::isfinite(servo_period_s) && servo_period_s > 0.0 && servo_period_s <= 1.0))
    throw Error(
        fmt::format("{}: servo_period_s {} s is outside (0, 1] s", generator, servo_period_s));
}

}  // namespace detail

}  // namespace mrroc::ecp
