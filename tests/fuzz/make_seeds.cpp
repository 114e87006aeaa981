// Writes the seed corpora of the fuzz targets into tests/fuzz/corpus/<target>/ (docs/fuzzing.md):
// messages encoded by the real encoders (comm::encode, then LCM), request/reply exchanges as the
// endpoints see them, the process-set files of configs/, the robots' parameters.toml, NEXT_STATE
// arguments as the MP tasks write them, and trajectory files written by TrajectoryFile::to_text;
// fuzz_auth's seeds are messages signed with its key. Also rewrites the message inputs of
// tests/fuzz/regressions/ (real encodings with one length field changed), so that they still reach
// the decoders after a message type changes.
//
//   fuzz_make_seeds <source dir>     (scripts/fuzz --seeds runs it)
#include <linux/can.h>
#include <linux/can/error.h>

#include <algorithm>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <initializer_list>
#include <iterator>
#include <string>
#include <vector>

#include <fmt/format.h>

#include "fuzz_auth_key.hpp"
#include "mrroc/can/canopen.hpp"
#include "mrroc/comm/auth.hpp"
#include "mrroc/comm/codec.hpp"
#include "mrroc/config/process_set.hpp"
#include "mrroc/ecp/generators/trajectory_file.hpp"
#include "mrroc/msg/sensor_reading.hpp"
#include "mrroc_lcm/emergency_stop_t.hpp"
#include "mrroc_lcm/launch_command_t.hpp"
#include "mrroc_lcm/launch_status_t.hpp"
#include "mrroc_lcm/operator_command_t.hpp"
#include "mrroc_lcm/operator_reply_t.hpp"
#include "mrroc_lcm/process_status_t.hpp"
#include "mrroc_lcm/robot_state_t.hpp"
#include "mrroc_lcm/scene_objects_t.hpp"
#include "mrroc_lcm/srp_history_reply_t.hpp"
#include "mrroc_lcm/srp_history_request_t.hpp"
#include "mrroc_lcm/srp_message_t.hpp"

namespace {

namespace fs = std::filesystem;
using namespace mrroc;

fs::path g_corpus;

void write(const std::string& target, const std::string& name, const std::string& bytes) {
  const fs::path dir = g_corpus / target;
  fs::create_directories(dir);
  std::ofstream out(dir / name, std::ios::binary | std::ios::trunc);
  out << bytes;
  if (!out) throw std::runtime_error("cannot write " + (dir / name).string());
}

template <class Msg>
std::string bytes_of(const Msg& m) {
  std::string out(static_cast<std::size_t>(m.getEncodedSize()), '\0');
  const int n = m.encode(out.data(), 0, static_cast<int>(out.size()));
  if (n != static_cast<int>(out.size())) throw std::runtime_error("encode failed");
  return out;
}

void header(mrroc_lcm::header_t& h, const std::string& sender, std::int64_t seq, std::int8_t kind,
            const std::string& recipient = {}) {
  h.utime = 1700000000000000;
  h.sender = sender;
  h.recipient = recipient;
  h.seq = seq;
  h.kind = kind;
  h.auth_counter = 0;
  h.auth_len = 0;
  h.auth_tag.clear();
}

/// The channel fuzz_auth signs and verifies on.
const std::string kSignedChannel = "fuzz/edp/cmd";

/// Signs `m` as comm::sign does, with the key of fuzz_auth and a fixed counter (so that the seeds
/// do not change from one run to the next).
template <class Msg>
void sign_fixed(Msg& m, std::int64_t counter) {
  static comm::Authenticator auth(fuzz_auth::key());
  m.header.auth_counter = counter;
  m.header.auth_tag.clear();
  m.header.auth_len = 0;
  const std::string unsigned_bytes = bytes_of(m);
  const comm::Authenticator::Tag tag =
      auth.mac(kSignedChannel, reinterpret_cast<const std::uint8_t*>(unsigned_bytes.data()),
               unsigned_bytes.size());
  m.header.auth_tag.assign(tag.begin(), tag.end());
  m.header.auth_len = static_cast<std::int16_t>(tag.size());
}

// ---- Values as the processes send them. ----

std::vector<edp::Instruction> instructions() {
  std::vector<edp::Instruction> out;
  edp::Instruction synchro;
  synchro.type = edp::InstructionType::synchro;
  out.push_back(synchro);
  edp::Instruction move;  // SET ARM in joints, a macro-step of 10 servo steps
  move.type = edp::InstructionType::set;
  move.set = edp::item::arm;
  move.set_arm_type = edp::ArmRepresentation::joint;
  move.motion_steps = 10;
  move.value_in_step_no = 8;
  move.arm = {0.6, -1.35, 0.15, 0.5, 1.0};
  out.push_back(move);
  edp::Instruction query;
  query.type = edp::InstructionType::query;
  out.push_back(query);
  edp::Instruction all;  // every field, as in tests/unit/test_messages.cpp
  all.type = edp::InstructionType::set_get;
  all.set =
      edp::item::arm | edp::item::tool | edp::item::outputs | edp::item::model | edp::item::servo;
  all.get = edp::item::arm | edp::item::inputs | edp::item::timing;
  all.set_arm_type = edp::ArmRepresentation::xyz_euler_zyz;
  all.get_arm_type = edp::ArmRepresentation::frame;
  all.motion_type = edp::MotionType::relative;
  all.motion_steps = 25;
  all.value_in_step_no = 24;
  all.arm = {0.1, 0.2, 0.3, -1.0, 0.5, 2.0};
  all.tool_type = edp::ArmRepresentation::xyz_angle_axis;
  all.tool = {0, 0, 0.25, 0, 0, 0};
  all.kinematic_model_no = 1;
  all.corrector_no = 2;
  all.servo_algorithm = {1, 2, 1, 1, 0};
  all.servo_parameters_no = {0, 1, 0, 3, 0};
  all.output_values = 0xA5;
  out.push_back(all);
  edp::Instruction frame;  // 12 values, the most the arm representations use
  frame.type = edp::InstructionType::set;
  frame.set = edp::item::arm;
  frame.set_arm_type = edp::ArmRepresentation::frame;
  frame.motion_steps = 50;
  frame.value_in_step_no = 51;
  frame.arm = {1, 0, 0, 0.8, 0, 1, 0, 0.0, 0, 0, 1, 1.1};
  out.push_back(frame);
  edp::Instruction grip;  // SET DEVICE of the mujoco gripper: opening [m], force [N]
  grip.type = edp::InstructionType::set_get;
  grip.set = edp::item::device;
  grip.get = edp::item::device;
  grip.device = {0.0, 20.0};
  out.push_back(grip);
  return out;
}

std::vector<edp::Reply> edp_replies() {
  std::vector<edp::Reply> out;
  edp::Reply ack;
  out.push_back(ack);
  edp::Reply data;
  data.type = edp::ReplyType::data;
  data.synchronised = true;
  data.step_no = 8;
  data.servo_cycle = 123456;
  data.arm_type = edp::ArmRepresentation::joint;
  data.arm = {0.6, -1.35, 0.15, 0.5, 1.0};
  data.joints = data.arm;
  data.desired_joints = {0.6, -1.35, 0.15, 0.5, 1.0};
  data.joint_velocities = {0, 0.01, 0, 0, -0.02};
  data.tool = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0.25};
  data.servo_algorithm = {1, 1, 1, 1, 1};
  data.servo_parameters_no = {0, 0, 0, 0, 0};
  data.input_values = 3;
  data.servo_cycles = 5000;
  data.servo_overruns = 1;
  data.servo_period_us = 2000;
  data.lateness_p50_us = 12.5;
  data.lateness_p99_us = 80;
  data.lateness_max_us = 950;
  out.push_back(data);
  edp::Reply gripper = data;  // GET DEVICE: opening [m], speed [m/s], force [N], holding
  gripper.device = {0.0399, 0.0, 19.6, 1.0};
  out.push_back(gripper);
  edp::Reply error;
  error.type = edp::ReplyType::error;
  error.error_code = edp::error_code::out_of_limits;
  error.error_text = "joint 2 (upper_arm) target 0.810000 rad exceeds upper limit 0.700000 rad";
  out.push_back(error);
  return out;
}

