// Message authentication (include/mrroc/comm/auth.hpp): key files, tags, counters and replays,
// and request/reply endpoints that drop and report what is not authentic; link delays; reports
// of malformed messages. Two buses in one process need UDP multicast (the test runs in its own
// network namespace).
#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <filesystem>
#include <fstream>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "drops.hpp"
#include "mrroc/comm/auth.hpp"
#include "mrroc/comm/edge.hpp"
#include "mrroc/comm/messages.hpp"
#include "mrroc/comm/reporter.hpp"
#include "mrroc/comm/request_reply.hpp"
#include "mrroc/config/process_set.hpp"
#include "mrroc/core/error.hpp"
#include "mrroc/core/time.hpp"
#include "mrroc_lcm/ecp_mp_reply_t.hpp"
#include "mrroc_lcm/mp_ecp_command_t.hpp"

using namespace mrroc;
using namespace std::chrono_literals;
using Req = mrroc_lcm::mp_ecp_command_t;
using Rep = mrroc_lcm::ecp_mp_reply_t;
namespace fs = std::filesystem;

namespace {

constexpr const char* kUrl = "udpm://239.255.76.67:7667?ttl=0";

std::vector<std::uint8_t> key(std::uint8_t fill) { return std::vector<std::uint8_t>(32, fill); }

fs::path write_file(const std::string& name, const std::string& text) {
  const fs::path p = fs::temp_directory_path() / ("mrroc-auth-" + std::to_string(getpid()) + name);
  std::ofstream(p) << text;
  fs::permissions(p, fs::perms::owner_read | fs::perms::owner_write);  // a secret: 0600
  return p;
}

Req request(int value) {
  Req r{};
  r.command = Req::START_TASK;
  r.motion_steps = value;
  r.arguments = "go";
  return r;
}

struct Echo {
  std::atomic<int> executions{0};
  std::unique_ptr<comm::Server<Req, Rep>> server;
  explicit Echo(comm::Bus& bus, comm::ServerOptions options = {}, const std::string& prefix = "a") {
    server = std::make_unique<comm::Server<Req, Rep>>(
        bus, "server", prefix + "/cmd", prefix + "/reply",
        [this](const Req& r, comm::Server<Req, Rep>::Responder responder) {
          ++executions;
          Rep rep{};
          rep.reply = Rep::ACKNOWLEDGE;
          rep.error_code = r.motion_steps;
          responder.reply(rep);
        },
        options);
  }
};

}  // namespace

TEST(AuthKey, FileErrorsNameTheFileAndTheProblem) {
  const fs::path good = write_file("good", std::string(64, 'a') + "\n");
  EXPECT_EQ(comm::load_auth_key(good).size(), 32U);
  EXPECT_EQ(comm::load_auth_key(good)[0], 0xaa);
  const fs::path short_key = write_file("short", "abcd");
  try {
    (void)comm::load_auth_key(short_key);
    FAIL() << "a 2-byte key was accepted";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find(short_key.string()), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("holds 4 hexadecimal digits"), std::string::npos)
        << e.what();
  }
  const fs::path bad = write_file("bad", std::string(63, 'a') + "x");
  EXPECT_THROW((void)comm::load_auth_key(bad), Error);
  EXPECT_THROW((void)comm::load_auth_key("/nonexistent/key"), Error);
  // A key others can read is refused, naming the mode and the fix.
  fs::permissions(good, fs::perms::group_read | fs::perms::others_read, fs::perm_options::add);
  try {
    (void)comm::load_auth_key(good);
    FAIL() << "a key readable by others was accepted";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("authentication key file '" + good.string() +
                                         "' has mode 0644: other users may read it"),
              std::string::npos)
        << e.what();
    EXPECT_NE(std::string(e.what()).find("chmod 600"), std::string::npos) << e.what();
  }
  fs::remove(good);
  fs::remove(short_key);
  fs::remove(bad);
}

