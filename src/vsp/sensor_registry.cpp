// Registry of VSP sensor plugins.
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
    throw e.at(vsp.plugin_where.known() ? vsp.plugin_where : vsp.where);
  }
}

void configure_sensor(SensorPlugin& plugin, const VspConfig& vsp) {
  ConfigErrorList errors;
  SensorSetup setup;
  setup.name = vsp.name;
  setup.sources = vsp.sources;
  setup.params = vsp.params;
  setup.params.collect_unknown_keys(&errors);  // every unknown key, and the other checks too
  errors.run(vsp.where, [&] { plugin.configure(setup); });
  setup.params.collect_unknown_keys(nullptr);
  errors.throw_if_any();
}

}  // namespace mrroc::vsp
