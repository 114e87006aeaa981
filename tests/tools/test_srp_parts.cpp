// The SRP's parts in-process: history numbering and selection, the JSON-lines log and its
// rotation, the servo timing statistics.
#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <string>

#include "history.hpp"
#include "log_file.hpp"
#include "servo_timing.hpp"

namespace fs = std::filesystem;
using namespace mrroc;
using namespace mrroc::srp;

namespace {

SrpMessage message(Severity severity, const std::string& text, int code = 0) {
  SrpMessage m;
  m.utime = 1'700'000'000'123'456;
  m.process = "ecp/irb6";
  m.robot = "irb6";
  m.severity = severity;
  m.code = code;
  m.text = text;
  return m;
}

}  // namespace

TEST(SrpHistory, NumbersFromOneAndForgetsTheOldest) {
  History h(3);
  EXPECT_EQ(h.last(), 0);
  for (int i = 1; i <= 5; ++i)
    EXPECT_EQ(h.add(message(Severity::info, std::to_string(i)), false).number, i);
  EXPECT_EQ(h.last(), 5);
  EXPECT_EQ(h.size(), 3U);
  const auto all = h.select(clamp_query(0, 500, 0));
  ASSERT_EQ(all.size(), 3U);
  EXPECT_EQ(all.front().number, 3);
  EXPECT_EQ(all.back().number, 5);
  EXPECT_EQ(all.back().message.text, "5");
}

TEST(SrpHistory, SelectsBySeverityAfterAndCountNewestFirstCut) {
  History h(100);
  // 1 info, 2 warning, 3 error, 4 info, 5 fatal, 6 warning
  for (Severity s : {Severity::info, Severity::warning, Severity::error, Severity::info,
                     Severity::fatal, Severity::warning})
    h.add(message(s, to_string(s)), false);
  const auto warnings = h.select(clamp_query(0, 500, 2));
  std::vector<std::int64_t> numbers;
  for (const auto& e : warnings) numbers.push_back(e.number);
  EXPECT_EQ(numbers, (std::vector<std::int64_t>{2, 3, 5, 6}));
  numbers.clear();
  for (const auto& e : h.select(clamp_query(3, 500, 2))) numbers.push_back(e.number);
  EXPECT_EQ(numbers, (std::vector<std::int64_t>{5, 6}));
  numbers.clear();
  for (const auto& e : h.select(clamp_query(0, 2, 1))) numbers.push_back(e.number);
  EXPECT_EQ(numbers, (std::vector<std::int64_t>{5, 6})) << "the newest when more match";
  EXPECT_TRUE(h.select(clamp_query(6, 500, 0)).empty());
}

TEST(SrpHistory, ClampsTheRequestFields) {
  EXPECT_EQ(clamp_query(0, 0, 0).max_count, 1);
  EXPECT_EQ(clamp_query(0, -7, 0).max_count, 1);
  EXPECT_EQ(clamp_query(0, 100000, 0).max_count, kMaxHistoryCount);
  EXPECT_EQ(clamp_query(-5, 10, 0).after, 0);
  EXPECT_EQ(clamp_query(0, 10, 9).min_severity, Severity::fatal);
  EXPECT_EQ(clamp_query(0, 10, -3).min_severity, Severity::debug);
}

TEST(SrpHistory, ReplyStaysBelowTheSizeLimitAndCutsLongTexts) {
  History h(1000);
  for (int i = 0; i < 500; ++i) h.add(message(Severity::info, std::string(1000, 'x')), false);
  h.add(message(Severity::error, std::string(20000, 'y')), false);
  // A multi-byte character across the cut point must not be split.
  h.add(message(Severity::error, std::string(4092, 'z') + "\xc3\xa9\xc3\xa9\xc3\xa9"), false);
  const auto entries = h.select(clamp_query(0, 500, 0));
  std::size_t bytes = 0;
  for (const auto& e : entries) bytes += encoded_size(e);
  EXPECT_LT(bytes, kMaxReplyBytes);
  EXPECT_GT(entries.size(), 40U);
  EXPECT_LT(entries.size(), 60U);
  EXPECT_EQ(entries.back().number, 502) << "the newest are kept";
  EXPECT_LE(entries[entries.size() - 2].message.text.size(), kMaxReplyTextBytes);
  const std::string& cut = entries.back().message.text;
  EXPECT_LE(cut.size(), kMaxReplyTextBytes);
  EXPECT_EQ(cut.substr(cut.size() - 3), "...");
  EXPECT_TRUE(nlohmann::json::accept("\"" + cut + "\"")) << "valid UTF-8";
}

