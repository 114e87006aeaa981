// Name -> factory registries of ECP and MP tasks.
#include <fmt/format.h>

#include <map>
#include <mutex>

#include "mrroc/ecp/task.hpp"
#include "mrroc/mp/task.hpp"

namespace mrroc {

namespace {
template <class Factory>
struct Registry {
  std::mutex mutex;
  std::map<std::string, Factory> factories;

  void add(const std::string& name, Factory f) {
    std::lock_guard lock(mutex);
    factories[name] = std::move(f);
  }
  template <class Context>
  auto make(const std::string& name, Context& context, const char* kind) {
    std::lock_guard lock(mutex);
    auto it = factories.find(name);
    if (it == factories.end()) {
      std::string known;
      for (const auto& [n, f] : factories) known += (known.empty() ? "" : ", ") + n;
      throw ConfigError(fmt::format("unknown {} task '{}' (known: {})", kind, name,
                                    known.empty() ? "none" : known));
    }
    return it->second(context);
  }
};

Registry<ecp::EcpTaskFactory>& ecp_registry() {
  static Registry<ecp::EcpTaskFactory> r;
  return r;
}
Registry<mp::MpTaskFactory>& mp_registry() {
  static Registry<mp::MpTaskFactory> r;
  return r;
}
}  // namespace

void ecp::register_ecp_task(const std::string& name, EcpTaskFactory factory) {
  ecp_registry().add(name, std::move(factory));
}
std::unique_ptr<ecp::EcpTask> ecp::make_ecp_task(const std::string& name, TaskContext& context) {
  return ecp_registry().make(name, context, "ECP");
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
  return mp_registry().make(name, context, "MP");
}

}  // namespace mrroc
