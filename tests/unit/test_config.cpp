// The process-set config: the demo loads; every kind of mistake gets "file:line: error: ...".
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <regex>

#include "mrroc/config/check.hpp"
#include "mrroc/config/process_set.hpp"
#include "mrroc/core/error.hpp"
#include "mrroc/core/nearest_name.hpp"
#include "mrroc/edp/arm_kinematics.hpp"
#include "mrroc/robot/robot_model.hpp"

using namespace mrroc;
namespace fs = std::filesystem;

namespace {

class ConfigTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("mrroc-config-test-" + std::to_string(::getpid()));
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }

  fs::path write(const std::string& text) {
    const fs::path p = dir_ / "set.toml";
    std::ofstream(p) << text;
    return p;
  }

  /// Loads `text` and returns the error message (fails the test if it loads).
  std::string error_of(const std::string& text) {
    const fs::path p = write(text);
    try {
      load_process_set(p);
    } catch (const ConfigError& e) {
      return e.what();
    }
    ADD_FAILURE() << "config loaded although it is wrong:\n" << text;
    return {};
  }

  std::string valid(const std::string& extra_robot_edp = "", const std::string& extra_system = "") {
    return "[system]\nname = \"t\"\n" + extra_system + "\n[mp]\ntask = \"start_and_wait\"\n\n" +
           "[[robot]]\nname = \"irb6\"\nmodel = \"" + std::string(MRROC_SOURCE_DIR) +
           "/robots/irb6\"\n[robot.edp]\nplugin = \"mujoco\"\n" + extra_robot_edp +
           "\n[robot.ecp]\ntask = \"visit_joint_poses\"\n";
  }

  fs::path dir_;
};

/// 1-based line of the first occurrence of `needle` in `text` (the n-th with `nth`).
int line_of(const std::string& text, const std::string& needle, int nth = 1) {
  std::size_t at = std::string::npos;
  for (int i = 0; i < nth; ++i) at = text.find(needle, at == std::string::npos ? 0 : at + 1);
  return 1 + static_cast<int>(std::count(text.begin(), text.begin() + static_cast<long>(at), '\n'));
}

void expect_located(const std::string& message, const fs::path& file, int line,
                    const std::string& words) {
  const std::string prefix = file.string() + ":" + std::to_string(line) + ": error: ";
  EXPECT_EQ(message.rfind(prefix, 0), 0U) << "expected prefix '" << prefix << "' in: " << message;
  EXPECT_NE(message.find(words), std::string::npos) << message;
}

}  // namespace

TEST_F(ConfigTest, DemoConfigLoads) {
  const ProcessSetConfig c =
      load_process_set(fs::path(MRROC_SOURCE_DIR) / "configs/demo-irb6.toml");
  EXPECT_EQ(c.name, "demo-irb6");
  ASSERT_EQ(c.robots.size(), 1U);
  EXPECT_EQ(c.robots[0].name, "irb6");
  EXPECT_EQ(c.robots[0].edp.plugin, "mujoco");
  EXPECT_DOUBLE_EQ(c.robots[0].edp.servo_period_s, 0.002);
  EXPECT_TRUE(fs::is_directory(c.robots[0].model_dir));
  EXPECT_EQ(c.robots[0].ecp.name, "visit_joint_poses");
  EXPECT_EQ(c.robots[0].ecp.args.get_double_rows("poses").size(), 3U);
  EXPECT_EQ(c.mp.name, "start_and_wait");
  EXPECT_EQ(&c.robot("irb6"), &c.robots[0]);
  EXPECT_THROW((void)c.robot("nope"), ConfigError);
}

TEST_F(ConfigTest, UnknownKeyIsAnErrorWithItsLine) {
  const std::string text = valid("pluginn = \"mujoco\"\n");
  expect_located(error_of(text), dir_ / "set.toml", line_of(text, "pluginn"),
                 "unknown key 'pluginn' in [robot.edp]");
}

TEST_F(ConfigTest, UnknownTopLevelTable) {
  const std::string text = valid() + "\n[mpp]\ntask = \"x\"\n";
  expect_located(error_of(text), dir_ / "set.toml", line_of(text, "[mpp]"), "unknown key 'mpp'");
}

