#pragma once
/// @file
/// The emergency stop's latch, held by mrroc-launch (which outlives EDP restarts), and the check
/// that no other process set runs on the set's LCM URL.
///
/// EstopLatch follows the operators' ENGAGE / RELEASE on `mrroc/estop` by the EDP's rules (ENGAGE
/// from anybody, RELEASE only when authentic, in the order they arrive, each command once:
/// comm::EstopRecord), keeps the state per robot of the set, and announces it every kPeriod (and
/// at once on every command it obeys) as one emergency_stop_t per robot, signed when the set has
/// a key: ENGAGED naming the ENGAGEs it holds, or RELEASED naming the RELEASE that set it and the
/// ENGAGEs that RELEASE ended. An EDP that starts hears it within a period and starts stopped or
/// released accordingly (edp/estop_listener.hpp, docs/operating.md "Emergency stop").

#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <functional>
#include <map>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "mrroc/comm/bus.hpp"
#include "mrroc/comm/edge.hpp"
#include "mrroc/comm/estop_record.hpp"
#include "mrroc/msg/emergency_stop.hpp"

namespace mrroc::launch {

class EstopLatch {
 public:
  /// How often the state is announced.
  static constexpr std::chrono::milliseconds kPeriod{150};
  /// How often while EDPs start (set_starting): a starting EDP holds its robot stopped until it
  /// hears the state, which took it 75 ms on average at kPeriod.
  static constexpr std::chrono::milliseconds kStartingPeriod{20};
  /// `log` gets one line per change of the latched state.
  EstopLatch(comm::Bus& bus, std::vector<std::string> robots,
             std::function<void(const std::string&)> log);
  ~EstopLatch();
  EstopLatch(const EstopLatch&) = delete;
  EstopLatch& operator=(const EstopLatch&) = delete;

  /// True when the stop of `robot` is latched engaged.
  [[nodiscard]] bool engaged(const std::string& robot) const;

  /// Announces every kStartingPeriod instead of kPeriod while `starting` (EDPs are starting).
  void set_starting(bool starting);

 private:
  struct Latched {
    comm::EstopRecord record;            ///< engaged while it holds an ENGAGE
    EstopCommandRef by;                  ///< the command that set the state (empty: start)
    std::vector<EstopCommandRef> ended;  ///< released: the ENGAGEs the last RELEASE ended
    std::string reason;
  };
  void on_command(EstopAction action, const std::string& robot, const std::string& reason,
                  const EstopCommandRef& command);
  void announce();
  void run();

  comm::Bus& bus_;
  const std::string sender_;
  std::function<void(const std::string&)> log_;
  std::optional<comm::Subscriber<EmergencyStop>> commands_;
  mutable std::mutex mutex_;
  std::condition_variable cv_;
  std::map<std::string, Latched> robots_;
  bool changed_ = false;
  bool starting_ = false;
  bool stop_ = false;
  std::thread thread_;
};

/// What runs on an LCM URL, as heard by running_set().
struct RunningSet {
  std::string launcher;           ///< e.g. "launcher pid 41 ('launch#41'), set 'demo-irb6' from F"
  std::vector<std::string> edps;  ///< e.g. "EDP of robot irb6 ('edp/irb6#57')"
  [[nodiscard]] std::string describe() const;
};

/// How long mrroc-launch listens for a running set before it starts anything: a running set's
/// latch announces every robot's stop every EstopLatch::kPeriod (heard twice in this time), its
/// EDPs broadcast their states every 20 ms.
inline constexpr std::chrono::milliseconds kRunningSetListen{300};
/// After traffic of a running set was heard: how much longer it waits for that set's launcher
/// table (broadcast every second) to name its config file.
inline constexpr std::chrono::milliseconds kRunningSetNameWait{1100};

/// Listens on the (started) bus for a running set, sending nothing: another launcher's table
/// (launch_status_t) or stop announcements, or robot_state_t of one of `robots`. Nothing when
/// the URL is quiet. On a bus with a key (comm::Bus::auth) only messages signed with it count:
/// the others cannot keep a set from starting; they are listed in `ignored` (what and from
/// whom, e.g. "the state of robot irb6 from 'edp/irb6#7'") when it is given.
std::optional<RunningSet> running_set(comm::Bus& bus, const std::vector<std::string>& robots,
                                      std::vector<std::string>* ignored = nullptr);

}  // namespace mrroc::launch
