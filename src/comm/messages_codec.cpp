/// @file
/// Codecs of the broadcast, operator and launcher messages (see comm/messages.hpp).
#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <iterator>

#include "mrroc/comm/messages.hpp"

namespace mrroc::comm {
namespace {

// The plain enumerations (include/mrroc/msg/) name the numbers of the .lcm constants: a change
// on one side that the other does not follow stops the build here.
template <class E>
constexpr bool same(E cpp, std::int8_t wire) {
  return static_cast<std::int8_t>(cpp) == wire;
}
using Stop = mrroc_lcm::emergency_stop_t;
static_assert(same(EstopAction::engage, Stop::ENGAGE) &&
              same(EstopAction::release, Stop::RELEASE) &&
              same(EstopAction::engaged, Stop::ENGAGED) &&
              same(EstopAction::released, Stop::RELEASED));
static_assert(kMaxEstopEngages == static_cast<std::size_t>(Stop::MAX_ENGAGES));
using Srp = mrroc_lcm::srp_message_t;
static_assert(same(Severity::debug, Srp::DEBUG) && same(Severity::info, Srp::INFO) &&
              same(Severity::warning, Srp::WARNING) && same(Severity::error, Srp::ERROR) &&
              same(Severity::fatal, Srp::FATAL));
using Status = mrroc_lcm::process_status_t;
static_assert(same(ProcessState::starting, Status::STARTING) &&
              same(ProcessState::ready, Status::READY) &&
              same(ProcessState::running, Status::RUNNING) &&
              same(ProcessState::stopping, Status::STOPPING) &&
              same(ProcessState::failed, Status::FAILED) &&
              same(ProcessState::finished, Status::FINISHED));
using OpCmd = mrroc_lcm::operator_command_t;
static_assert(same(mp::OperatorCommandType::start, OpCmd::START) &&
              same(mp::OperatorCommandType::pause, OpCmd::PAUSE) &&
              same(mp::OperatorCommandType::resume, OpCmd::RESUME) &&
              same(mp::OperatorCommandType::stop, OpCmd::STOP) &&
              same(mp::OperatorCommandType::terminate, OpCmd::TERMINATE) &&
              same(mp::OperatorCommandType::status, OpCmd::STATUS));
using OpRep = mrroc_lcm::operator_reply_t;
static_assert(same(mp::TaskState::idle, OpRep::IDLE) &&
              same(mp::TaskState::running, OpRep::RUNNING) &&
              same(mp::TaskState::paused, OpRep::PAUSED) &&
              same(mp::TaskState::stopping, OpRep::STOPPING) &&
              same(mp::TaskState::finished, OpRep::FINISHED) &&
              same(mp::TaskState::failed, OpRep::FAILED) &&
              same(mp::TaskState::terminating, OpRep::TERMINATING));
using LaunchCmd = mrroc_lcm::launch_command_t;
static_assert(same(launch::LaunchCommandType::restart, LaunchCmd::RESTART));
using SceneObj = mrroc_lcm::scene_object_t;
static_assert(same(SceneObjectShape::box, SceneObj::BOX) &&
              same(SceneObjectShape::sphere, SceneObj::SPHERE) &&
              same(SceneObjectShape::cylinder, SceneObj::CYLINDER) &&
              same(SceneObjectShape::capsule, SceneObj::CAPSULE));

/// `raw` as enumeration E when it is within lo..hi; else DecodeError naming message and field.
template <class E>
E checked(std::int8_t raw, std::int8_t lo, std::int8_t hi, const char* message, const char* field) {
  if (raw < lo || raw > hi)
    throw DecodeError(fmt::format("{}: field '{}' has value {}, expected {}..{}", message, field,
                                  static_cast<int>(raw), static_cast<int>(lo),
                                  static_cast<int>(hi)));
  return static_cast<E>(raw);
}

/// The length field `n` of `message` must be 0..limit.
void check_count(std::int32_t n, int limit, const char* message, const char* field) {
  if (n < 0 || n > limit)
    throw DecodeError(
        fmt::format("{}: field '{}' has value {}, expected 0..{}", message, field, n, limit));
}

template <class T>
void check_size(const std::vector<T>& v, std::int32_t n, const char* message, const char* field) {
  if (v.size() != static_cast<std::size_t>(n))
    throw DecodeError(fmt::format("{}: field '{}' has {} elements but its length field says {}",
                                  message, field, v.size(), n));
}

}  // namespace

mrroc_lcm::emergency_stop_t encode(const EmergencyStop& in) {
  if (in.engages.size() > kMaxEstopEngages)
    throw Error(fmt::format("emergency_stop_t: {} ENGAGEs named, at most {}", in.engages.size(),
                            kMaxEstopEngages));
  Stop m{};
  m.action = static_cast<std::int8_t>(in.action);
  m.robot = in.robot;
  m.reason = in.reason;
  m.command_id = in.command_id;
  m.by_sender = in.by.sender;
  m.by_id = in.by.id;
  m.n_engages = static_cast<std::int16_t>(in.engages.size());
  for (const EstopCommandRef& e : in.engages) {
    m.engage_senders.push_back(e.sender);
    m.engage_ids.push_back(e.id);
  }
  return m;
}

EmergencyStop decode(const mrroc_lcm::emergency_stop_t& m) {
  EmergencyStop out;
  out.action =
      checked<EstopAction>(m.action, Stop::ENGAGE, Stop::RELEASED, "emergency_stop_t", "action");
  out.robot = m.robot;
  out.reason = m.reason;
  out.command_id = m.command_id;
  out.by = EstopCommandRef{m.by_sender, m.by_id};
  // kMaxEstopEngages, not Stop::MAX_ENGAGES: the generated constant has no definition to bind
  // a reference to (fmt takes its arguments by reference; unoptimised builds fail to link).
  if (m.n_engages < 0 || static_cast<std::size_t>(m.n_engages) > kMaxEstopEngages)
    throw DecodeError(fmt::format("emergency_stop_t: field 'n_engages' is {}, not in 0..{}",
                                  m.n_engages, kMaxEstopEngages));
  check_size(m.engage_senders, m.n_engages, "emergency_stop_t", "engage_senders");
  check_size(m.engage_ids, m.n_engages, "emergency_stop_t", "engage_ids");
  for (std::size_t i = 0; i < m.engage_ids.size(); ++i)
    out.engages.push_back(EstopCommandRef{m.engage_senders[i], m.engage_ids[i]});
  return out;
}

mrroc_lcm::robot_state_t encode(const RobotState& in) {
  if (in.q.size() > static_cast<std::size_t>(kMaxVector))
    throw Error(
        fmt::format("robot_state_t: {} joints, at most {} can be sent", in.q.size(), kMaxVector));
  if (in.dq.size() != in.q.size() || in.q_desired.size() != in.q.size())
    throw Error(
        fmt::format("robot_state_t: q has {} values, dq {} and q_desired {}: one per "
                    "joint each",
                    in.q.size(), in.dq.size(), in.q_desired.size()));
  mrroc_lcm::robot_state_t m{};
  m.robot = in.robot;
  m.synchronised = in.synchronised;
  m.moving = in.moving;
  m.estop = in.estop;
  m.fault = in.fault;
  m.error = in.error;
  m.servo_step = in.servo_step;
  m.servo_period_s = in.servo_period_s;
  m.n_joints = static_cast<std::int32_t>(in.q.size());
  m.q = in.q;
  m.dq = in.dq;
  m.q_desired = in.q_desired;
  m.lateness_mean_us = in.lateness_mean_us;
  m.lateness_max_us = in.lateness_max_us;
  m.overruns = in.overruns;
  return m;
}

RobotState decode(const mrroc_lcm::robot_state_t& m) {
  constexpr const char* kType = "robot_state_t";
  check_count(m.n_joints, kMaxVector, kType, "n_joints");
  check_size(m.q, m.n_joints, kType, "q");
  check_size(m.dq, m.n_joints, kType, "dq");
  check_size(m.q_desired, m.n_joints, kType, "q_desired");
  RobotState out;
  out.robot = m.robot;
  out.synchronised = m.synchronised;
  out.moving = m.moving;
  out.estop = m.estop;
  out.fault = m.fault;
  out.error = m.error;
  out.servo_step = m.servo_step;
  out.servo_period_s = m.servo_period_s;
  out.q = m.q;
  out.dq = m.dq;
  out.q_desired = m.q_desired;
  out.lateness_mean_us = m.lateness_mean_us;
  out.lateness_max_us = m.lateness_max_us;
  out.overruns = m.overruns;
  return out;
}

mrroc_lcm::srp_message_t encode(const SrpMessage& in) {
  Srp m{};
  m.utime = in.utime;
  m.process = in.process;
  m.robot = in.robot;
  m.severity = static_cast<std::int8_t>(in.severity);
  m.code = in.code;
  m.text = in.text;
  return m;
}

SrpMessage decode(const mrroc_lcm::srp_message_t& m) {
  SrpMessage out;
  out.utime = m.utime;
  out.process = m.process;
  out.robot = m.robot;
  out.severity = checked<Severity>(m.severity, Srp::DEBUG, Srp::FATAL, "srp_message_t", "severity");
  out.code = m.code;
  out.text = m.text;
  return out;
}

mrroc_lcm::process_status_t encode(const ProcessStatus& in) {
  Status m{};
  m.process = in.process;
  m.robot = in.robot;
  m.pid = in.pid;
  m.state = static_cast<std::int8_t>(in.state);
  m.uptime_us = in.uptime_us;
  m.detail = in.detail;
  return m;
}

ProcessStatus decode(const mrroc_lcm::process_status_t& m) {
  ProcessStatus out;
  out.utime = m.header.utime;
  out.process = m.process;
  out.robot = m.robot;
  out.pid = m.pid;
  out.state = checked<ProcessState>(m.state, Status::STARTING, Status::FINISHED, "process_status_t",
                                    "state");
  out.uptime_us = m.uptime_us;
  out.detail = m.detail;
  return out;
}

mrroc_lcm::srp_history_request_t encode(const SrpHistoryRequest& in) {
  mrroc_lcm::srp_history_request_t m{};
  m.after = in.after;
  m.max_count = in.max_count;
  m.min_severity = static_cast<std::int8_t>(in.min_severity);
  return m;
}

SrpHistoryRequest decode(const mrroc_lcm::srp_history_request_t& m) {
  SrpHistoryRequest out;
  out.after = m.after;
  out.max_count = m.max_count;
  out.min_severity = checked<Severity>(m.min_severity, Srp::DEBUG, Srp::FATAL,
                                       "srp_history_request_t", "min_severity");
  return out;
}

mrroc_lcm::srp_history_reply_t encode(const SrpHistoryReply& in) {
  if (in.entries.size() > static_cast<std::size_t>(kMaxHistoryEntries))
    throw Error(fmt::format("srp_history_reply_t: {} entries, at most {} can be sent",
                            in.entries.size(), kMaxHistoryEntries));
  mrroc_lcm::srp_history_reply_t m{};
  m.last = in.last;
  m.n = static_cast<std::int32_t>(in.entries.size());
  for (const SrpHistoryEntry& e : in.entries) {
    m.numbers.push_back(e.number);
    Srp s = encode(e.message);
    // Each entry reads as the message the SRP received.
    s.header.utime = e.message.utime;
    s.header.sender = e.message.process;
    s.header.kind = mrroc_lcm::header_t::BROADCAST;
    m.messages.push_back(std::move(s));
  }
  return m;
}

SrpHistoryReply decode(const mrroc_lcm::srp_history_reply_t& m) {
  constexpr const char* kType = "srp_history_reply_t";
  check_count(m.n, kMaxHistoryEntries, kType, "n");
  check_size(m.numbers, m.n, kType, "numbers");
  check_size(m.messages, m.n, kType, "messages");
  SrpHistoryReply out;
  out.last = m.last;
  out.entries.reserve(m.messages.size());
  for (std::size_t i = 0; i < m.messages.size(); ++i) {
    SrpHistoryEntry e;
    e.number = m.numbers[i];
    try {
      e.message = decode(m.messages[i]);
    } catch (const DecodeError& error) {
      throw DecodeError(fmt::format("{}: entry {}: {}", kType, i, error.what()));
    }
    out.entries.push_back(std::move(e));
  }
  return out;
}

mrroc_lcm::operator_command_t encode(const mp::OperatorCommand& in) {
  OpCmd m{};
  m.command = static_cast<std::int8_t>(in.type);
  return m;
}

mp::OperatorCommand decode(const mrroc_lcm::operator_command_t& m) {
  if (m.command < OpCmd::START || m.command > OpCmd::STATUS)
    throw DecodeError(fmt::format(
        "operator_command_t: field 'command' has value {}, expected {}..{} (START, PAUSE, "
        "RESUME, STOP, TERMINATE, STATUS)",
        static_cast<int>(m.command), static_cast<int>(OpCmd::START),
        static_cast<int>(OpCmd::STATUS)));
  return {static_cast<mp::OperatorCommandType>(m.command)};
}

mrroc_lcm::operator_reply_t encode(const mp::OperatorReply& in) {
  OpRep m{};
  m.accepted = in.accepted;
  m.state = static_cast<std::int8_t>(in.state);
  m.task = in.task;
  m.runs = in.runs;
  m.started_utime = in.started_utime;
  m.text = in.text;
  return m;
}

mp::OperatorReply decode(const mrroc_lcm::operator_reply_t& m) {
  mp::OperatorReply out;
  out.accepted = m.accepted;
  out.state =
      checked<mp::TaskState>(m.state, OpRep::IDLE, OpRep::TERMINATING, "operator_reply_t", "state");
  out.task = m.task;
  out.runs = m.runs;
  out.started_utime = m.started_utime;
  out.text = m.text;
  return out;
}

mrroc_lcm::launch_status_t encode(const launch::LaunchStatus& in) {
  if (in.processes.size() > static_cast<std::size_t>(kMaxLaunchProcesses))
    throw Error(fmt::format("launch_status_t: {} processes, at most {} can be sent",
                            in.processes.size(), kMaxLaunchProcesses));
  mrroc_lcm::launch_status_t m{};
  m.set_name = in.set_name;
  m.config_file = in.config_file;
  m.state = in.state;
  m.launcher_pid = in.launcher_pid;
  m.uptime_s = in.uptime_s;
  for (const launch::ProcessRow& r : in.processes) {
    mrroc_lcm::launch_process_t p{};
    p.name = r.name;
    p.group = r.group;
    p.host = r.host;
    p.state = r.state;
    p.pid = r.pid;
    p.cpu_percent = r.cpu_percent;
    p.rss_kb = r.rss_kb;
    p.restarts = r.restarts;
    p.uptime_s = r.uptime_s;
    p.last_exit_code = r.last_exit_code;
    p.required = r.required;
    p.restart = r.restart;
    m.processes.push_back(std::move(p));
  }
  m.n = static_cast<std::int32_t>(m.processes.size());
  return m;
}

launch::LaunchStatus decode(const mrroc_lcm::launch_status_t& m) {
  check_count(m.n, kMaxLaunchProcesses, "launch_status_t", "n");
  check_size(m.processes, m.n, "launch_status_t", "processes");
  launch::LaunchStatus s;
  s.utime = m.header.utime;
  s.set_name = m.set_name;
  s.config_file = m.config_file;
  s.state = m.state;
  s.launcher_pid = m.launcher_pid;
  s.uptime_s = m.uptime_s;
  s.processes.reserve(m.processes.size());
  for (const auto& p : m.processes) {
    launch::ProcessRow r;
    r.name = p.name;
    r.group = p.group;
    r.host = p.host;
    r.state = p.state;
    r.pid = p.pid;
    r.cpu_percent = p.cpu_percent;
    r.rss_kb = p.rss_kb;
    r.restarts = p.restarts;
    r.uptime_s = p.uptime_s;
    r.last_exit_code = p.last_exit_code;
    r.required = p.required;
    r.restart = p.restart;
    s.processes.push_back(std::move(r));
  }
  return s;
}

mrroc_lcm::launch_command_t encode(const launch::LaunchCommand& in) {
  LaunchCmd m{};
  m.set_name = in.set_name;
  m.command = static_cast<std::int8_t>(in.type);
  m.process = in.process;
  return m;
}

launch::LaunchCommand decode(const mrroc_lcm::launch_command_t& m) {
  launch::LaunchCommand out;
  out.set_name = m.set_name;
  out.type = checked<launch::LaunchCommandType>(m.command, LaunchCmd::RESTART, LaunchCmd::RESTART,
                                                "launch_command_t", "command");
  out.process = m.process;
  return out;
}

mrroc_lcm::scene_objects_t encode(const SceneObjects& in) {
  if (in.objects.size() > static_cast<std::size_t>(kMaxSceneObjects))
    throw Error(fmt::format("scene_objects_t: {} objects, at most {} can be sent",
                            in.objects.size(), kMaxSceneObjects));
  mrroc_lcm::scene_objects_t m{};
  m.scene = in.scene;
  m.sim_time_s = in.sim_time_s;
  for (const SceneObjectPose& o : in.objects) {
    if (o.size.size() != scene_object_size_count(o.shape))
      throw Error(fmt::format("scene_objects_t: object '{}' has {} size values, its shape {}",
                              o.name, o.size.size(), scene_object_size_count(o.shape)));
    SceneObj e{};
    e.name = o.name;
    e.shape = static_cast<std::int8_t>(o.shape);
    e.n_size = static_cast<std::int32_t>(o.size.size());
    e.size = o.size;
    std::copy(o.rgba.begin(), o.rgba.end(), e.rgba);
    e.attach = o.attach;
    std::copy(o.local_position.begin(), o.local_position.end(), e.local_position);
    std::copy(o.local_quaternion.begin(), o.local_quaternion.end(), e.local_quaternion);
    std::copy(o.position.begin(), o.position.end(), e.position);
    std::copy(o.quaternion.begin(), o.quaternion.end(), e.quaternion);
    m.objects.push_back(std::move(e));
  }
  m.n = static_cast<std::int32_t>(m.objects.size());
  return m;
}

SceneObjects decode(const mrroc_lcm::scene_objects_t& m) {
  constexpr const char* kType = "scene_objects_t";
  check_count(m.n, kMaxSceneObjects, kType, "n");
  check_size(m.objects, m.n, kType, "objects");
  const auto finite = [&](const double* v, std::size_t n, const std::string& name,
                          const char* field) {
    for (std::size_t i = 0; i < n; ++i)
      if (!std::isfinite(v[i]))
        throw DecodeError(
            fmt::format("{}: object '{}': field '{}' has value {} at {}, expected "
                        "a finite number",
                        kType, name, field, v[i], i));
  };
  SceneObjects out;
  out.scene = m.scene;
  out.sim_time_s = m.sim_time_s;
  finite(&m.sim_time_s, 1, "", "sim_time_s");
  out.objects.reserve(m.objects.size());
  for (const SceneObj& e : m.objects) {
    SceneObjectPose o;
    o.name = e.name;
    o.shape = checked<SceneObjectShape>(e.shape, SceneObj::BOX, SceneObj::CAPSULE, kType, "shape");
    const auto expected = static_cast<std::int32_t>(scene_object_size_count(o.shape));
    if (e.n_size != expected)
      throw DecodeError(
          fmt::format("{}: object '{}': field 'n_size' has value {}, expected {} "
                      "for its shape",
                      kType, e.name, e.n_size, expected));
    check_size(e.size, e.n_size, kType, "size");
    finite(e.size.data(), e.size.size(), e.name, "size");
    for (const double v : e.size)
      if (!(v > 0.0))
        throw DecodeError(
            fmt::format("{}: object '{}': size {} m is not above 0", kType, e.name, v));
    finite(e.rgba, 4, e.name, "rgba");
    finite(e.local_position, 3, e.name, "local_position");
    finite(e.local_quaternion, 4, e.name, "local_quaternion");
    finite(e.position, 3, e.name, "position");
    finite(e.quaternion, 4, e.name, "quaternion");
    o.size = e.size;
    std::copy(std::begin(e.rgba), std::end(e.rgba), o.rgba.begin());
    o.attach = e.attach;
    std::copy(std::begin(e.local_position), std::end(e.local_position), o.local_position.begin());
    std::copy(std::begin(e.local_quaternion), std::end(e.local_quaternion),
              o.local_quaternion.begin());
    std::copy(std::begin(e.position), std::end(e.position), o.position.begin());
    std::copy(std::begin(e.quaternion), std::end(e.quaternion), o.quaternion.begin());
    out.objects.push_back(std::move(o));
  }
  return out;
}

}  // namespace mrroc::comm

namespace mrroc {
const char* to_string(EstopAction a) {
  switch (a) {
    case EstopAction::engage: return "ENGAGE";
    case EstopAction::release: return "RELEASE";
    case EstopAction::engaged: return "ENGAGED";
    case EstopAction::released: return "RELEASED";
  }
  return "?";
}
}  // namespace mrroc

namespace mrroc::mp {
const char* to_string(OperatorCommandType c) {
  switch (c) {
    case OperatorCommandType::start: return "START";
    case OperatorCommandType::pause: return "PAUSE";
    case OperatorCommandType::resume: return "RESUME";
    case OperatorCommandType::stop: return "STOP";
    case OperatorCommandType::terminate: return "TERMINATE";
    case OperatorCommandType::status: return "STATUS";
  }
  return "?";
}
const char* to_string(TaskState s) {
  switch (s) {
    case TaskState::idle: return "IDLE";
    case TaskState::running: return "RUNNING";
    case TaskState::paused: return "PAUSED";
    case TaskState::stopping: return "STOPPING";
    case TaskState::finished: return "FINISHED";
    case TaskState::failed: return "FAILED";
    case TaskState::terminating: return "TERMINATING";
  }
  return "?";
}
}  // namespace mrroc::mp
