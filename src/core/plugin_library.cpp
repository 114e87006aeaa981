#include "mrroc/core/plugin_library.hpp"

#include <dlfcn.h>
#include <fmt/format.h>

#include <mutex>
#include <set>

#include "mrroc/core/error.hpp"

namespace mrroc {

void load_plugin_library(const std::filesystem::path& library, const SourceLocation& where) {
  static std::mutex mutex;
  static std::set<std::string> loaded;
  std::lock_guard lock(mutex);
  const std::string path = std::filesystem::absolute(library).lexically_normal().string();
  if (loaded.count(path) != 0) return;
  // Kept loaded for the life of the process: registered factories point into it.
  if (dlopen(path.c_str(), RTLD_NOW | RTLD_GLOBAL) == nullptr)
    throw ConfigError(where, fmt::format("cannot load library '{}': {}", path, dlerror()));
  loaded.insert(path);
}

}  // namespace mrroc