TEST(SrpLog, JsonLineHasEveryField) {
  Entry e{7, false, message(Severity::warning, "joint 2 \"upper\"\nlimit", 6)};
  const auto j = nlohmann::json::parse(json_line(e));
  EXPECT_EQ(j["n"], 7);
  EXPECT_EQ(j["kind"], "message");
  EXPECT_EQ(j["time"], "2023-11-14T22:13:20.123456Z");
  EXPECT_EQ(j["utime"], 1'700'000'000'123'456);
  EXPECT_EQ(j["process"], "ecp/irb6");
  EXPECT_EQ(j["robot"], "irb6");
  EXPECT_EQ(j["severity"], "warning");
  EXPECT_EQ(j["code"], 6);
  EXPECT_EQ(j["text"], "joint 2 \"upper\"\nlimit");
  e.message.text = "bad \xff byte";
  EXPECT_TRUE(nlohmann::json::accept(json_line(e)));
}

TEST(SrpLog, StatusChangesBecomeEntries) {
  ProcessStatus s;
  s.utime = 5;
  s.process = "edp/irb6";
  s.robot = "irb6";
  s.pid = 42;
  s.state = ProcessState::failed;
  s.detail = "plugin 'mujoco' threw";
  const SrpMessage m = status_as_message(s);
  EXPECT_EQ(m.severity, Severity::error);
  EXPECT_EQ(m.text, "status: failed (pid 42): plugin 'mujoco' threw");
}

TEST(SrpLog, RotationKeepsEveryLineWithinTheLimit) {
  const fs::path dir = fs::temp_directory_path() / ("mrroc-srp-parts-" + std::to_string(getpid()));
  fs::remove_all(dir);
  const fs::path path = dir / "srp.jsonl";
  {
    RotatingLog log(path, 1000, 50);
    for (int i = 1; i <= 100; ++i) log.write("line " + std::to_string(i) + std::string(80, '.'));
    EXPECT_GT(log.rotations(), 5);
  }
  // Oldest file first: srp.jsonl.N .. srp.jsonl.1, then srp.jsonl.
  std::vector<fs::path> files;
  for (int i = 50; i >= 1; --i)
    if (fs::exists(path.string() + "." + std::to_string(i)))
      files.emplace_back(path.string() + "." + std::to_string(i));
  files.push_back(path);
  int expected = 1;
  for (const auto& f : files) {
    EXPECT_LE(fs::file_size(f), 1000U) << f;
    std::ifstream in(f);
    std::string line;
    while (std::getline(in, line)) {
      EXPECT_EQ(line.substr(0, line.find('.')), "line " + std::to_string(expected)) << f;
      ++expected;
    }
  }
  EXPECT_EQ(expected, 101);
  // keep = 2: only the two newest old files remain.
  {
    RotatingLog log(dir / "short.jsonl", 1000, 2);
    for (int i = 1; i <= 100; ++i) log.write(std::string(90, 'x'));
  }
  EXPECT_TRUE(fs::exists(dir / "short.jsonl.2"));
  EXPECT_FALSE(fs::exists(dir / "short.jsonl.3"));
  fs::remove_all(dir);
}

TEST(SrpTiming, WindowsAndTotals) {
  ServoTiming t;
  // Every 20 ms a state covering 10 servo steps of 2 ms.
  for (int i = 0; i < 5; ++i)
    t.add("irb6", TimingSample{10 * i, 0.002, 10.0 + i, 50.0 + i, 3 + (i >= 3 ? 2 : 0)});
  const auto w = t.take_window();
  ASSERT_EQ(w.count("irb6"), 1U);
  const TimingSummary& s = w.at("irb6");
  EXPECT_EQ(s.states, 5U);
  EXPECT_DOUBLE_EQ(s.servo_period_s, 0.002);
  EXPECT_DOUBLE_EQ(s.lateness_max_us, 54.0);
  EXPECT_EQ(s.overruns, 2) << "counted from the first state";
  EXPECT_EQ(s.overruns_total, 5);
  EXPECT_EQ(s.servo_steps, 40);
  // Mean weighted by steps: first state 1 step (10), the others 10 steps each (11, 12, 13, 14).
  EXPECT_NEAR(s.lateness_mean_us, (10.0 + 10 * (11 + 12 + 13 + 14)) / 41.0, 1e-9);
  EXPECT_TRUE(t.take_window().empty());
  t.add("irb6", TimingSample{50, 0.002, 20.0, 60.0, 6});
  const auto w2 = t.take_window();
  EXPECT_EQ(w2.at("irb6").overruns, 1) << "from the previous window's last state";
  EXPECT_EQ(t.total().at("irb6").overruns, 3);
  EXPECT_EQ(t.total().at("irb6").states, 6U);
  EXPECT_NE(describe(s).find("period 2.000 ms"), std::string::npos) << describe(s);
}
