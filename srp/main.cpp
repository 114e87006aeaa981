// mrroc-srp: the System Response Process. Shows every process' messages and status changes.
#include <CLI/CLI.hpp>
#include <fmt/format.h>

#include <chrono>
#include <cstdio>
#include <fstream>
#include <map>
#include <mutex>
#include <thread>

#include "mrroc/comm/bus.hpp"
#include "mrroc/config/process_set.hpp"
#include "mrroc/core/process.hpp"
#include "mrroc/core/reporter.hpp"
#include "mrroc/core/time.hpp"

namespace {

using namespace mrroc;

int run(const std::string& config_path, const std::string& log_path) {
  const ProcessSetConfig config = load_process_set(config_path);
  apply_cpu_affinity(config.srp.options.cpus);
  comm::Bus bus(config.lcm_url);
  std::mutex mutex;
  std::map<std::string, std::uint64_t> counts;
  std::map<std::string, ProcessState> states;
  std::ofstream log;
  if (!log_path.empty()) {
    log.open(log_path, std::ios::app);
    if (!log) throw Error(fmt::format("cannot open SRP log file '{}'", log_path));
  }
  auto emit = [&](const std::string& line) {
    std::fputs(line.c_str(), stdout);
    std::fputc('\n', stdout);
    std::fflush(stdout);
    if (log) log << line << '\n' << std::flush;
  };
  SystemListener listener(
      bus,
      [&](const SrpMessage& m) {
        std::lock_guard lock(mutex);
        ++counts[m.process];
        emit(fmt::format("{} {:<10} {:<7} {}{}", format_utime(m.utime), m.process,
                         to_string(m.severity), m.code != 0 ? fmt::format("[{}] ", m.code) : "",
                         m.text));
      },
      [&](const ProcessStatus& s) {
        std::lock_guard lock(mutex);
        auto it = states.find(s.process);
        if (it != states.end() && it->second == s.state) return;
        states[s.process] = s.state;
        emit(fmt::format("{} {:<10} status  {} (pid {}){}", format_utime(s.utime), s.process,
                         to_string(s.state), s.pid, s.detail.empty() ? "" : ": " + s.detail));
      });
  bus.start();
  Reporter reporter(bus, "srp");
  reporter.set_state(ProcessState::ready);
  while (!stop_requested()) std::this_thread::sleep_for(std::chrono::milliseconds(50));
  reporter.set_state(ProcessState::stopping);
  std::this_thread::sleep_for(std::chrono::milliseconds(100));  // late messages of the others
  bus.stop();
  std::string summary;
  std::uint64_t total = 0;
  for (const auto& [process, n] : counts) {
    summary += fmt::format("{}{} ({})", summary.empty() ? "" : ", ", process, n);
    total += n;
  }
  emit(fmt::format("srp summary: {} messages from {} processes: {}", total, counts.size(),
                   summary.empty() ? "none" : summary));
  if (listener.malformed() > 0)
    emit(fmt::format("srp summary: {} malformed messages dropped", listener.malformed()));
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{
      "mrroc-srp: System Response Process. Prints every process' messages (time, process, "
      "severity, code, text) and status changes; on exit prints a summary per process."};
  std::string config;
  std::string log;
  app.add_option("-c,--config", config, "process-set config file (TOML)")->required();
  app.add_option("--log", log, "also append every line to this file");
  CLI11_PARSE(app, argc, argv);
  mrroc::install_stop_handlers();
  try {
    return run(config, log);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "mrroc-srp: %s\n", e.what());
    return 2;
  }
}