TEST_F(ConfigTest, SyntaxErrorHasLine) {
  expect_located(error_of("[system]\nname = \"t\n"), dir_ / "set.toml", 2, "");
}

TEST_F(ConfigTest, MissingFileIsNamed) {
  try {
    load_process_set(dir_ / "absent.toml");
    FAIL();
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("absent.toml: error: config file not found"),
              std::string::npos)
        << e.what();
  }
}

TEST_F(ConfigTest, MissingModelFolderIsNamed) {
  std::string text = valid();
  text.replace(text.find("/robots/irb6"), 12, "/robots/irb7");
  expect_located(error_of(text), dir_ / "set.toml", line_of(text, "model ="),
                 "robots/irb7' not found");
}

TEST_F(ConfigTest, WrongTypeAndRangeNameValueAndUnit) {
  const std::string text = valid("servo_period_ms = \"2\"\n");
  expect_located(error_of(text), dir_ / "set.toml", line_of(text, "servo_period_ms"),
                 "'servo_period_ms' must be a number [ms]");
  const std::string text2 = valid("servo_period_ms = 500\n");
  expect_located(error_of(text2), dir_ / "set.toml", line_of(text2, "servo_period_ms"),
                 "'servo_period_ms' = 500 ms is outside 0.1..100 ms");
}

TEST_F(ConfigTest, LockStepIsABooleanAndOffByDefault) {
  EXPECT_FALSE(load_process_set(write(valid())).robots[0].edp.lock_step);
  EXPECT_TRUE(load_process_set(write(valid("lock_step = true\n"))).robots[0].edp.lock_step);
  const std::string text = valid("lock_step = \"yes\"\n");
  expect_located(error_of(text), dir_ / "set.toml", line_of(text, "lock_step"),
                 "'lock_step' must be true or false");
}

TEST_F(ConfigTest, UnsynchronisedLimitsHaveDefaultsAndRangesNamedAtTheirLine) {
  const EdpConfig defaults;
  const ProcessSetConfig plain = load_process_set(write(valid()));
  EXPECT_EQ(plain.robots[0].edp.unsynchronised_velocity_fraction, 0.1);
  EXPECT_EQ(plain.robots[0].edp.unsynchronised_acceleration_fraction, 0.1);
  EXPECT_EQ(plain.robots[0].edp.unsynchronised_max_move, 0.1);
  EXPECT_EQ(plain.robots[0].edp.unsynchronised_max_move, defaults.unsynchronised_max_move);
  const ProcessSetConfig given =
      load_process_set(write(valid("unsynchronised_velocity_fraction = 0.2\n"
                                   "unsynchronised_acceleration_fraction = 1\n"
                                   "unsynchronised_max_move = 0.05\n")));
  EXPECT_DOUBLE_EQ(given.robots[0].edp.unsynchronised_velocity_fraction, 0.2);
  EXPECT_DOUBLE_EQ(given.robots[0].edp.unsynchronised_acceleration_fraction, 1.0);
  EXPECT_DOUBLE_EQ(given.robots[0].edp.unsynchronised_max_move, 0.05);

  const std::string fast = valid("unsynchronised_velocity_fraction = 1.5\n");
  expect_located(error_of(fast), dir_ / "set.toml", line_of(fast, "unsynchronised_velocity"),
                 "'unsynchronised_velocity_fraction' = 1.5 is outside 0.01..1 (a fraction of "
                 "every joint's max_joint_velocity, kept to before SYNCHRO)");
  const std::string zero = valid("unsynchronised_acceleration_fraction = 0\n");
  expect_located(error_of(zero), dir_ / "set.toml", line_of(zero, "unsynchronised_acceleration"),
                 "'unsynchronised_acceleration_fraction' = 0 is outside 0.01..1");
  const std::string text = valid("unsynchronised_acceleration_fraction = \"low\"\n");
  expect_located(error_of(text), dir_ / "set.toml", line_of(text, "unsynchronised_acceleration"),
                 "'unsynchronised_acceleration_fraction' must be a number: a fraction of every "
                 "joint's max_joint_acceleration");
  const std::string far = valid("unsynchronised_max_move = 2\n");
  expect_located(error_of(far), dir_ / "set.toml", line_of(far, "unsynchronised_max_move"),
                 "'unsynchronised_max_move' = 2 rad (or m) is outside 0.001..1 rad (or m)");
}

