// mrroc-srp as a real process, fed by real reporters and robot-state publishers over LCM: the
// numbered history and its filters, the rotated JSON-lines log, colours, servo timing.
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <string>
#include <thread>
#include <vector>

#include "mrroc/comm/bus.hpp"
#include "mrroc/comm/reporter.hpp"
#include "mrroc/comm/request_reply.hpp"
#include "mrroc/config/process_set.hpp"
#include "mrroc/core/time.hpp"
#include "mrroc_lcm/robot_state_t.hpp"
#include "mrroc_lcm/srp_history_reply_t.hpp"
#include "mrroc_lcm/srp_history_request_t.hpp"
#include "srp_process.hpp"

namespace fs = std::filesystem;
using namespace std::chrono_literals;
using mrroc::test::ChildProcess;
using HistoryClient =
    mrroc::comm::Client<mrroc_lcm::srp_history_request_t, mrroc_lcm::srp_history_reply_t>;

namespace {

class Srp : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() /
           ("mrroc-test-srp-" + std::to_string(getpid()) + "-" +
            ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override {
    if (!HasFailure()) fs::remove_all(dir_);
  }

  /// A set with one robot; `srp_keys` go into [srp].
  fs::path config(const std::string& srp_keys) const {
    const fs::path file = dir_ / "set.toml";
    std::ofstream f(file);
    f << "[system]\nname = \"srp-test\"\n[srp]\n"
      << srp_keys << "\n[mp]\ntask = \"start_and_wait\"\n[[robot]]\nname = \"irb6\"\nmodel = \""
      << MRROC_SOURCE_DIR << "/robots/irb6\"\n[robot.edp]\nplugin = \"mock\"\n"
      << "[robot.ecp]\ntask = \"follow_mp\"\n";
    return file;
  }

  static std::unique_ptr<ChildProcess> start_srp(const fs::path& config,
                                                 std::vector<std::string> extra = {}) {
    std::vector<std::string> argv{std::string(MRROC_BIN_DIR) + "/mrroc-srp", "--config",
                                  config.string()};
    argv.insert(argv.end(), extra.begin(), extra.end());
    auto srp = std::make_unique<ChildProcess>(argv);
    EXPECT_TRUE(srp->wait_for("status  ready", 10s)) << srp->output();
    return srp;
  }

  static mrroc_lcm::srp_history_reply_t ask(HistoryClient& client, std::int64_t after,
                                            std::int32_t max_count, std::int8_t min_severity) {
    mrroc_lcm::srp_history_request_t request{};
    request.after = after;
    request.max_count = max_count;
    request.min_severity = min_severity;
    return client.call(request);
  }

  /// Waits until the SRP's history holds a message with `text`.
  static bool wait_for_text(HistoryClient& client, const std::string& text) {
    for (int i = 0; i < 100; ++i) {
      const auto reply = ask(client, 0, 500, 0);
      for (const auto& m : reply.messages)
        if (m.text == text) return true;
      std::this_thread::sleep_for(50ms);
    }
    return false;
  }

  fs::path dir_;
};

/// The severities the test reports, in order: i -> i % 5.
mrroc::Severity severity_of(int i) { return static_cast<mrroc::Severity>(i % 5); }

}  // namespace

