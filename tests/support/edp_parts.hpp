#pragma once
// The parts of an EDP as the EDP unit tests build them (no LCM): a robot's model, its hardware
// plugin configured for the servo period, its kinematics; the tests then build the servo loop
// and command interpreter on them, each with the options it examines.
#include <sched.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "motion_blend.hpp"
#include "mrroc/config/params.hpp"
#include "mrroc/edp/arm_kinematics.hpp"
#include "mrroc/edp/hardware.hpp"
#include "mrroc/msg/edp_instruction.hpp"
#include "mrroc/robot/robot_model.hpp"

namespace mrroc::test {

/// `plugin` for robot `model`, configured for `period_s` with `params`.
inline std::unique_ptr<edp::Hardware> configured_hardware(const RobotModel& model,
                                                          const std::string& plugin,
                                                          double period_s, Params params = {}) {
  std::unique_ptr<edp::Hardware> hardware = edp::make_hardware(plugin);
  edp::HardwareSetup setup;
  setup.robot = model.name;
  setup.model_dir = model.folder;
  setup.servo_period_s = period_s;
  setup.synchro_positions = model.synchro_joint_positions;
  setup.params = std::move(params);
  hardware->configure(setup);
  return hardware;
}

/// SET ARM JOINT to `q` in `steps` servo steps, read in step `value_in_step_no`.
inline edp::Instruction set_joints_instruction(std::vector<double> q, int steps,
                                               int value_in_step_no,
                                               edp::MotionType motion = edp::MotionType::absolute) {
  edp::Instruction in;
  in.type = edp::InstructionType::set;
  in.set = edp::item::arm;
  in.set_arm_type = edp::ArmRepresentation::joint;
  in.motion_type = motion;
  in.motion_steps = steps;
  in.value_in_step_no = value_in_step_no;
  in.arm = std::move(q);
  return in;
}

/// Servo steps of the shortest macro-step from rest at `from` to rest at `to` within every joint's
/// velocity and acceleration limit, both scaled by `share` (edp::shortest_rest_to_rest_steps).
inline int rest_to_rest_steps(const RobotModel& model, const std::vector<double>& from,
                              const std::vector<double>& to, double period_s, double share = 1.0) {
  int steps = 1;
  for (std::size_t j = 0; j < model.axes() && j < from.size() && j < to.size(); ++j)
    steps = std::max(
        steps, edp::shortest_rest_to_rest_steps(to[j] - from[j], share * model.max_velocity[j],
                                                share * model.max_acceleration[j], period_s));
  return steps;
}

/// One joint at a constant `velocity` [rad/s] as macro-steps (target, servo steps) the EDP runs
/// within the joint's acceleration limit: a first macro-step of `ramp_steps` from rest at `start`
/// whose mean velocity is `velocity` (without a successor queued yet the EDP ends it at that
/// velocity, accelerating at 3 velocity / T in its first half and decelerating at velocity / T in
/// its second), `segments` macro-steps of `steps` at `velocity` (constant: they start and end at
/// it), and a last one of `ramp_steps` at half the velocity that brings the joint to rest
/// (decelerating uniformly at velocity / T).
inline std::vector<std::pair<double, int>> cruise(double start, double velocity, int ramp_steps,
                                                  int steps, int segments, double period_s) {
  std::vector<std::pair<double, int>> out;
  const double ramp = velocity * ramp_steps * period_s;
  out.emplace_back(start + ramp, ramp_steps);
  for (int k = 1; k <= segments; ++k)
    out.emplace_back(start + ramp + velocity * steps * period_s * k, steps);
  out.emplace_back(out.back().first + 0.5 * ramp, ramp_steps);
  return out;
}

/// The model of stock robot `name` (robots/<name>).
inline RobotModel stock_model(const std::string& name) {
  return load_robot_model((std::filesystem::path(MRROC_SOURCE_DIR) / "robots" / name).string());
}

/// How many threads of this process run at a real-time policy (SCHED_FIFO or SCHED_RR).
inline int threads_with_real_time_policy() {
  int count = 0;
  for (const auto& task : std::filesystem::directory_iterator("/proc/self/task")) {
    const int policy = sched_getscheduler(std::atoi(task.path().filename().c_str()));
    if (policy == SCHED_FIFO || policy == SCHED_RR) ++count;
  }
  return count;
}

}  // namespace mrroc::test