TEST_F(ConfigTest, DuplicateRobotAndBadName) {
  std::string text = valid();
  const std::string robot = text.substr(text.find("[[robot]]"));
  const std::string twice = text + "\n" + robot;
  expect_located(error_of(twice), dir_ / "set.toml", line_of(twice, "name = \"irb6\"", 2),
                 "used twice");
  std::string bad = valid();
  bad.replace(bad.find("name = \"irb6\""), 13, "name = \"IRB 6\"");
  EXPECT_NE(error_of(bad).find("must match"), std::string::npos);
}

TEST_F(ConfigTest, MissingRequiredKeysAndTables) {
  EXPECT_NE(error_of("[system]\nname = \"t\"\n").find("missing table [mp]"), std::string::npos);
  std::string no_plugin = valid();
  no_plugin.replace(no_plugin.find("plugin = \"mujoco\"\n"), 18, "");
  EXPECT_NE(error_of(no_plugin).find("missing key 'plugin' in [robot.edp]"), std::string::npos);
  EXPECT_NE(error_of("[system]\nname = \"t\"\n[mp]\ntask = \"x\"\n").find("no [[robot]]"),
            std::string::npos);
}

TEST_F(ConfigTest, BadLcmUrl) {
  const std::string text = valid("", "lcm_url = \"239.255.76.67:7667\"\n");
  expect_located(error_of(text), dir_ / "set.toml", line_of(text, "lcm_url"), "is not a URL");
}

TEST_F(ConfigTest, ParamsReportUnreadAndWrongTypes) {
  const std::string text = valid() + "[robot.ecp.args]\nposes = [[0.0, 1.0]]\nspeed = 2\n";
  const fs::path p = write(text);
  const std::string speed_at = "set.toml:" + std::to_string(line_of(text, "speed"));
  const std::string poses_at = "set.toml:" + std::to_string(line_of(text, "poses ="));
  const ProcessSetConfig c = load_process_set(p);
  const Params& args = c.robots[0].ecp.args;
  EXPECT_EQ(args.get_double_rows("poses").size(), 1U);
  try {
    args.reject_unread("robot.ecp.args");
    FAIL();
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find(speed_at + ": error: unknown key 'speed'"),
              std::string::npos)
        << e.what();
  }
  try {
    (void)args.get_string("poses");
    FAIL();
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find(poses_at + ": error: 'poses' must be a string"),
              std::string::npos)
        << e.what();
  }
  EXPECT_DOUBLE_EQ(args.get_double("speed"), 2.0);
  EXPECT_THROW((void)args.get_double("absent"), ConfigError);
  EXPECT_DOUBLE_EQ(args.get_double("absent", 1.5), 1.5);
}

TEST_F(ConfigTest, PriorityIsZeroUnlessATableSetsIt) {
  const ProcessSetConfig c = load_process_set(write(valid()));
  EXPECT_EQ(c.robots[0].edp.options.priority, 0);
  EXPECT_EQ(c.robots[0].ecp.options.priority, 0);
  EXPECT_EQ(c.mp.options.priority, 0);
  EXPECT_EQ(c.srp.options.priority, 0);
  EXPECT_EQ(c.ui.options.priority, 0);
  const ProcessSetConfig set = load_process_set(write(valid("priority = 79\n")));
  EXPECT_EQ(set.robots[0].edp.options.priority, 79);
  EXPECT_EQ(set.robots[0].ecp.options.priority, 0);
}

TEST_F(ConfigTest, PriorityOutsideItsRangeNamesValueAndLimit) {
  const std::string text = valid("priority = 80\n");
  expect_located(error_of(text), dir_ / "set.toml", line_of(text, "priority"),
                 "'priority' = 80 is outside 0..79");
  const std::string text2 = valid("priority = -1\n");
  expect_located(error_of(text2), dir_ / "set.toml", line_of(text2, "priority"),
                 "'priority' = -1 is outside 0..79");
  const std::string text3 = valid("priority = 1.5\n");
  expect_located(error_of(text3), dir_ / "set.toml", line_of(text3, "priority"),
                 "'priority' must be an integer");
}

