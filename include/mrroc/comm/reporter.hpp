#pragma once
/// @file
/// Messages for the System Response Process (SRP) and the status/heartbeat of a process.
///
/// Every process owns one `Reporter`: `report()` prints the message on the process' stderr and
/// publishes it on `mrroc/srp`; `set_state()` publishes the process status on `mrroc/status`
/// at once and then every second (heartbeat) until the reporter is destroyed.
///
/// No LCM here (the task contexts hand tasks a Reporter): the bus is only named.

#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <thread>

namespace mrroc::comm {
class Bus;
}  // namespace mrroc::comm

namespace mrroc {

enum class Severity : std::int8_t { debug = 0, info = 1, warning = 2, error = 3, fatal = 4 };
const char* to_string(Severity s);

enum class ProcessState : std::int8_t {
  starting = 1,
  ready = 2,
  running = 3,
  stopping = 4,
  failed = 5,
  finished = 6
};
const char* to_string(ProcessState s);

struct SrpMessage {
  std::int64_t utime = 0;  ///< [us since the Unix epoch]
  std::string process;     ///< e.g. "edp/irb6"
  std::string robot;
  Severity severity = Severity::info;
  int code = 0;
  std::string text;
};

struct ProcessStatus {
  std::int64_t utime = 0;
  std::string process;
  std::string robot;
  int pid = 0;
  ProcessState state = ProcessState::starting;
  std::int64_t uptime_us = 0;
  std::string detail;
};

class Reporter {
 public:
  /// @param process  process name as the SRP shows it ("mp", "ecp/irb6", "edp/irb6", ...)
  Reporter(comm::Bus& bus, std::string process, std::string robot = {});
  ~Reporter();
  Reporter(const Reporter&) = delete;
  Reporter& operator=(const Reporter&) = delete;

  void report(Severity severity, int code, const std::string& text);
  void info(const std::string& text) { report(Severity::info, 0, text); }
  void warning(const std::string& text) { report(Severity::warning, 0, text); }
  void error(int code, const std::string& text) { report(Severity::error, code, text); }

  /// Publishes the new state now (and in every heartbeat after).
  void set_state(ProcessState state, const std::string& detail = {});
  [[nodiscard]] ProcessState state() const;
  [[nodiscard]] const std::string& process() const { return process_; }

 private:
  void publish_status();
  comm::Bus& bus_;
  std::string process_;
  std::string robot_;
  std::string sender_;
  std::int64_t started_ns_;
  mutable std::mutex mutex_;
  std::condition_variable cv_;
  ProcessState state_ = ProcessState::starting;
  std::string detail_;
  std::int64_t seq_ = 0;
  bool stopping_ = false;
  std::thread heartbeat_;
};

/// Receives SRP messages and process statuses (callbacks run on the bus thread).
class SystemListener {
 public:
  using MessageHandler = std::function<void(const SrpMessage&)>;
  using StatusHandler = std::function<void(const ProcessStatus&)>;
  SystemListener(comm::Bus& bus, MessageHandler on_message, StatusHandler on_status);
  ~SystemListener();
  SystemListener(const SystemListener&) = delete;
  SystemListener& operator=(const SystemListener&) = delete;

  [[nodiscard]] std::uint64_t malformed() const { return malformed_.load(); }

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
  std::atomic<std::uint64_t> malformed_{0};
};

}  // namespace mrroc
