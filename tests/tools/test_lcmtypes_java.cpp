// The Java classes of mrroc-lcmtypes.jar (what lcm-spy uses) decode messages encoded by the C++
// code: one message of each type is written to a file, a Java program decodes each with the
// generated class and prints its fields, and the test compares them with what it encoded.
#include <fmt/format.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <string>
#include <vector>

#include "mrroc_lcm/ecp_mp_reply_t.hpp"
#include "mrroc_lcm/edp_instruction_t.hpp"
#include "mrroc_lcm/edp_reply_t.hpp"
#include "mrroc_lcm/emergency_stop_t.hpp"
#include "mrroc_lcm/header_t.hpp"
#include "mrroc_lcm/launch_process_t.hpp"
#include "mrroc_lcm/launch_status_t.hpp"
#include "mrroc_lcm/mp_ecp_command_t.hpp"
#include "mrroc_lcm/operator_command_t.hpp"
#include "mrroc_lcm/operator_reply_t.hpp"
#include "mrroc_lcm/process_status_t.hpp"
#include "mrroc_lcm/raw_sensor_t.hpp"
#include "mrroc_lcm/robot_state_t.hpp"
#include "mrroc_lcm/srp_history_reply_t.hpp"
#include "mrroc_lcm/srp_history_request_t.hpp"
#include "mrroc_lcm/srp_message_t.hpp"
#include "mrroc_lcm/vsp_command_t.hpp"
#include "mrroc_lcm/vsp_reply_t.hpp"

namespace fs = std::filesystem;

namespace {

class JavaTypes : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("mrroc-test-lcmtypes-" + std::to_string(getpid()));
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override {
    if (!HasFailure()) fs::remove_all(dir_);
  }

  /// Writes `msg` encoded to <dir>/<type>.bin and remembers its fingerprint.
  template <class Msg>
  void write(const Msg& msg) {
    const std::string type = Msg::getTypeName();
    std::vector<std::uint8_t> data(static_cast<std::size_t>(msg.getEncodedSize()));
    ASSERT_EQ(msg.encode(data.data(), 0, static_cast<int>(data.size())),
              static_cast<int>(data.size()));
    std::ofstream(dir_ / (type + ".bin"), std::ios::binary)
        .write(reinterpret_cast<const char*>(data.data()),
               static_cast<std::streamsize>(data.size()));
    fingerprints_[type] = fmt::format("{:x}", static_cast<std::uint64_t>(Msg::getHash()));
  }

  /// A header naming the type, so that a mix-up of files would show.
  static mrroc_lcm::header_t header(const std::string& type, std::int64_t seq) {
    mrroc_lcm::header_t h{};
    h.utime = 1'700'000'000'000'000 + seq;
    h.sender = type + "#7";
    h.recipient = "";
    h.seq = seq;
    h.kind = mrroc_lcm::header_t::BROADCAST;
    return h;
  }

  fs::path dir_;
  std::map<std::string, std::string> fingerprints_;
};

/// Runs the Java decoder; its output as "path" -> "value".
std::map<std::string, std::string> run_java(const fs::path& dir,
                                            const std::vector<std::string>& load,
                                            std::string& raw) {
  std::string cmd = fmt::format("'{}' -cp '{}' DecodeMessages '{}'", MRROC_JAVA,
                                MRROC_JAVA_CLASSPATH, dir.string());
  for (const auto& type : load) cmd += " " + type;
  cmd += " 2>&1";
  FILE* p = popen(cmd.c_str(), "r");
  char buf[4096];
  while (p != nullptr && std::fgets(buf, sizeof buf, p) != nullptr) raw += buf;
  const int status = p != nullptr ? pclose(p) : -1;
  EXPECT_EQ(status, 0) << cmd << "\n" << raw;
  std::map<std::string, std::string> fields;
  std::size_t at = 0;
  while (at < raw.size()) {
    const std::size_t end = raw.find('\n', at);
    const std::string line = raw.substr(at, end - at);
    at = end == std::string::npos ? raw.size() : end + 1;
    const std::size_t eq = line.find('=');
    if (eq != std::string::npos)
      fields[line.substr(0, eq)] = line.substr(eq + 1);
    else
      fields[line] = "";
  }
  return fields;
}

}  // namespace

