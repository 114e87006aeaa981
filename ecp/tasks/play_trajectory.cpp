// Stock ECP task "play_trajectory": synchronises the robot (skipped when the EDP already is), then
// plays a teach-in trajectory file back (the web console's "Record pose", or ecp::TeachInRecorder)
// with TeachInPlaybackGenerator: one rest-to-rest segment per recorded pose, within fractions of
// the robot's limits. The file is read when the task runs, so it may be recorded after the set
// started. Arguments ([robot.ecp.args]):
//   file = "irb6.traj"         the trajectory; a relative path is taken from the config file's
//                              folder (the console writes to [ui] teach_dir)
//   velocity_scale = 0.5       (0, 1]: fraction of the joints' velocity limits (JOINT and MOTOR
//                              files) or of the joint velocity a Cartesian path may ask for
//   acceleration_scale = 0.5   (0, 1]: the same for the acceleration limits
//   motion_steps = 10          servo steps per macro-step (2..1000)
#include <filesystem>

#include <fmt/format.h>
#include <fmt/ranges.h>

#include "mrroc/config/check.hpp"
#include "mrroc/ecp/generators/teach_in.hpp"
#include "mrroc/ecp/generators/trajectory_file.hpp"
#include "mrroc/ecp/task.hpp"

namespace mrroc::ecp {

namespace {

/// The fraction `key` (default 0.5); one of another type or outside (0, 1] is added to `errors`
/// at its line and the default used.
double fraction(const Params& args, const std::string& key, ConfigErrorList& errors) {
  double value = 0.5;
  errors.run(args.location_of(key), [&] {
    const double given = args.get_double(key, 0.5);
    if (!(given > 0.0 && given <= 1.0))
      throw ConfigError(
          args.location_of(key),
          fmt::format("{} {} is outside (0, 1] (a fraction of the robot's limits)", key, given));
    value = given;
  });
  return value;
}

}  // namespace

class PlayTrajectory : public EcpTask {
 public:
  explicit PlayTrajectory(TaskContext& context) : context_(context) {
    const Params& args = context.args;
    // Every argument checked on its own at its own line: a mistake in one does not hide the
    // others.
    ConfigErrorList errors;
    errors.run(args.location_of("file"), [&] {
      const SourceLocation where = args.location_of("file");
      std::filesystem::path file = args.get_string("file");
      if (file.empty()) throw ConfigError(where, "file is empty (a trajectory file is needed)");
      if (file.is_relative() && !where.file.empty())
        file = std::filesystem::path(where.file).parent_path() / file;
      file_ = file.lexically_normal();
    });
    const double velocity = fraction(args, "velocity_scale", errors);
    const double acceleration = fraction(args, "acceleration_scale", errors);
    std::int64_t steps = 10;
    errors.run(args.location_of("motion_steps"), [&] {
      const std::int64_t given = args.get_int("motion_steps", 10);
      if (given < 2 || given > 1000)
        throw ConfigError(args.location_of("motion_steps"),
                          fmt::format("motion_steps {} is outside 2..1000", given));
      steps = given;
    });
    errors.run(args.location(), [&] { args.reject_unread("robot.ecp.args"); });
    errors.throw_if_any();
    options_.interpolation.velocity_scale = velocity;
    options_.interpolation.acceleration_scale = acceleration;
    options_.interpolation.motion_steps = static_cast<int>(steps);
    options_.interpolation.servo_period_s = context.servo_period_s;
    options_.cartesian.joint_velocity_scale = velocity;
    options_.cartesian.joint_acceleration_scale = acceleration;
    options_.cartesian.motion_steps = static_cast<int>(steps);
    options_.cartesian.servo_period_s = context.servo_period_s;
  }

  void main_task() override {
    Robot& robot = context_.robot;
    // Read and check the whole file before anything moves.
    if (!std::filesystem::exists(file_))
      throw Error(
          fmt::format("{}: error: no such trajectory file (record poses first, e.g. with "
                      "the web console's Record pose)",
                      file_.string()));
    const TrajectoryFile trajectory = TrajectoryFile::load(file_);
    if (trajectory.points.empty())
      throw Error(
          fmt::format("{}: the trajectory holds no pose (record some first)", file_.string()));
    robot.synchronise();
    TeachInPlaybackGenerator generator(robot.model(), trajectory, options_);
    context_.reporter.info(fmt::format("playing {} pose(s) of {} from [{:.4f}]",
                                       trajectory.points.size(), file_.string(),
                                       fmt::join(robot.image().joints, ", ")));
    Move(robot, {}, generator);
    context_.reporter.info(fmt::format("trajectory played: joints [{:.4f}] rad",
                                       fmt::join(robot.image().joints, ", ")));
  }

 private:
  TaskContext& context_;
  std::filesystem::path file_;
  TeachInPlaybackOptions options_;
};

MRROC_REGISTER_ECP_TASK("play_trajectory", PlayTrajectory);

}  // namespace mrroc::ecp
