// mrroc-launch: starts a process set from one config file (recorder, SRP, emulator, VSPs, EDPs,
// ECPs, web console, then MP; the processes of one layer together), on this computer or others
// ([[launch.host]]), waits for each process to report ready, prefixes their output with the time
// and their names, leaving their reports to the SRP while it runs (and writes per-process log
// files), restarts processes by their restart policy, broadcasts the process table, and exits with
// the task's outcome. SIGINT/SIGTERM stop everything in reverse order. `mrroc-launch status CONFIG`
// prints the process table of a running set.
#include <fcntl.h>
#include <fmt/format.h>
#include <poll.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <csignal>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <iostream>
#include <map>
#include <mutex>
#include <optional>
#include <regex>
#include <set>
#include <string>
#include <tuple>
#include <utility>
#include <vector>

#include "estop_latch.hpp"
#include "launch_plan.hpp"
#include "mrroc/comm/auth.hpp"
#include "mrroc/comm/bus.hpp"
#include "mrroc/comm/edge.hpp"
#include "mrroc/comm/reporter.hpp"
#include "mrroc/comm/request_reply.hpp"
#include "mrroc/config/check.hpp"
#include "mrroc/config/process_set.hpp"
#include "mrroc/core/command_line.hpp"
#include "mrroc/core/time.hpp"
#include "status_board.hpp"
#include "supervisor.hpp"

namespace {

using namespace mrroc;
using launch::PlannedProcess;
namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;
using std::chrono::milliseconds;

/// Exit codes of mrroc-launch (also in docs/getting-started.md).
constexpr int kExitConfig = 2;       // the config is wrong: nothing was started
constexpr int kExitStartFailed = 3;  // a process failed to start or to become ready
constexpr int kExitProcessDied = 4;  // a required process ended for good while the task ran
constexpr int kExitTaskFailed = 1;   // the MP reported that the task failed
constexpr int kExitInternal = 5;     // the launcher itself failed (e.g. LCM would not open)
/// The longest wait before a restart [s].
constexpr double kMaxBackoffS = 30.0;
/// A process that reports no status counts as ready when it still runs after this.
constexpr milliseconds kSilentReady{300};
/// Operator commands to the launcher (launch_command_t; `mrroc-ui restart` sends them).
constexpr const char* kCommandChannel = "mrroc/launch/command";
/// The process that prints every process' reports: while it runs (from its ready on), the
/// supervisor leaves the processes' own copies of their reports off the console.
constexpr const char* kReportPrinter = "srp";

/// "HH:MM:SS.mmm " (local time now): the start of every line the launcher prints while it runs
/// a set, as the supervisor's lines start.
std::string stamp() { return format_utime(now_utime()) + " "; }

fs::path own_directory() {
  std::error_code ec;
  fs::path exe = fs::read_symlink("/proc/self/exe", ec);
  return ec ? fs::current_path() : exe.parent_path();
}

/// True if `program` is a path to an executable or found in PATH.
bool program_exists(const std::string& program) {
  auto executable = [](const fs::path& p) {
    std::error_code ec;
    return fs::is_regular_file(p, ec) && ::access(p.c_str(), X_OK) == 0;
  };
  if (program.find('/') != std::string::npos) return executable(program);
  const char* path = std::getenv("PATH");
  std::string_view rest = path != nullptr ? path : "/usr/local/bin:/usr/bin:/bin";
  for (;;) {
    const std::size_t colon = rest.find(':');
    const std::string_view dir = rest.substr(0, colon);
    if (executable(fs::path(dir.empty() ? "." : std::string(dir)) / program)) return true;
    if (colon == std::string_view::npos) return false;
    rest.remove_prefix(colon + 1);
  }
}

std::string quoted_command(const std::vector<std::string>& argv) {
  std::string line;
  for (const auto& w : argv) {  // piece by piece: GCC 12's -O3 warns about `"" + std::string`
    if (!line.empty()) line += ' ';
    line += launch::shell_quote(w);
  }
  return line;
}

/// The latest status of each process, with the time it arrived.
class ReadyWatch {
 public:
  void on_status(const ProcessStatus& s) {
    std::lock_guard lock(mutex_);
    seen_[s.process] = {s.state, Clock::now()};
    if (s.state == ProcessState::ready && !s.detail.empty()) declared_[s.process] = s.detail;
    cv_.notify_all();
  }
  /// The detail of the last ready status of `process` (an EDP's: what its plugin drives, e.g.
  /// "plugin 'can' drives real devices"); empty when none came. The launcher's listener takes
  /// only authentic statuses when the set has a key.
  std::string declaration(const std::string& process) {
    std::lock_guard lock(mutex_);
    auto it = declared_.find(process);
    return it == declared_.end() ? std::string() : it->second;
  }
  /// The state `process` reported (other than "starting") after `since`; nothing if there is
  /// none yet. (A restarted process is started after its predecessor was reaped, so what
  /// arrives after `since` comes from the new one.)
  std::optional<ProcessState> ready_since(const std::string& process, Clock::time_point since) {
    std::lock_guard lock(mutex_);
    return ready_locked(process, since);
  }
  /// Waits until `process` reported ready (or any later state) after `since`.
  std::optional<ProcessState> wait(const std::string& process, Clock::time_point since,
                                   Clock::time_point until, const std::function<bool()>& abort) {
    std::unique_lock lock(mutex_);
    while (Clock::now() < until) {
      if (auto state = ready_locked(process, since)) return state;
      if (abort()) return std::nullopt;
      cv_.wait_for(lock, milliseconds(20));
    }
    return std::nullopt;
  }

