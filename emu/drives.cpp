/// @file
/// Reading the drive wiring of a scene (see drives.hpp).
#include "drives.hpp"

#include <fmt/format.h>

#include <toml++/toml.h>
#include <cmath>
#include <set>

#include "mrroc/core/error.hpp"

namespace mrroc::emu {

std::vector<RobotDrives> read_drive_wiring(const std::filesystem::path& file,
                                           const CellWorld& world,
                                           const std::map<std::string, std::string>& overrides) {
  toml::table root;
  try {
    root = toml::parse_file(file.string());
  } catch (const toml::parse_error& e) {
    throw ConfigError(SourceLocation{file.string(), static_cast<int>(e.source().begin.line)},
                      std::string(e.description()));
  }
  const auto fail = [&](const toml::node& node, const std::string& text) {
    return ConfigError(SourceLocation{file.string(), static_cast<int>(node.source().begin.line)},
                       text);
  };
  const toml::array* robots = root["scene"]["robot"].as_array();
  std::vector<RobotDrives> out;
  std::set<std::pair<std::string, int>> used;
  for (std::size_t k = 0; k < world.robot_count(); ++k) {
    const CellRobot& robot = world.robot(k);
    const std::size_t n = robot.axis_count();
    RobotDrives d;
    d.bus = "virtual:" + robot.name;
    for (std::size_t i = 0; i < n; ++i) d.nodes.push_back(static_cast<int>(i + 1));
    for (std::size_t i = 0; i < n; ++i) {
      const double limit = robot.force_limits[i].upper;
      d.current_limit.push_back(std::isfinite(limit) && limit > 0.0 ? limit : INFINITY);
    }
    const toml::table* t = nullptr;
    if (robots != nullptr && k < robots->size() && (*robots)[k].is_table())
      t = (*robots)[k].as_table()->get_as<toml::table>("drives");
    if (t != nullptr) {
      for (const auto& [key, node] : *t)
        if (key != "bus" && key != "nodes" && key != "counts_per_unit" && key != "current_limit")
          throw fail(node, fmt::format("unknown key '{}' in [scene.robot.drives] (allowed: bus, "
                                       "nodes, counts_per_unit, current_limit)",
                                       key.str()));
      if (const toml::node* bus = t->get("bus")) {
        if (!bus->is_string()) throw fail(*bus, "'bus' must be a string such as \"virtual:cell1\"");
        d.bus = **bus->as_string();
      }
      if (const toml::node* nodes = t->get("nodes")) {
        const toml::array* list = nodes->as_array();
        if (list == nullptr || list->size() != n)
          throw fail(*nodes, fmt::format("'nodes' must list {} node ids (robot '{}' has {} axes)",
                                         n, robot.name, n));
        d.nodes.clear();
        for (const auto& v : *list) {
          const auto id = v.value<std::int64_t>();
          if (!id || *id < 1 || *id > 127) throw fail(v, "node ids must be integers in 1..127");
          d.nodes.push_back(static_cast<int>(*id));
        }
      }
      if (const toml::node* counts = t->get("counts_per_unit")) {
        const auto v = counts->value<double>();
        if (!v || !(*v > 0.0) || !std::isfinite(*v))
          throw fail(*counts, "'counts_per_unit' must be a positive number [counts per rad or m]");
        d.counts_per_unit = *v;
      }
      if (const toml::node* limit = t->get("current_limit")) {
        std::vector<double> values;
        if (const toml::array* list = limit->as_array()) {
          for (const auto& v : *list) values.push_back(v.value<double>().value_or(-1.0));
        } else {
          values.assign(n, limit->value<double>().value_or(-1.0));
        }
        if (values.size() != n)
          throw fail(*limit, fmt::format("'current_limit' must be one number or {} numbers [N m "
                                         "or N]",
                                         n));
        for (const double v : values)
          if (!(v > 0.0)) throw fail(*limit, "'current_limit' values must be positive [N m or N]");
        d.current_limit = values;
      }
    }
    if (const auto it = overrides.find(robot.name); it != overrides.end()) d.bus = it->second;
    for (const int node : d.nodes)
      if (!used.insert({d.bus, node}).second)
        throw ConfigError(SourceLocation::whole_file(file.string()),
                          fmt::format("node id {} is used twice on bus {} (robot '{}')", node,
                                      d.bus, robot.name));
    out.push_back(std::move(d));
  }
  for (const auto& [name, url] : overrides) {
    bool known = false;
    for (std::size_t k = 0; k < world.robot_count(); ++k)
      known = known || world.robot(k).name == name;
    if (!known)
      throw ConfigError("--bus " + name + "=" + url + ": the scene has no robot '" + name + "'");
  }
  return out;
}

}  // namespace mrroc::emu
