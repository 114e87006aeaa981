#pragma once
/// @file
/// Typed broadcasts and subscriptions: plain C++ values on both ends of a message that is not a
/// request/reply link (those are in links.hpp). The LCM type and codec of each plain type come
/// from MessageTraits (messages.hpp).
///
///   comm::broadcast(bus, channels::emergency_stop, {now_utime(), sender, seq}, stop);
///   comm::Subscriber<EmergencyStop> sub(bus, channels::emergency_stop,
///       [](const EmergencyStop& stop, const comm::Received& in) { ... in.authentic() ... });
///
/// A message that does not decode, or whose values do not validate (DecodeError), never reaches
/// the handler: the subscriber counts it (malformed()) and, unless told otherwise, reports it
/// through the bus' drop sink (drop_code::malformed, rate-limited per channel).

#include <atomic>
#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <utility>

#include "mrroc/comm/messages.hpp"
#include "mrroc/comm/request_reply.hpp"

namespace mrroc::comm {

/// The header of a message as plain values (header_t without kind and authentication).
struct Envelope {
  std::int64_t utime = 0;  ///< time of sending [us since the Unix epoch]
  std::string sender;      ///< unique name of the sending endpoint
  std::int64_t seq = 0;    ///< the sender's sequence number
};

/// Signs (when the bus has a key) and publishes `plain` on `channel` with `header` as a
/// BROADCAST. With `dice`, the link faults it plans are applied (comm/faults.hpp).
/// @throws Error when `plain` cannot be encoded (e.g. a vector longer than a message holds).
template <class Plain>
void broadcast(Bus& bus, const std::string& channel, const Envelope& header, const Plain& plain,
               FaultDice* dice = nullptr) {
  typename MessageTraits<Plain>::Lcm m = encode(plain);
  m.header.utime = header.utime;
  m.header.sender = header.sender;
  m.header.recipient.clear();
  m.header.seq = header.seq;
  m.header.kind = mrroc_lcm::header_t::BROADCAST;
  if (dice != nullptr)
    detail::publish_with_faults(bus, *dice, channel, std::move(m));
  else
    publish(bus, channel, std::move(m));
}

/// Decodes the bytes of one message (e.g. an event of an LCM log) into `Plain`; nothing when
/// they do not decode or validate, with the reason in `error` (when given). Never throws.
template <class Plain>
std::optional<Plain> decode_bytes(const void* data, int size, Envelope* header = nullptr,
                                  std::string* error = nullptr) noexcept {
  try {
    typename MessageTraits<Plain>::Lcm m;
    if (size < 0 || m.decode(data, 0, size) < 0) {
      if (error != nullptr) *error = "the bytes do not decode";
      return std::nullopt;
    }
    Plain out = decode(m);
    if (header != nullptr) *header = Envelope{m.header.utime, m.header.sender, m.header.seq};
    return out;
  } catch (const std::exception& e) {
    if (error != nullptr) *error = e.what();
    return std::nullopt;
  }
}

/// What a subscriber's handler learns about a message besides its values.
class Received {
 public:
  [[nodiscard]] const std::string& channel() const { return channel_; }
  [[nodiscard]] const Envelope& header() const { return header_; }
  /// True when the bus has no key or the message carries a valid tag from a counter not seen
  /// before; otherwise the message is counted (Subscriber::unauthenticated) and reported
  /// (drop_code::unauthenticated) and false is returned. Ask at most once per message (it
  /// advances the sender's replay counter) and only for messages acted on only when authentic.
  [[nodiscard]] bool authentic() const { return verify_(context_, lcm_message_, channel_, true); }
  /// As authentic(), counted but not reported (for a handler that keeps the message, marked).
  [[nodiscard]] bool authentic_unreported() const {
    return verify_(context_, lcm_message_, channel_, false);
  }

  Received(const std::string& channel, Envelope header, const void* lcm_message,
           bool (*verify)(void*, const void*, const std::string&, bool), void* context)
      : channel_(channel),
        header_(std::move(header)),
        lcm_message_(lcm_message),
        verify_(verify),
        context_(context) {}

