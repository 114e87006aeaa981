#pragma once
/// @file
/// Fault injection of the cell emulator: what `mrroc-axis-emu --fault SPEC` and the process set's
/// `[emulator] faults = [...]` take.
///
///   drive:<robot>/<axis>@<t>[=<code>]  the drive goes to fault with an EMCY code (hex, default
///                                      0x5000 device hardware)
///   silent:<robot>/<axis>@<t>          the drive's node falls silent (sends and hears nothing)
///   drop:<robot>@<t>=<fraction>        the robot's drives lose that fraction (0..1) of the
///                                      frames they send
///   busoff:<robot>@<t>[+<seconds>]     the robot's drives go bus-off (an error frame
///                                      CAN_ERR_BUSOFF is sent), for ever or for that long
///   sensor:<device>@<t>                the raw sensor device stops publishing (a dead receptor)
///
/// <axis> is an axis name or index (0-based); <t> is in seconds after all the robot's drives
/// first reached operation enabled (for `sensor`: the scene's first robot).
#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

namespace mrroc::emu {

class CellWorld;

enum class FaultKind { drive, silent, drop, bus_off, sensor };

struct FaultSpec {
  FaultKind kind = FaultKind::drive;
  std::string robot;            ///< empty for sensor
  std::string device;           ///< sensor
  std::string axis;             ///< name or index; empty for drop and busoff
  double at_s = 0.0;            ///< [s] after the robot's drives were first enabled
  std::uint16_t code = 0x5000;  ///< EMCY code (drive)
  double fraction = 0.0;        ///< drop
  double duration_s = -1.0;     ///< busoff; negative: for ever
  std::string text;             ///< the spec as written
};

/// @throws mrroc::ConfigError naming the spec and what is wrong with it.
FaultSpec parse_fault(std::string_view spec);

/// A fault found in the cell: the index of its robot and axis (`sensor`: robot 0, whose drives
/// time it).
struct ResolvedFault {
  FaultSpec spec;
  std::size_t robot = 0;
  std::size_t axis = 0;
};

/// parse_fault(spec), then its robot, axis or sensor device looked up in the cell (`sensors`:
/// the names of the scene's raw sensor devices). What the emulator does at start and its
/// `--check-config`. @throws mrroc::ConfigError naming the fault and what the cell lacks.
ResolvedFault resolve_fault(std::string_view spec, const CellWorld& world,
                            const std::vector<std::string>& sensors);

}  // namespace mrroc::emu
