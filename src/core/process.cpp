#include "mrroc/core/process.hpp"

#include <sched.h>
#include <sys/mman.h>
#include <sys/stat.h>

#include <atomic>
#include <cerrno>
#include <csignal>
#include <cstring>

#include <fmt/format.h>

#include "mrroc/core/error.hpp"

namespace mrroc {

namespace {
std::atomic<bool> g_stop{false};
extern "C" void on_stop_signal(int) { g_stop.store(true); }
}  // namespace

void install_stop_handlers() {
  struct sigaction sa {};
  sa.sa_handler = on_stop_signal;
  sigemptyset(&sa.sa_mask);
  sigaction(SIGINT, &sa, nullptr);
  sigaction(SIGTERM, &sa, nullptr);
  sigaction(SIGHUP, &sa, nullptr);
  std::signal(SIGPIPE, SIG_IGN);
}

bool stop_requested() { return g_stop.load(); }
void request_stop() { g_stop.store(true); }

void apply_cpu_affinity(const std::vector<int>& cpus) {
  if (cpus.empty()) return;
  cpu_set_t set;
  CPU_ZERO(&set);
  for (int c : cpus) CPU_SET(static_cast<std::size_t>(c), &set);
  if (sched_setaffinity(0, sizeof set, &set) != 0)
    throw Error(fmt::format("cannot pin the process to CPUs {}: {}", fmt::join(cpus, ","),
                            std::strerror(errno)));
}

std::string apply_priority(int priority) {
  if (priority <= 0) {
    sched_param current{};
    if ((sched_getscheduler(0) & ~SCHED_RESET_ON_FORK) == SCHED_FIFO &&
        sched_getparam(0, &current) == 0)
      return fmt::format("SCHED_FIFO {} (inherited)", current.sched_priority);
    return "SCHED_OTHER";
  }
  sched_param sp{};
  sp.sched_priority = priority;
  // Children (none of ours start any) would not inherit it.
  if (sched_setscheduler(0, SCHED_FIFO | SCHED_RESET_ON_FORK, &sp) == 0)
    return fmt::format("SCHED_FIFO {}", priority);
  return fmt::format("SCHED_OTHER (SCHED_FIFO {} refused: {})", priority, std::strerror(errno));
}

std::string lock_memory() {
  if (mlockall(MCL_CURRENT | MCL_FUTURE) == 0) return "memory locked (mlockall)";
  return fmt::format("memory not locked (mlockall: {})", std::strerror(errno));
}

void require_private_file(const std::filesystem::path& file, const std::string& what) {
  struct stat st {};
  if (::stat(file.c_str(), &st) != 0)
    throw Error(
        fmt::format("{} '{}' cannot be read: {}", what, file.string(), std::strerror(errno)));
  const unsigned mode = static_cast<unsigned>(st.st_mode) & 0777U;
  if ((mode & 0077U) != 0)
    throw Error(
        fmt::format("{} '{}' has mode {:04o}: other users may read it; a secret must be "
                    "readable by its owner only (chmod 600 '{}')",
                    what, file.string(), mode, file.string()));
}

}  // namespace mrroc
