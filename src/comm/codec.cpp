#include "mrroc/comm/codec.hpp"

#include <fmt/format.h>

namespace mrroc::comm {

namespace {

// The plain C++ types (include/mrroc/msg/) and the wire definitions (src/msg/*.lcm) name the same
// numbers: a change on one side that the other does not follow stops the build here.
template <class E>
constexpr bool same(E cpp, std::int8_t wire) {
  return static_cast<std::int8_t>(cpp) == wire;
}
using edp::ArmRepresentation;
using edp::InstructionType;
using edp::MotionType;
using edp::ReplyType;
using Ins = mrroc_lcm::edp_instruction_t;
static_assert(same(InstructionType::set, Ins::SET) && same(InstructionType::get, Ins::GET) &&
              same(InstructionType::set_get, Ins::SET_GET) &&
              same(InstructionType::synchro, Ins::SYNCHRO) &&
              same(InstructionType::query, Ins::QUERY));
static_assert(edp::item::arm == Ins::ARM_BIT && edp::item::tool == Ins::TOOL_BIT &&
              edp::item::model == Ins::MODEL_BIT && edp::item::servo == Ins::SERVO_BIT &&
              edp::item::outputs == Ins::OUTPUTS_BIT && edp::item::inputs == Ins::INPUTS_BIT &&
              edp::item::timing == Ins::TIMING_BIT && edp::item::device == Ins::DEVICE_BIT);
static_assert(same(ArmRepresentation::frame, Ins::FRAME) &&
              same(ArmRepresentation::xyz_euler_zyz, Ins::XYZ_EULER_ZYZ) &&
              same(ArmRepresentation::xyz_angle_axis, Ins::XYZ_ANGLE_AXIS) &&
              same(ArmRepresentation::joint, Ins::JOINT) &&
              same(ArmRepresentation::motor, Ins::MOTOR));
static_assert(same(MotionType::absolute, Ins::ABSOLUTE) &&
              same(MotionType::relative, Ins::RELATIVE));
using Rep = mrroc_lcm::edp_reply_t;
static_assert(same(ReplyType::acknowledge, Rep::ACKNOWLEDGE) && same(ReplyType::data, Rep::DATA) &&
              same(ReplyType::error, Rep::ERROR));
using Cmd = mrroc_lcm::mp_ecp_command_t;
static_assert(same(ecp::MpCommandType::start_task, Cmd::START_TASK) &&
              same(ecp::MpCommandType::next_pose, Cmd::NEXT_POSE) &&
              same(ecp::MpCommandType::end_motion, Cmd::END_MOTION) &&
              same(ecp::MpCommandType::next_state, Cmd::NEXT_STATE) &&
              same(ecp::MpCommandType::stop, Cmd::STOP) &&
              same(ecp::MpCommandType::pause, Cmd::PAUSE) &&
              same(ecp::MpCommandType::resume, Cmd::RESUME));
using EcpRep = mrroc_lcm::ecp_mp_reply_t;
static_assert(same(ecp::EcpReplyType::acknowledge, EcpRep::ACKNOWLEDGE) &&
              same(ecp::EcpReplyType::task_terminated, EcpRep::TASK_TERMINATED) &&
              same(ecp::EcpReplyType::error, EcpRep::ERROR));
static_assert(same(ecp::ErrorClass::non_fatal, EcpRep::NON_FATAL) &&
              same(ecp::ErrorClass::fatal, EcpRep::FATAL) &&
              same(ecp::ErrorClass::system, EcpRep::SYSTEM));

static_assert(same(ErrorClass::non_fatal, Rep::NON_FATAL) && same(ErrorClass::fatal, Rep::FATAL) &&
              same(ErrorClass::system, Rep::SYSTEM));

using L = mrroc_lcm::edp_instruction_t;

template <class E>
E checked_enum(std::int8_t raw, std::int8_t lo, std::int8_t hi, const char* field) {
  if (raw < lo || raw > hi)
    throw DecodeError(fmt::format("field '{}' has value {}, expected {}..{}", field, raw, lo, hi));
  return static_cast<E>(raw);
}

template <class T>
std::vector<T> checked_vector(const std::vector<T>& v, std::int32_t n, const char* field) {
  if (n < 0 || n > kMaxVector || static_cast<std::size_t>(n) != v.size())
    throw DecodeError(
        fmt::format("field '{}' has {} elements but its length field says {} "
                    "(at most {} allowed)",
                    field, v.size(), n, kMaxVector));
  return v;
}

template <class T>
std::int32_t length(const std::vector<T>& v, const char* field) {
  if (v.size() > static_cast<std::size_t>(kMaxVector))
    throw Error(fmt::format("field '{}' has {} elements, at most {} can be sent", field, v.size(),
                            kMaxVector));
  return static_cast<std::int32_t>(v.size());
}

std::int8_t arm_code(edp::ArmRepresentation r) { return static_cast<std::int8_t>(r); }
edp::ArmRepresentation arm_of(std::int8_t raw, const char* field) {
  return checked_enum<edp::ArmRepresentation>(raw, L::FRAME, L::MOTOR, field);
}

}  // namespace

mrroc_lcm::edp_instruction_t encode(const edp::Instruction& in) {
  L m{};
  m.instruction = static_cast<std::int8_t>(in.type);
  m.set_mask = static_cast<std::int16_t>(in.set);
  m.get_mask = static_cast<std::int16_t>(in.get);
  m.set_arm_type = arm_code(in.set_arm_type);
  m.get_arm_type = arm_code(in.get_arm_type);
  m.motion_type = static_cast<std::int8_t>(in.motion_type);
  m.motion_steps = in.motion_steps;
  m.value_in_step_no = in.value_in_step_no;
  m.n_arm = length(in.arm, "arm");
  m.arm = in.arm;
  m.tool_type = arm_code(in.tool_type);
  m.n_tool = length(in.tool, "tool");
  m.tool = in.tool;
  m.kinematic_model_no = in.kinematic_model_no;
  m.corrector_no = in.corrector_no;
  if (in.servo_algorithm.size() != in.servo_parameters_no.size())
    throw Error("servo_algorithm and servo_parameters_no must have the same length");
  m.n_servo = length(in.servo_algorithm, "servo_algorithm");
  m.servo_algorithm = in.servo_algorithm;
  m.servo_parameters_no = in.servo_parameters_no;
  m.output_values = static_cast<std::int32_t>(in.output_values);
  m.n_device = length(in.device, "device");
  m.device = in.device;
  m.with_query = in.with_query ? 1 : 0;
  m.no_successor = in.no_successor ? 1 : 0;
  m.take_over = in.take_over ? 1 : 0;
  return m;
}

edp::Instruction decode(const mrroc_lcm::edp_instruction_t& m) {
  edp::Instruction in;
  in.type = checked_enum<edp::InstructionType>(m.instruction, L::SET, L::QUERY, "instruction");
  constexpr int all_items = 255;
  if ((m.set_mask & ~all_items) != 0 || (m.get_mask & ~all_items) != 0)
    throw DecodeError(
        fmt::format("set_mask {} / get_mask {} has unknown bits", m.set_mask, m.get_mask));
  in.set = static_cast<std::uint8_t>(m.set_mask);
  in.get = static_cast<std::uint8_t>(m.get_mask);
  in.set_arm_type = arm_of(m.set_arm_type, "set_arm_type");
  in.get_arm_type = arm_of(m.get_arm_type, "get_arm_type");
  in.motion_type =
      checked_enum<edp::MotionType>(m.motion_type, L::ABSOLUTE, L::RELATIVE, "motion_type");
  in.motion_steps = m.motion_steps;
  in.value_in_step_no = m.value_in_step_no;
  in.arm = checked_vector(m.arm, m.n_arm, "arm");
  in.tool_type = arm_of(m.tool_type, "tool_type");
  in.tool = checked_vector(m.tool, m.n_tool, "tool");
  in.kinematic_model_no = m.kinematic_model_no;
  in.corrector_no = m.corrector_no;
  in.servo_algorithm = checked_vector(m.servo_algorithm, m.n_servo, "servo_algorithm");
  in.servo_parameters_no = checked_vector(m.servo_parameters_no, m.n_servo, "servo_parameters_no");
  in.output_values = static_cast<std::uint32_t>(m.output_values);
  in.device = checked_vector(m.device, m.n_device, "device");
  if (m.with_query != 0 && m.with_query != 1)
    throw DecodeError(fmt::format("field 'with_query' = {} is not 0 or 1", m.with_query));
  in.with_query = m.with_query == 1;
  if (m.no_successor != 0 && m.no_successor != 1)
    throw DecodeError(fmt::format("field 'no_successor' = {} is not 0 or 1", m.no_successor));
  in.no_successor = m.no_successor == 1;
  if (m.take_over != 0 && m.take_over != 1)
    throw DecodeError(fmt::format("field 'take_over' = {} is not 0 or 1", m.take_over));
  in.take_over = m.take_over == 1;
  return in;
}

mrroc_lcm::edp_reply_t encode(const edp::Reply& in) {
  mrroc_lcm::edp_reply_t m{};
  m.reply = static_cast<std::int8_t>(in.type);
  m.error_code = in.error_code;
  m.error_class = static_cast<std::int8_t>(in.error_class);
  m.error_text = in.error_text;
  m.is_synchronised = in.synchronised ? 1 : 0;
  m.step_no = in.step_no;
  m.macro_steps_ahead = in.macro_steps_ahead;
  m.servo_cycle = in.servo_cycle;
  m.arm_type = arm_code(in.arm_type);
  m.n_arm = length(in.arm, "arm");
  m.arm = in.arm;
  m.n_joints = length(in.joints, "joints");
  auto sized = [&](const std::vector<double>& v) {
    std::vector<double> out = v;
    out.resize(in.joints.size(), 0.0);
    return out;
  };
  m.joints = in.joints;
  m.desired_joints = sized(in.desired_joints);
  m.joint_velocities = sized(in.joint_velocities);
  m.tool_type = arm_code(in.tool_type);
  m.n_tool = length(in.tool, "tool");
  m.tool = in.tool;
  m.kinematic_model_no = in.kinematic_model_no;
  m.corrector_no = in.corrector_no;
  m.n_servo = length(in.servo_algorithm, "servo_algorithm");
  m.servo_algorithm = in.servo_algorithm;
  m.servo_parameters_no = in.servo_parameters_no;
  m.servo_parameters_no.resize(in.servo_algorithm.size(), 0);
  m.input_values = static_cast<std::int32_t>(in.input_values);
  m.n_device = length(in.device, "device");
  m.device = in.device;
  m.servo_cycles = in.servo_cycles;
  m.servo_overruns = in.servo_overruns;
  m.servo_period_us = in.servo_period_us;
  m.lateness_p50_us = in.lateness_p50_us;
  m.lateness_p99_us = in.lateness_p99_us;
  m.lateness_max_us = in.lateness_max_us;
  return m;
}

edp::Reply decode(const mrroc_lcm::edp_reply_t& m) {
  using R = mrroc_lcm::edp_reply_t;
  edp::Reply out;
  out.type = checked_enum<edp::ReplyType>(m.reply, R::ACKNOWLEDGE, R::ERROR, "reply");
  out.error_code = m.error_code;
  out.error_class = checked_enum<ErrorClass>(m.error_class, 0, R::SYSTEM, "error_class");
  out.error_text = m.error_text;
  out.synchronised = m.is_synchronised != 0;
  out.step_no = m.step_no;
  out.macro_steps_ahead = m.macro_steps_ahead;
  out.servo_cycle = m.servo_cycle;
  out.arm_type = arm_of(m.arm_type, "arm_type");
  out.arm = checked_vector(m.arm, m.n_arm, "arm");
  out.joints = checked_vector(m.joints, m.n_joints, "joints");
  out.desired_joints = checked_vector(m.desired_joints, m.n_joints, "desired_joints");
  out.joint_velocities = checked_vector(m.joint_velocities, m.n_joints, "joint_velocities");
  out.tool_type = arm_of(m.tool_type, "tool_type");
  out.tool = checked_vector(m.tool, m.n_tool, "tool");
  out.kinematic_model_no = m.kinematic_model_no;
  out.corrector_no = m.corrector_no;
  out.servo_algorithm = checked_vector(m.servo_algorithm, m.n_servo, "servo_algorithm");
  out.servo_parameters_no = checked_vector(m.servo_parameters_no, m.n_servo, "servo_parameters_no");
  out.input_values = static_cast<std::uint32_t>(m.input_values);
  out.device = checked_vector(m.device, m.n_device, "device");
  out.servo_cycles = m.servo_cycles;
  out.servo_overruns = m.servo_overruns;
  out.servo_period_us = m.servo_period_us;
  out.lateness_p50_us = m.lateness_p50_us;
  out.lateness_p99_us = m.lateness_p99_us;
  out.lateness_max_us = m.lateness_max_us;
  return out;
}

mrroc_lcm::mp_ecp_command_t encode(const ecp::MpCommand& in) {
  mrroc_lcm::mp_ecp_command_t m{};
  m.command = static_cast<std::int8_t>(in.type);
  m.state_name = in.state_name;
  m.arguments = in.arguments;
  m.arm_type = arm_code(in.arm_type);
  m.motion_type = static_cast<std::int8_t>(in.motion_type);
  m.motion_steps = in.motion_steps;
  m.value_in_step_no = in.value_in_step_no;
  m.n_arm = length(in.arm, "arm");
  m.arm = in.arm;
  return m;
}

ecp::MpCommand decode(const mrroc_lcm::mp_ecp_command_t& m) {
  using C = mrroc_lcm::mp_ecp_command_t;
  ecp::MpCommand out;
  out.type = checked_enum<ecp::MpCommandType>(m.command, C::START_TASK, C::RESUME, "command");
  out.state_name = m.state_name;
  out.arguments = m.arguments;
  out.arm_type = arm_of(m.arm_type, "arm_type");
  out.motion_type =
      checked_enum<edp::MotionType>(m.motion_type, L::ABSOLUTE, L::RELATIVE, "motion_type");
  out.motion_steps = m.motion_steps;
  out.value_in_step_no = m.value_in_step_no;
  out.arm = checked_vector(m.arm, m.n_arm, "arm");
  return out;
}

mrroc_lcm::ecp_mp_reply_t encode(const ecp::EcpReply& in) {
  mrroc_lcm::ecp_mp_reply_t m{};
  m.reply = static_cast<std::int8_t>(in.type);
  m.error_code = in.error_code;
  m.error_class = static_cast<std::int8_t>(in.error_class);
  m.error_text = in.error_text;
  m.is_synchronised = in.synchronised ? 1 : 0;
  m.n_joints = length(in.joints, "joints");
  m.joints = in.joints;
  m.desired_joints = in.desired_joints;
  m.desired_joints.resize(in.joints.size(), 0.0);
  m.arm_type = arm_code(in.arm_type);
  m.n_arm = length(in.arm, "arm");
  m.arm = in.arm;
  return m;
}

ecp::EcpReply decode(const mrroc_lcm::ecp_mp_reply_t& m) {
  using R = mrroc_lcm::ecp_mp_reply_t;
  ecp::EcpReply out;
  out.type = checked_enum<ecp::EcpReplyType>(m.reply, R::ACKNOWLEDGE, R::ERROR, "reply");
  out.error_code = m.error_code;
  out.error_class = checked_enum<ecp::ErrorClass>(m.error_class, 0, R::SYSTEM, "error_class");
  out.error_text = m.error_text;
  out.synchronised = m.is_synchronised != 0;
  out.joints = checked_vector(m.joints, m.n_joints, "joints");
  out.desired_joints = checked_vector(m.desired_joints, m.n_joints, "desired_joints");
  out.arm_type = arm_of(m.arm_type, "arm_type");
  out.arm = checked_vector(m.arm, m.n_arm, "arm");
  return out;
}

}  // namespace mrroc::comm

