// mrroc-mp: the Master Process. Runs the MP part of the task, coordinating the robots' ECPs.
#include <CLI/CLI.hpp>
#include <fmt/format.h>

#include <cstdio>
#include <atomic>
#include <chrono>
#include <memory>
#include <thread>

#include "mrroc/comm/links.hpp"
#include "mrroc/config/process_set.hpp"
#include "mrroc/core/plugin_library.hpp"
#include "mrroc/core/process.hpp"
#include "mrroc/core/reporter.hpp"
#include "mrroc/mp/task.hpp"

namespace {

using namespace mrroc;

int run(const std::string& config_path) {
  const ProcessSetConfig config = load_process_set(config_path);
  apply_cpu_affinity(config.mp.options.cpus);
  comm::Bus bus(config.lcm_url);
  bus.start();
  Reporter reporter(bus, "mp");
  try {
    std::vector<std::unique_ptr<mp::Robot>> robots;
    mp::TaskContext context{{}, reporter, config.mp.args, config, &bus};
    for (const auto& robot : config.robots) {
      robots.push_back(std::make_unique<mp::Robot>(bus, robot.name));
      context.robots.push_back(robots.back().get());
    }
    if (!config.mp.library.empty()) load_plugin_library(config.mp.library, config.mp.where);
    std::unique_ptr<mp::MpTask> task;
    try {
      task = mp::make_mp_task(config.mp.name, context);
    } catch (const ConfigError& e) {
      const std::string text = e.what();
      if (text.find(": error: ") != std::string::npos) throw;
      throw ConfigError(fmt::format("{}: error: {}", config.mp.where.str(), text));
    }
    reporter.set_state(ProcessState::ready);
    reporter.info(fmt::format("task '{}' started with {} robot(s)", config.mp.name,
                              config.robots.size()));
    reporter.set_state(ProcessState::running);
    std::atomic<bool> done{false};
    std::string failure;
    std::thread task_thread([&] {
      try {
        task->main_task();
      } catch (const std::exception& e) {
        failure = e.what();
      }
      done = true;
    });
    bool stop_sent = false;
    while (!done) {
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
      if (stop_requested() && !stop_sent) {
        // Operator stop: ask every ECP to stop its task; their START_TASK replies then end the task.
        stop_sent = true;
        reporter.warning("stop requested: sending STOP to every ECP");
        for (mp::Robot* robot : context.robots) {
          try {
            robot->stop();
          } catch (const std::exception& e) {
            reporter.warning(fmt::format("STOP to ecp/{}: {}", robot->name(), e.what()));
          }
        }
      }
    }
    task_thread.join();
    if (!failure.empty()) throw Error(failure);
    if (stop_sent) throw Error("task stopped on request");
    reporter.info(fmt::format("task '{}' finished", config.mp.name));
    reporter.set_state(ProcessState::finished);
    return 0;
  } catch (const std::exception& e) {
    reporter.report(Severity::fatal, 0, e.what());
    reporter.set_state(ProcessState::failed, e.what());
    return 1;
  }
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{
      "mrroc-mp: Master Process. Runs the MP task named in the config and coordinates the ECPs; "
      "exits 0 when the task finished, 1 when it failed, 2 on a config error. Normally started "
      "by mrroc-launch."};
  std::string config;
  app.add_option("-c,--config", config, "process-set config file (TOML)")->required();
  CLI11_PARSE(app, argc, argv);
  mrroc::install_stop_handlers();
  try {
    return run(config);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "mrroc-mp: %s\n", e.what());
    return 2;
  }
}
