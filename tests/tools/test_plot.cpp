// mrroc-plot on an LCM log written here with real encoded robot_state_t, its errors, and on a log
// lcm-logger records beside the IRb-6 demo.
#include <fmt/format.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <array>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <lcm/lcm-cpp.hpp>
#include <sstream>
#include <string>
#include <vector>

#include "mrroc_lcm/process_status_t.hpp"
#include "mrroc_lcm/robot_state_t.hpp"
#include "srp_process.hpp"

namespace fs = std::filesystem;
using namespace std::chrono_literals;
using mrroc::test::ChildProcess;

namespace {

const std::string kPlot = std::string(MRROC_BIN_DIR) + "/mrroc-plot";

class Plot : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() /
           ("mrroc-test-plot-" + std::to_string(getpid()) + "-" +
            ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override {
    if (!HasFailure()) fs::remove_all(dir_);
  }
  fs::path dir_;
};

template <class Msg>
void write_event(lcm::LogFile& log, const std::string& channel, std::int64_t utime,
                 const Msg& msg) {
  std::vector<std::uint8_t> data(static_cast<std::size_t>(msg.getEncodedSize()));
  ASSERT_EQ(msg.encode(data.data(), 0, static_cast<int>(data.size())),
            static_cast<int>(data.size()));
  lcm::LogEvent event{};
  event.timestamp = utime;
  event.channel = channel;
  event.datalen = static_cast<std::int32_t>(data.size());
  event.data = data.data();
  ASSERT_EQ(log.writeEvent(&event), 0);
}

/// Joint j of state k of a robot with offset `base`.
double q_of(double base, int k, int j) { return base + 0.001 * k - 0.25 * j; }
double dq_of(int k, int j) { return std::sin(0.1 * k) * (j + 1); }

mrroc_lcm::robot_state_t state(const std::string& robot, int k, int n, double base,
                               std::int64_t utime) {
  mrroc_lcm::robot_state_t s{};
  s.header.utime = utime;
  s.header.sender = "edp/" + robot + "#1";
  s.header.kind = mrroc_lcm::header_t::BROADCAST;
  s.robot = robot;
  s.synchronised = true;
  s.servo_step = 10 * k;
  s.servo_period_s = 0.002;
  s.n_joints = n;
  for (int j = 0; j < n; ++j) {
    s.q.push_back(q_of(base, k, j));
    s.dq.push_back(dq_of(k, j));
    s.q_desired.push_back(q_of(base, k, j) + 1e-4);
  }
  s.lateness_mean_us = 10.0 + k % 7;
  s.lateness_max_us = 30.0 + k % 11;
  s.overruns = k / 50;
  return s;
}

/// Width and height from a PNG's IHDR chunk; {0, 0} when the file is not a PNG.
std::array<std::uint32_t, 2> png_size(const fs::path& file) {
  std::ifstream in(file, std::ios::binary);
  std::array<unsigned char, 24> head{};
  in.read(reinterpret_cast<char*>(head.data()), head.size());
  const std::array<unsigned char, 8> signature{0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};
  if (in.gcount() != 24 || !std::equal(signature.begin(), signature.end(), head.begin()) ||
      std::string(head.begin() + 12, head.begin() + 16) != "IHDR")
    return {0, 0};
  const auto be32 = [&](std::size_t at) {
    return (std::uint32_t{head[at]} << 24) | (std::uint32_t{head[at + 1]} << 16) |
           (std::uint32_t{head[at + 2]} << 8) | std::uint32_t{head[at + 3]};
  };
  return {be32(16), be32(20)};
}

/// The data rows of a .dat file.
std::vector<std::vector<double>> read_data(const fs::path& file) {
  std::ifstream in(file);
  std::vector<std::vector<double>> rows;
  std::string line;
  while (std::getline(in, line)) {
    if (line.empty() || line[0] == '#') continue;
    std::istringstream fields(line);
    std::vector<double> row;
    double v = 0;
    while (fields >> v) row.push_back(v);
    rows.push_back(row);
  }
  return rows;
}

}  // namespace

