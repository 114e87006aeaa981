// mrroc-srp: the System Response Process. Shows every process' messages and status changes,
// keeps them in a rotated JSON-lines log and in a numbered history served to the operator
// console, and watches the servo-loop timing of every robot.
#include <fmt/format.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <map>
#include <memory>
#include <mutex>
#include <thread>
#include <vector>

#include "history.hpp"
#include "log_file.hpp"
#include "mrroc/comm/auth.hpp"
#include "mrroc/comm/bus.hpp"
#include "mrroc/comm/edge.hpp"
#include "mrroc/comm/links.hpp"
#include "mrroc/comm/reporter.hpp"
#include "mrroc/comm/request_reply.hpp"
#include "mrroc/config/process_set.hpp"
#include "mrroc/core/command_line.hpp"
#include "mrroc/core/process.hpp"
#include "mrroc/core/time.hpp"
#include "servo_timing.hpp"

namespace {

using namespace mrroc;

constexpr auto kTimingInterval = std::chrono::seconds(10);

const char* colour_of(Severity s) {
  switch (s) {
    case Severity::debug: return "\033[2m";
    case Severity::info: return "";
    case Severity::warning: return "\033[33m";
    case Severity::error: return "\033[31m";
    case Severity::fatal: return "\033[1;31m";
  }
  return "";
}

/// "ui[irb6]" when the robot is not already part of the process name ("ecp/irb6").
std::string process_label(const SrpMessage& m) {
  if (m.robot.empty()) return m.process;
  const std::string suffix = "/" + m.robot;
  if (m.process.size() >= suffix.size() &&
      m.process.compare(m.process.size() - suffix.size(), suffix.size(), suffix) == 0)
    return m.process;
  return fmt::format("{}[{}]", m.process, m.robot);
}

struct Console {
  bool colour = false;
  void print(const std::string& line, const char* code = "") const {
    if (colour && *code != '\0')
      std::fputs(fmt::format("{}{}\033[0m\n", code, line).c_str(), stdout);
    else
      std::fputs((line + '\n').c_str(), stdout);
    std::fflush(stdout);
  }
};

/// Everything the bus-thread callbacks share, under one mutex.
struct Srp {
  std::mutex mutex;
  Console console;
  srp::History history;
  std::vector<std::unique_ptr<srp::RotatingLog>> logs;
  bool log_failed = false;
  std::map<std::string, std::uint64_t> counts;
  std::map<std::string, ProcessState> states;
  srp::ServoTiming timing;
  std::uint64_t history_requests = 0;

  explicit Srp(std::size_t history_size) : history(history_size) {}