TEST(ConfigError, WhatReadsFileLineErrorMessage) {
  const ConfigError at_line(SourceLocation{"cell/set.toml", 12}, "'port' = 0 is outside 1..65535");
  EXPECT_STREQ(at_line.what(), "cell/set.toml:12: error: 'port' = 0 is outside 1..65535");
  EXPECT_EQ(at_line.where().file, "cell/set.toml");
  EXPECT_EQ(at_line.where().line, 12);
  EXPECT_EQ(at_line.message(), "'port' = 0 is outside 1..65535");
  EXPECT_TRUE(at_line.located());

  const ConfigError whole(SourceLocation::whole_file("robots/x/model.urdf"), "does not parse");
  EXPECT_STREQ(whole.what(), "robots/x/model.urdf: error: does not parse");
  EXPECT_TRUE(whole.located());

  const ConfigError line_zero(SourceLocation{"missing.toml", 0}, "cannot read");
  EXPECT_STREQ(line_zero.what(), "missing.toml:0: error: cannot read");

  const ConfigError unlocated("unknown task 'x' (known: none)");
  EXPECT_STREQ(unlocated.what(), "unknown task 'x' (known: none)");
  EXPECT_FALSE(unlocated.located());
}

TEST(ConfigError, AtLocatesOnlyAnErrorWithoutFile) {
  const SourceLocation table{"set.toml", 30};
  const ConfigError bare("unknown task 'x' (known: none)");
  const ConfigError placed = bare.at(table);
  EXPECT_STREQ(placed.what(), "set.toml:30: error: unknown task 'x' (known: none)");
  EXPECT_EQ(placed.where().line, 30);
  EXPECT_EQ(placed.message(), bare.message());

  // An error that names its file keeps it: the key's own line is more precise than the table's.
  const ConfigError precise(SourceLocation{"set.toml", 33}, "'speed' must be a number");
  EXPECT_STREQ(precise.at(table).what(), "set.toml:33: error: 'speed' must be a number");
  EXPECT_EQ(precise.at(table).where().line, 33);
}

TEST(ConfigError, ParamsErrorKeepsItsLocationThroughTheRethrow) {
  const Params args = params_from_toml("speed = 0.1\nlabel = 3\n", "command");
  const SourceLocation table{"set.toml", 40};
  try {
    try {
      (void)args.get_string("label");
      FAIL() << "an integer read as a string";
    } catch (const ConfigError& e) {
      throw e.at(table);
    }
  } catch (const ConfigError& e) {
    EXPECT_STREQ(e.what(), "command:2: error: 'label' must be a string, not 3");
    EXPECT_EQ(e.where().file, "command");
    EXPECT_EQ(e.where().line, 2);
  }
}

TEST(ConfigError, UnknownKinematicsIsLocatedAtTheModelsParameterFile) {
  RobotModel model;
  model.name = "r";
  model.folder = "/nowhere/robots/r";
  model.kinematics = "no_such_solver";
  try {
    (void)edp::make_arm_kinematics(model);
    FAIL() << "an unknown kinematics solver was accepted";
  } catch (const ConfigError& e) {
    EXPECT_EQ(e.where().file, "/nowhere/robots/r/parameters.toml");
    EXPECT_EQ(std::string(e.what()).rfind("/nowhere/robots/r/parameters.toml: error: ", 0), 0U)
        << e.what();
    EXPECT_NE(e.message().find("no_such_solver"), std::string::npos) << e.what();
  }
}

