// The name -> factory registry of ECP tasks, and the virtual sensors of an ECP task.
#include "../core/registry.hpp"
#include "mrroc/ecp/task.hpp"

namespace mrroc {

namespace {
detail::Registry<ecp::EcpTaskFactory>& ecp_registry() {
  static detail::Registry<ecp::EcpTaskFactory> r("ECP task");
  return r;
}
}  // namespace

void ecp::register_ecp_task(const std::string& name, EcpTaskFactory factory) {
  ecp_registry().add(name, std::move(factory));
}
std::unique_ptr<ecp::EcpTask> ecp::make_ecp_task(const std::string& name, TaskContext& context) {
  return ecp_registry().get(name)(context);
}

}  // namespace mrroc

namespace mrroc::ecp {

std::unique_ptr<VirtualSensor> TaskContext::sensor(const std::string& vsp) const {
  if (bus == nullptr) throw Error("this task context has no LCM bus for virtual sensors");
  return std::make_unique<VirtualSensor>(*bus, vsp, process.empty() ? "ecp" : process);
}

}  // namespace mrroc::ecp