TEST(Auth, SignedMessagesVerifyAndTamperingOrReplayIsCaught) {
  comm::Authenticator sender(key(7));
  comm::Authenticator receiver(key(7));
  comm::Authenticator stranger(key(8));
  Req r = request(5);
  r.header.sender = "ecp#1";
  comm::sign(sender, r, "a/cmd");
  EXPECT_EQ(r.header.auth_len, 32);
  EXPECT_EQ(comm::verify(receiver, r, "a/cmd"), comm::Authenticator::Verdict::ok);
  // The same message again: a replay.
  EXPECT_EQ(comm::verify(receiver, r, "a/cmd"), comm::Authenticator::Verdict::replayed);
  // Changed content, changed sender, or another key: a wrong tag.
  Req changed = r;
  changed.motion_steps = 6;
  EXPECT_EQ(comm::verify(receiver, changed, "a/cmd"), comm::Authenticator::Verdict::bad_tag);
  Req renamed = r;
  renamed.header.sender = "ecp#2";
  EXPECT_EQ(comm::verify(receiver, renamed, "a/cmd"), comm::Authenticator::Verdict::bad_tag);
  Req foreign = request(5);
  foreign.header.sender = "ecp#1";
  comm::sign(stranger, foreign, "a/cmd");
  EXPECT_EQ(comm::verify(receiver, foreign, "a/cmd"), comm::Authenticator::Verdict::bad_tag);
  // No tag at all.
  Req plain = request(5);
  EXPECT_EQ(comm::verify(receiver, plain, "a/cmd"), comm::Authenticator::Verdict::missing);
}

TEST(Auth, AStringHoldingANulStillVerifiesAfterTheWire) {
  // LCM's encoder cuts a string at a NUL: the tag must cover the bytes that go out.
  comm::Authenticator sender(key(9));
  comm::Authenticator receiver(key(9));
  Req r = request(1);
  r.header.sender = "ecp#1";
  r.arguments = std::string("ab\0cd", 5);
  comm::sign(sender, r, "a/cmd");
  std::vector<std::uint8_t> wire(static_cast<std::size_t>(r.getEncodedSize()));
  const int n = r.encode(wire.data(), 0, static_cast<int>(wire.size()));
  ASSERT_GT(n, 0);
  Req received;
  ASSERT_GE(received.decode(wire.data(), 0, n), 0);
  EXPECT_EQ(received.arguments, "ab");
  EXPECT_EQ(comm::verify(receiver, received, "a/cmd"), comm::Authenticator::Verdict::ok);
}

TEST(Auth, CountersIncreaseAndReorderingWithinASecondIsAccepted) {
  comm::Authenticator a(key(1));
  std::int64_t last = 0;
  for (int i = 0; i < 1000; ++i) {
    const std::int64_t c = a.next_counter();
    ASSERT_GT(c, last);
    last = c;
  }
  const std::int64_t now = now_utime();
  comm::Authenticator r(key(1), now - 5'000'000);  // started 5 s ago
  using V = comm::Authenticator::Verdict;
  EXPECT_EQ(r.accept_counter("x", "c", now), V::ok);
  EXPECT_EQ(r.accept_counter("x", "c", now + 10), V::ok);
  EXPECT_EQ(r.accept_counter("x", "c", now + 5), V::ok) << "overtaken message within the window";
  EXPECT_EQ(r.accept_counter("x", "c", now + 5), V::replayed);
  EXPECT_EQ(r.accept_counter("x", "c", now + 10), V::replayed);
  EXPECT_EQ(r.accept_counter("x", "c", now - 2'000'000), V::replayed) << "older than the window";
  // Counters are kept per sender and channel: the same counter on another channel is new.
  EXPECT_EQ(r.accept_counter("x", "d", now + 10), V::ok);
  EXPECT_EQ(r.accept_counter("x", "d", now + 10), V::replayed);
  // Signed before the receiver started (its epoch): recorded earlier, replayed now, however
  // recent, for a new sender and within a known sender's reorder window alike.
  EXPECT_EQ(r.accept_counter("y", "c", now - 5'000'001), V::stale);
  EXPECT_EQ(r.accept_counter("y", "c", now - 5'000'000), V::ok);
  EXPECT_EQ(r.accept_counter("z", "c", now - 4'500'000), V::ok);
  EXPECT_EQ(r.accept_counter("z", "c", now - 5'000'001), V::stale);
}

