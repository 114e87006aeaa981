#pragma once
/// @file
/// How a cell's axes are wired as CiA 402 drives: which bus, which node ids, encoder resolution
/// and current limit. Read from the scene file's `[scene.robot.drives]` tables:
///
///     [[scene.robot]]
///     name = "left"
///     ...
///     [scene.robot.drives]
///     bus = "virtual:left"          # default "virtual:<robot>"
///     nodes = [1, 2, 3, 4, 5]       # default 1..n, in axis order
///     counts_per_unit = 100000      # encoder counts per rad (or m), default 100000
///     current_limit = [400, ...]    # |force| a drive may hold for 50 ms [N m or N]; one number
///                                   # or one per axis; default: the actuator's forcerange
///
/// `mrroc-axis-emu --bus <robot>=<url>` overrides a robot's bus.
#include <filesystem>
#include <map>
#include <string>
#include <vector>

#include "cell_world.hpp"

namespace mrroc::emu {

struct RobotDrives {
  std::string bus;
  std::vector<int> nodes;
  double counts_per_unit = 100000.0;
  std::vector<double> current_limit;  ///< per axis [N m or N]
};

/// One entry per robot of `world`, in robot order. @throws ConfigError ("file:line: error: ...").
std::vector<RobotDrives> read_drive_wiring(const std::filesystem::path& scene_file,
                                           const CellWorld& world,
                                           const std::map<std::string, std::string>& bus_overrides);

}  // namespace mrroc::emu