std::vector<ecp::MpCommand> mp_commands() {
  std::vector<ecp::MpCommand> out;
  ecp::MpCommand start;
  start.type = ecp::MpCommandType::start_task;
  out.push_back(start);
  ecp::MpCommand state;
  state.type = ecp::MpCommandType::next_state;
  state.state_name = "visit_joint_poses";
  state.arguments = "poses = [[1.0, -1.5708, 0.0, 0.0, 0.0], [0.0, -1.5708, 0.0, 0.0, 0.0]]\n";
  out.push_back(state);
  ecp::MpCommand pose;
  pose.type = ecp::MpCommandType::next_pose;
  pose.arm_type = edp::ArmRepresentation::xyz_angle_axis;
  pose.motion_type = edp::MotionType::absolute;
  pose.motion_steps = 20;
  pose.value_in_step_no = 19;
  pose.arm = {0.8, 0.0, 1.1, 0.0, 1.5, 0.0};
  out.push_back(pose);
  for (const auto t : {ecp::MpCommandType::end_motion, ecp::MpCommandType::stop,
                       ecp::MpCommandType::pause, ecp::MpCommandType::resume}) {
    ecp::MpCommand c;
    c.type = t;
    out.push_back(c);
  }
  return out;
}

std::vector<ecp::EcpReply> ecp_replies() {
  std::vector<ecp::EcpReply> out;
  ecp::EcpReply ack;
  ack.synchronised = true;
  ack.joints = {0.6, -1.35, 0.15, 0.5, 1.0};
  ack.desired_joints = ack.joints;
  out.push_back(ack);
  ecp::EcpReply pose;
  pose.arm_type = edp::ArmRepresentation::xyz_euler_zyz;
  pose.arm = {0.8, 0.0, 1.1, 0.0, 1.5, 0.0};
  out.push_back(pose);
  ecp::EcpReply done;
  done.type = ecp::EcpReplyType::task_terminated;
  out.push_back(done);
  ecp::EcpReply error;
  error.type = ecp::EcpReplyType::error;
  error.error_class = ecp::ErrorClass::non_fatal;
  error.error_code = ecp::error_code::malformed;
  error.error_text = "malformed command: field 'motion_type' has value 7, expected 1..2";
  out.push_back(error);
  return out;
}

std::vector<vsp::Request> vsp_requests() {
  return {{vsp::Command::configure, "zero = true\n"},
          {vsp::Command::initiate_reading, "tool_rotation = [0.0, 0.0, 1.5708]\n"},
          {vsp::Command::get_reading, ""},
          {vsp::Command::terminate, ""}};
}

std::vector<vsp::Reply> vsp_replies() {
  std::vector<vsp::Reply> out;
  out.emplace_back();  // ACKNOWLEDGE
  vsp::Reply force;
  force.kind = vsp::ReplyKind::reading;
  force.reading.valid = true;
  force.reading.reading_utime = 1700000000000000;
  force.reading.age_us = 850;
  force.reading.reading_no = 12;
  force.reading.values = {0.5, -1.25, 9.81, 0.01, -0.02, 0.0};
  force.reading.names = {"fx", "fy", "fz", "tx", "ty", "tz"};
  force.reading.units = {"N", "N", "N", "N m", "N m", "N m"};
  out.push_back(force);
  vsp::Reply stale;
  stale.kind = vsp::ReplyKind::reading;
  stale.reading.invalid_reason = "source left_wrist_gauges stale for 120 ms";
  stale.reading.values = {0.0};
  stale.reading.names = {"range"};
  stale.reading.units = {"m"};
  out.push_back(stale);
  vsp::Reply error;
  error.kind = vsp::ReplyKind::error;
  error.error_code = vsp::error_code::bad_argument;
  error.error_text = "unknown key 'zeroo' in CONFIGURE arguments";
  out.push_back(error);
  return out;
}

std::vector<vsp::RawSample> raw_samples() {
  std::vector<vsp::RawSample> out;
  vsp::RawSample gauges;
  gauges.device = "left_wrist_gauges";
  gauges.sample_utime = 1700000000000000;
  gauges.sample_no = 41;
  gauges.values = {0.011, -0.002, 0.0005, 0.3, -0.12, 0.07};
  gauges.names = {"g0", "g1", "g2", "g3", "g4", "g5"};
  gauges.units = {"V", "V", "V", "V", "V", "V"};
  out.push_back(gauges);
  vsp::RawSample range;
  range.device = "sonar";
  range.sample_no = 7;
  range.valid = false;
  range.values = {0.0};
  range.names = {"d"};
  range.units = {"m"};
  out.push_back(range);
  return out;
}

