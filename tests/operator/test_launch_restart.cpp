// Restart policies, required processes, the status table and log files on a real process set
// (SRP, EDP with MuJoCo, ECP, MP of tests/operator/configs/long-irb6.toml); an EDP on emulated
// CiA 402 drives (plugin "can", mrroc-axis-emu) restarted only after `mrroc-ui restart`.
#include <signal.h>

#include <regex>

#include "operator_helpers.hpp"

namespace mrroc::test {
namespace {

/// The row of `name` in a `mrroc-launch status` table, split into its columns.
std::vector<std::string> row_of(const std::string& table, const std::string& name) {
  std::istringstream lines(table);
  std::string line;
  while (std::getline(lines, line)) {
    std::istringstream words(line);
    std::vector<std::string> columns;
    for (std::string w; words >> w;) columns.push_back(w);
    if (!columns.empty() && columns[0] == name) return columns;
  }
  return {};
}
// Columns: NAME GROUP HOST STATE PID CPU% RSS RESTARTS UPTIME EXIT REQUIRED RESTART
constexpr std::size_t kState = 3, kPid = 4, kCpu = 5, kRss = 6, kRestarts = 7, kExit = 9,
                      kRequired = 10, kRestart = 11;

TEST(LaunchRestart, ABackOffBelowTheMinimumAndTooManyRestartsAreRefused) {
  const fs::path dir = temp_dir("backoff");
  const struct {
    const char* keys;
    const char* error;
  } cases[] = {
      {"restart = \"always\"\nrestart_backoff_s = 0\n",
       "error: 'restart_backoff_s' = 0 s is below the minimum of 0.2 s"},
      {"restart = \"always\"\nrestart_backoff_s = 0.1\n",
       "error: 'restart_backoff_s' = 0.1 s is below the minimum of 0.2 s"},
      {"restart = \"always\"\nmax_restarts = 1000\n",
       "error: 'max_restarts' = 1000 restarts is outside 0..20 restarts"},
  };
  for (const auto& c : cases) {
    const fs::path config = write_config(dir, "long-irb6.toml", c.keys);
    const auto [code, out] = run({launcher(), "--check", config.string()});
    EXPECT_EQ(code, 2) << c.keys << out;  // a config error
    EXPECT_TRUE(std::regex_search(out, std::regex("set\\.toml:[0-9]+: " + std::string(c.error))))
        << c.keys << out;
  }
  const fs::path ok =
      write_config(dir, "long-irb6.toml", "restart = \"always\"\nrestart_backoff_s = 0.2\n");
  const auto [code, out] = run({launcher(), "--check", ok.string()});
  EXPECT_EQ(code, 0) << out;
}

TEST(LaunchRestart, OnFailureRestartsTheSrpWhileTheTaskFinishesWithStatusAndLogs) {
  const fs::path dir = temp_dir("onfailure");
  const fs::path config =
      write_config(dir, "long-irb6.toml",
                   "restart = \"on-failure\"\nmax_restarts = 2\nrestart_backoff_s = 0.2\n",
                   "[launch]\nlog_dir = \"logs\"\nlog_max_kb = 1\nlog_keep = 2\n");
  Background launch({launcher(), config.string()});
  ASSERT_TRUE(launch.wait_for("task running")) << launch.output();
  const pid_t old_pid = launch.pid_of("srp");
  ASSERT_GT(old_pid, 0) << launch.output();
  std::this_thread::sleep_for(1s);
  ASSERT_EQ(::kill(old_pid, SIGKILL), 0);
  const auto ended = launch.wait_for(
      "srp ended while the task was running (code 137); restart 1 of 2 in 200 ms", 10s);
  ASSERT_TRUE(ended) << launch.output();
  ASSERT_TRUE(launch.wait_for("srp ready again", 15s)) << launch.output();
  const pid_t new_pid = launch.pid_of("srp");
  EXPECT_NE(new_pid, old_pid);

  // The status table, from another process (as an operator would run it).
  std::this_thread::sleep_for(1500ms);  // a CPU sample over a full second
  const auto [code, table] = run({launcher(), "status", config.string()}, 20s);
  EXPECT_EQ(code, 0) << table;
  std::printf("%s", table.c_str());
  const auto srp = row_of(table, "srp");
  ASSERT_EQ(srp.size(), 12u) << table;
  EXPECT_EQ(srp[kState], "running");
  EXPECT_EQ(srp[kPid], std::to_string(new_pid));
  EXPECT_EQ(srp[kRestarts], "1");
  EXPECT_EQ(srp[kExit], "137");
  EXPECT_EQ(srp[kRestart], "on-failure");
  const auto edp = row_of(table, "edp/irb6");
  ASSERT_EQ(edp.size(), 12u) << table;
  EXPECT_EQ(edp[kState], "running");
  EXPECT_EQ(edp[kPid], std::to_string(launch.pid_of("edp/irb6")));
  // CPU % over the last second (its arithmetic is checked in test_supervisor).
  EXPECT_GE(std::stod(edp[kCpu]), 0.0) << table;
  EXPECT_LE(std::stod(edp[kCpu]), 100.0 * static_cast<double>(std::thread::hardware_concurrency()))
      << table;
  EXPECT_GT(std::stol(edp[kRss]), 10000) << table;
  EXPECT_EQ(edp[kRestarts], "0");
  EXPECT_EQ(edp[kRequired], "yes");
  EXPECT_TRUE(has(table, "set 'long-irb6'")) << table;

  const pid_t ecp_pid = launch.pid_of("ecp/irb6");
  EXPECT_EQ(launch.wait(120s), 0) << launch.output();
  const std::string out = launch.output();
  EXPECT_TRUE(has(out, "task finished")) << out;
  EXPECT_EQ(leftovers(), "");

  // Log files: one per process, time-stamped lines; the chatty SRP's was rotated.
  const fs::path logs = dir / "logs";
  for (const char* name : {"srp.log", "edp_irb6.log", "ecp_irb6.log", "mp.log"})
    EXPECT_TRUE(fs::exists(logs / name)) << name;
  // (Every file is rotated at 1 KiB: the last lines of the ECP are in the current file.)
  const std::string ecp_log = slurp(logs / "ecp_irb6.log");
  EXPECT_TRUE(
      std::regex_search(ecp_log, std::regex(R"(\d\d:\d\d:\d\d\.\d{3}Z .*pose 9/9 reached)")))
      << ecp_log;
  EXPECT_TRUE(has(ecp_log, "--- ecp/irb6 (pid " + std::to_string(ecp_pid) + ") exited with code 0"))
      << ecp_log;
  EXPECT_TRUE(fs::exists(logs / "srp.log.1"));
  EXPECT_TRUE(fs::exists(logs / "srp.log.2"));
  EXPECT_FALSE(fs::exists(logs / "srp.log.3"));
  EXPECT_LE(fs::file_size(logs / "srp.log.1"), 1024u + 8192u);
  EXPECT_TRUE(has(slurp(logs / "srp.log") + slurp(logs / "srp.log.1") + slurp(logs / "srp.log.2"),
                  "--- srp (pid"));
  // The status command after the set ended: nobody answers.
  const auto [late_code, late] = run({launcher(), "status", "--timeout", "1", config.string()});
  EXPECT_EQ(late_code, 1) << late;
  EXPECT_TRUE(has(late, "no launcher of set 'long-irb6' answered")) << late;
  fs::remove_all(dir);
}

TEST(LaunchRestart, ANonRequiredProcessEndsAndTheSetGoesOn) {
  const fs::path dir = temp_dir("notrequired");
  const fs::path config = write_config(dir, "long-irb6.toml", "required = false\n");
  Background launch({launcher(), config.string()});
  ASSERT_TRUE(launch.wait_for("task running")) << launch.output();
  ASSERT_EQ(::kill(launch.pid_of("srp"), SIGKILL), 0);
  ASSERT_TRUE(launch.wait_for(
      "srp ended while the task was running (code 137) and is not restarted (restart = \"never\"); "
      "not required: the set goes on",
      10s))
      << launch.output();
  const auto [code, table] = run({launcher(), "status", config.string()}, 20s);
  EXPECT_EQ(code, 0) << table;
  const auto srp = row_of(table, "srp");
  ASSERT_EQ(srp.size(), 12u) << table;
  EXPECT_EQ(srp[kState], "failed");
  EXPECT_EQ(srp[kPid], "-");
  EXPECT_EQ(srp[kRequired], "no");
  EXPECT_EQ(launch.wait(120s), 0) << launch.output();
  EXPECT_TRUE(has(launch.output(), "task finished")) << launch.output();
  EXPECT_EQ(leftovers(), "");
  fs::remove_all(dir);
}

TEST(LaunchRestart, ARequiredProcessThatIsNotRestartedStopsTheSet) {
  const fs::path dir = temp_dir("required");
  const fs::path config = write_config(dir, "long-irb6.toml", "");
  Background launch({launcher(), config.string()});
  ASSERT_TRUE(launch.wait_for("task running")) << launch.output();
  ASSERT_EQ(::kill(launch.pid_of("edp/irb6"), SIGKILL), 0);
  EXPECT_EQ(launch.wait(60s), 4) << launch.output();
  const std::string out = launch.output();
  EXPECT_TRUE(has(out,
                  "edp/irb6 ended while the task was running (code 137) and is not restarted "
                  "(restart = \"never\"); it "
                  "is required: stopping the set"))
      << out;
  EXPECT_FALSE(has(out, "task finished")) << out;
  EXPECT_TRUE(has(out, "all processes stopped; exit code 4")) << out;
  EXPECT_EQ(leftovers(), "");
  fs::remove_all(dir);
}

TEST(LaunchRestart, BackoffDoublesAndUsedUpRestartsStopTheSet) {
  const fs::path dir = temp_dir("backoff");
  const fs::path config = write_config(
      dir, "long-irb6.toml", "restart = \"always\"\nmax_restarts = 2\nrestart_backoff_s = 0.6\n");
  Background launch({launcher(), config.string()});
  ASSERT_TRUE(launch.wait_for("task running")) << launch.output();
  std::vector<double> delays;
  for (int k = 1; k <= 2; ++k) {
    const std::size_t from = launch.line_count();
    const pid_t pid = launch.pid_of("srp");
    const auto killed = Clock::now();
    ASSERT_EQ(::kill(pid, SIGKILL), 0);
    const auto restarting =
        launch.wait_for("restarting srp (restart " + std::to_string(k), 10s, from);
    ASSERT_TRUE(restarting) << launch.output();
    delays.push_back(seconds(*restarting - killed));
    ASSERT_TRUE(launch.wait_for("srp ready again", 15s, from)) << launch.output();
    EXPECT_NE(launch.pid_of("srp"), pid);
  }
  std::printf("back-off delays measured: %.3f s, %.3f s (configured 0.6 s, 1.2 s)\n", delays[0],
              delays[1]);
  // From the kill to the restart: the back-off plus noticing the end (25 ms polls) and the
  // main loop's 50 ms tick.
  EXPECT_GE(delays[0], 0.6);
  EXPECT_LE(delays[0], 0.6 + 0.4);
  EXPECT_GE(delays[1], 1.2);
  EXPECT_LE(delays[1], 1.2 + 0.4);
  ASSERT_EQ(::kill(launch.pid_of("srp"), SIGKILL), 0);
  EXPECT_EQ(launch.wait(60s), 4) << launch.output();
  EXPECT_TRUE(
      has(launch.output(),
          "srp ended while the task was running (code 137) and is not restarted (all 2 restarts "
          "(max_restarts) used); it is required: stopping the set"))
      << launch.output();
  EXPECT_EQ(leftovers(), "");
  fs::remove_all(dir);
}

// A plugin of one's own that does not say whether it drives real devices counts as driving
// them: its EDP is held like one on drives (the plugin's declaration decides, not its name).
TEST(LaunchRestart, AnEdpWhosePluginDoesNotDeclareSimulatedHardwareIsHeld) {
  const fs::path dir = temp_dir("undeclared");
  std::string text = slurp(kSource / "tests/operator/configs/long-irb6.toml");
  auto replace = [&](const std::string& what, const std::string& with) {
    replace_once(text, what, with);
  };
  replace("\"../../../robots/irb6\"", "\"" + (kSource / "robots/irb6").string() + "\"");
  replace("task = \"start_and_wait\"", "task = \"start_and_wait\"\nstart = \"operator\"");
  replace("plugin = \"mujoco\"", "plugin = \"undeclared\"\nlibrary = \"" +
                                     std::string(MRROC_UNDECLARED_HARDWARE) +
                                     "\"\nrestart = \"on-failure\"\nrestart_backoff_s = 0.2");
  const fs::path config = dir / "undeclared.toml";
  std::ofstream(config) << text;

  const auto [check_code, check] = run({launcher(), "--check", config.string()});
  EXPECT_EQ(check_code, 0) << check;
  EXPECT_TRUE(has(check,
                  "back-off from 0.2 s, each after an operator's acknowledgement (plugin "
                  "'undeclared' drives real devices)"))
      << check;

  Background launch({launcher(), config.string()});
  ASSERT_TRUE(launch.wait_for("task running", 60s)) << launch.output();
  const pid_t old_pid = launch.pid_of("edp/irb6");
  ASSERT_GT(old_pid, 0) << launch.output();
  ASSERT_EQ(::kill(old_pid, SIGKILL), 0);
  EXPECT_TRUE(
      launch.wait_for("edp/irb6 (plugin 'undeclared' drives real devices) ended while "
                      "the task was running (code 137); not restarted until an operator "
                      "acknowledges",
                      10s))
      << launch.output();
  std::this_thread::sleep_for(1s);  // its back-off (0.2 s) is long over
  EXPECT_FALSE(has(launch.output(), "restarting edp/irb6")) << launch.output();
  const auto [end_code, end_out] =
      run({(kBin / "mrroc-ui").string(), "terminate", "-c", config.string()});
  EXPECT_EQ(end_code, 0) << end_out;
  EXPECT_GE(launch.wait(60s), 0) << launch.output();
  EXPECT_EQ(leftovers(), "");
  fs::remove_all(dir);
}

TEST(LaunchRestart, AnEdpOnCanDrivesIsRestartedOnlyAfterTheOperatorAcknowledges) {
  const fs::path dir = temp_dir("canack");
  std::string text = slurp(kSource / "tests/operator/configs/long-irb6.toml");
  auto replace = [&](const std::string& what, const std::string& with) {
    const auto at = text.find(what);
    ASSERT_NE(at, std::string::npos) << what;
    text.replace(at, what.size(), with);
  };
  replace("\"../../../robots/irb6\"", "\"" + (kSource / "robots/irb6").string() + "\"");
  replace("task = \"start_and_wait\"", "task = \"start_and_wait\"\nstart = \"operator\"");
  replace("plugin = \"mujoco\"", "plugin = \"can\"");
  // The drives of configs/demo-irb6-can.toml, emulated on its scene.
  replace("servo_period_ms = 2.0",
          "servo_period_ms = 2.0\nrestart = \"on-failure\"\nmax_restarts = 2\n"
          "restart_backoff_s = 0.2\n\n[robot.edp.params]\nbus = \"virtual:irb6\"\n"
          "nodes = [1, 2, 3, 4, 5]\ncounts_per_unit = 100000\nsilent_cycles = 25\neds = [\"" +
              (kSource / "configs/drives/emu-csp.eds").string() + "\", \"" +
              (kSource / "configs/drives/emu-pp-split.eds").string() + "\", \"" +
              (kSource / "configs/drives/emu-ip.eds").string() + "\", \"" +
              (kSource / "configs/drives/emu-ip.eds").string() + "\", \"" +
              (kSource / "configs/drives/emu-pp-split.eds").string() + "\"]\n");
  const fs::path config = dir / "can.toml";
  std::ofstream(config) << "[emulator]\nscene = \""
                        << (kSource / "configs/scenes/irb6.toml").string() << "\"\n\n"
                        << text;
  const std::string ui = (kBin / "mrroc-ui").string();

  const auto [check_code, check] = run({launcher(), "--check", config.string()});
  EXPECT_EQ(check_code, 0) << check;
  // The plugin's declaration (the EDP's --check-config), not its name, decides.
  EXPECT_TRUE(has(check,
                  "back-off from 0.2 s, each after an operator's acknowledgement (plugin 'can' "
                  "drives real devices)"))
      << check;

  Background launch({launcher(), config.string()});
  ASSERT_TRUE(launch.wait_for("task running", 60s)) << launch.output();
  const pid_t old_pid = launch.pid_of("edp/irb6");
  ASSERT_GT(old_pid, 0) << launch.output();
  // Nothing is held yet: an acknowledgement is refused (exit 1), an unknown process is an error.
  const auto [early_code, early] = run({ui, "restart", "-c", config.string(), "edp/irb6"});
  EXPECT_EQ(early_code, 1) << early;
  EXPECT_TRUE(has(early,
                  "RESTART REFUSED: edp/irb6 is not waiting for an acknowledgement "
                  "(state running)"))
      << early;
  const auto [unknown_code, unknown] = run({ui, "restart", "-c", config.string(), "edp/nope"});
  EXPECT_EQ(unknown_code, 2) << unknown;
  EXPECT_TRUE(has(unknown, "'edp/nope' is not a process of set 'long-irb6'")) << unknown;

  ASSERT_EQ(::kill(old_pid, SIGKILL), 0);
  const auto held = launch.wait_for(
      "edp/irb6 (plugin 'can' drives real devices) ended while the task was running (code "
      "137); not restarted until an operator acknowledges: mrroc-ui restart -c " +
          fs::absolute(config).lexically_normal().string() + " edp/irb6",
      10s);
  ASSERT_TRUE(held) << launch.output();
  // Its policy would restart it after 0.2 s: it is still down 2 s later.
  std::this_thread::sleep_for(2s);
  EXPECT_FALSE(has(launch.output(), "restarting edp/irb6")) << launch.output();
  EXPECT_EQ(launch.pid_of("edp/irb6"), old_pid) << launch.output();
  const auto [code, table] = run({launcher(), "status", config.string()}, 20s);
  EXPECT_EQ(code, 0) << table;
  const auto edp = row_of(table, "edp/irb6");
  ASSERT_EQ(edp.size(), 12u) << table;
  EXPECT_EQ(edp[kState], "held") << table;
  EXPECT_EQ(edp[kPid], "-") << table;
  EXPECT_EQ(edp[kRestarts], "0") << table;
  EXPECT_EQ(edp[kExit], "137") << table;
  EXPECT_EQ(launch.wait(0ms), -1) << "the set must wait for the operator\n" << launch.output();

  const std::size_t from = launch.line_count();
  const auto acked = Clock::now();
  const auto [ack_code, ack] = run({ui, "restart", "-c", config.string(), "edp/irb6"});
  EXPECT_EQ(ack_code, 0) << ack;
  EXPECT_TRUE(has(ack, "RESTART of edp/irb6 acknowledged: the launcher restarts it")) << ack;
  ASSERT_TRUE(launch.wait_for("edp/irb6: restart acknowledged by ui", 10s, from))
      << launch.output();
  const auto restarting = launch.wait_for("restarting edp/irb6 (restart 1 of 2)", 10s, from);
  ASSERT_TRUE(restarting) << launch.output();
  // The back-off still applies after the acknowledgement.
  EXPECT_GE(seconds(*restarting - acked), 0.2);
  ASSERT_TRUE(launch.wait_for("edp/irb6 ready again", 30s, from)) << launch.output();
  const pid_t new_pid = launch.pid_of("edp/irb6");
  EXPECT_NE(new_pid, old_pid);
  EXPECT_GT(new_pid, 0);

  // The restarted EDP drives the emulated drives through the whole task.
  const auto [start_code, start_out] = run({ui, "start", "-c", config.string()});
  EXPECT_EQ(start_code, 0) << start_out;
  EXPECT_TRUE(launch.wait_for("task 'start_and_wait' finished", 120s, from)) << launch.output();
  // (With start = "operator" the MP waits for the next START: terminate ends the set.)
  const auto [end_code, end_out] = run({ui, "terminate", "-c", config.string()});
  EXPECT_EQ(end_code, 0) << end_out;
  EXPECT_EQ(launch.wait(60s), 0) << launch.output();
  EXPECT_TRUE(has(launch.output(), "task finished")) << launch.output();
  EXPECT_EQ(leftovers(), "");
  fs::remove_all(dir);
}

}  // namespace
}  // namespace mrroc::test