TEST_F(ConfigTest, KeysLeftOutTakeTheStructsDefaults) {
  const std::string text =
      valid() +
      "\n[srp]\n\n[ui]\nweb = true\n\n[launch]\n[[launch.host]]\nname = \"cell\"\n\n"
      "[[vsp]]\nname = \"wrist\"\nplugin = \"force_torque\"\nsources = [\"gauge\"]\n";
  const ProcessSetConfig c = load_process_set(write(text));

  const ProcessSetConfig set_defaults;
  EXPECT_EQ(c.ready_timeout_s, set_defaults.ready_timeout_s);
  EXPECT_EQ(c.mp_waits_for_operator, set_defaults.mp_waits_for_operator);

  const SrpConfig srp;
  EXPECT_EQ(c.srp.log_max_kb, srp.log_max_kb);
  EXPECT_EQ(c.srp.log_keep, srp.log_keep);
  EXPECT_EQ(c.srp.history, srp.history);

  const UiConfig ui;
  EXPECT_EQ(c.ui.bind, ui.bind);
  EXPECT_EQ(c.ui.port, ui.port);
  EXPECT_TRUE(c.ui.web);

  const LaunchConfig launch;
  EXPECT_EQ(c.launch.log_max_kb, launch.log_max_kb);
  EXPECT_EQ(c.launch.log_keep, launch.log_keep);
  ASSERT_EQ(c.launch.hosts.size(), 1U);
  const HostConfig host;
  EXPECT_EQ(c.launch.hosts[0].command, host.command);
  EXPECT_EQ(c.launch.hosts[0].quote, host.quote);
  EXPECT_EQ(c.launch.hosts[0].address, "cell");  // the name, when no address is given

  const EdpConfig edp;
  EXPECT_EQ(c.robots[0].edp.servo_period_s, edp.servo_period_s);
  EXPECT_EQ(c.robots[0].edp.servo_period_s, kDefaultServoPeriodS);
  EXPECT_EQ(c.robots[0].edp.lookahead, edp.lookahead);
  EXPECT_EQ(c.robots[0].edp.lock_step, edp.lock_step);

  ASSERT_EQ(c.vsps.size(), 1U);
  const VspConfig vsp;
  EXPECT_EQ(c.vsps[0].period_s, vsp.period_s);
  EXPECT_EQ(c.vsps[0].stale_after_s, vsp.stale_after_s);
  EXPECT_EQ(c.vsps[0].periodic, vsp.periodic);

  const ProcessOptions options;
  for (const ProcessOptions* o : {&c.srp.options, &c.ui.options, &c.mp.options,
                                  &c.robots[0].edp.options, &c.vsps[0].options}) {
    EXPECT_EQ(o->stop_grace_s, options.stop_grace_s);
    EXPECT_EQ(o->stop_signal, options.stop_signal);
    EXPECT_EQ(o->host, options.host);
    EXPECT_EQ(o->restart, options.restart);
    EXPECT_EQ(o->max_restarts, options.max_restarts);
    EXPECT_EQ(o->restart_backoff_s, options.restart_backoff_s);
    EXPECT_EQ(o->required, options.required);
  }
  EXPECT_EQ(c.srp.options.group, "srp");
  EXPECT_EQ(c.robots[0].edp.options.group, "edp");
}

TEST_F(ConfigTest, KeysGivenOverrideTheDefaults) {
  const std::string text =
      valid("servo_period_ms = 1\nlookahead = 3\nmax_restarts = 5\nrestart_backoff_s = 1.5\n") +
      "\n[launch]\n[[launch.host]]\nname = \"ns\"\ncommand = [\"ip\", \"netns\", \"exec\", "
      "\"{host}\"]\n";
  const ProcessSetConfig c = load_process_set(write(text));
  EXPECT_DOUBLE_EQ(c.robots[0].edp.servo_period_s, 0.001);
  EXPECT_EQ(c.robots[0].edp.lookahead, 3);
  EXPECT_EQ(c.robots[0].edp.options.max_restarts, 5);
  EXPECT_DOUBLE_EQ(c.robots[0].edp.options.restart_backoff_s, 1.5);
  ASSERT_EQ(c.launch.hosts.size(), 1U);
  EXPECT_EQ(c.launch.hosts[0].command, (std::vector<std::string>{"ip", "netns", "exec", "{host}"}));
  EXPECT_FALSE(c.launch.hosts[0].quote);  // a command of one's own is not quoted unless asked
}