/// fuzz_vsp_plugins: [vsp][source][raw_sensor_t] for the first VSPs of the example sets, with
/// samples of 1 (range, encoder), 6 (strain gauges) and 7 (object pose) values.
void vsp_plugin_seeds() {
  int i = 0;
  for (const std::size_t count : {1U, 6U, 7U}) {
    vsp::RawSample s;
    s.device = "seed";
    s.sample_utime = 1700000000000000;
    s.sample_no = 1;
    for (std::size_t k = 0; k < count; ++k) {
      s.values.push_back(0.01 * static_cast<double>(k + 1));
      s.names.push_back(fmt::format("v{}", k));
      s.units.push_back("V");
    }
    auto m = comm::encode(s);
    header(m.header, "mrroc-axis-emu#77", 1, mrroc_lcm::header_t::BROADCAST);
    const std::string bytes = bytes_of(m);
    for (unsigned vsp = 0; vsp < 6; ++vsp)
      write("vsp_plugins", fmt::format("{:02}", i++),
            std::string{static_cast<char>(vsp), '\0'} + bytes);
  }
}

template <class Plain>
void message_seeds(const std::string& target, const std::vector<Plain>& values, std::int8_t kind) {
  int i = 0;
  for (const Plain& v : values) {
    auto m = comm::encode(v);
    switch (kind) {
      case mrroc_lcm::header_t::REQUEST: header(m.header, "ecp/irb6#4242", i + 1, kind); break;
      case mrroc_lcm::header_t::REPLY:
        header(m.header, "edp/irb6", i + 1, kind, "ecp/irb6#4242");
        break;
      default: header(m.header, "mrroc-axis-emu#77", i + 1, kind); break;
    }
    write(target, fmt::format("{:02}", i++), bytes_of(m));
  }
}

void other_message_seeds() {
  mrroc_lcm::emergency_stop_t stop{};
  header(stop.header, "ui#17", 1, mrroc_lcm::header_t::BROADCAST);
  stop.action = mrroc_lcm::emergency_stop_t::ENGAGE;
  stop.robot = "";
  stop.reason = "operator pressed STOP";
  write("emergency_stop", "00", bytes_of(stop));
  stop.action = mrroc_lcm::emergency_stop_t::RELEASE;
  stop.robot = "irb6";
  stop.reason = "";
  stop.command_id = 1790000000000000;
  write("emergency_stop", "01", bytes_of(stop));
  stop.action = mrroc_lcm::emergency_stop_t::ENGAGED;
  stop.command_id = 0;
  stop.by_sender = "ui#17";
  stop.by_id = 1790000000000001;
  stop.n_engages = 2;
  stop.engage_senders = {"ui#17", "ui#18"};
  stop.engage_ids = {1790000000000001, 1790000000000002};
  write("emergency_stop", "02", bytes_of(stop));

  mrroc_lcm::srp_message_t srp{};
  header(srp.header, "edp/irb6#99", 3, mrroc_lcm::header_t::BROADCAST);
  srp.utime = 1700000000000001;
  srp.process = "edp/irb6";
  srp.robot = "irb6";
  srp.severity = mrroc_lcm::srp_message_t::WARNING;
  srp.code = 1;
  srp.text = "malformed instruction dropped: field 'motion_type' has value 7, expected 1..2";
  write("srp_message", "00", bytes_of(srp));
  srp.severity = mrroc_lcm::srp_message_t::INFO;
  srp.code = 0;
  srp.text = "ready: plugin 'mujoco', 5 axes";
  write("srp_message", "01", bytes_of(srp));

  mrroc_lcm::process_status_t status{};
  header(status.header, "ecp/irb6#100", 7, mrroc_lcm::header_t::BROADCAST);
  status.process = "ecp/irb6";
  status.robot = "irb6";
  status.pid = 100;
  status.state = mrroc_lcm::process_status_t::RUNNING;
  status.uptime_us = 2500000;
  status.detail = "";
  write("process_status", "00", bytes_of(status));
  status.state = mrroc_lcm::process_status_t::FAILED;
  status.detail = "no reply from EDP irb6";
  write("process_status", "01", bytes_of(status));
}

// ---- The console's, the EDP's, the launcher's and the SRP history's messages. ----

mrroc_lcm::srp_message_t srp_entry(const std::string& process, std::int8_t severity,
                                   const std::string& text, std::int64_t seq) {
  mrroc_lcm::srp_message_t m{};
  header(m.header, process + "#" + std::to_string(100 + seq), seq, mrroc_lcm::header_t::BROADCAST);
  m.utime = 1700000000000000 + seq;
  m.process = process;
  m.robot = process.starts_with("edp/") ? process.substr(4) : "";
  m.severity = severity;
  m.code = 0;
  m.text = text;
  return m;
}

std::vector<mrroc_lcm::operator_command_t> operator_commands() {
  std::vector<mrroc_lcm::operator_command_t> out;
  std::int64_t seq = 0;
  for (const std::int8_t c :
       {mrroc_lcm::operator_command_t::START, mrroc_lcm::operator_command_t::PAUSE,
        mrroc_lcm::operator_command_t::RESUME, mrroc_lcm::operator_command_t::STOP,
        mrroc_lcm::operator_command_t::TERMINATE, mrroc_lcm::operator_command_t::STATUS}) {
    mrroc_lcm::operator_command_t m{};
    header(m.header, "ui#4711", ++seq, mrroc_lcm::header_t::REQUEST);
    m.command = c;
    out.push_back(m);
  }
  return out;
}

std::vector<mrroc_lcm::operator_reply_t> operator_replies() {
  std::vector<mrroc_lcm::operator_reply_t> out;
  mrroc_lcm::operator_reply_t running{};
  header(running.header, "mp#42", 1, mrroc_lcm::header_t::REPLY, "ui#4711");
  running.accepted = true;
  running.state = mrroc_lcm::operator_reply_t::RUNNING;
  running.task = "visit_joint_poses";
  running.runs = 1;
  running.started_utime = 1700000000000000;
  running.text = "";
  out.push_back(running);
  mrroc_lcm::operator_reply_t refused = running;
  refused.header.seq = 2;
  refused.accepted = false;
  refused.state = mrroc_lcm::operator_reply_t::IDLE;
  refused.runs = 0;
  refused.started_utime = 0;
  refused.text = "RESUME does not apply: the task is not paused (IDLE)";
  out.push_back(refused);
  mrroc_lcm::operator_reply_t failed = running;
  failed.header.seq = 3;
  failed.state = mrroc_lcm::operator_reply_t::FAILED;
  failed.runs = 2;
  failed.text = "ECP irb6: joint 2 (upper_arm) target 0.81 rad exceeds upper limit 0.7 rad";
  out.push_back(failed);
  return out;
}