// The tag covers the channel: a request recorded on one robot's command channel does not
// verify on another's (configs/tight-bar.toml: left/edp/cmd, right/edp/cmd), whatever the
// counters.
TEST(Auth, AMessageSignedForOneChannelDoesNotVerifyOnAnother) {
  comm::Authenticator sender(key(7));
  comm::Authenticator receiver(key(7));
  Req r = request(5);
  r.header.sender = "ecp/left#1";
  comm::sign(sender, r, "left/edp/cmd");
  EXPECT_EQ(comm::verify(receiver, r, "right/edp/cmd"), comm::Authenticator::Verdict::bad_tag);
  EXPECT_EQ(comm::verify(receiver, r, "left/edp/cm"), comm::Authenticator::Verdict::bad_tag);
  EXPECT_EQ(comm::verify(receiver, r, "left/edp/cmd"), comm::Authenticator::Verdict::ok);
  // The channel and the message are framed apart: moving a byte between them changes the tag.
  const comm::Authenticator::Tag a =
      sender.mac("ab", reinterpret_cast<const std::uint8_t*>("c"), 1);
  const comm::Authenticator::Tag b =
      sender.mac("a", reinterpret_cast<const std::uint8_t*>("bc"), 2);
  EXPECT_NE(a, b);
}

// A process that starts (e.g. restarted by the launcher) refuses everything signed before it
// started, also what it never saw, and takes what is signed afterwards.
TEST(Auth, ARestartedReceiverRefusesTrafficRecordedBeforeItStarted) {
  comm::Authenticator sender(key(7));
  Req recorded = request(1);
  recorded.header.sender = "ecp#1";
  comm::sign(sender, recorded, "irb6/edp/cmd");
  std::this_thread::sleep_for(2ms);
  comm::Authenticator restarted(key(7));
  EXPECT_EQ(comm::verify(restarted, recorded, "irb6/edp/cmd"), comm::Authenticator::Verdict::stale);
  Req fresh = request(2);
  fresh.header.sender = "ecp#1";
  comm::sign(sender, fresh, "irb6/edp/cmd");
  EXPECT_EQ(comm::verify(restarted, fresh, "irb6/edp/cmd"), comm::Authenticator::Verdict::ok);
  // Within a second of the fresh one, so a reordered message but for the epoch.
  EXPECT_EQ(comm::verify(restarted, recorded, "irb6/edp/cmd"), comm::Authenticator::Verdict::stale);
}

