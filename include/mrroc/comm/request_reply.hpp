#pragma once
/// @file
/// Request/reply on top of LCM publish/subscribe. Every link between processes uses it.
///
/// Protocol (see docs/messages.md):
/// - A request carries `header.sender` (a name unique to the client) and `header.seq`, increasing
///   by one per new request of that client.
/// - The client waits `attempt_timeout` for the reply whose `header.recipient` is its name and
/// whose
///   `header.seq` equals the request's; otherwise it re-sends the *same* request (same seq). After
///   `max_attempts` silent attempts it throws `TimeoutError` naming the peer, the channel, the
///   sequence number and the time waited.
/// - The server remembers, per client, the last sequence it accepted. A repeated sequence is never
///   executed twice: if its reply is ready, the cached reply is sent again; if it is still being
///   executed, an IN_PROGRESS reply tells the client to keep waiting (long requests such as
///   START_TASK or SYNCHRO stay alive without an arbitrary time limit). Older sequences are
///   dropped.
///
/// Message types are LCM types with a `header` field of type `mrroc_lcm::header_t`.

#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <cstdio>
#include <deque>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <utility>

#include <fmt/format.h>

#include "mrroc/comm/auth.hpp"
#include "mrroc/comm/bus.hpp"
#include "mrroc/comm/faults.hpp"
#include "mrroc/comm/sync_annotations.hpp"
#include "mrroc/core/error.hpp"
#include "mrroc/core/time.hpp"
#include "mrroc_lcm/header_t.hpp"

