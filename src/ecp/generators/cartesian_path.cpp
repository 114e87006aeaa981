#include "mrroc/ecp/generators/cartesian_path.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <numbers>

#include "mrroc/core/error.hpp"
#include "mrroc/kinematics/pose.hpp"

namespace mrroc::ecp {

namespace {

[[noreturn]] void bad_argument(const std::string& text) {
  throw CommandError(edp::error_code::bad_argument, text);
}

bool finite(const Eigen::Vector3d& v) { return v.allFinite(); }

const char* kind_name(CartesianSegment::Kind kind) {
  switch (kind) {
    case CartesianSegment::Kind::line: return "line";
    case CartesianSegment::Kind::line_by: return "line by a displacement";
    case CartesianSegment::Kind::arc_through: return "three-point arc";
    case CartesianSegment::Kind::arc_about: return "arc about an axis";
  }
  return "?";
}

void check_positive(double value, const char* name, const char* unit) {
  if (!(std::isfinite(value) && value > 0.0))
    throw Error(
        fmt::format("Cartesian path: {} {} {} is not a positive number", name, value, unit));
}

void check_scale(double value, const char* name) {
  if (!(value > 0.0 && value <= 1.0))
    throw Error(fmt::format("Cartesian path: {} {} is outside (0, 1]", name, value));
}

/// One segment, resolved against its start frame: pose(s) for s in [0, 1].
struct ResolvedSegment {
  enum class Orientation { slerp, constant, turn };
  bool arc = false;
  Eigen::Vector3d p0, p1;  // line
  CircleArc circle;        // arc
  Orientation orientation = Orientation::slerp;
  Eigen::Quaterniond q0, q1;
  Eigen::Matrix3d r0;
  Eigen::Isometry3d end;  // exact pose at s = 1
  double length = 0.0;    // [m]
  double rotation = 0.0;  // [rad]

