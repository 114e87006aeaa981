// Message authentication (include/mrroc/comm/auth.hpp): raw bytes received as a message and
// checked by comm::verify with a fixed key, signed messages, signed messages with one byte
// changed, and sequences of counters.
//
// Input: [selector][rest]. The selector (mod 14) picks one of 13 message types (kTypes below) for
// the rest, or (13) the counter mode, where the rest is a sequence of 9-byte records
// [sender (mod 3)][counter offset, 8 bytes little-endian] handed to Authenticator::accept_counter.
//
// Properties (docs/fuzzing.md):
// - verify never throws, whatever decoded;
// - a received message whose tag verify accepts (verdict ok, replayed or stale) carries
//   HMAC-SHA256(key, domain, channel, the message encoded with an empty tag), recomputed here with
//   OpenSSL directly (with random input this only happens for the signed seeds); one that verifies
//   ok is "replayed" the second time;
// - a decoded message signed with the key (comm::sign) and
//   sent as bytes verifies ok once, then "replayed"; on another channel it is "bad tag";
// - with one byte of a signed encoding changed (16 positions per input), the bytes either do not
//   decode or verify says missing or bad_tag; the only exception is a changed byte that ends a
//   string (the decoder does not read it): then the message is the one that was signed and
//   verify says replayed;
// - counters: a counter is accepted (ok) at most once per sender; one greater than every counter
//   seen from a known sender is accepted; one more than the reorder window below the highest is
//   not; stale exactly when the counter is earlier than the receiver's start (its epoch).
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <map>
#include <optional>
#include <set>
#include <string>
#include <tuple>
#include <vector>

#include <openssl/evp.h>
#include <openssl/hmac.h>
#include <lcm/lcm-cpp.hpp>

#include "fuzz_auth_key.hpp"
#include "fuzz_common.hpp"
#include "mrroc/comm/auth.hpp"
#include "mrroc/comm/sync_annotations.hpp"
#include "mrroc/core/time.hpp"
#include "mrroc_lcm/ecp_mp_reply_t.hpp"
#include "mrroc_lcm/edp_instruction_t.hpp"
#include "mrroc_lcm/edp_reply_t.hpp"
#include "mrroc_lcm/emergency_stop_t.hpp"
#include "mrroc_lcm/launch_status_t.hpp"
#include "mrroc_lcm/mp_ecp_command_t.hpp"
#include "mrroc_lcm/operator_command_t.hpp"
#include "mrroc_lcm/operator_reply_t.hpp"
#include "mrroc_lcm/robot_state_t.hpp"
#include "mrroc_lcm/srp_history_reply_t.hpp"
#include "mrroc_lcm/srp_history_request_t.hpp"
#include "mrroc_lcm/vsp_command_t.hpp"
#include "mrroc_lcm/vsp_reply_t.hpp"