namespace mrroc::comm {

struct ClientOptions {
  std::chrono::milliseconds attempt_timeout{250};  ///< wait per attempt before re-sending
  int max_attempts = 12;  ///< silent attempts (no reply, no IN_PROGRESS) before TimeoutError
  LinkFaults faults;      ///< injected on this client's outgoing requests
};

struct ServerOptions {
  LinkFaults faults;  ///< injected on this server's outgoing replies
  /// Requests sent longer ago than this (by their header.utime; 0: no limit) are dropped, not
  /// executed: their client gave up or re-sent them since (each attempt carries a fresh time).
  /// Across hosts this needs clocks synchronised well within it.
  std::chrono::milliseconds max_request_age{0};
};

/// Counters of one endpoint (for tests, SRP and benchmarks).
struct LinkStats {
  std::uint64_t requests = 0;         ///< new requests (client: sent; server: accepted)
  std::uint64_t resends = 0;          ///< client: re-sent requests
  std::uint64_t duplicates = 0;       ///< server: repeated sequences answered from the cache
  std::uint64_t in_progress = 0;      ///< server: IN_PROGRESS replies sent
  std::uint64_t stale = 0;            ///< dropped: old sequences / replies nobody waits for
  std::uint64_t expired = 0;          ///< server: dropped, sent longer ago than max_request_age
  std::uint64_t malformed = 0;        ///< dropped: could not be decoded
  std::uint64_t unauthenticated = 0;  ///< dropped: no or wrong tag, or replayed (auth.hpp)
};

/// Publishes `msg` on `channel`, signed when the bus has a key (for broadcasts: status, SRP
/// messages, robot state, emergency stop).
template <class Msg>
void publish(Bus& bus, const std::string& channel, Msg msg) {
  if (Authenticator* auth = bus.auth()) sign(*auth, msg, channel);
  detail::published();
  bus.lcm().publish(channel, &msg);
}

namespace detail {
/// The next request sequence number of this process, shared by all its clients. A server keeps
/// the last sequence of each client name and drops lower ones as stale; a client made again
/// under the same name (unique_endpoint_name: a task's second run in the same ECP or MP)
/// continues above the numbers its predecessor used instead of starting at 1 again.
std::int64_t next_request_seq();

/// Signs (when the bus has a key) and publishes `msg`, with the link faults of `dice`.
template <class Msg>
void publish_with_faults(Bus& bus, FaultDice& dice, const std::string& channel, Msg msg) {
  if (Authenticator* auth = bus.auth()) sign(*auth, msg, channel);
  const FaultPlan plan = dice.plan();
  if (plan.copies == 0) return;
  std::vector<std::uint8_t> bytes(static_cast<std::size_t>(msg.getEncodedSize()));
  msg.encode(bytes.data(), 0, static_cast<int>(bytes.size()));
  published();
  for (int i = 0; i < plan.copies; ++i) {
    if (plan.delay_us[i] > 0)
      bus.publish_later(channel, bytes, std::chrono::microseconds(plan.delay_us[i]));
    else
      bus.lcm().publish(channel, bytes.data(), static_cast<unsigned int>(bytes.size()));
  }
}

/// Checks a received message on a bus with a key; counts and (unless `report` is false)
/// reports what it refuses.
template <class Msg>
bool authentic(Bus& bus, const Msg& msg, const std::string& channel, std::uint64_t& dropped,
               bool report = true) {
  Authenticator* auth = bus.auth();
  if (auth == nullptr) return true;
  int recalled = 0;
  Authenticator::Verdict verdict{};
  if (bus.recall_verdict(channel, msg.header.sender, msg.header.auth_counter, recalled)) {
    verdict = static_cast<Authenticator::Verdict>(recalled);
  } else {
    verdict = verify(*auth, msg, channel);
    bus.remember_verdict(channel, msg.header.sender, msg.header.auth_counter,
                         static_cast<int>(verdict));
  }
  if (verdict == Authenticator::Verdict::ok) return true;
  ++dropped;
  if (report)
    bus.report_drop(drop_code::unauthenticated, "unauthenticated on " + channel,
                    fmt::format("dropped a message on '{}' from '{}': {}", channel,
                                msg.header.sender, to_string(verdict)));
  return false;
}

/// Counts and reports a message that did not decode.
inline void report_malformed(Bus& bus, const std::string& channel, int size) {
  bus.report_drop(drop_code::malformed, "malformed on " + channel,
                  fmt::format("dropped a malformed message on '{}' ({} bytes that do not decode)",
                              channel, size));
}
/// Counts and reports a message that decoded but did not validate (`why`: the DecodeError).
inline void report_malformed(Bus& bus, const std::string& channel, int size,
                             const std::string& why) {
  bus.report_drop(
      drop_code::malformed, "malformed on " + channel,
      fmt::format("dropped a malformed message on '{}' ({} bytes): {}", channel, size, why));
}
}  // namespace detail

/// The requesting side of a link. `call` is thread-safe (calls are serialised).
template <class Req, class Rep>
class Client {
 public:
  /// @param name  unique client name (the process name is made unique with the pid).
  /// @param peer  human-readable name of the server for error messages, e.g. "EDP irb6".
  Client(Bus& bus, std::string name, std::string peer, std::string request_channel,
         std::string reply_channel, ClientOptions options = {})
      : bus_(bus),
        name_(std::move(name)),
        peer_(std::move(peer)),
        request_channel_(std::move(request_channel)),
        reply_channel_(std::move(reply_channel)),
        options_(options),
        dice_(options.faults.active() ? options.faults : link_faults_from_environment()) {
    subscription_ = bus_.subscribe<Client*>(reply_channel_, &Client::dispatch, this);
  }
  ~Client() { bus_.unsubscribe(subscription_); }
  Client(const Client&) = delete;
  Client& operator=(const Client&) = delete;

