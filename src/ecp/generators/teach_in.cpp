#include "mrroc/ecp/generators/teach_in.hpp"

#include <fmt/format.h>

#include <cmath>

#include "mrroc/core/error.hpp"
#include "mrroc/kinematics/pose.hpp"

namespace mrroc::ecp {

namespace {
bool is_cartesian(edp::ArmRepresentation r) {
  return r == edp::ArmRepresentation::frame || r == edp::ArmRepresentation::xyz_euler_zyz ||
         r == edp::ArmRepresentation::xyz_angle_axis;
}
}  // namespace

TeachInRecorder::TeachInRecorder(const RobotModel& model, edp::ArmRepresentation representation,
                                 Source source, const Eigen::Isometry3d& tool)
    : model_(model), kinematics_(edp::make_arm_kinematics(model)), source_(source) {
  if (!representation_from_string(edp::to_string(representation)))
    throw Error(
        fmt::format("teach-in: representation {} is unknown", static_cast<int>(representation)));
  if (is_cartesian(representation) && !kinematics_->cartesian())
    throw CommandError(edp::error_code::not_supported,
                       fmt::format("teach-in: robot '{}' has no Cartesian kinematics for {}",
                                   model.name, edp::to_string(representation)));
  kinematics_->set_tool(tool);
  trajectory_.representation = representation;
  trajectory_.axes = model.axes();
  trajectory_.robot = model.name;
}

const TrajectoryPoint& TeachInRecorder::record(const RobotImage& image,
                                               std::optional<double> duration_s,
                                               std::optional<double> velocity_scale) {
  const std::vector<double>& q = source_ == Source::measured ? image.joints : image.desired_joints;
  if (q.size() != model_.axes())
    throw Error(
        fmt::format("teach-in: the robot image has {} {} joint values, robot '{}' has {} "
                    "axes (read the robot state first)",
                    q.size(), source_ == Source::measured ? "measured" : "desired", model_.name,
                    model_.axes()));
  for (std::size_t j = 0; j < q.size(); ++j)
    if (!std::isfinite(q[j]))
      throw Error(
          fmt::format("teach-in: joint {} ({}) value is not finite", j, model_.joint_names[j]));
  if (duration_s && !(std::isfinite(*duration_s) && *duration_s > 0.0))
    throw Error(fmt::format("teach-in: duration {} s is not > 0", *duration_s));
  if (velocity_scale && !(*velocity_scale > 0.0 && *velocity_scale <= 1.0))
    throw Error(fmt::format("teach-in: velocity_scale {} is outside (0, 1]", *velocity_scale));
  if (duration_s && velocity_scale)
    throw Error("teach-in: a pose has either a duration or a velocity scale, not both");

  TrajectoryPoint point;
  switch (trajectory_.representation) {
    case edp::ArmRepresentation::joint: point.values = q; break;
    case edp::ArmRepresentation::motor: point.values = kinematics_->motors_from_joints(q); break;
    default:
      point.values = kinematics::to_vector(kinematics_->forward(q), trajectory_.representation);
      break;
  }
  point.duration_s = duration_s;
  point.velocity_scale = velocity_scale;
  trajectory_.points.push_back(std::move(point));
  return trajectory_.points.back();
}

void TeachInRecorder::remove_last() {
  if (!trajectory_.points.empty()) trajectory_.points.pop_back();
}

void TeachInRecorder::clear() { trajectory_.points.clear(); }

TeachInPlaybackGenerator::TeachInPlaybackGenerator(const RobotModel& model,
                                                   const TrajectoryFile& trajectory,
                                                   TeachInPlaybackOptions options)
    : PlannedMotionGenerator(model) {
  if (trajectory.axes != model.axes())
    throw CommandError(edp::error_code::bad_argument,
                       fmt::format("teach-in playback: the trajectory is for {} axes, robot '{}' "
                                   "has {}",
                                   trajectory.axes, model.name, model.axes()));
  if (!trajectory.robot.empty() && trajectory.robot != model.name)
    throw CommandError(edp::error_code::bad_argument,
                       fmt::format("teach-in playback: the trajectory was recorded on robot "
                                   "'{}', this is '{}'",
                                   trajectory.robot, model.name));
  const std::size_t expected = trajectory.values_per_point();
  for (std::size_t i = 0; i < trajectory.points.size(); ++i)
    if (trajectory.points[i].values.size() != expected)
      throw CommandError(edp::error_code::bad_argument,
                         fmt::format("teach-in playback: point {} has {} values, {} expected",
                                     i + 1, trajectory.points[i].values.size(), expected));

  if (is_cartesian(trajectory.representation)) {
    std::vector<CartesianSegment> segments;
    segments.reserve(trajectory.points.size());
    for (std::size_t i = 0; i < trajectory.points.size(); ++i) {
      const TrajectoryPoint& p = trajectory.points[i];
      Eigen::Isometry3d frame;
      try {
        frame = kinematics::from_vector(p.values, trajectory.representation);
      } catch (...) {
        detail::rethrow_with_context(fmt::format("teach-in playback: point {}: ", i + 1));
      }
      CartesianSegment s = CartesianSegment::line_to(frame);
      s.duration_s = p.duration_s.value_or(0.0);
      s.velocity_scale = p.velocity_scale.value_or(1.0);
      segments.push_back(s);
    }
    CartesianOptions cartesian = options.cartesian;
    cartesian.representation = trajectory.representation;
    playback_ = std::make_unique<CartesianPathGenerator>(model, std::move(segments), cartesian);
  } else {
    std::vector<Waypoint> waypoints;
    waypoints.reserve(trajectory.points.size());
    for (const TrajectoryPoint& p : trajectory.points) {
      Waypoint w;
      w.position = p.values;
      w.duration_s = p.duration_s.value_or(0.0);
      w.velocity_scale = p.velocity_scale.value_or(1.0);
      waypoints.push_back(std::move(w));
    }
    InterpolationOptions interpolation = options.interpolation;
    interpolation.representation = trajectory.representation;
    playback_ =
        std::make_unique<InterpolationGenerator>(model, std::move(waypoints), interpolation);
  }
}

MotionPlan TeachInPlaybackGenerator::make_plan(const std::vector<double>& start_joints) const {
  return playback_->plan_from(start_joints);
}

}  // namespace mrroc::ecp