TEST_F(JavaTypes, DecodeWhatCppEncodes) {
  using namespace mrroc_lcm;
  std::int64_t seq = 0;
  {
    header_t h = header("header_t", ++seq);
    h.auth_counter = 99;
    h.auth_len = 2;
    h.auth_tag = {1, 255};
    write(h);
  }
  {
    robot_state_t s{};
    s.header = header("robot_state_t", ++seq);
    s.robot = "irb6";
    s.synchronised = true;
    s.estop = true;
    s.error = "joint 2 (upper_arm) target 0.81 rad exceeds upper limit 0.70 rad";
    s.servo_step = 123456789012;
    s.servo_period_s = 0.002;
    s.n_joints = 5;
    s.q = {0.0, -1.5708, 0.25, 0.5, 1.0};
    s.dq = {0.1, 0.2, 0.3, 0.4, 0.5};
    s.q_desired = {-0.5, -1.8, -0.2, -0.6, -1.2};
    s.lateness_mean_us = 12.5;
    s.lateness_max_us = 85.25;
    s.overruns = 3;
    write(s);
  }
  {
    srp_message_t m{};
    m.header = header("srp_message_t", ++seq);
    m.utime = 42;
    m.process = "edp/irb6";
    m.robot = "irb6";
    m.severity = srp_message_t::ERROR;
    m.code = 6;
    m.text = "d\xc3\xa9j\xc3\xa0 vu\nsecond line";
    write(m);
    srp_history_reply_t r{};
    r.header = header("srp_history_reply_t", ++seq);
    r.last = 17;
    r.n = 2;
    r.numbers = {16, 17};
    r.messages = {m, m};
    r.messages[1].text = "the newest";
    r.messages[1].severity = srp_message_t::FATAL;
    write(r);
  }
  {
    srp_history_request_t r{};
    r.header = header("srp_history_request_t", ++seq);
    r.after = 10;
    r.max_count = 500;
    r.min_severity = 2;
    write(r);
  }
  {
    launch_process_t p{};
    p.name = "edp/irb6";
    p.group = "edp";
    p.host = "local";
    p.state = "running";
    p.pid = 1234;
    p.cpu_percent = 37.5;
    p.rss_kb = 20480;
    p.restarts = 1;
    p.uptime_s = 12.25;
    p.last_exit_code = -1;
    p.required = true;
    p.restart = "on-failure";
    write(p);
    launch_status_t s{};
    s.header = header("launch_status_t", ++seq);
    s.set_name = "demo-irb6";
    s.config_file = "/etc/mrroc/demo-irb6.toml";
    s.state = "running";
    s.launcher_pid = 1;
    s.uptime_s = 3.5;
    s.n = 2;
    s.processes = {p, p};
    s.processes[1].name = "ecp/irb6";
    write(s);
  }
  {
    process_status_t s{};
    s.header = header("process_status_t", ++seq);
    s.process = "mp";
    s.pid = 77;
    s.state = process_status_t::FAILED;
    s.uptime_us = 5'000'000;
    s.detail = "task failed";
    write(s);
    emergency_stop_t e{};
    e.header = header("emergency_stop_t", ++seq);
    e.action = emergency_stop_t::ENGAGE;
    e.robot = "irb6";
    e.reason = "operator";
    write(e);
    operator_command_t c{};
    c.header = header("operator_command_t", ++seq);
    c.command = operator_command_t::PAUSE;
    write(c);
    operator_reply_t o{};
    o.header = header("operator_reply_t", ++seq);
    o.accepted = true;
    o.state = operator_reply_t::PAUSED;
    o.task = "start_and_wait";
    o.runs = 2;
    o.started_utime = 1'700'000'000'500'000;
    write(o);
  }
  {
    edp_instruction_t i{};
    i.header = header("edp_instruction_t", ++seq);
    i.instruction = edp_instruction_t::SET;
    i.set_arm_type = edp_instruction_t::JOINT;
    i.motion_steps = 100;
    i.n_arm = 3;
    i.arm = {0.5, -1.25, 2.0};
    i.n_servo = 2;
    i.servo_algorithm = {1, -3};
    i.servo_parameters_no = {4, 5};
    write(i);
    edp_reply_t r{};
    r.header = header("edp_reply_t", ++seq);
    r.reply = edp_reply_t::DATA;
    r.n_joints = 2;
    r.joints = {0.125, 0.25};
    r.desired_joints = {0.5, 1.0};
    r.joint_velocities = {-0.5, -1.0};
    r.lateness_p99_us = 33.5;
    write(r);
    mp_ecp_command_t c{};
    c.header = header("mp_ecp_command_t", ++seq);
    c.state_name = "visit_joint_poses";
    c.arguments = "poses = [[0, 1]]";
    write(c);
    ecp_mp_reply_t e{};
    e.header = header("ecp_mp_reply_t", ++seq);
    e.error_code = 104;
    e.error_text = "no reply from EDP irb6";
    write(e);
  }
  {
    vsp_command_t c{};
    c.header = header("vsp_command_t", ++seq);
    c.arguments = "zero = true";
    write(c);
    vsp_reply_t r{};
    r.header = header("vsp_reply_t", ++seq);
    r.n = 1;
    r.values = {9.81};
    r.names = {"fz"};
    r.units = {"N"};
    write(r);
    raw_sensor_t s{};
    s.header = header("raw_sensor_t", ++seq);
    s.device = "sonar";
    s.sample_no = 8;
    s.n = 2;
    s.values = {1.5, 2.5};
    s.names = {"d0", "d1"};
    s.units = {"m", "m"};
    write(s);
  }

  // Every type of src/msg is in the jar, with the fingerprint the C++ code uses.
  std::vector<std::string> all_types;
  for (const auto& entry : fs::directory_iterator(fs::path(MRROC_SOURCE_DIR) / "src/msg"))
    if (entry.path().extension() == ".lcm") all_types.push_back(entry.path().stem().string());
  std::string raw;
  const auto f = run_java(dir_, all_types, raw);
  EXPECT_GE(all_types.size(), 18U);
  for (const auto& type : all_types) {
    const auto known = fingerprints_.find(type);
    if (known == fingerprints_.end()) {  // a type this test does not encode: it loads
      EXPECT_NE(raw.find("loaded " + type + " fingerprint "), std::string::npos) << type << "\n"
                                                                                 << raw;
      continue;
    }
    EXPECT_EQ(f.count("loaded " + type + " fingerprint " + known->second), 1U)
        << type << " (C++ fingerprint " << known->second << ")\n"
        << raw;
    EXPECT_EQ(f.count("decoded " + type), 1U) << type << "\n" << raw;
  }
  const std::map<std::string, std::string> expected{
      {"header_t.sender", "header_t#7"},
      {"header_t.auth_counter", "99"},
      {"header_t.auth_tag[1]", "-1"},
      {"robot_state_t.header.seq", "2"},
      {"robot_state_t.header.sender", "robot_state_t#7"},
      {"robot_state_t.robot", "irb6"},
      {"robot_state_t.synchronised", "true"},
      {"robot_state_t.moving", "false"},
      {"robot_state_t.estop", "true"},
      {"robot_state_t.error", "joint 2 (upper_arm) target 0.81 rad exceeds upper limit 0.70 rad"},
      {"robot_state_t.servo_step", "123456789012"},
      {"robot_state_t.servo_period_s", "0.002"},
      {"robot_state_t.n_joints", "5"},
      {"robot_state_t.q.length", "5"},
      {"robot_state_t.q[1]", "-1.5708"},
      {"robot_state_t.dq[4]", "0.5"},
      {"robot_state_t.q_desired[4]", "-1.2"},
      {"robot_state_t.lateness_mean_us", "12.5"},
      {"robot_state_t.lateness_max_us", "85.25"},
      {"robot_state_t.overruns", "3"},
      // lcm-gen's Java classes read a string byte by byte as Latin-1 characters: the UTF-8
      // bytes arrive intact, and the test program prints each of them as one character.
      {"srp_message_t.text", "d\xc3\x83\xc2\xa9j\xc3\x83\xc2\xa0 vu\\nsecond line"},
      {"srp_message_t.severity", "3"},
      {"srp_message_t.code", "6"},
      {"srp_history_reply_t.last", "17"},
      {"srp_history_reply_t.numbers[0]", "16"},
      {"srp_history_reply_t.messages.length", "2"},
      {"srp_history_reply_t.messages[0].process", "edp/irb6"},
      {"srp_history_reply_t.messages[1].text", "the newest"},
      {"srp_history_reply_t.messages[1].severity", "4"},
      {"srp_history_request_t.after", "10"},
      {"srp_history_request_t.max_count", "500"},
      {"srp_history_request_t.min_severity", "2"},
      {"launch_process_t.cpu_percent", "37.5"},
      {"launch_process_t.restart", "on-failure"},
      {"launch_process_t.last_exit_code", "-1"},
      {"launch_status_t.processes[0].pid", "1234"},
      {"launch_status_t.processes[1].name", "ecp/irb6"},
      {"launch_status_t.processes[1].required", "true"},
      {"launch_status_t.set_name", "demo-irb6"},
      {"process_status_t.state", "5"},
      {"process_status_t.detail", "task failed"},
      {"emergency_stop_t.action", "1"},
      {"emergency_stop_t.reason", "operator"},
      {"operator_command_t.command", "2"},
      {"operator_reply_t.task", "start_and_wait"},
      {"operator_reply_t.started_utime", "1700000000500000"},
      {"edp_instruction_t.arm[1]", "-1.25"},
      {"edp_instruction_t.servo_algorithm[1]", "-3"},
      {"edp_instruction_t.motion_steps", "100"},
      {"edp_reply_t.joint_velocities[1]", "-1.0"},
      {"edp_reply_t.lateness_p99_us", "33.5"},
      {"mp_ecp_command_t.arguments", "poses = [[0, 1]]"},
      {"ecp_mp_reply_t.error_code", "104"},
      {"vsp_command_t.arguments", "zero = true"},
      {"vsp_reply_t.values[0]", "9.81"},
      {"vsp_reply_t.units[0]", "N"},
      {"raw_sensor_t.names[1]", "d1"},
      {"raw_sensor_t.values[1]", "2.5"},
      {"raw_sensor_t.sample_no", "8"},
  };
  for (const auto& [path, value] : expected) {
    const auto it = f.find(path);
    ASSERT_NE(it, f.end()) << path << " not printed\n" << raw;
    EXPECT_EQ(it->second, value) << path;
  }
}

