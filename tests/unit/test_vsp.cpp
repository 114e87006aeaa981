// The VSP: its config, the shell (on-demand and periodic readings, staleness, malformed samples,
// TERMINATE/CONFIGURE), the stock plugins, and the ECP/MP side (VirtualSensor) including a dead
// VSP. Raw samples are published on LCM here as a device driver (or mrroc-axis-emu) would.
#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <mutex>
#include <thread>

#include "mrroc/comm/auth.hpp"
#include "mrroc/comm/bus.hpp"
#include "mrroc/comm/codec.hpp"
#include "mrroc/comm/reporter.hpp"
#include "mrroc/comm/request_reply.hpp"
#include "mrroc/config/process_set.hpp"
#include "mrroc/core/time.hpp"
#include "mrroc/ecp/virtual_sensor.hpp"
#include "shell.hpp"

namespace fs = std::filesystem;
using namespace mrroc;
using namespace std::chrono_literals;

namespace {

std::string test_url() {
  const char* url = std::getenv("MRROC_TEST_LCM_URL");
  return url != nullptr && *url != '\0' ? url : "memq://";
}

/// A process set with the given [[vsp]] tables (and a minimal robot), loaded.
ProcessSetConfig config_with(const std::string& vsps) {
  const fs::path file =
      fs::temp_directory_path() / ("mrroc-vsp-test-" + std::to_string(::getpid()) + ".toml");
  std::ofstream(file) << "[system]\nname = \"t\"\n"
                      << vsps << "\n[mp]\ntask = \"start_and_wait\"\n[[robot]]\nname = \"irb6\"\n"
                      << "model = \"" << MRROC_SOURCE_DIR << "/robots/irb6\"\n"
                      << "[robot.edp]\nplugin = \"mock\"\n[robot.ecp]\ntask = \"follow_mp\"\n";
  ProcessSetConfig c = load_process_set(file);
  fs::remove(file);
  return c;
}

void publish(comm::Bus& bus, const std::string& device, std::vector<double> values,
             bool valid = true) {
  static std::atomic<std::int64_t> no{0};
  vsp::RawSample s;
  s.device = device;
  s.sample_utime = now_utime();
  s.sample_no = no++;
  s.valid = valid;
  s.values = std::move(values);
  s.names.resize(s.values.size());
  s.units.resize(s.values.size());
  mrroc_lcm::raw_sensor_t m = comm::encode(s);
  bus.lcm().publish(channels::raw_sensor(device), &m);
}

/// A running VSP shell on its own thread.
struct RunningVsp {
  RunningVsp(comm::Bus& bus, Reporter& reporter, const VspConfig& config,
             vsp::Shell::WallClock clock = {})
      : shell(bus, reporter, config, vsp::make_sensor(config.plugin), std::move(clock)),
        thread([this] { shell.serve([this] { return !stop; }); }) {}
  ~RunningVsp() {
    stop = true;
    thread.join();
  }
  vsp::Shell shell;
  std::atomic<bool> stop{false};
  std::thread thread;
};

/// Publishes `values` on `device` every 2 ms until destroyed.
struct Publisher {
  Publisher(comm::Bus& bus, std::string device, std::vector<double> values)
      : thread([&bus, this, device = std::move(device), values = std::move(values)] {
          while (!stop) {
            {
              std::lock_guard lock(mutex);
              publish(bus, device, override.empty() ? values : override);
            }
            std::this_thread::sleep_for(2ms);
          }
        }) {}
  ~Publisher() {
    stop = true;
    thread.join();
  }
  void set(std::vector<double> v) {
    std::lock_guard lock(mutex);
    override = std::move(v);
  }
  std::mutex mutex;
  std::vector<double> override;
  std::atomic<bool> stop{false};
  std::thread thread;
};

void refresh(ecp::VirtualSensor& s) {
  s.initiate_reading();
  s.get_reading();
}

}  // namespace

