// Registry of EDP hardware plugins.
#include "../core/registry.hpp"
#include "mrroc/edp/hardware.hpp"

namespace mrroc::edp {

namespace {
::mrroc::detail::Registry<HardwareFactory>& registry() {
  static ::mrroc::detail::Registry<HardwareFactory> r("hardware plugin");
  return r;
}
}  // namespace

void register_hardware(const std::string& name, HardwareFactory factory) {
  registry().add(name, std::move(factory));
}

std::unique_ptr<Hardware> make_hardware(const std::string& name) { return registry().get(name)(); }

std::vector<std::string> hardware_names() { return registry().names(); }

}  // namespace mrroc::edp
