#include "mrroc/ecp/generators/guarded_move.hpp"

#include <fmt/format.h>

#include <cmath>

#include "mrroc/core/error.hpp"
#include "mrroc/kinematics/pose.hpp"

namespace mrroc::ecp {

namespace {

void check_motion(const GuardedMotion& motion, const char* unit) {
  const auto check = [&](double value, const char* name, const char* suffix) {
    if (!(std::isfinite(value) && value > 0.0))
      throw Error(fmt::format("guarded move: {} {} {}{} is not a positive number", name, value,
                              unit, suffix));
  };
  check(motion.speed, "speed", "/s");
  check(motion.acceleration, "acceleration", "/s^2");
  check(motion.max_distance, "max_distance", "");
}

// Position of the tool frame origin in a Cartesian representation's values.
Eigen::Vector3d position_of(const std::vector<double>& values, edp::ArmRepresentation r) {
  if (r == edp::ArmRepresentation::frame) return {values[3], values[7], values[11]};
  return {values[0], values[1], values[2]};
}

}  // namespace

GuardedMoveGenerator::GuardedMoveGenerator(std::unique_ptr<PlannedMotionGenerator> motion,
                                           TerminalCondition condition, GuardedMotion guarded,
                                           bool cartesian)
    : motion_(std::move(motion)),
      condition_(std::move(condition)),
      guarded_(guarded),
      cartesian_(cartesian) {}

GuardedMoveGenerator GuardedMoveGenerator::along_axes(const RobotModel& model,
                                                      std::vector<double> direction,
                                                      GuardedMotion motion,
                                                      TerminalCondition condition,
                                                      InterpolationOptions options) {
  check_motion(motion, "rad");
  if (direction.size() != model.axes())
    throw CommandError(edp::error_code::bad_argument,
                       fmt::format("guarded move: direction has {} values, robot '{}' has {} axes",
                                   direction.size(), model.name, model.axes()));
  double norm = 0.0;
  for (const double d : direction) norm += d * d;
  norm = std::sqrt(norm);
  if (!(std::isfinite(norm) && norm > 0.0))
    throw CommandError(edp::error_code::bad_argument,
                       "guarded move: direction is zero or not finite");
  options.profile = ProfileShape::trapezoidal;
  options.max_velocity.assign(model.axes(), 1.0);
  options.max_acceleration.assign(model.axes(), 1.0);
  Waypoint end;
  end.relative = true;
  end.position.resize(model.axes());
  for (std::size_t j = 0; j < model.axes(); ++j) {
    const double u = direction[j] / norm;
    end.position[j] = u * motion.max_distance;
    if (u != 0.0) {  // axes that do not move keep a placeholder limit
      options.max_velocity[j] = motion.speed * std::abs(u);
      options.max_acceleration[j] = motion.acceleration * std::abs(u);
    }
  }
  auto generator = std::make_unique<InterpolationGenerator>(model, std::vector<Waypoint>{end},
                                                            std::move(options));
  return {std::move(generator), std::move(condition), motion, false};
}

GuardedMoveGenerator GuardedMoveGenerator::along_line(const RobotModel& model,
                                                      const Eigen::Vector3d& direction,
                                                      GuardedMotion motion,
                                                      TerminalCondition condition,
                                                      CartesianOptions options) {
  check_motion(motion, "m");
  if (!direction.allFinite() || direction.norm() == 0.0)
    throw CommandError(edp::error_code::bad_argument,
                       "guarded move: direction is zero or not finite");
  options.profile = ProfileShape::trapezoidal;
  options.max_linear_velocity = motion.speed;
  options.max_linear_acceleration = motion.acceleration;
  auto generator = std::make_unique<CartesianPathGenerator>(
      model,
      std::vector<CartesianSegment>{
          CartesianSegment::line_by(direction.normalized() * motion.max_distance)},
      options);
  return {std::move(generator), std::move(condition), motion, true};
}

bool GuardedMoveGenerator::first_step(RobotImage& robot, const SensorList& sensors) {
  condition_met_ = condition_(robot, sensors);
  if (condition_met_) return false;
  return motion_->first_step(robot, sensors);
}

bool GuardedMoveGenerator::next_step(RobotImage& robot, const SensorList& sensors) {
  condition_met_ = condition_(robot, sensors);
  if (condition_met_) return false;
  if (motion_->next_step(robot, sensors)) return true;
  const double travelled = distance();
  throw GuardedMoveExhausted(
      fmt::format("guarded move: travelled {} {} (the maximum distance {} {}) without the "
                  "terminal condition",
                  travelled, cartesian_ ? "m" : "rad", guarded_.max_distance,
                  cartesian_ ? "m" : "rad"),
      travelled);
}

double GuardedMoveGenerator::distance() const {
  const MotionPlan& p = motion_->plan();
  const std::size_t sent = motion_->macro_steps_sent();
  if (sent == 0 || p.targets.empty()) return 0.0;
  const std::vector<double>& now = p.targets[sent - 1];
  if (cartesian_)
    return (position_of(now, p.representation) - position_of(p.start, p.representation)).norm();
  double sum = 0.0;
  for (std::size_t j = 0; j < now.size(); ++j) sum += (now[j] - p.start[j]) * (now[j] - p.start[j]);
  return std::sqrt(sum);
}

}  // namespace mrroc::ecp