TEST(VspConfig, ReadsVspTablesAndRefusesMistakes) {
  const ProcessSetConfig c = config_with(
      "[[vsp]]\nname = \"wrist\"\nplugin = \"force_torque\"\nsources = [\"gauges\"]\n"
      "mode = \"periodic\"\nperiod_ms = 5\nstale_after_ms = 50\n[vsp.params]\nfilter_hz = 30\n");
  ASSERT_EQ(c.vsps.size(), 1U);
  EXPECT_EQ(c.vsp("wrist").plugin, "force_torque");
  EXPECT_TRUE(c.vsp("wrist").periodic);
  EXPECT_DOUBLE_EQ(c.vsp("wrist").period_s, 0.005);
  EXPECT_DOUBLE_EQ(c.vsp("wrist").stale_after_s, 0.05);
  EXPECT_THROW((void)c.vsp("elbow"), ConfigError);
  try {
    (void)config_with("[[vsp]]\nname = \"w\"\nplugin = \"range\"\n");
    FAIL();
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("missing key 'sources'"), std::string::npos) << e.what();
  }
  try {
    (void)config_with(
        "[[vsp]]\nname = \"w\"\nplugin = \"range\"\nsources = [\"a\"]\nmode = \"fast\"\n");
    FAIL();
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("mode 'fast' must be"), std::string::npos) << e.what();
  }
}

TEST(Vsp, ForceTorqueCalibratesZeroesAndCompensatesTheToolsWeight) {
  comm::Bus bus(test_url());
  Reporter reporter(bus, "vsp/test");
  const ProcessSetConfig c = config_with(
      "[[vsp]]\nname = \"wrist\"\nplugin = \"force_torque\"\nsources = [\"gauges\"]\n"
      "[vsp.params]\ncalibration = [[2,0,0,0,0,0],[0,2,0,0,0,0],[0,0,2,0,0,0],[0,0,0,1,0,0],"
      "[0,0,0,0,1,0],[0,0,0,0,0,1]]\ntool_mass = 1.0\ntool_com = [0.0, 0.0, 0.1]\ngravity = "
      "10.0\n");
  RunningVsp vsp(bus, reporter, c.vsp("wrist"));
  bus.start();
  Publisher gauges(bus, "gauges", {1.0, 0.0, -5.0, 0.0, 0.0, 0.0});
  ecp::VirtualSensor sensor(bus, "wrist", "test");
  std::this_thread::sleep_for(30ms);
  // Sensor frame = world frame: the tool weighs 10 N along -z; the gauges say fz = -10 N after
  // calibration, so the compensated force along z is 0 and fx = 2 N remains.
  refresh(sensor);
  ASSERT_TRUE(sensor.image().valid) << sensor.image().invalid_reason;
  EXPECT_NEAR(sensor.value("fx"), 2.0, 1e-9);
  EXPECT_NEAR(sensor.value("fz"), 0.0, 1e-9);
  // Sensor turned upside down (rotation pi about x): the weight pulls along +z of the sensor.
  sensor.set_context("rotation = [1, 0, 0, 0, -1, 0, 0, 0, -1]");
  refresh(sensor);
  EXPECT_NEAR(sensor.value("fz"), -20.0, 1e-9);
  // Zeroing removes what is measured now.
  sensor.set_context("");
  sensor.configure("zero = true");
  refresh(sensor);
  EXPECT_NEAR(sensor.value("fx"), 0.0, 1e-9);
  gauges.set({1.5, 0.0, -5.0, 0.0, 0.0, 0.0});
  std::this_thread::sleep_for(20ms);
  refresh(sensor);
  EXPECT_NEAR(sensor.value("fx"), 1.0, 1e-9);
  EXPECT_GE(sensor.image().reading_no, 1);
  EXPECT_LT(sensor.image().age_us, 50000);
  // A bad CONFIGURE argument is refused with its name.
  try {
    sensor.configure("zeroo = true");
    FAIL();
  } catch (const ecp::SensorError& e) {
    EXPECT_NE(std::string(e.what()).find("zeroo"), std::string::npos) << e.what();
  }
}

