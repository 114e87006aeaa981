// Stock ECP task "grasp_part": picks a part up with the gripper of a Gripper robot
// (ecp/tasks/gripper.hpp), lifts it, checks it still holds it, puts it back and lets go.
//   [robot.ecp.args]
//   above = [...]      joint pose [rad] above the part, the fingers open around nothing
//   grasp = [...]      joint pose [rad] with the part between the fingers
//   lift = [...]       joint pose [rad] with the part lifted
//   force = 20.0       closing force [N]
//   velocity_scale, acceleration_scale (0.5), motion_steps (10): as visit_joint_poses
// Configs: configs/gripper-irb6.toml (robots/irb6/irb6_gripper.xml).
#include <fmt/format.h>

#include "gripper.hpp"
#include "joint_motion_options.hpp"
#include "mrroc/config/check.hpp"
#include "mrroc/ecp/generators/joint_poses.hpp"
#include "mrroc/ecp/task.hpp"

namespace mrroc::ecp {

class GraspPart : public EcpTask {
 public:
  explicit GraspPart(TaskContext& context)
      : context_(context), gripper_(context.robot_as<Gripper>()) {
    const Params& args = context.args;
    // Every argument checked on its own at its own line: a mistake in one does not hide the
    // others.
    ConfigErrorList errors;
    const RobotModel& model = gripper_.model();
    for (const char* key : {"above", "grasp", "lift"}) {
      std::vector<double>& pose = pose_of(key);
      errors.run(args.location_of(key), [&] {
        pose = args.get_doubles(key);
        model.check_joint_limits(pose, key);
      });
    }
    errors.run(args.location_of("force"), [&] {
      force_ = args.get_double("force", 20.0);
      if (!(force_ > 0.0 && force_ <= Gripper::kMaxForce))
        throw ConfigError(fmt::format("force {} N is outside (0, {}] N of the gripper", force_,
                                      Gripper::kMaxForce));
    });
    options_ = joint_motion_options(args, context.servo_period_s, errors);
    errors.run(args.location(), [&] { args.reject_unread("robot.ecp.args"); });
    if (errors.empty())
      errors.run(args.location_of("above"), [&] {
        JointPosesGenerator check(model, {above_, grasp_, lift_, grasp_, above_}, options_);
      });
    errors.throw_if_any();
  }

  void main_task() override {
    Reporter& report = context_.reporter;
    gripper_.synchronise();
    gripper_.open();
    move_to(above_);
    move_to(grasp_);
    gripper_.close(force_);
    if (!gripper_.holding())
      throw Error(
          fmt::format("the gripper closed to {:.5f} m without holding the part", gripper_.width()));
    report.info(fmt::format("holding the part: opening {:.5f} m, grip force {:.1f} N",
                            gripper_.width(), gripper_.force()));
    move_to(lift_);
    gripper_.read_device();
    if (!gripper_.holding())
      throw Error(
          fmt::format("the part slipped out during the lift (opening {:.5f} m)", gripper_.width()));
    report.info(fmt::format("lifted, still holding: opening {:.5f} m, grip force {:.1f} N",
                            gripper_.width(), gripper_.force()));
    move_to(grasp_);
    gripper_.open();
    report.info(fmt::format("put back and released: opening {:.5f} m, holding {}", gripper_.width(),
                            gripper_.holding() ? "yes" : "no"));
    move_to(above_);
  }

 private:
  std::vector<double>& pose_of(const std::string& key) {
    return key == "above" ? above_ : key == "grasp" ? grasp_ : lift_;
  }
  void move_to(const std::vector<double>& pose) {
    JointPosesGenerator generator(gripper_.model(), {pose}, options_);
    Move(gripper_, {}, generator);
  }

  TaskContext& context_;
  Gripper& gripper_;
  std::vector<double> above_;
  std::vector<double> grasp_;
  std::vector<double> lift_;
  double force_ = 20.0;
  JointPosesOptions options_;
};

MRROC_REGISTER_ECP_TASK_WITH_ROBOT("grasp_part", GraspPart, Gripper);

}  // namespace mrroc::ecp
