#pragma once
/// @file
/// The launcher's messages as plain values: its process table (launch_status_t and
/// launch_process_t, channel mrroc/launch/status) and an operator's command to it
/// (launch_command_t, channel mrroc/launch/command).

#include <cstdint>
#include <string>
#include <vector>

namespace mrroc::launch {

/// One row of the table.
struct ProcessRow {
  std::string name;
  std::string group;
  std::string host = "local";
  /// "waiting", "starting", "running", "backoff", "exited", "failed", "stopped"
  std::string state = "waiting";
  int pid = 0;               ///< 0 when not running
  double cpu_percent = 0.0;  ///< over the last second (100 = one CPU)
  std::int64_t rss_kb = 0;   ///< resident memory [KiB]; 0 when unknown
  int restarts = 0;
  double uptime_s = 0.0;    ///< since the current start [s]
  int last_exit_code = -1;  ///< -1 when it has not ended yet
  bool required = true;
  std::string restart = "never";
  /// Read CPU and memory from /proc/<pid> (false for processes on another computer). The
  /// launcher's own: not sent (decoded as true).
  bool local_metrics = true;
};

/// The whole table.
struct LaunchStatus {
  std::int64_t utime = 0;  ///< time of sending [us since the Unix epoch] (header.utime)
  std::string set_name;
  std::string config_file;
  std::string state;  ///< "starting", "running", "stopping", "stopped"
  int launcher_pid = 0;
  double uptime_s = 0.0;
  std::vector<ProcessRow> processes;
};

enum class LaunchCommandType : std::int8_t {
  /// Acknowledge the restart of a process the launcher holds until an operator agrees.
  restart = 1,
};

/// An operator's command to the launcher of a set (launch_command_t).
struct LaunchCommand {
  std::string set_name;  ///< the set it is for: launchers of other sets ignore it
  LaunchCommandType type = LaunchCommandType::restart;
  std::string process;  ///< e.g. "edp/irb6"
};

}  // namespace mrroc::launch
