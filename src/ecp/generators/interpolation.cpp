#include "mrroc/ecp/generators/interpolation.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>

#include "mrroc/core/error.hpp"

namespace mrroc::ecp {

namespace {

bool is_motor(edp::ArmRepresentation r) { return r == edp::ArmRepresentation::motor; }

void check_scale(double value, const char* name) {
  if (!(value > 0.0 && value <= 1.0))
    throw Error(fmt::format("interpolation: {} {} is outside (0, 1]", name, value));
}

void check_explicit_limits(const std::vector<double>& limits, std::size_t axes, const char* name) {
  if (limits.empty()) return;
  if (limits.size() != axes)
    throw Error(fmt::format("interpolation: {} has {} values, the robot has {} axes", name,
                            limits.size(), axes));
  for (std::size_t j = 0; j < axes; ++j)
    if (!(std::isfinite(limits[j]) && limits[j] > 0.0))
      throw Error(fmt::format("interpolation: {} of axis {} is {}, not a positive number", name, j,
                              limits[j]));
}

// Transmission ratio |dm_j/dq_j| at q by central differences (one-sided next to a linkage limit).
double transmission_ratio(const edp::ArmKinematics& kinematics, std::vector<double> q,
                          std::size_t j) {
  constexpr double h = 1e-6;
  const double q0 = q[j];
  const double m0 = kinematics.motors_from_joints(q)[j];
  double plus = NAN;
  double minus = NAN;
  try {
    q[j] = q0 + h;
    plus = kinematics.motors_from_joints(q)[j];
  } catch (const CommandError&) {
  }
  try {
    q[j] = q0 - h;
    minus = kinematics.motors_from_joints(q)[j];
  } catch (const CommandError&) {
  }
  if (std::isfinite(plus) && std::isfinite(minus)) return std::abs(plus - minus) / (2.0 * h);
  if (std::isfinite(plus)) return std::abs(plus - m0) / h;
  if (std::isfinite(minus)) return std::abs(m0 - minus) / h;
  throw CommandError(edp::error_code::out_of_limits,
                     fmt::format("motor {} transmission ratio cannot be evaluated at joint value "
                                 "{:.6f} rad",
                                 j, q0));
}

}  // namespace

std::vector<Waypoint> to_waypoints(const std::vector<std::vector<double>>& poses) {
  std::vector<Waypoint> waypoints;
  waypoints.reserve(poses.size());
  for (const auto& p : poses) waypoints.push_back(Waypoint{p});
  return waypoints;
}

InterpolationGenerator::InterpolationGenerator(const RobotModel& model,
                                               std::vector<Waypoint> waypoints,
                                               InterpolationOptions options)
    : PlannedMotionGenerator(model),
      waypoints_(std::move(waypoints)),
      options_(std::move(options)) {
  const auto rep = options_.representation;
  if (rep != edp::ArmRepresentation::joint && rep != edp::ArmRepresentation::motor)
    throw Error(
        fmt::format("interpolation: representation {} is not JOINT or MOTOR (use the "
                    "Cartesian path generator for Cartesian motions)",
                    edp::to_string(rep)));
  if (options_.profile != ProfileShape::trapezoidal && options_.profile != ProfileShape::quintic)
    throw Error("interpolation: unknown profile shape");
  check_scale(options_.velocity_scale, "velocity_scale");
  check_scale(options_.acceleration_scale, "acceleration_scale");
  detail::check_macro_step_options(options_.motion_steps, options_.servo_period_s, "interpolation");
  const std::size_t axes = model.axes();
  check_explicit_limits(options_.max_velocity, axes, "max_velocity");
  check_explicit_limits(options_.max_acceleration, axes, "max_acceleration");

  for (std::size_t i = 0; i < waypoints_.size(); ++i) {
    const Waypoint& w = waypoints_[i];
    const std::string what = fmt::format("waypoint {}", i + 1);
    if (w.position.size() != axes)
      throw CommandError(edp::error_code::bad_argument,
                         fmt::format("{} has {} {} values, robot '{}' has {} axes", what,
                                     w.position.size(), edp::to_string(rep), model.name, axes));
    for (std::size_t j = 0; j < axes; ++j)
      if (!std::isfinite(w.position[j]))
        throw CommandError(
            edp::error_code::bad_argument,
            fmt::format("{} value {} ({}) is not a finite number", what, j, model.joint_names[j]));
    if (!(std::isfinite(w.duration_s) && w.duration_s >= 0.0))
      throw CommandError(edp::error_code::bad_argument,
                         fmt::format("{} duration {} s is not a number >= 0", what, w.duration_s));
    if (!(w.velocity_scale > 0.0 && w.velocity_scale <= 1.0))
      throw CommandError(
          edp::error_code::bad_argument,
          fmt::format("{} velocity_scale {} is outside (0, 1]", what, w.velocity_scale));
    if (w.relative) continue;  // checked on the plan, once the start is known
    if (is_motor(rep)) {
      kinematics().check_motor_limits(w.position, what.c_str());
      kinematics().check_joint_limits(kinematics().joints_from_motors(w.position), what.c_str());
    } else {
      kinematics().check_joint_limits(w.position, what.c_str());
    }
  }
}

void InterpolationGenerator::limits_at(const std::vector<double>& joints,
                                       std::vector<double>& max_velocity,
                                       std::vector<double>& max_acceleration) const {
  const RobotModel& m = model();
  const std::size_t axes = m.axes();
  max_velocity.assign(axes, 0.0);
  max_acceleration.assign(axes, 0.0);
  for (std::size_t j = 0; j < axes; ++j) {
    const double ratio =
        is_motor(options_.representation) ? transmission_ratio(kinematics(), joints, j) : 1.0;
    max_velocity[j] = options_.max_velocity.empty()
                          ? m.max_velocity[j] * options_.velocity_scale * ratio
                          : options_.max_velocity[j];
    max_acceleration[j] = options_.max_acceleration.empty()
                              ? m.max_acceleration[j] * options_.acceleration_scale * ratio
                              : options_.max_acceleration[j];
  }
}

MotionPlan InterpolationGenerator::make_plan(const std::vector<double>& start_joints) const {
  const RobotModel& m = model();
  const edp::ArmKinematics& kin = kinematics();
  const auto rep = options_.representation;
  const std::size_t axes = m.axes();

  MotionPlan plan;
  plan.representation = rep;
  plan.motion_steps = options_.motion_steps;
  plan.servo_period_s = options_.servo_period_s;
  plan.start_joints = start_joints;
  const double dt = plan.macro_step_s();

  std::vector<double> max_velocity;
  std::vector<double> max_acceleration;
  limits_at(start_joints, max_velocity, max_acceleration);

  std::vector<double> from = is_motor(rep) ? kin.motors_from_joints(start_joints) : start_joints;
  std::vector<double> from_joints = start_joints;
  plan.start = from;
  const auto to_joints = [&](const std::vector<double>& x) {
    return is_motor(rep) ? kin.joints_from_motors(x) : x;
  };

  for (std::size_t i = 0; i < waypoints_.size(); ++i) {
    const Waypoint& w = waypoints_[i];
    const std::string context = fmt::format(
        "{} interpolation, segment {} (to waypoint {}): ", edp::to_string(rep), i + 1, i + 1);
    try {
      std::vector<double> to = w.position;
      if (w.relative)
        for (std::size_t j = 0; j < axes; ++j) to[j] += from[j];

      // Path parameter limits: an axis moving by d has velocity d * ds/dt.
      const double k = w.velocity_scale;
      double v_path = INFINITY;
      double a_path = INFINITY;
      for (std::size_t j = 0; j < axes; ++j) {
        const double d = std::abs(to[j] - from[j]);
        if (d == 0.0) continue;
        v_path = std::min(v_path, max_velocity[j] * k / d);
        a_path = std::min(a_path, max_acceleration[j] * k * k / d);
      }

      PlannedSegment segment;
      segment.first_macro_step = plan.targets.size();
      if (!std::isfinite(v_path)) {  // no motion
        if (w.duration_s <= 0.0) continue;
        segment.macro_steps =
            static_cast<std::size_t>(std::max(1.0, std::ceil(w.duration_s / dt - 1e-9)));
        for (std::size_t s = 0; s < segment.macro_steps; ++s) {
          plan.targets.push_back(to);
          plan.joints.push_back(from_joints);
        }
        plan.segments.push_back(segment);
        continue;
      }

      const MotionProfile fast = MotionProfile::fastest(options_.profile, v_path, a_path);
      if (w.duration_s > 0.0 && w.duration_s < fast.duration() * (1.0 - 1e-12))
        throw CommandError(edp::error_code::out_of_limits,
                           fmt::format("duration {} s is shorter than the {:.4f} s the velocity "
                                       "and acceleration limits allow",
                                       w.duration_s, fast.duration()));
      double duration = w.duration_s > 0.0 ? w.duration_s : fast.duration();

      std::vector<std::vector<double>> targets;
      std::vector<std::vector<double>> joints;
      constexpr int kAttempts = 20;
      for (int attempt = 0;; ++attempt) {
        const auto n = static_cast<std::size_t>(std::max(1.0, std::ceil(duration / dt - 1e-9)));
        const MotionProfile profile = MotionProfile::with_duration(options_.profile, v_path, a_path,
                                                                   static_cast<double>(n) * dt);
        targets.assign(n, std::vector<double>(axes));
        joints.clear();
        for (std::size_t step = 1; step <= n; ++step) {
          std::vector<double>& x = targets[step - 1];
          if (step == n) {
            x = to;  // exactly the waypoint, free of rounding
          } else {
            const double s = profile.position(static_cast<double>(step) * dt);
            for (std::size_t j = 0; j < axes; ++j) x[j] = from[j] + (to[j] - from[j]) * s;
          }
          try {
            joints.push_back(to_joints(x));
          } catch (...) {
            detail::rethrow_with_context(fmt::format("macro-step {} of {}: ", step, n));
          }
        }
        const detail::JointRates rates =
            detail::joint_rates(from_joints, joints, 0, n, dt, m.max_velocity, m.max_acceleration);
        const double ratio = std::max(rates.velocity_ratio, std::sqrt(rates.acceleration_ratio));
        if (ratio <= 1.0 + 1e-9) {
          segment.macro_steps = n;
          segment.profile = profile;
          break;
        }
        if (w.duration_s > 0.0 || attempt == kAttempts) {
          const bool velocity = rates.velocity_ratio >= rates.acceleration_ratio;
          const std::size_t axis = velocity ? rates.velocity_axis : rates.acceleration_axis;
          const std::size_t step = velocity ? rates.velocity_step : rates.acceleration_step;
          throw CommandError(
              edp::error_code::out_of_limits,
              fmt::format("joint {} ({}) {} {:.6f} {} in macro-step {} of {} exceeds the limit "
                          "{:.6f} {}{}",
                          axis, m.joint_names[axis], velocity ? "velocity" : "acceleration",
                          velocity ? rates.velocity : rates.acceleration,
                          velocity ? "rad/s" : "rad/s^2", std::min(step + 1, n), n,
                          velocity ? m.max_velocity[axis] : m.max_acceleration[axis],
                          velocity ? "rad/s" : "rad/s^2",
                          w.duration_s > 0.0
                              ? fmt::format(" (duration {} s is too short)", w.duration_s)
                              : std::string()));
        }
        // Slow the whole segment down in time: velocities scale with 1 / f, accelerations with
        // 1 / f^2 (also the part due to the curvature of the transmission).
        const double f = ratio * (1.0 + 1e-6);
        v_path /= f;
        a_path /= f * f;
        duration = MotionProfile::fastest(options_.profile, v_path, a_path).duration();
      }

      // What the EDP will check, macro-step by macro-step.
      const std::vector<double>* previous = &from_joints;
      for (std::size_t step = 0; step < targets.size(); ++step) {
        try {
          if (is_motor(rep)) kin.check_motor_limits(targets[step], "target");
          detail::check_macro_step_path(kin, *previous, joints[step], options_.motion_steps);
        } catch (...) {
          detail::rethrow_with_context(
              fmt::format("macro-step {} of {}: ", step + 1, targets.size()));
        }
        previous = &joints[step];
      }

      from = to;
      from_joints = joints.back();
      plan.targets.insert(plan.targets.end(), targets.begin(), targets.end());
      plan.joints.insert(plan.joints.end(), joints.begin(), joints.end());
      plan.segments.push_back(segment);
    } catch (...) {
      detail::rethrow_with_context(context);
    }
  }
  return plan;
}

}  // namespace mrroc::ecp
