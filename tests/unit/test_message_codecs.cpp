// Codecs of the broadcast, operator and launcher messages (comm/messages.hpp): plain values ->
// LCM type -> bytes -> LCM type -> plain values, and malformed messages rejected with the
// message, field and value named.
#include <gtest/gtest.h>

#include <limits>
#include <string>
#include <vector>

#include "mrroc/comm/messages.hpp"
#include "through_bytes.hpp"

using namespace mrroc;
using test::through_bytes;

namespace {

template <class Plain>
Plain round_trip(const Plain& in) {
  return comm::decode(through_bytes(comm::encode(in)));
}

/// decode(m) throws DecodeError whose text names every one of `words`.
template <class Msg>
void expect_rejected(const Msg& m, const std::vector<std::string>& words) {
  try {
    (void)comm::decode(m);
    ADD_FAILURE() << "accepted a message with a bad '" << words.front() << "'";
  } catch (const comm::DecodeError& e) {
    for (const std::string& w : words)
      EXPECT_NE(std::string(e.what()).find(w), std::string::npos) << e.what() << " lacks " << w;
  }
}

}  // namespace

TEST(MessageCodecs, EmergencyStopRoundTripAndRejection) {
  for (EstopAction a :
       {EstopAction::engage, EstopAction::release, EstopAction::engaged, EstopAction::released}) {
    EmergencyStop in{a, "irb6", "door opened", 1234567, {"ui#3", 77}, {{"ui#3", 76}, {"ui#9", 5}}};
    const EmergencyStop out = round_trip(in);
    EXPECT_EQ(out.action, a);
    EXPECT_EQ(out.robot, "irb6");
    EXPECT_EQ(out.reason, "door opened");
    EXPECT_EQ(out.command_id, 1234567);
    EXPECT_EQ(out.by, (EstopCommandRef{"ui#3", 77}));
    ASSERT_EQ(out.engages.size(), 2u);
    EXPECT_EQ(out.engages[1], (EstopCommandRef{"ui#9", 5}));
  }
  auto m = comm::encode(EmergencyStop{});
  m.action = 0;
  expect_rejected(m, {"emergency_stop_t", "action", "0", "1..4"});
  m.action = 5;
  expect_rejected(m, {"action", "5"});
  m.action = 3;
  m.n_engages = 17;
  expect_rejected(m, {"emergency_stop_t", "n_engages", "17", "0..16"});
  m.n_engages = 1;
  expect_rejected(m, {"engage_senders", "0 elements", "1"});
  EmergencyStop too_many;
  too_many.engages.resize(kMaxEstopEngages + 1);
  EXPECT_THROW((void)comm::encode(too_many), Error);
}

TEST(MessageCodecs, RobotStateRoundTripAndRejection) {
  RobotState in;
  in.robot = "irb6";
  in.synchronised = true;
  in.moving = true;
  in.estop = false;
  in.fault = true;
  in.error = "drive 3 fault";
  in.servo_step = 987654321;
  in.servo_period_s = 0.002;
  in.q = {0.1, -0.2, 0.3};
  in.dq = {1.0, 2.0, -3.0};
  in.q_desired = {0.11, -0.21, 0.31};
  in.lateness_mean_us = 12.5;
  in.lateness_max_us = 80.25;
  in.overruns = 7;
  const RobotState out = round_trip(in);
  EXPECT_EQ(out.robot, in.robot);
  EXPECT_TRUE(out.synchronised);
  EXPECT_TRUE(out.moving);
  EXPECT_FALSE(out.estop);
  EXPECT_TRUE(out.fault);
  EXPECT_EQ(out.error, in.error);
  EXPECT_EQ(out.servo_step, in.servo_step);
  EXPECT_EQ(out.servo_period_s, in.servo_period_s);
  EXPECT_EQ(out.q, in.q);
  EXPECT_EQ(out.dq, in.dq);
  EXPECT_EQ(out.q_desired, in.q_desired);
  EXPECT_EQ(out.lateness_mean_us, in.lateness_mean_us);
  EXPECT_EQ(out.lateness_max_us, in.lateness_max_us);
  EXPECT_EQ(out.overruns, in.overruns);

  const auto good = comm::encode(in);
  auto m = good;
  m.n_joints = comm::kMaxVector + 1;
  expect_rejected(m, {"robot_state_t", "n_joints", "17"});
  m = good;
  m.n_joints = -1;
  expect_rejected(m, {"n_joints", "-1"});
  m = good;
  m.dq.pop_back();  // the length field disagrees with the data
  expect_rejected(m, {"dq", "2 elements", "3"});

  RobotState uneven = in;
  uneven.q_desired.pop_back();
  EXPECT_THROW(comm::encode(uneven), Error);
  RobotState too_many = in;
  too_many.q.assign(comm::kMaxVector + 1, 0.0);
  too_many.dq = too_many.q;
  too_many.q_desired = too_many.q;
  EXPECT_THROW(comm::encode(too_many), Error);
}

