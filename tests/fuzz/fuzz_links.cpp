// Raw buffers delivered to the real receiving endpoints, through LCM's in-process transport
// (memq://, no network): the request/reply servers of the EDP, ECP and VSP links
// (comm::EdpServer, comm::EcpServer, comm::VspServer), the clients' reply handlers (comm::Client)
// and the SRP's SystemListener.
//
// Input: a sequence of records [channel][flags][length, 2 bytes little-endian][payload]; the last
// record takes what is left. Channel (mod 8): 0 EDP requests, 1 EDP replies, 2 ECP requests, 3 ECP
// replies, 4 SRP messages, 5 process statuses, 6 VSP requests, 7 VSP replies. Flag bit 0: answer
// the requests the server queued. Each input gets fresh endpoints, so that it replays alike.
//
// Built twice: `links` on a bus without a key, `links_auth` (MRROC_FUZZ_LINKS_AUTH) on a bus with
// a key (Bus::enable_auth), where every request/reply endpoint checks the messages' tags. There,
// flag bit 1 signs the payload with the key before sending it (when it decodes as the channel's
// type), flag bit 2 sends the last payload signed on that channel again instead (a replay), and
// flag bit 3 signs it for another channel (a replay from elsewhere; see auth.hpp), and flag bit 4
// first gives the bus a new authenticator, as a restart of every receiving process does (a
// replay is then refused as signed before the start, a fresh signature accepted).
//
// Properties (docs/fuzzing.md), checked after every record:
// - nothing throws out of the handlers, whatever the bytes;
// - a server counts each request exactly once, as new, duplicate, in progress, stale or malformed,
//   and malformed exactly when the bytes do not decode;
// - a new request reaches the queue once, decoded exactly when comm::decode accepts it (else with
//   a non-empty decode error); per client, queued sequence numbers only increase (a request is
//   never executed twice);
// - a client counts undecodable replies as malformed;
// - the SystemListener either counts a message as malformed or hands over one with a known
//   severity or state;
// - with a key: a request or reply (for this client) that decodes and was not freshly signed is
//   dropped as unauthenticated and reaches no queue; a freshly signed one is never dropped as
//   unauthenticated; a replayed one (also one signed for another channel) always is; a process
//   status that is not authentic is dropped, an SRP message passed on;
// - every drop report (Bus::report_drop, to the SRP) names the channel of the message dropped,
//   with drop code malformed or unauthenticated, and reports of one kind are at least
//   Bus::kDropReportPeriod apart.
#include <chrono>
#include <cstddef>
#include <cstdint>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "fuzz_common.hpp"
#include "mrroc/comm/auth.hpp"
#include "mrroc/comm/bus.hpp"
#include "mrroc/comm/links.hpp"
#include "mrroc/comm/reporter.hpp"
#include "mrroc/comm/request_reply.hpp"
#include "mrroc/config/process_set.hpp"
#include "mrroc/core/time.hpp"
#include "mrroc_lcm/process_status_t.hpp"
#include "mrroc_lcm/srp_message_t.hpp"

