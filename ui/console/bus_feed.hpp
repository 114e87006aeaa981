#pragma once
// Feeds the console's state from the bus: each robot's state, the cell emulator's scene
// objects, the launcher's process table, SRP messages and process statuses (subscriptions, on the
// bus thread), the MP's state (STATUS every 400 ms) and the SRP's history (asked for every 2 s
// until it answers), on a poller thread. Every message arrives decoded and checked (comm/edge.hpp,
// comm/links.hpp).

#include <condition_variable>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "console/state.hpp"

namespace mrroc::comm {
class Bus;
}  // namespace mrroc::comm

namespace mrroc {
class SystemListener;
}

namespace mrroc::ui {

class BusFeed {
 public:
  /// Subscribes (before the bus starts, so that nothing is missed).
  /// @param no_mp_text  what the state shows when no MP answers STATUS
  BusFeed(comm::Bus& bus, ConsoleState& state, std::string no_mp_text);
  /// Stops the poller and unsubscribes; the bus must outlive it.
  ~BusFeed();
  BusFeed(const BusFeed&) = delete;
  BusFeed& operator=(const BusFeed&) = delete;

  /// Starts polling the MP and the SRP (the bus must be started).
  void start_polling();
  /// Ends the poller (also done by the destructor).
  void stop_polling();

 private:
  struct Subscribers;
  struct Clients;
  void poll_loop();
  void poll_mp();
  void fetch_history();

  ConsoleState& state_;
  std::string no_mp_text_;
  std::unique_ptr<Subscribers> subscribers_;
  std::unique_ptr<SystemListener> listener_;
  std::unique_ptr<Clients> clients_;
  std::thread poller_;
  std::mutex poll_mutex_;
  std::condition_variable poll_cv_;
  bool poll_stop_ = false;
};

}  // namespace mrroc::ui
