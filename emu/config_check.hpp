#pragma once
/// @file
/// `mrroc-axis-emu --check-config` (run by `mrroc-launch --check`): what the emulator builds at
/// start, with nothing opened and nothing sent, and what the process set expects of its cell.

#include <vector>

#include "mrroc/config/process_set.hpp"
#include "mrroc/core/error.hpp"

namespace mrroc::emu {

/// Every error the cell emulator of `set` (its [emulator] table) would meet at start, and every
/// disagreement between the set and its scene:
///   - the scene: read, composed into one MJCF and loaded by MuJoCo (CellWorld), its drive
///     wiring ([scene.robot.drives]) and its raw sensor devices ([[scene.sensor]]);
///   - the [emulator] faults (as `--fault` parses them), against the scene's robots, axes and
///     sensor devices;
///   - every [[robot]] whose EDP uses the `can` plugin on a `virtual:` bus: the scene has a robot
///     of that name, the EDP's `bus`, `nodes` and `counts_per_unit` equal the scene's wiring of
///     it (a robot on another bus, other node ids or another encoder resolution would not find
///     its drives, or would move by the wrong amount), and its model folder is the scene's.
/// Each error is a ConfigError at the place to change (the set's key or the scene's table).
/// A set without [emulator]: none.
std::vector<ConfigError> check_emulator_config(const ProcessSetConfig& set);

}  // namespace mrroc::emu
