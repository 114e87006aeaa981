#pragma once
/// @file
/// One LCM connection per process, with the thread that dispatches incoming messages.
///
/// The comm layer (this folder) is the only code that sees LCM types. Handlers registered on the bus
/// run on the bus thread and must return quickly (they hand work to other threads).

#include <atomic>
#include <memory>
#include <string>
#include <thread>

#include <lcm/lcm-cpp.hpp>

namespace mrroc::comm {

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

  [[nodiscard]] lcm::LCM& lcm() { return *lcm_; }
  [[nodiscard]] const std::string& url() const { return url_; }
  /// True when called from the dispatch thread (request/reply calls must not be made from there).
  [[nodiscard]] bool on_bus_thread() const;

 private:
  std::string url_;
  std::unique_ptr<lcm::LCM> lcm_;
  std::thread thread_;
  std::atomic<bool> running_{false};
};

/// Resolves the URL the way Bus does (empty -> $LCM_DEFAULT_URL -> kDefaultLcmUrl).
std::string resolve_lcm_url(const std::string& url);

}  // namespace mrroc::comm