namespace mrroc::edp {
const char* to_string(ArmRepresentation r) {
  switch (r) {
    case ArmRepresentation::frame: return "FRAME";
    case ArmRepresentation::xyz_euler_zyz: return "XYZ_EULER_ZYZ";
    case ArmRepresentation::xyz_angle_axis: return "XYZ_ANGLE_AXIS";
    case ArmRepresentation::joint: return "JOINT";
    case ArmRepresentation::motor: return "MOTOR";
  }
  return "?";
}
const char* to_string(InstructionType t) {
  switch (t) {
    case InstructionType::set: return "SET";
    case InstructionType::get: return "GET";
    case InstructionType::set_get: return "SET_GET";
    case InstructionType::synchro: return "SYNCHRO";
    case InstructionType::query: return "QUERY";
  }
  return "?";
}
}  // namespace mrroc::edp

namespace mrroc::ecp {
const char* to_string(MpCommandType t) {
  switch (t) {
    case MpCommandType::start_task: return "START_TASK";
    case MpCommandType::next_pose: return "NEXT_POSE";
    case MpCommandType::end_motion: return "END_MOTION";
    case MpCommandType::next_state: return "NEXT_STATE";
    case MpCommandType::stop: return "STOP";
    case MpCommandType::pause: return "PAUSE";
    case MpCommandType::resume: return "RESUME";
  }
  return "?";
}
}  // namespace mrroc::ecp
