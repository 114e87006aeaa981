#pragma once
/// @file
/// The process-set config file: one TOML file describes a whole controller (LCM URL, robots with
/// their EDP hardware plugin and ECP task, the MP task, per-process options). Every process of the
/// set reads the same file. See docs/configs.md for the schema.
///
/// Errors are `ConfigError`s reading "file:line: error: ..."; unknown keys are errors; missing
/// files and folders are named. A key left out takes the default of its member initialiser below
/// (the reader writes no default of its own).

#include <array>
#include <filesystem>
#include <optional>
#include <set>
#include <string>
#include <string_view>
#include <vector>

#include "mrroc/config/collision.hpp"
#include "mrroc/config/params.hpp"
#include "mrroc/core/time.hpp"

namespace mrroc {

/// Restart limits: the shortest back-off a config may set [s] and the most restarts.
inline constexpr double kMinRestartBackoffS = 0.2;
inline constexpr int kMaxRestartsLimit = 20;

/// What the launcher does when a process ends while the set runs.
enum class RestartPolicy {
  never,       ///< leave it ended
  on_failure,  ///< start it again when it ended with a non-zero code or a signal
  always,      ///< start it again whenever it ended
};
[[nodiscard]] const char* to_string(RestartPolicy policy);

/// Options every process of the set accepts (the launcher's keys; docs/configs.md).
struct ProcessOptions {
  std::vector<int> cpus;  ///< CPU affinity (empty: any CPU)
  /// SCHED_FIFO priority of the process' threads, 0..79 (default 0: the policy it was started
  /// with, normally SCHED_OTHER). The EDP's servo thread runs at 80 regardless.
  int priority = 0;
  double stop_grace_s = 3.0;   ///< stop signal to SIGKILL grace period when stopping [s]
  int stop_signal = 15;        ///< signal that asks the process to stop (`stop_signal = "SIGINT"`)
  std::string host = "local";  ///< where it runs: "local" or the name of a [[launch.host]]
  SourceLocation host_where;   ///< where `host` was given (for errors)
  std::string group;           ///< group name (default: srp, emu, vsp, edp, ecp, mp, ui)
  RestartPolicy restart = RestartPolicy::never;
  int max_restarts = 3;            ///< restarts allowed before the process counts as ended (≤ 20)
  double restart_backoff_s = 0.5;  ///< wait before the first restart (≥ 0.2 s); doubles, ≤ 30 s
  bool required = true;            ///< its end (after its restarts) stops the whole set
};

/// A computer the launcher starts processes on ([[launch.host]]).
struct HostConfig {
  std::string name;
  /// Start-command template: argv words in front of the process' own command line. "{host}" is
  /// replaced by `address`.
  std::vector<std::string> command = {"ssh", "-o", "BatchMode=yes", "{host}"};
  /// What "{host}" stands for (default: the name): a host name, an IPv4 or IPv6 address (plain
  /// or in brackets), user@host or a network namespace name (`is_valid_host_address`).
  std::string address;
  /// Pass the command line as one shell-quoted word instead of separate words. Always in force
  /// for an ssh command (`is_ssh_command`), which hands it to the remote shell; for another
  /// command of one's own the default is false.
  bool quote = true;
  SourceLocation where;
};

/// The index of the word of `command` that runs ssh ("ssh" or a path ending in "/ssh"), in any
/// place: a wrapper in front (`sudo -u op ssh {host}`, `env X=1 /usr/bin/ssh {host}`) still
/// hands the command line to a remote shell. `command.size()` when no word does.
std::size_t ssh_word(const std::vector<std::string>& command);

/// True when `command` runs ssh (`ssh_word`).
bool is_ssh_command(const std::vector<std::string>& command);

/// True for what a [[launch.host]] address may be: a host name, IPv4 address, IPv6 address
/// (plain or in brackets, with an optional %zone), user@ in front of any of these, or a network
/// namespace name. Never true for text that starts with '-' (an option to ssh) or holds
/// whitespace, control characters or shell metacharacters.
bool is_valid_host_address(std::string_view address);

/// The launcher's own settings ([launch]).
struct LaunchConfig {
  std::filesystem::path log_dir;  ///< one log file per process here (empty: no log files)
  double log_max_kb = 1024.0;     ///< a log file is rotated when it grows beyond this [KiB]
  int log_keep = 3;               ///< rotated files kept (name.log.1 .. name.log.N)
  std::filesystem::path record;   ///< record every LCM message with lcm-logger here (optional)
  std::vector<HostConfig> hosts;
};

/// The operator console ([ui]): `mrroc-ui serve`, started by the launcher when `web = true`.
/// True for a loopback address or name: "localhost", "::1" or any 127.x.y.z (there the console
/// may generate its API token at start; elsewhere [ui] token_file is required).
bool is_loopback(std::string_view host);

struct UiConfig {
  bool web = false;  ///< the launcher starts the web console
  std::string bind = "127.0.0.1";
  int port = 8080;
  std::filesystem::path token_file;  ///< required unless bound to a loopback address (then a
                                     ///< token is generated at every start)
  std::filesystem::path teach_dir;   ///< where teach-in trajectory files go (default: ./)
  /// Names (or addresses) by which browsers reach the console, besides its bind address and the
  /// loopback names; a request naming another host is refused.
  std::vector<std::string> hosts;
  ProcessOptions options;
  SourceLocation where;
};

/// The System Response Process ([srp]).
struct SrpConfig {
  std::filesystem::path log;  ///< persistent log (JSON lines), rotated (empty: none)
  double log_max_kb = 4096.0;
  int log_keep = 5;
  int history = 10000;  ///< messages kept in memory for the console's history
  ProcessOptions options;
};

/// Macro-steps an EDP queues ahead of its servo loop by default (`[robot.edp] lookahead`);
/// chosen by measurement (docs/edp.md, "Lookahead").
inline constexpr int kDefaultLookahead = 8;
/// The most macro-steps an EDP may queue (its queue is allocated once, this long).
inline constexpr int kMaxLookahead = 64;

struct EdpConfig {
  std::string plugin;             ///< hardware plugin name, e.g. "mujoco"
  SourceLocation plugin_where;    ///< where `plugin` was given (for errors)
  std::filesystem::path library;  ///< shared library registering the plugin (optional)
  double servo_period_s = kDefaultServoPeriodS;  ///< servo period [s]
  /// Macro-steps queued ahead of the servo loop (1..kMaxLookahead; 1: the paper's one successor,
  /// for sensor-driven generators that need the shortest reaction).
  int lookahead = kDefaultLookahead;
  /// Simulated hardware only: servo cycles run back to back while there is motion to execute
  /// (simulated time advances as fast as the machine allows) instead of one per period.
  bool lock_step = false;
  /// What an emergency stop does to the binary outputs (bit i = line i): the lines of
  /// `kept_outputs` stay as they are, every other line takes its state in `safe_outputs`
  /// (default: every line off). A release restores nothing.
  std::uint32_t safe_outputs = 0;
  std::uint32_t kept_outputs = 0;
  /// Motion before SYNCHRO (RELATIVE MOTOR and JOINT moves only, docs/edp.md): the fractions
  /// (0.01..1) of every joint's velocity and acceleration limit (`max_joint_velocity`,
  /// `max_joint_acceleration` of the model's parameters.toml) it keeps to, and the largest
  /// change of any joint one such move may ask for [rad | m] (joint limits cannot be checked
  /// before the position is known).
  double unsynchronised_velocity_fraction = 0.1;
  double unsynchronised_acceleration_fraction = 0.1;
  double unsynchronised_max_move = 0.1;
  Params params;  ///< the plugin's own parameters ([robot.edp.params])
  ProcessOptions options;
  SourceLocation where;
};

/// A task (MP or ECP): a name registered by a task plugin, its optional library, its arguments.
struct TaskConfig {
  std::string name;
  SourceLocation name_where;      ///< where `task` was given (for errors)
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
  std::filesystem::path scene;      ///< scene file (absolute path)
  bool lock_step = false;           ///< physics advances by SYNC, not by the wall clock
  std::vector<std::string> faults;  ///< fault injections, as `mrroc-axis-emu --fault` takes them
  ProcessOptions options;
  SourceLocation where;
};

/// A virtual sensor process ([[vsp]]; docs/sensors.md).
struct VspConfig {
  std::string name;                  ///< e.g. "wrist_force"; channels vsp/<name>/...
  std::string plugin;                ///< sensor plugin name, e.g. "force_torque"
  SourceLocation plugin_where;       ///< where `plugin` was given (for errors)
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
  std::filesystem::path file;     ///< absolute path of the config file
  std::string name;               ///< name of the set (for messages)
  std::string lcm_url;            ///< empty: $LCM_DEFAULT_URL or the ttl=0 default
  double ready_timeout_s = 10.0;  ///< how long the launcher waits for each process to be ready [s]
  /// Shared key (file with at least 32 hex digits) for message authentication; empty: none.
  std::filesystem::path auth_key_file;
  TaskConfig mp;
  /// [mp] start: "auto" runs the task at once; "operator" waits for START from mrroc-ui.
  bool mp_waits_for_operator = false;
  SrpConfig srp;
  UiConfig ui;
  LaunchConfig launch;
  std::optional<EmulatorConfig> emulator;  ///< started after the SRP, before the EDPs
  std::vector<RobotConfig> robots;
  std::vector<VspConfig> vsps;  ///< started after the emulator, before the EDPs
  /// The collision guard of the EDPs ([collision]; defaults when the set has none).
  CollisionConfig collision;

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

/// What `check_process_set` found: the config as far as it could be read, and every error.
struct ProcessSetCheck {
  /// Every table that could be read; a table with an error is read up to it (the rest keeps
  /// its defaults).
  ProcessSetConfig config;
  /// Every error of the file, each with its `file:line`, in the order found.
  std::vector<ConfigError> errors;
  /// The processes whose own tables have an error ("edp/irb6", "ecp/irb6", "vsp/camera", "mp",
  /// "emu"): their own checks (`--check-config`) are left out, the error is reported already.
  std::set<std::string> broken;