  /// Sends `request` and returns the matching reply.
  /// @throws TimeoutError after `max_attempts` attempts without any sign of life from the server,
  /// CallAbandoned when abandon() ended the wait.
  Rep call(Req request) {
    if (bus_.on_bus_thread())
      throw Error("request/reply call on '" + request_channel_ + "' from the bus thread");
    std::lock_guard call_lock(call_mutex_);
    std::unique_lock lock(mutex_);
    const std::int64_t seq = detail::next_request_seq();
    waiting_seq_ = seq;
    reply_.reset();
    in_progress_ = false;
    abandoned_ = false;
    request.header.utime = now_utime();
    request.header.sender = name_;
    request.header.recipient = "";
    request.header.seq = seq;
    request.header.kind = mrroc_lcm::header_t::REQUEST;
    ++stats_.requests;
    send(lock, request);
    int silent_attempts = 1;
    const auto started = std::chrono::steady_clock::now();
    for (;;) {
      const bool woke = cv_.wait_for(lock, options_.attempt_timeout, [&] {
        return reply_.has_value() || in_progress_ || abandoned_;
      });
      if (reply_) {
        waiting_seq_ = -1;
        Rep out = std::move(*reply_);
        reply_.reset();
        return out;
      }
      if (abandoned_) {
        waiting_seq_ = -1;
        abandoned_ = false;
        const auto waited = std::chrono::duration_cast<std::chrono::milliseconds>(
            std::chrono::steady_clock::now() - started);
        throw CallAbandoned(
            fmt::format("request {} to {} on channel '{}' abandoned after {} ms without its reply",
                        seq, peer_, request_channel_, waited.count()));
      }
      if (woke && in_progress_) {
        in_progress_ = false;
        silent_attempts = 0;
        continue;
      }
      if (silent_attempts >= options_.max_attempts) {
        waiting_seq_ = -1;
        const auto waited = std::chrono::duration_cast<std::chrono::milliseconds>(
            std::chrono::steady_clock::now() - started);
        throw TimeoutError(
            fmt::format("no reply from {} on channel '{}' to request {} after {} attempts of {} ms "
                        "({} ms in all)",
                        peer_, request_channel_, seq, silent_attempts,
                        options_.attempt_timeout.count(), waited.count()));
      }
      ++silent_attempts;
      ++stats_.resends;
      note_resend(seq, silent_attempts);
      request.header.utime = now_utime();
      send(lock, request);
    }
  }

  /// Ends the wait of the call in progress, if any, at once: it throws CallAbandoned, and its
  /// reply, should it still come, is dropped as stale. A call that starts later is not affected.
  /// For a stop that must not wait for a silent server's last attempts (an ECP told to STOP while
  /// its EDP does not answer). Thread-safe.
  void abandon() {
    std::lock_guard lock(mutex_);
    if (waiting_seq_ < 0) return;
    abandoned_ = true;
    cv_.notify_all();
  }

  [[nodiscard]] LinkStats stats() const {
    std::lock_guard lock(mutex_);
    return stats_;
  }
  [[nodiscard]] const std::string& name() const { return name_; }

 private:
  void send(std::unique_lock<std::mutex>& lock, const Req& request) {
    lock.unlock();
    detail::publish_with_faults(bus_, dice_, request_channel_, request);
    lock.lock();
  }

  // LCM calls a plain function with the object as context (no pointer-to-member dispatch).
  static void dispatch(const lcm::ReceiveBuffer* buffer, const std::string& channel, Client* self) {
    Rep reply;
    if (!detail::decode_received(buffer, reply)) {
      {
        std::lock_guard lock(self->mutex_);
        ++self->stats_.malformed;
      }
      detail::report_malformed(self->bus_, channel, static_cast<int>(buffer->data_size));
      return;
    }
    self->on_reply(&reply, channel);
  }

  void on_reply(const Rep* reply, const std::string& channel) {
    if (reply->header.recipient != name_) return;  // another client's reply on a shared channel
    std::uint64_t rejected = 0;
    const bool ok = detail::authentic(bus_, *reply, channel, rejected);
    std::lock_guard lock(mutex_);
    if (!ok) {
      stats_.unauthenticated += rejected;
      return;
    }
    if (reply->header.seq != waiting_seq_ || reply_) {
      ++stats_.stale;
      return;
    }
    if (reply->header.kind == mrroc_lcm::header_t::IN_PROGRESS) {
      in_progress_ = true;
    } else {
      reply_ = *reply;
    }
    cv_.notify_all();
  }

