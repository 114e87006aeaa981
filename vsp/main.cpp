// mrroc-vsp: a Virtual Sensor Process. Aggregates the raw samples of its sources (raw sensor
// devices on mrroc/raw/<device>) into readings with a sensor plugin, and serves them to ECPs and
// the MP: CONFIGURE, INITIATE_READING, GET_READING, TERMINATE on vsp/<name>/cmd (docs/sensors.md).
#include <fmt/format.h>

#include <cstdio>

#include "mrroc/comm/auth.hpp"
#include "mrroc/comm/bus.hpp"
#include "mrroc/comm/reporter.hpp"
#include "mrroc/config/process_set.hpp"
#include "mrroc/core/command_line.hpp"
#include "mrroc/core/error.hpp"
#include "mrroc/core/plugin_library.hpp"
#include "mrroc/core/process.hpp"
#include "shell.hpp"

int main(int argc, char** argv) {
  mrroc::CommandLine cli(
      "mrroc-vsp",
      "mrroc-vsp: Virtual Sensor Process. Turns raw sensor samples into readings with a sensor "
      "plugin (force_torque, range, conveyor, object_pose, or one from a library) and serves "
      "CONFIGURE, INITIATE_READING, GET_READING, TERMINATE. See docs/sensors.md.");
  std::string config_path;
  std::string name;
  cli.option("-c,--config", config_path, "process-set config file (TOML)").required();
  cli.option("--vsp", name, "name of the [[vsp]] to run").required();
  if (const auto exit_code = cli.parse(argc, argv)) return *exit_code;

  using namespace mrroc;
  install_stop_handlers();
  ProcessSetConfig config;
  const VspConfig* vsp = nullptr;
  try {
    config = load_process_set(config_path);
    vsp = &config.vsp(name);
  } catch (const Error& e) {
    std::fprintf(stderr, "mrroc-vsp: %s\n", e.what());
    return 2;
  }
  const std::string process = "vsp/" + vsp->name;
  try {
    apply_cpu_affinity(vsp->options.cpus);
    const std::string scheduling = apply_priority(vsp->options.priority);
    comm::Bus bus(config.lcm_url);
    comm::enable_auth_from_file(bus, config.auth_key_file);
    Reporter reporter(bus, process);
    try {
      if (!vsp->library.empty()) load_plugin_library(vsp->library, vsp->where);
      std::unique_ptr<vsp::SensorPlugin> plugin;
      try {
        plugin = vsp::make_sensor(vsp->plugin);
      } catch (const ConfigError& e) {
        throw e.at(vsp->where);
      }
      vsp::Shell shell(bus, reporter, *vsp, std::move(plugin));
      bus.start();
      reporter.set_state(ProcessState::ready);
      reporter.info(fmt::format(
          "ready: plugin '{}', sources {}, {}, {}", vsp->plugin, fmt::join(vsp->sources, ", "),
          vsp->periodic ? fmt::format("periodic every {:.0f} ms", vsp->period_s * 1000.0)
                        : std::string("on demand"),
          scheduling));
      shell.serve([] { return !stop_requested(); });
      reporter.set_state(ProcessState::finished);
      return 0;
    } catch (const Error& e) {
      reporter.error(2, e.what());
      reporter.set_state(ProcessState::failed, e.what());
      std::fprintf(stderr, "mrroc-vsp: %s\n", e.what());
      return 1;
    }
  } catch (const Error& e) {
    std::fprintf(stderr, "mrroc-vsp: %s\n", e.what());
    return 2;
  }
}
