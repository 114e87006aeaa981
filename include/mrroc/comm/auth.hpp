#pragma once
/// @file
/// Message authentication with a key shared by the processes of a set ([system] auth_key_file).
///
/// Every message a process with the key sends carries, in its header, a counter and
/// HMAC-SHA256(key, "mrroc-auth-2", the LCM channel it is published on, the message encoded with
/// an empty tag). The counter is the sender's wall-clock time in microseconds, made strictly
/// increasing per process, so it never repeats, not even across restarts. A receiver with the
/// key accepts a message only when
///  - the tag is there and correct for the channel it arrived on (the message comes from a holder
///    of the key, unchanged, and was sent on this channel: a request recorded on one robot's
///    command channel does not verify on another's; each command channel has one server, so
///    the channel names a request's recipient), and
///  - its counter was not seen before from that sender on that channel: greater than the highest
///    so far, or within the last second below it and not among the counters already accepted
///    (LCM may reorder a little), and
///  - the counter is not earlier than the receiver's own start (its epoch): whatever was
///    recorded before a process started, e.g. before the launcher restarted it, is refused by it
///    ("stale"), also within the reorder window. The hosts' clocks must agree (NTP) to well
///    under the time a process takes to start.
/// Requests and replies are checked by every request/reply endpoint, RELEASE of the emergency
/// stop by the EDP, statuses by every SystemListener, robot states by the console and the
/// launcher's emergency-stop latch; SRP messages are checked and, when not authentic, logged
/// marked as unverified.

#include <array>
#include <chrono>
#include <cstdint>
#include <filesystem>
#include <map>
#include <mutex>
#include <set>
#include <string>
#include <utility>
#include <vector>

namespace mrroc::comm {

/// Reads a key file: hexadecimal digits (at least 64, i.e. 32 bytes; white space ignored).
/// @throws Error naming the file and what is wrong with it.
std::vector<std::uint8_t> load_auth_key(const std::filesystem::path& file);

class Bus;
/// Enables authentication on `bus` with the key in `key_file`; does nothing when it is empty
/// (the set runs without a key). Every process calls it with [system] auth_key_file right
/// after opening its bus. @throws Error for an unreadable or bad key file.
void enable_auth_from_file(Bus& bus, const std::filesystem::path& key_file);

class Authenticator {
 public:
  using Tag = std::array<std::uint8_t, 32>;
  enum class Verdict { ok, missing, bad_tag, replayed, stale };
  /// How far below the highest counter of a sender a reordered message may be.
  static constexpr std::int64_t kReorderWindowUs = 1'000'000;

  /// The epoch (the first counter of an unknown sender must be later) is the time of
  /// construction, or `epoch_utime` when given (tests).
  /// @throws Error when the key is shorter than 32 bytes.
  explicit Authenticator(std::vector<std::uint8_t> key, std::int64_t epoch_utime = 0);

  /// The next counter of this process (strictly increasing, microseconds since the epoch).
  std::int64_t next_counter();
  /// HMAC-SHA256 of the domain, `channel` and `size` bytes (see above).
  [[nodiscard]] Tag mac(const std::string& channel, const std::uint8_t* data,
                        std::size_t size) const;
  /// The same, built in `scratch`: no allocation in mrroc's code when its capacity holds
  /// mac_input_size(channel, size) bytes (for senders that must not allocate, e.g. sensors).
  [[nodiscard]] Tag mac(const std::string& channel, const std::uint8_t* data, std::size_t size,
                        std::vector<std::uint8_t>& scratch) const;
  [[nodiscard]] static std::size_t mac_input_size(const std::string& channel, std::size_t size);
  /// Compares in constant time.
  [[nodiscard]] static bool same(const std::uint8_t* a, const std::uint8_t* b, std::size_t n);
  /// Checks (and on success records) a counter of `sender` on `channel`.
  Verdict accept_counter(const std::string& sender, const std::string& channel,
                         std::int64_t counter);
  /// Microseconds since the Unix epoch; see the constructor.
  [[nodiscard]] std::int64_t epoch_utime() const { return epoch_utime_; }

 private:
  struct Seen {
    std::int64_t highest = 0;
    std::set<std::int64_t> recent;  ///< accepted counters within the reorder window
  };
  std::vector<std::uint8_t> key_;
  std::int64_t epoch_utime_;
  std::mutex mutex_;
  std::int64_t last_counter_ = 0;
  std::map<std::pair<std::string, std::string>, Seen> seen_;  ///< by sender and channel
};

const char* to_string(Authenticator::Verdict verdict);

/// Signs `msg` for `channel` (sets header.auth_counter and header.auth_tag).
template <class Msg>
void sign(Authenticator& auth, Msg& msg, const std::string& channel) {
  msg.header.auth_counter = auth.next_counter();
  msg.header.auth_tag.clear();
  msg.header.auth_len = 0;
  // encode() may write fewer bytes than getEncodedSize() (LCM cuts a string at a NUL): the tag
  // covers exactly the bytes that go out.
  std::vector<std::uint8_t> bytes(static_cast<std::size_t>(msg.getEncodedSize()));
  const int written = msg.encode(bytes.data(), 0, static_cast<int>(bytes.size()));
  const Authenticator::Tag tag =
      auth.mac(channel, bytes.data(), written > 0 ? static_cast<std::size_t>(written) : 0);
  msg.header.auth_tag.assign(tag.begin(), tag.end());
  msg.header.auth_len = static_cast<std::int16_t>(tag.size());
}

/// Checks the tag and counter of a message received on `channel`.
template <class Msg>
Authenticator::Verdict verify(Authenticator& auth, const Msg& received,
                              const std::string& channel) {
  if (received.header.auth_len != 32 || received.header.auth_tag.size() != 32)
    return Authenticator::Verdict::missing;
  Msg copy = received;
  copy.header.auth_tag.clear();
  copy.header.auth_len = 0;
  std::vector<std::uint8_t> bytes(static_cast<std::size_t>(copy.getEncodedSize()));
  const int written = copy.encode(bytes.data(), 0, static_cast<int>(bytes.size()));
  const Authenticator::Tag tag =
      auth.mac(channel, bytes.data(), written > 0 ? static_cast<std::size_t>(written) : 0);
  if (!Authenticator::same(tag.data(), received.header.auth_tag.data(), tag.size()))
    return Authenticator::Verdict::bad_tag;
  return auth.accept_counter(received.header.sender, channel, received.header.auth_counter);
}

}  // namespace mrroc::comm
