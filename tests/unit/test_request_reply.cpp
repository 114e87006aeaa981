// Request/reply over LCM (in-process memq:// transport): sequence numbers, resend on timeout,
// duplicate suppression, IN_PROGRESS for long requests, clear timeout errors.
#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <cstdlib>
#include <map>
#include <memory>
#include <string>
#include <thread>

#include "mrroc/comm/faults.hpp"
#include "mrroc/comm/request_reply.hpp"
#include "mrroc_build_options.hpp"
#include "mrroc_lcm/ecp_mp_reply_t.hpp"
#include "mrroc_lcm/mp_ecp_command_t.hpp"

using namespace mrroc;
using namespace std::chrono_literals;
using Req = mrroc_lcm::mp_ecp_command_t;
using Rep = mrroc_lcm::ecp_mp_reply_t;

namespace {

/// In-process transport by default; MRROC_TEST_LCM_URL selects another one (the ThreadSanitizer
/// stage uses UDP multicast, because LCM's in-process queue hands buffers over through GLib locks
/// that ThreadSanitizer cannot see).
std::string test_url() {
  const char* url = std::getenv("MRROC_TEST_LCM_URL");
  return url != nullptr && *url != '\0' ? url : "memq://";
}

// Echo server: replies with error_code = the request's motion_steps; counts executions.
struct EchoServer {
  std::atomic<int> executions{0};
  std::map<int, int> per_value;  // value -> times executed (bus thread only)
  std::unique_ptr<comm::Server<Req, Rep>> server;
  EchoServer(comm::Bus& bus, comm::ServerOptions options = {}) {
    server = std::make_unique<comm::Server<Req, Rep>>(
        bus, "server", "t/cmd", "t/reply",
        [this](const Req& r, comm::Server<Req, Rep>::Responder responder) {
          ++executions;
          ++per_value[r.motion_steps];
          Rep rep{};
          rep.reply = Rep::ACKNOWLEDGE;
          rep.error_code = r.motion_steps;
          responder.reply(rep);
        },
        options);
  }
};

Req request(int value) {
  Req r{};
  r.command = Req::START_TASK;
  r.motion_steps = value;
  return r;
}

}  // namespace

TEST(RequestReply, EchoesWithMatchingSequence) {
  comm::Bus bus(test_url());
  EchoServer echo(bus);
  comm::Client<Req, Rep> client(bus, "client", "echo server", "t/cmd", "t/reply");
  bus.start();
  std::int64_t last_seq = 0;
  for (int i = 1; i <= 50; ++i) {
    const Rep rep = client.call(request(i));
    EXPECT_EQ(rep.error_code, i);
    EXPECT_GT(rep.header.seq, last_seq) << "sequences grow";
    last_seq = rep.header.seq;
    EXPECT_EQ(rep.header.recipient, "client");
    EXPECT_EQ(rep.header.kind, std::int8_t{mrroc_lcm::header_t::REPLY});
  }
  EXPECT_EQ(echo.executions, 50);
  EXPECT_EQ(client.stats().resends, 0U);
}

TEST(RequestReply, AClientMadeAgainUnderTheSameNameIsAnswered) {
  // A task's second run in the same process makes its clients again under the same endpoint
  // name; the server, which remembers the first client's last sequence, must answer them.
  comm::Bus bus(test_url());
  EchoServer echo(bus);
  bus.start();
  for (int run = 1; run <= 3; ++run) {
    comm::ClientOptions options;
    options.attempt_timeout = 100ms;
    options.max_attempts = 3;
    comm::Client<Req, Rep> client(bus, "ecp/irb6#42", "echo server", "t/cmd", "t/reply", options);
    for (int i = 1; i <= 3; ++i)
      EXPECT_EQ(client.call(request(run * 10 + i)).error_code, run * 10 + i) << "run " << run;
  }
  EXPECT_EQ(echo.executions, 9);
  EXPECT_EQ(echo.server->stats().stale, 0U);
}

