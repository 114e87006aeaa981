#pragma once
/// @file
/// The launcher's process table: what `mrroc-launch` broadcasts as launch_status_t on
/// `channels::launch_status` every second and on every change, and what
/// `mrroc-launch status` prints (the table's types are in mrroc/msg/launch.hpp).

#include <sys/types.h>

#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <functional>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "mrroc/comm/bus.hpp"
#include "mrroc/msg/launch.hpp"

namespace mrroc::launch {

/// CPU time of a process so far [clock ticks] (utime + stime of /proc/<pid>/stat); nullopt
/// when it cannot be read.
std::optional<std::uint64_t> process_cpu_ticks(pid_t pid);
/// Resident memory of a process [KiB] (/proc/<pid>/statm); nullopt when it cannot be read.
std::optional<std::int64_t> process_rss_kb(pid_t pid);

/// The table as text: one header line and one line per process.
std::string format_status_table(const LaunchStatus& status);

/// Holds the table and broadcasts it from its own thread (every second, and within about
/// 50 ms of every change). CPU % and RSS are measured by that thread once a second.
class StatusBoard {
 public:
  StatusBoard(comm::Bus& bus, LaunchStatus initial);
  /// Publishes a last table with state "stopped" and joins the thread.
  ~StatusBoard();
  StatusBoard(const StatusBoard&) = delete;
  StatusBoard& operator=(const StatusBoard&) = delete;

  /// Changes the row of `name` (under the board's lock) and publishes soon.
  void update(const std::string& name, const std::function<void(ProcessRow&)>& change);
  /// Sets the state of the whole set and publishes soon.
  void set_state(const std::string& state);
  [[nodiscard]] LaunchStatus snapshot() const;

 private:
  void run();
  void publish(const LaunchStatus& status);

  comm::Bus& bus_;
  mutable std::mutex mutex_;
  std::condition_variable cv_;
  LaunchStatus status_;
  std::vector<std::chrono::steady_clock::time_point> started_;  // per row, of the current start
  bool changed_ = true;
  bool stopping_ = false;
  std::int64_t seq_ = 0;
  std::chrono::steady_clock::time_point t0_;
  std::thread thread_;
};

/// Listens on `bus` for up to `timeout` for the table of the set named `set_name` (any set
/// when empty). The bus must not be started yet (this starts and stops it).
std::optional<LaunchStatus> receive_status(comm::Bus& bus, const std::string& set_name,
                                           std::chrono::milliseconds timeout);

}  // namespace mrroc::launch