TEST(Auth, EndpointsWithTheKeyTalkAndDropStrangersWithAReport) {
  comm::Bus server_bus(kUrl);
  comm::Bus client_bus(kUrl);
  comm::Bus stranger_bus(kUrl);
  server_bus.enable_auth(key(3));
  client_bus.enable_auth(key(3));
  stranger_bus.enable_auth(key(4));  // another key; a bus without any key behaves alike
  test::Drops drops;
  drops.attach(server_bus);
  Echo echo(server_bus);
  comm::Client<Req, Rep> client(client_bus, "client", "echo", "a/cmd", "a/reply");
  comm::Client<Req, Rep> stranger(stranger_bus, "stranger", "echo", "a/cmd", "a/reply",
                                  comm::ClientOptions{20ms, 3, {}});
  server_bus.start();
  client_bus.start();
  stranger_bus.start();
  for (int i = 1; i <= 20; ++i) ASSERT_EQ(client.call(request(i)).error_code, i);
  EXPECT_EQ(echo.executions, 20);
  EXPECT_THROW((void)stranger.call(request(99)), TimeoutError);
  EXPECT_EQ(echo.executions, 20) << "the stranger's request was executed";
  EXPECT_EQ(echo.server->stats().unauthenticated, 3U) << "3 attempts, 3 drops";
  const auto seen = drops.get();
  ASSERT_EQ(seen.size(), 1U) << "reports are rate-limited: the first at once, then quiet";
  EXPECT_EQ(seen[0].first, comm::drop_code::unauthenticated);
  EXPECT_EQ(seen[0].second,
            "dropped a message on 'a/cmd' from 'stranger': wrong authentication tag");
  // A message of the authentic client, recorded and sent again by somebody else: a replay.
  Req recorded = request(42);
  recorded.header.sender = "client";
  recorded.header.seq = 1000;
  comm::sign(*client_bus.auth(), recorded, "a/cmd");
  client_bus.lcm().publish("a/cmd", &recorded);
  std::this_thread::sleep_for(100ms);
  EXPECT_EQ(echo.executions, 21);
  stranger_bus.lcm().publish("a/cmd", &recorded);  // the replay
  std::this_thread::sleep_for(100ms);
  EXPECT_EQ(echo.executions, 21) << "the replayed request was executed";
  EXPECT_EQ(echo.server->stats().unauthenticated, 4U);
  server_bus.stop();
  client_bus.stop();
  stranger_bus.stop();
}

// Two servers of one set (two robots' EDPs): a request recorded on one's channel and sent on
// the other's is refused there, and a status that a stranger forges is not acted on, while a
// forged SRP line is kept, marked.
TEST(Auth, RequestsReplayedOnAnotherChannelAndForgedStatusesAreRefused) {
  comm::Bus server_bus(kUrl);
  comm::Bus client_bus(kUrl);
  comm::Bus stranger_bus(kUrl);
  server_bus.enable_auth(key(3));
  client_bus.enable_auth(key(3));
  test::Drops drops;
  drops.attach(server_bus);
  Echo left(server_bus, {}, "left");
  Echo right(server_bus, {}, "right");
  std::mutex mutex;
  std::vector<std::string> lines;
  std::vector<std::string> statuses;
  SystemListener listener(
      server_bus,
      [&](const SrpMessage& m) {
        std::lock_guard lock(mutex);
        lines.push_back(m.text);
      },
      [&](const ProcessStatus& s) {
        std::lock_guard lock(mutex);
        statuses.push_back(s.process);
      });
  server_bus.start();
  client_bus.start();
  // Recorded from the left client, sent on the right channel by someone without the key.
  Req recorded = request(7);
  recorded.header.sender = "ecp/left#1";
  recorded.header.seq = 1;
  comm::sign(*client_bus.auth(), recorded, "left/edp/cmd");
  stranger_bus.lcm().publish("right/cmd", &recorded);
  // A status and an SRP line from a stranger (no key), then the same from a process with it.
  auto status = [](const std::string& process) {
    ProcessStatus s;
    s.process = process;
    s.state = ProcessState::failed;
    s.pid = 1;
    return s;
  };
  auto line = [](const std::string& text) {
    SrpMessage m;
    m.utime = now_utime();
    m.process = "edp";
    m.severity = Severity::error;
    m.text = text;
    return m;
  };
  comm::broadcast(stranger_bus, channels::status, {now_utime(), "forger#9", 1}, status("forged"));
  comm::broadcast(stranger_bus, channels::srp, {now_utime(), "forger#9", 2}, line("forged"));
  comm::broadcast(client_bus, channels::status, {now_utime(), "edp#2", 1}, status("signed"));
  comm::broadcast(client_bus, channels::srp, {now_utime(), "edp#2", 2}, line("signed"));
  std::this_thread::sleep_for(200ms);
  server_bus.stop();
  client_bus.stop();
  EXPECT_EQ(right.executions, 0) << "a request signed for left/cmd was executed on right/cmd";
  EXPECT_EQ(right.server->stats().unauthenticated, 1U);
  bool reported = false;
  for (const auto& [code, text] : drops.get())
    reported = reported || (code == comm::drop_code::unauthenticated &&
                            text ==
                                "dropped a message on 'right/cmd' from 'ecp/left#1': wrong "
                                "authentication tag");
  EXPECT_TRUE(reported) << "the replay on another channel was not reported";
  std::lock_guard lock(mutex);
  EXPECT_EQ(statuses, std::vector<std::string>{"signed"});
  ASSERT_EQ(lines.size(), 2U);
  const std::string forged = std::string(SystemListener::kUnverifiedMark) + "forged";
  EXPECT_TRUE((lines[0] == forged && lines[1] == "signed") ||
              (lines[1] == forged && lines[0] == "signed"))
      << lines[0] << " / " << lines[1];
  EXPECT_EQ(listener.unauthenticated(), 2U);
}