  Bus& bus_;
  std::string name_;
  std::string peer_;
  std::string request_channel_;
  std::string reply_channel_;
  ClientOptions options_;
  FaultDice dice_;
  mrroc::comm::Subscription* subscription_ = nullptr;

  std::mutex call_mutex_;
  mutable std::mutex mutex_;
  std::condition_variable cv_;
  std::int64_t waiting_seq_ = -1;
  std::optional<Rep> reply_;
  bool in_progress_ = false;
  bool abandoned_ = false;
  LinkStats stats_;
  /// Re-sends are said on standard error (the launcher's output, with the process' name in
  /// front), at most one line a second per client with the count since the last: a request or
  /// reply lost on the way delays a call by a whole attempt, which is what stops a robot whose
  /// lookahead is shorter than that.
  std::chrono::steady_clock::time_point last_resend_note_{};
  std::uint64_t resends_noted_ = 0;

  void note_resend(std::int64_t seq, int attempt) {
    const auto now = std::chrono::steady_clock::now();
    if (now - last_resend_note_ < std::chrono::seconds(1)) return;
    const std::uint64_t since = stats_.resends - resends_noted_;
    std::fprintf(stderr,
                 "%s: no reply from %s on channel '%s' to request %lld within %lld ms: sent again "
                 "(attempt %d; %llu re-sends since the last such note)\n",
                 name_.c_str(), peer_.c_str(), request_channel_.c_str(),
                 static_cast<long long>(seq),
                 static_cast<long long>(options_.attempt_timeout.count()), attempt,
                 static_cast<unsigned long long>(since));
    last_resend_note_ = now;
    resends_noted_ = stats_.resends;
  }
};

/// The serving side of a link.
///
/// New requests either go to a handler (called on the bus thread; it must not block) or, when no
/// handler is given, into a queue read with `wait_request`. Either way each request comes with a
/// `Responder` that may be used from any thread, at any later time, exactly once.
template <class Req, class Rep>
class Server {
  struct PeerState {
    std::int64_t seq = 0;
    bool done = false;
    std::optional<Rep> cached;
  };
  struct State {
    Bus* bus;
    std::string name;
    std::string reply_channel;
    FaultDice dice;
    std::mutex mutex;
    std::map<std::string, PeerState> peers;
    LinkStats stats;
    State(Bus* b, std::string n, std::string ch, const LinkFaults& f)
        : bus(b), name(std::move(n)), reply_channel(std::move(ch)), dice(f) {}
  };

 public:
  /// Replies to one request; copyable; `reply` takes effect once.
  class Responder {
   public:
    Responder() = default;
    void reply(Rep rep) const {
      if (!state_) return;
      {
        std::lock_guard lock(state_->mutex);
        auto& peer = state_->peers[client_];
        if (peer.seq != seq_ || peer.done) return;  // superseded or already answered
        rep.header.utime = now_utime();
        rep.header.sender = state_->name;
        rep.header.recipient = client_;
        rep.header.seq = seq_;
        rep.header.kind = mrroc_lcm::header_t::REPLY;
        peer.done = true;
        peer.cached = rep;
      }
      detail::publish_with_faults(*state_->bus, state_->dice, state_->reply_channel, rep);
    }
    [[nodiscard]] const std::string& client() const { return client_; }
    [[nodiscard]] std::int64_t seq() const { return seq_; }

   private:
    friend class Server;
    Responder(std::shared_ptr<State> state, std::string client, std::int64_t seq)
        : state_(std::move(state)), client_(std::move(client)), seq_(seq) {}
    std::shared_ptr<State> state_;
    std::string client_;
    std::int64_t seq_ = 0;
  };

  struct Incoming {
    Req request;
    Responder responder;
  };
  using Handler = std::function<void(const Req&, Responder)>;