namespace {

using mrroc::comm::Authenticator;
using Verdict = Authenticator::Verdict;

// The types the selector picks, in this order (make_seeds.cpp writes the same selector bytes).
using kTypes =
    std::tuple<mrroc_lcm::edp_instruction_t, mrroc_lcm::edp_reply_t, mrroc_lcm::mp_ecp_command_t,
               mrroc_lcm::ecp_mp_reply_t, mrroc_lcm::vsp_command_t, mrroc_lcm::vsp_reply_t,
               mrroc_lcm::emergency_stop_t, mrroc_lcm::operator_command_t,
               mrroc_lcm::operator_reply_t, mrroc_lcm::srp_history_request_t,
               mrroc_lcm::srp_history_reply_t, mrroc_lcm::launch_status_t,
               mrroc_lcm::robot_state_t>;
constexpr std::size_t kTypeCount = std::tuple_size_v<kTypes>;
static_assert(kTypeCount == fuzz_auth::kMessageTypes);

/// The channel messages are signed for and received on.
constexpr const char* kChannel = "fuzz/edp/cmd";

Authenticator& signer() {
  static Authenticator a(fuzz_auth::key());
  return a;
}

const char* name(Verdict v) { return mrroc::comm::to_string(v); }
bool tag_accepted(Verdict v) { return v != Verdict::missing && v != Verdict::bad_tag; }

template <class Msg>
std::vector<std::uint8_t> encode_bytes(const Msg& m) {
  std::vector<std::uint8_t> out(static_cast<std::size_t>(m.getEncodedSize()));
  const int n = m.encode(out.data(), 0, static_cast<int>(out.size()));
  // Fewer bytes than getEncodedSize() when a string holds a NUL (LCM writes it with strlen).
  fuzz::expect(n >= 0 && n <= static_cast<int>(out.size()),
               fmt::format("encode returned {} for {} bytes", n, out.size()));
  out.resize(static_cast<std::size_t>(n));
  return out;
}

/// The bytes the tag covers: the message encoded with an empty tag.
template <class Msg>
std::vector<std::uint8_t> signed_part(const Msg& m) {
  Msg copy = m;
  copy.header.auth_tag.clear();
  copy.header.auth_len = 0;
  return encode_bytes(copy);
}

template <class Msg>
std::optional<Msg> decode(const std::uint8_t* data, std::size_t size) {
  lcm::ReceiveBuffer buffer{};
  buffer.data = const_cast<std::uint8_t*>(data);
  buffer.data_size = static_cast<std::uint32_t>(size);
  Msg msg;
  bool ok = false;
  fuzz::no_throw("comm::detail::decode_received",
                 [&] { ok = mrroc::comm::detail::decode_received(&buffer, msg); });
  if (!ok) return std::nullopt;
  return msg;
}

template <class Msg>
Verdict verify(Authenticator& auth, const Msg& m, const char* what) {
  Verdict v = Verdict::missing;
  fuzz::no_throw(what, [&] { v = mrroc::comm::verify(auth, m, kChannel); });
  fuzz::expect(std::strcmp(name(v), "?") != 0,
               fmt::format("{}: verdict {} has no name", what, static_cast<int>(v)));
  return v;
}

/// HMAC-SHA256 with the key over the domain, the channel (with its length) and `message`, by
/// OpenSSL directly (not through Authenticator::mac).
std::vector<std::uint8_t> reference_mac(const std::vector<std::uint8_t>& message) {
  const std::vector<std::uint8_t>& key = fuzz_auth::key();
  const std::string domain = "mrroc-auth-2";
  const std::string channel = kChannel;
  std::vector<std::uint8_t> bytes(domain.begin(), domain.end());
  const auto n = static_cast<std::uint32_t>(channel.size());
  for (const unsigned shift : {24U, 16U, 8U, 0U})
    bytes.push_back(static_cast<std::uint8_t>(n >> shift));
  bytes.insert(bytes.end(), channel.begin(), channel.end());
  bytes.insert(bytes.end(), message.begin(), message.end());
  std::vector<std::uint8_t> out(EVP_MAX_MD_SIZE);
  unsigned int length = 0;
  fuzz::expect(HMAC(EVP_sha256(), key.data(), static_cast<int>(key.size()), bytes.data(),
                    bytes.size(), out.data(), &length) != nullptr,
               "OpenSSL HMAC failed");
  out.resize(length);
  return out;
}

std::vector<std::uint8_t> tag_of(const mrroc_lcm::header_t& h) {
  return {h.auth_tag.begin(), h.auth_tag.end()};
}

std::uint64_t fnv1a(const std::uint8_t* data, std::size_t size) {
  std::uint64_t h = 14695981039346656037ULL;
  for (std::size_t i = 0; i < size; ++i) h = (h ^ data[i]) * 1099511628211ULL;
  return h;
}

template <class Msg>
void check_message(const std::uint8_t* data, std::size_t size) {
  // 1. The bytes as received.
  const std::optional<Msg> received = decode<Msg>(data, size);
  if (!received) return;
  {
    Authenticator receiver(fuzz_auth::key());
    const Verdict v = verify(receiver, *received, "verify of received bytes");
    if (tag_accepted(v)) {
      fuzz::expect(tag_of(received->header) == reference_mac(signed_part(*received)),
                   fmt::format("verify said '{}' for a message whose tag is not the HMAC of its "
                               "contents with the key",
                               name(v)));
      if (v == Verdict::ok) {
        const Verdict again = verify(receiver, *received, "second verify of received bytes");
        fuzz::expect(again == Verdict::replayed,
                     fmt::format("a message verified ok, then '{}' (not replayed)", name(again)));
      }
    }
  }

  // 2. The same message signed with the key, sent as bytes. A string holding a NUL is cut on the
  // wire: the tag covers the bytes encode() writes, so it still verifies (docs/fuzzing.md,
  // "Findings" 6).
  Authenticator receiver(fuzz_auth::key());  // started before the message is signed
  Msg message = *received;
  fuzz::no_throw("comm::sign", [&] { mrroc::comm::sign(signer(), message, kChannel); });
  const std::vector<std::uint8_t> wire = encode_bytes(message);
  const std::optional<Msg> sent = decode<Msg>(wire.data(), wire.size());
  fuzz::expect(sent.has_value(), "a signed message does not decode from its bytes");
  const Verdict first = verify(receiver, *sent, "verify of a signed message");
  fuzz::expect(first == Verdict::ok,
               fmt::format("a message signed with the key verified as '{}'", name(first)));
  const Verdict second = verify(receiver, *sent, "second verify of a signed message");
  fuzz::expect(
      second == Verdict::replayed,
      fmt::format("a signed message received twice was '{}' the second time", name(second)));

  // The same signed message received on another channel: a wrong tag, whatever its counter.
  {
    Authenticator elsewhere(fuzz_auth::key(), 1);
    Verdict v = Verdict::ok;
    fuzz::no_throw("verify on another channel",
                   [&] { v = mrroc::comm::verify(elsewhere, *sent, "fuzz/edp/cmd2"); });
    fuzz::expect(v == Verdict::bad_tag,
                 fmt::format("a message signed for '{}' verified as '{}' on another channel",
                             kChannel, name(v)));
  }

  // 3. One byte of the signed encoding changed.
  const std::vector<std::uint8_t> original = signed_part(*sent);
  std::uint64_t h = fnv1a(data, size);
  for (int k = 0; k < 16; ++k) {
    h = h * 6364136223846793005ULL + 1442695040888963407ULL;
    const std::size_t pos = static_cast<std::size_t>(h >> 33U) % wire.size();
    const auto flip = static_cast<std::uint8_t>(1U + ((h >> 8U) % 255U));
    std::vector<std::uint8_t> changed = wire;
    changed[pos] ^= flip;
    const std::optional<Msg> m = decode<Msg>(changed.data(), changed.size());
    if (!m) continue;
    const Verdict v = verify(receiver, *m, "verify of a changed signed message");
    if (!tag_accepted(v)) continue;
    fuzz::expect(signed_part(*m) == original && tag_of(m->header) == tag_of(sent->header),
                 fmt::format("byte {} of {} of a signed message changed ({:#04x} -> {:#04x}) and "
                             "verify said '{}'",
                             pos, wire.size(), wire[pos], changed[pos], name(v)));
    fuzz::expect(v == Verdict::replayed,
                 fmt::format("a signed message with an unread byte changed verified as '{}' "
                             "after it had been received",
                             name(v)));
  }
}

/// Counter mode: a model of what the receiver accepted.
void check_counters(const std::uint8_t* data, std::size_t size) {
  Authenticator receiver(fuzz_auth::key());
  const std::int64_t now = mrroc::now_utime();
  std::map<std::string, std::set<std::int64_t>> accepted;
  for (std::size_t pos = 0; pos + 9 <= size; pos += 9) {
    const std::string sender = fmt::format("sender{}", data[pos] % 3U);
    std::uint64_t raw = 0;
    for (unsigned i = 0; i < 8; ++i)
      raw |= static_cast<std::uint64_t>(data[pos + 1 + i]) << (8U * i);
    // Offsets around now: mostly within a few seconds (the reorder window is 1 s).
    const auto offset = static_cast<std::int64_t>(raw % 8'000'001ULL) - 4'000'000;
    const std::int64_t counter = (raw >> 62U) == 3U ? static_cast<std::int64_t>(raw) : now + offset;
    Verdict v = Verdict::missing;
    fuzz::no_throw("accept_counter",
                   [&] { v = receiver.accept_counter(sender, kChannel, counter); });
    auto it = accepted.find(sender);
    const bool known = it != accepted.end();
    fuzz::expect((v == Verdict::stale) == (counter < receiver.epoch_utime()),
                 fmt::format("counter {} ({} the receiver's start) was '{}'", counter,
                             counter < receiver.epoch_utime() ? "before" : "not before", name(v)));
    fuzz::expect(v == Verdict::ok || v == Verdict::replayed || v == Verdict::stale,
                 fmt::format("accept_counter returned '{}'", name(v)));
    if (known && !it->second.empty()) {
      const std::int64_t highest = *it->second.rbegin();
      if (counter > highest)
        fuzz::expect(v == Verdict::ok, fmt::format("counter {} above the highest {} of {} was "
                                                   "'{}'",
                                                   counter, highest, sender, name(v)));
      if (counter <= highest - Authenticator::kReorderWindowUs)
        fuzz::expect(v != Verdict::ok,
                     fmt::format("counter {} more than the reorder window below {} accepted",
                                 counter, highest));
    }
    if (v == Verdict::ok)
      fuzz::expect(accepted[sender].insert(counter).second,
                   fmt::format("counter {} of {} accepted twice", counter, sender));
  }
}

template <std::size_t I = 0>
void dispatch(std::size_t type, const std::uint8_t* data, std::size_t size) {
  if constexpr (I < kTypeCount) {
    if (type == I) {
      check_message<std::tuple_element_t<I, kTypes>>(data, size);
      return;
    }
    dispatch<I + 1>(type, data, size);
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size < 1 || size > (1U << 20)) return -1;
  const std::size_t selector = data[0] % (kTypeCount + 1);
  if (selector == kTypeCount)
    check_counters(data + 1, size - 1);
  else
    dispatch(selector, data + 1, size - 1);
  return 0;
}