TEST(Vsp, StaleSourceMakesReadingsInvalidAndNamesIt) {
  comm::Bus bus(test_url());
  std::mutex m;
  std::vector<std::string> srp;
  SystemListener listener(
      bus,
      [&](const SrpMessage& msg) {
        std::lock_guard lock(m);
        srp.push_back(msg.text);
      },
      [](const ProcessStatus&) {});
  Reporter reporter(bus, "vsp/range");
  const ProcessSetConfig c = config_with(
      "[[vsp]]\nname = \"range\"\nplugin = \"range\"\nsources = [\"sonar\"]\nstale_after_ms = "
      "40\n");
  RunningVsp vsp(bus, reporter, c.vsp("range"));
  bus.start();
  ecp::VirtualSensor sensor(bus, "range", "test");
  refresh(sensor);
  EXPECT_FALSE(sensor.image().valid);
  EXPECT_NE(sensor.image().invalid_reason.find("no sample from source 'sonar' yet"),
            std::string::npos)
      << sensor.image().invalid_reason;
  {
    Publisher sonar(bus, "sonar", {0.5});
    std::this_thread::sleep_for(20ms);
    refresh(sensor);
    ASSERT_TRUE(sensor.image().valid) << sensor.image().invalid_reason;
    EXPECT_NEAR(sensor.value("distance"), 0.5, 1e-12);
  }
  std::this_thread::sleep_for(80ms);
  refresh(sensor);
  EXPECT_FALSE(sensor.image().valid);
  EXPECT_NE(sensor.image().invalid_reason.find("source 'sonar' stale for"), std::string::npos)
      << sensor.image().invalid_reason;
  EXPECT_THROW((void)sensor.valid_image(), ecp::SensorError);
  std::this_thread::sleep_for(50ms);
  std::lock_guard lock(m);
  bool reported = false;
  for (const auto& t : srp)
    reported = reported ||
               t.find("VSP 'range': reading invalid: source 'sonar' stale") != std::string::npos;
  EXPECT_TRUE(reported);
}

TEST(Vsp, OneRawSensorFeedsTwoVirtualSensors) {
  comm::Bus bus(test_url());
  Reporter reporter(bus, "vsp/test");
  const ProcessSetConfig c = config_with(
      "[[vsp]]\nname = \"near\"\nplugin = \"range\"\nsources = [\"ir\", \"sonar\"]\n"
      "[[vsp]]\nname = \"sonar_only\"\nplugin = \"range\"\nsources = [\"sonar\"]\n"
      "[vsp.params]\nmedian = 3\n");
  RunningVsp a(bus, reporter, c.vsp("near"));
  RunningVsp b(bus, reporter, c.vsp("sonar_only"));
  bus.start();
  Publisher ir(bus, "ir", {0.3});
  Publisher sonar(bus, "sonar", {0.8});
  std::this_thread::sleep_for(30ms);
  ecp::VirtualSensor near(bus, "near", "test");
  ecp::VirtualSensor far(bus, "sonar_only", "test");
  refresh(near);
  refresh(far);
  EXPECT_NEAR(near.value("distance"), 0.3, 1e-12);  // the nearer of the two
  EXPECT_NEAR(far.value("distance"), 0.8, 1e-12);
}

