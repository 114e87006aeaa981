// Stock MP task "tool_path": the MP generates one robot's tool frame every macro-step along a
// path of points (straight segments, each rest to rest with a quintic time law) at a fixed
// orientation, and sends it as NEXT_POSE (tight coordination, paper section 2). The robot's ECP
// runs `follow_mp` (the poses go to the EDP as they are) or `follow_mp_compliant` (it corrects
// each pose from its wrist force: hybrid control, configs/sensing-hybrid.toml).
//
// [mp.args]: robot = "name", path = [[x, y, z], ...] (tool position in the robot's base frame
// [m]), rotation = [rx, ry, rz] (the tool's orientation, a rotation vector [rad]), speed [m/s]
// (peak, at most 0.5) or speeds = [...] (one per segment), motion_steps (servo steps per
// macro-step, 4..1000).
#include <fmt/format.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>

#include "mrroc/config/check.hpp"
#include "mrroc/ecp/generator.hpp"
#include "mrroc/kinematics/pose.hpp"
#include "mrroc/mp/task.hpp"
#include "straight_path.hpp"

namespace mrroc::mp {

namespace {

class ToolPathGenerator : public Generator {
 public:
  ToolPathGenerator(const Eigen::Matrix3d& orientation, std::vector<Eigen::Vector3d> path,
                    std::vector<double> speeds, int motion_steps, double servo_period_s)
      : orientation_(orientation),
        start_(path.front()),
        path_(std::move(path), std::move(speeds), motion_steps * servo_period_s),
        steps_(motion_steps) {}

  bool first_step(const ImageList& robots, const ecp::SensorList&) override {
    // To the path's first point in one long macro-step (2 s), then half a second at rest there.
    command(robots, start_, 1000, 1001);
    approaching_ = true;
    return true;
  }

  bool next_step(const ImageList& robots, const ecp::SensorList&) override {
    if (approaching_) {
      approaching_ = false;
      command(robots, start_, 250, 251);
      return true;
    }
    Eigen::Vector3d point;
    if (!path_.next(point)) return false;
    // Read a third of the macro-step early: the next pose passes the ECP (and its sensors, when
    // it corrects the pose) before it is queued in the EDP.
    command(robots, point, steps_, path_.at_end() ? steps_ + 1 : ecp::early_reading_step(steps_));
    return true;
  }

  [[nodiscard]] int macro_steps() const { return macro_total_; }

 private:
  void command(const ImageList& robots, const Eigen::Vector3d& position, int steps, int value) {
    Eigen::Isometry3d tool = Eigen::Isometry3d::Identity();
    tool.linear() = orientation_;
    tool.translation() = position;
    ecp::MpCommand& c = robots[0]->command;
    c.arm_type = edp::ArmRepresentation::frame;
    c.motion_type = edp::MotionType::absolute;
    c.motion_steps = steps;
    c.value_in_step_no = value;
    c.arm = kinematics::to_vector(tool, edp::ArmRepresentation::frame);
    robots[0]->commanded = true;
    ++macro_total_;
  }

  Eigen::Matrix3d orientation_;
  Eigen::Vector3d start_;
  StraightPath path_;
  int steps_;
  bool approaching_ = true;
  int macro_total_ = 0;
};

}  // namespace

class ToolPath : public MpTask {
 public:
  explicit ToolPath(TaskContext& context) : context_(context) {
    const Params& args = context.args;
    // Every argument checked on its own at its own line: a mistake in one does not hide the
    // others.
    ConfigErrorList errors;
    errors.run(args.location_of("robot"),
               [&] { robot_ = &context.robot(args.get_string("robot")); });
    const bool have_path =
        errors.run(args.location_of("path"), [&] { path_ = read_path_points(args); });
    errors.run(args.location_of("rotation"), [&] {
      const std::vector<double> r = args.get_doubles("rotation", {0.0, 0.0, 0.0});
      if (r.size() != 3)
        throw ConfigError(args.location_of("rotation"),
                          "'rotation' is a rotation vector [rx, ry, rz] (rad)");
      const Eigen::Vector3d axis(r[0], r[1], r[2]);
      orientation_ = axis.norm() > 0.0
                         ? Eigen::AngleAxisd(axis.norm(), axis.normalized()).toRotationMatrix()
                         : Eigen::Matrix3d::Identity();
    });
    // The speeds: one for every segment, or one for all; counted only against a valid path.
    const char* key = args.has("speeds") ? "speeds" : "speed";
    errors.run(args.location_of(key), [&] {
      const std::size_t segments = have_path ? path_.size() - 1 : 0;
      const double speed = args.get_double("speed", 0.02);
      speeds_ = args.get_doubles("speeds",
                                 std::vector<double>(std::max<std::size_t>(segments, 1), speed));
      if (have_path && speeds_.size() != segments)
        throw ConfigError(
            args.location_of(key),
            fmt::format("'speeds' has {} values for {} segments", speeds_.size(), segments));
      for (double v : speeds_)
        if (!(v > 0.0 && v <= 0.5))
          throw ConfigError(args.location_of(key),
                            fmt::format("{} {} m/s is outside (0, 0.5] m/s", key, v));
    });
    errors.run(args.location_of("motion_steps"), [&] {
      const std::int64_t steps = args.get_int("motion_steps", 10);
      if (steps < 4 || steps > 1000)
        throw ConfigError(args.location_of("motion_steps"),
                          fmt::format("motion_steps {} is outside 4..1000 servo steps", steps));
      motion_steps_ = static_cast<int>(steps);
    });
    errors.run(args.location(), [&] { args.reject_unread("mp.args"); });
    errors.throw_if_any();
  }

  void main_task() override {
    robot_->start_task();  // the ECP's task: synchronise (and, when compliant, zero its sensor)
    ToolPathGenerator generator(orientation_, path_, speeds_, motion_steps_,
                                context_.config.robot(robot_->name()).edp.servo_period_s);
    Move(RobotList{robot_}, {}, generator);
    context_.reporter.info(fmt::format("tool path of {} points done in {} macro-steps",
                                       path_.size(), generator.macro_steps()));
  }

 private:
  TaskContext& context_;
  Robot* robot_ = nullptr;
  std::vector<Eigen::Vector3d> path_;
  Eigen::Matrix3d orientation_;
  std::vector<double> speeds_;
  int motion_steps_ = 10;
};

MRROC_REGISTER_MP_TASK("tool_path", ToolPath);

}  // namespace mrroc::mp