 private:
  struct Seen {
    ProcessState state;
    Clock::time_point at;
  };
  std::optional<ProcessState> ready_locked(const std::string& process,
                                           Clock::time_point since) const {
    auto it = seen_.find(process);
    if (it == seen_.end() || it->second.at < since || it->second.state == ProcessState::starting)
      return std::nullopt;
    return it->second.state;
  }
  std::mutex mutex_;
  std::condition_variable cv_;
  std::map<std::string, Seen> seen_;
  std::map<std::string, std::string> declared_;
};

int describe_exit(const launch::ChildExit& e) {
  return e.signal != 0 ? 128 + e.signal : e.exit_code;
}

/// Where a process of the plan is while the set runs (main thread only).
struct Runtime {
  int restarts = 0;
  int pid = 0;
  Clock::time_point started{};
  std::optional<Clock::time_point> restart_at;      // in back-off until then
  std::optional<Clock::time_point> ready_deadline;  // restarted, waiting for ready
  bool ended = false;                               // ended and will not be restarted
  bool held = false;  // its restart waits for an operator's acknowledgement (state "held")
};

/// Restart acknowledgements from `mrroc-ui restart` (bus thread in, main thread out).
class AckInbox {
 public:
  struct Ack {
    std::string process;
    std::string sender;
  };
  AckInbox(comm::Bus& bus, std::string set_name) : bus_(bus), set_name_(std::move(set_name)) {
    subscriber_.emplace(bus_, kCommandChannel,
                        [this](const launch::LaunchCommand& m, const comm::Received& in) {
                          if (m.set_name != set_name_) return;  // another set's
                          if (!in.authentic()) return;
                          std::lock_guard lock(mutex_);
                          acks_.push_back({m.process, in.header().sender});
                        });
  }
  ~AckInbox() { subscriber_.reset(); }
  AckInbox(const AckInbox&) = delete;
  AckInbox& operator=(const AckInbox&) = delete;
  std::vector<Ack> take() {
    std::lock_guard lock(mutex_);
    return std::exchange(acks_, {});
  }

