// mrroc-vsp: a Virtual Sensor Process. Aggregates the raw samples of its sources (raw sensor
// devices on mrroc/raw/<device>) into readings with a sensor plugin, and serves them to ECPs and
// the MP: CONFIGURE, INITIATE_READING, GET_READING, TERMINATE on vsp/<name>/cmd (docs/sensors.md).
#include <fmt/format.h>

#include <cstdio>

#include "mrroc/comm/auth.hpp"
#include "mrroc/comm/bus.hpp"
#include "mrroc/comm/reporter.hpp"
#include "mrroc/config/check.hpp"
#include "mrroc/config/process_set.hpp"
#include "mrroc/core/command_line.hpp"
#include "mrroc/core/error.hpp"
#include "mrroc/core/plugin_library.hpp"
#include "mrroc/core/process.hpp"
#include "shell.hpp"

namespace {

/// What the VSP builds before it reports ready, at start and for --check-config: the plugin
/// library, the plugin (by name), configured with its sources and [vsp.params], in its shell.
std::unique_ptr<mrroc::vsp::Shell> prepare(mrroc::comm::Bus& bus, mrroc::Reporter& reporter,
                                           const mrroc::VspConfig& vsp) {
  using namespace mrroc;
  if (!vsp.library.empty()) load_plugin_library(vsp.library, vsp.where);
  return std::make_unique<vsp::Shell>(bus, reporter, vsp, vsp::make_sensor(vsp));
}

/// --check-config: the process set's errors and this VSP's (prepare), one per line on stderr,
/// nothing started and nothing sent beyond the process (kCheckLcmUrl).
int check(const std::string& config_path, const std::string& name) {
  using namespace mrroc;
  const ProcessSetCheck set = check_process_set(config_path);
  ConfigErrorList errors;
  errors.add(set.errors);
  if (!set.broken_process("vsp/" + name)) {
    errors.run(SourceLocation::whole_file(set.config.file.string()), [&] {
      const VspConfig& vsp = set.config.vsp(name);
      comm::Bus bus(kCheckLcmUrl);
      Reporter reporter(bus, "vsp/" + vsp.name);
      (void)prepare(bus, reporter, vsp);
    });
  }
  for (const auto& error : errors.errors()) std::fprintf(stderr, "%s\n", error.what());
  if (!errors.empty()) return kExitConfigErrors;
  std::printf("mrroc-vsp: vsp/%s: config is valid\n", name.c_str());
  return 0;
}

}  // namespace

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
  bool check_config = false;
  cli.flag("--check-config", check_config,
           "check the config as the VSP does at start (plugin library, plugin name, sources, "
           "[vsp.params]), print every error as file:line and exit (0 valid, 2 errors); nothing "
           "is started and nothing is sent (mrroc-launch --check runs it)");
  if (const auto exit_code = cli.parse(argc, argv)) return *exit_code;

  using namespace mrroc;
  install_stop_handlers();
  if (check_config) {
    try {
      return check(config_path, name);
    } catch (const std::exception& e) {
      std::fprintf(stderr, "mrroc-vsp: %s\n", e.what());
      return kExitConfigErrors;
    }
  }
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
      const std::unique_ptr<vsp::Shell> shell = prepare(bus, reporter, *vsp);
      bus.start();
      reporter.set_state(ProcessState::ready);
      reporter.info(fmt::format(
          "ready: plugin '{}', sources {}, {}, {}", vsp->plugin, fmt::join(vsp->sources, ", "),
          vsp->periodic ? fmt::format("periodic every {:.0f} ms", vsp->period_s * 1000.0)
                        : std::string("on demand"),
          scheduling));
      shell->serve([] { return !stop_requested(); });
      reporter.set_state(ProcessState::finished);
      return 0;
    } catch (const Error& e) {
      ConfigErrorList errors;  // every error of a ConfigErrors, one report each
      errors.add(e, {});
      for (const auto& error : errors.errors()) {
        reporter.error(2, error.what());
        std::fprintf(stderr, "mrroc-vsp: %s\n", error.what());
      }
      reporter.set_state(ProcessState::failed, errors.errors().front().what());
      return 1;
    }
  } catch (const Error& e) {
    std::fprintf(stderr, "mrroc-vsp: %s\n", e.what());
    return 2;
  }
}