TEST(MessageCodecs, SrpMessageAndProcessStatus) {
  const SrpMessage in{1700000000000000, "edp/irb6", "irb6", Severity::warning, 42, "hot"};
  const SrpMessage out = round_trip(in);
  EXPECT_EQ(out.utime, in.utime);
  EXPECT_EQ(out.process, in.process);
  EXPECT_EQ(out.robot, in.robot);
  EXPECT_EQ(out.severity, Severity::warning);
  EXPECT_EQ(out.code, 42);
  EXPECT_EQ(out.text, "hot");
  auto m = comm::encode(in);
  m.severity = 5;
  expect_rejected(m, {"srp_message_t", "severity", "5", "0..4"});
  m.severity = -1;
  expect_rejected(m, {"severity", "-1"});

  ProcessStatus status;
  status.process = "mp";
  status.robot = "";
  status.pid = 4321;
  status.state = ProcessState::finished;
  status.uptime_us = 5000000;
  status.detail = "done";
  auto sm = comm::encode(status);
  sm.header.utime = 1700000000123456;  // the time of sending, set by the sender's header
  const ProcessStatus back = comm::decode(through_bytes(sm));
  EXPECT_EQ(back.utime, 1700000000123456);
  EXPECT_EQ(back.process, "mp");
  EXPECT_EQ(back.pid, 4321);
  EXPECT_EQ(back.state, ProcessState::finished);
  EXPECT_EQ(back.uptime_us, 5000000);
  EXPECT_EQ(back.detail, "done");
  sm.state = 0;
  expect_rejected(sm, {"process_status_t", "state", "0", "1..6"});
  sm.state = 7;
  expect_rejected(sm, {"state", "7"});
}

TEST(MessageCodecs, SrpHistoryRequestAndReply) {
  const SrpHistoryRequest request{17, 250, Severity::error};
  const SrpHistoryRequest r = round_trip(request);
  EXPECT_EQ(r.after, 17);
  EXPECT_EQ(r.max_count, 250);
  EXPECT_EQ(r.min_severity, Severity::error);
  auto rm = comm::encode(request);
  rm.min_severity = 9;
  expect_rejected(rm, {"srp_history_request_t", "min_severity", "9"});

  SrpHistoryReply reply;
  reply.last = 30;
  reply.entries.push_back({29, SrpMessage{100, "ecp/irb6", "irb6", Severity::info, 0, "a"}});
  reply.entries.push_back({30, SrpMessage{200, "srp", "", Severity::fatal, 3, "b"}});
  const SrpHistoryReply back = round_trip(reply);
  EXPECT_EQ(back.last, 30);
  ASSERT_EQ(back.entries.size(), 2u);
  EXPECT_EQ(back.entries[0].number, 29);
  EXPECT_EQ(back.entries[0].message.process, "ecp/irb6");
  EXPECT_EQ(back.entries[1].number, 30);
  EXPECT_EQ(back.entries[1].message.severity, Severity::fatal);
  EXPECT_EQ(back.entries[1].message.code, 3);
  // Each entry reads as the message the SRP received (its time and process in the header).
  const auto wire = comm::encode(reply);
  EXPECT_EQ(wire.messages[1].header.utime, 200);
  EXPECT_EQ(wire.messages[1].header.sender, "srp");

  auto m = wire;
  m.messages[1].severity = 8;
  expect_rejected(m, {"srp_history_reply_t", "entry 1", "severity", "8"});
  m = wire;
  m.numbers.pop_back();
  expect_rejected(m, {"numbers", "1 elements", "2"});
  m = wire;
  m.n = comm::kMaxHistoryEntries + 1;
  expect_rejected(m, {"'n'", "501", "0..500"});

  SrpHistoryReply too_long;
  too_long.entries.resize(comm::kMaxHistoryEntries + 1);
  EXPECT_THROW(comm::encode(too_long), Error);
}

