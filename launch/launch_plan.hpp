#pragma once
/// @file
/// What `mrroc-launch` starts, in which order and how: the plan built from a process-set
/// config (docs/configs.md). Pure functions, no side effects (used by `--check` and the tests).

#include <signal.h>

#include <filesystem>
#include <string>
#include <string_view>
#include <vector>

#include "mrroc/config/process_set.hpp"
#include "supervisor.hpp"

namespace mrroc::launch {

/// One process of the plan.
struct PlannedProcess {
  std::string name;   ///< as in its status messages and the output prefix: "edp/irb6"
  std::string group;  ///< ProcessOptions::group ("edp", "record", ...)
  std::string host;   ///< "local" or a [[launch.host]] name
  ProcessOptions options;
  /// False for processes that publish no process_status_t (lcm-logger): they count as ready
  /// once they run for a moment.
  bool reports_ready = true;
  /// The process' own command line (before host templating).
  std::vector<std::string> command;
  /// True for an EDP. Its restart policy waits, after each end, for an operator's
  /// acknowledgement (`mrroc-ui restart`) before the back-off starts when its hardware plugin
  /// declares that it drives real devices (edp::Hardware::drives_real_devices), which the EDP
  /// says in its ready status and in `--check-config`, and when it said nothing.
  bool edp = false;
  /// The EDP's declaration when known, e.g. "plugin 'can' drives real devices" (--check fills
  /// it from the EDP's --check-config; a running set from its ready status).
  std::string devices;
  /// What the supervisor runs: the command, for another host wrapped in its start command with
  /// the environment in front (`env NAME=value ... program args`); log file, stop signal and
  /// grace period filled in.
  ChildSpec spec;
};

/// Launcher options given on the command line.
struct PlanOptions {
  std::filesystem::path bin_dir;  ///< where the mrroc-* executables are
  std::string srp_log;            ///< --srp-log (empty: none)
  std::filesystem::path record;   ///< --record, else [launch] record (empty: none)
};

/// The processes in start order: record (lcm-logger), srp, emu, vsp/*, edp/*, ecp/*, ui (when
/// [ui] web = true), mp. Stopping goes in reverse order.
/// @throws mrroc::Error when a process names an unknown host (load_process_set checks that).
std::vector<PlannedProcess> make_plan(const ProcessSetConfig& config, const PlanOptions& options);

/// Whether an EDP's declaration ("plugin 'X' drives real devices" / "... drives no real
/// devices", PlannedProcess::devices) says that it drives real devices.
bool declares_real_devices(std::string_view declaration);

/// `word` quoted for a POSIX shell (unchanged when it has only safe characters).
std::string shell_quote(std::string_view word);

/// How the remote side of an ssh host stops its program (`host_command`).
struct RemoteStop {
  int signal = SIGTERM;  ///< sent when the connection's input ends
  double grace_s = 3.0;  ///< then SIGKILL after this many seconds (rounded up)
};

/// The POSIX sh script that runs a program on an ssh host (`host_command`), arguments
/// `SIGNAL GRACE PROGRAM ARGS...`: it runs the program with stdin from /dev/null and, in the
/// background, reads its own stdin (the ssh connection's) until it ends; then it sends SIGNAL
/// (a name such as TERM) to its process group (the program, its children and the script),
/// and SIGKILL GRACE seconds later if the program is still there (which ends the script too).
/// Otherwise it exits with the program's exit status. The connection's input ends when the
/// launcher closes it to stop the process, when the ssh client ends (killed, or the launcher
/// gone) and when sshd finds the connection lost.
std::string_view remote_stop_script();

/// The argv that runs `command` (with `env`, "NAME=value") on `host`: the host's start command
/// with "{host}" replaced by its address, then `env NAME=value ... command...`.
///  - ssh (`is_ssh_command`): "--" in front of the word with "{host}" unless the command has a
///    "--" already (an address is never taken for an option), then one shell-quoted word for
///    the remote shell, whatever `quote` says: `exec sh -c SCRIPT mrroc-remote SIGNAL GRACE
///    env ... command...` (`remote_stop_script`, with `stop`'s signal and grace).
///  - another command: `env ... command...` as separate words, or (quote = true) as one
///    shell-quoted word.
std::vector<std::string> host_command(const HostConfig& host, const std::vector<std::string>& env,
                                      const std::vector<std::string>& command,
                                      const RemoteStop& stop = {});

/// The log file of a process: log_dir/<name with '/' as '_'>.log ("edp/irb6" -> edp_irb6.log).
std::filesystem::path log_file_of(const std::filesystem::path& log_dir, const std::string& name);

/// The multicast TTL of an LCM URL's `ttl=N` parameter (0 when it has none: LCM's default).
int lcm_url_ttl(const std::string& url);

/// A warning when the set's messages can reach other computers (`ttl` > 0 in its LCM URL, or a
/// [[launch.host]]) while it has no [system] auth_key_file: then anyone on that network can
/// command its processes, release an emergency stop and forge their states. Empty otherwise.
/// `mrroc-launch` prints it at every start and with --check.
std::string unprotected_network_warning(const ProcessSetConfig& config);

/// "SIGTERM", "SIGINT", ... (or "signal N").
std::string signal_text(int signal);

}  // namespace mrroc::launch
