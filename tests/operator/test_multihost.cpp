// A process set on two "computers": two network namespaces joined by a veth pair, created here
// (inside scripts/netns-run, so nothing reaches the real network). MP, SRP and the web console
// run on host "a", ECP and EDP on host "b", each started through `ip netns exec`; the launcher
// runs in "a". The console, which has no [ui] token_file, generates its API token: the test reads
// it from the URL the console prints and asks the console for the robot's state with it.
#include <signal.h>
#include <sys/stat.h>

#include <cstdlib>
#include <regex>
#include <thread>

#include "operator_helpers.hpp"

namespace mrroc::test {
namespace {

int sh(const std::string& command) {
  const int status = std::system(command.c_str());
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

std::string capture(const std::string& command) {
  FILE* p = ::popen(command.c_str(), "r");
  if (p == nullptr) return {};
  std::string out;
  char buf[4096];
  while (std::fgets(buf, sizeof buf, p) != nullptr) out += buf;
  ::pclose(p);
  return out;
}

/// Packets counted by `ip -s link` on an interface of a namespace: {rx, tx}.
std::pair<long, long> packets(const std::string& ns, const std::string& dev) {
  // The line after "RX: bytes packets ..." holds the numbers, likewise for TX.
  const std::string out = capture("ip -n " + ns + " -s link show " + dev);
  std::istringstream lines(out);
  std::string line;
  long rx = -1;
  long tx = -1;
  long* next = nullptr;
  while (std::getline(lines, line)) {
    if (next != nullptr) {
      std::istringstream words(line);
      long bytes = 0;
      words >> bytes >> *next;
      next = nullptr;
    }
    if (has(line, "RX:")) next = &rx;
    if (has(line, "TX:")) next = &tx;
  }
  return {rx, tx};
}

class TwoHosts : public testing::Test {
 protected:
  void SetUp() override {
    created_ = true;
    ASSERT_EQ(sh("ip netns add " + a_ + " && ip netns add " + b_), 0)
        << "cannot create network namespaces (needs root and iproute2)";
    const std::string script =
        "set -e\n"
        "ip link add mrroc-va type veth peer name mrroc-vb\n"
        "ip link set mrroc-va netns " +
        a_ +
        "\n"
        "ip link set mrroc-vb netns " +
        b_ +
        "\n"
        "ip -n " +
        a_ +
        " addr add 10.77.0.1/24 dev mrroc-va\n"
        "ip -n " +
        b_ +
        " addr add 10.77.0.2/24 dev mrroc-vb\n"
        "for ns in " +
        a_ + " " + b_ +
        "; do ip -n $ns link set lo up; done\n"
        "ip -n " +
        a_ +
        " link set mrroc-va up\n"
        "ip -n " +
        b_ +
        " link set mrroc-vb up\n"
        "ip -n " +
        a_ +
        " route add 224.0.0.0/4 dev mrroc-va\n"
        "ip -n " +
        b_ + " route add 224.0.0.0/4 dev mrroc-vb\n";
    ASSERT_EQ(sh(script), 0);
    // Both ends up: the link is up (a veth is "state UP" only when its peer is up too).
    const std::string link = capture("ip -n " + a_ + " link show mrroc-va");
    ASSERT_TRUE(has(link, "state UP")) << link;
  }
  void TearDown() override {
    if (!created_) return;
    EXPECT_EQ(sh("ip netns del " + a_ + " 2>/dev/null; ip netns del " + b_), 0);
    EXPECT_FALSE(has(capture("ip netns list"), "mrroc-" + std::to_string(::getpid())));
  }

  const std::string a_ = "mrroc-" + std::to_string(::getpid()) + "-a";
  const std::string b_ = "mrroc-" + std::to_string(::getpid()) + "-b";
  bool created_ = false;
};

/// The set's key ([system] auth_key_file of multihost.toml): 64 hex digits, its owner's alone.
void write_key(const fs::path& file) {
  std::ofstream(file) << "8899aabbccddeeff00112233445566778899aabbccddeeff0011223344556677\n";
  fs::permissions(file, fs::perms::owner_read | fs::perms::owner_write, fs::perm_options::replace);
}

TEST_F(TwoHosts, TheDemoRunsAcrossTwoNamespaces) {
  const fs::path dir = temp_dir("multihost");
  fs::path config = write_config(dir, "multihost.toml", "");
  write_key(dir / "set.key");
  std::string text = slurp(config);
  for (const auto& [from, to] : {std::pair{std::string("\"mrroc-a\""), "\"" + a_ + "\""},
                                 std::pair{std::string("\"mrroc-b\""), "\"" + b_ + "\""}})
    text.replace(text.find(from), from.size(), to);
  text.replace(text.find("[launch]\n"), 9, "[launch]\nlog_dir = \"logs\"\n");
  std::ofstream(config) << text;

  // The plan shows the templated command lines.
  const auto [check_code, plan] = run({launcher(), "--check", config.string()});
  EXPECT_EQ(check_code, 0) << plan;
  // Other computers and ttl=1, but a key: nothing to warn of.
  EXPECT_FALSE(has(plan, "warning:")) << plan;
  EXPECT_TRUE(has(plan, "ip netns exec " + b_ +
                            " env 'LCM_DEFAULT_URL=udpm://239.255.76.67:7667?ttl=1' " +
                            (kBin / "mrroc-edp").string()))
      << plan;

  const auto before = packets(b_, "mrroc-vb");
  Background launch({"ip", "netns", "exec", a_, launcher(), config.string()});
  ASSERT_TRUE(launch.wait_for("task running", 60s)) << launch.output();
  // Each process runs in the namespace of its host.
  auto netns_of = [](pid_t pid) {
    std::error_code ec;
    return fs::read_symlink("/proc/" + std::to_string(pid) + "/ns/net", ec).string();
  };
  const std::string ns_launcher = netns_of(launch.pid());
  // The launcher itself is `ip netns exec` until it execs mrroc-launch: its pid is the same.
  EXPECT_EQ(netns_of(launch.pid_of("srp")), ns_launcher);
  EXPECT_EQ(netns_of(launch.pid_of("mp")), ns_launcher);
  EXPECT_EQ(netns_of(launch.pid_of("edp/irb6")), netns_of(launch.pid_of("ecp/irb6")));
  EXPECT_NE(netns_of(launch.pid_of("edp/irb6")), ns_launcher);
  EXPECT_NE(netns_of(launch.pid_of("edp/irb6")), netns_of(::getpid()));
  // The status table, asked from host "a".
  const auto [scode, table] =
      run({"ip", "netns", "exec", a_, launcher(), "status", config.string()}, 20s);
  EXPECT_EQ(scode, 0) << table;
  std::printf("%s", table.c_str());
  // Through `ip netns exec` the pid is the EDP's own: its memory is shown.
  EXPECT_TRUE(std::regex_search(
      table, std::regex(R"(edp/irb6 +edp +b +running +[0-9]+ +[0-9.]+ +[1-9][0-9]{3,} )")))
      << table;
  EXPECT_TRUE(std::regex_search(table, std::regex(R"(mp +mp +a +running)"))) << table;
  EXPECT_EQ(netns_of(launch.pid_of("ui")), ns_launcher);
  // The console's URL, printed on its standard output (here the launcher's, not a terminal)
  // without the token, which is in ui-8093.token in the set's [launch] log_dir, for its owner
  // only; the path of that file is printed.
  const fs::path token_file = dir / "logs" / "ui-8093.token";
  ASSERT_TRUE(launch.wait_for("API token in " + token_file.string(), 20s)) << launch.output();
  EXPECT_TRUE(has(launch.output(),
                  "web console of set 'multihost' at http://127.0.0.1:8093/ "
                  "(open it once as http://127.0.0.1:8093/?token=TOKEN"))
      << launch.output();
  const std::string token = [&] {
    std::string t = slurp(token_file);
    if (!t.empty() && t.back() == '\n') t.pop_back();
    return t;
  }();
  ASSERT_TRUE(std::regex_match(token, std::regex("[0-9a-f]{48}"))) << token;
  EXPECT_EQ(fs::status(token_file).permissions() & fs::perms::all,
            fs::perms::owner_read | fs::perms::owner_write);
  // Without the token: 401.
  const auto [ncode, refused] =
      run({"ip", "netns", "exec", a_, "curl", "-s", "-o", "/dev/null", "-w", "%{http_code}",
           "--max-time", "5", "http://127.0.0.1:8093/api/state"},
          20s);
  EXPECT_EQ(refused, "401") << "curl exit " << ncode;
  // The web console in "a" shows the robot whose EDP runs in "b": its state crossed the veth.
  std::string console;
  for (int attempt = 0; attempt < 20; ++attempt) {
    const auto [ccode, body] =
        run({"ip", "netns", "exec", a_, "curl", "-s", "-w", "\\n", "--max-time", "5", "-H",
             "Authorization: Bearer " + token, "http://127.0.0.1:8093/api/state"},
            20s);
    console = "curl exit " + std::to_string(ccode) + ": " + body;  // for the failure message
    if (ccode == 0 && has(console, "\"synchronised\":true")) break;
    std::this_thread::sleep_for(250ms);
  }
  EXPECT_TRUE(has(console, "\"synchronised\":true")) << console;
  EXPECT_TRUE(has(console, "\"name\":\"edp/irb6\"")) << console;

  EXPECT_EQ(launch.wait(120s), 0) << launch.output();
  const std::string out = launch.output();
  EXPECT_TRUE(has(out, "started edp/irb6 (pid")) << out;
  EXPECT_TRUE(has(out, "on host b")) << out;
  EXPECT_TRUE(has(out, "task finished")) << out;
  // The ECP's report crossed to the SRP on host "a", which printed it (the one copy on the
  // console); the ECP's own output, from host "b", is in its log file.
  EXPECT_TRUE(std::regex_search(
      out, std::regex(R"(\[srp\] +[0-9:.]+ ecp/irb6 +info +task 'visit_joint_poses' started)")))
      << out;
  const std::string ecp_log = slurp(dir / "logs" / "ecp_irb6.log");
  EXPECT_TRUE(has(ecp_log, "Z ecp/irb6: info: task 'visit_joint_poses' started")) << ecp_log;
  // The token is in no line of the output and no log file.
  EXPECT_FALSE(has(out, token)) << "the launcher's output holds the console's token";
  for (const auto& entry : fs::directory_iterator(dir / "logs")) {
    if (entry.path().filename().string().find(".log") == std::string::npos) continue;
    EXPECT_FALSE(has(slurp(entry.path()), token)) << entry.path() << " holds the console's token";
  }
  EXPECT_TRUE(has(out, "web console at http://127.0.0.1:8093/ (API token required; it is in '" +
                           token_file.string() + "')"))
      << out;
  EXPECT_FALSE(fs::exists(token_file)) << "removed when the console ended";

  const auto after = packets(b_, "mrroc-vb");
  std::printf("veth of host b: %ld packets received, %ld sent during the run\n",
              after.first - before.first, after.second - before.second);
  // The EDP in "b" broadcasts its state every 20 ms and answers every macro-step of the ECP
  // (which is in "b" too); the MP's commands and everyone's status come across from "a".
  EXPECT_GT(after.second - before.second, 300);  // b -> a
  EXPECT_GT(after.first - before.first, 20);     // a -> b
  EXPECT_EQ(leftovers(), "");
  fs::remove_all(dir);
}

// The shipped example of a set on two computers (configs/multi-host/two-computers.toml), set up
// as its comment tells a user: the key made beside it, the robot computer's address changed (here
// namespace "b"). Its host "cell" is reached through ssh: the launcher quotes the command line,
// puts "--" before the host, stops a process by closing its input, and the remote side sends the
// stop signal. There is no ssh server here: a stand-in named ssh, put in front of the config's
// default command, takes the words ssh would and runs the command line as sshd does (sh -c, in a
// session of its own), inside namespace "b", its input that of the connection. The EDP, started
// in "b", ends on SIGTERM (its status says finished) and is gone when the launcher has ended.
// Without its key the example is refused by --check, naming the file.
TEST_F(TwoHosts, TheShippedTwoComputerExampleRunsWithItsKeyOverSsh) {
  const fs::path dir = temp_dir("multihost-ssh");
  const fs::path ssh = dir / "ssh";
  std::ofstream(ssh) << "#!/bin/sh\n"
                        "# ssh [options] -- DESTINATION LINE, DESTINATION a network namespace\n"
                        "while [ \"$1\" != \"--\" ]; do shift; done\n"
                        "exec setsid -w ip netns exec \"$2\" sh -c \"$3\"\n";
  fs::permissions(ssh, fs::perms::owner_all);
  std::string text = slurp(kSource / "configs/multi-host/two-computers.toml");
  auto replace = [&](const std::string& from, const std::string& to) {
    replace_once(text, from, to);
  };
  replace("\"../../robots/irb6\"", "\"" + (kSource / "robots/irb6").string() + "\"");
  replace("address = \"cell-pc\"", "address = \"" + b_ + "\"\ncommand = [\"" + ssh.string() +
                                       "\", \"-o\", \"BatchMode=yes\", \"{host}\"]");
  const fs::path config = dir / "two-computers.toml";
  std::ofstream(config) << text;

  // Without its key: refused, naming the file.
  const auto [no_key_code, no_key] = run({launcher(), "--check", config.string()});
  EXPECT_EQ(no_key_code, 2) << no_key;
  EXPECT_TRUE(has(no_key, (dir / "set.key").string())) << no_key;
  EXPECT_TRUE(has(no_key, "openssl rand -hex 32")) << no_key;
  write_key(dir / "set.key");
  const auto [check_code, plan] = run({launcher(), "--check", config.string()});
  EXPECT_EQ(check_code, 0) << plan;
  EXPECT_FALSE(has(plan, "warning:")) << plan;

  Background launch({"ip", "netns", "exec", a_, launcher(), config.string()});
  ASSERT_TRUE(launch.wait_for("task running", 60s)) << launch.output();
  // The EDP's own pid, from its status (the launcher knows only the stand-in's), is in "b".
  std::smatch ready;
  const std::string so_far = launch.output();
  ASSERT_TRUE(
      std::regex_search(so_far, ready, std::regex(R"(edp/irb6 +status +ready \(pid ([0-9]+)\))")))
      << so_far;
  const std::string edp = ready[1];
  std::error_code ec;
  const std::string edp_ns = fs::read_symlink("/proc/" + edp + "/ns/net", ec).string();
  struct stat b_ns {};
  ASSERT_EQ(::stat(("/run/netns/" + b_).c_str(), &b_ns), 0);
  EXPECT_EQ(edp_ns, "net:[" + std::to_string(b_ns.st_ino) + "]") << "the EDP runs in \"b\"";

  EXPECT_EQ(launch.wait(120s), 0) << launch.output();
  const std::string out = launch.output();
  EXPECT_TRUE(std::regex_search(
      out, std::regex(R"(stopping edp/irb6 \(pid [0-9]+\) by closing its input)")))
      << out;
  EXPECT_TRUE(
      std::regex_search(out, std::regex(R"(edp/irb6 +status +finished \(pid )" + edp + R"(\))")))
      << "the EDP did not end by its stop signal\n"
      << out;
  EXPECT_FALSE(has(out, "killed edp/irb6")) << out;
  EXPECT_FALSE(fs::exists("/proc/" + edp)) << "the EDP outlived the launcher";
  EXPECT_EQ(leftovers(), "");
  fs::remove_all(dir);
}

}  // namespace
}  // namespace mrroc::test
