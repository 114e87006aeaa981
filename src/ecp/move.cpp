#include <chrono>
#include <thread>

#include "mrroc/core/process.hpp"
#include "mrroc/ecp/generator.hpp"
#include "mrroc/ecp/robot.hpp"

namespace mrroc::ecp {

namespace {
void refresh(const SensorList& sensors) {
  for (Sensor* s : sensors) s->initiate_reading();
  for (Sensor* s : sensors) s->get_reading();
}
/// Throws on a stop request; returns true when a pause held the task.
bool check_stop(Robot& robot) {
  if (robot.stop_requested() || mrroc::stop_requested())
    throw TaskStopped("task stopped on request");
  return robot.wait_while_paused();
}
/// check_stop() in the middle of a motion: before a pause holds the task or a stop ends it, the
/// EDP learns that no macro-step follows, so the robot comes to rest as a planned stop.
bool check_stop_moving(Robot& robot) {
  if (robot.stop_requested() || mrroc::stop_requested() || robot.paused())
    robot.announce_no_successor();
  return check_stop(robot);
}
/// The macro-step `c` read its arm early: it promised the EDP a successor.
bool promises_successor(const edp::Instruction& c) {
  return (c.type == edp::InstructionType::set || c.type == edp::InstructionType::set_get) &&
         (c.set & edp::item::arm) != 0 && c.value_in_step_no < c.motion_steps;
}
}  // namespace

void Move(Robot& robot, const SensorList& sensors, Generator& generator) {
  constexpr int kMaxRefusals = 3;
  bool promised = false;  // the last macro-step sent promised a successor
  check_stop(robot);
  refresh(sensors);
  bool more = generator.first_step(robot.image(), sensors);
  int refusals = 0;
  while (more) {
    try {
      robot.execute();
      promised = promises_successor(robot.image().command);
      refusals = 0;
    } catch (const EdpRefused& e) {
      // A late macro-step made the EDP stop the robot off the planned path, and the planned
      // continuation would be too fast or too abrupt from there: re-plan from where it stands.
      const bool replan =
          e.code() == edp::error_code::too_fast || e.code() == edp::error_code::too_abrupt;
      if (!replan || ++refusals > kMaxRefusals) throw;
      robot.read_state();
      if (!generator.resume(robot.image(), sensors)) throw;
      continue;
    }
    refresh(sensors);
    if (check_stop_moving(robot)) {
      // After a pause the robot stands (its EDP ran out of macro-steps): continue from there.
      robot.read_state();
      if (generator.resume(robot.image(), sensors)) continue;
    }
    more = generator.next_step(robot.image(), sensors);
  }
  // A generator that ends after a macro-step that promised a successor (a guarded move that
  // felt its contact) stops the robot on purpose: the EDP's ramp is a planned stop.
  if (promised) robot.announce_no_successor();
}

bool RobotCondition::check(const SensorList&) {
  throw Error(
      "a RobotCondition decides from the robot image too: use it in Wait or a guarded move, "
      "which call holds(robot, sensors)");
}

void Wait(Robot& robot, const SensorList& sensors, Condition& condition, double period_s) {
  auto* on_robot = dynamic_cast<RobotCondition*>(&condition);
  for (;;) {
    check_stop(robot);
    refresh(sensors);
    if (on_robot != nullptr) {
      RobotImage& image = robot.image();
      const edp::Instruction saved = image.command;
      image.command = edp::Instruction{};
      image.command.type = edp::InstructionType::get;
      image.command.get = on_robot->items();
      image.command.get_arm_type = edp::ArmRepresentation::joint;
      robot.execute();
      image.command = saved;
      if (on_robot->holds(image, sensors)) return;
    } else if (condition.check(sensors)) {
      return;
    }
    std::this_thread::sleep_for(std::chrono::duration<double>(period_s));
  }
}

}  // namespace mrroc::ecp
