// One LCM message type, decoded from raw bytes the way every handler decodes it
// (comm::detail::decode_received), then into plain values by its codec (comm::decode of
// comm/codec.hpp for the links and raw sensor samples, of comm/messages.hpp for the others, as
// the typed subscribers and links decode them). One program for all types, started under one
// name per type (fuzz/fuzz_<type>), which selects it (LLVMFuzzerInitialize below).
//
// Properties (docs/fuzzing.md):
// - decoding never throws: bytes either decode or are rejected;
// - bytes that decode re-encode to the bytes that were read (LCM's encoding is canonical), except
//   for the byte that ends each string (the decoder skips it, the encoder writes NUL), unless a
//   string holds a NUL, which LCM's encoder cuts; the re-encoding decodes again and encodes to
//   itself;
// - comm::decode throws only DecodeError, naming the field; a message it accepts holds only named
//   enumerators and consistent vectors (finite values in a valid sensor reading or sample),
//   encodes without an error, and decodes again to the same value, also through bytes.
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include <lcm/lcm-cpp.hpp>

#include "fuzz_common.hpp"
#include "mrroc/comm/codec.hpp"
#include "mrroc/comm/messages.hpp"
#include "mrroc/comm/sync_annotations.hpp"
#include "mrroc_lcm/ecp_mp_reply_t.hpp"
#include "mrroc_lcm/edp_instruction_t.hpp"
#include "mrroc_lcm/edp_reply_t.hpp"
#include "mrroc_lcm/emergency_stop_t.hpp"
#include "mrroc_lcm/launch_command_t.hpp"
#include "mrroc_lcm/launch_status_t.hpp"
#include "mrroc_lcm/mp_ecp_command_t.hpp"
#include "mrroc_lcm/operator_command_t.hpp"
#include "mrroc_lcm/operator_reply_t.hpp"
#include "mrroc_lcm/process_status_t.hpp"
#include "mrroc_lcm/raw_sensor_t.hpp"
#include "mrroc_lcm/robot_state_t.hpp"
#include "mrroc_lcm/scene_objects_t.hpp"
#include "mrroc_lcm/srp_history_reply_t.hpp"
#include "mrroc_lcm/srp_history_request_t.hpp"
#include "mrroc_lcm/srp_message_t.hpp"
#include "mrroc_lcm/vsp_command_t.hpp"
#include "mrroc_lcm/vsp_reply_t.hpp"

