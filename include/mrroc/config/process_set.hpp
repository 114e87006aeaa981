#pragma once
/// @file
/// The process-set config file: one TOML file describes a whole controller (LCM URL, robots with
/// their EDP hardware plugin and ECP task, the MP task, per-process options). Every process of the
/// set reads the same file. See docs/configs.md for the schema.
///
/// Errors are `ConfigError`s reading "file:line: error: ..."; unknown keys are errors; missing
/// files and folders are named.

#include <array>
#include <filesystem>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "mrroc/config/params.hpp"

namespace mrroc {

/// Options every process of the set accepts.
struct ProcessOptions {
  std::vector<int> cpus;      ///< CPU affinity (empty: any CPU)
  double stop_grace_s = 3.0;  ///< SIGTERM to SIGKILL grace period when stopping [s]
};

struct EdpConfig {
  std::string plugin;            ///< hardware plugin name, e.g. "mujoco"
  std::filesystem::path library; ///< shared library registering the plugin (optional)
  double servo_period_s = 0.002; ///< servo period [s]
  Params params;                 ///< the plugin's own parameters ([robot.edp.params])
  ProcessOptions options;
  SourceLocation where;
};

/// A task (MP or ECP): a name registered by a task plugin, its optional library, its arguments.
struct TaskConfig {
  std::string name;
  std::filesystem::path library;  ///< shared library to load before looking the name up (optional)
  Params args;                    ///< the task's own arguments ([...args])
  ProcessOptions options;
  SourceLocation where;
};

struct RobotConfig {
  std::string name;                 ///< e.g. "irb6"; used in channel and process names
  std::filesystem::path model_dir;  ///< absolute path of robots/<name>/
  /// Pose of the robot's base in the cell: x, y, z [m] and a rotation vector [rad] (default 0).
  std::array<double, 6> base{};
  EdpConfig edp;
  TaskConfig ecp;
  SourceLocation where;
};

/// The cell emulator (`mrroc-axis-emu`): one MuJoCo world whose axes are emulated CiA 402
/// drives on CAN buses ([emulator] in the process set; docs/hil.md).
struct EmulatorConfig {
  std::filesystem::path scene;  ///< scene file (absolute path)
  bool lock_step = false;       ///< physics advances by SYNC, not by the wall clock
  std::vector<std::string> faults;  ///< fault injections, as `mrroc-axis-emu --fault` takes them
  ProcessOptions options;
  SourceLocation where;
};

/// A virtual sensor process ([[vsp]]; docs/sensors.md).
struct VspConfig {
  std::string name;                  ///< e.g. "wrist_force"; channels vsp/<name>/...
  std::string plugin;                ///< sensor plugin name, e.g. "force_torque"
  std::filesystem::path library;     ///< shared library registering the plugin (optional)
  std::vector<std::string> sources;  ///< raw sensor devices feeding it (mrroc/raw/<device>)
  bool periodic = false;             ///< readings made every period (else on INITIATE_READING)
  double period_s = 0.01;            ///< periodic mode [s]
  double stale_after_s = 0.1;        ///< a source silent for longer makes readings invalid [s]
  Params params;                     ///< the plugin's own parameters ([vsp.params])
  ProcessOptions options;
  SourceLocation where;
};

struct ProcessSetConfig {
  std::filesystem::path file;  ///< absolute path of the config file
  std::string name;            ///< name of the set (for messages)
  std::string lcm_url;         ///< empty: $LCM_DEFAULT_URL or the ttl=0 default
  double ready_timeout_s = 10.0;  ///< how long the launcher waits for each process to be ready [s]
  TaskConfig mp;
  ProcessOptions srp;
  std::optional<EmulatorConfig> emulator;  ///< started after the SRP, before the EDPs
  std::vector<RobotConfig> robots;
  std::vector<VspConfig> vsps;  ///< started after the emulator, before the EDPs

  /// @throws ConfigError when no robot has this name.
  [[nodiscard]] const RobotConfig& robot(const std::string& name) const;
  /// @throws ConfigError when no VSP has this name.
  [[nodiscard]] const VspConfig& vsp(const std::string& name) const;
};

/// Parses `key = value` lines (TOML) into Params, e.g. the arguments of a NEXT_STATE command.
/// Locations read "<origin>:line". @throws ConfigError.
Params params_from_toml(const std::string& text, const std::string& origin);

/// Loads and validates a process-set file. @throws ConfigError ("file:line: error: ...").
ProcessSetConfig load_process_set(const std::filesystem::path& file);

/// Validates `text` as if it were the content of the process-set file `file`, exactly as
/// `load_process_set` does: `file` names the errors and relative paths resolve against its folder,
/// but it is never read and need not exist (for tests and fuzzing). @throws ConfigError.
ProcessSetConfig parse_process_set(std::string_view text, const std::filesystem::path& file);

/// Channel names of the links (at most 63 characters, as LCM requires).
namespace channels {
inline std::string edp_command(const std::string& robot) { return robot + "/edp/cmd"; }
inline std::string edp_reply(const std::string& robot) { return robot + "/edp/reply"; }
inline std::string ecp_command(const std::string& robot) { return robot + "/ecp/cmd"; }
inline std::string ecp_reply(const std::string& robot) { return robot + "/ecp/reply"; }
inline std::string vsp_command(const std::string& vsp) { return "vsp/" + vsp + "/cmd"; }
inline std::string vsp_reply(const std::string& vsp) { return "vsp/" + vsp + "/reply"; }
/// Raw sensor samples of one device (raw_sensor_t).
inline std::string raw_sensor(const std::string& device) { return "mrroc/raw/" + device; }
inline constexpr const char* srp = "mrroc/srp";
inline constexpr const char* status = "mrroc/status";
inline constexpr const char* emergency_stop = "mrroc/estop";
}  // namespace channels

}  // namespace mrroc
