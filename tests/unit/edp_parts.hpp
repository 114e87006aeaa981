#pragma once
// The parts of an EDP as the EDP unit tests build them (no LCM): a robot's model, its hardware
// plugin configured for the servo period, its kinematics; the tests then build the servo loop
// and command interpreter on them, each with the options it examines.
#include <memory>
#include <string>
#include <vector>

#include "mrroc/config/params.hpp"
#include "mrroc/edp/arm_kinematics.hpp"
#include "mrroc/edp/hardware.hpp"
#include "mrroc/edp/instruction.hpp"
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
inline edp::Instruction set_joints_instruction(
    std::vector<double> q, int steps, int value_in_step_no,
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

/// The model of stock robot `name` (robots/<name>).
inline RobotModel stock_model(const std::string& name) {
  return load_robot_model(std::string(MRROC_SOURCE_DIR) + "/robots/" + name);
}

}  // namespace mrroc::test
