#pragma once
/// @file
/// Loading user plugins (tasks, hardware plugins) from shared libraries. A library registers its
/// classes from static registrars (MRROC_REGISTER_ECP_TASK, MRROC_REGISTER_MP_TASK,
/// MRROC_REGISTER_HARDWARE) when it is loaded.

#include <filesystem>

#include "mrroc/core/error.hpp"

namespace mrroc {

/// Loads `library` (dlopen, RTLD_NOW | RTLD_GLOBAL) once; later calls with the same path do
/// nothing.
/// @throws ConfigError "where: error: cannot load library 'path': <dlerror>".
void load_plugin_library(const std::filesystem::path& library, const SourceLocation& where);

}  // namespace mrroc