TEST(RequestReply, SurvivesDropAndDuplicateWithoutExecutingTwice) {
  comm::Bus bus(test_url());
  comm::ServerOptions server_options;
  server_options.faults = comm::LinkFaults{0.3, 0.3, 7};
  EchoServer echo(bus, server_options);
  comm::ClientOptions client_options;
  client_options.attempt_timeout = 5ms;
  client_options.max_attempts = 50;
  client_options.faults = comm::LinkFaults{0.3, 0.3, 11};
  comm::Client<Req, Rep> client(bus, "client", "echo server", "t/cmd", "t/reply", client_options);
  bus.start();
  constexpr int kCalls = 300;
  for (int i = 1; i <= kCalls; ++i) ASSERT_EQ(client.call(request(i)).error_code, i);
  std::this_thread::sleep_for(20ms);
  bus.stop();
  // Every request executed exactly once although requests and replies were lost and repeated.
  EXPECT_EQ(echo.executions, kCalls);
  for (const auto& [value, times] : echo.per_value) EXPECT_EQ(times, 1) << "request " << value;
  const comm::LinkStats cs = client.stats();
  const comm::LinkStats ss = echo.server->stats();
  EXPECT_GT(cs.resends, 0U) << "faults were injected, resends must have happened";
  EXPECT_GT(ss.duplicates, 0U) << "repeated requests must have been answered from the cache";
  std::printf("resends %llu, duplicates answered from cache %llu, stale %llu\n",
              static_cast<unsigned long long>(cs.resends),
              static_cast<unsigned long long>(ss.duplicates),
              static_cast<unsigned long long>(ss.stale + cs.stale));
}

TEST(RequestReply, LongRequestStaysAliveThroughInProgressReplies) {
  comm::Bus bus(test_url());
  // Queue-mode server: the reply comes 400 ms later from another thread.
  comm::Server<Req, Rep> server(bus, "server", "t/cmd", "t/reply");
  comm::ClientOptions options;
  options.attempt_timeout = 50ms;
  options.max_attempts = 3;  // 150 ms of silence would be a timeout
  comm::Client<Req, Rep> client(bus, "client", "slow server", "t/cmd", "t/reply", options);
  bus.start();
  std::atomic<int> executions{0};
  std::thread worker([&] {
    auto in = server.wait_request(2000ms);
    ASSERT_TRUE(in);
    ++executions;
    std::this_thread::sleep_for(400ms);
    Rep rep{};
    rep.reply = Rep::TASK_TERMINATED;
    in->responder.reply(rep);
    EXPECT_FALSE(server.wait_request(100ms)) << "a re-sent request must not be queued again";
  });
  const Rep rep = client.call(request(1));
  worker.join();
  EXPECT_EQ(rep.reply, std::int8_t{Rep::TASK_TERMINATED});
  EXPECT_EQ(executions, 1);
  EXPECT_GT(server.stats().in_progress, 0U);
}

TEST(RequestReply, TimeoutNamesPeerChannelAndAttempts) {
  comm::Bus bus(test_url());
  comm::ClientOptions options;
  options.attempt_timeout = 20ms;
  options.max_attempts = 3;
  comm::Client<Req, Rep> client(bus, "client", "EDP nowhere", "nobody/cmd", "nobody/reply",
                                options);
  bus.start();
  testing::internal::CaptureStderr();
  try {
    client.call(request(1));
    FAIL() << "expected a TimeoutError";
  } catch (const TimeoutError& e) {
    const std::string text = e.what();
    EXPECT_NE(text.find("EDP nowhere"), std::string::npos) << text;
    EXPECT_NE(text.find("nobody/cmd"), std::string::npos) << text;
    EXPECT_NE(text.find("3 attempts of 20 ms"), std::string::npos) << text;
  }
  EXPECT_EQ(client.stats().resends, 2U);
  // The first re-send is said on standard error (one line a second at most: the second, 20 ms
  // later, is not).
  const std::string said = testing::internal::GetCapturedStderr();
  EXPECT_NE(said.find("client: no reply from EDP nowhere on channel 'nobody/cmd' to request "),
            std::string::npos)
      << said;
  EXPECT_NE(said.find("within 20 ms: sent again (attempt 2; 1 re-sends since the last such note)"),
            std::string::npos)
      << said;
  EXPECT_EQ(said.find("attempt 3"), std::string::npos) << said;
}

TEST(RequestReply, AnAbandonedCallEndsAtOnceAndTheNextCallIsAnswered) {
  comm::Bus bus(test_url());
  // Queue-mode server that does not answer the first request (a silent EDP).
  comm::Server<Req, Rep> server(bus, "server", "t/cmd", "t/reply");
  comm::ClientOptions options;
  options.attempt_timeout = 250ms;
  options.max_attempts = 12;  // 3 s of silence before a TimeoutError
  comm::Client<Req, Rep> client(bus, "client", "EDP silent", "t/cmd", "t/reply", options);
  bus.start();
  client.abandon();  // no call in progress: nothing to abandon, the next call is not affected
  std::thread stopper([&] {
    ASSERT_TRUE(server.wait_request(2000ms));
    std::this_thread::sleep_for(100ms);
    client.abandon();
  });
  const auto started = std::chrono::steady_clock::now();
  try {
    client.call(request(1));
    FAIL() << "expected CallAbandoned";
  } catch (const CallAbandoned& e) {
    const std::string text = e.what();
    EXPECT_NE(text.find("EDP silent"), std::string::npos) << text;
    EXPECT_NE(text.find("abandoned after"), std::string::npos) << text;
  }
  const auto waited = std::chrono::steady_clock::now() - started;
  stopper.join();
  // Ended by abandon() (100 ms after the request arrived), not by the 3 s of attempts.
  EXPECT_LT(waited, 2000ms);
  // The next call is a new request, answered as usual.
  std::thread answerer([&] {
    for (;;) {
      auto in = server.wait_request(2000ms);
      ASSERT_TRUE(in);
      if (in->request.motion_steps != 2) continue;
      Rep rep{};
      rep.reply = Rep::ACKNOWLEDGE;
      rep.error_code = 2;
      in->responder.reply(rep);
      return;
    }
  });
  const Rep rep = client.call(request(2));
  answerer.join();
  EXPECT_EQ(rep.error_code, 2);
}