namespace {

using namespace std::chrono_literals;
using mrroc::comm::LinkStats;

constexpr const char* kRobot = "fuzz";

#ifdef MRROC_FUZZ_LINKS_AUTH
constexpr bool kAuth = true;
#else
constexpr bool kAuth = false;
#endif

/// The channel of the record being delivered (drop reports must name it).
std::string g_channel;

/// Drop reports: the last time each kind (code, channel) was reported.
void on_drop_report(int code, const std::string& text) {
  static std::map<std::string, std::chrono::steady_clock::time_point> last;
  fuzz::expect(code == mrroc::comm::drop_code::malformed ||
                   (kAuth && code == mrroc::comm::drop_code::unauthenticated),
               fmt::format("drop report with code {}: {}", code, text));
  fuzz::expect(
      text.find("'" + g_channel + "'") != std::string::npos,
      fmt::format("drop report for a message on '{}' does not name it: {}", g_channel, text));
  const auto now = std::chrono::steady_clock::now();
  const std::string kind = fmt::format("{} {}", code, g_channel);
  auto it = last.find(kind);
  if (it != last.end())
    fuzz::expect(
        now - it->second >= mrroc::comm::Bus::kDropReportPeriod - 1ms,
        fmt::format("two drop reports of one kind within {} ms: {}",
                    std::chrono::duration_cast<std::chrono::milliseconds>(now - it->second).count(),
                    text));
  last[kind] = now;
}

mrroc::comm::Bus& bus() {
  static mrroc::comm::Bus& b = []() -> mrroc::comm::Bus& {
    static mrroc::comm::Bus made("memq://");
    made.set_drop_sink(on_drop_report);
    return made;
  }();
  return b;
}

/// With a key: a fresh authenticator per input (before its endpoints are made), so that what it
/// remembers of senders does not grow over the run and each input replays alike.
void fresh_key() {
  if (!kAuth) return;
  std::vector<std::uint8_t> key;
  for (unsigned i = 0; i < 32; ++i) key.push_back(static_cast<std::uint8_t>(i * 11U + 5U));
  bus().enable_auth(key);
}

/// Signs `payload` as the channel's type `Msg` with the bus' key (when it decodes); `last` keeps
/// the signed bytes for a replay. Returns whether it was signed.
template <class Msg>
bool sign_payload(std::string& payload, std::string& last, const std::string& channel) {
  Msg m;
  if (m.decode(payload.data(), 0, static_cast<int>(payload.size())) < 0) return false;
  const auto encode = [&] {
    std::string out(static_cast<std::size_t>(m.getEncodedSize()), '\0');
    const int n = m.encode(out.data(), 0, static_cast<int>(out.size()));
    fuzz::expect(n >= 0 && n <= static_cast<int>(out.size()), "a message does not encode");
    out.resize(static_cast<std::size_t>(n));
    return out;
  };
  fuzz::no_throw("comm::sign", [&] { mrroc::comm::sign(*bus().auth(), m, channel); });
  payload = encode();
  last = payload;
  return true;
}

/// How a record was sent: as it was, freshly signed, or a replay of an earlier signed one.
enum class Sent { raw, signed_now, replayed };

/// Applies flag bits 1 to 4 (only with a key) to a payload sent on `channel`.
template <class Msg>
Sent prepare(std::string& payload, std::uint8_t flags, std::string& last_signed,
             const std::string& channel) {
  if (!kAuth) return Sent::raw;
  if ((flags & 16U) != 0) {
    // Every receiver restarts: what it saw is forgotten. A restart takes time: the new start
    // comes after every counter signed so far (several may fall in one microsecond).
    const std::int64_t last = bus().auth()->next_counter();
    while (mrroc::now_utime() <= last) {
    }
    fresh_key();
  }
  if ((flags & 4U) != 0 && !last_signed.empty()) {
    payload = last_signed;
    return Sent::replayed;
  }
  if ((flags & 8U) != 0) {
    std::string elsewhere;
    if (sign_payload<Msg>(payload, elsewhere, channel + "/other")) return Sent::replayed;
  }
  if ((flags & 2U) != 0 && sign_payload<Msg>(payload, last_signed, channel))
    return Sent::signed_now;
  return Sent::raw;
}

/// Dispatches everything queued on the in-process transport.
void deliver() {
  for (int i = 0; i < 1000; ++i) {
    int handled = 0;
    fuzz::no_throw("LCM dispatch", [&] { handled = bus().lcm().handleTimeout(0); });
    if (handled <= 0) return;
  }
  fuzz::fail("the in-process transport never ran empty (a handler publishing in a loop?)");
}

std::uint64_t total(const LinkStats& s) {
  return s.requests + s.duplicates + s.in_progress + s.stale + s.malformed + s.unauthenticated;
}

template <class Msg>
std::optional<Msg> lcm_decode(const std::string& bytes) {
  Msg m;
  int n = -1;
  fuzz::no_throw("LCM decode",
                 [&] { n = m.decode(bytes.data(), 0, static_cast<int>(bytes.size())); });
  if (n < 0) return std::nullopt;
  return m;
}

/// One server side of a link (EDP, ECP or VSP) plus what it has queued so far.
template <class PlainServer, class LcmReq, class PlainRep>
struct ServerSide {
  PlainServer server;
  std::string channel;
  std::map<std::string, std::int64_t> last_queued;  // client -> highest queued sequence

  ServerSide(const std::string& name, const std::string& request_channel,
             const std::string& reply_channel)
      : server(bus(), name, request_channel, reply_channel), channel(request_channel) {}

  std::string last_signed;

