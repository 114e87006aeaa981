#pragma once
/// @file
/// The EDP's emergency-stop listener: its own LCM socket (a Bus of its own on the set's URL,
/// never started: its thread is the listener's) and its own thread at SCHED_FIFO priority, above
/// the EDP's command threads and at most the servo thread's 80. It engages the stop of the servo
/// loop when it is created (an EDP starts stopped) and then follows `emergency_stop_t` on
/// `mrroc/estop` (docs/messages.md, docs/operating.md "Emergency stop"):
///  - ENGAGE (an operator's command, from anybody: stopping is always safe) stops at once;
///  - RELEASE (an operator's command) releases when it is authentic (with the set's key);
///  - ENGAGED (the latch holder's announcement, from anybody) stops, unless every ENGAGE it names
///    was released here already;
///  - RELEASED (the latch holder's announcement) releases when it is authentic and names as ended
///    every ENGAGE this EDP holds (or the EDP holds none: the hold it started in), so a latch that
///    missed an ENGAGE cannot undo it.
/// Commands are named by sender and number and followed in the order they arrive
/// (comm::EstopRecord): no sender's clock orders anything.
/// After hold_for_shutdown() nothing releases the stop any more.

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <filesystem>
#include <mutex>
#include <optional>
#include <string>
#include <thread>

#include "mrroc/comm/bus.hpp"
#include "mrroc/comm/edge.hpp"
#include "mrroc/comm/estop_record.hpp"
#include "mrroc/msg/emergency_stop.hpp"
#include "servo_loop.hpp"

namespace mrroc::edp {

class EstopListener {
 public:
  /// How long an EDP waits at start for the stop's state before it reports ready (stopped).
  static constexpr std::chrono::milliseconds kStateWait{500};

  /// Opens the socket (with the set's key when `auth_key_file` is not empty), engages the stop of
  /// `servo` and starts the thread at SCHED_FIFO `priority` (1..99; falls back to the normal
  /// scheduler without the privilege: see scheduling()). Dropped messages go to `drop_sink`.
  EstopListener(ServoLoop& servo, std::string robot, const std::string& lcm_url,
                const std::filesystem::path& auth_key_file, int priority,
                comm::Bus::DropSink drop_sink);
  ~EstopListener();
  EstopListener(const EstopListener&) = delete;
  EstopListener& operator=(const EstopListener&) = delete;

  /// Waits until the stop's state was heard (an announcement or an operator's command for this
  /// robot) or `timeout` passed; true when it was heard.
  bool wait_state(std::chrono::milliseconds timeout);
  /// "SCHED_FIFO 70" or "SCHED_OTHER (SCHED_FIFO 70 refused: Operation not permitted)".
  [[nodiscard]] std::string scheduling() const;
  /// Why the stop is engaged now (for the SRP), e.g. "operator (from ui#12)".
  [[nodiscard]] std::string reason() const;
  /// Who announced the state last ("launch#41"), empty when no announcement was heard.
  [[nodiscard]] std::string announcer() const;
  /// Engages the stop for good (the EDP is stopping): no message releases it any more.
  void hold_for_shutdown();
  /// The SCHED_FIFO priority of the listener for command threads at `command_priority`.
  static int priority_for(int command_priority);

 private:
  void run();
  void on_message(const EmergencyStop& m, const comm::Received& in);
  void engage(const std::string& why, bool only_if_released);
  /// Releases the servo loop's stop (with mutex_ held).
  void release_locked();

  ServoLoop& servo_;
  const std::string robot_;
  comm::Bus bus_;
  const int priority_;
  std::atomic<bool> stop_{false};
  std::thread thread_;

  mutable std::mutex mutex_;
  std::condition_variable heard_cv_;
  bool heard_ = false;
  bool shutdown_ = false;
  comm::EstopRecord record_;  ///< the ENGAGEs this EDP obeyed and holds
  std::string reason_;
  /// True while the EDP holds only because it started stopped (no stop of anyone's yet).
  bool starting_hold_ = true;
  std::string announcer_;
  std::string scheduling_;
  std::optional<comm::Subscriber<EmergencyStop>> subscriber_;
};

}  // namespace mrroc::edp