TEST_F(ConfigTest, HostAddressesAreNamesOrAddressesNeverOptionsOrShellText) {
  for (const char* address : {"robot@10.0.0.7", "host.example", "cell-pc", "10.0.0.7", "fe80::1",
                              "[fe80::1]", "robot@[fe80::1]", "fe80::1%eth0", "ns-1", "mrroc_b"}) {
    const std::string text =
        valid() + "\n[launch]\n[[launch.host]]\nname = \"cell\"\naddress = \"" + address + "\"\n";
    try {
      const ProcessSetConfig c = load_process_set(write(text));
      ASSERT_EQ(c.launch.hosts.size(), 1U);
      EXPECT_EQ(c.launch.hosts[0].address, address);
    } catch (const ConfigError& e) {
      ADD_FAILURE() << address << " was refused: " << e.what();
    }
  }
  for (const char* address : {"-oProxyCommand=x", "a b", "a;b", "$(x)", "a\\tb", "a\\nb", "`x`",
                              "a&b", "a|b", "a'b", "", "@host", "robot@-oProxyCommand=x",
                              "[fe80::1", "[10.0.0.7]", "fe80::1%e th0", "a@b@c", "x/../y"}) {
    const std::string text =
        valid() + "\n[launch]\n[[launch.host]]\nname = \"cell\"\naddress = \"" + address + "\"\n";
    const std::string error = error_of(text);
    // The value as the file holds it once TOML has read the escapes.
    std::string value = address;
    for (const auto& [escape, ch] : {std::pair{"\\t", '\t'}, std::pair{"\\n", '\n'}})
      if (const auto at = value.find(escape); at != std::string::npos)
        value.replace(at, 2, std::string(1, ch));
    expect_located(error, dir_ / "set.toml", line_of(text, "address ="),
                   "'address' = '" + value + "' is not a host address");
  }
  // Without 'address' the name is the address: a bad one is reported at 'name'.
  const std::string text =
      valid() + "\n[launch]\n[[launch.host]]\nname = \"-oProxyCommand=touch /tmp/x\"\n";
  expect_located(error_of(text), dir_ / "set.toml", line_of(text, "name = \"-o"),
                 "'name' = '-oProxyCommand=touch /tmp/x' is not a host address");
}

TEST_F(ConfigTest, SshHostsAlwaysQuoteAndKeepTheirInput) {
  const std::string host = "\n[launch]\n[[launch.host]]\nname = \"cell\"\n";
  // A command of one's own that runs ssh is quoted all the same.
  // So is a command that runs ssh behind a wrapper: ssh in any word hands the line to a remote
  // shell.
  for (const char* command :
       {R"(["ssh", "-t", "-t", "-o", "BatchMode=yes", "{host}"])", R"(["/usr/bin/ssh", "{host}"])",
        R"(["sshpass", "-e", "ssh", "{host}"])",
        R"(["sudo", "-n", "-u", "robot", "/usr/bin/ssh", "{host}"])"}) {
    const ProcessSetConfig c =
        load_process_set(write(valid() + host + "command = " + command + "\n"));
    ASSERT_EQ(c.launch.hosts.size(), 1U);
    EXPECT_TRUE(c.launch.hosts[0].quote) << command;
    EXPECT_TRUE(is_ssh_command(c.launch.hosts[0].command)) << command;
  }
  EXPECT_TRUE(load_process_set(write(valid() + host + "quote = true\n")).launch.hosts[0].quote);
  // Other commands keep `quote` as given.
  EXPECT_FALSE(is_ssh_command({"ip", "netns", "exec", "{host}"}));
  EXPECT_FALSE(is_ssh_command({"/usr/bin/sshpass", "-e", "{host}"}));
  EXPECT_FALSE(is_ssh_command({"ssh-agent", "run", "{host}"}));
  EXPECT_EQ(ssh_word({"env", "A=1", "/usr/bin/ssh", "{host}"}), 2U);
  EXPECT_TRUE(load_process_set(write(valid() + host +
                                     "command = [\"ip\", \"netns\", \"exec\", \"{host}\"]\n"
                                     "quote = true\n"))
                  .launch.hosts[0]
                  .quote);

  // quote = false with ssh (the default command or one's own) is refused at 'quote'.
  for (const std::string command : {"", "command = [\"ssh\", \"-t\", \"-t\", \"{host}\"]\n",
                                    "command = [\"sudo\", \"ssh\", \"{host}\"]\n"}) {
    const std::string text = valid() + host + command + "quote = false\n";
    expect_located(error_of(text), dir_ / "set.toml", line_of(text, "quote = false"),
                   "'quote' = false does not go with an ssh command");
  }
  // -n and -f give ssh no input: refused at 'command'; option arguments are not options.
  for (const char* command : {R"(["ssh", "-n", "{host}"])", R"(["ssh", "-tn", "{host}"])",
                              R"(["ssh", "-o", "BatchMode=yes", "-f", "{host}"])",
                              R"(["sudo", "-u", "robot", "ssh", "-n", "{host}"])"}) {
    const std::string text = valid() + host + "command = " + command + "\n";
    expect_located(error_of(text), dir_ / "set.toml", line_of(text, "command ="),
                   "'command' gives ssh option -");
  }
  for (const char* command :
       {R"(["ssh", "-o", "-n", "{host}"])", R"(["ssh", "-lfn", "{host}"])",
        R"(["ssh", "-p", "22", "--", "{host}", "-n"])", R"(["sudo", "-n", "ssh", "{host}"])"})
    EXPECT_NO_THROW(load_process_set(write(valid() + host + "command = " + command + "\n")))
        << command;
}