TEST(Vsp, PeriodicTerminateAndConfigure) {
  comm::Bus bus(test_url());
  Reporter reporter(bus, "vsp/test");
  const ProcessSetConfig c = config_with(
      "[[vsp]]\nname = \"belt\"\nplugin = \"conveyor\"\nsources = [\"belt_encoder\"]\n"
      "mode = \"periodic\"\nperiod_ms = 5\n");
  RunningVsp vsp(bus, reporter, c.vsp("belt"));
  bus.start();
  std::atomic<bool> stop{false};
  std::thread belt([&] {  // 0.1 m/s
    const auto start = std::chrono::steady_clock::now();
    while (!stop) {
      const double t =
          std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
      publish(bus, "belt_encoder", {0.1 * t});
      std::this_thread::sleep_for(2ms);
    }
  });
  ecp::VirtualSensor sensor(bus, "belt", "test");
  std::this_thread::sleep_for(300ms);
  sensor.get_reading();  // periodic: no INITIATE_READING needed
  ASSERT_TRUE(sensor.image().valid) << sensor.image().invalid_reason;
  const std::int64_t first = sensor.image().reading_no;
  EXPECT_NEAR(sensor.value("speed"), 0.1, 0.02);
  std::this_thread::sleep_for(50ms);
  sensor.get_reading();
  EXPECT_GE(sensor.image().reading_no, first + 5);
  sensor.terminate();
  sensor.get_reading();
  EXPECT_FALSE(sensor.image().valid);
  EXPECT_NE(sensor.image().invalid_reason.find("terminated"), std::string::npos);
  sensor.configure();
  std::this_thread::sleep_for(30ms);
  sensor.get_reading();
  EXPECT_TRUE(sensor.image().valid) << sensor.image().invalid_reason;
  stop = true;
  belt.join();
}

TEST(Vsp, ObjectPoseSaysWhetherTheObjectIsSeen) {
  comm::Bus bus(test_url());
  Reporter reporter(bus, "vsp/test");
  const ProcessSetConfig c =
      config_with("[[vsp]]\nname = \"camera\"\nplugin = \"object_pose\"\nsources = [\"cam\"]\n");
  RunningVsp vsp(bus, reporter, c.vsp("camera"));
  bus.start();
  ecp::VirtualSensor sensor(bus, "camera", "test");
  publish(bus, "cam", {}, false);
  std::this_thread::sleep_for(20ms);
  refresh(sensor);
  ASSERT_TRUE(sensor.image().valid) << sensor.image().invalid_reason;
  EXPECT_EQ(sensor.value("visible"), 0.0);
  publish(bus, "cam", {1.0, 0.2, 0.9, 1.0, 0.0, 0.0, 0.0});
  std::this_thread::sleep_for(20ms);
  refresh(sensor);
  EXPECT_EQ(sensor.value("visible"), 1.0);
  EXPECT_NEAR(sensor.value("y"), 0.2, 1e-12);
}

TEST(Vsp, DeadVspMakesTheImageInvalidQuickly) {
  comm::Bus bus(test_url());
  Reporter reporter(bus, "vsp/test");
  const ProcessSetConfig c =
      config_with("[[vsp]]\nname = \"range\"\nplugin = \"range\"\nsources = [\"sonar\"]\n");
  bus.start();
  Publisher sonar(bus, "sonar", {1.0});
  ecp::VirtualSensor sensor(bus, "range", "test");
  {
    RunningVsp vsp(bus, reporter, c.vsp("range"));
    std::this_thread::sleep_for(20ms);
    refresh(sensor);
    ASSERT_TRUE(sensor.image().valid) << sensor.image().invalid_reason;
  }
  const auto t0 = std::chrono::steady_clock::now();
  refresh(sensor);
  const double took = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  EXPECT_FALSE(sensor.image().valid);
  EXPECT_NE(sensor.image().invalid_reason.find("VSP 'range' did not answer"), std::string::npos)
      << sensor.image().invalid_reason;
  EXPECT_LT(took, 0.5);  // two calls of 3 attempts of 40 ms
  try {
    (void)sensor.valid_image();
    FAIL();
  } catch (const ecp::SensorError& e) {
    EXPECT_EQ(e.code(), ecp::error_code::sensor_invalid);
    EXPECT_EQ(e.error_class(), ecp::ErrorClass::system);
  }
}