TEST(MessageCodecs, OperatorCommandAndReply) {
  for (int c = 1; c <= 6; ++c) {
    const auto type = static_cast<mp::OperatorCommandType>(c);
    EXPECT_EQ(round_trip(mp::OperatorCommand{type}).type, type);
  }
  auto cm = comm::encode(mp::OperatorCommand{});
  cm.command = 7;
  expect_rejected(cm, {"operator_command_t", "command", "7", "1..6", "TERMINATE"});
  EXPECT_STREQ(mp::to_string(mp::OperatorCommandType::terminate), "TERMINATE");

  mp::OperatorReply reply;
  reply.accepted = true;
  reply.state = mp::TaskState::paused;
  reply.task = "two_robots";
  reply.runs = 3;
  reply.started_utime = 1700000000000000;
  reply.text = "task paused";
  const mp::OperatorReply back = round_trip(reply);
  EXPECT_TRUE(back.accepted);
  EXPECT_EQ(back.state, mp::TaskState::paused);
  EXPECT_EQ(back.task, reply.task);
  EXPECT_EQ(back.runs, 3);
  EXPECT_EQ(back.started_utime, reply.started_utime);
  EXPECT_EQ(back.text, reply.text);
  EXPECT_STREQ(mp::to_string(back.state), "PAUSED");
  auto rm = comm::encode(reply);
  rm.state = 0;
  expect_rejected(rm, {"operator_reply_t", "state", "0", "1..7"});
  rm.state = 8;
  expect_rejected(rm, {"state", "8"});
}

TEST(MessageCodecs, LaunchStatusAndCommand) {
  launch::LaunchStatus status;
  status.set_name = "demo";
  status.config_file = "/etc/mrroc/demo.toml";
  status.state = "running";
  status.launcher_pid = 999;
  status.uptime_s = 12.5;
  launch::ProcessRow row;
  row.name = "edp/irb6";
  row.group = "edp";
  row.host = "cell-pc";
  row.state = "held";
  row.pid = 1234;
  row.cpu_percent = 37.5;
  row.rss_kb = 20480;
  row.restarts = 2;
  row.uptime_s = 3.25;
  row.last_exit_code = 1;
  row.required = false;
  row.restart = "on-failure";
  row.local_metrics = false;  // the launcher's own: not sent
  status.processes = {row, launch::ProcessRow{}};
  auto wire = comm::encode(status);
  wire.header.utime = 1700000000000001;
  const launch::LaunchStatus back = comm::decode(through_bytes(wire));
  EXPECT_EQ(back.utime, 1700000000000001);
  EXPECT_EQ(back.set_name, "demo");
  EXPECT_EQ(back.config_file, status.config_file);
  EXPECT_EQ(back.state, "running");
  EXPECT_EQ(back.launcher_pid, 999);
  EXPECT_EQ(back.uptime_s, 12.5);
  ASSERT_EQ(back.processes.size(), 2u);
  const launch::ProcessRow& r = back.processes[0];
  EXPECT_EQ(r.name, row.name);
  EXPECT_EQ(r.group, row.group);
  EXPECT_EQ(r.host, row.host);
  EXPECT_EQ(r.state, row.state);
  EXPECT_EQ(r.pid, row.pid);
  EXPECT_EQ(r.cpu_percent, row.cpu_percent);
  EXPECT_EQ(r.rss_kb, row.rss_kb);
  EXPECT_EQ(r.restarts, row.restarts);
  EXPECT_EQ(r.uptime_s, row.uptime_s);
  EXPECT_EQ(r.last_exit_code, row.last_exit_code);
  EXPECT_FALSE(r.required);
  EXPECT_EQ(r.restart, row.restart);
  EXPECT_TRUE(r.local_metrics);

  auto m = wire;
  m.n = -3;
  expect_rejected(m, {"launch_status_t", "'n'", "-3"});
  m = wire;
  m.processes.pop_back();
  expect_rejected(m, {"processes", "1 elements", "2"});
  launch::LaunchStatus huge;
  huge.processes.resize(comm::kMaxLaunchProcesses + 1);
  EXPECT_THROW(comm::encode(huge), Error);

  const launch::LaunchCommand command{"demo", launch::LaunchCommandType::restart, "edp/irb6"};
  const launch::LaunchCommand c = round_trip(command);
  EXPECT_EQ(c.set_name, "demo");
  EXPECT_EQ(c.type, launch::LaunchCommandType::restart);
  EXPECT_EQ(c.process, "edp/irb6");
  auto cm = comm::encode(command);
  cm.command = 2;
  expect_rejected(cm, {"launch_command_t", "command", "2", "1..1"});
}

