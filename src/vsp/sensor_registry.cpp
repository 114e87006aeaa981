// Registry of VSP sensor plugins.
#include "../core/registry.hpp"
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

}  // namespace mrroc::vsp
