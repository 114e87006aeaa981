#include "command_interpreter.hpp"

#include "collision_guard.hpp"

#include <fmt/format.h>
#include <fmt/ranges.h>

#include <algorithm>
#include <bit>
#include <cmath>

#include "mrroc/core/error.hpp"
#include "mrroc/edp/path_check.hpp"
#include "mrroc/kinematics/pose.hpp"

namespace mrroc::edp {

namespace {
constexpr double kSynchroTimeout = 60.0;  // longest synchronisation [s]
constexpr double kResetTimeout = 60.0;    // longest re-activation after a fault [s]
/// What a SET may not change while the emergency stop is engaged: motion, the device, the binary
/// outputs (they hold their safe state) and the servo settings.
constexpr std::uint8_t kRefusedUnderStop = item::arm | item::device | item::outputs | item::servo;

/// "SET OUTPUTS refused: emergency stop engaged (...)", naming what the instruction changes.
std::string refused_under_stop(const Instruction& in) {
  std::string what;
  if (in.type == InstructionType::synchro) {
    what = "SYNCHRO";
  } else {
    for (auto [bit, name] : {std::pair{item::arm, "ARM"}, std::pair{item::device, "DEVICE"},
                             std::pair{item::outputs, "OUTPUTS"}, std::pair{item::servo, "SERVO"}})
      if ((in.set & bit) != 0) {
        // Appended piece by piece (and the type put in front by fmt): GCC 12's -O3 warns
        // (-Wstringop-overflow, -Wrestrict) about the temporaries of `literal + std::string`
        // here, a false positive.
        if (!what.empty()) what += '+';
        what += name;
      }
    what = fmt::format("{} {}", to_string(in.type), what);
  }
  return fmt::format(
      "{} refused: emergency stop engaged ({}release it first, e.g. mrroc-ui "
      "release)",
      what,
      (in.set & item::outputs) != 0
          ? "the binary outputs hold their safe state until a SET after the "
            "release; "
          : "");
}
}  // namespace

CommandInterpreter::CommandInterpreter(ServoLoop& servo, const RobotModel& model,
                                       ArmKinematics& kinematics, double servo_period_s)
    : servo_(servo), model_(model), kinematics_(kinematics), period_s_(servo_period_s) {}

namespace {
bool is_cartesian(ArmRepresentation r) {
  return r == ArmRepresentation::frame || r == ArmRepresentation::xyz_euler_zyz ||
         r == ArmRepresentation::xyz_angle_axis;
}
}  // namespace

Reply CommandInterpreter::error(int code, const std::string& text) {
  Reply r;
  r.type = ReplyType::error;
  r.error_code = code;
  r.error_class = error_class_of(code);
  r.error_text = text;
  return r;
}

Reply CommandInterpreter::execute(const Instruction& in, const std::string& client) {
  owner_changed_ = false;
  const auto now = std::chrono::steady_clock::now();
  if (client != owner_) {
    const bool at_rest = servo_.stopped();
    const double silent_s = std::chrono::duration<double>(now - owner_seen_).count();
    if (!owner_.empty() && !(at_rest && (in.take_over || silent_s >= owner_lease_s_))) {
      return error(
          error_code::not_owner,
          fmt::format("{} refused: this EDP is driven by '{}' (its last instruction {:.1f} s ago); "
                      "{}",
                      to_string(in.type), owner_, silent_s,
                      at_rest ? fmt::format("take it over (take_over) or wait until it has been "
                                            "silent for {:.1f} s",
                                            owner_lease_s_)
                              : std::string("the robot is moving: wait until it is at rest")));
    }
    owner_changed_ = true;
    owner_ = client;
    due_ = Due::nothing;  // a QUERY due to the previous owner is forgotten
  } else if (in.take_over && in.type != InstructionType::query && servo_.stopped()) {
    // The owner itself after a timeout: whatever QUERY it left due is forgotten.
    due_ = Due::nothing;
  }
  owner_seen_ = now;
  return execute(in);
}

Reply CommandInterpreter::execute(const Instruction& in) {
  Reply reply;
  // Said of the macro-steps already queued, whatever becomes of this instruction.
  if (in.no_successor) servo_.waive_successor();
  if (in.type == InstructionType::query) {
    reply = query();
  } else if (due_ != Due::nothing) {
    reply = error(error_code::query_expected,
                  fmt::format("{} refused: query expected (a QUERY must follow every other "
                              "instruction)",
                              to_string(in.type)));
  } else if (servo_.faulted() && in.type != InstructionType::synchro) {
    reply = error(error_code::hardware_fault,
                  "hardware fault: " + servo_.fault_text() +
                      " (the robot is held; SYNCHRO resets the fault and re-synchronises)");
  } else if (servo_.emergency_stopped() &&
             (in.type == InstructionType::synchro ||
              ((in.type == InstructionType::set || in.type == InstructionType::set_get) &&
               (in.set & kRefusedUnderStop) != 0))) {
    reply = error(error_code::emergency_stop, refused_under_stop(in));
  } else {
    try {
      reply = accept(in);
      // One exchange: the reply carries what the QUERY would have returned.
      if (in.with_query) reply = query();
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
    if (servo_.faulted()) {
      // Reset: the servo loop powers the drives again; the position reference is found anew.
      // A bring-up takes as long as the plugin's devices need (the CAN plugin resets, configures
      // and enables every drive, bounded by its `bring_up_timeout_s`): the reply waits for it
      // to end, whatever the host's load; kResetTimeout only guards against a plugin that never
      // returns.
      if (!servo_.reset_fault(kResetTimeout))
        throw CommandError(error_code::hardware_fault,
                           "SYNCHRO refused: the fault could not be reset: " + servo_.fault_text());
    }
    if (servo_.synchronised())
      throw CommandError(error_code::already_synchronised, "SYNCHRO refused: already synchronised");
    if (!servo_.stopped())
      // A motion before SYNCHRO that a QUERY answered early (value_in_step_no < motion_steps)
      // still runs: the synchronisation starts from where it ends.
      throw CommandError(error_code::bad_argument,
                         "SYNCHRO refused: the robot is still moving (a motion before "
                         "synchronisation runs); send SYNCHRO once it is at rest");
    servo_.begin_synchronisation();
    due_ = Due::synchro;
    return Reply{};
  }
  constexpr std::uint8_t settable =
      item::arm | item::tool | item::model | item::servo | item::outputs | item::device;
  constexpr std::uint8_t gettable = item::arm | item::tool | item::model | item::servo |
                                    item::inputs | item::timing | item::device;
  if (sets && (in.set & ~settable) != 0)
    throw CommandError(error_code::bad_argument,
                       fmt::format("SET of items {:#x} is not possible (SET takes ARM, TOOL, "
                                   "MODEL, SERVO, OUTPUTS, DEVICE)",
                                   in.set & ~settable));
  if (gets && (in.get & ~gettable) != 0)
    throw CommandError(error_code::bad_argument,
                       fmt::format("GET of items {:#x} is not possible (GET takes ARM, TOOL, "
                                   "MODEL, SERVO, INPUTS, TIMING, DEVICE)",
                                   in.get & ~gettable));
  if (((sets && (in.set & item::outputs) != 0) || (gets && (in.get & item::inputs) != 0)) &&
      !servo_.hardware().binary_io())
    throw CommandError(
        error_code::not_supported,
        fmt::format("{} refused: plugin '{}' has no binary inputs or outputs",
                    sets && (in.set & item::outputs) != 0 ? "SET OUTPUTS" : "GET INPUTS",
                    servo_.hardware().name()));
  if (sets && (in.set & item::outputs) != 0) {
    const std::uint32_t lines = servo_.hardware().output_lines();
    if (const std::uint32_t missing = in.output_values & ~lines; missing != 0)
      throw CommandError(
          error_code::bad_argument,
          fmt::format("SET OUTPUTS {:#x} refused: output line {} does not exist (plugin '{}' has "
                      "lines {:#x})",
                      in.output_values, std::countr_zero(missing), servo_.hardware().name(),
                      lines));
  }
  const bool sets_device = sets && (in.set & item::device) != 0;
  if ((sets_device || (gets && (in.get & item::device) != 0)) && servo_.device().name.empty())
    throw CommandError(
        error_code::not_supported,
        fmt::format("{} refused: plugin '{}' drives no device",
                    sets_device ? "SET DEVICE" : "GET DEVICE", servo_.hardware().name()));
  if (sets_device) validate_device(in);
  if (gets && (in.get & item::arm) != 0 && in.get_arm_type != ArmRepresentation::joint) {
    if (!servo_.synchronised())
      throw CommandError(error_code::not_synchronised,
                         fmt::format("GET ARM in {} refused: robot not synchronised (only JOINT "
                                     "readings, of the raw encoders, exist before SYNCHRO)",
                                     to_string(in.get_arm_type)));
    if (is_cartesian(in.get_arm_type) && !kinematics_.cartesian())
      (void)kinematics_.forward({});  // throws not_supported with the reason
  }

  // Apply MODEL and TOOL tentatively, validate everything, and undo them if anything is refused:
  // a refused SET changes nothing.
  const int old_model = kinematics_.model_no();
  const int old_corrector = kinematics_.corrector_no();
  const Eigen::Isometry3d old_tool = kinematics_.tool();
  std::vector<double> target;
  try {
    if (sets && (in.set & item::model) != 0)
      kinematics_.select_model(in.kinematic_model_no, in.corrector_no);
    if (sets && (in.set & item::tool) != 0) {
      if (!is_cartesian(in.tool_type))
        throw CommandError(error_code::bad_argument,
                           fmt::format("a tool is a frame: tool_type {} is not FRAME, "
                                       "XYZ_EULER_ZYZ or XYZ_ANGLE_AXIS",
                                       to_string(in.tool_type)));
      kinematics_.set_tool(kinematics::from_vector(in.tool, in.tool_type));
    }
    if (sets && (in.set & item::servo) != 0) validate_servo(in);
    if (sets && (in.set & item::arm) != 0) target = arm_target(in);
  } catch (...) {
    kinematics_.select_model(old_model, old_corrector);
    kinematics_.set_tool(old_tool);
    throw;
  }

  // The servo loop refuses them too when a stop came after the check in execute().
  if (sets && (in.set & item::outputs) != 0 && !servo_.request_outputs(in.output_values))
    throw CommandError(error_code::emergency_stop, refused_under_stop(in));
  if (sets && (in.set & item::servo) != 0 &&
      !servo_.request_servo(in.servo_algorithm, in.servo_parameters_no))
    throw CommandError(error_code::emergency_stop, refused_under_stop(in));
  if (sets_device) servo_.request_device(in.device);
  due_arm_type_ = in.get_arm_type;
  due_tool_type_ = is_cartesian(in.tool_type) ? in.tool_type : ArmRepresentation::frame;
  due_get_ = gets ? in.get : 0;
  if (!target.empty()) {
    // A macro-step refused when it was due to start takes every one queued behind it along; the
    // client hears of it once, here or in the reply it waits for.
    if (const std::uint64_t refused = servo_.refused_upto(); refused > refusal_reported_) {
      refusal_reported_ = refused;
      throw CommandError(
          servo_.refusal_code(refused),
          "SET refused: an earlier macro-step was refused: " + servo_.refusal(refused));
    }
    due_macro_step_ = servo_.submit(target, in.motion_steps, in.value_in_step_no);
    due_at_ = servo_.reply_due_at(due_macro_step_, in.value_in_step_no < in.motion_steps);
    due_ = Due::arm_reading;
    return Reply{};
  }
  // A reading while the robot stands with nothing queued ends the motion a refusal belonged to
  // (an MP or ECP that stopped it reads where it stands before it re-plans): the new plan's
  // first SET is not answered with the old refusal.
  if (servo_.stopped()) refusal_reported_ = std::max(refusal_reported_, servo_.refused_upto());
  due_ = Due::get;
  return Reply{};
}

void CommandInterpreter::validate_servo(const Instruction& in) const {
  Hardware& hw = servo_.hardware();
  if (in.servo_algorithm.size() != model_.axes() || in.servo_parameters_no.size() != model_.axes())
    throw CommandError(
        error_code::bad_argument,
        fmt::format("SET SERVO needs one algorithm and one parameter set per axis "
                    "({}), got {} and {}",
                    model_.axes(), in.servo_algorithm.size(), in.servo_parameters_no.size()));
  for (std::size_t i = 0; i < model_.axes(); ++i) {
    const int algorithm = in.servo_algorithm[i];
    const int set = in.servo_parameters_no[i];
    if (algorithm < 0 || algorithm >= hw.servo_algorithm_count())
      throw CommandError(error_code::bad_argument,
                         fmt::format("axis {} ({}): servo algorithm {} is outside 0..{} of plugin "
                                     "'{}'",
                                     i, model_.joint_names[i], algorithm,
                                     hw.servo_algorithm_count() - 1, hw.name()));
    if (set < 0 || set >= hw.servo_parameter_set_count(algorithm))
      throw CommandError(error_code::bad_argument,
                         fmt::format("axis {} ({}): servo parameter set {} is outside 0..{} for "
                                     "algorithm {}",
                                     i, model_.joint_names[i], set,
                                     hw.servo_parameter_set_count(algorithm) - 1, algorithm));
  }
}

void CommandInterpreter::validate_device(const Instruction& in) const {
  const DeviceDescription& device = servo_.device();
  if (in.device.size() != device.command.size()) {
    std::string fields;
    for (const DeviceField& f : device.command)
      fields += fmt::format("{}{} [{}]", fields.empty() ? "" : ", ", f.name, f.unit);
    throw CommandError(
        error_code::bad_argument,
        fmt::format("SET DEVICE has {} values, device '{}' of plugin '{}' takes {}: {}",
                    in.device.size(), device.name, servo_.hardware().name(), device.command.size(),
                    fields));
  }
  for (std::size_t i = 0; i < in.device.size(); ++i) {
    const DeviceField& f = device.command[i];
    const double v = in.device[i];
    if (!std::isfinite(v))
      throw CommandError(error_code::bad_argument,
                         fmt::format("SET DEVICE {} field {} ({}) value {} {} is not a finite "
                                     "number",
                                     device.name, i, f.name, v, f.unit));
    if (v > f.max)
      throw CommandError(error_code::out_of_limits,
                         fmt::format("SET DEVICE {} field {} ({}) {:g} {} exceeds its upper limit "
                                     "of {:g} {}",
                                     device.name, i, f.name, v, f.unit, f.max, f.unit));
    if (v < f.min)
      throw CommandError(error_code::out_of_limits,
                         fmt::format("SET DEVICE {} field {} ({}) {:g} {} is below its lower limit "
                                     "of {:g} {}",
                                     device.name, i, f.name, v, f.unit, f.min, f.unit));
  }
}

std::vector<double> CommandInterpreter::arm_target(const Instruction& in) const {
  if (in.motion_steps < 1 || in.motion_steps > 100000)
    throw CommandError(error_code::bad_argument,
                       fmt::format("motion_steps {} is outside 1..100000", in.motion_steps));
  if (in.value_in_step_no < 1 || in.value_in_step_no > in.motion_steps + 1)
    throw CommandError(error_code::bad_argument,
                       fmt::format("value_in_step_no {} is outside 1..{} (motion_steps + 1)",
                                   in.value_in_step_no, in.motion_steps + 1));
  if (!servo_.synchronised()) return unsynchronised_target(in);
  const bool relative = in.motion_type == MotionType::relative;
  const std::vector<double> start = servo_.planned_end();
  std::vector<double> target;
  switch (in.set_arm_type) {
    case ArmRepresentation::joint:
    case ArmRepresentation::motor: {
      const bool motor = in.set_arm_type == ArmRepresentation::motor;
      check_axis_values(in);
      std::vector<double> values = in.arm;
      if (relative) {
        const std::vector<double> base = motor ? kinematics_.motors_from_joints(start) : start;
        for (std::size_t i = 0; i < values.size(); ++i) values[i] += base[i];
      }
      if (motor) {
        kinematics_.check_motor_limits(values, "target");
        target = kinematics_.joints_from_motors(values);
      } else {
        target = std::move(values);
      }
      break;
    }
    case ArmRepresentation::frame:
    case ArmRepresentation::xyz_euler_zyz:
    case ArmRepresentation::xyz_angle_axis: {
      const Eigen::Isometry3d given = kinematics::from_vector(in.arm, in.set_arm_type);
      const Eigen::Isometry3d goal =
          relative ? kinematics::compose_relative(kinematics_.forward(start), given) : given;
      target = kinematics_.inverse(goal, start);
      break;
    }
  }
  check_path(start, target, in.motion_steps);
  return target;
}

void CommandInterpreter::check_axis_values(const Instruction& in) const {
  if (in.arm.size() != model_.axes())
    throw CommandError(
        error_code::bad_argument,
        fmt::format("SET ARM {} has {} values, robot '{}' has {} axes", to_string(in.set_arm_type),
                    in.arm.size(), model_.name, model_.axes()));
  for (std::size_t i = 0; i < in.arm.size(); ++i)
    if (!std::isfinite(in.arm[i]))
      throw CommandError(error_code::bad_argument,
                         fmt::format("SET ARM {} value {} ({}) is not a finite number",
                                     to_string(in.set_arm_type), i, model_.joint_names[i]));
}

std::vector<double> CommandInterpreter::unsynchronised_target(const Instruction& in) const {
  const bool relative = in.motion_type == MotionType::relative;
  const bool axis_values =
      in.set_arm_type == ArmRepresentation::joint || in.set_arm_type == ArmRepresentation::motor;
  if (!relative || !axis_values)
    throw CommandError(
        error_code::not_synchronised,
        fmt::format("SET ARM {} {} refused: robot not synchronised (its position is unknown: "
                    "send SYNCHRO first; before it only RELATIVE MOTOR and JOINT moves are "
                    "allowed, at reduced limits)",
                    to_string(in.set_arm_type), relative ? "RELATIVE" : "ABSOLUTE"));
  check_axis_values(in);
  const bool motor = in.set_arm_type == ArmRepresentation::motor;
  // The change of every joint. A motor move goes through the transmission at the
  // synchronisation pose, the only position known: exact for a linear transmission, the change
  // there for a nonlinear one (the IRb-6's ball screws).
  std::vector<double> change = in.arm;
  if (motor) {
    const std::vector<double>& base = model_.synchro_joint_positions;
    std::vector<double> motors = kinematics_.motors_from_joints(base);
    for (std::size_t i = 0; i < motors.size(); ++i) motors[i] += in.arm[i];
    try {
      change = kinematics_.joints_from_motors(motors);
    } catch (const CommandError& e) {
      throw CommandError(e.code(), fmt::format("SET ARM MOTOR RELATIVE refused before SYNCHRO: "
                                               "the motor change is too large for the "
                                               "transmission: {}",
                                               e.what()));
    }
    for (std::size_t i = 0; i < change.size(); ++i) change[i] -= base[i];
  }
  const double bound = servo_.unsynchronised_limits().max_move;
  for (std::size_t i = 0; i < change.size(); ++i)
    if (!(std::abs(change[i]) <= bound))  // also a change that is not a number
      throw CommandError(
          error_code::out_of_limits,
          fmt::format(
              "SET ARM {} RELATIVE refused before SYNCHRO: axis {} ({}) would move "
              "{:.4f} {}{}, more than the {:.4f} {} one move may take before "
              "synchronisation ([robot.edp] unsynchronised_max_move; the joint limits "
              "cannot be checked while the position is unknown)",
              to_string(in.set_arm_type), i, model_.joint_names[i], change[i], model_.unit(i),
              // A coupled transmission moves a joint by other motors' changes too.
              motor ? fmt::format(" (from the motor changes [{:.4f}] rad)", fmt::join(in.arm, ", "))
                    : std::string(),
              bound, model_.unit(i)));
  // Raw axis positions: relative to where the motion already queued ends. The planning of the
  // macro-step (the servo loop) keeps it within the reduced velocity and acceleration limits.
  std::vector<double> target = servo_.planned_end();
  for (std::size_t i = 0; i < target.size(); ++i) target[i] += change[i];
  return target;
}

void CommandInterpreter::check_path(const std::vector<double>& start,
                                    const std::vector<double>& target, int steps) const {
  // The target, then every interpolation step, against the joint and motor limits (the ECP's
  // planned motions check their macro-steps with the same function).
  check_straight_path(kinematics_, start, target, steps, "step");
  // The same line against the cell and the robot itself (collision_guard.hpp).
  if (collision_ != nullptr) collision_->check_path(start, target, steps);
}

std::vector<double> CommandInterpreter::arm_values(const std::vector<double>& joints,
                                                   ArmRepresentation type) const {
  switch (type) {
    case ArmRepresentation::joint: return joints;
    case ArmRepresentation::motor: return kinematics_.motors_from_joints(joints);
    default: return kinematics::to_vector(kinematics_.forward(joints), type);
  }
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
                     "synchronisation failed: " +
                         (servo_.faulted() ? servo_.fault_text()
                          : servo_.emergency_stopped()
                              ? std::string("interrupted by the emergency stop; the robot is "
                                            "held (release it, then SYNCHRO again)")
                              : std::string("timed out")));
      return reading_reply(servo_.latest());
    case Due::get: return reading_reply(servo_.latest());
    case Due::arm_reading: {
      // Generous bound: every macro-step queued up to this one, a stopping ramp (when a
      // successor came late), plus 5 s: this only catches a stuck loop.
      const double timeout = 2.0 * static_cast<double>(servo_.queued_steps() + 2) * period_s_ + 5.0;
      auto reading = servo_.wait_reply(due_macro_step_, due_at_, timeout);
      if (!reading && servo_.emergency_stopped())
        return error(error_code::emergency_stop,
                     "macro-step interrupted: emergency stop engaged; the robot is held");
      if (!reading)
        if (const std::string why = servo_.refusal(due_macro_step_); !why.empty()) {
          refusal_reported_ = std::max(refusal_reported_, servo_.refused_upto());
          return error(servo_.refusal_code(due_macro_step_), "SET refused: " + why);
        }
      if (!reading)
        return error(error_code::hardware_fault,
                     servo_.faulted() ? "hardware fault: " + servo_.fault_text()
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
  r.macro_steps_ahead = reading.macro_steps_ahead;
  r.servo_cycle = reading.cycle;
  const auto n = static_cast<std::ptrdiff_t>(model_.axes());
  r.joints.assign(reading.joints.begin(), reading.joints.begin() + n);
  r.desired_joints.assign(reading.desired.begin(), reading.desired.begin() + n);
  r.joint_velocities.assign(reading.velocities.begin(), reading.velocities.begin() + n);
  r.arm_type = ArmRepresentation::joint;
  r.arm = r.joints;
  if (reading.synchronised && (due_get_ & item::arm) != 0) {
    try {
      r.arm = arm_values(r.joints, due_arm_type_);
      r.arm_type = due_arm_type_;
    } catch (const CommandError& e) {
      return error(e.code(), fmt::format("GET ARM in {}: {}", to_string(due_arm_type_), e.what()));
    }
  }
  r.tool_type = due_tool_type_;
  r.tool = kinematics::to_vector(kinematics_.tool(), due_tool_type_);
  r.kinematic_model_no = kinematics_.model_no();
  r.corrector_no = kinematics_.corrector_no();
  r.input_values = reading.inputs;
  if ((due_get_ & item::device) != 0)
    r.device.assign(reading.device.begin(),
                    reading.device.begin() + static_cast<std::ptrdiff_t>(reading.device_fields));
  r.servo_algorithm.assign(reading.servo_algorithm.begin(), reading.servo_algorithm.begin() + n);
  r.servo_parameters_no.assign(reading.servo_parameter_set.begin(),
                               reading.servo_parameter_set.begin() + n);
  if ((due_get_ & item::timing) != 0) {
    const TimingStats t = servo_.timing();
    r.servo_cycles = t.cycles;
    r.servo_overruns = t.overruns;
    r.servo_period_us = t.period_us;
    r.lateness_p50_us = t.lateness_p50_us;
    r.lateness_p99_us = t.lateness_p99_us;
    r.lateness_max_us = t.lateness_max_us;
  }
  return r;
}

}  // namespace mrroc::edp