TEST(Loopback, OnlyLoopbackAddressesAndLocalhost) {
  for (const char* host : {"localhost", "127.0.0.1", "127.1.2.3", "::1"})
    EXPECT_TRUE(is_loopback(host)) << host;
  for (const char* host : {"", "0.0.0.0", "::", "10.0.0.1", "128.0.0.1", "127.example.com",
                           "127.0.0.1.example.com", "localhost.example.com", "::2"})
    EXPECT_FALSE(is_loopback(host)) << host;
}

TEST_F(ConfigTest, AConsoleBoundBeyondLoopbackNeedsATokenFile) {
  EXPECT_NO_THROW(load_process_set(write(valid() + "\n[ui]\nbind = \"127.0.0.2\"\n")));
  try {
    load_process_set(write(valid() + "\n[ui]\nbind = \"127.evil.example\"\n"));
    FAIL() << "a host name that starts with 127. is not loopback";
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("bind '127.evil.example' is not a loopback address"),
              std::string::npos)
        << e.what();
  }
}

TEST_F(ConfigTest, ConsoleHostsAreNamesOrAddressesWithoutPorts) {
  const ProcessSetConfig c = load_process_set(
      write(valid() + "\n[ui]\nhosts = [\"cell-pc\", \"10.0.0.5\", \"fe80::1\"]\n"));
  EXPECT_EQ(c.ui.hosts, (std::vector<std::string>{"cell-pc", "10.0.0.5", "fe80::1"}));
  try {
    load_process_set(write(valid() + "\n[ui]\nhosts = [\"cell-pc:8080\"]\n"));
    FAIL() << "a host with a port was accepted";
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("host 'cell-pc:8080' must be a name or an address"),
              std::string::npos)
        << e.what();
  }
}

