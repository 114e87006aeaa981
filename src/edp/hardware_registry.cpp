#include <fmt/format.h>

#include <map>
#include <mutex>

#include "mrroc/core/error.hpp"
#include "mrroc/edp/hardware.hpp"

namespace mrroc::edp {

namespace {
std::map<std::string, HardwareFactory>& registry() {
  static std::map<std::string, HardwareFactory> r;
  return r;
}
std::mutex& registry_mutex() {
  static std::mutex m;
  return m;
}
}  // namespace

void register_hardware(const std::string& name, HardwareFactory factory) {
  std::lock_guard lock(registry_mutex());
  registry()[name] = std::move(factory);
}

std::unique_ptr<Hardware> make_hardware(const std::string& name) {
  std::lock_guard lock(registry_mutex());
  auto it = registry().find(name);
  if (it == registry().end()) {
    std::string known;
    for (const auto& [n, f] : registry()) known += (known.empty() ? "" : ", ") + n;
    throw ConfigError(fmt::format("unknown hardware plugin '{}' (known: {})", name, known));
  }
  return it->second();
}

std::vector<std::string> hardware_names() {
  std::lock_guard lock(registry_mutex());
  std::vector<std::string> out;
  for (const auto& [n, f] : registry()) out.push_back(n);
  return out;
}

}  // namespace mrroc::edp
