// mrroc-launch: starts a process set from one config file (SRP, EDPs, ECPs, then MP), waits for
// each process to report ready, prefixes their output with their names, and exits with the task's
// outcome. SIGINT/SIGTERM stop everything in reverse order.
#include <CLI/CLI.hpp>
#include <fmt/format.h>
#include <unistd.h>

#include <chrono>
#include <condition_variable>
#include <csignal>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <map>
#include <mutex>

#include "mrroc/comm/bus.hpp"
#include "mrroc/config/process_set.hpp"
#include "mrroc/core/reporter.hpp"
#include "supervisor.hpp"

namespace {

using namespace mrroc;
namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

/// Exit codes of mrroc-launch (also in docs/getting-started.md).
constexpr int kExitConfig = 2;        // the config is wrong: nothing was started
constexpr int kExitStartFailed = 3;   // a process failed to start or to become ready
constexpr int kExitProcessDied = 4;   // a process other than the MP ended while the task ran
constexpr int kExitTaskFailed = 1;    // the MP reported that the task failed
constexpr int kExitInternal = 5;      // the launcher itself failed (e.g. LCM would not open)

struct Stage {
  std::string name;  // process name, as in its status messages
  launch::ChildSpec spec;
};

fs::path own_directory() {
  std::error_code ec;
  fs::path exe = fs::read_symlink("/proc/self/exe", ec);
  return ec ? fs::current_path() : exe.parent_path();
}

launch::ChildSpec child(const std::string& name, std::vector<std::string> argv, double grace_s) {
  launch::ChildSpec spec;
  spec.name = name;
  spec.argv = std::move(argv);
  spec.stop_grace = std::chrono::milliseconds(static_cast<long>(grace_s * 1000.0));
  return spec;
}

std::vector<Stage> plan(const ProcessSetConfig& config, const fs::path& bin_dir,
                        const std::string& srp_log) {
  const std::string cfg = config.file.string();
  auto exe = [&](const char* name) { return (bin_dir / name).string(); };
  std::vector<Stage> stages;
  std::vector<std::string> srp_argv{exe("mrroc-srp"), "--config", cfg};
  if (!srp_log.empty()) {
    srp_argv.push_back("--log");
    srp_argv.push_back(srp_log);
  }
  stages.push_back({"srp", child("srp", srp_argv, config.srp.options.stop_grace_s)});
  if (config.emulator)
    stages.push_back({"emu", child("emu", {exe("mrroc-axis-emu"), "--config", cfg},
                                   config.emulator->options.stop_grace_s)});
  for (const auto& v : config.vsps)
    stages.push_back({"vsp/" + v.name, child("vsp/" + v.name,
                                             {exe("mrroc-vsp"), "--config", cfg, "--vsp", v.name},
                                             v.options.stop_grace_s)});
  for (const auto& r : config.robots)
    stages.push_back({"edp/" + r.name, child("edp/" + r.name,
                                             {exe("mrroc-edp"), "--config", cfg, "--robot", r.name},
                                             r.edp.options.stop_grace_s)});
  for (const auto& r : config.robots)
    stages.push_back({"ecp/" + r.name, child("ecp/" + r.name,
                                             {exe("mrroc-ecp"), "--config", cfg, "--robot", r.name},
                                             r.ecp.options.stop_grace_s)});
  stages.push_back({"mp", child("mp", {exe("mrroc-mp"), "--config", cfg},
                                config.mp.options.stop_grace_s)});
  if (!config.lcm_url.empty())
    for (auto& s : stages) s.spec.env.push_back("LCM_DEFAULT_URL=" + config.lcm_url);
  return stages;
}

class ReadyWatch {
 public:
  void on_status(const ProcessStatus& s) {
    std::lock_guard lock(mutex_);
    states_[s.process] = s.state;
    cv_.notify_all();
  }
  /// Waits until `process` reported ready (or any later state). Returns its state or nothing.
  std::optional<ProcessState> wait(const std::string& process, Clock::time_point until,
                                   const std::function<bool()>& abort) {
    std::unique_lock lock(mutex_);
    while (Clock::now() < until) {
      auto it = states_.find(process);
      if (it != states_.end() && it->second != ProcessState::starting) return it->second;
      if (abort()) return std::nullopt;
      cv_.wait_for(lock, std::chrono::milliseconds(20));
    }
    return std::nullopt;
  }

