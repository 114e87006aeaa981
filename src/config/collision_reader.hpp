#pragma once
/// @file
/// Reading of the `[collision]` table of a process-set file (private to the config layer).

#include <filesystem>
#include <string>
#include <vector>

#include <toml++/toml.h>

#include "mrroc/config/collision.hpp"

namespace mrroc::config_detail {

/// Reads `[collision]` (`node` null: the defaults). `robots`: the names of the set's robots, which
/// "<robot>/<link>" in `allow` must name. @throws ConfigError ("file:line: error: ...") at the
/// first bad value, naming it, its unit and its limit.
CollisionConfig read_collision(const toml::node* node, const std::filesystem::path& file,
                               const std::vector<std::string>& robots);

}  // namespace mrroc::config_detail
