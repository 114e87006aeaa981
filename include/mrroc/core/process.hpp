#pragma once
/// @file
/// Small helpers every process binary uses: stop signals, CPU affinity, real-time priority,
/// memory locking.

#include <filesystem>
#include <string>
#include <vector>

namespace mrroc {

/// SIGINT, SIGTERM and SIGHUP set a flag (read with `stop_requested`) instead of killing the
/// process: a process whose terminal or connection hangs up stops as a stopped one does.
void install_stop_handlers();
[[nodiscard]] bool stop_requested();
void request_stop();

/// Pins the calling process to `cpus` (no-op when empty). @throws Error naming the CPUs.
void apply_cpu_affinity(const std::vector<int>& cpus);

/// Puts the calling thread, and every thread it starts afterwards, in SCHED_FIFO at `priority`
/// (1..79; 0 keeps the policy the process was started with). Call it first in main(), before any
/// thread exists. Returns the policy now in force, for the ready message: "SCHED_FIFO 50",
/// "SCHED_OTHER" or, when the system refuses (no CAP_SYS_NICE, RLIMIT_RTPRIO),
/// "SCHED_OTHER (SCHED_FIFO 50 refused: ...)". Never throws.
std::string apply_priority(int priority);

/// Tries `mlockall(MCL_CURRENT | MCL_FUTURE)`; returns what happened, for the log.
std::string lock_memory();

/// Refuses a secret (`what`, e.g. "authentication key file") that other users may read or write:
/// any group or other permission bit, as ssh does for private keys.
/// @throws Error naming the file, its mode and the command that fixes it.
void require_private_file(const std::filesystem::path& file, const std::string& what);

}  // namespace mrroc
