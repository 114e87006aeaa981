// mrroc-ecp: the Effector Control Process of one robot. Runs the robot's task on START_TASK.
#include <fmt/format.h>

#include <chrono>
#include <cstdio>
#include <optional>
#include <thread>

#include "mrroc/comm/auth.hpp"
#include "mrroc/comm/reporter.hpp"
#include "mrroc/config/check.hpp"
#include "mrroc/config/process_set.hpp"
#include "mrroc/core/command_line.hpp"
#include "mrroc/core/plugin_library.hpp"
#include "mrroc/core/process.hpp"
#include "shell.hpp"

namespace {

using namespace mrroc;

/// What the ECP builds before it reports ready, at start and for --check-config: the task
/// library, the robot model, the robot's image and the task, built once (every error found).
std::unique_ptr<ecp::EcpShell> prepare(comm::Bus& bus, const ProcessSetConfig& config,
                                       const RobotConfig& robot_config, Reporter& reporter) {
  if (!robot_config.ecp.library.empty())
    load_plugin_library(robot_config.ecp.library, robot_config.ecp.where);
  std::vector<std::string> vsps;
  for (const VspConfig& vsp : config.vsps) vsps.push_back(vsp.name);
  return std::make_unique<ecp::EcpShell>(bus, robot_config, reporter, std::move(vsps));
}

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
    const std::unique_ptr<ecp::EcpShell> shell = prepare(bus, config, robot_config, reporter);
    shell->run(scheduling);
    reporter.set_state(ProcessState::finished);
  } catch (const std::exception& e) {
    ConfigErrorList errors;
    errors.add(e, {});
    for (const auto& error : errors.errors()) reporter.report(Severity::fatal, 0, error.what());
    reporter.set_state(ProcessState::failed, errors.errors().front().what());
    return 1;
  }
  return 0;
}

/// --check-config: the process set's errors and this ECP's (prepare), one per line on stderr,
/// nothing started and nothing sent beyond the process (kCheckLcmUrl).
int check(const std::string& config_path, const std::string& robot_name) {
  const ProcessSetCheck set = check_process_set(config_path);
  ConfigErrorList errors;
  errors.add(set.errors);
  if (!set.broken_process("ecp/" + robot_name)) {
    errors.run(SourceLocation::whole_file(set.config.file.string()), [&] {
      const RobotConfig& robot_config = set.config.robot(robot_name);
      comm::Bus bus(kCheckLcmUrl);
      Reporter reporter(bus, "ecp/" + robot_config.name, robot_config.name);
      (void)prepare(bus, set.config, robot_config, reporter);
    });
  }
  for (const auto& error : errors.errors()) std::fprintf(stderr, "%s\n", error.what());
  if (!errors.empty()) return kExitConfigErrors;
  std::printf("mrroc-ecp: ecp/%s: config is valid\n", robot_name.c_str());
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
  bool check_config = false;
  cli.option("-c,--config", config, "process-set config file (TOML)").required();
  cli.option("-r,--robot", robot, "name of the robot ([[robot]] name in the config)").required();
  cli.flag("--check-config", check_config,
           "check the config as the ECP does at start (task library, robot model, task name and "
           "every argument, poses against the limits), print every error as file:line and exit "
           "(0 valid, 2 errors); nothing is started and nothing is sent (mrroc-launch --check "
           "runs it)");
  if (const auto exit_code = cli.parse(argc, argv)) return *exit_code;
  mrroc::install_stop_handlers();
  try {
    if (check_config) return check(config, robot);
    return run(config, robot);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "mrroc-ecp: %s\n", e.what());
    return 2;
  }
}