// lcm-spy finds the types through the class path mrroc-lcm-spy sets ($CLASSPATH), by fingerprint.
TEST_F(JavaTypes, LcmSpyFindsTheTypesThroughTheScriptsClassPath) {
  FILE* p = popen((std::string(MRROC_BIN_DIR) + "/mrroc-lcm-spy --classpath").c_str(), "r");
  ASSERT_NE(p, nullptr);
  char buf[4096] = {};
  std::string classpath = std::fgets(buf, sizeof buf, p) != nullptr ? buf : "";
  EXPECT_EQ(pclose(p), 0);
  if (!classpath.empty() && classpath.back() == '\n') classpath.pop_back();
  EXPECT_NE(classpath.find("mrroc-lcmtypes.jar"), std::string::npos) << classpath;
  EXPECT_NE(classpath.find("lcm.jar"), std::string::npos) << classpath;

  const std::map<std::string, std::string> types{
      {"mrroc_lcm.robot_state_t",
       fmt::format("{:x}", static_cast<std::uint64_t>(mrroc_lcm::robot_state_t::getHash()))},
      {"mrroc_lcm.srp_message_t",
       fmt::format("{:x}", static_cast<std::uint64_t>(mrroc_lcm::srp_message_t::getHash()))},
      {"mrroc_lcm.edp_instruction_t",
       fmt::format("{:x}", static_cast<std::uint64_t>(mrroc_lcm::edp_instruction_t::getHash()))},
      {"mrroc_lcm.launch_status_t",
       fmt::format("{:x}", static_cast<std::uint64_t>(mrroc_lcm::launch_status_t::getHash()))},
  };
  std::string cmd = fmt::format("env CLASSPATH='{}' '{}' -cp '{}' SpyFindsTypes", classpath,
                                MRROC_JAVA, MRROC_JAVA_SPY_CLASSPATH);
  for (const auto& [name, hash] : types) cmd += " " + hash;
  cmd += " 2>&1";
  std::string raw;
  p = popen(cmd.c_str(), "r");
  ASSERT_NE(p, nullptr);
  while (std::fgets(buf, sizeof buf, p) != nullptr) raw += buf;
  EXPECT_EQ(pclose(p), 0) << raw;
  for (const auto& [name, hash] : types)
    EXPECT_NE(raw.find("found " + hash + " " + name + "\n"), std::string::npos) << name << "\n"
                                                                                << raw;

  // Without the script's class path lcm-spy would not know them: the test can fail.
  std::string bare;
  p = popen(fmt::format("env -u CLASSPATH '{}' -cp '{}' SpyFindsTypes {} 2>&1", MRROC_JAVA,
                        MRROC_JAVA_SPY_CLASSPATH, types.begin()->second)
                .c_str(),
            "r");
  ASSERT_NE(p, nullptr);
  while (std::fgets(buf, sizeof buf, p) != nullptr) bare += buf;
  pclose(p);
  EXPECT_NE(bare.find("missing " + types.begin()->second), std::string::npos) << bare;
}