TEST(Vsp, MalformedRawSamplesAreCountedAndDropped) {
  comm::Bus bus(test_url());
  Reporter reporter(bus, "vsp/test");
  const ProcessSetConfig c =
      config_with("[[vsp]]\nname = \"range\"\nplugin = \"range\"\nsources = [\"sonar\"]\n");
  RunningVsp vsp(bus, reporter, c.vsp("range"));
  bus.start();
  const std::string junk = "not an LCM message";
  bus.lcm().publish(channels::raw_sensor("sonar"), junk.data(), static_cast<unsigned>(junk.size()));
  mrroc_lcm::raw_sensor_t bad{};  // decodes as LCM, but a value is not a number
  bad.device = "sonar";
  bad.valid = 1;
  bad.n = 1;
  bad.values = {std::nan("")};
  bad.names = {"d"};
  bad.units = {"m"};
  bus.lcm().publish(channels::raw_sensor("sonar"), &bad);
  // A well-formed sample of three values, which the range plugin (one value per source) refuses
  // by throwing: counted as malformed, the VSP goes on.
  mrroc_lcm::raw_sensor_t three{};
  three.device = "sonar";
  three.valid = 1;
  three.n = 3;
  three.values = {1.0, 2.0, 3.0};
  three.names = {"a", "b", "c"};
  three.units = {"m", "m", "m"};
  bus.lcm().publish(channels::raw_sensor("sonar"), &three);
  std::this_thread::sleep_for(50ms);
  EXPECT_EQ(vsp.shell.malformed(), 3U);
  // Nothing reached the plugin: still no sample.
  ecp::VirtualSensor sensor(bus, "range", "test");
  refresh(sensor);
  EXPECT_NE(sensor.image().invalid_reason.find("no sample from source 'sonar' yet"),
            std::string::npos)
      << sensor.image().invalid_reason;
  // A good sample afterwards is read: the VSP kept running.
  Publisher sonar(bus, "sonar", {1.25});
  std::this_thread::sleep_for(30ms);
  refresh(sensor);
  ASSERT_TRUE(sensor.image().valid) << sensor.image().invalid_reason;
}

namespace {
/// One sample of `device` taken at `sample_utime`, sent as it is (no signature).
void publish_taken_at(comm::Bus& bus, const std::string& device, double value,
                      std::int64_t sample_utime) {
  vsp::RawSample s;
  s.device = device;
  s.sample_utime = sample_utime;
  s.values = {value};
  s.names = {"d"};
  s.units = {"m"};
  mrroc_lcm::raw_sensor_t m = comm::encode(s);
  bus.lcm().publish(channels::raw_sensor(device), &m);
}
}  // namespace

