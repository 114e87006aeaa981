#include "status_board.hpp"

#include <unistd.h>

#include <fstream>
#include <map>
#include <sstream>

#include <fmt/format.h>

#include "mrroc/comm/edge.hpp"
#include "mrroc/config/process_set.hpp"
#include "mrroc/core/time.hpp"

namespace mrroc::launch {

namespace {

using Clock = std::chrono::steady_clock;
}  // namespace

std::optional<std::uint64_t> process_cpu_ticks(pid_t pid) {
  std::ifstream in(fmt::format("/proc/{}/stat", pid));
  std::string text;
  if (!std::getline(in, text)) return std::nullopt;
  // The command name (field 2) may hold spaces and parentheses: fields follow the last ')'.
  const std::size_t close = text.rfind(')');
  if (close == std::string::npos) return std::nullopt;
  std::istringstream fields(text.substr(close + 1));
  std::string field;
  std::uint64_t utime = 0;
  std::uint64_t stime = 0;
  // Field 3 is the state; utime and stime are fields 14 and 15.
  for (int i = 3; i <= 15; ++i) {
    if (!(fields >> field)) return std::nullopt;
    try {
      if (i == 14) utime = std::stoull(field);
      if (i == 15) stime = std::stoull(field);
    } catch (const std::exception&) {
      return std::nullopt;
    }
  }
  return utime + stime;
}

std::optional<std::int64_t> process_rss_kb(pid_t pid) {
  std::ifstream in(fmt::format("/proc/{}/statm", pid));
  std::int64_t size = 0;
  std::int64_t resident = 0;
  if (!(in >> size >> resident)) return std::nullopt;
  return resident * (::sysconf(_SC_PAGESIZE) / 1024);
}

std::string format_status_table(const LaunchStatus& s) {
  std::string out = fmt::format("set '{}' ({}): {}, launcher pid {}, up {:.1f} s\n", s.set_name,
                                s.config_file, s.state, s.launcher_pid, s.uptime_s);
  std::size_t width = 4;
  for (const auto& r : s.processes) width = std::max(width, r.name.size());
  out += fmt::format("{:<{}}  {:<8} {:<8} {:<8} {:>7} {:>6} {:>9} {:>8} {:>9} {:>4} {:<8} {}\n",
                     "NAME", width, "GROUP", "HOST", "STATE", "PID", "CPU%", "RSS[KiB]", "RESTARTS",
                     "UPTIME[s]", "EXIT", "REQUIRED", "RESTART");
  for (const auto& r : s.processes) {
    out += fmt::format(
        "{:<{}}  {:<8} {:<8} {:<8} {:>7} {:>6.1f} {:>9} {:>8} {:>9.1f} {:>4} {:<8} {}\n", r.name,
        width, r.group, r.host, r.state, r.pid > 0 ? std::to_string(r.pid) : "-", r.cpu_percent,
        r.rss_kb > 0 ? std::to_string(r.rss_kb) : "-", r.restarts, r.uptime_s,
        r.last_exit_code >= 0 ? std::to_string(r.last_exit_code) : "-", r.required ? "yes" : "no",
        r.restart);
  }
  return out;
}

StatusBoard::StatusBoard(comm::Bus& bus, LaunchStatus initial)
    : bus_(bus), status_(std::move(initial)), t0_(Clock::now()) {
  started_.assign(status_.processes.size(), t0_);
  thread_ = std::thread([this] { run(); });
}

StatusBoard::~StatusBoard() {
  {
    std::lock_guard lock(mutex_);
    stopping_ = true;
    status_.state = "stopped";
  }
  cv_.notify_all();
  thread_.join();
}

void StatusBoard::update(const std::string& name, const std::function<void(ProcessRow&)>& change) {
  {
    std::lock_guard lock(mutex_);
    for (std::size_t i = 0; i < status_.processes.size(); ++i) {
      ProcessRow& r = status_.processes[i];
      if (r.name != name) continue;
      const int old_pid = r.pid;
      change(r);
      if (r.pid != old_pid && r.pid != 0) {
        started_[i] = Clock::now();
        r.cpu_percent = 0.0;
      }
      if (r.pid == 0) {
        r.cpu_percent = 0.0;
        r.rss_kb = 0;
      }
    }
    changed_ = true;
  }
  cv_.notify_all();
}

void StatusBoard::set_state(const std::string& state) {
  {
    std::lock_guard lock(mutex_);
    status_.state = state;
    changed_ = true;
  }
  cv_.notify_all();
}

LaunchStatus StatusBoard::snapshot() const {
  std::lock_guard lock(mutex_);
  return status_;
}

void StatusBoard::publish(const LaunchStatus& status) {
  comm::broadcast(
      bus_, channels::launch_status,
      comm::Envelope{status.utime, fmt::format("mrroc-launch/{}", status.launcher_pid), ++seq_},
      status);
}

void StatusBoard::run() {
  const double ticks_per_s = static_cast<double>(::sysconf(_SC_CLK_TCK));
  std::map<int, std::pair<std::uint64_t, Clock::time_point>> last_cpu;  // by pid
  auto next_sample = Clock::now();
  std::unique_lock lock(mutex_);
  for (;;) {
    cv_.wait_until(lock, next_sample, [&] { return changed_ || stopping_; });
    const auto now = Clock::now();
    if (now >= next_sample) {
      next_sample = now + std::chrono::seconds(1);
      std::vector<std::pair<std::size_t, int>> pids;
      for (std::size_t i = 0; i < status_.processes.size(); ++i) {
        const ProcessRow& r = status_.processes[i];
        if (r.pid > 0 && r.local_metrics) pids.emplace_back(i, r.pid);
      }
      lock.unlock();  // reading /proc takes a moment; the table may change meanwhile
      std::map<int, std::pair<std::optional<double>, std::optional<std::int64_t>>> measured;
      std::map<int, std::pair<std::uint64_t, Clock::time_point>> cpu_now;
      for (const auto& [i, pid] : pids) {
        std::optional<double> percent;
        if (const auto ticks = process_cpu_ticks(pid)) {
          cpu_now[pid] = {*ticks, now};
          if (auto it = last_cpu.find(pid); it != last_cpu.end() && *ticks >= it->second.first) {
            const double wall = std::chrono::duration<double>(now - it->second.second).count();
            if (wall > 0.05)
              percent = 100.0 * static_cast<double>(*ticks - it->second.first) / ticks_per_s / wall;
          }
        }
        measured[pid] = {percent, process_rss_kb(pid)};
      }
      last_cpu = std::move(cpu_now);
      lock.lock();
      for (auto& r : status_.processes) {
        auto it = measured.find(r.pid);
        if (r.pid <= 0 || it == measured.end()) continue;
        if (it->second.first) r.cpu_percent = *it->second.first;
        if (it->second.second) r.rss_kb = *it->second.second;
      }
    }
    changed_ = false;
    // A process started since the last sample shows its memory at once (CPU needs two samples).
    for (auto& r : status_.processes)
      if (r.pid > 0 && r.local_metrics && r.rss_kb == 0)
        if (const auto rss = process_rss_kb(r.pid)) r.rss_kb = *rss;
    status_.utime = now_utime();
    status_.uptime_s = std::chrono::duration<double>(now - t0_).count();
    for (std::size_t i = 0; i < status_.processes.size(); ++i) {
      ProcessRow& r = status_.processes[i];
      r.uptime_s = r.pid > 0 ? std::chrono::duration<double>(now - started_[i]).count() : 0.0;
    }
    const LaunchStatus copy = status_;
    const bool last = stopping_;
    lock.unlock();
    publish(copy);
    if (last) return;
    // Changes closer together than this are published together.
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
    lock.lock();
  }
}

std::optional<LaunchStatus> receive_status(comm::Bus& bus, const std::string& set_name,
                                           std::chrono::milliseconds timeout) {
  struct Inbox {
    std::mutex mutex;
    std::condition_variable cv;
    std::optional<LaunchStatus> status;
    std::string wanted;
  } inbox;
  inbox.wanted = set_name;
  std::optional<comm::Subscriber<LaunchStatus>> tables;
  tables.emplace(
      bus, channels::launch_status,
      [&inbox](const LaunchStatus& s, const comm::Received&) {
        if (!inbox.wanted.empty() && s.set_name != inbox.wanted) return;
        std::lock_guard lock(inbox.mutex);
        inbox.status = s;
        inbox.cv.notify_all();
      },
      comm::SubscriberOptions::unreported());
  bus.start();
  std::optional<LaunchStatus> result;
  {
    std::unique_lock lock(inbox.mutex);
    inbox.cv.wait_for(lock, timeout, [&] { return inbox.status.has_value(); });
    result = inbox.status;
  }
  bus.stop();
  tables.reset();
  return result;
}

}  // namespace mrroc::launch
