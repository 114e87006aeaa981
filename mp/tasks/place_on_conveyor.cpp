// Stock MP task "place_on_conveyor": loose cooperation (paper, section 2). The IRb-6 carries an
// object to the conveyor's loading station and releases it; only then (the MP synchronises the
// two ECPs) does the conveyor carry it away, while the arm retreats.
//
// [mp.args]: arm = "irb6", conveyor = "conveyor" (robot names), approach / place / retreat
// (joint poses of the arm [rad]), belt_target (conveyor position [m]), gripper_output (bit).
#include <fmt/format.h>
#include <fmt/ranges.h>

#include <cmath>

#include "mrroc/mp/task.hpp"

namespace mrroc::mp {

namespace {
std::string poses_argument(const std::vector<std::vector<double>>& poses) {
  std::string rows;
  for (const auto& p : poses)
    rows += fmt::format("{}[{}]", rows.empty() ? "" : ", ", fmt::join(p, ", "));
  return fmt::format("poses = [{}]\n", rows);
}
}  // namespace

class PlaceOnConveyor : public MpTask {
 public:
  static constexpr double kDeliveryTolerance = 0.002;  // [m]

  explicit PlaceOnConveyor(TaskContext& context)
      : context_(context),
        arm_(context.robot(context.args.get_string("arm", "irb6"))),
        conveyor_(context.robot(context.args.get_string("conveyor", "conveyor"))),
        approach_(context.args.get_doubles("approach")),
        place_(context.args.get_doubles("place")),
        retreat_(context.args.get_doubles("retreat")),
        belt_target_(context.args.get_double("belt_target")),
        gripper_(context.args.get_int("gripper_output", 1)) {
    context.args.reject_unread("mp.args");
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
                     poses_argument({{belt_target_}}) + "velocity_scale = 0.8\n");
      } else {
        r.next_state("visit_joint_poses", poses_argument({retreat_}));
      }
    });
    const double belt = conveyor_.image().joints.empty() ? 0.0 : conveyor_.image().joints[0];
    if (std::abs(belt - belt_target_) > kDeliveryTolerance)
      throw Error(
          fmt::format("object not delivered: {} at {:.4f} m, target {:.4f} m (tolerance "
                      "{:.4f} m)",
                      conveyor_.name(), belt, belt_target_, kDeliveryTolerance));
    log.info(fmt::format("object delivered: {} at {:.4f} m", conveyor_.name(), belt));
  }

 private:
  TaskContext& context_;
  Robot& arm_;
  Robot& conveyor_;
  std::vector<double> approach_, place_, retreat_;
  double belt_target_;
  std::int64_t gripper_;
};

MRROC_REGISTER_MP_TASK("place_on_conveyor", PlaceOnConveyor);

}  // namespace mrroc::mp