 private:
  comm::Bus& bus_;
  std::string set_name_;
  std::mutex mutex_;
  std::vector<Ack> acks_;
  std::optional<comm::Subscriber<launch::LaunchCommand>> subscriber_;
};

/// The plan; `detailed` adds a line per process with its group, host, restart policy, stop
/// signal, grace period and log file (--check: without time stamps, nothing runs).
void print_plan(const ProcessSetConfig& config, const std::vector<PlannedProcess>& plan,
                bool detailed) {
  const std::string at = detailed ? std::string() : stamp();
  std::cout << fmt::format("{}mrroc-launch: process set '{}' from {} ({} robot(s), LCM {})\n", at,
                           config.name, config.file.string(), config.robots.size(),
                           comm::resolve_lcm_url(config.lcm_url));
  for (std::size_t i = 0; i < plan.size(); ++i) {
    const PlannedProcess& p = plan[i];
    std::cout << fmt::format("{}  {}. {:<12} {}\n", at, i + 1, p.name, quoted_command(p.spec.argv));
    if (!detailed) continue;
    std::string restart = to_string(p.options.restart);
    if (p.options.restart != RestartPolicy::never)
      restart += fmt::format(
          " (at most {}, back-off from {:.1f} s{})", p.options.max_restarts,
          p.options.restart_backoff_s,
          !p.edp ? ""
          : p.devices.empty()
              ? ", each after an operator's acknowledgement unless its plugin declares that it "
                "drives no real devices"
          : launch::declares_real_devices(p.devices)
              ? fmt::format(", each after an operator's acknowledgement ({})", p.devices)
              : "");
    std::cout << fmt::format(
        "     group {}, host {}, restart {}, {}, stop {} then SIGKILL after {:.1f} s, log {}\n",
        p.group, p.host, p.name == "mp" ? "never (its end is the end of the task)" : restart,
        p.name == "mp" ? "required" : (p.options.required ? "required" : "not required"),
        launch::signal_text(p.options.stop_signal), p.options.stop_grace_s,
        p.spec.log_file.empty() ? "-" : p.spec.log_file.string());
  }
  std::cout.flush();
}

/// True for the processes that check their own part of the config (`--check-config`).
bool checks_own_config(const PlannedProcess& p) {
  return p.name == "mp" || p.name == "emu" || p.name.rfind("edp/", 0) == 0 ||
         p.name.rfind("ecp/", 0) == 0 || p.name.rfind("vsp/", 0) == 0;
}

/// The longest a process' --check-config may take (it loads models, no network).
constexpr std::chrono::seconds kCheckTimeout{60};

/// Runs `argv` here (stdin from /dev/null) and returns its exit code (128+N for signal N, -1
/// when it could not be started) and what it printed (stdout and stderr). A program still
/// running after `timeout` is killed (exit code 128+SIGKILL, the output says so).
std::pair<int, std::string> run_captured(const std::vector<std::string>& argv,
                                         std::chrono::milliseconds timeout) {
  int out[2];
  if (::pipe2(out, O_CLOEXEC) != 0) return {-1, std::string("pipe: ") + std::strerror(errno)};
  std::vector<char*> args;
  for (const auto& a : argv) args.push_back(const_cast<char*>(a.c_str()));
  args.push_back(nullptr);
  const pid_t pid = ::fork();
  if (pid < 0) {
    ::close(out[0]);
    ::close(out[1]);
    return {-1, std::string("fork: ") + std::strerror(errno)};
  }
  if (pid == 0) {
    const int null = ::open("/dev/null", O_RDONLY | O_CLOEXEC);
    if (null >= 0) ::dup2(null, STDIN_FILENO);
    ::dup2(out[1], STDOUT_FILENO);
    ::dup2(out[1], STDERR_FILENO);
    ::execvp(args[0], args.data());
    std::fprintf(stderr, "cannot run %s: %s\n", args[0], std::strerror(errno));
    ::_exit(127);
  }
  ::close(out[1]);
  std::string output;
  const auto deadline = Clock::now() + timeout;
  bool killed = false;
  for (;;) {
    const auto left = std::chrono::duration_cast<milliseconds>(deadline - Clock::now()).count();
    if (left <= 0) {
      ::kill(pid, SIGKILL);
      killed = true;
      break;
    }
    pollfd p{out[0], POLLIN, 0};
    const int ready = ::poll(&p, 1, static_cast<int>(std::min<long long>(left, 100)));
    if (ready < 0 && errno != EINTR) break;
    if (ready <= 0) continue;
    std::array<char, 4096> buffer{};
    const ssize_t n = ::read(out[0], buffer.data(), buffer.size());
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) break;  // end of output: the program ended (or closed it)
    output.append(buffer.data(), static_cast<std::size_t>(n));
  }
  ::close(out[0]);
  int status = 0;
  while (::waitpid(pid, &status, 0) < 0 && errno == EINTR) {
  }
  if (killed)
    output += fmt::format("\n(killed after {} s)",
                          std::chrono::duration_cast<std::chrono::seconds>(timeout).count());
  const int code = WIFEXITED(status)     ? WEXITSTATUS(status)
                   : WIFSIGNALED(status) ? 128 + WTERMSIG(status)
                                         : -1;
  return {code, output};
}

/// The errors of a check, each once, ordered by file and line (errors without a location last).
class ErrorReport {
 public:
  void add(const std::string& line) {
    if (line.empty() || !seen_.insert(line).second) return;
    static const std::regex located(R"(^(.*?):(-?\d+): error: )");
    static const std::regex whole_file(R"(^(.*?): error: )");
    std::smatch m;
    Entry e{line, "", 0, order_++};
    if (std::regex_search(line, m, located)) {
      e.file = m[1];
      e.line = std::stoi(m[2]);
    } else if (std::regex_search(line, m, whole_file)) {
      e.file = m[1];
      e.line = -1;
    } else {
      e.file = "\x7f";  // after every file name
    }
    entries_.push_back(std::move(e));
  }
  void add(const std::vector<ConfigError>& errors) {
    for (const auto& e : errors) add(std::string(e.what()));
  }
  [[nodiscard]] bool empty() const { return entries_.empty(); }
  [[nodiscard]] std::size_t size() const { return entries_.size(); }
  void print(std::FILE* out) {
    std::stable_sort(entries_.begin(), entries_.end(), [](const Entry& a, const Entry& b) {
      return std::tie(a.file, a.line, a.order) < std::tie(b.file, b.line, b.order);
    });
    for (const auto& e : entries_) std::fprintf(out, "%s\n", e.text.c_str());
  }