std::vector<mrroc_lcm::robot_state_t> robot_states() {
  std::vector<mrroc_lcm::robot_state_t> out;
  mrroc_lcm::robot_state_t m{};
  header(m.header, "edp/irb6#99", 500, mrroc_lcm::header_t::BROADCAST);
  m.robot = "irb6";
  m.synchronised = true;
  m.moving = true;
  m.servo_step = 250000;
  m.servo_period_s = 0.002;
  m.n_joints = 5;
  m.q = {0.6, -1.35, 0.15, 0.5, 1.0};
  m.dq = {0.0, 0.01, 0.0, 0.0, -0.02};
  m.q_desired = {0.6, -1.349, 0.15, 0.5, 0.999};
  m.lateness_mean_us = 14.5;
  m.lateness_max_us = 950;
  m.overruns = 1;
  m.error = "";
  out.push_back(m);
  mrroc_lcm::robot_state_t fault{};
  header(fault.header, "edp/rnt#98", 7, mrroc_lcm::header_t::BROADCAST);
  fault.robot = "rnt";
  fault.estop = true;
  fault.fault = true;
  fault.error = "axis 3: following error 0.21 rad exceeds 0.2 rad";
  fault.servo_period_s = 0.001;
  fault.n_joints = 0;
  out.push_back(fault);
  return out;
}

mrroc_lcm::launch_process_t launched(const std::string& name, const std::string& group,
                                     const std::string& state, std::int32_t pid) {
  mrroc_lcm::launch_process_t p{};
  p.name = name;
  p.group = group;
  p.host = "local";
  p.state = state;
  p.pid = pid;
  p.cpu_percent = pid != 0 ? 3.5 : 0.0;
  p.rss_kb = pid != 0 ? 20480 : 0;
  p.restarts = 0;
  p.uptime_s = pid != 0 ? 12.25 : 0.0;
  p.last_exit_code = -1;
  p.required = true;
  p.restart = "never";
  return p;
}

std::vector<mrroc_lcm::launch_status_t> launch_statuses() {
  std::vector<mrroc_lcm::launch_status_t> out;
  mrroc_lcm::launch_status_t m{};
  header(m.header, "mrroc-launch#10", 12, mrroc_lcm::header_t::BROADCAST);
  m.set_name = "demo-irb6";
  m.config_file = "/opt/mrroc/configs/demo-irb6.toml";
  m.state = "running";
  m.launcher_pid = 10;
  m.uptime_s = 12.5;
  m.processes = {launched("srp", "srp", "running", 11), launched("edp/irb6", "edp", "running", 12),
                 launched("ecp/irb6", "ecp", "running", 13), launched("mp", "mp", "running", 14)};
  m.processes[1].host = "cabinet";
  m.processes[1].restart = "on-failure";
  m.processes[1].restarts = 1;
  m.n = static_cast<std::int32_t>(m.processes.size());
  out.push_back(m);
  mrroc_lcm::launch_status_t stopping = m;
  stopping.header.seq = 13;
  stopping.state = "stopping";
  stopping.processes = {launched("mp", "mp", "exited", 0), launched("ui", "ui", "backoff", 0)};
  stopping.processes[0].last_exit_code = 0;
  stopping.processes[1].required = false;
  stopping.processes[1].restart = "always";
  stopping.n = 2;
  out.push_back(stopping);
  return out;
}

std::vector<mrroc_lcm::srp_history_request_t> history_requests() {
  std::vector<mrroc_lcm::srp_history_request_t> out;
  mrroc_lcm::srp_history_request_t all{};
  header(all.header, "ui#4711", 1, mrroc_lcm::header_t::REQUEST);
  all.after = 0;
  all.max_count = 500;
  all.min_severity = mrroc_lcm::srp_message_t::DEBUG;
  out.push_back(all);
  mrroc_lcm::srp_history_request_t newer = all;
  newer.header.seq = 2;
  newer.after = 1234;
  newer.max_count = 50;
  newer.min_severity = mrroc_lcm::srp_message_t::WARNING;
  out.push_back(newer);
  return out;
}

std::vector<mrroc_lcm::srp_history_reply_t> history_replies() {
  std::vector<mrroc_lcm::srp_history_reply_t> out;
  mrroc_lcm::srp_history_reply_t m{};
  header(m.header, "srp#11", 1, mrroc_lcm::header_t::REPLY, "ui#4711");
  m.last = 3;
  m.numbers = {1, 2, 3};
  m.messages = {
      srp_entry("edp/irb6", mrroc_lcm::srp_message_t::INFO, "ready: plugin 'mujoco', 5 axes", 1),
      srp_entry("mp", mrroc_lcm::srp_message_t::INFO, "task visit_joint_poses started", 2),
      srp_entry("edp/irb6", mrroc_lcm::srp_message_t::WARNING,
                "malformed instruction dropped: field 'motion_type' has value 7, expected 1..2",
                3)};
  m.n = 3;
  out.push_back(m);
  mrroc_lcm::srp_history_reply_t empty{};
  header(empty.header, "srp#11", 2, mrroc_lcm::header_t::REPLY, "ui#4711");
  empty.last = 0;
  empty.n = 0;
  out.push_back(empty);
  return out;
}

std::vector<mrroc_lcm::launch_command_t> launch_commands() {
  std::vector<mrroc_lcm::launch_command_t> out;
  mrroc_lcm::launch_command_t m{};
  header(m.header, "ui#4711", 1, mrroc_lcm::header_t::BROADCAST);
  m.set_name = "cell-hil";
  m.command = mrroc_lcm::launch_command_t::RESTART;
  m.process = "edp/irb6";
  out.push_back(m);
  return out;
}

std::vector<mrroc_lcm::scene_objects_t> scene_objects() {
  std::vector<mrroc_lcm::scene_objects_t> out;
  mrroc_lcm::scene_objects_t m{};
  header(m.header, "emu#12", 30, mrroc_lcm::header_t::BROADCAST);
  m.scene = "conveyor-pick";
  m.sim_time_s = 1.0;
  mrroc_lcm::scene_object_t part{};
  part.name = "part";
  part.shape = mrroc_lcm::scene_object_t::BOX;
  part.n_size = 3;
  part.size = {0.03, 0.03, 0.03};
  const double red[4] = {0.8, 0.2, 0.2, 1.0};
  std::copy(red, red + 4, part.rgba);
  part.attach = "conveyor/belt_link";
  part.local_position[2] = 0.04;
  part.local_quaternion[0] = 1.0;
  part.position[0] = -0.9;
  part.position[1] = -0.65;
  part.position[2] = 0.79;
  part.quaternion[0] = 1.0;
  mrroc_lcm::scene_object_t probe = part;
  probe.name = "probe";
  probe.shape = mrroc_lcm::scene_object_t::SPHERE;
  probe.n_size = 1;
  probe.size = {0.02};
  probe.attach = "";
  mrroc_lcm::scene_object_t can = probe;
  can.name = "can";
  can.shape = mrroc_lcm::scene_object_t::CAPSULE;
  can.n_size = 2;
  can.size = {0.04, 0.06};
  m.objects = {part, probe, can};
  m.n = 3;
  out.push_back(m);
  mrroc_lcm::scene_objects_t empty{};
  header(empty.header, "emu#13", 0, mrroc_lcm::header_t::BROADCAST);
  empty.scene = "bare";
  out.push_back(empty);
  return out;
}