  void receive(std::string payload, std::uint8_t flags) {
    const Sent sent = prepare<LcmReq>(payload, flags, last_signed, channel);
    const LinkStats before = server.stats();
    g_channel = channel;
    bus().lcm().publish(channel, payload.data(), static_cast<unsigned>(payload.size()));
    deliver();
    const LinkStats after = server.stats();
    const std::optional<LcmReq> raw = lcm_decode<LcmReq>(payload);
    check_authentication(sent, raw.has_value(), before.unauthenticated, after.unauthenticated,
                         channel);
    fuzz::expect(total(after) == total(before) + 1,
                 fmt::format("server on '{}' counted a request {} times", channel,
                             total(after) - total(before)));
    fuzz::expect((after.malformed == before.malformed + 1) == !raw.has_value(),
                 fmt::format("server on '{}': malformed count {} -> {} for bytes that {}", channel,
                             before.malformed, after.malformed, raw ? "decode" : "do not decode"));
    const std::uint64_t accepted = after.requests - before.requests;

    std::uint64_t queued = 0;
    for (;;) {
      std::optional<typename PlainServer::Incoming> in;
      fuzz::no_throw("wait_request", [&] { in = server.wait_request(0ms); });
      if (!in) break;
      ++queued;
      fuzz::expect(raw.has_value(), "a request that does not decode reached the queue");
      const std::string& client = raw->header.sender;
      const std::int64_t seq = raw->header.seq;
      fuzz::expect(in->responder.client() == client, "queued request names another client");
      auto last = last_queued.find(client);
      fuzz::expect(
          last == last_queued.end() || seq > last->second,
          fmt::format("request {} of client {} queued again (after {})", seq, fuzz::escaped(client),
                      last == last_queued.end() ? 0 : last->second));
      last_queued[client] = seq;
      bool decodes = false;
      fuzz::guarded<mrroc::comm::DecodeError>(
          "comm::decode",
          [&] {
            (void)mrroc::comm::decode(*raw);
            decodes = true;
          },
          [](const mrroc::comm::DecodeError&) {});
      fuzz::expect(in->request.has_value() == decodes,
                   "the server's decode verdict differs from comm::decode");
      fuzz::expect(in->request.has_value() || !in->decode_error.empty(),
                   "a request that failed to decode carries no reason");
      if ((flags & 1U) != 0) {
        PlainRep reply{};
        if (!in->request) reply.error_text = "malformed: " + in->decode_error;
        fuzz::no_throw("Responder::reply", [&] { in->responder.reply(reply); });
      }
    }
    fuzz::expect(queued == accepted,
                 fmt::format("server on '{}' accepted {} requests but queued {}", channel, accepted,
                             queued));
    deliver();  // the replies (and re-sent cached replies) go to the clients
  }
};

/// With a key: whether the endpoint dropped a message that decodes as unauthenticated exactly
/// when it was not freshly signed. Without one: never.
void check_authentication(Sent sent, bool decodes, std::uint64_t before, std::uint64_t after,
                          const std::string& channel) {
  const bool dropped = after != before;
  fuzz::expect(after - before <= 1,
               fmt::format("endpoint on '{}' counted one message {} times as unauthenticated",
                           channel, after - before));
  const bool expected = kAuth && decodes && sent != Sent::signed_now;
  fuzz::expect(dropped == expected,
               fmt::format("endpoint on '{}' {} a message that {} and was {}", channel,
                           dropped ? "dropped as unauthenticated" : "accepted",
                           decodes ? "decodes" : "does not decode",
                           sent == Sent::raw          ? "not signed"
                           : sent == Sent::signed_now ? "signed with the key"
                                                      : "a replay"));
}

template <class LcmReq, class LcmRep>
struct ClientSide {
  mrroc::comm::Client<LcmReq, LcmRep> client;
  std::string channel;
  ClientSide(const std::string& request_channel, const std::string& reply_channel)
      : client(bus(), "client", "fuzz server", request_channel, reply_channel),
        channel(reply_channel) {}

  std::string last_signed;