 private:
  struct Entry {
    std::string text;
    std::string file;
    int line;
    int order;
  };
  std::set<std::string> seen_;
  std::vector<Entry> entries_;
  int order_ = 0;
};

/// --check: every process that checks its own config (emulator, EDPs, ECPs, VSPs, MP) runs its
/// `--check-config` here, the same code it runs at start (docs/configs.md, "When each part is
/// checked"); their errors join `report`.
void check_processes(const ProcessSetCheck& set, std::vector<PlannedProcess>& plan,
                     ErrorReport& report) {
  for (auto& p : plan) {
    if (!checks_own_config(p) || set.broken_process(p.name)) continue;
    if (!program_exists(p.command[0])) continue;  // reported already
    std::vector<std::string> argv = p.command;
    argv.emplace_back("--check-config");
    const auto [code, output] = run_captured(argv, kCheckTimeout);
    bool any = false;
    std::size_t start = 0;
    while (start < output.size()) {
      std::size_t end = output.find('\n', start);
      if (end == std::string::npos) end = output.size();
      const std::string line = output.substr(start, end - start);
      start = end + 1;
      if (line.find(": error: ") != std::string::npos) {
        report.add(line);
        any = true;
      }
      // mrroc-edp: "...: config is valid; plugin 'can' drives real devices".
      if (const std::size_t at = line.find(": config is valid; "); p.edp && at != std::string::npos)
        p.devices = line.substr(at + 19);
    }
    if (code != 0 && !any)
      report.add(fmt::format("mrroc-launch: {}: '{} --check-config' ended with code {}: {}", p.name,
                             p.command[0], code, output));
  }
}

