#pragma once
/// @file
/// One LCM connection per process, with the thread that dispatches incoming messages.
///
/// The comm layer (this folder) is the only code that sees LCM types. Handlers registered on the
/// bus run on the bus thread and must return quickly (they hand work to other threads).

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include <lcm/lcm-cpp.hpp>

namespace mrroc::comm {

class Authenticator;

/// A subscription made with Bus::subscribe (opaque; ended with Bus::unsubscribe).
class Subscription;

/// SRP codes of messages a process dropped (reported through the bus' drop sink).
namespace drop_code {
inline constexpr int malformed = 1;         ///< could not be decoded
inline constexpr int unauthenticated = 12;  ///< no or wrong HMAC, or a replayed counter
}  // namespace drop_code

/// The default LCM URL: multicast with ttl=0, so nothing leaves the host.
inline constexpr const char* kDefaultLcmUrl = "udpm://239.255.76.67:7667?ttl=0";

/// An LCM connection plus its dispatch thread.
class Bus {
 public:
  /// Opens the connection. An empty URL means `LCM_DEFAULT_URL` from the environment, else
  /// `kDefaultLcmUrl`. @throws mrroc::Error naming the URL when LCM cannot open it.
  explicit Bus(const std::string& url);
  ~Bus();
  Bus(const Bus&) = delete;
  Bus& operator=(const Bus&) = delete;

  /// Starts the dispatch thread (idempotent).
  void start();
  /// Stops and joins the dispatch thread (idempotent).
  void stop();

  /// Calls `handler(buffer, channel, context)` on the bus thread for every message on `channel`
  /// (an LCM regular expression). Safe from any thread, also while the bus runs: unlike LCM's
  /// C++ subscribeFunction, which registers its callback before it stores the handler the
  /// callback reads and keeps its subscriptions in a vector it does not guard, the handler is in
  /// place before LCM can call it and the bus' own list is locked.
  template <class Context>
  Subscription* subscribe(const std::string& channel,
                          void (*handler)(const lcm::ReceiveBuffer*, const std::string&, Context),
                          Context context) {
    return subscribe_function(
        channel, [handler, context](const lcm::ReceiveBuffer* buffer, const std::string& ch) {
          handler(buffer, ch, context);
        });
  }
  using Handler = std::function<void(const lcm::ReceiveBuffer*, const std::string&)>;
  Subscription* subscribe_function(const std::string& channel, Handler handler);
  /// Ends a subscription made with subscribe (null: nothing). Safe from any thread, also from a
  /// handler (its own or another's). When it returns, no call of the handler is in progress
  /// (but the caller's own, from a handler) and none begins.
  void unsubscribe(Subscription* subscription);

  [[nodiscard]] lcm::LCM& lcm() { return *lcm_; }
  [[nodiscard]] const std::string& url() const { return url_; }
  /// True when called from the dispatch thread (request/reply calls must not be made from there).
  [[nodiscard]] bool on_bus_thread() const;

  /// Signs every message sent through the comm layer with `key` and makes every request/reply
  /// endpoint drop (and report) messages without a valid tag (see auth.hpp). Call before any
  /// link is created on this bus.
  void enable_auth(std::vector<std::uint8_t> key);
  /// The authenticator, or null when the set runs without a key.
  [[nodiscard]] Authenticator* auth() const { return auth_.get(); }
  /// Several handlers of one process may receive the same message (e.g. two subscribers of a
  /// channel); its counter is recorded by the first check, so the others are told that check's
  /// verdict instead of "replayed". On the bus thread, for the message being dispatched: true
  /// and `verdict` set when a handler of it was already checked; never elsewhere.
  bool recall_verdict(const std::string& channel, const std::string& sender, std::int64_t counter,
                      int& verdict) const;
  void remember_verdict(const std::string& channel, const std::string& sender, std::int64_t counter,
                        int verdict);

  /// Where reports of dropped messages go (normally the process' Reporter, which installs
  /// itself): `code` is a drop_code, `text` names the channel, sender and reason.
  using DropSink = std::function<void(int code, const std::string& text)>;
  void set_drop_sink(DropSink sink);
  /// Reports a dropped message, rate-limited per `kind` (e.g. "malformed on irb6/edp/cmd"): the
  /// first at once, later ones at most every kDropReportPeriod, with the number dropped since.
  void report_drop(int code, const std::string& kind, const std::string& text);
  static constexpr std::chrono::seconds kDropReportPeriod{10};

  /// Publishes already encoded bytes after `delay` (link fault injection); messages still
  /// waiting when the bus stops are not sent.
  void publish_later(const std::string& channel, std::vector<std::uint8_t> bytes,
                     std::chrono::microseconds delay);

 private:
  struct Delayed {
    std::string channel;
    std::vector<std::uint8_t> bytes;
  };
  struct DropCount {
    std::chrono::steady_clock::time_point quiet_until{};
    std::uint64_t unreported = 0;
  };
  void run_delayer();

  std::string url_;
  std::unique_ptr<lcm::LCM> lcm_;
  std::thread thread_;
  std::atomic<bool> running_{false};
  std::unique_ptr<Authenticator> auth_;
  struct Verdict {
    std::uint64_t delivery = 0;
    std::string channel;
    std::string sender;
    std::int64_t counter = 0;
    int verdict = 0;
  };
  std::uint64_t delivery_ = 1;  ///< the message being dispatched (bus thread only)
  Verdict last_verdict_;        ///< bus thread only

  std::mutex drop_mutex_;
  DropSink drop_sink_;
  std::map<std::string, DropCount> drops_;

  std::mutex delay_mutex_;
  std::condition_variable delay_cv_;
  std::multimap<std::chrono::steady_clock::time_point, Delayed> delayed_;
  std::thread delayer_;
  bool delayer_stop_ = false;
  void end_retired();

  std::mutex subscriptions_mutex_;
  std::vector<std::unique_ptr<Subscription>> subscriptions_;
  /// Ended subscriptions whose LCM subscription the bus thread ends between two dispatches.
  std::vector<std::unique_ptr<Subscription>> retired_;
  bool dispatching_ = false;  ///< the bus thread runs (guarded by subscriptions_mutex_)
};

/// Resolves the URL the way Bus does (empty -> $LCM_DEFAULT_URL -> kDefaultLcmUrl).
std::string resolve_lcm_url(const std::string& url);

}  // namespace mrroc::comm
