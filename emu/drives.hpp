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
///     eds = "../drives/emu-ip.eds"  # the drives' EDS/DCF (relative to the scene file): one for
///                                   # all or one per axis; default: mrroc's emulated drive
///                                   # (configs/drives/emu-csp.eds)
///
///     [[scene.robot.drives.input]]     # a digital input line of one of this robot's drives
///     axis = "column"                  # the drive: axis name or 0-based index
///     line = 0                         # 0..7, the drive's input line (0x60FD bit 16 + line)
///     source = "presence"              # presence | grasp | output
///     object = "part"                  # presence: on while this object's origin (body position)
///     region = [x0, x1, y0, y1, z0, z1]#   is inside region (world frame, m; x0 < x1, ...): a
///                                      #   light barrier or proximity switch
///                                      # grasp: on while a grasp of `object` is engaged
///     grasp = 0                        #   optional: only the object's [[scene.object.grasp]] of
///                                      #   this 0-based index (default: any of them)
///     from_axis = "column"             # output: on while this output line of this robot's drive
///     from_line = 0                    #   `from_axis` is on (a loop-back wire)
///     invert = false                   # optional: the line is on while the source is off
///
/// Each input line of a drive has at most one wire; lines without one are off. A source's keys
/// belong to it alone (`region` with source "output" is an error). The inputs follow the physics
/// step by step (evaluate_inputs); an output wire sees the outputs the drive had at the step's
/// start (what the master set by the SYNC before it).
///
/// `mrroc-axis-emu --bus <robot>=<url>` overrides a robot's bus.
#include <array>
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <map>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "cell_world.hpp"
#include "mrroc/can/canopen.hpp"
#include "mrroc/can/eds.hpp"
#include "mrroc/core/error.hpp"

namespace mrroc::emu {

/// Digital lines per drive, inputs and outputs alike (0x60FD bits 16..23, 0x60FE bits 16..23).
inline constexpr int kDriveLines = static_cast<int>(can::canopen::kUserLines);

/// What drives a digital input line.
enum class InputSource {
  presence,  ///< an object's origin inside a box of the world
  grasp,     ///< a grasp of an object engaged
  output,    ///< an output line of one of the robot's drives
};

/// One [[scene.robot.drives.input]]: a wire into input line `line` of axis `axis`' drive.
struct InputWire {
  std::size_t axis = 0;
  int line = 0;  ///< 0 .. kDriveLines - 1
  InputSource source = InputSource::presence;
  bool invert = false;
  std::string object;               ///< presence, grasp
  std::array<double, 6> region{};   ///< presence: x0, x1, y0, y1, z0, z1 [m, world]
  int grasp = -1;                   ///< grasp: the object's grasp index, -1 any
  std::size_t from_axis = 0;        ///< output
  int from_line = 0;                ///< output: 0 .. kDriveLines - 1
  SourceLocation where;             ///< of its table
  int body = -1;                    ///< presence: the object's MuJoCo body id
  std::vector<std::size_t> grasps;  ///< grasp: the CellWorld grasps it watches
};

struct RobotDrives {
  std::string bus;
  std::vector<int> nodes;
  double counts_per_unit = 100000.0;
  std::vector<double> current_limit;  ///< per axis [N m or N]
  /// Per axis, the drive's EDS/DCF; empty: mrroc's emulated drive's.
  std::vector<std::shared_ptr<const can::eds::Dictionary>> eds;
  std::vector<InputWire> inputs;  ///< in file order
};

/// One entry per robot of `world`, in robot order. @throws ConfigError ("file:line: error: ...")
///   at the offending key, naming the key, its value and the limit or the allowed names.
std::vector<RobotDrives> read_drive_wiring(const std::filesystem::path& scene_file,
                                           const CellWorld& world,
                                           const std::map<std::string, std::string>& bus_overrides);

/// The input lines of robot `robot`'s drives now (bit k = line k), one per axis into `inputs`,
/// from the world as of its last step or reset and from `outputs`, the drives' output lines
/// (`Cia402Drive::output_lines()`), one per axis. Returns false (inputs untouched) when either
/// size is not the robot's axis count. Real time: neither allocates nor throws.
bool evaluate_inputs(const RobotDrives& wiring, const CellWorld& world,
                     std::span<const std::uint8_t> outputs,
                     std::span<std::uint8_t> inputs) noexcept;

/// One line for the log: "robot 'irb6' axis 'column' input 0: presence of 'part' in x 0.35..0.45
/// y -0.75..-0.55 z 0.70..1.00 m".
std::string describe_input(const CellRobot& robot, const InputWire& wire);

}  // namespace mrroc::emu