namespace {

TEST(NearestName, SuggestsTheKnownNameATypingMistakeAway) {
  const std::vector<std::string> tasks = {"engrave", "follow_mp", "grasp_part",
                                          "visit_joint_poses"};
  EXPECT_EQ(nearest_name("engarve", tasks), "engrave");                      // two letters swapped
  EXPECT_EQ(nearest_name("visit_joint_posez", tasks), "visit_joint_poses");  // one replaced
  EXPECT_EQ(nearest_name("folow_mp", tasks), "follow_mp");                   // one left out
  EXPECT_EQ(nearest_name("grasp_parts", tasks), "grasp_part");               // one too many
  EXPECT_EQ(nearest_name("Engrave", tasks), "engrave");                      // case is one edit
  EXPECT_EQ(nearest_name("engrave", tasks), "engrave");                      // a known name: itself
}

TEST(NearestName, NothingForAnEmptyNameNoKnownNamesOrAFarName) {
  const std::vector<std::string> tasks = {"engrave", "follow_mp", "visit_joint_poses"};
  EXPECT_EQ(nearest_name("", tasks), std::nullopt);
  EXPECT_EQ(nearest_name("engarve", {}), std::nullopt);
  EXPECT_EQ(nearest_name("", {}), std::nullopt);
  EXPECT_EQ(nearest_name("", {""}), std::nullopt);
  EXPECT_EQ(nearest_name("polish", tasks), std::nullopt);
  EXPECT_EQ(nearest_name("visit_cartesian_poses", tasks), std::nullopt);
  // Three edits are too many for a name of 7 letters (at most 7 / 3 = 2).
  EXPECT_EQ(nearest_name("enxxave", tasks), "engrave");
  EXPECT_EQ(nearest_name("exxxave", tasks), std::nullopt);
  // A short name is never replaced whole: "ab" is not a typing mistake of "xy".
  EXPECT_EQ(nearest_name("a", {"b"}), std::nullopt);
  EXPECT_EQ(nearest_name("ab", {"xy"}), std::nullopt);
  EXPECT_EQ(nearest_name("ab", {"ax"}), "ax");
  // Equally near: the first in the order given.
  EXPECT_EQ(nearest_name("cat", {"bat", "car"}), "bat");
  EXPECT_EQ(nearest_name("cat", {"car", "bat"}), "car");
}

TEST(NearestName, EditDistanceCountsEachEditOnce) {
  EXPECT_EQ(edit_distance("", ""), 0U);
  EXPECT_EQ(edit_distance("", "abc"), 3U);
  EXPECT_EQ(edit_distance("abc", ""), 3U);
  EXPECT_EQ(edit_distance("abc", "abc"), 0U);
  EXPECT_EQ(edit_distance("abc", "acb"), 1U);  // a swap of neighbours
  EXPECT_EQ(edit_distance("abc", "axc"), 1U);
  EXPECT_EQ(edit_distance("kitten", "sitting"), 3U);
  EXPECT_EQ(edit_distance("ca", "abc"), 3U);  // no substring edited twice (optimal alignment)
}

TEST(NearestName, AnUnknownNameOfARegistryNamesTheSuggestionOnlyWhenNear) {
  RobotModel model;
  model.name = "r";
  model.folder = "/nowhere/robots/r";
  model.kinematics = "irb7";
  try {
    (void)edp::make_arm_kinematics(model);
    FAIL() << "an unknown kinematics solver was accepted";
  } catch (const ConfigError& e) {
    EXPECT_NE(e.message().find("unknown kinematics solver 'irb7' (known: "), std::string::npos)
        << e.what();
    EXPECT_NE(e.message().find("; did you mean 'irb6'?"), std::string::npos) << e.what();
  }
  model.kinematics = "no_such_solver";
  try {
    (void)edp::make_arm_kinematics(model);
    FAIL() << "an unknown kinematics solver was accepted";
  } catch (const ConfigError& e) {
    EXPECT_EQ(e.message().find("did you mean"), std::string::npos) << e.what();
  }
}

TEST(ConfigError, ACollectingCheckReportsEveryOptionalArgumentOfAnotherTypeOnceAndGoesOn) {
  const Params args = params_from_toml(
      "speed = \"fast\"\nsteps = 2.5\nlabel = 3\nflag = 1\nposes = \"home\"\nextra = 1\n",
      "set.toml");
  ConfigErrorList errors;
  // Collecting unknown keys only (a plugin of real devices at start): a type error throws.
  args.collect_unknown_keys(&errors);
  EXPECT_THROW((void)args.get_double("speed", 0.5), ConfigError);
  EXPECT_TRUE(errors.empty());
  args.collect_errors(&errors);
  // Optional: the default, the error kept (once, however often the task reads the key).
  EXPECT_DOUBLE_EQ(args.get_double("speed", 0.5), 0.5);
  EXPECT_DOUBLE_EQ(args.get_double("speed", 0.5), 0.5);
  EXPECT_EQ(args.get_int("steps", 10), 10);
  EXPECT_EQ(args.get_string("label", "x"), "x");
  EXPECT_TRUE(args.get_bool("flag", true));
  // Required: no value to go on with, so it throws (the task's own ConfigErrorList::run keeps it).
  EXPECT_THROW((void)args.get_double_rows("poses"), ConfigError);
  args.reject_unread("args");
  args.collect_unknown_keys(nullptr);
  std::string all;
  for (const auto& e : errors.errors()) all += std::string(e.what()) + "\n";
  EXPECT_EQ(all,
            "set.toml:1: error: 'speed' must be a number, not \"fast\"\n"
            "set.toml:2: error: 'steps' must be an integer, not 2.5\n"
            "set.toml:3: error: 'label' must be a string, not 3\n"
            "set.toml:4: error: 'flag' must be true or false, not 1\n"
            "set.toml:6: error: unknown key 'extra' in [args]\n");
  // Without the sink the same reads throw again.
  EXPECT_THROW((void)args.get_double("speed", 0.5), ConfigError);
}

}  // namespace
