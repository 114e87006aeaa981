// mrroc-ui: operator commands for a running process set: the emergency stop (engage, release)
// for every robot or one, task commands to the MP (start, pause, resume, stop, terminate,
// status), the acknowledgement of a held restart to the launcher (restart), and the web operator
// console (serve). docs/operating.md.
#include <fmt/format.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <cstdio>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "console/console.hpp"
#include "console/http_api.hpp"
#include "mrroc/comm/auth.hpp"
#include "mrroc/comm/bus.hpp"
#include "mrroc/comm/edge.hpp"
#include "mrroc/comm/reporter.hpp"
#include "mrroc/comm/request_reply.hpp"
#include "mrroc/config/process_set.hpp"
#include "mrroc/core/command_line.hpp"
#include "mrroc/core/error.hpp"
#include "mrroc/core/process.hpp"
#include "mrroc/core/time.hpp"
#include "operator.hpp"

namespace {

using namespace mrroc;

// Exit codes of the task commands.
constexpr int kExitRefused = 1;      // the MP answered and refused the command
constexpr int kExitConfig = 2;       // bad command line or config
constexpr int kExitNoMp = 3;         // no MP answered
constexpr int kExitUnconfirmed = 4;  // estop / release: a robot did not confirm in time
// restart: 1 the process is not held for an acknowledgement, 2 it is not in the set,
// 3 no launcher of the set answered (or it did not confirm in time).
constexpr int kExitNoLauncher = 3;
/// Operator commands to the launcher (launch_command_t); launch/main.cpp serves them.
constexpr const char* kLaunchCommandChannel = "mrroc/launch/command";

/// Acknowledges the restart of `process`, which the launcher holds (state "held", an EDP on
/// CiA 402 drives), and waits until the launcher's process table shows it released.
int acknowledge_restart(const std::string& config_path, const std::string& process,
                        double timeout_s) {
  const ProcessSetConfig config = load_process_set(config_path);
  comm::Bus bus(config.lcm_url);
  comm::enable_auth_from_file(bus, config.auth_key_file);
  struct Watch {
    std::mutex mutex;
    std::condition_variable cv;
    std::string set_name;
    std::optional<launch::LaunchStatus> latest;
    std::uint64_t received = 0;  // tables received so far
  } watch;
  watch.set_name = config.name;
  std::optional<comm::Subscriber<launch::LaunchStatus>> tables;
  tables.emplace(
      bus, channels::launch_status,
      [&watch](const launch::LaunchStatus& m, const comm::Received&) {
        if (m.set_name != watch.set_name) return;
        std::lock_guard lock(watch.mutex);
        watch.latest = m;
        ++watch.received;
        watch.cv.notify_all();
      },
      comm::SubscriberOptions::unreported());
  bus.start();
  using SteadyClock = std::chrono::steady_clock;
  const auto deadline =
      SteadyClock::now() + std::chrono::milliseconds(std::lround(timeout_s * 1e3));
  struct Row {
    bool found = false;
    std::string state;
  };
  // `process` in the first table received after the `after`-th one, or nothing by `until`.
  auto next_row = [&](std::uint64_t after, SteadyClock::time_point until) -> std::optional<Row> {
    std::unique_lock lock(watch.mutex);
    if (!watch.cv.wait_until(lock, until, [&] { return watch.received > after; }))
      return std::nullopt;
    for (const auto& r : watch.latest->processes)
      if (r.name == process) return Row{true, r.state};
    return Row{};
  };
  auto received = [&] {
    std::lock_guard lock(watch.mutex);
    return watch.received;
  };
  const std::string where = fmt::format("set '{}', {}, LCM {}", config.name, config.file.string(),
                                        comm::resolve_lcm_url(config.lcm_url));
  int code = 0;
  const std::optional<Row> before = next_row(0, deadline);
  if (!before) {
    std::fprintf(stderr,
                 "mrroc-ui: no launcher answers on '%s' (%s) within %.1f s: is the set "
                 "running?\n",
                 channels::launch_status, where.c_str(), timeout_s);
    code = kExitNoLauncher;
  } else if (!before->found) {
    std::fprintf(stderr, "mrroc-ui: RESTART: '%s' is not a process of %s\n", process.c_str(),
                 where.c_str());
    code = kExitConfig;
  } else if (before->state != "held") {
    std::fprintf(stderr,
                 "mrroc-ui: RESTART REFUSED: %s is not waiting for an acknowledgement (state "
                 "%s); only a process in state 'held' is\n",
                 process.c_str(), before->state.c_str());
    code = kExitRefused;
  } else {
    launch::LaunchCommand command;
    command.set_name = config.name;
    command.type = launch::LaunchCommandType::restart;
    command.process = process;
    comm::Envelope header;
    header.sender = comm::unique_endpoint_name("ui");
    std::optional<Row> after;
    // Sent again every 250 ms until a table shows the process released (the launcher acts on
    // the first copy that arrives and ignores the others).
    for (std::int64_t seq = 1; SteadyClock::now() < deadline; ++seq) {
      header.seq = seq;
      header.utime = now_utime();
      const std::uint64_t seen = received();
      comm::broadcast(bus, kLaunchCommandChannel, header, command);
      const auto until = std::min(deadline, SteadyClock::now() + std::chrono::milliseconds(250));
      for (std::uint64_t n = seen; (after = next_row(n, until)); n = received())
        if (after->state != "held") break;
      if (after && after->state != "held") break;
    }
    if (after && after->state != "held") {
      std::printf("mrroc-ui: RESTART of %s acknowledged: the launcher restarts it (state %s)\n",
                  process.c_str(), after->state.c_str());
    } else {
      std::fprintf(stderr,
                   "mrroc-ui: RESTART of %s not confirmed: the launcher still holds it after "
                   "%.1f s (%s)\n",
                   process.c_str(), timeout_s, where.c_str());
      code = kExitNoLauncher;
    }
  }
  tables.reset();
  return code;
}

int send_emergency_stop(const std::string& config_path, bool engage, const std::string& robot,
                        const std::string& reason) {
  const ProcessSetConfig config = load_process_set(config_path);
  if (!robot.empty()) (void)config.robot(robot);  // a typo in the robot name is an error
  comm::Bus bus(config.lcm_url);
  comm::enable_auth_from_file(bus, config.auth_key_file);
  bus.start();
  Reporter reporter(bus, "ui");
  std::vector<std::string> robots;
  for (const auto& r : config.robots) robots.push_back(r.name);
  const ui::EstopConfirmation c =
      ui::send_and_confirm_emergency_stop(bus, engage, robots, robot, reason);
  const std::string what = ui::describe_emergency_stop(engage, robot, reason) + ": " +
                           ui::describe_confirmation(engage, c);
  if (engage || !c.all())
    reporter.report(Severity::error, 10, what);
  else
    reporter.warning(what);
  if (!c.all()) {
    std::fprintf(stderr, "mrroc-ui: %s\n", what.c_str());
    return kExitUnconfirmed;
  }
  std::printf("mrroc-ui: %s\n", what.c_str());
  return 0;
}

int send_task_command(const std::string& config_path, ui::OperatorCommand command,
                      double timeout_s) {
  const ProcessSetConfig config = load_process_set(config_path);
  comm::Bus bus(config.lcm_url);
  comm::enable_auth_from_file(bus, config.auth_key_file);
  bus.start();
  comm::ClientOptions options;
  options.attempt_timeout = std::chrono::milliseconds(250);
  options.max_attempts = std::max(1, static_cast<int>(timeout_s / 0.25));
  ui::MpClient client(bus, comm::unique_endpoint_name("ui"), "MP", channels::mp_command,
                      channels::mp_reply, options);
  ui::MpStatus s;
  try {
    s = ui::send_operator_command(client, command);
  } catch (const TimeoutError&) {
    std::fprintf(stderr,
                 "mrroc-ui: no MP answers on '%s' (set '%s', %s, LCM %s) within %.1f s: is the "
                 "set running?\n",
                 channels::mp_command, config.name.c_str(), config.file.string().c_str(),
                 comm::resolve_lcm_url(config.lcm_url).c_str(), timeout_s);
    return kExitNoMp;
  }
  std::string upper = ui::to_string(command);
  for (char& c : upper) c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
  std::printf("mrroc-ui: %s %s: MP task '%s' %s, runs %d%s%s\n", upper.c_str(),
              s.accepted ? "accepted" : "REFUSED", s.task.c_str(), s.state.c_str(), s.runs,
              s.text.empty() ? "" : ": ", s.text.c_str());
  return s.accepted ? 0 : kExitRefused;
}

int serve(const std::string& config_path, const std::string& bind, int port) {
  const ProcessSetConfig config = load_process_set(config_path);
  apply_cpu_affinity(config.ui.options.cpus);
  (void)apply_priority(config.ui.options.priority);  // 0 (SCHED_OTHER) unless configured
  ui::ConsoleOptions options;
  options.bind = bind.empty() ? config.ui.bind : bind;
  options.port = port > 0 ? port : config.ui.port;
  // Without a token file the console generates its token (loopback addresses only).
  if (!config.ui.token_file.empty()) {
    options.token = ui::read_token_file(config.ui.token_file);
  } else if (!is_loopback(options.bind)) {
    throw ConfigError(SourceLocation::whole_file(config.file.string()),
                      fmt::format("--bind {} is not a loopback address: set [ui] token_file so "
                                  "that every API request must carry a token",
                                  options.bind));
  }
  ui::Console console(config, options);
  return console.run();
}

}  // namespace

