// Stock MP task "place_on_conveyor": loose cooperation (paper, section 2). The IRb-6 carries an
// object to the conveyor's loading station and releases it; only then (the MP synchronises the
// two ECPs) does the conveyor carry it away, while the arm retreats.
//
// [mp.args]: arm = "irb6", conveyor = "conveyor" (robot names), approach / place / retreat
// (joint poses of the arm [rad]), belt_target (conveyor position [m]), gripper_output (bit).
#include <fmt/format.h>
#include <fmt/ranges.h>

#include <cmath>

#include "mrroc/config/check.hpp"
#include "mrroc/mp/task.hpp"
#include "mrroc/robot/robot_model.hpp"

namespace mrroc::mp {

namespace {
std::string poses_argument(const std::vector<std::vector<double>>& poses) {
  std::string rows;
  for (const auto& p : poses)
    rows += fmt::format("{}[{}]", rows.empty() ? "" : ", ", fmt::join(p, ", "));
  return fmt::format("poses = [{}]\n", rows);
}

/// The joint pose `q` given as argument `key`, checked now (so that `mrroc-launch --check` finds
/// it) against the joint count and limits of the robot it is for, as its ECP and EDP would check
/// it.
/// @throws ConfigError at the argument naming the joint, the value, the unit and the limit.
std::vector<double> joint_pose(const TaskContext& context, const std::string& key,
                               const RobotModel& model, std::vector<double> q) {
  try {
    model.check_joint_limits(q, key.c_str());
  } catch (const Error& e) {
    throw ConfigError(context.args.location_of(key), e.what());
  }
  return q;
}
}  // namespace

class PlaceOnConveyor : public MpTask {
 public:
  static constexpr double kDeliveryTolerance = 0.002;  // [m]

  explicit PlaceOnConveyor(TaskContext& context)
      : context_(context),
        arm_(context.robot(context.args.get_string("arm", "irb6"))),
        conveyor_(context.robot(context.args.get_string("conveyor", "conveyor"))),
        gripper_(context.args.get_int("gripper_output", 1)) {
    // Every pose is checked, each error reported (ConfigErrors).
    ConfigErrorList errors;
    const Params& a = context.args;
    const SourceLocation& at = a.location();
    const auto model_of = [&](const Robot& r) {
      return load_robot_model(context.config.robot(r.name()).model_dir);
    };
    const RobotModel arm = model_of(arm_);
    const RobotModel conveyor = model_of(conveyor_);
    errors.run(
        at, [&] { approach_ = joint_pose(context, "approach", arm, a.get_doubles("approach")); });
    errors.run(at, [&] { place_ = joint_pose(context, "place", arm, a.get_doubles("place")); });
    errors.run(at,
               [&] { retreat_ = joint_pose(context, "retreat", arm, a.get_doubles("retreat")); });
    errors.run(at, [&] {
      belt_target_ = joint_pose(context, "belt_target", conveyor, {a.get_double("belt_target")});
    });
    errors.run(at, [&] { a.reject_unread("mp.args"); });
    errors.throw_if_any();
  }

  void main_task() override {
    Reporter& log = context_.reporter;
    parallel({&arm_, &conveyor_}, [](Robot& r) { r.start_task(); });  // follow_mp: synchronise
    log.info("both robots synchronised");
    arm_.next_state("set_outputs", fmt::format("outputs = {}\n", gripper_));  // grip
    arm_.next_state("visit_joint_poses", poses_argument({approach_, place_}));
    arm_.next_state("set_outputs", "outputs = 0\n");  // release
    log.info(fmt::format("object placed on the conveyor by {}", arm_.name()));
    // Synchronisation point: the conveyor starts only now, the arm retreats meanwhile.
    parallel({&arm_, &conveyor_}, [&](Robot& r) {
      if (&r == &conveyor_) {
        log.info(fmt::format("{} carries the object away", conveyor_.name()));
        r.next_state("visit_joint_poses",
                     poses_argument({belt_target_}) + "velocity_scale = 0.8\n");
      } else {
        r.next_state("visit_joint_poses", poses_argument({retreat_}));
      }
    });
    const double belt = conveyor_.image().joints.empty() ? 0.0 : conveyor_.image().joints[0];
    if (std::abs(belt - belt_target_[0]) > kDeliveryTolerance)
      throw Error(
          fmt::format("object not delivered: {} at {:.4f} m, target {:.4f} m (tolerance "
                      "{:.4f} m)",
                      conveyor_.name(), belt, belt_target_[0], kDeliveryTolerance));
    log.info(fmt::format("object delivered: {} at {:.4f} m", conveyor_.name(), belt));
  }

 private:
  TaskContext& context_;
  Robot& arm_;
  Robot& conveyor_;
  std::vector<double> approach_, place_, retreat_;
  std::vector<double> belt_target_;  ///< the conveyor's one joint [m]
  std::int64_t gripper_;
};

MRROC_REGISTER_MP_TASK("place_on_conveyor", PlaceOnConveyor);

}  // namespace mrroc::mp