/// Writes the messages as they are, and the first of them signed too (the auth fields set).
template <class Msg>
void lcm_seeds(const std::string& target, std::vector<Msg> messages) {
  int i = 0;
  for (const Msg& m : messages) write(target, fmt::format("{:02}", i++), bytes_of(m));
  sign_fixed(messages.front(), 1700000000000000);
  write(target, fmt::format("{:02}-signed", i), bytes_of(messages.front()));
}

void new_message_seeds() {
  lcm_seeds("operator_command", operator_commands());
  lcm_seeds("operator_reply", operator_replies());
  lcm_seeds("robot_state", robot_states());
  lcm_seeds("launch_status", launch_statuses());
  lcm_seeds("srp_history_request", history_requests());
  lcm_seeds("srp_history_reply", history_replies());
  lcm_seeds("launch_command", launch_commands());
  lcm_seeds("scene_objects", scene_objects());
}

// ---- fuzz_auth: [selector][message] with messages signed with its key, and counter sequences.

template <class Msg>
void auth_seed(std::size_t selector, Msg m, const std::string& name, std::int64_t counter) {
  sign_fixed(m, counter);
  write("auth", name, std::string(1, static_cast<char>(selector)) + bytes_of(m));
}

template <class Plain>
auto lcm_of(const Plain& v, const std::string& sender, std::int64_t seq, std::int8_t kind) {
  auto m = comm::encode(v);
  header(m.header, sender, seq, kind,
         kind == mrroc_lcm::header_t::REPLY ? std::string("client#1") : std::string());
  return m;
}

void auth_seeds() {
  // The selectors of fuzz_auth.cpp's kTypes.
  constexpr std::int64_t c = 1700000000000000;
  const std::int8_t req = mrroc_lcm::header_t::REQUEST;
  const std::int8_t rep = mrroc_lcm::header_t::REPLY;
  auth_seed(0, lcm_of(instructions()[1], "ecp/irb6#1", 1, req), "edp_instruction", c);
  auth_seed(1, lcm_of(edp_replies()[1], "edp/irb6#2", 1, rep), "edp_reply", c + 1);
  auth_seed(2, lcm_of(mp_commands()[1], "mp#3", 1, req), "mp_ecp_command", c + 2);
  auth_seed(3, lcm_of(ecp_replies()[3], "ecp/irb6#1", 1, rep), "ecp_mp_reply", c + 3);
  auth_seed(4, lcm_of(vsp_requests()[1], "ecp/irb6#1", 1, req), "vsp_command", c + 4);
  auth_seed(5, lcm_of(vsp_replies()[1], "vsp/wrist#5", 1, rep), "vsp_reply", c + 5);
  mrroc_lcm::emergency_stop_t release{};
  header(release.header, "ui#17", 2, mrroc_lcm::header_t::BROADCAST);
  release.action = mrroc_lcm::emergency_stop_t::RELEASE;
  release.robot = "irb6";
  release.reason = "";
  auth_seed(6, release, "emergency_stop", c + 6);
  auth_seed(7, operator_commands()[0], "operator_command", c + 7);
  auth_seed(8, operator_replies()[2], "operator_reply", c + 8);
  auth_seed(9, history_requests()[1], "srp_history_request", c + 9);
  auth_seed(10, history_replies()[0], "srp_history_reply", c + 10);
  auth_seed(11, launch_statuses()[0], "launch_status", c + 11);
  auth_seed(12, robot_states()[0], "robot_state", c + 12);
  // Counter mode (selector 13): counters around now from three senders, in order, reordered
  // within the window, repeated, and far behind.
  std::string counters(1, static_cast<char>(fuzz_auth::kMessageTypes));
  const auto add = [&](int sender, std::uint64_t raw) {
    counters += static_cast<char>(sender);
    for (unsigned i = 0; i < 8; ++i) counters += static_cast<char>((raw >> (8U * i)) & 0xffU);
  };
  // raw % 8000001 - 4000000 is the offset from now [us].
  for (const std::uint64_t offset :
       {4000000ULL, 4000100ULL, 4000050ULL, 4000100ULL, 4000200ULL, 2000000ULL, 4500000ULL})
    add(0, offset);
  add(1, 4000000);
  add(1, 0);
  add(2, 0xC000000000000000ULL);
  add(1, 3999999);
  write("auth", "counters", counters);
}

// ---- Request/reply exchanges for fuzz_links: records [channel][flags][length LE16][payload]. ----

/// Flags added to every record: for links_auth, bit 1 (sign the payload with the key).
int g_link_flags = 0;

std::string record(int channel, int flags, const std::string& payload) {
  std::string out;
  out += static_cast<char>(channel);
  out += static_cast<char>(flags | g_link_flags);
  out += static_cast<char>(payload.size() & 0xffU);
  out += static_cast<char>((payload.size() >> 8U) & 0xffU);
  return out + payload;
}

template <class Plain>
std::string request(const Plain& v, const std::string& client, std::int64_t seq) {
  auto m = comm::encode(v);
  header(m.header, client, seq, mrroc_lcm::header_t::REQUEST);
  return bytes_of(m);
}

template <class Plain>
std::string reply(const Plain& v, std::int64_t seq, std::int8_t kind = mrroc_lcm::header_t::REPLY) {
  auto m = comm::encode(v);
  header(m.header, "server", seq, kind, "client");
  return bytes_of(m);
}

