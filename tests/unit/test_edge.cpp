// The typed broadcast and subscriber (comm/edge.hpp): plain values delivered with their header,
// malformed messages counted and reported instead of reaching the handler, authentication
// checked on request.
#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdlib>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "drops.hpp"
#include "mrroc/comm/edge.hpp"

using namespace mrroc;
using namespace std::chrono_literals;

namespace {

/// In-process transport by default; MRROC_TEST_LCM_URL selects another one (as in
/// test_request_reply).
std::string test_url() {
  const char* url = std::getenv("MRROC_TEST_LCM_URL");
  return url != nullptr && *url != '\0' ? url : "memq://";
}

/// What a handler received, for the test thread to wait on.
template <class T>
struct Inbox {
  std::mutex mutex;
  std::condition_variable cv;
  std::vector<T> values;
  std::vector<comm::Envelope> headers;
  std::vector<std::string> channels;
  void add(const T& v, const comm::Received& in) {
    std::lock_guard lock(mutex);
    values.push_back(v);
    headers.push_back(in.header());
    channels.push_back(in.channel());
    cv.notify_all();
  }
  bool wait_for(std::size_t n, std::chrono::milliseconds timeout = 2000ms) {
    std::unique_lock lock(mutex);
    return cv.wait_for(lock, timeout, [&] { return values.size() >= n; });
  }
};

template <class Msg>
void publish_raw(comm::Bus& bus, const std::string& channel, const Msg& m) {
  bus.lcm().publish(channel, &m);
}

}  // namespace

TEST(Edge, DeliversPlainValuesWithTheirHeader) {
  comm::Bus bus(test_url());
  Inbox<RobotState> inbox;
  comm::Subscriber<RobotState> sub(
      bus, "irb6/edp/state",
      [&](const RobotState& s, const comm::Received& in) { inbox.add(s, in); });
  bus.start();
  RobotState state;
  state.robot = "irb6";
  state.estop = true;
  state.q = {0.5, 0.25};
  state.dq = {0.0, 0.0};
  state.q_desired = {0.5, 0.25};
  comm::broadcast(bus, "irb6/edp/state", comm::Envelope{1700000000000000, "edp/irb6#1", 41}, state);
  ASSERT_TRUE(inbox.wait_for(1));
  std::lock_guard lock(inbox.mutex);
  EXPECT_EQ(inbox.values[0].robot, "irb6");
  EXPECT_TRUE(inbox.values[0].estop);
  EXPECT_EQ(inbox.values[0].q, state.q);
  EXPECT_EQ(inbox.headers[0].utime, 1700000000000000);
  EXPECT_EQ(inbox.headers[0].sender, "edp/irb6#1");
  EXPECT_EQ(inbox.headers[0].seq, 41);
  EXPECT_EQ(inbox.channels[0], "irb6/edp/state");
  EXPECT_EQ(sub.malformed(), 0u);
}

TEST(Edge, MalformedMessagesAreCountedAndReportedNotDelivered) {
  comm::Bus bus(test_url());
  test::Drops drops;
  drops.attach(bus);
  Inbox<EmergencyStop> inbox;
  std::atomic<int> told{0};
  std::string why;
  comm::SubscriberOptions options;
  options.on_malformed = [&](const std::string& channel, const std::string& text) {
    if (channel == "mrroc/estop" && told++ == 0) why = text;
  };
  comm::Subscriber<EmergencyStop> sub(
      bus, "mrroc/estop",
      [&](const EmergencyStop& s, const comm::Received& in) { inbox.add(s, in); },
      std::move(options));
  bus.start();
  // An action outside the .lcm constants: decodes as LCM, does not validate.
  mrroc_lcm::emergency_stop_t bad{};
  bad.action = 9;
  publish_raw(bus, "mrroc/estop", bad);
  // Bytes that are not an emergency_stop_t at all.
  const std::vector<std::uint8_t> junk{1, 2, 3, 4, 5};
  bus.lcm().publish("mrroc/estop", junk.data(), static_cast<unsigned>(junk.size()));
  // Then a good one: the subscriber is still alive and delivers it.
  comm::broadcast(bus, "mrroc/estop", comm::Envelope{1, "ui#2", 1},
                  EmergencyStop{EstopAction::engage, "", "test", 0, {}, {}});
  ASSERT_TRUE(inbox.wait_for(1));
  {
    std::lock_guard lock(inbox.mutex);
    ASSERT_EQ(inbox.values.size(), 1u);
    EXPECT_EQ(inbox.values[0].action, EstopAction::engage);
  }
  EXPECT_EQ(sub.malformed(), 2u);
  EXPECT_EQ(told.load(), 2);
  EXPECT_NE(why.find("action"), std::string::npos) << why;
  EXPECT_NE(why.find("9"), std::string::npos) << why;
  // Reported once per channel within the report period (Bus::report_drop), naming the reason.
  const auto seen = drops.get();
  ASSERT_EQ(seen.size(), 1u);
  EXPECT_EQ(seen[0].first, comm::drop_code::malformed);
  EXPECT_NE(seen[0].second.find("mrroc/estop"), std::string::npos) << seen[0].second;
  EXPECT_NE(seen[0].second.find("action"), std::string::npos) << seen[0].second;
}