 private:
  const std::string& channel_;
  Envelope header_;
  const void* lcm_message_;
  bool (*verify_)(void*, const void*, const std::string&, bool);
  void* context_;
};

struct SubscriberOptions {
  /// Report messages that do not decode through the bus' drop sink (they are always counted).
  bool report_malformed = true;
  /// Called on the bus thread for each message that does not decode, with its channel and
  /// why ("bytes that do not decode" or the DecodeError's text); must not throw.
  std::function<void(const std::string& channel, const std::string& why)> on_malformed;

  /// Counted, not reported (for tools that only watch: what they cannot read is not theirs to
  /// report).
  static SubscriberOptions unreported() {
    SubscriberOptions o;
    o.report_malformed = false;
    return o;
  }
};

/// A subscription that hands `handler` decoded plain values on the bus thread; ends when
/// destroyed. The handler must return quickly and must not throw.
template <class Plain>
class Subscriber {
  using Lcm = typename MessageTraits<Plain>::Lcm;

 public:
  using Handler = std::function<void(const Plain&, const Received&)>;

  /// `channel` is an LCM regular expression (Bus::subscribe).
  Subscriber(Bus& bus, const std::string& channel, Handler handler, SubscriberOptions options = {})
      : state_(std::make_unique<State>(bus, std::move(handler), std::move(options))) {
    subscription_ = bus.subscribe<State*>(channel, &Subscriber::dispatch, state_.get());
  }
  ~Subscriber() {
    if (state_) state_->bus.unsubscribe(subscription_);
  }
  Subscriber(Subscriber&& other) noexcept
      : state_(std::move(other.state_)),
        subscription_(std::exchange(other.subscription_, nullptr)) {}
  Subscriber& operator=(Subscriber&&) = delete;
  Subscriber(const Subscriber&) = delete;
  Subscriber& operator=(const Subscriber&) = delete;

  /// Messages dropped because they did not decode or validate.
  [[nodiscard]] std::uint64_t malformed() const { return state_->malformed.load(); }
  /// Messages Received::authentic() refused.
  [[nodiscard]] std::uint64_t unauthenticated() const { return state_->unauthenticated.load(); }

 private:
  struct State {
    Bus& bus;
    Handler handler;
    SubscriberOptions options;
    std::atomic<std::uint64_t> malformed{0};
    std::atomic<std::uint64_t> unauthenticated{0};
    State(Bus& b, Handler h, SubscriberOptions o)
        : bus(b), handler(std::move(h)), options(std::move(o)) {}
  };

  static bool verify(void* context, const void* message, const std::string& channel, bool report) {
    auto* state = static_cast<State*>(context);
    std::uint64_t dropped = 0;
    const bool ok =
        detail::authentic(state->bus, *static_cast<const Lcm*>(message), channel, dropped, report);
    state->unauthenticated += dropped;
    return ok;
  }

  static void dispatch(const lcm::ReceiveBuffer* buffer, const std::string& channel, State* state) {
    Lcm m;
    std::optional<Plain> plain;
    std::string error;
    const bool bytes_decode = detail::decode_received(buffer, m);
    if (bytes_decode) {
      try {
        plain = decode(m);
      } catch (const std::exception& e) {  // DecodeError, or an allocation that failed
        error = e.what();
      }
    }
    if (!plain) {
      ++state->malformed;
      if (!bytes_decode) error = "bytes that do not decode";
      if (state->options.on_malformed) state->options.on_malformed(channel, error);
      const int size = static_cast<int>(buffer->data_size);
      if (state->options.report_malformed) {
        if (bytes_decode)
          detail::report_malformed(state->bus, channel, size, error);
        else
          detail::report_malformed(state->bus, channel, size);
      }
      return;
    }
    const Received received(channel, Envelope{m.header.utime, m.header.sender, m.header.seq}, &m,
                            &Subscriber::verify, state);
    state->handler(*plain, received);
  }

  std::unique_ptr<State> state_;
  Subscription* subscription_ = nullptr;
};

}  // namespace mrroc::comm