 private:
  std::mutex mutex_;
  std::condition_variable cv_;
  std::map<std::string, ProcessState> states_;
};

int describe_exit(const launch::ChildExit& e) {
  return e.signal != 0 ? 128 + e.signal : e.exit_code;
}

int run(const std::string& config_path, bool check_only, const std::string& bin_dir_option,
        const std::string& srp_log) {
  ProcessSetConfig config;
  try {
    config = load_process_set(config_path);
  } catch (const ConfigError& e) {
    std::fprintf(stderr, "%s\nmrroc-launch: nothing started\n", e.what());
    return kExitConfig;
  }
  const fs::path bin_dir = bin_dir_option.empty() ? own_directory() : fs::path(bin_dir_option);
  const std::vector<Stage> stages = plan(config, bin_dir, srp_log);
  for (const auto& s : stages)
    if (!fs::exists(s.spec.argv[0])) {
      std::fprintf(stderr, "mrroc-launch: executable '%s' not found (use --bin-dir)\n",
                   s.spec.argv[0].c_str());
      return kExitConfig;
    }

  std::cout << fmt::format("mrroc-launch: process set '{}' from {} ({} robot(s), LCM {})\n",
                           config.name, config.file.string(), config.robots.size(),
                           comm::resolve_lcm_url(config.lcm_url));
  for (std::size_t i = 0; i < stages.size(); ++i)
    std::cout << fmt::format("  {}. {:<12} {}\n", i + 1, stages[i].name,
                             fmt::join(stages[i].spec.argv, " "));
  std::cout.flush();
  if (check_only) {
    std::cout << "mrroc-launch: config is valid (--check: nothing started)\n";
    return 0;
  }

  launch::install_stop_signal_handlers();
  if (!config.lcm_url.empty()) ::setenv("LCM_DEFAULT_URL", config.lcm_url.c_str(), 1);
  comm::Bus bus(config.lcm_url);
  ReadyWatch ready;
  SystemListener listener(bus, {}, [&](const ProcessStatus& s) { ready.on_status(s); });
  bus.start();

  launch::Supervisor supervisor(std::cout);
  std::size_t width = 0;
  for (const auto& s : stages) width = std::max(width, s.name.size());
  supervisor.reserve_name_width(width);
  const auto t0 = Clock::now();
  auto since = [&] {
    return std::chrono::duration_cast<std::chrono::milliseconds>(Clock::now() - t0).count();
  };

  int outcome = 0;
  bool started_all = true;
  for (const auto& stage : stages) {
    pid_t pid = 0;
    try {
      pid = supervisor.start(stage.spec);
    } catch (const std::exception& e) {
      supervisor.log(fmt::format("mrroc-launch: cannot start {}: {}", stage.name, e.what()));
      outcome = kExitStartFailed;
      started_all = false;
      break;
    }
    supervisor.log(fmt::format("mrroc-launch: started {} (pid {})", stage.name, pid));
    const auto deadline =
        Clock::now() + std::chrono::milliseconds(static_cast<long>(config.ready_timeout_s * 1e3));
    const auto state = ready.wait(stage.name, deadline, [&] {
      return supervisor.stop_requested() || !supervisor.is_running(stage.spec.name);
    });
    if (supervisor.stop_requested()) {
      outcome = 128 + launch::stop_signal();
      started_all = false;
      break;
    }
    if (!state || *state == ProcessState::failed) {
      supervisor.log(fmt::format(
          "mrroc-launch: {} {}", stage.name,
          !supervisor.is_running(stage.spec.name) ? "ended before it was ready"
          : state                                 ? "failed while starting"
                                                  : fmt::format("was not ready within {:.1f} s",
                                                                config.ready_timeout_s)));
      outcome = kExitStartFailed;
      started_all = false;
      break;
    }
    supervisor.log(fmt::format("mrroc-launch: {} ready at {} ms", stage.name, since()));
  }

  if (started_all) {
    supervisor.log(fmt::format("mrroc-launch: all {} processes ready in {} ms; task running",
                               stages.size(), since()));
    bool done = false;
    while (!done) {
      for (const auto& e : supervisor.wait_events(std::chrono::milliseconds(200))) {
        if (e.name == "mp") {
          const int mp_code = describe_exit(e);
          outcome = mp_code == 0 ? 0 : kExitTaskFailed;
          supervisor.log(fmt::format("mrroc-launch: task {} (mp exit code {}) after {} ms",
                                     outcome == 0 ? "finished" : "FAILED", mp_code, since()));
          done = true;
        } else if (!done) {
          supervisor.log(fmt::format("mrroc-launch: {} ended while the task was running "
                                     "(code {}): stopping the set",
                                     e.name, describe_exit(e)));
          outcome = kExitProcessDied;
          done = true;
        }
      }
      if (!done && supervisor.stop_requested()) {
        supervisor.log("mrroc-launch: stop requested: stopping the set");
        outcome = 128 + launch::stop_signal();
        done = true;
      }
    }
  }
  supervisor.stop_all();
  bus.stop();
  supervisor.log(fmt::format("mrroc-launch: all processes stopped; exit code {}", outcome));
  return outcome;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{
      "mrroc-launch: starts a process set (SRP, EDPs, ECPs, then MP) from one config file, waits "
      "for each process to be ready, prefixes each process' output with its name, and exits "
      "with the task's outcome: 0 task finished, 1 task failed, 2 config error (nothing "
      "started), 3 a process failed to start, 4 a process died during the task, 5 the launcher "
      "itself failed, 128+N stopped by signal N. SIGINT/SIGTERM stop every process in reverse order (SIGTERM, then SIGKILL "
      "after its grace period)."};
  std::string config;
  std::string bin_dir;
  std::string srp_log;
  bool check = false;
  app.add_option("config", config, "process-set config file (TOML)")->required();
  app.add_flag("--check", check, "validate the config and print the plan; start nothing");
  app.add_option("--bin-dir", bin_dir,
                 "where the mrroc-* executables are (default: beside mrroc-launch)");
  app.add_option("--srp-log", srp_log, "file the SRP appends every message to");
  CLI11_PARSE(app, argc, argv);
  std::signal(SIGPIPE, SIG_IGN);  // a closed stdout must not kill the launcher before its children
  try {
    return run(config, check, bin_dir, srp_log);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "mrroc-launch: %s\n", e.what());
    return kExitInternal;
  }
}