TEST_F(Plot, PlotsEveryRobotAndWritesItsData) {
  const fs::path log_file = dir_ / "run.lcmlog";
  constexpr int kStates = 120;
  const std::int64_t t0 = 1'700'000'000'000'000;
  {
    lcm::LogFile log(log_file.string(), "w");
    ASSERT_TRUE(log.good());
    mrroc_lcm::process_status_t status{};
    status.process = "mp";
    status.state = 2;
    write_event(log, "mrroc/status", t0 - 1000, status);
    for (int k = 0; k < kStates; ++k) {
      const std::int64_t t = t0 + 20'000 * k;
      write_event(log, "irb6/edp/state", t + 50, state("irb6", k, 5, 0.5, t));
      if (k % 2 == 0)
        write_event(log, "conveyor/edp/state", t + 60, state("conveyor", k / 2, 1, -1.0, t + 10));
    }
    // Bytes that do not decode as robot_state_t on a state channel are skipped.
    std::vector<std::uint8_t> junk(40, 0xAB);
    lcm::LogEvent event{};
    event.timestamp = t0 + 20'000 * kStates;
    event.channel = "irb6/edp/state";
    event.datalen = static_cast<std::int32_t>(junk.size());
    event.data = junk.data();
    ASSERT_EQ(log.writeEvent(&event), 0);
  }
  const fs::path out = dir_ / "plots";
  ChildProcess plot(
      {kPlot, log_file.string(), "-o", out.string(), "--width", "800", "--height", "400"});
  ASSERT_EQ(plot.wait(), 0) << plot.output();
  const std::string text = plot.output();
  EXPECT_NE(text.find("1 robot states did not decode"), std::string::npos) << text;
  EXPECT_NE(text.find("robot irb6: 120 states, 5 joints, 2.380 s"), std::string::npos) << text;
  EXPECT_NE(text.find("robot conveyor: 60 states, 1 joints"), std::string::npos) << text;
  for (const char* robot : {"irb6", "conveyor"}) {
    for (const char* kind : {"joints", "velocities", "lateness"}) {
      const fs::path png = out / fmt::format("{}-{}.png", robot, kind);
      EXPECT_NE(text.find("wrote " + png.string()), std::string::npos) << text;
      ASSERT_TRUE(fs::exists(png)) << png;
      EXPECT_EQ(png_size(png), (std::array<std::uint32_t, 2>{800, 400})) << png;
      EXPECT_GT(fs::file_size(png), 2000U) << png << ": too small to hold a plot";
    }
    EXPECT_NE(text.find("wrote " + (out / fmt::format("{}.dat", robot)).string()),
              std::string::npos);
  }
  // irb6.dat: t, step, q1..5, dq1..5, qd1..5, lateness mean, max, overruns.
  const auto rows = read_data(out / "irb6.dat");
  ASSERT_EQ(rows.size(), static_cast<std::size_t>(kStates));
  for (int k = 0; k < kStates; ++k) {
    const auto& row = rows[static_cast<std::size_t>(k)];
    ASSERT_EQ(row.size(), 2U + 15U + 3U) << "row " << k;
    EXPECT_NEAR(row[0], 0.02 * k, 1e-6) << "time of state " << k;
    EXPECT_EQ(row[1], 10 * k);
    for (int j = 0; j < 5; ++j) {
      EXPECT_NEAR(row[2 + static_cast<std::size_t>(j)], q_of(0.5, k, j), 1e-8);
      EXPECT_NEAR(row[7 + static_cast<std::size_t>(j)], dq_of(k, j), 1e-8);
      EXPECT_NEAR(row[12 + static_cast<std::size_t>(j)], q_of(0.5, k, j) + 1e-4, 1e-8);
    }
    EXPECT_NEAR(row[17], 10.0 + k % 7, 1e-3);
    EXPECT_NEAR(row[18], 30.0 + k % 11, 1e-3);
    EXPECT_EQ(row[19], k / 50);
  }
  const auto conveyor = read_data(out / "conveyor.dat");
  ASSERT_EQ(conveyor.size(), 60U);
  EXPECT_NEAR(conveyor[59][0], 0.04 * 59 + 10e-6, 1e-6) << "time from the first state of the log";
  EXPECT_NEAR(conveyor[59][2], q_of(-1.0, 59, 0), 1e-8);
}

