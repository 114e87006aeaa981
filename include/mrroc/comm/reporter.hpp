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

#include "mrroc/msg/system.hpp"

namespace mrroc::comm {
class Bus;
}  // namespace mrroc::comm

namespace mrroc {

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

/// Receives SRP messages and process statuses (callbacks run on the bus thread). When the bus
/// has a key (comm/auth.hpp), a status that is not authentic is dropped (counted and reported:
/// the launcher, the console and the SRP act on statuses), and an SRP message that is not
/// authentic is handed over with kUnverifiedMark in front of its text.
class SystemListener {
 public:
  static constexpr const char* kUnverifiedMark = "(unverified sender) ";
  using MessageHandler = std::function<void(const SrpMessage&)>;
  using StatusHandler = std::function<void(const ProcessStatus&)>;
  SystemListener(comm::Bus& bus, MessageHandler on_message, StatusHandler on_status);
  ~SystemListener();
  SystemListener(const SystemListener&) = delete;
  SystemListener& operator=(const SystemListener&) = delete;

  /// Messages dropped because they did not decode or had an unknown severity or state.
  [[nodiscard]] std::uint64_t malformed() const;
  /// Statuses dropped and SRP messages marked because they were not authentic.
  [[nodiscard]] std::uint64_t unauthenticated() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace mrroc