// A source's age and order come from the samples' own time: a sample taken 300 ms ago that
// arrives now is stale, and an older sample after a newer one changes nothing.
TEST(Vsp, SamplesAreAgedAndOrderedByTheirOwnTime) {
  comm::Bus bus(test_url());
  Reporter reporter(bus, "vsp/test");
  const ProcessSetConfig c = config_with(
      "[[vsp]]\nname = \"range\"\nplugin = \"range\"\nsources = [\"sonar\"]\nstale_after_ms = "
      "100\n");
  RunningVsp vsp(bus, reporter, c.vsp("range"));
  bus.start();
  ecp::VirtualSensor sensor(bus, "range", "test");
  const std::int64_t now = now_utime();
  publish_taken_at(bus, "sonar", 0.7, now - 300'000);
  std::this_thread::sleep_for(30ms);
  refresh(sensor);
  EXPECT_FALSE(sensor.image().valid) << "a sample taken 300 ms ago counted as fresh";
  EXPECT_NE(sensor.image().invalid_reason.find("source 'sonar' stale for"), std::string::npos)
      << sensor.image().invalid_reason;
  publish_taken_at(bus, "sonar", 0.5, now_utime());
  const std::int64_t newest = now_utime();
  publish_taken_at(bus, "sonar", 0.9, newest - 50'000);  // reordered or replayed: older
  std::this_thread::sleep_for(30ms);
  refresh(sensor);
  ASSERT_TRUE(sensor.image().valid) << sensor.image().invalid_reason;
  EXPECT_NEAR(sensor.value("distance"), 0.5, 1e-12) << "an older sample replaced a newer one";
  EXPECT_EQ(vsp.shell.out_of_order(), 1U);
  EXPECT_GE(sensor.image().age_us, 30'000);  // from the sample's time, not its arrival
}

// With the set's key, a sample counts only when signed for its channel by a holder of the key.
TEST(Vsp, WithAKeyOnlySignedSamplesCount) {
  comm::Bus bus(test_url());
  bus.enable_auth(std::vector<std::uint8_t>(32, 5));
  Reporter reporter(bus, "vsp/test");
  const ProcessSetConfig c =
      config_with("[[vsp]]\nname = \"range\"\nplugin = \"range\"\nsources = [\"sonar\"]\n");
  RunningVsp vsp(bus, reporter, c.vsp("range"));
  bus.start();
  ecp::VirtualSensor sensor(bus, "range", "test");
  publish_taken_at(bus, "sonar", 0.1, now_utime());  // forged: no tag
  vsp::RawSample s;
  s.device = "sonar";
  s.sample_utime = now_utime();
  s.values = {0.2};
  s.names = {"d"};
  s.units = {"m"};
  comm::publish(bus, channels::raw_sensor("other"), comm::encode(s));  // signed elsewhere
  std::this_thread::sleep_for(30ms);
  refresh(sensor);
  EXPECT_FALSE(sensor.image().valid);
  EXPECT_NE(sensor.image().invalid_reason.find("no sample from source 'sonar' yet"),
            std::string::npos)
      << sensor.image().invalid_reason;
  // The forged one is not counted here: it arrived on 'sonar'; the one signed for 'other' never
  // reached this VSP's channel.
  EXPECT_EQ(vsp.shell.unauthenticated(), 1U);
  mrroc_lcm::raw_sensor_t elsewhere = comm::encode(s);
  comm::sign(*bus.auth(), elsewhere, channels::raw_sensor("other"));
  bus.lcm().publish(channels::raw_sensor("sonar"), &elsewhere);  // moved to 'sonar'
  s.sample_utime = now_utime();
  s.values = {0.3};
  comm::publish(bus, channels::raw_sensor("sonar"), comm::encode(s));  // signed for 'sonar'
  std::this_thread::sleep_for(30ms);
  refresh(sensor);
  ASSERT_TRUE(sensor.image().valid) << sensor.image().invalid_reason;
  EXPECT_NEAR(sensor.value("distance"), 0.3, 1e-12);
  EXPECT_EQ(vsp.shell.unauthenticated(), 2U);
}

// Gauge values that overflow the calibration (finite volts, infinite newtons) are refused as
// malformed: the filter keeps the last good force, and no reading is ever valid with infinity.
TEST(Vsp, ForcesThatOverflowAreRefusedAndTheReadingStaysUsable) {
  comm::Bus bus(test_url());
  Reporter reporter(bus, "vsp/test");
  const ProcessSetConfig c = config_with(
      "[[vsp]]\nname = \"wrist\"\nplugin = \"force_torque\"\nsources = [\"gauges\"]\n"
      "[vsp.params]\nfilter_hz = 30\ncalibration = [[2,0,0,0,0,0],[0,2,0,0,0,0],[0,0,2,0,0,0],"
      "[0,0,0,1,0,0],[0,0,0,0,1,0],[0,0,0,0,0,1]]\n");
  RunningVsp vsp(bus, reporter, c.vsp("wrist"));
  bus.start();
  ecp::VirtualSensor sensor(bus, "wrist", "test");
  publish(bus, "gauges", {1.0, 0.0, 0.0, 0.0, 0.0, 0.0});
  std::this_thread::sleep_for(20ms);
  publish(bus, "gauges", {1.5e308, 0.0, 0.0, 0.0, 0.0, 0.0});  // 3e308 N: infinity
  std::this_thread::sleep_for(20ms);
  refresh(sensor);
  ASSERT_TRUE(sensor.image().valid) << sensor.image().invalid_reason;
  EXPECT_NEAR(sensor.value("fx"), 2.0, 1e-9);
  EXPECT_EQ(vsp.shell.malformed(), 1U);
}

namespace {
/// The SRP's messages, kept for the assertions.
struct SrpTexts {
  explicit SrpTexts(comm::Bus& bus)
      : listener(
            bus,
            [this](const SrpMessage& msg) {
              std::lock_guard lock(mutex);
              texts.push_back(msg.text);
            },
            [](const ProcessStatus&) {}) {}
  /// The first message containing `part`, or "".
  std::string find(const std::string& part) {
    std::lock_guard lock(mutex);
    for (const auto& t : texts)
      if (t.find(part) != std::string::npos) return t;
    return "";
  }
  std::mutex mutex;
  std::vector<std::string> texts;
  SystemListener listener;
};
}  // namespace

// A sample stamped in the future is refused: it would hold back every later genuine sample
// (ordered by sample time) while its negative age kept the frozen value valid. One ahead by less
// than stale_after_ms is taken, but ages by its arrival too: it never stays fresh for longer.
TEST(Vsp, SamplesFromTheFutureNeitherFreezeNorHoldBackTheReading) {
  comm::Bus bus(test_url());
  SrpTexts srp(bus);
  Reporter reporter(bus, "vsp/range");
  const ProcessSetConfig c = config_with(
      "[[vsp]]\nname = \"range\"\nplugin = \"range\"\nsources = [\"sonar\"]\nstale_after_ms = "
      "200\n");
  RunningVsp vsp(bus, reporter, c.vsp("range"));
  bus.start();
  ecp::VirtualSensor sensor(bus, "range", "test");
  // 150 ms ahead (within the tolerance): taken, and stale 200 ms after it came.
  publish_taken_at(bus, "sonar", 0.8, now_utime() + 150'000);
  std::this_thread::sleep_for(20ms);
  refresh(sensor);
  ASSERT_TRUE(sensor.image().valid) << sensor.image().invalid_reason;
  EXPECT_NEAR(sensor.value("distance"), 0.8, 1e-12);
  std::this_thread::sleep_for(250ms);
  refresh(sensor);
  EXPECT_FALSE(sensor.image().valid) << "a sample stamped ahead stayed fresh after it had aged";
  EXPECT_NE(sensor.image().invalid_reason.find("source 'sonar' stale for"), std::string::npos)
      << sensor.image().invalid_reason;
  // 60 s ahead: refused, and the genuine samples after it keep the reading fresh and valid.
  const std::int64_t future = now_utime() + 60'000'000;
  publish_taken_at(bus, "sonar", 0.9, future);
  std::this_thread::sleep_for(20ms);
  EXPECT_EQ(vsp.shell.from_the_future(), 1U);
  Publisher sonar(bus, "sonar", {0.5});
  std::this_thread::sleep_for(30ms);
  refresh(sensor);
  ASSERT_TRUE(sensor.image().valid) << sensor.image().invalid_reason;
  EXPECT_NEAR(sensor.value("distance"), 0.5, 1e-12) << "the future sample froze the reading";
  std::this_thread::sleep_for(300ms);  // beyond stale_after_ms: still fresh, from the genuine ones
  sonar.set({0.6});
  std::this_thread::sleep_for(20ms);
  refresh(sensor);
  ASSERT_TRUE(sensor.image().valid) << sensor.image().invalid_reason;
  EXPECT_NEAR(sensor.value("distance"), 0.6, 1e-12);
  EXPECT_LT(sensor.image().age_us, 200'000);
  EXPECT_EQ(vsp.shell.from_the_future(), 1U);
  EXPECT_EQ(vsp.shell.out_of_order(), 0U);
  std::this_thread::sleep_for(50ms);
  const std::string text = srp.find("ahead of this VSP's clock");
  EXPECT_NE(text.find("raw sample on " + channels::raw_sensor("sonar") + " from '"),
            std::string::npos)
      << text;
  EXPECT_NE(text.find("taken at " + std::to_string(future) + " us"), std::string::npos) << text;
  EXPECT_NE(text.find("tolerance 200 ms): dropped"), std::string::npos) << text;
}

// The clocks of the VSP's host and of its source step back 10 s together (an NTP correction):
// the source's samples are older than its last one. The reading is invalid (its newest sample
// is stamped ahead of the clock), never the frozen last value; once the source has been stale
// for stale_after_ms of this host's time it is re-anchored and the readings are valid again.
TEST(Vsp, ASourceWhoseClockSteppedBackIsReanchoredOnceStale) {
  comm::Bus bus(test_url());
  SrpTexts srp(bus);
  Reporter reporter(bus, "vsp/range");
  const ProcessSetConfig c = config_with(
      "[[vsp]]\nname = \"range\"\nplugin = \"range\"\nsources = [\"sonar\"]\nstale_after_ms = "
      "300\n");
  std::atomic<std::int64_t> offset{0};  // of both clocks [us]
  RunningVsp vsp(bus, reporter, c.vsp("range"), [&] { return now_utime() + offset.load(); });
  bus.start();
  std::atomic<double> value{0.5};
  std::atomic<bool> stop{false};
  std::atomic<bool> quiet{false};  // no sample in flight while both clocks step
  std::thread sonar([&] {
    while (!stop) {
      if (!quiet) publish_taken_at(bus, "sonar", value.load(), now_utime() + offset.load());
      std::this_thread::sleep_for(2ms);
    }
  });
  ecp::VirtualSensor sensor(bus, "range", "test");
  std::this_thread::sleep_for(30ms);
  refresh(sensor);
  ASSERT_TRUE(sensor.image().valid) << sensor.image().invalid_reason;
  EXPECT_NEAR(sensor.value("distance"), 0.5, 1e-12);
  // Both clocks step back together, between two samples: a sample stamped before the step and
  // received after it would rightly count as one from the future (a CI run saw that race).
  quiet = true;
  std::this_thread::sleep_for(20ms);
  value = 0.7;
  offset = -10'000'000;
  quiet = false;
  std::this_thread::sleep_for(30ms);
  refresh(sensor);
  EXPECT_FALSE(sensor.image().valid) << "the last value before the step stayed valid";
  EXPECT_NE(sensor.image().invalid_reason.find("source 'sonar' stale: its newest sample is "
                                               "stamped"),
            std::string::npos)
      << sensor.image().invalid_reason;
  EXPECT_NE(sensor.image().invalid_reason.find("ms ahead of this VSP's clock (tolerance 300 ms"),
            std::string::npos)
      << sensor.image().invalid_reason;
  std::this_thread::sleep_for(500ms);
  refresh(sensor);
  ASSERT_TRUE(sensor.image().valid) << sensor.image().invalid_reason;
  EXPECT_NEAR(sensor.value("distance"), 0.7, 1e-12);
  EXPECT_LT(sensor.image().age_us, 300'000);
  stop = true;
  sonar.join();
  EXPECT_EQ(vsp.shell.reanchored(), 1U);
  EXPECT_GE(vsp.shell.out_of_order(), 1U);
  EXPECT_EQ(vsp.shell.from_the_future(), 0U);
  std::this_thread::sleep_for(50ms);
  const std::string text = srp.find("re-anchored");
  EXPECT_NE(text.find("VSP 'range': the clock of source 'sonar' stepped back: re-anchored to the "
                      "raw sample on " +
                      channels::raw_sensor("sonar")),
            std::string::npos)
      << text;
  EXPECT_NE(text.find("(limit 300 ms)"), std::string::npos) << text;
}
