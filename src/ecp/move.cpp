#include <chrono>
#include <thread>

#include "mrroc/core/process.hpp"
#include "mrroc/ecp/generator.hpp"

namespace mrroc::ecp {

namespace {
void refresh(const SensorList& sensors) {
  for (Sensor* s : sensors) s->initiate_reading();
  for (Sensor* s : sensors) s->get_reading();
}
void check_stop(Robot& robot) {
  if (robot.stop_requested() || mrroc::stop_requested())
    throw TaskStopped("task stopped on request");
  robot.wait_while_paused();
}
}  // namespace

void Move(Robot& robot, const SensorList& sensors, Generator& generator) {
  check_stop(robot);
  refresh(sensors);
  if (!generator.first_step(robot.image(), sensors)) return;
  do {
    robot.execute();
    refresh(sensors);
    check_stop(robot);
  } while (generator.next_step(robot.image(), sensors));
}

void Wait(Robot& robot, const SensorList& sensors, Condition& condition, double period_s) {
  for (;;) {
    check_stop(robot);
    refresh(sensors);
    if (condition.check(sensors)) return;
    std::this_thread::sleep_for(std::chrono::duration<double>(period_s));
  }
}

}  // namespace mrroc::ecp
