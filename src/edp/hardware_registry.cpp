// Registry of EDP hardware plugins.
#include <fmt/format.h>

#include <optional>

#include "../core/registry.hpp"
#include "mrroc/config/check.hpp"
#include "mrroc/config/process_set.hpp"
#include "mrroc/core/error.hpp"
#include "mrroc/edp/hardware.hpp"
#include "mrroc/robot/robot_model.hpp"

namespace mrroc::edp {

namespace {
::mrroc::detail::Registry<HardwareFactory>& registry() {
  static ::mrroc::detail::Registry<HardwareFactory> r("hardware plugin");
  return r;
}
}  // namespace

void Hardware::home_axes() {
  throw HardwareError(fmt::format("hardware plugin '{}' cannot home its axes by itself", name()));
}

void register_hardware(const std::string& name, HardwareFactory factory) {
  registry().add(name, std::move(factory));
}

std::unique_ptr<Hardware> make_hardware(const std::string& name) { return registry().get(name)(); }

std::vector<std::string> hardware_names() { return registry().names(); }

std::unique_ptr<Hardware> make_configured_hardware(const RobotConfig& robot,
                                                   const RobotModel& model, bool open_devices) {
  std::unique_ptr<Hardware> hardware;
  try {
    hardware = make_hardware(robot.edp.plugin);
  } catch (const ConfigError& e) {
    ConfigErrorList errors;
    errors.add(e, robot.edp.plugin_where.known() ? robot.edp.plugin_where : robot.edp.where);
    // A name near a known plugin (the error suggests it): the parameters are checked against
    // that plugin, opening no device, so that their own mistakes show in the same run.
    if (const std::optional<std::string> near = registry().nearest(robot.edp.plugin)) {
      ConfigErrorList parameter_errors;
      parameter_errors.run(robot.edp.where, [&] {
        const std::unique_ptr<Hardware> suggested = make_hardware(*near);
        HardwareSetup setup;
        setup.robot = robot.name;
        setup.model_dir = robot.model_dir;
        setup.servo_period_s = robot.edp.servo_period_s;
        setup.synchro_positions = model.synchro_joint_positions;
        setup.params = robot.edp.params;
        setup.params.collect_errors(&parameter_errors);
        if (suggested->simulated())
          suggested->configure(setup);
        else
          suggested->check(setup);
        setup.params.collect_unknown_keys(nullptr);
      });
      errors.add(noted(parameter_errors.errors(),
                       fmt::format("(checked as hardware plugin '{}')", *near)));
    }
    errors.throw_if_any();
  }
  // Before configure(), which opens the devices of real hardware.
  if (robot.edp.lock_step && !hardware->simulated())
    throw ConfigError(
        robot.edp.where,
        fmt::format("lock_step = true needs simulated hardware; plugin '{}' drives its axes in "
                    "real time (for emulated drives, set lock_step in [emulator] instead)",
                    hardware->name()));
  ConfigErrorList errors;
  HardwareSetup setup;
  setup.robot = robot.name;
  setup.model_dir = robot.model_dir;
  setup.servo_period_s = robot.edp.servo_period_s;
  setup.synchro_positions = model.synchro_joint_positions;
  setup.params = robot.edp.params;
  // Every unknown key, and the other checks too; an optional parameter of another type as well
  // where nothing opens a device (a plugin of real devices configured at start stops at it).
  if (open_devices && !hardware->simulated())
    setup.params.collect_unknown_keys(&errors);
  else
    setup.params.collect_errors(&errors);
  if (open_devices || hardware->simulated())
    errors.run(robot.edp.where, [&] { hardware->configure(setup); });
  else
    errors.run(robot.edp.where, [&] { hardware->check(setup); });
  setup.params.collect_unknown_keys(nullptr);
  errors.throw_if_any();
  return hardware;
}

}  // namespace mrroc::edp
