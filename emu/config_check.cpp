/// @file
/// mrroc-axis-emu --check-config (config_check.hpp).
#include "config_check.hpp"

#include <fmt/format.h>
#include <fmt/ranges.h>

#include <cmath>
#include <filesystem>
#include <map>
#include <memory>
#include <string>

#include "cell_world.hpp"
#include "drives.hpp"
#include "faults.hpp"
#include "mrroc/config/check.hpp"
#include "sensors.hpp"

namespace mrroc::emu {

namespace {

namespace fs = std::filesystem;

fs::path normal(const fs::path& p) {
  std::error_code ec;
  const fs::path c = fs::weakly_canonical(p, ec);
  return ec ? p.lexically_normal() : c;
}

/// The set's `can` robots on virtual buses against the scene's robots and wiring.
void check_can_robots(const ProcessSetConfig& set, const CellWorld& world,
                      const std::vector<RobotDrives>& wiring, ConfigErrorList& errors) {
  const std::string scene = set.emulator->scene.string();
  for (const RobotConfig& robot : set.robots) {
    if (robot.edp.plugin != "can") continue;
    Params params = robot.edp.params;  // a copy: reading marks its keys
    if (!params.has("bus")) continue;  // the EDP's own check reports it
    std::string bus;
    if (!errors.run(params.location(), [&] { bus = params.get_string("bus"); })) continue;
    if (bus.rfind("virtual:", 0) != 0) continue;  // a real bus: not the emulator's
    std::size_t k = 0;
    try {
      k = world.robot_index(robot.name);
    } catch (const Error&) {
      std::string names;
      for (std::size_t i = 0; i < world.robot_count(); ++i)
        names += (i == 0 ? "" : ", ") + world.robot(i).name;
      errors.add(ConfigError(
          robot.where,
          fmt::format("robot '{}' drives the emulated bus '{}', but the emulator's scene {} has "
                      "no robot '{}' (its robots: {})",
                      robot.name, bus, scene, robot.name, names)));
      continue;
    }
    const RobotDrives& w = wiring[k];
    if (bus != w.bus)
      errors.add(ConfigError(params.location_of("bus"),
                             fmt::format("robot '{}': bus '{}' is not where the scene {} wires its "
                                         "drives: '{}' ([scene.robot.drives] bus)",
                                         robot.name, bus, scene, w.bus)));
    std::vector<int> nodes;
    if (params.has("nodes")) {
      errors.run(params.location_of("nodes"), [&] {
        for (const double n : params.get_doubles("nodes")) nodes.push_back(static_cast<int>(n));
      });
    } else {
      for (std::size_t i = 0; i < world.robot(k).axis_count(); ++i)
        nodes.push_back(static_cast<int>(i + 1));
    }
    if (!nodes.empty() && nodes != w.nodes)
      errors.add(ConfigError(
          params.has("nodes") ? params.location_of("nodes") : params.location(),
          fmt::format("robot '{}': node ids [{}] are not the scene's [{}] ({} [scene.robot.drives] "
                      "nodes): the EDP would not find its drives",
                      robot.name, fmt::join(nodes, ", "), fmt::join(w.nodes, ", "), scene)));
    double counts = 0.0;
    if (errors.run(params.location(),
                   [&] { counts = params.get_double("counts_per_unit", 100000.0); }) &&
        std::abs(counts - w.counts_per_unit) > 1e-9 * w.counts_per_unit)
      errors.add(ConfigError(
          params.has("counts_per_unit") ? params.location_of("counts_per_unit") : params.location(),
          fmt::format("robot '{}': counts_per_unit = {} counts/unit is not the emulated drives' "
                      "{} ({} [scene.robot.drives] counts_per_unit): every position would be "
                      "off by their ratio",
                      robot.name, counts, w.counts_per_unit, scene)));
    if (normal(robot.model_dir) != normal(world.robot(k).model_dir))
      errors.add(ConfigError(
          robot.where,
          fmt::format("robot '{}': model '{}' is not the scene's model of it, '{}'", robot.name,
                      robot.model_dir.string(), world.robot(k).model_dir.string())));
  }
}

}  // namespace

std::vector<ConfigError> check_emulator_config(const ProcessSetConfig& set) {
  ConfigErrorList errors;
  if (!set.emulator) return errors.errors();
  const fs::path& scene = set.emulator->scene;
  const SourceLocation at = set.emulator->where;
  std::unique_ptr<CellWorld> world;
  if (!errors.run(at, [&] { world = std::make_unique<CellWorld>(scene); }))
    return errors.errors();  // nothing else can be checked without the world
  std::vector<RobotDrives> wiring;
  const bool wired = errors.run(at, [&] { wiring = read_drive_wiring(scene, *world, {}); });
  std::vector<std::string> devices;
  errors.run(at, [&] {
    for (const SensorConfig& c : read_sensor_configs(scene, *world)) devices.push_back(c.name);
  });
  for (const std::string& f : set.emulator->faults)
    errors.run(at, [&] { (void)resolve_fault(f, *world, devices); });
  if (wired) check_can_robots(set, *world, wiring, errors);
  return errors.errors();
}

}  // namespace mrroc::emu