TEST(RequestReply, RepliesGoOnlyToTheirClient) {
  comm::Bus bus(test_url());
  EchoServer echo(bus);
  comm::Client<Req, Rep> a(bus, "a", "echo", "t/cmd", "t/reply");
  comm::Client<Req, Rep> b(bus, "b", "echo", "t/cmd", "t/reply");
  bus.start();
  std::thread ta([&] {
    for (int i = 0; i < 100; ++i) EXPECT_EQ(a.call(request(1000 + i)).error_code, 1000 + i);
  });
  std::thread tb([&] {
    for (int i = 0; i < 100; ++i) EXPECT_EQ(b.call(request(2000 + i)).error_code, 2000 + i);
  });
  ta.join();
  tb.join();
  EXPECT_EQ(echo.executions, 200);
}

TEST(RequestReply, CallFromBusThreadIsRefused) {
  comm::Bus bus(test_url());
  comm::Client<Req, Rep> client(bus, "client", "x", "t/cmd", "t/reply");
  std::atomic<bool> refused{false};
  comm::Server<Req, Rep> server(bus, "s", "t/other", "t/other_reply",
                                [&](const Req&, comm::Server<Req, Rep>::Responder) {
                                  try {
                                    client.call(request(1));
                                  } catch (const Error&) {
                                    refused = true;
                                  }
                                });
  comm::Client<Req, Rep> trigger(bus, "trigger", "s", "t/other", "t/other_reply",
                                 comm::ClientOptions{10ms, 1, {}});
  bus.start();
  EXPECT_THROW(trigger.call(request(1)), TimeoutError);
  EXPECT_TRUE(refused);
}

TEST(Bus, BadUrlIsNamed) {
  try {
    comm::Bus bus("nonsense://what");
    FAIL();
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("nonsense://what"), std::string::npos);
  }
}

// LCM calls a handler with its own lock released: Bus::unsubscribe from another thread waits for
// a call in progress, and no call begins after it returned.
TEST(Bus, UnsubscribeWaitsForAHandlerInProgress) {
  comm::Bus bus(test_url());
  std::atomic<bool> entered{false};
  std::atomic<bool> left{false};
  std::atomic<bool> ended{false};
  std::atomic<int> calls_after_end{0};
  comm::Subscription* sub =
      bus.subscribe_function("t/slow", [&](const lcm::ReceiveBuffer*, const std::string&) {
        if (ended) ++calls_after_end;
        entered = true;
        std::this_thread::sleep_for(200ms);
        left = true;
      });
  bus.start();
  const std::uint8_t byte = 1;
  bus.lcm().publish("t/slow", &byte, 1);
  const auto deadline = std::chrono::steady_clock::now() + 5s;
  while (!entered && std::chrono::steady_clock::now() < deadline) std::this_thread::sleep_for(1ms);
  ASSERT_TRUE(entered) << "the handler was not called within 5 s";
  bus.unsubscribe(sub);
  ended = true;
  EXPECT_TRUE(left) << "unsubscribe returned while the handler was still running";
  for (int i = 0; i < 5; ++i) bus.lcm().publish("t/slow", &byte, 1);
  std::this_thread::sleep_for(100ms);
  bus.stop();
  EXPECT_EQ(calls_after_end, 0);
}