TEST_F(Srp, HistoryLogAndTiming) {
  const fs::path log = dir_ / "srp.jsonl";
  const fs::path extra = dir_ / "extra" / "copy.jsonl";
  auto srp =
      start_srp(config(fmt::format("log = \"{}\"\nlog_max_kb = 1\nlog_keep = 100\nhistory = 1000",
                                   log.string())),
                {"--log", extra.string()});
  mrroc::comm::Bus bus("");
  HistoryClient client(bus, mrroc::comm::unique_endpoint_name("test"), "SRP",
                       mrroc::channels::srp_history_command, mrroc::channels::srp_history_reply);
  bus.start();
  constexpr int kMessages = 60;
  {
    mrroc::Reporter reporter(bus, "ecp/irb6", "irb6");
    mrroc::Reporter ui(bus, "ui", "irb6");
    for (int i = 0; i < kMessages; ++i) {
      reporter.report(severity_of(i), i % 5 >= 2 ? 100 + i : 0, fmt::format("message {}", i));
      std::this_thread::sleep_for(2ms);
    }
    ui.warning("from the operator");
  }
  ASSERT_TRUE(wait_for_text(client, "from the operator")) << srp->output();

  // Robot states over more than one 10 s timing window: 2 ms servo period, a state per 10 steps.
  const auto started = std::chrono::steady_clock::now();
  int states = 0;
  while (std::chrono::steady_clock::now() - started < 11s &&
         srp->output().find("timing  irb6:") == std::string::npos) {
    mrroc_lcm::robot_state_t state{};
    state.header.utime = mrroc::now_utime();
    state.header.kind = mrroc_lcm::header_t::BROADCAST;
    state.robot = "irb6";
    state.servo_step = 10 * states;
    state.servo_period_s = 0.002;
    state.n_joints = 2;
    state.q = {0.1, 0.2};
    state.dq = {0.0, 0.0};
    state.q_desired = {0.1, 0.2};
    state.lateness_mean_us = 12.5;
    state.lateness_max_us = 40.0 + (states == 7 ? 500.0 : 0.0);
    state.overruns = states >= 7 ? 1 : 0;
    bus.lcm().publish(mrroc::channels::robot_state("irb6"), &state);
    ++states;
    std::this_thread::sleep_for(20ms);
  }
  EXPECT_TRUE(
      srp->wait_for("timing  irb6: period 2.000 ms, lateness mean 12.5 us, max 540.0 us, "
                    "overruns 1 (total 1)",
                    3s))
      << srp->output();

  // Everything, numbered 1..last without gaps; status changes are entries too.
  const auto all = ask(client, 0, 500, 0);
  ASSERT_GT(all.n, kMessages);
  ASSERT_EQ(all.numbers.size(), static_cast<std::size_t>(all.n));
  EXPECT_EQ(all.numbers.front(), 1);
  EXPECT_EQ(all.numbers.back(), all.last);
  for (std::size_t k = 1; k < all.numbers.size(); ++k)
    EXPECT_EQ(all.numbers[k], all.numbers[k - 1] + 1);
  std::vector<std::string> texts;
  for (const auto& m : all.messages)
    if (m.process == "ecp/irb6" && m.text.rfind("message ", 0) == 0) texts.push_back(m.text);
  ASSERT_EQ(texts.size(), static_cast<std::size_t>(kMessages));
  for (int i = 0; i < kMessages; ++i)
    EXPECT_EQ(texts[static_cast<std::size_t>(i)], fmt::format("message {}", i));
  bool saw_status = false;
  for (const auto& m : all.messages)
    saw_status |= m.text.rfind("status: ready (pid", 0) == 0 && m.process == "srp";
  EXPECT_TRUE(saw_status);

  // Severity filter: exactly the entries of `all` with severity >= warning, same numbers.
  const auto warnings = ask(client, 0, 500, 2);
  std::vector<std::int64_t> expected;
  for (std::size_t k = 0; k < all.messages.size(); ++k)
    if (all.messages[k].severity >= 2) expected.push_back(all.numbers[k]);
  EXPECT_EQ(warnings.numbers, expected);
  for (const auto& m : warnings.messages) EXPECT_GE(m.severity, 2) << m.text;
  // The code and robot survive; "from the operator" carries its robot.
  bool operator_seen = false;
  for (const auto& m : warnings.messages)
    if (m.text == "from the operator") operator_seen = m.process == "ui" && m.robot == "irb6";
  EXPECT_TRUE(operator_seen);

  // `after` and `max_count`: the newest 3 matching entries after the 10th.
  const auto newest = ask(client, 10, 3, 3);
  std::vector<std::int64_t> errors_after_10;
  for (std::size_t k = 0; k < all.messages.size(); ++k)
    if (all.messages[k].severity >= 3 && all.numbers[k] > 10)
      errors_after_10.push_back(all.numbers[k]);
  ASSERT_GE(errors_after_10.size(), 3U);
  EXPECT_EQ(newest.numbers,
            std::vector<std::int64_t>(errors_after_10.end() - 3, errors_after_10.end()));
  // Out-of-range max_count is clamped: 0 -> 1, 100000 -> 500.
  EXPECT_EQ(ask(client, 0, 0, 0).n, 1);
  EXPECT_EQ(ask(client, 0, 100000, 0).n, all.n);
  EXPECT_EQ(ask(client, all.last, 500, 0).n, 0);

  const std::int64_t last_before_stop = ask(client, 0, 1, 0).last;
  EXPECT_EQ(srp->stop(), 0) << srp->output();
  const std::string out = srp->output();
  EXPECT_NE(out.find("srp summary: timing irb6: period 2.000 ms"), std::string::npos) << out;
  EXPECT_NE(out.find(fmt::format("{} states", states)), std::string::npos) << out;
  EXPECT_NE(out.find("ui[irb6]   warning from the operator"), std::string::npos) << out;
  EXPECT_NE(out.find("ecp/irb6   error   [103] message 3"), std::string::npos) << out;
  EXPECT_EQ(out.find('\033'), std::string::npos) << "colour codes on a pipe with --color=auto";

  // The log: rotated into many files, every line JSON, every entry exactly once and in order.
  for (const fs::path& path : {log, extra}) {
    std::vector<fs::path> files;
    for (int i = 100; i >= 1; --i)
      if (fs::exists(path.string() + "." + std::to_string(i)))
        files.emplace_back(path.string() + "." + std::to_string(i));
    files.push_back(path);
    EXPECT_GT(files.size(), 5U) << "rotated at 1 KiB";
    std::int64_t n = 0;
    std::vector<std::string> logged;
    for (const auto& file : files) {
      EXPECT_LE(fs::file_size(file), 1024U) << file;
      std::ifstream in(file);
      std::string line;
      while (std::getline(in, line)) {
        nlohmann::json j;
        ASSERT_NO_THROW(j = nlohmann::json::parse(line)) << file << ": " << line;
        EXPECT_EQ(j.at("n").get<std::int64_t>(), ++n) << file;
        for (const char* key : {"time", "process", "robot", "severity", "text", "kind"})
          EXPECT_TRUE(j.at(key).is_string()) << key;
        EXPECT_TRUE(j.at("utime").is_number_integer());
        EXPECT_TRUE(j.at("code").is_number_integer());
        EXPECT_EQ(j.at("time").get<std::string>().size(), 27U) << j.at("time");
        if (j.at("process") == "ecp/irb6" && j.at("kind") == "message") {
          logged.push_back(j.at("text"));
          const int i = std::stoi(j.at("text").get<std::string>().substr(8));
          EXPECT_EQ(j.at("severity"), mrroc::to_string(severity_of(i)));
          EXPECT_EQ(j.at("code"), i % 5 >= 2 ? 100 + i : 0);
          EXPECT_EQ(j.at("robot"), "irb6");
        }
      }
    }
    EXPECT_GE(n, last_before_stop) << path;
    EXPECT_EQ(logged, texts) << path;
  }
}