void link_seeds(const std::string& target) {
  const auto ins = instructions();
  const auto cmds = mp_commands();
  enum {
    edp_cmd = 0,
    edp_reply = 1,
    ecp_cmd = 2,
    ecp_reply = 3,
    srp = 4,
    status = 5,
    vsp_cmd = 6,
    vsp_reply = 7
  };
  // A new request, its duplicate while in progress, answered, duplicate again (cached reply), the
  // next request, then a stale one.
  std::string edp = record(edp_cmd, 0, request(ins[1], "ecp/irb6#1", 1)) +
                    record(edp_cmd, 1, request(ins[1], "ecp/irb6#1", 1)) +
                    record(edp_cmd, 0, request(ins[1], "ecp/irb6#1", 1)) +
                    record(edp_cmd, 1, request(ins[2], "ecp/irb6#1", 2)) +
                    record(edp_cmd, 0, request(ins[0], "ecp/irb6#1", 1));
  write(target, "edp_exchange", edp);
  std::string ecp = record(ecp_cmd, 1, request(cmds[0], "mp#1", 1)) +
                    record(ecp_cmd, 1, request(cmds[1], "mp#1", 2)) +
                    record(ecp_cmd, 0, request(cmds[2], "mp#2", 1)) +
                    record(ecp_cmd, 1, request(cmds[2], "mp#2", 1));
  write(target, "ecp_exchange", ecp);
  const auto vreq = vsp_requests();
  const auto vrep = vsp_replies();
  write(target, "vsp_exchange",
        record(vsp_cmd, 1, request(vreq[0], "ecp/irb6#1", 1)) +
            record(vsp_cmd, 0, request(vreq[1], "ecp/irb6#1", 2)) +
            record(vsp_cmd, 1, request(vreq[1], "ecp/irb6#1", 2)) +
            record(vsp_cmd, 1, request(vreq[2], "ecp/irb6#1", 3)) +
            record(vsp_reply, 0, reply(vrep[1], 3)) + record(vsp_reply, 0, reply(vrep[3], 1)));
  // An instruction that decodes as LCM but fails validation (motion_type 7), a truncated one, and
  // bytes that are no message at all.
  auto invalid = comm::encode(ins[1]);
  header(invalid.header, "ecp/irb6#1", 3, mrroc_lcm::header_t::REQUEST);
  invalid.motion_type = 7;
  const std::string valid = request(ins[1], "ecp/irb6#1", 4);
  write(target, "malformed",
        record(edp_cmd, 1, bytes_of(invalid)) +
            record(edp_cmd, 1, valid.substr(0, valid.size() / 2)) +
            record(ecp_cmd, 1, std::string("\x01\x02\x03", 3)));
  const auto reps = edp_replies();
  const auto ecps = ecp_replies();
  write(target, "replies",
        record(edp_reply, 0, reply(reps[1], 1)) +
            record(edp_reply, 0, reply(edp::Reply{}, 2, mrroc_lcm::header_t::IN_PROGRESS)) +
            record(ecp_reply, 0, reply(ecps[0], -1)) + record(ecp_reply, 0, reply(ecps[3], 4)));
  mrroc_lcm::srp_message_t s{};
  header(s.header, "edp/irb6#99", 1, mrroc_lcm::header_t::BROADCAST);
  s.process = "edp/irb6";
  s.severity = 2;
  s.text = "emergency stop released";
  mrroc_lcm::process_status_t st{};
  header(st.header, "mp#5", 1, mrroc_lcm::header_t::BROADCAST);
  st.process = "mp";
  st.state = 2;
  write(target, "system", record(srp, 0, bytes_of(s)) + record(status, 0, bytes_of(st)));
}

// ---- Regression inputs (tests/fuzz/regressions/, docs/fuzzing.md "Findings"): real encodings
// with one length field set to what the bug needed, so that they follow changes of the types. ----

fs::path g_regressions;

void write_regression(const std::string& target, const std::string& name,
                      const std::string& bytes) {
  const fs::path dir = g_regressions / target;
  fs::create_directories(dir);
  std::ofstream out(dir / name, std::ios::binary | std::ios::trunc);
  out << bytes;
  if (!out) throw std::runtime_error("cannot write " + (dir / name).string());
}

/// `bytes` with the big-endian integer of `width` bytes at `offset` set to `value`.
std::string patched(std::string bytes, std::size_t offset, std::int64_t value, unsigned width) {
  if (offset + width > bytes.size()) throw std::runtime_error("patch beyond the message");
  const auto v = static_cast<std::uint64_t>(value);
  for (unsigned i = 0; i < width; ++i)
    bytes[offset + i] = static_cast<char>((v >> (8U * (width - 1 - i))) & 0xffU);
  return bytes;
}

constexpr std::size_t kHash = 8;  // the fingerprint in front of every message

/// Where the 4-byte length of an array is in `a`, given `b`, the same message with one more
/// element (the first byte that differs is the length's last byte).
std::size_t length_at(const std::string& a, const std::string& b) {
  std::size_t i = 0;
  while (i < a.size() && i < b.size() && a[i] == b[i]) ++i;
  if (i < 3 + kHash || i >= a.size()) throw std::runtime_error("no array length found");
  return i - 3;
}

/// Where, in an encoded message, its header's recipient length and auth_len are.
std::size_t recipient_length_at(const mrroc_lcm::header_t& h) {
  return kHash + 8 + 4 + h.sender.size() + 1;
}
std::size_t auth_len_at(const mrroc_lcm::header_t& h) {
  return recipient_length_at(h) + 4 + h.recipient.size() + 1 + 8 + 1 + 8;
}

void regression_inputs() {
  auto move = comm::encode(instructions()[1]);
  header(move.header, "ecp/irb6#4242", 2, mrroc_lcm::header_t::REQUEST);
  const std::string ins = bytes_of(move);
  auto longer = move;
  longer.arm.push_back(0.0);
  ++longer.n_arm;
  const std::size_t n_arm_at = length_at(ins, bytes_of(longer));
  write_regression("edp_instruction", "lcm-array-length-2p29-plus-1",
                   patched(ins, n_arm_at, (1 << 29) + 1, 4));
  write_regression("edp_instruction", "lcm-array-length-negative", patched(ins, n_arm_at, -1, 4));
  write_regression("edp_instruction", "lcm-string-length-0",
                   patched(ins, recipient_length_at(move.header), 0, 4));
  write_regression("edp_instruction", "lcm-auth-len-negative",
                   patched(ins, auth_len_at(move.header), -1, 2));
  write_regression("links", "edp-request-lcm-string-length-0",
                   record(0, 1, patched(ins, recipient_length_at(move.header), 0, 4)));

  auto gauges = comm::encode(raw_samples()[0]);
  header(gauges.header, "mrroc-axis-emu#77", 1, mrroc_lcm::header_t::BROADCAST);
  const std::string raw = bytes_of(gauges);
  auto more = gauges;
  more.values.push_back(0.0);
  more.names.emplace_back("g6");
  more.units.emplace_back("V");
  ++more.n;
  const std::size_t n_at = length_at(raw, bytes_of(more));
  write_regression("raw_sensor", "lcm-array-length-2p28", patched(raw, n_at, 1 << 28, 4));
  write_regression("raw_sensor", "lcm-array-length-negative", patched(raw, n_at, -1, 4));

  // Arrays of nested structs.
  const mrroc_lcm::launch_status_t status = launch_statuses()[0];
  auto status_more = status;
  status_more.processes.push_back(status.processes[0]);
  ++status_more.n;
  const std::size_t status_n_at = length_at(bytes_of(status), bytes_of(status_more));
  write_regression("launch_status", "lcm-struct-array-length-negative",
                   patched(bytes_of(status), status_n_at, -1, 4));
  write_regression("launch_status", "lcm-struct-array-length-2p30",
                   patched(bytes_of(status), status_n_at, 1 << 30, 4));
  const mrroc_lcm::srp_history_reply_t history = history_replies()[0];
  auto history_more = history;
  history_more.numbers.push_back(4);
  history_more.messages.push_back(history.messages[0]);
  ++history_more.n;
  const std::size_t history_n_at = length_at(bytes_of(history), bytes_of(history_more));
  write_regression("srp_history_reply", "lcm-struct-array-length-negative",
                   patched(bytes_of(history), history_n_at, -1, 4));
  write_regression("srp_history_reply", "lcm-struct-array-length-2p30",
                   patched(bytes_of(history), history_n_at, 1 << 30, 4));
}

