#pragma once
/// @file
/// Small helpers every process binary uses: stop signals, CPU affinity, memory locking.

#include <string>
#include <vector>

namespace mrroc {

/// SIGINT and SIGTERM set a flag (read with `stop_requested`) instead of killing the process.
void install_stop_handlers();
[[nodiscard]] bool stop_requested();
void request_stop();

/// Pins the calling process to `cpus` (no-op when empty). @throws Error naming the CPUs.
void apply_cpu_affinity(const std::vector<int>& cpus);

/// Tries `mlockall(MCL_CURRENT | MCL_FUTURE)`; returns what happened, for the log.
std::string lock_memory();

}  // namespace mrroc