  Server(Bus& bus, std::string name, std::string request_channel, std::string reply_channel,
         Handler handler = {}, ServerOptions options = {})
      : bus_(bus),
        handler_(std::move(handler)),
        max_request_age_us_(options.max_request_age.count() * 1000),
        state_(std::make_shared<State>(
            &bus, std::move(name), std::move(reply_channel),
            options.faults.active() ? options.faults : link_faults_from_environment())) {
    subscription_ = bus_.subscribe<Server*>(request_channel, &Server::dispatch, this);
  }
  ~Server() {
    bus_.unsubscribe(subscription_);
    std::lock_guard lock(queue_mutex_);
    closed_ = true;
    queue_cv_.notify_all();
  }
  Server(const Server&) = delete;
  Server& operator=(const Server&) = delete;

  /// Next queued request (queue mode), or nothing after `timeout`.
  std::optional<Incoming> wait_request(std::chrono::milliseconds timeout) {
    std::unique_lock lock(queue_mutex_);
    if (!queue_cv_.wait_for(lock, timeout, [&] { return !queue_.empty() || closed_; }))
      return std::nullopt;
    if (queue_.empty()) return std::nullopt;
    Incoming in = std::move(queue_.front());
    queue_.pop_front();
    return in;
  }

  [[nodiscard]] LinkStats stats() const {
    std::lock_guard lock(state_->mutex);
    return state_->stats;
  }

 private:
  static void dispatch(const lcm::ReceiveBuffer* buffer, const std::string& channel, Server* self) {
    Req request;
    if (!detail::decode_received(buffer, request)) {
      {
        std::lock_guard lock(self->state_->mutex);
        ++self->state_->stats.malformed;
      }
      detail::report_malformed(self->bus_, channel, static_cast<int>(buffer->data_size));
      return;
    }
    std::uint64_t rejected = 0;
    if (!detail::authentic(self->bus_, request, channel, rejected)) {
      std::lock_guard lock(self->state_->mutex);
      self->state_->stats.unauthenticated += rejected;
      return;
    }
    self->on_request(&request);
  }

  void on_request(const Req* request) {
    const std::string& client = request->header.sender;
    const std::int64_t seq = request->header.seq;
    std::optional<Rep> resend;
    if (max_request_age_us_ > 0 && now_utime() - request->header.utime > max_request_age_us_) {
      std::lock_guard lock(state_->mutex);
      ++state_->stats.expired;
      return;
    }
    {
      std::lock_guard lock(state_->mutex);
      auto& peer = state_->peers[client];
      if (seq == peer.seq) {
        if (peer.done && peer.cached) {
          ++state_->stats.duplicates;
          resend = *peer.cached;
        } else {
          ++state_->stats.in_progress;
          Rep progress{};
          progress.header.utime = now_utime();
          progress.header.sender = state_->name;
          progress.header.recipient = client;
          progress.header.seq = seq;
          progress.header.kind = mrroc_lcm::header_t::IN_PROGRESS;
          resend = std::move(progress);
        }
      } else if (seq < peer.seq) {
        ++state_->stats.stale;
        return;
      } else {
        peer.seq = seq;
        peer.done = false;
        peer.cached.reset();
        ++state_->stats.requests;
      }
    }
    if (resend) {
      detail::publish_with_faults(bus_, state_->dice, state_->reply_channel, *resend);
      return;
    }
    Responder responder(state_, client, seq);
    if (handler_) {
      handler_(*request, std::move(responder));
      return;
    }
    std::lock_guard lock(queue_mutex_);
    queue_.push_back(Incoming{*request, std::move(responder)});
    queue_cv_.notify_one();
  }

  Bus& bus_;
  Handler handler_;
  std::int64_t max_request_age_us_ = 0;
  std::shared_ptr<State> state_;
  mrroc::comm::Subscription* subscription_ = nullptr;
  std::mutex queue_mutex_;
  std::condition_variable queue_cv_;
  std::deque<Incoming> queue_;
  bool closed_ = false;
};

/// A unique endpoint name: "<base>#<pid>".
std::string unique_endpoint_name(const std::string& base);

}  // namespace mrroc::comm