namespace fuzz_message {

using fuzz::bits;
using fuzz::escaped;

// ---- The string fields of each LCM type (the ones LCM's encoder cuts at a NUL). ----

std::vector<const std::string*> strings_of(const mrroc_lcm::header_t& h) {
  return {&h.sender, &h.recipient};
}
template <class Msg>
std::vector<const std::string*> with_header(const Msg& m, std::vector<const std::string*> more) {
  std::vector<const std::string*> out = strings_of(m.header);
  out.insert(out.end(), more.begin(), more.end());
  return out;
}
std::vector<const std::string*> strings_of(const mrroc_lcm::edp_instruction_t& m) {
  return with_header(m, {});
}
std::vector<const std::string*> strings_of(const mrroc_lcm::edp_reply_t& m) {
  return with_header(m, {&m.error_text});
}
std::vector<const std::string*> strings_of(const mrroc_lcm::mp_ecp_command_t& m) {
  return with_header(m, {&m.state_name, &m.arguments});
}
std::vector<const std::string*> strings_of(const mrroc_lcm::ecp_mp_reply_t& m) {
  return with_header(m, {&m.error_text});
}
std::vector<const std::string*> strings_of(const mrroc_lcm::emergency_stop_t& m) {
  std::vector<const std::string*> out = with_header(m, {&m.robot, &m.reason, &m.by_sender});
  for (const std::string& s : m.engage_senders) out.push_back(&s);
  return out;
}
std::vector<const std::string*> strings_of(const mrroc_lcm::srp_message_t& m) {
  return with_header(m, {&m.process, &m.robot, &m.text});
}
std::vector<const std::string*> strings_of(const mrroc_lcm::process_status_t& m) {
  return with_header(m, {&m.process, &m.robot, &m.detail});
}
std::vector<const std::string*> strings_of(const mrroc_lcm::vsp_command_t& m) {
  return with_header(m, {&m.arguments});
}
void add(std::vector<const std::string*>& out, const std::vector<std::string>& v) {
  for (const std::string& s : v) out.push_back(&s);
}
std::vector<const std::string*> strings_of(const mrroc_lcm::vsp_reply_t& m) {
  auto out = with_header(m, {&m.error_text, &m.invalid_reason});
  add(out, m.names);
  add(out, m.units);
  return out;
}
std::vector<const std::string*> strings_of(const mrroc_lcm::raw_sensor_t& m) {
  auto out = with_header(m, {&m.device});
  add(out, m.names);
  add(out, m.units);
  return out;
}
std::vector<const std::string*> strings_of(const mrroc_lcm::operator_command_t& m) {
  return with_header(m, {});
}
std::vector<const std::string*> strings_of(const mrroc_lcm::operator_reply_t& m) {
  return with_header(m, {&m.task, &m.text});
}
std::vector<const std::string*> strings_of(const mrroc_lcm::robot_state_t& m) {
  return with_header(m, {&m.robot, &m.error});
}
std::vector<const std::string*> strings_of(const mrroc_lcm::launch_status_t& m) {
  auto out = with_header(m, {&m.set_name, &m.config_file, &m.state});
  for (const mrroc_lcm::launch_process_t& p : m.processes)
    out.insert(out.end(), {&p.name, &p.group, &p.host, &p.state, &p.restart});
  return out;
}
std::vector<const std::string*> strings_of(const mrroc_lcm::launch_command_t& m) {
  return with_header(m, {&m.set_name, &m.process});
}
std::vector<const std::string*> strings_of(const mrroc_lcm::srp_history_request_t& m) {
  return with_header(m, {});
}
std::vector<const std::string*> strings_of(const mrroc_lcm::scene_objects_t& m) {
  auto out = with_header(m, {&m.scene});
  for (const mrroc_lcm::scene_object_t& o : m.objects) out.insert(out.end(), {&o.name, &o.attach});
  return out;
}
std::vector<const std::string*> strings_of(const mrroc_lcm::srp_history_reply_t& m) {
  auto out = with_header(m, {});
  for (const mrroc_lcm::srp_message_t& s : m.messages) {
    const auto inner = strings_of(s);  // its header's strings too
    out.insert(out.end(), inner.begin(), inner.end());
  }
  return out;
}

// ---- Plain values as canonical text (all fields; doubles by bits). `wire` applies LCM's cut of
// strings at a NUL, for values that went through bytes. ----

std::string str(const std::string& s, bool wire) {
  return escaped(wire ? fuzz::wire_string(s) : s);
}
std::string doubles(const std::vector<double>& v) {
  std::string out = "[";
  for (const double d : v) out += bits(d) + ",";
  return out + "]";
}
std::string bytes(const std::vector<std::int8_t>& v) {
  std::string out = "[";
  for (const std::int8_t b : v) out += fmt::format("{},", b);
  return out + "]";
}
std::string strs(const std::vector<std::string>& v, bool wire) {
  std::string out = "[";
  for (const std::string& x : v) out += str(x, wire) + ",";
  return out + "]";
}
int code(auto e) { return static_cast<int>(e); }

std::string canonical(const mrroc::edp::Instruction& v, bool) {
  return fmt::format(
      "type={} set={} get={} set_arm_type={} get_arm_type={} motion_type={} motion_steps={} "
      "value_in_step_no={} arm={} tool_type={} tool={} kinematic_model_no={} corrector_no={} "
      "servo_algorithm={} servo_parameters_no={} output_values={} with_query={} "
      "no_successor={}",
      code(v.type), v.set, v.get, code(v.set_arm_type), code(v.get_arm_type), code(v.motion_type),
      v.motion_steps, v.value_in_step_no, doubles(v.arm), code(v.tool_type), doubles(v.tool),
      v.kinematic_model_no, v.corrector_no, bytes(v.servo_algorithm), bytes(v.servo_parameters_no),
      v.output_values, v.with_query, v.no_successor);
}
std::string canonical(const mrroc::edp::Reply& v, bool wire) {
  return fmt::format(
      "type={} error_code={} error_text={} synchronised={} step_no={} macro_steps_ahead={} "
      "servo_cycle={} arm_type={} "
      "arm={} joints={} desired_joints={} joint_velocities={} tool_type={} tool={} "
      "kinematic_model_no={} corrector_no={} servo_algorithm={} servo_parameters_no={} "
      "input_values={} servo_cycles={} servo_overruns={} servo_period_us={} lateness_p50_us={} "
      "lateness_p99_us={} lateness_max_us={}",
      code(v.type), v.error_code, str(v.error_text, wire), v.synchronised, v.step_no,
      v.macro_steps_ahead, v.servo_cycle, code(v.arm_type), doubles(v.arm), doubles(v.joints),
      doubles(v.desired_joints), doubles(v.joint_velocities), code(v.tool_type), doubles(v.tool),
      v.kinematic_model_no, v.corrector_no, bytes(v.servo_algorithm), bytes(v.servo_parameters_no),
      v.input_values, v.servo_cycles, v.servo_overruns, bits(v.servo_period_us),
      bits(v.lateness_p50_us), bits(v.lateness_p99_us), bits(v.lateness_max_us));
}
std::string canonical(const mrroc::ecp::MpCommand& v, bool wire) {
  return fmt::format(
      "type={} state_name={} arguments={} arm_type={} motion_type={} motion_steps={} "
      "value_in_step_no={} arm={}",
      code(v.type), str(v.state_name, wire), str(v.arguments, wire), code(v.arm_type),
      code(v.motion_type), v.motion_steps, v.value_in_step_no, doubles(v.arm));
}
std::string canonical(const mrroc::ecp::EcpReply& v, bool wire) {
  return fmt::format(
      "type={} error_code={} error_class={} error_text={} synchronised={} joints={} "
      "desired_joints={} arm_type={} arm={}",
      code(v.type), v.error_code, code(v.error_class), str(v.error_text, wire), v.synchronised,
      doubles(v.joints), doubles(v.desired_joints), code(v.arm_type), doubles(v.arm));
}

std::string canonical(const mrroc::vsp::Request& v, bool wire) {
  return fmt::format("command={} arguments={}", code(v.command), str(v.arguments, wire));
}
std::string canonical(const mrroc::vsp::Reply& v, bool wire) {
  const mrroc::vsp::Reading& r = v.reading;
  return fmt::format(
      "kind={} error_code={} error_text={} valid={} invalid_reason={} reading_utime={} age_us={} "
      "reading_no={} values={} names={} units={}",
      code(v.kind), v.error_code, str(v.error_text, wire), r.valid, str(r.invalid_reason, wire),
      r.reading_utime, r.age_us, r.reading_no, doubles(r.values), strs(r.names, wire),
      strs(r.units, wire));
}
std::string canonical(const mrroc::vsp::RawSample& v, bool wire) {
  return fmt::format("device={} sample_utime={} sample_no={} valid={} values={} names={} units={}",
                     str(v.device, wire), v.sample_utime, v.sample_no, v.valid, doubles(v.values),
                     strs(v.names, wire), strs(v.units, wire));
}

// The time of sending of a process status and a launcher's table comes from the header, which
// comm::encode leaves to the publisher: not part of their canonical text. Nor is a process row's
// local_metrics (the launcher's own, not sent).
std::string canonical(const mrroc::EmergencyStop& v, bool wire) {
  std::string engages;
  for (const auto& e : v.engages) engages += fmt::format(" {}:{}", str(e.sender, wire), e.id);
  return fmt::format("action={} robot={} reason={} command_id={} by={}:{} engages={}",
                     code(v.action), str(v.robot, wire), str(v.reason, wire), v.command_id,
                     str(v.by.sender, wire), v.by.id, engages);
}
std::string canonical(const mrroc::RobotState& v, bool wire) {
  return fmt::format(
      "robot={} synchronised={} moving={} estop={} fault={} error={} servo_step={} "
      "servo_period_s={} q={} dq={} q_desired={} lateness_mean_us={} lateness_max_us={} "
      "overruns={}",
      str(v.robot, wire), v.synchronised, v.moving, v.estop, v.fault, str(v.error, wire),
      v.servo_step, bits(v.servo_period_s), doubles(v.q), doubles(v.dq), doubles(v.q_desired),
      bits(v.lateness_mean_us), bits(v.lateness_max_us), v.overruns);
}
std::string canonical(const mrroc::SrpMessage& v, bool wire) {
  return fmt::format("utime={} process={} robot={} severity={} code={} text={}", v.utime,
                     str(v.process, wire), str(v.robot, wire), code(v.severity), v.code,
                     str(v.text, wire));
}
std::string canonical(const mrroc::ProcessStatus& v, bool wire) {
  return fmt::format("process={} robot={} pid={} state={} uptime_us={} detail={}",
                     str(v.process, wire), str(v.robot, wire), v.pid, code(v.state), v.uptime_us,
                     str(v.detail, wire));
}
std::string canonical(const mrroc::SrpHistoryRequest& v, bool) {
  return fmt::format("after={} max_count={} min_severity={}", v.after, v.max_count,
                     code(v.min_severity));
}
std::string canonical(const mrroc::SrpHistoryReply& v, bool wire) {
  std::string out = fmt::format("last={} entries=[", v.last);
  for (const mrroc::SrpHistoryEntry& e : v.entries)
    out += fmt::format("{}:{{{}}},", e.number, canonical(e.message, wire));
  return out + "]";
}
std::string canonical(const mrroc::mp::OperatorCommand& v, bool) {
  return fmt::format("type={}", code(v.type));
}
std::string canonical(const mrroc::mp::OperatorReply& v, bool wire) {
  return fmt::format("accepted={} state={} task={} runs={} started_utime={} text={}", v.accepted,
                     code(v.state), str(v.task, wire), v.runs, v.started_utime, str(v.text, wire));
}
std::string canonical(const mrroc::launch::LaunchStatus& v, bool wire) {
  std::string out =
      fmt::format("set_name={} config_file={} state={} launcher_pid={} uptime_s={} processes=[",
                  str(v.set_name, wire), str(v.config_file, wire), str(v.state, wire),
                  v.launcher_pid, bits(v.uptime_s));
  for (const mrroc::launch::ProcessRow& p : v.processes)
    out += fmt::format(
        "{{name={} group={} host={} state={} pid={} cpu_percent={} rss_kb={} restarts={} "
        "uptime_s={} last_exit_code={} required={} restart={}}},",
        str(p.name, wire), str(p.group, wire), str(p.host, wire), str(p.state, wire), p.pid,
        bits(p.cpu_percent), p.rss_kb, p.restarts, bits(p.uptime_s), p.last_exit_code, p.required,
        str(p.restart, wire));
  return out + "]";
}
std::string canonical(const mrroc::launch::LaunchCommand& v, bool wire) {
  return fmt::format("set_name={} type={} process={}", str(v.set_name, wire), code(v.type),
                     str(v.process, wire));
}
std::string canonical(const mrroc::SceneObjects& v, bool wire) {
  std::string out =
      fmt::format("scene={} sim_time_s={} objects=[", str(v.scene, wire), bits(v.sim_time_s));
  const auto array = [](const auto& a) { return doubles(std::vector<double>(a.begin(), a.end())); };
  for (const mrroc::SceneObjectPose& o : v.objects)
    out += fmt::format("{{name={} shape={} size={} rgba={} attach={} local={}{} pose={}{}}},",
                       str(o.name, wire), code(o.shape), doubles(o.size), array(o.rgba),
                       str(o.attach, wire), array(o.local_position), array(o.local_quaternion),
                       array(o.position), array(o.quaternion));
  return out + "]";
}

// ---- What a decoded value holds: named enumerators, consistent vectors. ----

/// An enumeration of any message: its to_string (found by argument-dependent lookup) names it.
template <class Enum>
void expect_named(Enum e, const char* field) {
  fuzz::expect(std::strcmp(to_string(e), "?") != 0,
               fmt::format("decoded {} holds the unnamed value {}", field, code(e)));
}
void check_decoded(const mrroc::edp::Instruction& v) {
  fuzz::expect(std::strcmp(mrroc::edp::to_string(v.type), "?") != 0,
               fmt::format("decoded instruction type {} has no name", code(v.type)));
  expect_named(v.set_arm_type, "set_arm_type");
  expect_named(v.get_arm_type, "get_arm_type");
  expect_named(v.tool_type, "tool_type");
  fuzz::expect(v.motion_type == mrroc::edp::MotionType::absolute ||
                   v.motion_type == mrroc::edp::MotionType::relative,
               "decoded motion_type is neither absolute nor relative");
  // Every bit of the 8-bit masks names an item (ARM_BIT .. DEVICE_BIT): the wire's int16 masks
  // with a bit above DEVICE_BIT do not decode.
  fuzz::expect(v.device.size() <= static_cast<std::size_t>(mrroc::comm::kMaxVector),
               "decoded device part is longer than the codec allows");
  fuzz::expect(v.servo_algorithm.size() == v.servo_parameters_no.size(),
               "decoded servo vectors differ in length");
}
void check_decoded(const mrroc::edp::Reply& v) {
  fuzz::expect(code(v.type) >= 1 && code(v.type) <= 3,
               fmt::format("decoded reply type {} is unknown", code(v.type)));
  expect_named(v.arm_type, "arm_type");
  expect_named(v.tool_type, "tool_type");
  fuzz::expect(
      v.desired_joints.size() == v.joints.size() && v.joint_velocities.size() == v.joints.size(),
      "decoded joint vectors differ in length");
  fuzz::expect(v.device.size() <= static_cast<std::size_t>(mrroc::comm::kMaxVector),
               "decoded device part is longer than the codec allows");
}
void check_decoded(const mrroc::ecp::MpCommand& v) {
  fuzz::expect(std::strcmp(mrroc::ecp::to_string(v.type), "?") != 0,
               fmt::format("decoded MP command {} has no name", code(v.type)));
  expect_named(v.arm_type, "arm_type");
  fuzz::expect(v.motion_type == mrroc::edp::MotionType::absolute ||
                   v.motion_type == mrroc::edp::MotionType::relative,
               "decoded motion_type is neither absolute nor relative");
}
void check_decoded(const mrroc::ecp::EcpReply& v) {
  fuzz::expect(code(v.type) >= 1 && code(v.type) <= 3,
               fmt::format("decoded ECP reply type {} is unknown", code(v.type)));
  fuzz::expect(code(v.error_class) >= 0 && code(v.error_class) <= 3,
               fmt::format("decoded error_class {} is unknown", code(v.error_class)));
  expect_named(v.arm_type, "arm_type");
  fuzz::expect(v.desired_joints.size() == v.joints.size(),
               "decoded joint vectors differ in length");
}

void check_sensor_values(const std::vector<double>& values, const std::vector<std::string>& names,
                         const std::vector<std::string>& units, bool valid, const char* what) {
  fuzz::expect(names.size() == values.size() && units.size() == values.size() &&
                   values.size() <= static_cast<std::size_t>(mrroc::comm::kMaxSensorValues),
               fmt::format("decoded {} has {} values, {} names, {} units", what, values.size(),
                           names.size(), units.size()));
  if (valid)
    for (const double v : values)
      fuzz::expect(std::isfinite(v), fmt::format("decoded valid {} holds {}", what, v));
}
void check_decoded(const mrroc::vsp::Request& v) {
  fuzz::expect(std::strcmp(mrroc::vsp::to_string(v.command), "?") != 0,
               fmt::format("decoded VSP command {} has no name", code(v.command)));
}
void check_decoded(const mrroc::vsp::Reply& v) {
  fuzz::expect(code(v.kind) >= 0 && code(v.kind) <= 2,
               fmt::format("decoded VSP reply kind {} is unknown", code(v.kind)));
  check_sensor_values(v.reading.values, v.reading.names, v.reading.units, v.reading.valid,
                      "reading");
}
void check_decoded(const mrroc::vsp::RawSample& v) {
  fuzz::expect(!v.device.empty(), "decoded raw sample without a device name");
  check_sensor_values(v.values, v.names, v.units, v.valid, "raw sample");
}

void check_decoded(const mrroc::EmergencyStop& v) { expect_named(v.action, "action"); }
void check_decoded(const mrroc::RobotState& v) {
  fuzz::expect(v.dq.size() == v.q.size() && v.q_desired.size() == v.q.size() &&
                   v.q.size() <= static_cast<std::size_t>(mrroc::comm::kMaxVector),
               fmt::format("decoded robot state has {} q, {} dq, {} q_desired", v.q.size(),
                           v.dq.size(), v.q_desired.size()));
}
void check_decoded(const mrroc::SrpMessage& v) { expect_named(v.severity, "severity"); }
void check_decoded(const mrroc::ProcessStatus& v) { expect_named(v.state, "state"); }
void check_decoded(const mrroc::SrpHistoryRequest& v) {
  expect_named(v.min_severity, "min_severity");
}
void check_decoded(const mrroc::SrpHistoryReply& v) {
  fuzz::expect(v.entries.size() <= static_cast<std::size_t>(mrroc::comm::kMaxHistoryEntries),
               fmt::format("decoded history reply has {} entries", v.entries.size()));
  for (const mrroc::SrpHistoryEntry& e : v.entries) check_decoded(e.message);
}
void check_decoded(const mrroc::mp::OperatorCommand& v) {
  fuzz::expect(std::strcmp(mrroc::mp::to_string(v.type), "?") != 0,
               fmt::format("decoded operator command {} has no name", code(v.type)));
}
void check_decoded(const mrroc::mp::OperatorReply& v) {
  fuzz::expect(std::strcmp(mrroc::mp::to_string(v.state), "?") != 0,
               fmt::format("decoded task state {} has no name", code(v.state)));
}
void check_decoded(const mrroc::launch::LaunchStatus& v) {
  fuzz::expect(v.processes.size() <= static_cast<std::size_t>(mrroc::comm::kMaxLaunchProcesses),
               fmt::format("decoded launcher table has {} rows", v.processes.size()));
}
void check_decoded(const mrroc::launch::LaunchCommand& v) {
  fuzz::expect(v.type == mrroc::launch::LaunchCommandType::restart,
               fmt::format("decoded launch command {} is unknown", code(v.type)));
}
void check_decoded(const mrroc::SceneObjects& v) {
  fuzz::expect(v.objects.size() <= static_cast<std::size_t>(mrroc::comm::kMaxSceneObjects),
               fmt::format("decoded scene has {} objects", v.objects.size()));
  for (const mrroc::SceneObjectPose& o : v.objects) {
    fuzz::expect(
        code(o.shape) >= 1 && code(o.shape) <= 4 &&
            o.size.size() == mrroc::scene_object_size_count(o.shape),
        fmt::format("decoded object of shape {} has {} sizes", code(o.shape), o.size.size()));
    for (const double x : o.size)
      fuzz::expect(std::isfinite(x) && x > 0.0, fmt::format("decoded object size {}", x));
    for (const double x : o.position)
      fuzz::expect(std::isfinite(x), fmt::format("decoded object position {}", x));
  }
}

// ---- LCM level. ----

template <class Msg>
std::vector<std::uint8_t> encode_bytes(const Msg& m, const char* what) {
  std::vector<std::uint8_t> out(static_cast<std::size_t>(m.getEncodedSize()));
  int written = -1;
  fuzz::no_throw(what, [&] { written = m.encode(out.data(), 0, static_cast<int>(out.size())); });
  fuzz::expect(
      written >= 0 && static_cast<std::size_t>(written) <= out.size(),
      fmt::format("{}: encode returned {} for a buffer of {} bytes", what, written, out.size()));
  out.resize(static_cast<std::size_t>(written));
  return out;
}

/// Decodes `data` as the handlers do. Nothing when the bytes are rejected.
template <class Msg>
std::optional<Msg> decode_as_handlers_do(const std::uint8_t* data, std::size_t size) {
  lcm::ReceiveBuffer buffer{};
  buffer.data = const_cast<std::uint8_t*>(data);
  buffer.data_size = static_cast<std::uint32_t>(size);
  Msg msg;
  bool ok = false;
  fuzz::no_throw("comm::detail::decode_received",
                 [&] { ok = mrroc::comm::detail::decode_received(&buffer, msg); });
  if (!ok) return std::nullopt;
  return msg;
}

template <class Msg>
void check_lcm_round_trip(const Msg& msg, const std::uint8_t* data, std::size_t size) {
  Msg again;
  const int read = again.decode(data, 0, static_cast<int>(size));
  fuzz::expect(read >= 0 && static_cast<std::size_t>(read) <= size,
               fmt::format("a second decode of the same bytes returned {}", read));
  bool has_nul = false;
  for (const std::string* s : strings_of(msg))
    has_nul = has_nul || s->find('\0') != std::string::npos;

  const std::vector<std::uint8_t> encoded = encode_bytes(msg, "LCM encode of a decoded message");
  if (!has_nul) {
    // The same bytes, except that the decoder does not look at the byte that ends a string, which
    // the encoder writes as NUL: at most one such difference per string.
    fuzz::expect(encoded.size() == static_cast<std::size_t>(read),
                 fmt::format("decoded {} bytes re-encode to {} bytes", read, encoded.size()));
    std::size_t differences = 0;
    for (std::size_t i = 0; i < encoded.size(); ++i) {
      if (encoded[i] == data[i]) continue;
      fuzz::expect(encoded[i] == 0 && ++differences <= strings_of(msg).size(),
                   fmt::format("decoded bytes re-encode differently at byte {} ({:#04x} -> "
                               "{:#04x})",
                               i, data[i], encoded[i]));
    }
  }
  Msg decoded;
  const int n = decoded.decode(encoded.data(), 0, static_cast<int>(encoded.size()));
  fuzz::expect(
      n == static_cast<int>(encoded.size()),
      fmt::format("a re-encoded message of {} bytes decodes with result {}", encoded.size(), n));
  const std::vector<std::uint8_t> twice =
      encode_bytes(decoded, "LCM encode of a re-decoded message");
  fuzz::expect(twice == encoded, "a re-encoded message does not encode to itself");
}

// ---- Codec level (the types comm::decode converts). ----

template <class Msg>
void check_codec(const Msg& msg) {
  using Plain = decltype(mrroc::comm::decode(msg));
  std::optional<Plain> plain;
  fuzz::guarded<mrroc::comm::DecodeError>(
      "comm::decode", [&] { plain = mrroc::comm::decode(msg); },
      [](const mrroc::comm::DecodeError& e) {
        // The link codecs name the field ("field 'arm' ..."); the sensor codecs name the type
        // first ("raw_sensor_t: n = ...").
        const std::string_view text = e.what();
        fuzz::expect(text.starts_with("field '") || text.starts_with("set_mask ") ||
                         text.starts_with(std::string(Msg::getTypeName()) + ": "),
                     fmt::format("DecodeError does not name the field: {}", escaped(text)));
      });
  if (!plain) return;
  check_decoded(*plain);
  const std::string expected = canonical(*plain, false);

  Msg encoded;
  fuzz::no_throw("comm::encode of a decoded value", [&] { encoded = mrroc::comm::encode(*plain); });
  std::optional<Plain> again;
  fuzz::no_throw("comm::decode of a re-encoded value",
                 [&] { again = mrroc::comm::decode(encoded); });
  const std::string got = canonical(*again, false);
  fuzz::expect(got == expected,
               fmt::format("decode(encode(x)) != x\n  x:    {}\n  got: {}", expected, got));

  const std::vector<std::uint8_t> wire = encode_bytes(encoded, "LCM encode of a re-encoded value");
  Msg received;
  fuzz::expect(received.decode(wire.data(), 0, static_cast<int>(wire.size())) ==
                   static_cast<int>(wire.size()),
               "a re-encoded value does not decode from its bytes");
  std::optional<Plain> through_bytes;
  if (canonical(*plain, true) == expected) {
    fuzz::no_throw("comm::decode of a re-encoded value through bytes",
                   [&] { through_bytes = mrroc::comm::decode(received); });
  } else {
    // A string held a NUL and arrived shortened: it may no longer pass validation (a device name
    // "\0x" arrives empty), but it must still be refused cleanly.
    fuzz::guarded<mrroc::comm::DecodeError>(
        "comm::decode of a re-encoded value through bytes",
        [&] { through_bytes = mrroc::comm::decode(received); },
        [](const mrroc::comm::DecodeError&) {});
    if (!through_bytes) return;
  }
  const std::string expected_wire = canonical(*plain, true);
  const std::string got_wire = canonical(*through_bytes, true);
  fuzz::expect(
      got_wire == expected_wire,
      fmt::format("decode(bytes(encode(x))) != x\n  x:    {}\n  got: {}", expected_wire, got_wire));
}

template <class Msg>
void check_codec_if_any(const Msg& msg) {
  if constexpr (requires { mrroc::comm::decode(msg); }) check_codec(msg);
}

/// One input of type Message: decoded as the handlers do, then checked at both levels.
template <class Message>
int test_one(const std::uint8_t* data, std::size_t size) {
  const std::optional<Message> msg = decode_as_handlers_do<Message>(data, size);
  if (!msg) return 0;
  check_lcm_round_trip(*msg, data, size);
  check_codec_if_any(*msg);
  return 0;
}

using Test = int (*)(const std::uint8_t*, std::size_t);
struct Target {
  std::string_view name;  // the program is fuzz_<name>
  Test test;
};
constexpr Target kTargets[] = {
    {"edp_instruction", &test_one<mrroc_lcm::edp_instruction_t>},
    {"edp_reply", &test_one<mrroc_lcm::edp_reply_t>},
    {"mp_ecp_command", &test_one<mrroc_lcm::mp_ecp_command_t>},
    {"ecp_mp_reply", &test_one<mrroc_lcm::ecp_mp_reply_t>},
    {"vsp_command", &test_one<mrroc_lcm::vsp_command_t>},
    {"vsp_reply", &test_one<mrroc_lcm::vsp_reply_t>},
    {"raw_sensor", &test_one<mrroc_lcm::raw_sensor_t>},
    {"emergency_stop", &test_one<mrroc_lcm::emergency_stop_t>},
    {"srp_message", &test_one<mrroc_lcm::srp_message_t>},
    {"process_status", &test_one<mrroc_lcm::process_status_t>},
    {"operator_command", &test_one<mrroc_lcm::operator_command_t>},
    {"operator_reply", &test_one<mrroc_lcm::operator_reply_t>},
    {"robot_state", &test_one<mrroc_lcm::robot_state_t>},
    {"launch_status", &test_one<mrroc_lcm::launch_status_t>},
    {"launch_command", &test_one<mrroc_lcm::launch_command_t>},
    {"srp_history_request", &test_one<mrroc_lcm::srp_history_request_t>},
    {"srp_history_reply", &test_one<mrroc_lcm::srp_history_reply_t>},
    {"scene_objects", &test_one<mrroc_lcm::scene_objects_t>},
};
Test selected = nullptr;

}  // namespace fuzz_message

// The program is built once and started under one name per message type, fuzz/fuzz_<type> (links
// to fuzz_message, tests/fuzz/CMakeLists.txt): the name selects the type.
extern "C" int LLVMFuzzerInitialize(int* argc, char*** argv) {
  using namespace fuzz_message;
  const std::string self = *argc > 0 ? std::filesystem::path((*argv)[0]).filename().string() : "";
  for (const Target& t : kTargets)
    if (self == "fuzz_" + std::string(t.name)) selected = t.test;
  if (selected == nullptr) {
    std::string names;
    for (const Target& t : kTargets) names += " fuzz_" + std::string(t.name);
    std::fprintf(stderr, "%s: start this program as one of:%s\n", self.c_str(), names.c_str());
    std::exit(2);
  }
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size > (1U << 20)) return -1;  // far above any message; keeps int offsets meaningful
  return fuzz_message::selected(data, size);
}