int run(const std::string& config_path, bool check_only, const launch::PlanOptions& options) {
  const ProcessSetCheck set = check_process_set(config_path);
  const ProcessSetConfig& config = set.config;
  ErrorReport report;
  report.add(set.errors);
  std::vector<PlannedProcess> plan;
  try {
    plan = launch::make_plan(config, options);
  } catch (const std::exception& e) {
    if (set.ok()) report.add(std::string(e.what()));  // else reported already (unknown host)
  }
  for (const auto& p : plan) {
    for (const std::string* program : {&p.spec.argv[0], &p.command[0]}) {
      if (!program_exists(*program)) {
        report.add(
            fmt::format("mrroc-launch: executable '{}' of {} not found{}", *program, p.name,
                        program->find('/') != std::string::npos ? " (use --bin-dir)" : " in PATH"));
      }
    }
  }
  // What the processes check at start: only for --check (a start finds it the same way).
  if (check_only) check_processes(set, plan, report);
  if (!report.empty()) {
    report.print(stderr);
    if (check_only && report.size() > 1)
      std::fprintf(stderr, "mrroc-launch: %zu errors; nothing started\n", report.size());
    else
      std::fprintf(stderr, "mrroc-launch: nothing started\n");
    return kExitConfig;
  }

  print_plan(config, plan, check_only);
  // At every start (and with --check): a set reachable from the network without a key.
  if (const std::string warning = launch::unprotected_network_warning(config); !warning.empty()) {
    std::cout.flush();
    std::fprintf(stderr, "%smrroc-launch: %s\n", check_only ? "" : stamp().c_str(),
                 warning.c_str());
  }
  if (check_only) {
    std::cout << "mrroc-launch: config is valid (--check: nothing started)\n";
    return 0;
  }

  launch::install_stop_signal_handlers();
  if (!config.lcm_url.empty()) ::setenv("LCM_DEFAULT_URL", config.lcm_url.c_str(), 1);
  comm::Bus bus(config.lcm_url);
  comm::enable_auth_from_file(bus, config.auth_key_file);  // signs the stop's announcements
  ReadyWatch ready;
  SystemListener listener(bus, {}, [&](const ProcessStatus& s) { ready.on_status(s); });
  bus.start();
  // One process set per LCM URL: listen (sending nothing) for a set that runs there already.
  std::vector<std::string> robot_names;
  for (const auto& r : config.robots) robot_names.push_back(r.name);
  std::vector<std::string> ignored;
  const auto other = launch::running_set(bus, robot_names, &ignored);
  if (!ignored.empty()) {
    std::string list;
    for (const auto& i : ignored) list += (list.empty() ? "" : "; ") + i;
    std::fprintf(stderr,
                 "%smrroc-launch: warning: unauthenticated messages on LCM %s, not signed with "
                 "the set's key (ignored: they do not keep the set from starting): %s\n",
                 stamp().c_str(), bus.url().c_str(), list.c_str());
  }
  if (other) {
    const std::string at = stamp();
    std::fprintf(stderr,
                 "%smrroc-launch: refusing to start set '%s' (%s): another process set runs on "
                 "LCM %s: %s. One process set per LCM URL: stop it first, or give this set "
                 "another [system] lcm_url\n%smrroc-launch: nothing started\n",
                 at.c_str(), config.name.c_str(), config.file.string().c_str(), bus.url().c_str(),
                 other->describe().c_str(), at.c_str());
    return kExitConfig;
  }

  launch::LaunchStatus initial;
  initial.set_name = config.name;
  initial.config_file = config.file.string();
  initial.state = "starting";
  initial.launcher_pid = static_cast<int>(::getpid());
  for (const auto& p : plan) {
    launch::ProcessRow row;
    row.name = p.name;
    row.group = p.group;
    row.host = p.host;
    row.required = p.name == "mp" || p.options.required;
    row.restart = p.name == "mp" ? "never" : to_string(p.options.restart);
    // Through ssh the local pid is the ssh client's; a wrapper such as `ip netns exec` runs
    // the program itself under that pid.
    row.local_metrics = p.host == "local";
    for (const auto& h : config.launch.hosts)
      if (h.name == p.host && !h.quote && !is_ssh_command(h.command)) row.local_metrics = true;
    initial.processes.push_back(std::move(row));
  }

  launch::Supervisor supervisor(std::cout);
  // The emergency stop's latch: announced before any EDP starts, kept across EDP restarts.
  launch::EstopLatch estop_latch(bus, robot_names,
                                 [&](const std::string& line) { supervisor.log(line); });
  launch::StatusBoard board(bus, std::move(initial));
  AckInbox acks(bus, config.name);
  const std::string ui_config = fs::absolute(config.file).lexically_normal().string();
  // A warning for the SRP (the operator's view), besides the launcher's own output.
  auto srp_warning = [&](const std::string& robot, const std::string& text) {
    comm::Envelope header;
    header.sender = comm::unique_endpoint_name("launch");
    header.utime = now_utime();
    SrpMessage m;
    m.utime = header.utime;
    m.process = "launch";
    m.robot = robot;
    m.severity = Severity::warning;
    m.text = text;
    comm::broadcast(bus, channels::srp, header, m);
  };
  std::size_t width = 0;
  for (const auto& p : plan) width = std::max(width, p.name.size());
  supervisor.reserve_name_width(width);
  const auto t0 = Clock::now();
  auto since = [&] { return std::chrono::duration_cast<milliseconds>(Clock::now() - t0).count(); };
  const auto ready_timeout = milliseconds(std::lround(config.ready_timeout_s * 1e3));
  std::vector<Runtime> rt(plan.size());

  /// Starts process i; returns false (and logs why) if it could not be started.
  auto start = [&](std::size_t i) {
    const PlannedProcess& p = plan[i];
    board.update(p.name, [](launch::ProcessRow& r) { r.state = "starting"; });
    try {
      rt[i].started = Clock::now();
      rt[i].pid = supervisor.start(p.spec);
    } catch (const std::exception& e) {
      supervisor.log(fmt::format("mrroc-launch: cannot start {}: {}", p.name, e.what()));
      board.update(p.name, [](launch::ProcessRow& r) { r.state = "failed"; });
      return false;
    }
    board.update(p.name, [&](launch::ProcessRow& r) { r.pid = rt[i].pid; });
    supervisor.log(fmt::format("mrroc-launch: started {} (pid {}){}", p.name, rt[i].pid,
                               p.host == "local" ? "" : " on host " + p.host));
    return true;
  };

  // The processes of one layer (vsp/*, edp/*, ecp/*: consecutive in the plan) do not wait for
  // each other: they start together and the next layer starts when all of them are ready. Two
  // EDPs, each about 300 ms from start to ready, took 600 ms one after the other.
  auto layer = [&](std::size_t i) {
    const std::string& name = plan[i].name;
    const auto slash = name.find('/');
    return slash == std::string::npos ? name + "#" + std::to_string(i) : name.substr(0, slash);
  };
  int outcome = 0;
  bool started_all = true;
  std::vector<bool> launched(plan.size(), false);
  for (std::size_t i = 0; i < plan.size(); ++i) {
    const PlannedProcess& p = plan[i];
    if (i == 0 || layer(i) != layer(i - 1)) {
      // The first of its layer: start the whole layer. Starting EDPs wait for the stop's state.
      estop_latch.set_starting(plan[i].edp);
      for (std::size_t k = i; k < plan.size() && layer(k) == layer(i); ++k) {
        launched[k] = start(k);
        if (!launched[k] && plan[k].options.required) break;
      }
    }
    if (!launched[i]) {
      if (!p.options.required) continue;  // e.g. no lcm-logger: the set goes on
      outcome = kExitStartFailed;
      started_all = false;
      break;
    }
    std::optional<ProcessState> state;
    if (p.reports_ready) {
      state = ready.wait(p.name, rt[i].started, Clock::now() + ready_timeout, [&] {
        return supervisor.stop_requested() || !supervisor.is_running(p.name);
      });
    } else {
      const auto until = Clock::now() + kSilentReady;
      while (Clock::now() < until && supervisor.is_running(p.name) && !supervisor.stop_requested())
        std::this_thread::sleep_for(milliseconds(10));
      if (supervisor.is_running(p.name)) state = ProcessState::running;
    }
    if (supervisor.stop_requested()) {
      outcome = 128 + launch::stop_signal();
      started_all = false;
      break;
    }
    if (!state || *state == ProcessState::failed) {
      const std::string why =
          !supervisor.is_running(p.name) ? "ended before it was ready"
          : state                        ? "failed while starting"
                  : fmt::format("was not ready within {:.1f} s", config.ready_timeout_s);
      if (!p.options.required) {
        supervisor.log(
            fmt::format("mrroc-launch: {} {}; not required: the set goes on", p.name, why));
        continue;
      }
      supervisor.log(fmt::format("mrroc-launch: {} {}", p.name, why));
      outcome = kExitStartFailed;
      started_all = false;
      break;
    }
    board.update(p.name, [](launch::ProcessRow& r) { r.state = "running"; });
    if (p.name == kReportPrinter) supervisor.set_report_printer(p.name);
    supervisor.log(fmt::format("mrroc-launch: {} ready at {} ms", p.name, since()));
  }

  auto index_of = [&](const std::string& name) -> std::optional<std::size_t> {
    for (std::size_t i = 0; i < plan.size(); ++i)
      if (plan[i].name == name) return i;
    return std::nullopt;
  };

  estop_latch.set_starting(false);
  if (started_all) {
    board.set_state("running");
    supervisor.log(fmt::format("mrroc-launch: all {} processes ready in {} ms; task running",
                               plan.size(), since()));
    bool done = false;
    // A required process ended for good: the set stops.
    auto give_up = [&](const std::string& text) {
      supervisor.log(fmt::format("mrroc-launch: {}: stopping the set", text));
      outcome = kExitProcessDied;
      done = true;
    };
    while (!done) {
      for (const auto& e : supervisor.wait_events(milliseconds(50))) {
        if (done) break;
        const auto found = index_of(e.name);
        if (!found) continue;
        const std::size_t i = *found;
        const PlannedProcess& p = plan[i];
        const int code = describe_exit(e);
        rt[i].pid = 0;
        rt[i].ready_deadline.reset();
        board.update(p.name, [&](launch::ProcessRow& r) {
          r.state = code == 0 ? "exited" : "failed";
          r.pid = 0;
          r.last_exit_code = code;
        });
        if (p.name == "mp") {
          outcome = code == 0 ? 0 : kExitTaskFailed;
          supervisor.log(fmt::format("mrroc-launch: task {} (mp exit code {}) after {} ms",
                                     outcome == 0 ? "finished" : "FAILED", code, since()));
          done = true;
          break;
        }
        const RestartPolicy policy = p.options.restart;
        const bool wants_restart =
            policy == RestartPolicy::always || (policy == RestartPolicy::on_failure && code != 0);
        // An EDP whose plugin drives real devices (or did not say): a restarted one would
        // enable them again, so only when an operator agrees.
        const std::string declared = p.edp ? ready.declaration(p.name) : std::string();
        if (wants_restart && rt[i].restarts < p.options.max_restarts && p.edp &&
            (declared.empty() || launch::declares_real_devices(declared))) {
          rt[i].held = true;
          board.update(p.name, [](launch::ProcessRow& r) { r.state = "held"; });
          const std::string text = fmt::format(
              "{} ({}) ended while the task was running (code {}); not restarted until an "
              "operator acknowledges: mrroc-ui restart -c {} {}",
              p.name,
              declared.empty() ? "its plugin never declared whether it drives real devices"
                               : declared,
              code, ui_config, p.name);
          supervisor.log("mrroc-launch: " + text);
          srp_warning(p.name.substr(p.name.find('/') + 1), text);
          continue;
        }
        if (wants_restart && rt[i].restarts < p.options.max_restarts) {
          const double backoff =
              std::min(kMaxBackoffS, p.options.restart_backoff_s * std::pow(2.0, rt[i].restarts));
          rt[i].restart_at = Clock::now() + milliseconds(std::lround(backoff * 1e3));
          board.update(p.name, [](launch::ProcessRow& r) { r.state = "backoff"; });
          supervisor.log(
              fmt::format("mrroc-launch: {} ended while the task was running (code {}); restart {} "
                          "of {} in {} ms "
                          "(restart = \"{}\")",
                          p.name, code, rt[i].restarts + 1, p.options.max_restarts,
                          std::lround(backoff * 1e3), to_string(policy)));
          continue;
        }
        rt[i].ended = true;
        const std::string why = !wants_restart ? fmt::format("restart = \"{}\"", to_string(policy))
                                               : fmt::format("all {} restarts (max_restarts) used",
                                                             p.options.max_restarts);
        if (p.options.required) {
          give_up(
              fmt::format("{} ended while the task was running (code {}) and is not restarted "
                          "({}); it is required",
                          p.name, code, why));
        } else {
          supervisor.log(
              fmt::format("mrroc-launch: {} ended while the task was running (code {}) "
                          "and is not restarted ({}); "
                          "not required: the set goes on",
                          p.name, code, why));
        }
      }
      if (done) break;
      for (const auto& ack : acks.take()) {
        const auto found = index_of(ack.process);
        if (!found || !rt[*found].held) {
          supervisor.log(fmt::format(
              "mrroc-launch: ignored a restart acknowledgement for '{}' from {}: {}", ack.process,
              ack.sender, found ? "it is not waiting for one" : "no such process in this set"));
          continue;
        }
        const std::size_t i = *found;
        const PlannedProcess& p = plan[i];
        rt[i].held = false;
        const double backoff =
            std::min(kMaxBackoffS, p.options.restart_backoff_s * std::pow(2.0, rt[i].restarts));
        rt[i].restart_at = Clock::now() + milliseconds(std::lround(backoff * 1e3));
        board.update(p.name, [](launch::ProcessRow& r) { r.state = "backoff"; });
        supervisor.log(fmt::format(
            "mrroc-launch: {}: restart acknowledged by {}; restart {} of {} in {} ms", p.name,
            ack.sender, rt[i].restarts + 1, p.options.max_restarts, std::lround(backoff * 1e3)));
      }
      const auto now = Clock::now();
      for (std::size_t i = 0; i < plan.size() && !done; ++i) {
        const PlannedProcess& p = plan[i];
        if (rt[i].restart_at && now >= *rt[i].restart_at) {
          rt[i].restart_at.reset();
          ++rt[i].restarts;
          board.update(p.name, [&](launch::ProcessRow& r) { r.restarts = rt[i].restarts; });
          supervisor.log(fmt::format("mrroc-launch: restarting {} (restart {} of {})", p.name,
                                     rt[i].restarts, p.options.max_restarts));
          if (!start(i)) {
            rt[i].ended = true;
            if (p.options.required) give_up(fmt::format("{} could not be restarted", p.name));
            continue;
          }
          rt[i].ready_deadline = Clock::now() + (p.reports_ready ? ready_timeout : kSilentReady);
        }
        if (rt[i].ready_deadline && rt[i].pid != 0) {
          std::optional<ProcessState> state;
          if (p.reports_ready) {
            state = ready.ready_since(p.name, rt[i].started);
          } else if (now >= *rt[i].ready_deadline) {
            state = ProcessState::running;
          }
          if (state && *state != ProcessState::failed) {
            rt[i].ready_deadline.reset();
            board.update(p.name, [](launch::ProcessRow& r) { r.state = "running"; });
            if (p.name == kReportPrinter) supervisor.set_report_printer(p.name);
            supervisor.log(fmt::format("mrroc-launch: {} ready again at {} ms (restart {})", p.name,
                                       since(), rt[i].restarts));
          } else if (state || now >= *rt[i].ready_deadline) {
            rt[i].ready_deadline.reset();
            const std::string why = state ? "failed while starting again"
                                          : fmt::format(
                                                "was not ready within {:.1f} s after "
                                                "its restart",
                                                config.ready_timeout_s);
            if (p.options.required) {
              give_up(fmt::format("{} {}; it is required", p.name, why));
            } else {
              supervisor.log(fmt::format("mrroc-launch: warning: {} {}", p.name, why));
            }
          }
        }
      }
      if (!done && supervisor.stop_requested()) {
        supervisor.log("mrroc-launch: stop requested: stopping the set");
        outcome = 128 + launch::stop_signal();
        done = true;
      }
    }
  }
  board.set_state("stopping");
  supervisor.stop_all();
  for (const auto& p : plan)
    board.update(p.name, [](launch::ProcessRow& r) {
      if (r.pid != 0 || r.state == "running" || r.state == "backoff" || r.state == "starting" ||
          r.state == "held")
        r.state = "stopped";
      r.pid = 0;
    });
  for (const auto& e : supervisor.exits()) {
    if (auto i = index_of(e.name))
      board.update(e.name, [&](launch::ProcessRow& r) { r.last_exit_code = describe_exit(e); });
  }
  supervisor.log(fmt::format("mrroc-launch: all processes stopped; exit code {}", outcome));
  return outcome;
}

