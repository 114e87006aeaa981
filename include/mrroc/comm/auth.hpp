#pragma once
/// @file
/// Message authentication with a key shared by the processes of a set ([system] auth_key_file).
///
/// Every message a process with the key sends carries, in its header, a counter and
/// HMAC-SHA256(key, the message encoded with an empty tag). The counter is the sender's
/// wall-clock time in microseconds, made strictly increasing per process, so it never repeats,
/// not even across restarts. A receiver with the key accepts a message only when
///  - the tag is there and correct (the message comes from a holder of the key, unchanged), and
///  - its counter was not seen before from that sender: greater than the highest so far, or
///    within the last second below it and not among the counters already accepted (LCM may
///    reorder a little), and
///  - the first message of a sender is at most `kFreshness` older than the receiver's clock (a
///    message recorded earlier cannot be replayed to a receiver that restarted).
/// Requests and replies are checked by every request/reply endpoint, RELEASE of the emergency
/// stop by the EDP; broadcasts (status, SRP messages, robot state) are signed but not checked.

#include <array>
#include <chrono>
#include <cstdint>
#include <filesystem>
#include <map>
#include <mutex>
#include <set>
#include <string>
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
  /// How old the first message of an unknown sender may be.
  static constexpr std::chrono::seconds kFreshness{30};
  /// How far below the highest counter of a sender a reordered message may be.
  static constexpr std::int64_t kReorderWindowUs = 1'000'000;

  /// @throws Error when the key is shorter than 32 bytes.
  explicit Authenticator(std::vector<std::uint8_t> key);

  /// The next counter of this process (strictly increasing, microseconds since the epoch).
  std::int64_t next_counter();
  /// HMAC-SHA256 of `size` bytes.
  [[nodiscard]] Tag mac(const std::uint8_t* data, std::size_t size) const;
  /// Compares in constant time.
  [[nodiscard]] static bool same(const std::uint8_t* a, const std::uint8_t* b, std::size_t n);
  /// Checks (and on success records) a counter of `sender`.
  Verdict accept_counter(const std::string& sender, std::int64_t counter);

 private:
  struct Seen {
    std::int64_t highest = 0;
    std::set<std::int64_t> recent;  ///< accepted counters within the reorder window
  };
  std::vector<std::uint8_t> key_;
  std::mutex mutex_;
  std::int64_t last_counter_ = 0;
  std::map<std::string, Seen> seen_;
};

const char* to_string(Authenticator::Verdict verdict);

/// Signs `msg` (sets header.auth_counter and header.auth_tag).
template <class Msg>
void sign(Authenticator& auth, Msg& msg) {
  msg.header.auth_counter = auth.next_counter();
  msg.header.auth_tag.clear();
  msg.header.auth_len = 0;
  // encode() may write fewer bytes than getEncodedSize() (LCM cuts a string at a NUL): the tag
  // covers exactly the bytes that go out.
  std::vector<std::uint8_t> bytes(static_cast<std::size_t>(msg.getEncodedSize()));
  const int written = msg.encode(bytes.data(), 0, static_cast<int>(bytes.size()));
  const Authenticator::Tag tag =
      auth.mac(bytes.data(), written > 0 ? static_cast<std::size_t>(written) : 0);
  msg.header.auth_tag.assign(tag.begin(), tag.end());
  msg.header.auth_len = static_cast<std::int16_t>(tag.size());
}

/// Checks a received message's tag and counter.
template <class Msg>
Authenticator::Verdict verify(Authenticator& auth, const Msg& received) {
  if (received.header.auth_len != 32 || received.header.auth_tag.size() != 32)
    return Authenticator::Verdict::missing;
  Msg copy = received;
  copy.header.auth_tag.clear();
  copy.header.auth_len = 0;
  std::vector<std::uint8_t> bytes(static_cast<std::size_t>(copy.getEncodedSize()));
  const int written = copy.encode(bytes.data(), 0, static_cast<int>(bytes.size()));
  const Authenticator::Tag tag =
      auth.mac(bytes.data(), written > 0 ? static_cast<std::size_t>(written) : 0);
  if (!Authenticator::same(tag.data(), received.header.auth_tag.data(), tag.size()))
    return Authenticator::Verdict::bad_tag;
  return auth.accept_counter(received.header.sender, received.header.auth_counter);
}

}  // namespace mrroc::comm