  [[nodiscard]] bool ok() const { return errors.empty(); }
  [[nodiscard]] bool broken_process(const std::string& process) const {
    return broken.count(process) != 0;
  }
};

/// Validates a process-set file as `load_process_set` does, with the same code, but reports
/// every error instead of the first: each table is read on its own (an error ends the reading
/// of its table, not of the file) and every unknown key is an error of its own. Never throws a
/// ConfigError (a file that does not parse as TOML is one error).
ProcessSetCheck check_process_set(const std::filesystem::path& file);
/// The same for `text` as the content of `file` (as `parse_process_set`).
ProcessSetCheck check_process_set_text(std::string_view text, const std::filesystem::path& file);

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
/// Robot state broadcast by the EDP (robot_state_t).
inline std::string robot_state(const std::string& robot) { return robot + "/edp/state"; }
/// Operator commands to the MP (operator_command_t / operator_reply_t).
inline constexpr const char* mp_command = "mrroc/mp/cmd";
inline constexpr const char* mp_reply = "mrroc/mp/reply";
/// The launcher's process table (launch_status_t).
inline constexpr const char* launch_status = "mrroc/launch/status";
/// The SRP's history (srp_history_request_t / srp_history_reply_t).
inline constexpr const char* srp_history_command = "mrroc/srp/history/cmd";
inline constexpr const char* srp_history_reply = "mrroc/srp/history/reply";
/// The cell emulator's scene objects and their poses (scene_objects_t).
inline constexpr const char* scene_objects = "mrroc/scene/objects";
}  // namespace channels

}  // namespace mrroc