  [[nodiscard]] Eigen::Isometry3d at(double s) const {
    if (s >= 1.0) return end;
    Eigen::Isometry3d f = Eigen::Isometry3d::Identity();
    f.translation() = arc ? circle.at(s) : Eigen::Vector3d(p0 + (p1 - p0) * s);
    switch (orientation) {
      case Orientation::slerp: f.linear() = q0.slerp(s, q1).normalized().toRotationMatrix(); break;
      case Orientation::constant: f.linear() = r0; break;
      case Orientation::turn:
        f.linear() = Eigen::AngleAxisd(s * circle.angle, circle.normal).toRotationMatrix() * r0;
        break;
    }
    return f;
  }
};

ResolvedSegment resolve(const CartesianSegment& segment, const Eigen::Isometry3d& start) {
  ResolvedSegment r;
  r.r0 = start.linear();
  r.q0 = Eigen::Quaterniond(r.r0);
  const Eigen::Vector3d p0 = start.translation();
  switch (segment.kind) {
    case CartesianSegment::Kind::line:
    case CartesianSegment::Kind::line_by: {
      r.p0 = p0;
      if (segment.kind == CartesianSegment::Kind::line) {
        r.p1 = segment.end.translation();
        r.end = segment.end;
        r.q1 = Eigen::Quaterniond(segment.end.linear());
        r.orientation = ResolvedSegment::Orientation::slerp;
        r.rotation = r.q0.angularDistance(r.q1);
      } else {
        r.p1 = p0 + segment.point;
        r.end = start;
        r.end.translation() = r.p1;
        r.orientation = ResolvedSegment::Orientation::constant;
      }
      r.length = (r.p1 - r.p0).norm();
      break;
    }
    case CartesianSegment::Kind::arc_through: {
      r.arc = true;
      r.circle = CircleArc::through(p0, segment.point, segment.end.translation());
      r.end = segment.end;
      r.q1 = Eigen::Quaterniond(segment.end.linear());
      r.orientation = ResolvedSegment::Orientation::slerp;
      r.rotation = r.q0.angularDistance(r.q1);
      r.length = r.circle.length();
      break;
    }
    case CartesianSegment::Kind::arc_about: {
      r.arc = true;
      const Eigen::Vector3d n = segment.axis.normalized();
      const Eigen::Vector3d offset = p0 - segment.point;
      const Eigen::Vector3d along = n * n.dot(offset);
      r.circle.centre = segment.point + along;
      r.circle.normal = n;
      r.circle.start = p0;
      r.circle.radius = (offset - along).norm();
      r.circle.angle = segment.angle;
      if (r.circle.radius < 1e-9)
        bad_argument(
            fmt::format("arc about an axis: the start ({:.6f}, {:.6f}, {:.6f}) m lies on "
                        "the axis (radius {:.3g} m)",
                        p0.x(), p0.y(), p0.z(), r.circle.radius));
      r.orientation = segment.rotate_orientation ? ResolvedSegment::Orientation::turn
                                                 : ResolvedSegment::Orientation::constant;
      r.rotation = segment.rotate_orientation ? std::abs(segment.angle) : 0.0;
      r.length = r.circle.length();
      r.end = Eigen::Isometry3d::Identity();
      r.end.translation() = r.circle.at(1.0);
      r.end.linear() =
          segment.rotate_orientation
              ? Eigen::Matrix3d(Eigen::AngleAxisd(segment.angle, n).toRotationMatrix() * r.r0)
              : r.r0;
      break;
    }
  }
  return r;
}

}  // namespace

CircleArc CircleArc::through(const Eigen::Vector3d& start, const Eigen::Vector3d& via,
                             const Eigen::Vector3d& end) {
  const Eigen::Vector3d a = via - start;
  const Eigen::Vector3d b = end - start;
  const Eigen::Vector3d n = a.cross(b);
  const double scale = a.norm() * b.norm();
  if (!(scale > 1e-18) || n.norm() <= 1e-9 * scale)
    bad_argument(fmt::format(
        "three-point arc: start ({:.6f}, {:.6f}, {:.6f}), via ({:.6f}, "
        "{:.6f}, {:.6f}) and end ({:.6f}, {:.6f}, {:.6f}) m are collinear or "
        "coincide",
        start.x(), start.y(), start.z(), via.x(), via.y(), via.z(), end.x(), end.y(), end.z()));
  CircleArc arc;
  // Circumcentre of the triangle (start, via, end).
  arc.centre = start + (a.squaredNorm() * b.cross(n) + b.squaredNorm() * n.cross(a)) /
                           (2.0 * n.squaredNorm());
  arc.normal = n.normalized();
  arc.start = start;
  arc.radius = (start - arc.centre).norm();
  // (start, via, end) turn counter-clockwise about the normal, so the arc from the start about
  // the normal meets `via` before `end`.
  const Eigen::Vector3d u = start - arc.centre;
  const Eigen::Vector3d w = end - arc.centre;
  double angle = std::atan2(arc.normal.dot(u.cross(w)), u.dot(w));
  if (angle <= 0.0) angle += 2.0 * std::numbers::pi;
  arc.angle = angle;
  return arc;
}

Eigen::Vector3d CircleArc::at(double s) const {
  return centre + Eigen::AngleAxisd(s * angle, normal) * (start - centre);
}

CartesianSegment CartesianSegment::line_to(const Eigen::Isometry3d& end) {
  CartesianSegment s;
  s.kind = Kind::line;
  s.end = end;
  return s;
}

CartesianSegment CartesianSegment::line_by(const Eigen::Vector3d& displacement) {
  CartesianSegment s;
  s.kind = Kind::line_by;
  s.point = displacement;
  return s;
}

CartesianSegment CartesianSegment::arc_through(const Eigen::Vector3d& via,
                                               const Eigen::Isometry3d& end) {
  CartesianSegment s;
  s.kind = Kind::arc_through;
  s.point = via;
  s.end = end;
  return s;
}

CartesianSegment CartesianSegment::arc_about(const Eigen::Vector3d& centre,
                                             const Eigen::Vector3d& axis, double angle,
                                             bool rotate_orientation) {
  CartesianSegment s;
  s.kind = Kind::arc_about;
  s.point = centre;
  s.axis = axis;
  s.angle = angle;
  s.rotate_orientation = rotate_orientation;
  return s;
}

CartesianPathGenerator::CartesianPathGenerator(const RobotModel& model,
                                               std::vector<CartesianSegment> segments,
                                               CartesianOptions options)
    : PlannedMotionGenerator(model), segments_(std::move(segments)), options_(options) {
  if (!kinematics().cartesian())
    throw CommandError(edp::error_code::not_supported,
                       fmt::format("Cartesian path: robot '{}' has no Cartesian kinematics "
                                   "(kinematics solver not set in parameters.toml)",
                                   model.name));
  const auto rep = options_.representation;
  if (rep != edp::ArmRepresentation::frame && rep != edp::ArmRepresentation::xyz_angle_axis &&
      rep != edp::ArmRepresentation::xyz_euler_zyz)
    throw Error(
        fmt::format("Cartesian path: representation {} is not FRAME, XYZ_ANGLE_AXIS or "
                    "XYZ_EULER_ZYZ",
                    edp::to_string(rep)));
  if (options_.profile != ProfileShape::trapezoidal && options_.profile != ProfileShape::quintic)
    throw Error("Cartesian path: unknown profile shape");
  check_positive(options_.max_linear_velocity, "max_linear_velocity", "m/s");
  check_positive(options_.max_linear_acceleration, "max_linear_acceleration", "m/s^2");
  check_positive(options_.max_angular_velocity, "max_angular_velocity", "rad/s");
  check_positive(options_.max_angular_acceleration, "max_angular_acceleration", "rad/s^2");
  check_scale(options_.joint_velocity_scale, "joint_velocity_scale");
  check_scale(options_.joint_acceleration_scale, "joint_acceleration_scale");
  detail::check_macro_step_options(options_.motion_steps, options_.servo_period_s,
                                   "Cartesian path");
  // The tool is a frame: checked (orthonormal, finite) through its 12 values.
  (void)kinematics::frame_from_values(kinematics::frame_to_values(options_.tool));
  kinematics().select_model(options_.kinematic_model_no, options_.corrector_no);
  kinematics().set_tool(options_.tool);

  for (std::size_t i = 0; i < segments_.size(); ++i) {
    const CartesianSegment& s = segments_[i];
    const std::string what =
        fmt::format("Cartesian path segment {} ({})", i + 1, kind_name(s.kind));
    try {
      if (!(std::isfinite(s.duration_s) && s.duration_s >= 0.0))
        bad_argument(fmt::format("duration {} s is not a number >= 0", s.duration_s));
      if (!(s.velocity_scale > 0.0 && s.velocity_scale <= 1.0))
        bad_argument(fmt::format("velocity_scale {} is outside (0, 1]", s.velocity_scale));
      if (!finite(s.point)) bad_argument("a point or displacement is not finite");
      if (s.kind == CartesianSegment::Kind::line || s.kind == CartesianSegment::Kind::arc_through)
        (void)kinematics::frame_from_values(kinematics::frame_to_values(s.end));
      if (s.kind == CartesianSegment::Kind::arc_about) {
        if (!finite(s.axis) || s.axis.norm() < 1e-12)
          bad_argument("the axis is zero or not finite");
        if (!(std::isfinite(s.angle) && std::abs(s.angle) <= 2.0 * std::numbers::pi + 1e-12))
          bad_argument(fmt::format("angle {} rad is outside [-2 pi, 2 pi]", s.angle));
      }
    } catch (...) {
      detail::rethrow_with_context(what + ": ");
    }
  }
}

Eigen::Isometry3d CartesianPathGenerator::forward(const std::vector<double>& joints) const {
  return kinematics().forward(joints);
}

MotionPlan CartesianPathGenerator::make_plan(const std::vector<double>& start_joints) const {
  const RobotModel& m = model();
  const edp::ArmKinematics& kin = kinematics();
  const std::size_t axes = m.axes();

  MotionPlan plan;
  plan.representation = options_.representation;
  plan.motion_steps = options_.motion_steps;
  plan.servo_period_s = options_.servo_period_s;
  plan.start_joints = start_joints;
  if (options_.set_tool_and_model) {
    plan.first_command_sets = static_cast<std::uint8_t>(edp::item::tool | edp::item::model);
    const auto tool = kinematics::frame_to_values(options_.tool);
    plan.tool.assign(tool.begin(), tool.end());
    plan.kinematic_model_no = options_.kinematic_model_no;
    plan.corrector_no = options_.corrector_no;
  }
  const double dt = plan.macro_step_s();

  std::vector<double> max_velocity(axes);
  std::vector<double> max_acceleration(axes);
  for (std::size_t j = 0; j < axes; ++j) {
    max_velocity[j] = m.max_velocity[j] * options_.joint_velocity_scale;
    max_acceleration[j] = m.max_acceleration[j] * options_.joint_acceleration_scale;
  }

  Eigen::Isometry3d from = kin.forward(start_joints);
  plan.start = kinematics::to_vector(from, options_.representation);
  std::vector<double> from_joints = start_joints;

  for (std::size_t i = 0; i < segments_.size(); ++i) {
    const CartesianSegment& seg = segments_[i];
    const std::string context =
        fmt::format("Cartesian path segment {} ({}): ", i + 1, kind_name(seg.kind));
    try {
      const ResolvedSegment path = resolve(seg, from);
      const double k = seg.velocity_scale;
      double v_path = INFINITY;
      double a_path = INFINITY;
      if (path.length > 1e-12) {
        v_path = std::min(v_path, options_.max_linear_velocity * k / path.length);
        a_path = std::min(a_path, options_.max_linear_acceleration * k * k / path.length);
      }
      if (path.rotation > 1e-12) {
        v_path = std::min(v_path, options_.max_angular_velocity * k / path.rotation);
        a_path = std::min(a_path, options_.max_angular_acceleration * k * k / path.rotation);
      }

      PlannedSegment segment;
      segment.first_macro_step = plan.targets.size();
      std::size_t n = 0;
      std::optional<MotionProfile> profile;
      if (!std::isfinite(v_path)) {  // no motion
        if (seg.duration_s <= 0.0) continue;
        n = static_cast<std::size_t>(std::max(1.0, std::ceil(seg.duration_s / dt - 1e-9)));
      } else {
        const MotionProfile fast = MotionProfile::fastest(options_.profile, v_path, a_path);
        if (seg.duration_s > 0.0 && seg.duration_s < fast.duration() * (1.0 - 1e-12))
          throw CommandError(edp::error_code::out_of_limits,
                             fmt::format("duration {} s is shorter than the {:.4f} s the "
                                         "Cartesian velocity and acceleration limits allow",
                                         seg.duration_s, fast.duration()));
        const double duration = seg.duration_s > 0.0 ? seg.duration_s : fast.duration();
        n = static_cast<std::size_t>(std::max(1.0, std::ceil(duration / dt - 1e-9)));
        profile = MotionProfile::with_duration(options_.profile, v_path, a_path,
                                               static_cast<double>(n) * dt);
      }

      std::vector<double> previous = from_joints;
      std::vector<double> previous_velocity(axes, 0.0);
      std::vector<double> velocity(axes, 0.0);
      const auto check_rates = [&](std::size_t step, bool at_rest_after) {
        for (std::size_t j = 0; j < axes; ++j) {
          const double a = (velocity[j] - previous_velocity[j]) / dt;
          if (!at_rest_after && std::abs(velocity[j]) > max_velocity[j] * (1.0 + 1e-9))
            throw CommandError(
                edp::error_code::out_of_limits,
                fmt::format("macro-step {} of {}: joint {} ({}) velocity {:.6f} rad/s exceeds "
                            "the limit {:.6f} rad/s",
                            step, n, j, m.joint_names[j], velocity[j], max_velocity[j]));
          if (std::abs(a) > max_acceleration[j] * (1.0 + 1e-9))
            throw CommandError(
                edp::error_code::out_of_limits,
                fmt::format("macro-step {} of {}: joint {} ({}) acceleration {:.6f} rad/s^2 "
                            "{}exceeds the limit {:.6f} rad/s^2",
                            step, n, j, m.joint_names[j], a,
                            at_rest_after ? "(stopping after the last macro-step) " : "",
                            max_acceleration[j]));
        }
      };
      for (std::size_t step = 1; step <= n; ++step) {
        const double s =
            profile ? (step == n ? 1.0 : profile->position(static_cast<double>(step) * dt)) : 1.0;
        const Eigen::Isometry3d target = profile ? path.at(s) : from;
        std::vector<double> q;
        try {
          q = kin.inverse(target, previous);
          detail::check_macro_step_path(kin, previous, q, options_.motion_steps);
        } catch (...) {
          const Eigen::Vector3d p = target.translation();
          detail::rethrow_with_context(
              fmt::format("macro-step {} of {} (tool at {:.6f} {:.6f} {:.6f} m): ", step, n, p.x(),
                          p.y(), p.z()));
        }
        for (std::size_t j = 0; j < axes; ++j) velocity[j] = (q[j] - previous[j]) / dt;
        check_rates(step, false);
        previous_velocity = velocity;
        previous = q;
        plan.targets.push_back(kinematics::to_vector(target, options_.representation));
        plan.joints.push_back(std::move(q));
      }
      std::fill(velocity.begin(), velocity.end(), 0.0);
      check_rates(n, true);

      segment.macro_steps = n;
      segment.profile = profile;
      plan.segments.push_back(segment);
      from = path.end;
      from_joints = previous;
    } catch (...) {
      detail::rethrow_with_context(context);
    }
  }
  return plan;
}

}  // namespace mrroc::ecp