// ---- Text inputs. ----

std::string read_file(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

void text_seeds(const fs::path& source) {
  for (const auto& f : fs::directory_iterator(source / "configs"))
    if (f.path().extension() == ".toml")
      write("process_set", f.path().filename().string(), read_file(f.path()));
  // A set with virtual sensors, as tests/unit/test_vsp.cpp writes it (no file of configs/ has one).
  write("process_set", "vsp.toml",
        "[system]\nname = \"t\"\n"
        "[[vsp]]\nname = \"wrist\"\nplugin = \"force_torque\"\nsources = [\"gauges\"]\n"
        "mode = \"periodic\"\nperiod_ms = 5\nstale_after_ms = 50\n[vsp.params]\nfilter_hz = 30\n"
        "[[vsp]]\nname = \"sonar\"\nplugin = \"range\"\nsources = [\"sonar\"]\n"
        "\n[mp]\ntask = \"start_and_wait\"\n[[robot]]\nname = \"irb6\"\n"
        "model = \"../robots/irb6\"\n[robot.edp]\nplugin = \"mock\"\n"
        "[robot.ecp]\ntask = \"follow_mp\"\n");
  for (const auto& robot : fs::directory_iterator(source / "robots"))
    if (fs::exists(robot.path() / "parameters.toml"))
      write("robot_model", robot.path().filename().string() + ".toml",
            read_file(robot.path() / "parameters.toml"));

  // NEXT_STATE arguments as the MP tasks and tests write them.
  write("params", "poses", "poses = [[0.6, -1.35, 0.15, 0.5, 1.0], [0, -1.5708, 0, 0, 0]]\n");
  write("params", "outputs", "outputs = 1\n");
  write("params", "poses_scale", "poses = [[0.5]]\nvelocity_scale = 0.8\n");
  write("params", "retry", "arguments = \"class = 'non_fatal'\\ntimes = 2\\n\"\nattempts = 3\n");
  write("params", "every_type",
        "flag = true\ncount = -3\nratio = 2.5e-3\nname = \"irb6\"\nnames = [\"a\", \"b\"]\n"
        "empty = []\nrow = [1, 2.5]\n");

  // Trajectory files: the format's examples and the writer's output in every representation.
  write("trajectory_file", "example",
        "# mrroc trajectory v1 representation=JOINT axes=5 robot=irb6\n"
        "# column lower_arm upper_arm wrist_pitch wrist_roll [rad]\n"
        "\n"
        "0 -1.5707963267948966 0 0 0\n"
        "  0.2\t-1.4 0.1 0 0.5 duration=2.5   # to the left\n"
        "0.2 -1.4 0.1 0 0.5 duration=1\n"
        "+1e-1 -1.5 -0.05 0.1 0 velocity_scale=0.5\r\n");
  ecp::TrajectoryFile joint;
  joint.representation = edp::ArmRepresentation::joint;
  joint.axes = 5;
  joint.robot = "irb6";
  joint.points = {{{0, -1.5707963267948966, 0, 0, 0}},
                  {{0.2, -1.4, 0.1, 0, 0.5}, 2.5, std::nullopt},
                  {{0.1, -1.5, -0.05, 0.1, 0}, std::nullopt, 0.5}};
  write("trajectory_file", "joint", joint.to_text());
  ecp::TrajectoryFile motor;
  motor.representation = edp::ArmRepresentation::motor;
  motor.axes = 2;
  motor.points = {{{12.5, -3e-4}}, {{1e+2, 0.25}, 1.0, std::nullopt}};
  write("trajectory_file", "motor", motor.to_text());
  ecp::TrajectoryFile frame;
  frame.representation = edp::ArmRepresentation::frame;
  frame.axes = 5;
  frame.robot = "irb6";
  frame.points = {{{1, 0, 0, 0.8, 0, 1, 0, 0, 0, 0, 1, 1.1}},
                  {{0, -1, 0, 0.7, 1, 0, 0, 0.1, 0, 0, 1, 1.0}, 2.0, std::nullopt}};
  write("trajectory_file", "frame", frame.to_text());
  ecp::TrajectoryFile euler;
  euler.representation = edp::ArmRepresentation::xyz_euler_zyz;
  euler.axes = 5;
  euler.points = {{{0.8, 0, 1.1, 0, 1.5, 0}}, {{0.7, 0.1, 1.0, 0.3, 1.4, -0.2}, std::nullopt, 1.0}};
  write("trajectory_file", "xyz_euler_zyz", euler.to_text());
  ecp::TrajectoryFile axis;
  axis.representation = edp::ArmRepresentation::xyz_angle_axis;
  axis.axes = 6;
  axis.robot = "rnt";
  axis.points = {{{0.8, 0, 1.1, 0, 1.5, 0}}};
  write("trajectory_file", "xyz_angle_axis", axis.to_text());
}

// --- CAN (fuzz_can.cpp): records of can_id (4, little endian), dlc, 8 data bytes, op -----------
std::string can_record(const can_frame& f, std::uint8_t op) {
  std::string r(14, '\0');
  const std::uint32_t id = f.can_id;
  std::memcpy(r.data(), &id, 4);
  r[4] = static_cast<char>(f.can_dlc);
  std::memcpy(r.data() + 5, f.data, 8);
  r[13] = static_cast<char>(op);
  return r;
}
can_frame raw_frame(std::uint32_t id, std::initializer_list<std::uint8_t> bytes) {
  can_frame f{};
  f.can_id = id;
  f.can_dlc = static_cast<std::uint8_t>(bytes.size());
  std::size_t i = 0;
  for (const std::uint8_t b : bytes) f.data[i++] = b;
  return f;
}

void can_seeds() {
  namespace co = mrroc::can::canopen;
  constexpr std::uint8_t kToDrive = 0x01;
  constexpr std::uint8_t kCycle = 0x10;
  constexpr std::uint8_t k2ms = 0x04;
  // The master's bring-up of drive 1 as the drive sees it: NMT start, SDO writes (mode 8, the
  // interpolation period), then shutdown -> switch on -> enable operation over RPDO1 with SYNCs.
  std::string bring_up = can_record(raw_frame(0x000, {0x01, 0x01}), kToDrive);
  bring_up += can_record(co::encode_request(1, {true, 0x6060, 0, 8, 1}), kToDrive);
  bring_up += can_record(co::encode_request(1, {true, 0x60C2, 1, 2, 1}), kToDrive);
  bring_up += can_record(co::encode_request(1, {false, 0x6041, 0, 0, 0}), kToDrive);
  for (const std::uint16_t cw : {co::controlword::kShutdown, co::controlword::kSwitchOn,
                                 co::controlword::kEnableOperation}) {
    bring_up += can_record(co::encode(1, co::Rpdo1{cw, 0}), kToDrive);
    bring_up += can_record(raw_frame(0x080, {}), kToDrive | kCycle | k2ms);
  }
  for (int k = 1; k <= 20; ++k) {
    bring_up +=
        can_record(co::encode(1, co::Rpdo1{co::controlword::kEnableOperation, 100 * k}), kToDrive);
    bring_up += can_record(raw_frame(0x080, {}), kToDrive | kCycle | k2ms);
  }
  // Digital outputs: the mask and lines by SDO, then lines by RPDO2 at a SYNC.
  bring_up += can_record(co::encode_request(1, {true, 0x60FE, 2, 0x00FF0000, 4}), kToDrive);
  bring_up += can_record(co::encode_request(1, {true, 0x60FE, 1, 0x00010000, 4}), kToDrive);
  bring_up += can_record(co::encode(1, co::Rpdo2{0x00A50000}), kToDrive);
  bring_up += can_record(raw_frame(0x080, {}), kToDrive | kCycle | k2ms);
  bring_up += can_record(co::encode(1, co::Rpdo1{co::controlword::kQuickStop, 0}), kToDrive);
  bring_up += can_record(raw_frame(0x080, {}), kToDrive | kCycle | k2ms);
  bring_up += can_record(co::encode(1, co::Rpdo1{co::controlword::kFaultReset, 0}), kToDrive);
  write("can", "drive_bring_up", bring_up);

  // What the master receives: boot-up and heartbeats, TPDOs of both drives, an EMCY, SDO
  // responses (a value, a confirmed write, an abort), cycles in between.
  std::string master = can_record(raw_frame(0x701, {0x00}), 0);
  master += can_record(raw_frame(0x702, {0x05}), 0);
  for (int k = 0; k < 10; ++k) {
    master += can_record(co::encode(1, co::Tpdo1{1000 + k, co::kHomeSwitchBit}), 0);
    master += can_record(co::encode(2, co::Tpdo1{-500 - k, 0}), kCycle | k2ms);
  }
  master += can_record(co::encode_emcy(2, {co::emcy::kFollowingError, 0x81, {}}), kCycle);
  master += can_record(co::encode_response(1, {0x6041, 0, false, 0, 0x0237, 2, false}), 0);
  master += can_record(co::encode_response(1, {0x6060, 0, false, 0, 0, 0, true}), 0);
  master += can_record(
      co::encode_response(2, {0x6060, 0, true, co::sdo_abort::kNoObject, 0, 0, false}), kCycle);
  master += can_record(co::encode(1, co::Tpdo2{0x0218}), kCycle | k2ms);  // fault
  write("can", "master_receives", master);

  // An error frame (bus-off) and a remote frame.
  write("can", "error_and_remote",
        can_record(raw_frame(CAN_ERR_BUSOFF, {0, 0, 0, 0, 0, 0, 0, 0}), 0x80 | kCycle) +
            can_record(raw_frame(0x181, {}), 0x40 | kCycle));
}

}  // namespace

