#include "command_interpreter.hpp"

#include <fmt/format.h>

#include "mrroc/core/error.hpp"

namespace mrroc::edp {

namespace {
constexpr double kSynchroTimeout = 60.0;  // longest synchronisation [s]
}

CommandInterpreter::CommandInterpreter(ServoLoop& servo, const RobotModel& model,
                                       double servo_period_s)
    : servo_(servo), model_(model), period_s_(servo_period_s) {}

Reply CommandInterpreter::error(int code, const std::string& text) {
  Reply r;
  r.type = ReplyType::error;
  r.error_code = code;
  r.error_text = text;
  return r;
}

Reply CommandInterpreter::execute(const Instruction& in) {
  Reply reply;
  if (in.type == InstructionType::query) {
    reply = query();
  } else if (due_ != Due::nothing) {
    reply = error(error_code::query_expected,
                  fmt::format("{} refused: query expected (a QUERY must follow every other "
                              "instruction)",
                              to_string(in.type)));
  } else if (servo_.faulted()) {
    reply = error(error_code::hardware_fault, "hardware fault: " + servo_.fault_text());
  } else {
    try {
      reply = accept(in);
    } catch (const CommandError& e) {
      reply = error(e.code(), e.what());
    } catch (const HardwareError& e) {
      reply = error(error_code::hardware_fault, e.what());
    }
  }
  reply.synchronised = servo_.synchronised();
  return reply;
}

Reply CommandInterpreter::accept(const Instruction& in) {
  const bool sets = in.type == InstructionType::set || in.type == InstructionType::set_get;
  const bool gets = in.type == InstructionType::get || in.type == InstructionType::set_get;
  if (in.type == InstructionType::synchro) {
    if (servo_.synchronised())
      throw CommandError(error_code::already_synchronised, "SYNCHRO refused: already synchronised");
    servo_.begin_synchronisation();
    due_ = Due::synchro;
    return Reply{};
  }
  if (sets) {
    if ((in.set & ~item::arm) != 0)
      throw CommandError(error_code::not_supported,
                         fmt::format("SET of items {:#x} is not supported by this EDP yet (only "
                                     "ARM)",
                                     in.set & ~item::arm));
  }
  if (gets && (in.get & ~item::arm) != 0)
    throw CommandError(error_code::not_supported,
                       fmt::format("GET of items {:#x} is not supported by this EDP yet (only "
                                   "ARM)",
                                   in.get & ~item::arm));
  if (gets && in.get_arm_type != ArmRepresentation::joint)
    throw CommandError(error_code::not_supported,
                       fmt::format("GET ARM in {} is not supported by this EDP yet (only JOINT)",
                                   to_string(in.get_arm_type)));
  due_arm_type_ = in.get_arm_type;
  due_get_ = gets ? in.get : 0;
  if (sets && (in.set & item::arm) != 0) {
    if (!servo_.synchronised())
      throw CommandError(error_code::not_synchronised,
                         "SET ARM refused: robot not synchronised (send SYNCHRO first)");
    if (in.set_arm_type != ArmRepresentation::joint)
      throw CommandError(error_code::not_supported,
                         fmt::format("SET ARM in {} is not supported by this EDP yet (only JOINT)",
                                     to_string(in.set_arm_type)));
    if (in.motion_steps < 1 || in.motion_steps > 100000)
      throw CommandError(error_code::bad_argument,
                         fmt::format("motion_steps {} is outside 1..100000", in.motion_steps));
    if (in.value_in_step_no < 1 || in.value_in_step_no > in.motion_steps + 1)
      throw CommandError(error_code::bad_argument,
                         fmt::format("value_in_step_no {} is outside 1..{} (motion_steps + 1)",
                                     in.value_in_step_no, in.motion_steps + 1));
    if (in.arm.size() != model_.axes())
      throw CommandError(error_code::bad_argument,
                         fmt::format("SET ARM JOINT has {} values, robot '{}' has {} axes",
                                     in.arm.size(), model_.name, model_.axes()));
    std::vector<double> target = in.arm;
    if (in.motion_type == MotionType::relative) {
      const std::vector<double> base = servo_.planned_end();
      for (std::size_t i = 0; i < target.size(); ++i) target[i] += base[i];
    }
    // The interpolation is linear in joint space from a pose inside the limits, so the whole
    // path is inside the limits exactly when the target is.
    model_.check_joint_limits(target, "target");
    due_macro_step_ = servo_.submit(target, in.motion_steps, in.value_in_step_no);
    due_steps_ = in.motion_steps;
    due_ = Due::arm_reading;
    return Reply{};
  }
  due_ = Due::get;
  return Reply{};
}

Reply CommandInterpreter::query() {
  const Due due = due_;
  due_ = Due::nothing;
  switch (due) {
    case Due::nothing:
      return error(error_code::query_unexpected,
                   "QUERY refused: no instruction is waiting for its reply");
    case Due::synchro:
      if (!servo_.wait_synchronised(kSynchroTimeout))
        return error(error_code::hardware_fault,
                     "synchronisation failed: " + (servo_.faulted() ? servo_.fault_text()
                                                                    : std::string("timed out")));
      return reading_reply(servo_.latest());
    case Due::get:
      return reading_reply(servo_.latest());
    case Due::arm_reading: {
      // Generous bound: the queued macro-step plus the current one, plus a second.
      const double timeout = 2.0 * (due_steps_ + 2) * period_s_ + 1.0;
      auto reading = servo_.wait_reading(due_macro_step_, timeout);
      if (!reading)
        return error(error_code::hardware_fault,
                     servo_.faulted()
                         ? "hardware fault: " + servo_.fault_text()
                         : fmt::format("no reading of macro-step {} within {:.3f} s",
                                       due_macro_step_, timeout));
      return reading_reply(*reading);
    }
  }
  return error(error_code::malformed, "internal: unknown state");
}

Reply CommandInterpreter::reading_reply(const Reading& reading) const {
  Reply r;
  r.type = ReplyType::data;
  r.step_no = reading.step_no;
  r.servo_cycle = reading.cycle;
  const auto n = static_cast<std::ptrdiff_t>(model_.axes());
  r.joints.assign(reading.joints.begin(), reading.joints.begin() + n);
  r.desired_joints.assign(reading.desired.begin(), reading.desired.begin() + n);
  r.joint_velocities.assign(reading.velocities.begin(), reading.velocities.begin() + n);
  r.arm_type = ArmRepresentation::joint;
  r.arm = r.joints;
  return r;
}

}  // namespace mrroc::edp
