#include "mrroc/comm/bus.hpp"

#include <unistd.h>
#include <atomic>
#include <condition_variable>
#include <mutex>

#include <fmt/format.h>

#include <cstdlib>

#include "mrroc/comm/auth.hpp"
#include "mrroc/comm/request_reply.hpp"
#include "mrroc/comm/sync_annotations.hpp"
#include "mrroc/core/error.hpp"

namespace mrroc::comm {

class Subscription {
 public:
  explicit Subscription(Bus::Handler h) : handler(std::move(h)) {}
  /// LCM's C callback: the handler was stored before lcm_subscribe (see subscribe_function).
  static void on_message(const lcm_recv_buf_t* rbuf, const char* channel, void* user) {
    auto* self = static_cast<Subscription*>(user);
#if defined(__SANITIZE_THREAD__)
    __tsan_acquire(self);
#endif
    {
      std::lock_guard lock(self->state_mutex);
      if (self->ended) return;
      self->running = true;
    }
    struct Done {
      Subscription* s;
      ~Done() {
        {
          std::lock_guard lock(s->state_mutex);
          s->running = false;
        }
        s->idle.notify_all();
      }
    } done{self};
    const lcm::ReceiveBuffer buffer{rbuf->data, rbuf->data_size, rbuf->recv_utime};
    self->handler(&buffer, std::string(channel));
  }
  Bus::Handler handler;
  lcm_subscription_t* c_subscription = nullptr;
  /// Guards `ended` and `running`: LCM calls handlers without holding a lock of its own, so
  /// Bus::unsubscribe waits here for a call in progress.
  std::mutex state_mutex;
  std::condition_variable idle;
  bool ended = false;
  bool running = false;
};

namespace {
thread_local bool t_on_bus_thread = false;
}

Subscription* Bus::subscribe_function(const std::string& channel, Handler handler) {
  auto owned = std::make_unique<Subscription>(std::move(handler));
  Subscription* s = owned.get();
  // LCM keeps its handlers behind GLib locks that ThreadSanitizer cannot see: what was stored
  // above happens-before the callback. No lock of ours is held while LCM takes its own (a handler
  // runs under LCM's lock and may subscribe).
#if defined(__SANITIZE_THREAD__)
  __tsan_release(s);
#endif
  s->c_subscription =
      lcm_subscribe(lcm_->getUnderlyingLCM(), channel.c_str(), &Subscription::on_message, s);
  if (s->c_subscription == nullptr)
    throw Error("cannot subscribe to LCM channel '" + channel + "'");
  std::lock_guard lock(subscriptions_mutex_);
  subscriptions_.push_back(std::move(owned));
  return s;
}

void Bus::unsubscribe(Subscription* subscription) {
  if (subscription == nullptr) return;
  std::unique_ptr<Subscription> owned;
  {
    std::lock_guard lock(subscriptions_mutex_);
    for (auto it = subscriptions_.begin(); it != subscriptions_.end(); ++it) {
      if (it->get() != subscription) continue;
      owned = std::move(*it);
      subscriptions_.erase(it);
      break;
    }
  }
  if (!owned) return;
  {
    // LCM (1.3) runs a handler with its own lock released: a call in progress on the bus thread
    // is waited for here, and none begins after this block. On the bus thread the only call in
    // progress can be the caller's own.
    std::unique_lock lock(owned->state_mutex);
    owned->ended = true;
    if (!on_bus_thread()) owned->idle.wait(lock, [&] { return !owned->running; });
  }
  // LCM's dispatch loop loses track of a handler that lcm_unsubscribe removes while it
  // dispatches (from any thread): the handler is never freed, and a later one can be skipped.
  // While the bus thread runs, it ends the LCM subscription between two dispatches.
  {
    std::lock_guard lock(subscriptions_mutex_);
    if (dispatching_) {
      retired_.push_back(std::move(owned));
      return;
    }
  }
  lcm_unsubscribe(lcm_->getUnderlyingLCM(), owned->c_subscription);
}

void Bus::end_retired() {
  std::vector<std::unique_ptr<Subscription>> retired;
  {
    std::lock_guard lock(subscriptions_mutex_);
    retired.swap(retired_);
  }
  for (const auto& sub : retired) lcm_unsubscribe(lcm_->getUnderlyingLCM(), sub->c_subscription);
}

std::string resolve_lcm_url(const std::string& url) {
  if (!url.empty()) return url;
  if (const char* env = std::getenv("LCM_DEFAULT_URL"); env != nullptr && *env != '\0') return env;
  return kDefaultLcmUrl;
}

Bus::Bus(const std::string& url) : url_(resolve_lcm_url(url)) {
  lcm_ = std::make_unique<lcm::LCM>(url_);
  if (!lcm_->good())
    throw Error("cannot open LCM at '" + url_ +
                "' (is there a multicast route, e.g. 'ip route add 224.0.0.0/4 dev lo'?)");
}

Bus::~Bus() {
  stop();
  std::vector<std::unique_ptr<Subscription>> left;
  {
    std::lock_guard lock(subscriptions_mutex_);
    left.swap(subscriptions_);
  }
  for (const auto& sub : left) lcm_unsubscribe(lcm_->getUnderlyingLCM(), sub->c_subscription);
  {
    std::lock_guard lock(delay_mutex_);
    delayer_stop_ = true;
  }
  delay_cv_.notify_all();
  if (delayer_.joinable()) delayer_.join();
}

void Bus::enable_auth(std::vector<std::uint8_t> key) {
  auth_ = std::make_unique<Authenticator>(std::move(key));
}

void Bus::set_drop_sink(DropSink sink) {
  std::lock_guard lock(drop_mutex_);
  drop_sink_ = std::move(sink);
}

void Bus::report_drop(int code, const std::string& kind, const std::string& text) {
  // The sink is called under the lock, so that set_drop_sink({}) (e.g. a Reporter's destructor)
  // waits for a report in progress. The sink must not call report_drop.
  std::lock_guard lock(drop_mutex_);
  DropCount& d = drops_[kind];
  ++d.unreported;
  const auto now = std::chrono::steady_clock::now();
  if (now < d.quiet_until || !drop_sink_) return;
  const std::string message =
      d.unreported == 1
          ? text
          : fmt::format("{} ({} such messages dropped since the last report)", text, d.unreported);
  d.unreported = 0;
  d.quiet_until = now + kDropReportPeriod;
  drop_sink_(code, message);
}

void Bus::publish_later(const std::string& channel, std::vector<std::uint8_t> bytes,
                        std::chrono::microseconds delay) {
  std::lock_guard lock(delay_mutex_);
  if (delayer_stop_) return;
  if (!delayer_.joinable()) delayer_ = std::thread([this] { run_delayer(); });
  delayed_.emplace(std::chrono::steady_clock::now() + delay, Delayed{channel, std::move(bytes)});
  delay_cv_.notify_all();
}

void Bus::run_delayer() {
  std::unique_lock lock(delay_mutex_);
  while (!delayer_stop_) {
    if (delayed_.empty()) {
      delay_cv_.wait(lock);
      continue;
    }
    const auto due = delayed_.begin()->first;
    if (std::chrono::steady_clock::now() < due) {
      delay_cv_.wait_until(lock, due);
      continue;
    }
    Delayed d = std::move(delayed_.begin()->second);
    delayed_.erase(delayed_.begin());
    lock.unlock();
    lcm_->publish(d.channel, d.bytes.data(), static_cast<unsigned int>(d.bytes.size()));
    detail::published();
    lock.lock();
  }
}

void Bus::start() {
  if (running_.exchange(true)) return;
  {
    std::lock_guard lock(subscriptions_mutex_);
    dispatching_ = true;
  }
  thread_ = std::thread([this] {
    t_on_bus_thread = true;
    while (running_.load(std::memory_order_relaxed)) {
      ++delivery_;  // LCM dispatches at most one message per call
      lcm_->handleTimeout(50);
      end_retired();
    }
  });
}

void Bus::stop() {
  if (!running_.exchange(false)) return;
  if (thread_.joinable()) thread_.join();
  {
    std::lock_guard lock(subscriptions_mutex_);
    dispatching_ = false;
  }
  end_retired();
}

bool Bus::on_bus_thread() const { return t_on_bus_thread; }

bool Bus::recall_verdict(const std::string& channel, const std::string& sender,
                         std::int64_t counter, int& verdict) const {
  if (!on_bus_thread()) return false;
  const Verdict& v = last_verdict_;
  if (v.delivery != delivery_ || v.counter != counter || v.channel != channel || v.sender != sender)
    return false;
  verdict = v.verdict;
  return true;
}

void Bus::remember_verdict(const std::string& channel, const std::string& sender,
                           std::int64_t counter, int verdict) {
  if (!on_bus_thread()) return;
  last_verdict_ = Verdict{delivery_, channel, sender, counter, verdict};
}

namespace detail {

std::int64_t next_request_seq() {
  static std::atomic<std::int64_t> last{0};
  return ++last;
}

}  // namespace detail

std::string unique_endpoint_name(const std::string& base) {
  return base + "#" + std::to_string(::getpid());
}

}  // namespace mrroc::comm