TEST(Auth, DropReportsAreRateLimitedPerKind) {
  comm::Bus bus(kUrl);
  test::Drops drops;
  drops.attach(bus);
  for (int i = 0; i < 5; ++i) bus.report_drop(1, "kind", "text");
  ASSERT_EQ(drops.get().size(), 1U);
  EXPECT_EQ(drops.get()[0].second, "text");
  bus.report_drop(1, "other kind", "other");
  EXPECT_EQ(drops.get().size(), 2U) << "each kind has its own limit";
}

TEST(Links, MalformedMessagesAreCountedDroppedAndReported) {
  comm::Bus bus(kUrl);
  test::Drops drops;
  drops.attach(bus);
  Echo echo(bus);
  bus.start();
  const std::vector<std::uint8_t> garbage{1, 2, 3, 4, 5, 6, 7, 8, 9};
  for (int i = 0; i < 3; ++i) bus.lcm().publish("a/cmd", garbage.data(), 9);
  std::this_thread::sleep_for(200ms);
  bus.stop();
  EXPECT_EQ(echo.server->stats().malformed, 3U);
  EXPECT_EQ(echo.executions, 0);
  const auto seen = drops.get();
  ASSERT_EQ(seen.size(), 1U);
  EXPECT_EQ(seen[0].first, comm::drop_code::malformed);
  EXPECT_EQ(seen[0].second, "dropped a malformed message on 'a/cmd' (9 bytes that do not decode)");
}

TEST(Links, DelayedAndReorderedMessagesStillGiveEveryReplyOnce) {
  comm::Bus bus(kUrl);
  comm::ServerOptions so;
  so.faults = comm::LinkFaults{0.05, 0.1, 5, 0.5, 15.0};
  Echo echo(bus, so);
  comm::ClientOptions co;
  co.attempt_timeout = 10ms;
  co.max_attempts = 100;
  co.faults = comm::LinkFaults{0.05, 0.1, 9, 0.5, 15.0};
  comm::Client<Req, Rep> client(bus, "client", "echo", "a/cmd", "a/reply", co);
  bus.start();
  constexpr int kCalls = 200;
  const auto t0 = std::chrono::steady_clock::now();
  for (int i = 1; i <= kCalls; ++i) ASSERT_EQ(client.call(request(i)).error_code, i);
  const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  std::this_thread::sleep_for(50ms);
  bus.stop();
  EXPECT_EQ(echo.executions, kCalls) << "a request executed twice or not at all";
  EXPECT_GT(client.stats().stale + echo.server->stats().stale, 0U)
      << "late copies must have arrived after their successors";
  std::printf("%d calls over delayed links in %.2f s, %llu resends\n", kCalls, s,
              static_cast<unsigned long long>(client.stats().resends));
}