  // Caller holds the mutex.
  void record(const SrpMessage& m, bool status) {
    const srp::Entry& e = history.add(m, status);
    if (!logs.empty()) {
      const std::string line = srp::json_line(e);
      for (auto& log : logs) {
        try {
          log->write(line);
        } catch (const std::exception& ex) {
          if (!log_failed)
            std::fprintf(stderr, "mrroc-srp: log '%s': %s\n", log->path().c_str(), ex.what());
          log_failed = true;
        }
      }
    }
  }
};

void on_robot_state(Srp& srp, const std::string& robot, const RobotState& state) {
  // A state with figures that are not numbers would spoil every statistic after it.
  if (!std::isfinite(state.servo_period_s) || !std::isfinite(state.lateness_mean_us) ||
      !std::isfinite(state.lateness_max_us))
    return;
  srp::TimingSample sample;
  sample.servo_step = state.servo_step;
  sample.servo_period_s = state.servo_period_s;
  sample.lateness_mean_us = state.lateness_mean_us;
  sample.lateness_max_us = state.lateness_max_us;
  sample.overruns = state.overruns;
  std::lock_guard lock(srp.mutex);
  srp.timing.add(robot, sample);
}

SrpHistoryReply history_reply(const srp::History& history, const SrpHistoryRequest& request) {
  const srp::HistoryQuery query = srp::clamp_query(request.after, request.max_count,
                                                   static_cast<std::int8_t>(request.min_severity));
  const std::vector<srp::Entry> entries = history.select(query);
  SrpHistoryReply reply;
  reply.last = history.last();
  reply.entries.reserve(entries.size());
  for (const srp::Entry& e : entries) reply.entries.push_back({e.number, e.message});
  return reply;
}

void print_timing(Srp& srp, const std::map<std::string, srp::TimingSummary>& window,
                  const std::string& prefix) {
  for (const auto& [robot, summary] : window)
    srp.console.print(fmt::format("{}{}: {}", prefix, robot, srp::describe(summary)));
}

struct Options {
  std::string config;
  std::string log;
  std::string colour = "auto";
};

int run(const Options& options) {
  const ProcessSetConfig config = load_process_set(options.config);
  apply_cpu_affinity(config.srp.options.cpus);
  (void)apply_priority(config.srp.options.priority);  // 0 (SCHED_OTHER) unless configured
  Srp srp(static_cast<std::size_t>(config.srp.history));
  srp.console.colour =
      options.colour == "always" || (options.colour == "auto" && isatty(STDOUT_FILENO) == 1);

  // The [srp] log and --log; the same file named twice is written once.
  std::vector<std::filesystem::path> log_paths;
  if (!config.srp.log.empty()) log_paths.push_back(config.srp.log);
  if (!options.log.empty()) {
    const std::filesystem::path extra = std::filesystem::absolute(options.log);
    if (log_paths.empty() ||
        std::filesystem::weakly_canonical(extra) != std::filesystem::weakly_canonical(log_paths[0]))
      log_paths.push_back(extra);
  }
  const auto max_bytes = static_cast<std::uintmax_t>(config.srp.log_max_kb * 1024.0);
  for (const auto& path : log_paths)
    srp.logs.push_back(std::make_unique<srp::RotatingLog>(path, max_bytes, config.srp.log_keep));

  comm::Bus bus(config.lcm_url);
  comm::enable_auth_from_file(bus, config.auth_key_file);
  SystemListener listener(
      bus,
      [&](const SrpMessage& m) {
        std::lock_guard lock(srp.mutex);
        ++srp.counts[m.process];
        srp.record(m, false);
        srp.console.print(fmt::format("{} {:<10} {:<7} {}{}", format_utime(m.utime),
                                      process_label(m), to_string(m.severity),
                                      m.code != 0 ? fmt::format("[{}] ", m.code) : "", m.text),
                          colour_of(m.severity));
      },
      [&](const ProcessStatus& s) {
        std::lock_guard lock(srp.mutex);
        auto it = srp.states.find(s.process);
        if (it != srp.states.end() && it->second == s.state) return;
        srp.states[s.process] = s.state;
        srp.record(srp::status_as_message(s), true);
        srp.console.print(
            fmt::format("{} {:<10} status  {} (pid {}){}", format_utime(s.utime), s.process,
                        to_string(s.state), s.pid, s.detail.empty() ? "" : ": " + s.detail),
            s.state == ProcessState::failed ? "\033[31m" : "\033[36m");
      });
  comm::SrpHistoryServer history_server(bus, comm::unique_endpoint_name("srp"),
                                        channels::srp_history_command, channels::srp_history_reply,
                                        [&](comm::SrpHistoryServer::Incoming in) {
                                          // A request that does not validate (an unknown severity)
                                          // gets the newest number only.
                                          SrpHistoryReply reply;
                                          {
                                            std::lock_guard lock(srp.mutex);
                                            ++srp.history_requests;
                                            if (in.request)
                                              reply = history_reply(srp.history, *in.request);
                                            else
                                              reply.last = srp.history.last();
                                          }
                                          in.responder.reply(reply);
                                        });
  std::vector<comm::Subscriber<RobotState>> state_subscribers;
  for (const RobotConfig& robot : config.robots)
    state_subscribers.emplace_back(
        bus, channels::robot_state(robot.name),
        [&srp, name = robot.name](const RobotState& state, const comm::Received&) {
          on_robot_state(srp, name, state);
        },
        comm::SubscriberOptions::unreported());
  bus.start();
  Reporter reporter(bus, "srp");
  reporter.set_state(ProcessState::ready);
  auto next_timing = std::chrono::steady_clock::now() + kTimingInterval;
  while (!stop_requested()) {
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
    if (std::chrono::steady_clock::now() < next_timing) continue;
    next_timing += kTimingInterval;
    std::lock_guard lock(srp.mutex);
    print_timing(srp, srp.timing.take_window(),
                 fmt::format("{} {:<10} timing  ", format_utime(now_utime()), "srp"));
  }
  reporter.set_state(ProcessState::stopping);
  std::this_thread::sleep_for(std::chrono::milliseconds(100));  // late messages of the others
  bus.stop();
  state_subscribers.clear();

  std::lock_guard lock(srp.mutex);
  std::string summary;
  std::uint64_t total = 0;
  for (const auto& [process, n] : srp.counts) {
    summary += fmt::format("{}{} ({})", summary.empty() ? "" : ", ", process, n);
    total += n;
  }
  srp.console.print(fmt::format("srp summary: {} messages from {} processes: {}", total,
                                srp.counts.size(), summary.empty() ? "none" : summary));
  const auto timing = srp.timing.total();
  for (const RobotConfig& robot : config.robots) {
    const auto it = timing.find(robot.name);
    srp.console.print(
        fmt::format("srp summary: timing {}: {}", robot.name,
                    it == timing.end() ? "no robot state received" : srp::describe(it->second)));
  }
  srp.console.print(
      fmt::format("srp summary: history holds entries {}..{}, {} requests served",
                  srp.history.last() - static_cast<std::int64_t>(srp.history.size()) + 1,
                  srp.history.last(), srp.history_requests));
  for (const auto& log : srp.logs)
    srp.console.print(
        fmt::format("srp summary: log {} ({} rotations)", log->path().string(), log->rotations()));
  if (listener.malformed() > 0)
    srp.console.print(
        fmt::format("srp summary: {} malformed messages dropped", listener.malformed()));
  return 0;
}

constexpr const char* kDescription =
    "mrroc-srp: the System Response Process of a process set.\n"
    "\n"
    "Console: one line per SRP message (time, process, severity, [code] when not 0, text; the\n"
    "robot is shown as process[robot] when the process name does not already hold it) and per\n"
    "status change of a process. Colours by severity (debug dim, warning yellow, error red, fatal\n"
    "bold red, status changes cyan) with --color=always, or with auto when stdout is a terminal.\n"
    "\n"
    "Log: the [srp] log of the config and --log each get one JSON object per line: n, kind\n"
    "(message|status), time (ISO 8601, UTC), utime (us since the epoch), process, robot,\n"
    "severity, code, text. A file is rotated before it grows beyond [srp] log_max_kb: FILE.1 is\n"
    "the newest old file, up to [srp] log_keep of them; no line is split or lost.\n"
    "\n"
    "History: the last [srp] history entries (messages and status changes), numbered from 1,\n"
    "served on mrroc/srp/history/cmd (srp_history_request_t -> srp_history_reply_t): entries\n"
    "numbered above `after` with severity >= min_severity, at most max_count (clamped to\n"
    "1..500), the newest of them; a reply stays below 60000 bytes.\n"
    "\n"
    "Timing: robot_state_t of every robot of the config (<robot>/edp/state); every 10 s and at\n"
    "exit one line per robot: servo period, mean and max wake-up lateness, overruns.\n"
    "\n"
    "On exit (SIGINT, SIGTERM): a summary of messages per process, timing, history and logs.";

}  // namespace

int main(int argc, char** argv) {
  mrroc::CommandLine cli("mrroc-srp", kDescription);
  Options options;
  cli.option("-c,--config", options.config, "process-set config file (TOML)").required();
  cli.option("--log", options.log,
             "also write the JSON-lines log to this file (rotated as the [srp] log)");
  cli.option("--color", options.colour, "severity colours on the console: auto, always, never")
      .one_of({"auto", "always", "never"})
      .show_default();
  if (const auto exit_code = cli.parse(argc, argv)) return *exit_code;
  mrroc::install_stop_handlers();
  try {
    return run(options);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "mrroc-srp: %s\n", e.what());
    return 2;
  }
}