// Subscriptions ended while their channel is busy, from another thread and from their own
// handler, are called no more and leave nothing behind (the sanitizer stages see a handler that
// outlives its state and an LCM subscription never freed).
TEST(Bus, SubscriptionsEndedDuringTrafficAreCalledNoMore) {
  comm::Bus bus(test_url());
  std::atomic<bool> publishing{true};
  std::atomic<long> delivered{0};
  comm::Subscription* steady = bus.subscribe_function(
      "t/churn", [&](const lcm::ReceiveBuffer*, const std::string&) { ++delivered; });
  bus.start();
  std::thread publisher([&] {
    const std::uint8_t byte = 2;
    while (publishing) {
      bus.lcm().publish("t/churn", &byte, 1);
      std::this_thread::sleep_for(50us);
    }
  });
  constexpr int kRounds = 200;
  std::atomic<int> calls_after_end{0};
  for (int i = 0; i < kRounds; ++i) {
    auto state = std::make_unique<std::atomic<int>>(0);  // freed right after unsubscribe
    auto* calls = state.get();
    auto ended = std::make_shared<std::atomic<bool>>(false);
    comm::Subscription* sub = bus.subscribe_function(
        "t/churn", [calls, ended, &calls_after_end](const lcm::ReceiveBuffer*, const std::string&) {
          if (*ended) ++calls_after_end;
          ++*calls;
        });
    // One that ends itself from its handler, on the bus thread.
    auto self = std::make_shared<std::atomic<comm::Subscription*>>(nullptr);
    self->store(bus.subscribe_function(
        "t/churn", [&bus, self](const lcm::ReceiveBuffer*, const std::string&) {
          bus.unsubscribe(self->exchange(nullptr));  // null (not yet stored, or ended): nothing
        }));
    std::this_thread::sleep_for(std::chrono::microseconds(100 * (i % 7)));
    bus.unsubscribe(sub);
    *ended = true;
    state.reset();
  }
  std::this_thread::sleep_for(50ms);
  const long before = delivered;
  std::this_thread::sleep_for(50ms);
  EXPECT_GT(delivered, before) << "the subscription that stayed stopped receiving";
  publishing = false;
  publisher.join();
  bus.unsubscribe(steady);
  bus.stop();
  EXPECT_EQ(calls_after_end, 0);
}

// A request that took longer than the server's max_request_age to arrive is dropped, not
// executed (its client gave up or re-sent it); a fresh one with the next sequence is executed.
TEST(RequestReply, RequestsOlderThanTheDeadlineAreDroppedNotExecuted) {
  comm::Bus bus(test_url());
  comm::ServerOptions options;
  options.max_request_age = 200ms;
  EchoServer echo(bus, options);
  std::atomic<int> replies{0};
  auto on_reply = +[](const lcm::ReceiveBuffer*, const std::string&, std::atomic<int>* n) { ++*n; };
  mrroc::comm::Subscription* sub = bus.subscribe<std::atomic<int>*>("t/reply", on_reply, &replies);
  bus.start();
  Req old = request(7);
  old.header.sender = "late-client";
  old.header.seq = 1;
  old.header.kind = mrroc_lcm::header_t::REQUEST;
  old.header.utime = now_utime() - 1'000'000;  // sent 1 s ago
  bus.lcm().publish("t/cmd", &old);
  std::this_thread::sleep_for(100ms);
  EXPECT_EQ(echo.executions, 0);
  EXPECT_EQ(replies, 0);
  EXPECT_EQ(echo.server->stats().expired, 1U);
  Req fresh = old;
  fresh.header.seq = 2;
  fresh.header.utime = now_utime();
  bus.lcm().publish("t/cmd", &fresh);
  for (int i = 0; i < 100 && replies == 0; ++i) std::this_thread::sleep_for(10ms);
  EXPECT_EQ(echo.executions, 1);
  EXPECT_EQ(replies, 1);
  bus.unsubscribe(sub);
}

TEST(LinkFaults, TheEnvironmentVariableCountsOnlyInBuildsWithFaultInjection) {
  ASSERT_EQ(setenv("MRROC_LINK_FAULTS", "drop=0.25,duplicate=0.125,seed=3", 1), 0);
  const comm::LinkFaults faults = comm::link_faults_from_environment();
  if (kLinkFaultInjection) {
    EXPECT_DOUBLE_EQ(faults.drop, 0.25);
    EXPECT_DOUBLE_EQ(faults.duplicate, 0.125);
    EXPECT_EQ(faults.seed, 3U);
    ASSERT_EQ(setenv("MRROC_LINK_FAULTS", "drop=2", 1), 0);
    try {
      (void)comm::link_faults_from_environment();
      ADD_FAILURE() << "a probability of 2 was accepted";
    } catch (const Error& e) {
      EXPECT_EQ(std::string(e.what()),
                "MRROC_LINK_FAULTS: drop = 2 is outside 0..1 (a probability)");
    }
  } else {
    EXPECT_FALSE(faults.active()) << "a build without fault injection honoured MRROC_LINK_FAULTS";
  }
  ASSERT_EQ(unsetenv("MRROC_LINK_FAULTS"), 0);
}