TEST(MessageCodecs, SceneObjectsRoundTripAndRejection) {
  SceneObjects in;
  in.scene = "two-irb6";
  in.sim_time_s = 1.25;
  SceneObjectPose bar;
  bar.name = "bar";
  bar.shape = SceneObjectShape::box;
  bar.size = {0.25, 0.02, 0.02};
  bar.rgba = {0.2, 0.5, 0.8, 1.0};
  bar.position = {1.0, 0.0, 0.82};
  bar.quaternion = {0.5, 0.5, -0.5, 0.5};
  bar.local_position = {1.0, 0.0, 0.82};
  SceneObjectPose probe;
  probe.name = "probe";
  probe.shape = SceneObjectShape::sphere;
  probe.size = {0.02};
  probe.attach = "irb6/roll_link";
  probe.local_position = {0.34, 0.0, 0.0};
  probe.local_quaternion = {0.0, 1.0, 0.0, 0.0};
  in.objects = {bar, probe};
  const SceneObjects out = round_trip(in);
  EXPECT_EQ(out.scene, "two-irb6");
  EXPECT_EQ(out.sim_time_s, 1.25);
  ASSERT_EQ(out.objects.size(), 2U);
  EXPECT_EQ(out.objects[0].name, "bar");
  EXPECT_EQ(out.objects[0].shape, SceneObjectShape::box);
  EXPECT_EQ(out.objects[0].size, bar.size);
  EXPECT_EQ(out.objects[0].rgba, bar.rgba);
  EXPECT_EQ(out.objects[0].attach, "");
  EXPECT_EQ(out.objects[0].position, bar.position);
  EXPECT_EQ(out.objects[0].quaternion, bar.quaternion);
  EXPECT_EQ(out.objects[1].shape, SceneObjectShape::sphere);
  EXPECT_EQ(out.objects[1].size, probe.size);
  EXPECT_EQ(out.objects[1].attach, "irb6/roll_link");
  EXPECT_EQ(out.objects[1].local_position, probe.local_position);
  EXPECT_EQ(out.objects[1].local_quaternion, probe.local_quaternion);

  const auto wire = comm::encode(in);
  auto m = wire;
  m.n = 300;
  expect_rejected(m, {"scene_objects_t", "'n'", "300"});
  m = wire;
  m.objects[0].shape = 5;
  expect_rejected(m, {"scene_objects_t", "shape", "5", "1..4"});
  m = wire;
  m.objects[0].n_size = 2;
  m.objects[0].size.pop_back();
  expect_rejected(m, {"object 'bar'", "n_size", "2", "expected 3"});
  m = wire;
  m.objects[1].size[0] = -0.02;
  expect_rejected(m, {"object 'probe'", "-0.02", "not above 0"});
  m = wire;
  m.objects[0].position[2] = std::numeric_limits<double>::quiet_NaN();
  expect_rejected(m, {"object 'bar'", "position", "nan"});
  SceneObjects wrong = in;
  wrong.objects[1].size = {0.02, 0.1};  // a sphere has a radius only
  EXPECT_THROW(comm::encode(wrong), Error);
  SceneObjects huge;
  huge.objects.resize(comm::kMaxSceneObjects + 1, bar);
  EXPECT_THROW(comm::encode(huge), Error);
}