  void receive(std::string payload, std::uint8_t flags) {
    const Sent sent = prepare<LcmRep>(payload, flags, last_signed, channel);
    const LinkStats before = client.stats();
    g_channel = channel;
    bus().lcm().publish(channel, payload.data(), static_cast<unsigned>(payload.size()));
    deliver();
    const LinkStats after = client.stats();
    const std::optional<LcmRep> rep = lcm_decode<LcmRep>(payload);
    const bool decodes = rep.has_value();
    // The client looks only at replies addressed to it.
    check_authentication(sent, decodes && rep->header.recipient == "client", before.unauthenticated,
                         after.unauthenticated, channel);
    fuzz::expect(
        (after.malformed == before.malformed + 1) == !decodes,
        fmt::format("client on '{}': malformed count {} -> {} for bytes that {}", channel,
                    before.malformed, after.malformed, decodes ? "decode" : "do not decode"));
    fuzz::expect(after.stale <= before.stale + 1, "client counted one reply twice as stale");
  }
};

struct ListenerSide {
  std::uint64_t messages = 0;
  std::uint64_t statuses = 0;
  mrroc::SystemListener listener;
  ListenerSide()
      : listener(
            bus(),
            [this](const mrroc::SrpMessage& m) {
              ++messages;
              const int s = static_cast<int>(m.severity);
              fuzz::expect(s >= 0 && s <= 4, fmt::format("SRP message with severity {}", s));
            },
            [this](const mrroc::ProcessStatus& st) {
              ++statuses;
              const int s = static_cast<int>(st.state);
              fuzz::expect(s >= 1 && s <= 6, fmt::format("process status with state {}", s));
            }) {}

  void receive(const char* channel, const std::string& payload) {
    g_channel = channel;
    const std::uint64_t malformed = listener.malformed();
    const std::uint64_t unauthenticated = listener.unauthenticated();
    const std::uint64_t handled = messages + statuses;
    bus().lcm().publish(channel, payload.data(), static_cast<unsigned>(payload.size()));
    deliver();
    // Statuses that are not authentic are dropped; SRP messages are passed on, marked.
    const bool status = std::string(channel) == mrroc::channels::status;
    const std::uint64_t dropped = listener.malformed() - malformed +
                                  (status ? listener.unauthenticated() - unauthenticated : 0);
    const std::uint64_t passed = messages + statuses - handled;
    fuzz::expect(dropped + passed == 1,
                 fmt::format("SystemListener on '{}' dropped {} and passed on {} of one message",
                             channel, dropped, passed));
  }
};

using EdpSide = ServerSide<mrroc::comm::EdpServer, mrroc_lcm::edp_instruction_t, mrroc::edp::Reply>;
using EcpSide =
    ServerSide<mrroc::comm::EcpServer, mrroc_lcm::mp_ecp_command_t, mrroc::ecp::EcpReply>;
using VspSide = ServerSide<mrroc::comm::VspServer, mrroc_lcm::vsp_command_t, mrroc::vsp::Reply>;

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  namespace channels = mrroc::channels;
  deliver();  // nothing may be left from the previous input
  fresh_key();
  EdpSide edp("edp/fuzz", channels::edp_command(kRobot), channels::edp_reply(kRobot));
  EcpSide ecp("ecp/fuzz", channels::ecp_command(kRobot), channels::ecp_reply(kRobot));
  ClientSide<mrroc_lcm::edp_instruction_t, mrroc_lcm::edp_reply_t> edp_client(
      channels::edp_command(kRobot), channels::edp_reply(kRobot));
  ClientSide<mrroc_lcm::mp_ecp_command_t, mrroc_lcm::ecp_mp_reply_t> ecp_client(
      channels::ecp_command(kRobot), channels::ecp_reply(kRobot));
  ListenerSide srp;
  const std::string vsp_command = channels::vsp_command(kRobot);
  const std::string vsp_reply = channels::vsp_reply(kRobot);
  VspSide vsp("vsp/fuzz", vsp_command, vsp_reply);
  ClientSide<mrroc_lcm::vsp_command_t, mrroc_lcm::vsp_reply_t> vsp_client(vsp_command, vsp_reply);

  std::size_t pos = 0;
  while (pos + 4 <= size) {
    const std::uint8_t channel = data[pos];
    const std::uint8_t flags = data[pos + 1];
    std::size_t length =
        static_cast<std::size_t>(data[pos + 2]) | (static_cast<std::size_t>(data[pos + 3]) << 8U);
    pos += 4;
    if (length > size - pos) length = size - pos;
    const std::string payload(reinterpret_cast<const char*>(data + pos), length);
    pos += length;
    switch (channel % 8U) {
      case 0: edp.receive(payload, flags); break;
      case 1: edp_client.receive(payload, flags); break;
      case 2: ecp.receive(payload, flags); break;
      case 3: ecp_client.receive(payload, flags); break;
      case 4: srp.receive(channels::srp, payload); break;
      case 5: srp.receive(channels::status, payload); break;
      case 6: vsp.receive(payload, flags); break;
      default: vsp_client.receive(payload, flags); break;
    }
  }
  return 0;
}
