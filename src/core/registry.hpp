#pragma once
// Name -> factory registry shared by hardware plugins, arm kinematics and tasks. Registrations
// run from static initialisers (the MRROC_REGISTER_* macros), also of libraries loaded later.

#include <fmt/format.h>

#include <map>
#include <mutex>
#include <string>
#include <vector>

#include "mrroc/core/error.hpp"

namespace mrroc::detail {

template <class Factory>
class Registry {
 public:
  /// @param kind  what is registered, for messages: "hardware plugin", "ECP task", ...
  explicit Registry(const char* kind) : kind_(kind) {}

  void add(const std::string& name, Factory factory) {
    std::lock_guard lock(mutex_);
    factories_[name] = std::move(factory);
  }

  /// @throws ConfigError "unknown <kind> '<name>' (known: a, b)".
  [[nodiscard]] Factory get(const std::string& name) const {
    std::lock_guard lock(mutex_);
    auto it = factories_.find(name);
    if (it != factories_.end()) return it->second;
    std::string known;
    for (const auto& [n, f] : factories_) known += (known.empty() ? "" : ", ") + n;
    throw ConfigError(
        fmt::format("unknown {} '{}' (known: {})", kind_, name, known.empty() ? "none" : known));
  }

  [[nodiscard]] std::vector<std::string> names() const {
    std::lock_guard lock(mutex_);
    std::vector<std::string> out;
    for (const auto& [n, f] : factories_) out.push_back(n);
    return out;
  }

 private:
  const char* kind_;
  mutable std::mutex mutex_;
  std::map<std::string, Factory> factories_;
};

}  // namespace mrroc::detail