TEST_F(Plot, ClearErrors) {
  ChildProcess missing({kPlot, (dir_ / "none.lcmlog").string()});
  EXPECT_EQ(missing.wait(), 2);
  EXPECT_NE(missing.output().find("none.lcmlog' does not exist"), std::string::npos)
      << missing.output();

  const fs::path text = dir_ / "notes.txt";
  std::ofstream(text) << "this is not a log\n";
  ChildProcess not_log({kPlot, text.string()});
  EXPECT_EQ(not_log.wait(), 2);
  EXPECT_NE(not_log.output().find("is not an LCM log file"), std::string::npos) << not_log.output();

  const fs::path empty = dir_ / "empty.lcmlog";
  std::ofstream(empty).close();
  ChildProcess empty_log({kPlot, empty.string()});
  EXPECT_EQ(empty_log.wait(), 2);
  EXPECT_NE(empty_log.output().find("is empty"), std::string::npos) << empty_log.output();

  const fs::path no_states = dir_ / "status-only.lcmlog";
  {
    lcm::LogFile log(no_states.string(), "w");
    mrroc_lcm::process_status_t status{};
    status.process = "mp";
    for (int i = 0; i < 3; ++i) write_event(log, "mrroc/status", 1000 + i, status);
  }
  ChildProcess none({kPlot, no_states.string()});
  EXPECT_EQ(none.wait(), 2);
  EXPECT_NE(none.output().find("holds no robot state: 3 events"), std::string::npos)
      << none.output();

  ChildProcess help({kPlot, "--help"});
  EXPECT_EQ(help.wait(), 0);
  EXPECT_NE(help.output().find("lcm-logger"), std::string::npos);
  EXPECT_NE(help.output().find("-lateness.png"), std::string::npos);
  ChildProcess bad_size({kPlot, no_states.string(), "--width", "5"});
  EXPECT_NE(bad_size.wait(), 0);
  EXPECT_NE(bad_size.output().find("5"), std::string::npos) << bad_size.output();
}

// The IRb-6 demo recorded by lcm-logger: its last robot state is the demo's final pose.
TEST_F(Plot, RecordedDemoEndsAtTheFinalPose) {
  const fs::path log_file = dir_ / "demo.lcmlog";
  ChildProcess logger({"lcm-logger", "--lcm-url=udpm://239.255.76.67:7667?ttl=0", "-f",
                       "--flush-interval=50", log_file.string()});
  std::this_thread::sleep_for(500ms);  // subscribed before the set starts
  ChildProcess launch({std::string(MRROC_BIN_DIR) + "/mrroc-launch",
                       std::string(MRROC_SOURCE_DIR) + "/configs/demo-irb6.toml"});
  ASSERT_EQ(launch.wait(), 0) << launch.output();
  std::this_thread::sleep_for(300ms);
  EXPECT_EQ(logger.stop(SIGINT), 0) << logger.output();
  ASSERT_TRUE(fs::exists(log_file));

  const fs::path out = dir_ / "plots";
  ChildProcess plot({kPlot, log_file.string(), "-o", out.string()});
  ASSERT_EQ(plot.wait(), 0) << plot.output();
  for (const char* kind : {"joints", "velocities", "lateness"})
    EXPECT_EQ(png_size(out / fmt::format("irb6-{}.png", kind)),
              (std::array<std::uint32_t, 2>{1200, 600}));
  const auto rows = read_data(out / "irb6.dat");
  ASSERT_GT(rows.size(), 100U) << "a state every 20 ms for several seconds\n" << plot.output();
  const std::array<double, 5> final_pose{0.0, -1.5708, 0.0, 0.0, 0.0};
  const auto& last = rows.back();
  ASSERT_EQ(last.size(), 2U + 15U + 3U);
  for (std::size_t j = 0; j < 5; ++j)
    EXPECT_NEAR(last[2 + j], final_pose[j], 0.01) << "joint " << j + 1;
  // The robot moved: the first pose of the demo is far from the last.
  double travelled = 0;
  for (const auto& row : rows) travelled = std::max(travelled, std::abs(row[2] - final_pose[0]));
  EXPECT_GT(travelled, 0.4) << "joint 1 went to 0.6 and -0.5 rad on its way";
}