int main(int argc, char** argv) {
  if (argc == 2 && (std::string(argv[1]) == "--help" || std::string(argv[1]) == "-h")) {
    std::printf(
        "usage: %s <mrroc source dir>\n"
        "Rewrites <dir>/tests/fuzz/corpus/ (the fuzz targets' seeds) and the message inputs "
        "of <dir>/tests/fuzz/regressions/. See docs/fuzzing.md.\n",
        argv[0]);
    return 0;
  }
  if (argc != 2) {
    std::fprintf(stderr, "usage: %s <mrroc source dir> (--help for more)\n", argv[0]);
    return 2;
  }
  const fs::path source = argv[1];
  g_corpus = source / "tests" / "fuzz" / "corpus";
  g_regressions = source / "tests" / "fuzz" / "regressions";
  message_seeds("edp_instruction", instructions(), mrroc_lcm::header_t::REQUEST);
  message_seeds("edp_reply", edp_replies(), mrroc_lcm::header_t::REPLY);
  message_seeds("mp_ecp_command", mp_commands(), mrroc_lcm::header_t::REQUEST);
  message_seeds("ecp_mp_reply", ecp_replies(), mrroc_lcm::header_t::REPLY);
  message_seeds("vsp_command", vsp_requests(), mrroc_lcm::header_t::REQUEST);
  message_seeds("vsp_reply", vsp_replies(), mrroc_lcm::header_t::REPLY);
  message_seeds("raw_sensor", raw_samples(), mrroc_lcm::header_t::BROADCAST);
  vsp_plugin_seeds();
  other_message_seeds();
  new_message_seeds();
  auth_seeds();
  link_seeds("links");
  // The same exchanges on a bus with a key: every payload signed, then replays of the last
  // signed request and reply.
  g_link_flags = 2;
  link_seeds("links_auth");
  write("links_auth", "replays",
        record(0, 1, request(instructions()[1], "ecp/irb6#1", 1)) + record(0, 4, "") +
            record(0, 0, request(instructions()[2], "ecp/irb6#1", 2)) + record(0, 4, "") +
            record(3, 0, reply(ecp_replies()[0], 1)) + record(3, 4, ""));
  g_link_flags = 0;
  can_seeds();
  regression_inputs();
  text_seeds(source);
  std::printf("seeds written to %s, message regressions to %s\n", g_corpus.string().c_str(),
              g_regressions.string().c_str());
  return 0;
}