TEST(Edge, UnreportedSubscribersOnlyCount) {
  comm::Bus bus(test_url());
  test::Drops drops;
  drops.attach(bus);
  comm::Subscriber<ProcessStatus> sub(
      bus, "mrroc/status", [](const ProcessStatus&, const comm::Received&) {},
      comm::SubscriberOptions::unreported());
  bus.start();
  mrroc_lcm::process_status_t bad{};
  bad.state = 0;
  publish_raw(bus, "mrroc/status", bad);
  const auto until = std::chrono::steady_clock::now() + 2s;
  while (sub.malformed() == 0 && std::chrono::steady_clock::now() < until)
    std::this_thread::sleep_for(5ms);
  EXPECT_EQ(sub.malformed(), 1u);
  EXPECT_TRUE(drops.get().empty());
}

TEST(Edge, DecodeBytesNamesWhyItFailed) {
  const auto m = comm::encode(mp::OperatorReply{});
  std::vector<std::uint8_t> buf(static_cast<std::size_t>(m.getEncodedSize()));
  m.encode(buf.data(), 0, static_cast<int>(buf.size()));
  comm::Envelope header;
  std::string error;
  auto ok = comm::decode_bytes<mp::OperatorReply>(buf.data(), static_cast<int>(buf.size()), &header,
                                                  &error);
  ASSERT_TRUE(ok.has_value()) << error;
  EXPECT_EQ(ok->state, mp::TaskState::idle);
  EXPECT_FALSE(comm::decode_bytes<mp::OperatorReply>(buf.data(), 3, nullptr, &error).has_value());
  EXPECT_EQ(error, "the bytes do not decode");
  auto bad = m;
  bad.state = 42;
  buf.resize(static_cast<std::size_t>(bad.getEncodedSize()));
  bad.encode(buf.data(), 0, static_cast<int>(buf.size()));
  EXPECT_FALSE(comm::decode_bytes<mp::OperatorReply>(buf.data(), static_cast<int>(buf.size()),
                                                     nullptr, &error)
                   .has_value());
  EXPECT_NE(error.find("state"), std::string::npos) << error;
}

TEST(Edge, AuthenticityIsCheckedWhenTheHandlerAsks) {
  // Two connections on one multicast group (in the test's own network namespace): the set's
  // members sign with one key, a stranger with another.
  constexpr const char* kUrl = "udpm://239.255.76.67:7667?ttl=0";
  comm::Bus receiver(kUrl);
  comm::Bus member(kUrl);
  comm::Bus stranger(kUrl);
  receiver.enable_auth(std::vector<std::uint8_t>(32, 3));
  member.enable_auth(std::vector<std::uint8_t>(32, 3));
  stranger.enable_auth(std::vector<std::uint8_t>(32, 4));
  test::Drops drops;
  drops.attach(receiver);
  Inbox<EmergencyStop> inbox;
  std::mutex mutex;
  std::vector<std::pair<std::string, bool>> verdicts;
  comm::Subscriber<EmergencyStop> sub(receiver, "edge/estop",
                                      [&](const EmergencyStop& s, const comm::Received& in) {
                                        {
                                          std::lock_guard lock(mutex);
                                          verdicts.emplace_back(in.header().sender, in.authentic());
                                        }
                                        inbox.add(s, in);
                                      });
  receiver.start();
  const EmergencyStop release{EstopAction::release, "", "", 0, {}, {}};
  comm::broadcast(stranger, "edge/estop", comm::Envelope{1, "stranger#1", 1}, release);
  ASSERT_TRUE(inbox.wait_for(1));
  comm::broadcast(member, "edge/estop", comm::Envelope{2, "ui#1", 1}, release);
  ASSERT_TRUE(inbox.wait_for(2));
  std::lock_guard lock(mutex);
  ASSERT_EQ(verdicts.size(), 2u);
  EXPECT_EQ(verdicts[0], std::make_pair(std::string("stranger#1"), false));
  EXPECT_EQ(verdicts[1], std::make_pair(std::string("ui#1"), true));
  EXPECT_EQ(sub.unauthenticated(), 1u);
  const auto seen = drops.get();
  ASSERT_EQ(seen.size(), 1u);
  EXPECT_EQ(seen[0].first, comm::drop_code::unauthenticated);
  EXPECT_NE(seen[0].second.find("stranger#1"), std::string::npos) << seen[0].second;
}
