// mrroc-ecp: the Effector Control Process of one robot. Runs the robot's task on START_TASK.
#include <fmt/format.h>

#include <chrono>
#include <cstdio>
#include <optional>
#include <thread>

#include "mrroc/comm/auth.hpp"
#include "mrroc/comm/reporter.hpp"
#include "mrroc/config/process_set.hpp"
#include "mrroc/core/command_line.hpp"
#include "mrroc/core/plugin_library.hpp"
#include "mrroc/core/process.hpp"
#include "shell.hpp"

namespace {

using namespace mrroc;

int run(const std::string& config_path, const std::string& robot_name) {
  const ProcessSetConfig config = load_process_set(config_path);
  const RobotConfig& robot_config = config.robot(robot_name);
  apply_cpu_affinity(robot_config.ecp.options.cpus);
  const std::string scheduling = apply_priority(robot_config.ecp.options.priority);
  comm::Bus bus(config.lcm_url);
  comm::enable_auth_from_file(bus, config.auth_key_file);
  bus.start();
  Reporter reporter(bus, "ecp/" + robot_config.name, robot_config.name);
  try {
    if (!robot_config.ecp.library.empty())
      load_plugin_library(robot_config.ecp.library, robot_config.ecp.where);
    ecp::EcpShell shell(bus, robot_config, reporter);
    shell.run(scheduling);
    reporter.set_state(ProcessState::finished);
  } catch (const std::exception& e) {
    reporter.report(Severity::fatal, 0, e.what());
    reporter.set_state(ProcessState::failed, e.what());
    return 1;
  }
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  mrroc::CommandLine cli(
      "mrroc-ecp",
      "mrroc-ecp: Effector Control Process. Runs the robot's task (generators, Move, Wait) on "
      "the MP's START_TASK and drives the robot's EDP. Normally started by mrroc-launch.");
  std::string config;
  std::string robot;
  cli.option("-c,--config", config, "process-set config file (TOML)").required();
  cli.option("-r,--robot", robot, "name of the robot ([[robot]] name in the config)").required();
  if (const auto exit_code = cli.parse(argc, argv)) return *exit_code;
  mrroc::install_stop_handlers();
  try {
    return run(config, robot);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "mrroc-ecp: %s\n", e.what());
    return 2;
  }
}