TEST_F(Srp, ColoursOnlyWhenAsked) {
  const fs::path cfg = config("history = 100");
  for (const char* mode : {"always", "never"}) {
    auto srp = start_srp(cfg, {std::string("--color=") + mode});
    {
      mrroc::comm::Bus bus("");
      bus.start();
      mrroc::Reporter reporter(bus, "edp/irb6", "irb6");
      reporter.warning("a warning");
      reporter.error(8, "an error");
      reporter.info("the end");
      EXPECT_TRUE(srp->wait_for("the end", 5s)) << srp->output();
    }
    EXPECT_EQ(srp->stop(), 0);
    const std::string out = srp->output();
    if (std::string(mode) == "always") {
      EXPECT_NE(out.find("\033[33m"), std::string::npos) << out;
      EXPECT_NE(out.find("\033[31m"), std::string::npos) << out;
      EXPECT_NE(out.find("warning a warning\033[0m"), std::string::npos) << out;
      EXPECT_NE(out.find("[8] an error\033[0m"), std::string::npos) << out;
    } else {
      EXPECT_EQ(out.find('\033'), std::string::npos) << out;
      EXPECT_NE(out.find("edp/irb6   error   [8] an error"), std::string::npos) << out;
    }
  }
}

TEST_F(Srp, LargeHistoryRepliesStayBelowOneDatagram) {
  auto srp = start_srp(config("history = 1000"));
  mrroc::comm::Bus bus("");
  HistoryClient client(bus, mrroc::comm::unique_endpoint_name("test"), "SRP",
                       mrroc::channels::srp_history_command, mrroc::channels::srp_history_reply);
  bus.start();
  {
    mrroc::Reporter reporter(bus, "mp");
    for (int i = 0; i < 200; ++i) {
      reporter.info(fmt::format("{:04} {}", i, std::string(1000, 'x')));
      std::this_thread::sleep_for(1ms);
    }
    reporter.info("last");
  }
  ASSERT_TRUE(wait_for_text(client, "last")) << srp->output();
  const auto reply = ask(client, 0, 500, 0);
  std::vector<std::uint8_t> buffer(static_cast<std::size_t>(reply.getEncodedSize()));
  reply.encode(buffer.data(), 0, static_cast<int>(buffer.size()));
  EXPECT_LT(buffer.size(), 65507U) << "one UDP datagram";
  EXPECT_GT(reply.n, 40);
  EXPECT_LT(reply.n, 200);
  EXPECT_EQ(reply.numbers.back(), reply.last);
  EXPECT_EQ(reply.messages.back().text, "last") << "the newest are kept";
  EXPECT_EQ(srp->stop(), 0);
}

TEST_F(Srp, BadConfigAndOptionsAreNamed) {
  ChildProcess missing(
      {std::string(MRROC_BIN_DIR) + "/mrroc-srp", "--config", (dir_ / "none.toml").string()});
  EXPECT_EQ(missing.wait(), 2);
  EXPECT_NE(missing.output().find("none.toml"), std::string::npos) << missing.output();
  ChildProcess colour({std::string(MRROC_BIN_DIR) + "/mrroc-srp", "--config", config("").string(),
                       "--color=sometimes"});
  EXPECT_NE(colour.wait(), 0);
  EXPECT_NE(colour.output().find("sometimes"), std::string::npos) << colour.output();
  ChildProcess help({std::string(MRROC_BIN_DIR) + "/mrroc-srp", "--help"});
  EXPECT_EQ(help.wait(), 0);
  for (const char* topic : {"JSON", "log_max_kb", "--color", "history", "lateness"})
    EXPECT_NE(help.output().find(topic), std::string::npos) << topic;
}
