// Name -> factory registries of ECP and MP tasks.
#include "mrroc/ecp/task.hpp"
#include "mrroc/mp/task.hpp"
#include "registry.hpp"

namespace mrroc {

namespace {
detail::Registry<ecp::EcpTaskFactory>& ecp_registry() {
  static detail::Registry<ecp::EcpTaskFactory> r("ECP task");
  return r;
}
detail::Registry<mp::MpTaskFactory>& mp_registry() {
  static detail::Registry<mp::MpTaskFactory> r("MP task");
  return r;
}
}  // namespace

void ecp::register_ecp_task(const std::string& name, EcpTaskFactory factory) {
  ecp_registry().add(name, std::move(factory));
}
std::unique_ptr<ecp::EcpTask> ecp::make_ecp_task(const std::string& name, TaskContext& context) {
  return ecp_registry().get(name)(context);
}

mp::Robot& mp::TaskContext::robot(const std::string& name) const {
  std::string known;
  for (Robot* r : robots) {
    if (r->name() == name) return *r;
    known += (known.empty() ? "" : ", ") + r->name();
  }
  throw ConfigError(fmt::format("the MP task needs robot '{}', the process set has: {}", name,
                                known.empty() ? "none" : known));
}

void mp::register_mp_task(const std::string& name, MpTaskFactory factory) {
  mp_registry().add(name, std::move(factory));
}
std::unique_ptr<mp::MpTask> mp::make_mp_task(const std::string& name, TaskContext& context) {
  return mp_registry().get(name)(context);
}

}  // namespace mrroc
