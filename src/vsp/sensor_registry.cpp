// Registry of VSP sensor plugins.
#include <fmt/format.h>

#include <optional>

#include "../core/registry.hpp"
#include "mrroc/config/check.hpp"
#include "mrroc/config/process_set.hpp"
#include "mrroc/vsp/sensor.hpp"

namespace mrroc::vsp {

namespace {
::mrroc::detail::Registry<SensorFactory>& registry() {
  static ::mrroc::detail::Registry<SensorFactory> r("sensor plugin");
  return r;
}
}  // namespace

void register_sensor(const std::string& name, SensorFactory factory) {
  registry().add(name, std::move(factory));
}

std::unique_ptr<SensorPlugin> make_sensor(const std::string& name) {
  return registry().get(name)();
}

std::vector<std::string> sensor_names() { return registry().names(); }

std::unique_ptr<SensorPlugin> make_sensor(const VspConfig& vsp) {
  try {
    return make_sensor(vsp.plugin);
  } catch (const ConfigError& e) {
    ConfigErrorList errors;
    errors.add(e, vsp.plugin_where.known() ? vsp.plugin_where : vsp.where);
    // A name near a known plugin (the error suggests it): the parameters are checked against
    // that plugin, so that their own mistakes show in the same run.
    if (const std::optional<std::string> near = registry().nearest(vsp.plugin)) {
      ConfigErrorList parameter_errors;
      parameter_errors.run(vsp.where, [&] { configure_sensor(*make_sensor(*near), vsp); });
      errors.add(
          noted(parameter_errors.errors(), fmt::format("(checked as sensor plugin '{}')", *near)));
    }
    errors.throw_if_any();
    throw;  // not reached: `errors` holds at least `e`
  }
}

void configure_sensor(SensorPlugin& plugin, const VspConfig& vsp) {
  ConfigErrorList errors;
  SensorSetup setup;
  setup.name = vsp.name;
  setup.sources = vsp.sources;
  setup.params = vsp.params;
  // Every unknown key and optional parameter of another type, and the other checks too (a
  // sensor plugin's configure() reads its parameters, it opens no device).
  setup.params.collect_errors(&errors);
  errors.run(vsp.where, [&] { plugin.configure(setup); });
  setup.params.collect_unknown_keys(nullptr);
  errors.throw_if_any();
}

}  // namespace mrroc::vsp
