#pragma once
// Name -> factory registry shared by hardware plugins, arm kinematics and tasks. Registrations
// run from static initialisers (the MRROC_REGISTER_* macros), also of libraries loaded later.

#include <fmt/format.h>

#include <map>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include "mrroc/core/error.hpp"
#include "mrroc/core/nearest_name.hpp"

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

  /// @throws ConfigError "unknown <kind> '<name>' (known: a, b)", followed by "; did you mean
  ///   'a'?" when a known name is near (nearest_name).
  [[nodiscard]] Factory get(const std::string& name) const {
    std::lock_guard lock(mutex_);
    auto it = factories_.find(name);
    if (it != factories_.end()) return it->second;
    std::string known;
    std::vector<std::string> names;
    for (const auto& [n, f] : factories_) {
      known += (known.empty() ? "" : ", ") + n;
      names.push_back(n);
    }
    const std::optional<std::string> near = nearest_name(name, names);
    throw ConfigError(fmt::format("unknown {} '{}' (known: {}){}", kind_, name,
                                  known.empty() ? "none" : known,
                                  near ? fmt::format("; did you mean '{}'?", *near) : ""));
  }

  /// True when `name` is registered.
  [[nodiscard]] bool has(const std::string& name) const {
    std::lock_guard lock(mutex_);
    return factories_.count(name) != 0;
  }

  /// The registered name nearest to the unknown `name` (nearest_name), the one get()'s error
  /// suggests; nothing when none is near.
  [[nodiscard]] std::optional<std::string> nearest(const std::string& name) const {
    return nearest_name(name, names());
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