int run_status(int argc, char** argv) {
  mrroc::CommandLine cli(
      "mrroc-launch status",
      "mrroc-launch status: prints the process table of the running set of CONFIG (name, group, "
      "host, state, pid, CPU %, resident memory, restarts, uptime, last exit code, required, "
      "restart policy), as its launcher broadcasts it every second on mrroc/launch/status. Exits "
      "0 when a launcher of that set answered, 1 when none did within the timeout, 2 on a "
      "config error or a bad command line.");
  std::string config_path;
  double timeout_s = 3.0;
  cli.option("config", config_path, "process-set config file (TOML) of the running set").required();
  cli.option("--timeout", timeout_s, "how long to listen [s]").range(0.1, 60.0);
  if (const auto exit_code = cli.parse(argc, argv)) return *exit_code;
  ProcessSetConfig config;
  try {
    config = load_process_set(config_path);
  } catch (const ConfigError& e) {
    std::fprintf(stderr, "%s\n", e.what());
    return kExitConfig;
  }
  comm::Bus bus(config.lcm_url);
  const auto status =
      launch::receive_status(bus, config.name, milliseconds(std::lround(timeout_s * 1000.0)));
  if (!status) {
    std::printf("mrroc-launch status: no launcher of set '%s' answered within %.1f s on %s\n",
                config.name.c_str(), timeout_s, bus.url().c_str());
    return 1;
  }
  std::fputs(launch::format_status_table(*status).c_str(), stdout);
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  std::signal(SIGPIPE, SIG_IGN);  // a closed stdout must not kill the launcher before its children
  if (argc >= 2 && std::strcmp(argv[1], "status") == 0) {
    try {
      return run_status(argc - 1, argv + 1);
    } catch (const std::exception& e) {
      std::fprintf(stderr, "mrroc-launch status: %s\n", e.what());
      return kExitInternal;
    }
  }
  mrroc::CommandLine cli(
      "mrroc-launch",
      "mrroc-launch: starts a process set from one config file (lcm-logger when recording, SRP, "
      "emulator, VSPs, EDPs, ECPs, the web console when [ui] web = true, then MP), on this "
      "computer or on the [[launch.host]]s named by each process' 'host', waits for each process "
      "to be ready, prints each process' output with the time and its name (a process' own "
      "report lines only while the SRP does not run: the SRP prints every report) and writes one "
      "log file per process when [launch] log_dir is set, restarts processes by their 'restart' "
      "policy, broadcasts the process table every second on mrroc/launch/status, and exits with "
      "the task's outcome: 0 task finished, 1 task failed, 2 config error (nothing started), 3 a "
      "process failed to start, 4 a required process ended for good during the task, 5 the "
      "launcher itself failed, 128+N stopped by signal N. SIGINT/SIGTERM stop every process in "
      "reverse start order (its stop_signal, then SIGKILL after its stop_grace_s).\n"
      "'mrroc-launch status CONFIG' prints the process table of a running set (see "
      "'mrroc-launch status --help').");
  std::string config;
  std::string bin_dir;
  launch::PlanOptions options;
  std::string record;
  bool check = false;
  cli.option("config", config, "process-set config file (TOML)").required();
  cli.flag("--check", check,
           "validate the config and print the plan (order, command line after host "
           "templating, group, host, restart policy, stop signal, grace period, log file); "
           "start nothing");
  cli.option("--bin-dir", bin_dir,
             "where the mrroc-* executables are (default: beside mrroc-launch)");
  cli.option("--srp-log", options.srp_log, "file the SRP appends every message to");
  cli.option("--record", record,
             "record every LCM message of the run to this file with lcm-logger (overrides "
             "[launch] record)");
  if (const auto exit_code = cli.parse(argc, argv)) return *exit_code;
  options.bin_dir = bin_dir.empty() ? own_directory() : fs::path(bin_dir);
  if (!record.empty()) options.record = fs::absolute(record);
  try {
    return run(config, check, options);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "%smrroc-launch: %s\n", check ? "" : stamp().c_str(), e.what());
    return kExitInternal;
  }
}