int main(int argc, char** argv) {
  mrroc::CommandLine cli(
      "mrroc-ui",
      "mrroc-ui: operator commands for a running process set.\n"
      "  estop / release      engage / release the emergency stop of every robot (or one) and\n"
      "                       confirm it from every robot's state within 500 ms (exit 4: a\n"
      "                       robot did not confirm; the message names it)\n"
      "  start / pause / resume / stop / terminate / status\n"
      "                       task commands to the MP (exit 1: refused, 3: no MP answers)\n"
      "  restart PROCESS      acknowledge the restart of a process that the launcher holds\n"
      "                       for the operator (an EDP on CiA 402 drives, state 'held') and\n"
      "                       confirm it from the launcher's process table (exit 1: not held,\n"
      "                       2: no such process, 3: no launcher answers or confirms)\n"
      "  serve                the web operator console (docs/operating.md)\n"
      "A bad command line exits with 2.");
  cli.require_subcommand();
  std::string config;
  std::string robot;
  std::string reason = "operator";
  double timeout_s = 3.0;
  std::string bind;
  int port = 0;
  for (const char* name : {"estop", "release"}) {
    mrroc::CommandLine& sub =
        cli.subcommand(name, std::string(name) == "estop" ? "engage the emergency stop"
                                                          : "release the emergency stop");
    sub.option("-c,--config", config, "process-set config file (TOML)").required();
    sub.option("-r,--robot", robot, "only this robot (default: every robot)");
    sub.option("--reason", reason, "text sent to the SRP");
  }
  const std::pair<const char*, const char*> commands[] = {
      {"start", "start the MP task (the set runs with [mp] start = \"operator\")"},
      {"pause", "every ECP holds before its next macro-step"},
      {"resume", "continue after pause"},
      {"stop", "end the running task (the robots hold); start may follow"},
      {"terminate", "end the MP and so the whole set"},
      {"status", "print the MP task's state"},
  };
  for (const auto& [name, help] : commands) {
    mrroc::CommandLine& sub = cli.subcommand(name, help);
    sub.option("-c,--config", config, "process-set config file (TOML)").required();
    sub.option("--timeout", timeout_s, "wait at most this long for the MP's answer [s]")
        .range(0.25, 60.0);
  }
  std::string process;
  mrroc::CommandLine& restart_cmd = cli.subcommand(
      "restart",
      "acknowledge the restart of PROCESS (e.g. edp/irb6), an EDP on CiA 402 drives that ended "
      "and that the launcher holds until an operator agrees (state 'held' in 'mrroc-launch "
      "status'); the launcher then restarts it after its back-off, within max_restarts");
  restart_cmd.option("process", process, "the held process, e.g. edp/irb6").required();
  restart_cmd.option("-c,--config", config, "process-set config file (TOML)").required();
  restart_cmd.option("--timeout", timeout_s, "wait at most this long for the launcher's table [s]")
      .range(0.25, 60.0);
  mrroc::CommandLine& serve_cmd =
      cli.subcommand("serve",
                     "web operator console on [ui] bind:port (default 127.0.0.1:8080); every API "
                     "request needs the token of [ui] token_file or, without one, the token "
                     "generated at start (written to <[launch] log_dir, or the current "
                     "folder>/ui-<port>.token, mode 0600, until the console ends, and printed "
                     "with the URL only when standard output is a terminal) in its header "
                     "'Authorization: Bearer TOKEN'; SIGINT or SIGTERM stops it");
  serve_cmd.option("-c,--config", config, "process-set config file (TOML)").required();
  serve_cmd.option("--bind", bind, "listen on this address (default: [ui] bind)");
  serve_cmd.option("--port", port, "listen on this TCP port (default: [ui] port)").range(1, 65535);
  if (const auto exit_code = cli.parse(argc, argv)) return *exit_code;
  try {
    if (cli.got("estop") || cli.got("release"))
      return send_emergency_stop(config, cli.got("estop"), robot, reason);
    if (cli.got("restart")) return acknowledge_restart(config, process, timeout_s);
    if (cli.got("serve")) {
      install_stop_handlers();
      return serve(config, bind, port);
    }
    for (const auto& [name, help] : commands)
      if (cli.got(name))
        return send_task_command(config, *ui::operator_command_from_string(name), timeout_s);
    return kExitConfig;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "mrroc-ui: %s\n", e.what());
    return kExitConfig;
  }
}
