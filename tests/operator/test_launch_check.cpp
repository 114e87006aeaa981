// mrroc-launch --check (the plan with host templating), config errors of the launcher's keys,
// and recording a run with lcm-logger.
#include <signal.h>

#include "operator_helpers.hpp"

namespace mrroc::test {
namespace {

const char* kHosts = R"([launch]
log_dir = "logs"

[[launch.host]]
name = "cell"
address = "robot@10.0.0.7"

[[launch.host]]
name = "b"
command = ["ip", "netns", "exec", "{host}"]
address = "ns-b"
quote = false
)";

TEST(LaunchCheck, PrintsThePlanWithHostTemplatingAndStartsNothing) {
  const fs::path dir = temp_dir("check");
  std::string tables = kHosts;
  fs::path config =
      write_config(dir, "long-irb6.toml",
                   "host = \"cell\"\nrestart = \"always\"\nmax_restarts = 5\n"
                   "stop_signal = \"SIGINT\"\nstop_grace_s = 1.5\ngroup = \"logging\"\n",
                   tables);
  // The EDP on "b" (quote = false).
  std::string text = slurp(config);
  const std::string edp = "plugin = \"mujoco\"\n";
  text.replace(text.find(edp), edp.size(), edp + "host = \"b\"\nrequired = true\n");
  std::ofstream(config) << text;

  const auto [code, out] = run({launcher(), "--check", config.string()});
  std::printf("%s", out.c_str());
  EXPECT_EQ(code, 0) << out;
  const std::string cfg = config.string();
  const std::string bin = kBin.string();
  // ssh: "--" before the address; the command line with its environment is one shell-quoted
  // word, run by the remote stop script with the process' stop signal and grace (rounded up).
  EXPECT_TRUE(has(out, "1. srp          ssh -o BatchMode=yes -- robot@10.0.0.7 'exec sh -c '"))
      << out;
  EXPECT_TRUE(has(out,
                  " mrroc-remote INT 2 env "
                  "'\\''LCM_DEFAULT_URL=udpm://239.255.76.67:7667?ttl=0'\\'' " +
                      bin + "/mrroc-srp --config " + cfg + "'\n"))
      << out;
  EXPECT_TRUE(has(out,
                  "group logging, host cell, restart always (at most 5, back-off from 0.5 s), "
                  "required, stop SIGINT then SIGKILL after 1.5 s, log " +
                      (dir / "logs/srp.log").string()))
      << out;
  // ip netns exec: separate words.
  EXPECT_TRUE(has(out,
                  "2. edp/irb6     ip netns exec ns-b env "
                  "'LCM_DEFAULT_URL=udpm://239.255.76.67:7667?ttl=0' " +
                      bin + "/mrroc-edp --config " + cfg + " --robot irb6"))
      << out;
  EXPECT_TRUE(has(out,
                  "group edp, host b, restart never, required, stop SIGTERM then SIGKILL "
                  "after 3.0 s, log " +
                      (dir / "logs/edp_irb6.log").string()))
      << out;
  EXPECT_TRUE(has(out, "3. ecp/irb6     " + bin + "/mrroc-ecp")) << out;
  EXPECT_TRUE(has(out, "4. mp           " + bin + "/mrroc-mp")) << out;
  EXPECT_TRUE(has(out, "config is valid (--check: nothing started)")) << out;
  EXPECT_FALSE(has(out, "mrroc-launch: started")) << out;
  // Processes on other computers and no key: --check says so.
  EXPECT_TRUE(has(out, "mrroc-launch: warning: set 'long-irb6' (" + cfg +
                           ") has no [system] auth_key_file, but it runs processes on other "
                           "computers ([[launch.host]] cell, b): anyone on that network can"))
      << out;
  EXPECT_FALSE(fs::exists(dir / "logs")) << "--check must not create the log folder";
  EXPECT_EQ(leftovers(), "");

  // --record puts lcm-logger first.
  const auto [rcode, rout] =
      run({launcher(), "--check", "--record", (dir / "x.lcmlog").string(), config.string()});
  EXPECT_EQ(rcode, 0) << rout;
  EXPECT_TRUE(has(rout,
                  "1. record       lcm-logger '--lcm-url=udpm://239.255.76.67:7667?ttl=0' "
                  "--force --quiet " +
                      (dir / "x.lcmlog").string()))
      << rout;
  EXPECT_TRUE(has(rout, "group record, host local, restart never, not required, stop SIGINT"))
      << rout;
  fs::remove_all(dir);
}

/// `text` with its LCM URL's ttl=0 replaced by ttl=`ttl`.
std::string with_ttl(std::string text, int ttl) {
  const std::string zero = "?ttl=0\"";
  text.replace(text.find(zero), zero.size(), "?ttl=" + std::to_string(ttl) + "\"");
  return text;
}

TEST(LaunchCheck, ASetThatReachesTheNetworkWithoutAKeyIsWarnedAbout) {
  const fs::path dir = temp_dir("nokey");
  const fs::path key = dir / "set.key";
  std::ofstream(key) << "00112233445566778899aabbccddeeff00112233445566778899aabbccddeeff\n";
  fs::permissions(key, fs::perms::owner_read | fs::perms::owner_write, fs::perm_options::replace);
  const fs::path config = write_config(dir, "long-irb6.toml", "");
  const std::string text = slurp(config);
  const std::string warning = "has no [system] auth_key_file, but ";
  struct Case {
    std::string what;
    std::string text;
    std::string expected;  // empty: no warning
  };
  const std::string keyed =
      "[system]\nauth_key_file = \"" + key.string() + "\"\nname = \"long-irb6\"\n";
  std::string with_key = with_ttl(text, 1);
  with_key.replace(with_key.find("[system]\nname = \"long-irb6\"\n"),
                   std::string("[system]\nname = \"long-irb6\"\n").size(), keyed);
  const std::vector<Case> cases = {
      {"ttl=1 without a key", with_ttl(text, 1),
       warning + "its LCM URL udpm://239.255.76.67:7667?ttl=1 has ttl=1 (its messages leave "
                 "this computer): anyone on that network can start and stop its task"},
      {"ttl=0 on one computer", text, ""},
      {"ttl=1 with a key", with_key, ""},
  };
  for (const auto& c : cases) {
    std::ofstream(config) << c.text;
    const auto [code, out] = run({launcher(), "--check", config.string()});
    EXPECT_EQ(code, 0) << c.what << "\n" << out;  // a warning, not an error
    if (c.expected.empty())
      EXPECT_FALSE(has(out, "warning:")) << c.what << "\n" << out;
    else
      EXPECT_TRUE(has(out, c.expected)) << c.what << "\n" << out;
  }
  fs::remove_all(dir);
}

/// The line of the config holding `needle` (1-based).
int line_of(const fs::path& file, const std::string& needle) {
  std::istringstream lines(slurp(file));
  std::string line;
  for (int n = 1; std::getline(lines, line); ++n)
    if (has(line, needle)) return n;
  return -1;
}

TEST(LaunchCheck, BadLauncherKeysAreConfigErrorsNamingFileLineAndValue) {
  const fs::path dir = temp_dir("bad");
  struct Case {
    std::string srp_keys;
    std::string message;
    std::string line_of;  // text of the line named
  };
  const std::vector<Case> cases = {
      {"restart = \"sometimes\"\n",
       "error: restart 'sometimes' must be \"never\", \"on-failure\" or \"always\"", "sometimes"},
      {"stop_signal = \"SIGSTOP\"\n", "error: stop_signal 'SIGSTOP' is not one of SIGTERM",
       "SIGSTOP"},
      {"max_restarts = -1\n", "error: 'max_restarts' = -1", "max_restarts"},
      {"restart_backoff_s = 31\n", "error: 'restart_backoff_s' = 31 s is outside 0..30 s",
       "restart_backoff_s"},
      {"host = \"nowhere\"\n", "srp runs on host 'nowhere', which is not a [[launch.host]]",
       "nowhere"},
  };
  for (const auto& c : cases) {
    const fs::path config = write_config(dir, "long-irb6.toml", c.srp_keys);
    const auto [code, out] = run({launcher(), "--check", config.string()});
    EXPECT_EQ(code, 2) << c.srp_keys << out;
    EXPECT_TRUE(has(out, c.message)) << out;
    const std::string where =
        config.string() + ":" + std::to_string(line_of(config, c.line_of)) + ": ";
    EXPECT_TRUE(has(out, where)) << where << "\n" << out;
    EXPECT_TRUE(has(out, "nothing started")) << out;
  }
  EXPECT_EQ(leftovers(), "");
  fs::remove_all(dir);
}

TEST(LaunchRecord, RecordsEveryMessageOfTheRunWithLcmLogger) {
  const fs::path dir = temp_dir("record");
  const fs::path log = dir / "run.lcmlog";
  const fs::path config = write_config(dir, "long-irb6.toml", "");
  // The short demo's poses are enough here.
  std::string text = slurp(config);
  const auto begin = text.find("poses = [");
  const auto end = text.find("]\nvelocity_scale");
  text.replace(begin, end - begin + 1, "poses = [[0.0, -1.5708, 0.0, 0.0, 0.0]]");
  // ttl=1 (inside the test's private network namespace: only its loopback) and no key.
  std::ofstream(config) << with_ttl(text, 1);
  const auto [code, out] = run({launcher(), "--record", log.string(), config.string()}, 120s);
  EXPECT_EQ(code, 0) << out;
  // Every start warns of a set reachable from the network without a key.
  EXPECT_TRUE(std::regex_search(
      out,
      std::regex("[0-9:.]+ mrroc-launch: warning: set 'long-irb6' \\(.*\\) has no \\[system\\] "
                 "auth_key_file, but its LCM URL udpm://239.255.76.67:7667\\?ttl=1 has ttl=1")))
      << out;
  EXPECT_TRUE(has(out, "started record (pid")) << out;
  EXPECT_TRUE(has(out, "stopping record (pid")) << out;
  EXPECT_TRUE(has(out, ") with SIGINT")) << out;
  // Stopped last: after the SRP.
  EXPECT_LT(out.find("stopping srp"), out.find("stopping record")) << out;
  ASSERT_TRUE(fs::exists(log));
  const std::string recorded = slurp(log);
  EXPECT_GT(recorded.size(), 10000u);
  for (const char* channel : {"mrroc/status", "mrroc/srp", "irb6/edp/cmd", "irb6/edp/reply",
                              "irb6/ecp/cmd", "mrroc/launch/status"})
    EXPECT_TRUE(has(recorded, channel)) << channel;
  // The last messages of the run are in the file: the MP's "finished" status comes before
  // the logger is stopped.
  EXPECT_EQ(leftovers(), "");
  fs::remove_all(dir);
}

}  // namespace
}  // namespace mrroc::test