TEST(LcmSpyScript, HelpAndCheck) {
  FILE* p = popen((std::string(MRROC_BIN_DIR) + "/mrroc-lcm-spy --help 2>&1").c_str(), "r");
  ASSERT_NE(p, nullptr);
  std::string out;
  char buf[4096];
  while (std::fgets(buf, sizeof buf, p) != nullptr) out += buf;
  EXPECT_EQ(pclose(p), 0);
  EXPECT_NE(out.find("--lcm-url"), std::string::npos) << out;
  EXPECT_NE(out.find("CLASSPATH"), std::string::npos) << out;
  // --check names a missing jar.
  p = popen(("env MRROC_LCMTYPES_JAR=/nonexistent/types.jar " + std::string(MRROC_BIN_DIR) +
             "/mrroc-lcm-spy --check 2>&1")
                .c_str(),
            "r");
  ASSERT_NE(p, nullptr);
  out.clear();
  while (std::fgets(buf, sizeof buf, p) != nullptr) out += buf;
  EXPECT_NE(pclose(p), 0);
  EXPECT_NE(out.find("/nonexistent/types.jar"), std::string::npos) << out;
}

// lcm-spy itself, started by the script without a display: it finds every type of src/msg
// before it fails to open its window. Without jchart2d.jar the script refuses to start and
// names the package.
TEST(LcmSpyScript, SpyFindsEveryTypeBeforeItNeedsADisplay) {
  std::size_t n_types = 0;
  for (const auto& entry : fs::directory_iterator(fs::path(MRROC_SOURCE_DIR) / "src/msg"))
    if (entry.path().extension() == ".lcm") ++n_types;
  const bool have_jchart = fs::exists("/usr/share/java/jchart2d.jar");
  FILE* p = popen(("env -u DISPLAY " + std::string(MRROC_BIN_DIR) +
                   "/mrroc-lcm-spy --lcm-url 'udpm://239.255.76.67:7667?ttl=0' 2>&1")
                      .c_str(),
                  "r");
  ASSERT_NE(p, nullptr);
  std::string out;
  char buf[4096];
  while (std::fgets(buf, sizeof buf, p) != nullptr) out += buf;
  EXPECT_NE(pclose(p), 0) << "lcm-spy cannot run without a display\n" << out;
  if (have_jchart) {
    EXPECT_NE(out.find(fmt::format("Found {} LCM types", n_types)), std::string::npos) << out;
    EXPECT_NE(out.find("HeadlessException"), std::string::npos) << out;
  } else {
    EXPECT_NE(out.find("libjchart2d-java"), std::string::npos) << out;
  }
}
