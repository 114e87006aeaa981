// The EDP's `can` plugin against the real cell emulator (mrroc-axis-emu, lock-step, scene
// configs/scenes/irb6.toml): bring-up of five emulated drives, cyclic positions out and back,
// quick stop on emergency stop, binary I/O on the drives' digital lines, and a drive fault seen as
// a plugin fault. By default over a virtual bus; with MRROC_CAN_IFACE=vcan0 (the qemu test
// tests/hil) over SocketCAN on a real kernel.
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <functional>
#include <mutex>
#include <optional>
#include <regex>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "edp_parts.hpp"
#include "emu_process.hpp"
#include "mrroc/config/check.hpp"
#include "mrroc/config/params.hpp"
#include "mrroc/edp/hardware.hpp"
#include "plugins/can_hardware.hpp"
#include "servo_loop.hpp"

using namespace mrroc;
using namespace std::chrono_literals;

namespace {

std::string bus_url() {
  const char* iface = std::getenv("MRROC_CAN_IFACE");
  if (iface != nullptr && *iface != '\0') return std::string("socketcan:") + iface;
  return "virtual:plugin-test-" + std::to_string(::getpid());
}

/// mrroc-axis-emu on configs/scenes/irb6.toml with the robot on `url`.
class Emulator : public test::EmuProcess {
 public:
  explicit Emulator(const std::string& url, const std::vector<std::string>& extra = {},
                    bool lock_step = true)
      : EmuProcess(arguments(url, extra), lock_step) {}

 private:
  static std::vector<std::string> arguments(const std::string& url,
                                            const std::vector<std::string>& extra) {
    const std::string scene =
        (std::filesystem::path(MRROC_SOURCE_DIR) / "configs/scenes/irb6.toml").string();
    std::vector<std::string> args = {"--scene", scene, "--bus", "irb6=" + url};
    args.insert(args.end(), extra.begin(), extra.end());
    return args;
  }
};

/// The setup of the `can` plugin for configs/scenes/irb6.toml's drives on `url`; `adjust` adds
/// parameters.
edp::HardwareSetup plugin_setup(const std::string& url,
                                const std::function<void(Params&)>& adjust = {}) {
  edp::HardwareSetup setup;
  setup.robot = "irb6";
  setup.model_dir = std::string(MRROC_SOURCE_DIR) + "/robots/irb6";
  setup.servo_period_s = 0.002;
  Params p;
  p.set("bus", url, {});
  p.set("silent_cycles", std::int64_t{200}, {});  // the VM's software emulation is slow
  // The drives of configs/scenes/irb6.toml, each with its EDS.
  const std::string drives = std::string(MRROC_SOURCE_DIR) + "/configs/drives/";
  p.set("eds",
        std::vector<std::string>{drives + "emu-csp.eds", drives + "emu-pp-split.eds",
                                 drives + "emu-ip.eds", drives + "emu-ip.eds",
                                 drives + "emu-pp-split.eds"},
        {});
  if (adjust) adjust(p);
  setup.params = p;
  return setup;
}

std::unique_ptr<edp::Hardware> plugin(const std::string& url,
                                      const std::function<void(Params&)>& adjust = {}) {
  auto hw = edp::make_hardware("can");
  hw->configure(plugin_setup(url, adjust));
  return hw;
}

/// One cycle every `period`; returns the last status.
edp::CycleStatus cycle(edp::Hardware& hw, std::vector<edp::AxisFeedback>& fb,
                       const std::vector<double>& setpoints) {
  std::this_thread::sleep_for(4ms);
  const edp::CycleStatus r = hw.read(fb);
  const edp::CycleStatus w = hw.write(setpoints);
  return r == edp::CycleStatus::ok ? w : r;
}

}  // namespace

TEST(CanPlugin, DrivesTheEmulatedIrb6AndReadsItBack) {
  const std::string url = bus_url();
  Emulator emu(url);
  auto hw = plugin(url);
  ASSERT_EQ(hw->axis_count(), 5U);
  hw->activate();
  std::vector<edp::AxisFeedback> fb(5);
  ASSERT_EQ(hw->read(fb), edp::CycleStatus::ok) << hw->fault_text();
  std::vector<double> target(5);
  for (std::size_t i = 0; i < 5; ++i) target[i] = fb[i].position;
  // Column +0.1 rad in 100 cycles, then hold for 100.
  const double start = target[0];
  for (int k = 1; k <= 200; ++k) {
    target[0] = start + 0.1 * std::min(1.0, k / 100.0);
    ASSERT_EQ(cycle(*hw, fb, target), edp::CycleStatus::ok) << hw->fault_text();
  }
  EXPECT_NEAR(fb[0].position, start + 0.1, 2e-3);
  for (std::size_t i = 1; i < 5; ++i) EXPECT_NEAR(fb[i].position, target[i], 2e-3) << i;

  // Emergency stop: the drives quick-stop and hold; release re-enables them.
  hw->emergency_stop(true);
  for (int k = 0; k < 20; ++k)
    ASSERT_EQ(cycle(*hw, fb, target), edp::CycleStatus::ok) << hw->fault_text();
  hw->emergency_stop(false);
  for (std::size_t i = 0; i < 5; ++i) target[i] = fb[i].position;
  for (int k = 0; k < 20; ++k)
    ASSERT_EQ(cycle(*hw, fb, target), edp::CycleStatus::ok) << hw->fault_text();
  hw->deactivate();
}

TEST(CanPlugin, BinaryLinesAreTheDrivesDigitalLines) {
  // configs/scenes/irb6.toml wires the column drive's output line 0 to the lower arm drive's
  // input line 0, and the lower arm drive's output line 7 to the column drive's input line 7.
  const std::string url = bus_url();
  Emulator emu(url);
  auto hw = plugin(url);
  ASSERT_TRUE(hw->binary_io());
  EXPECT_EQ(hw->output_lines(), 0xFFFFU);  // two drives' eight lines
  hw->activate();
  std::vector<edp::AxisFeedback> fb(5);
  ASSERT_EQ(hw->read(fb), edp::CycleStatus::ok) << hw->fault_text();
  std::vector<double> hold(5);
  for (std::size_t i = 0; i < 5; ++i) hold[i] = fb[i].position;
  const auto inputs_after = [&](std::uint32_t outputs) {
    hw->write_outputs(outputs);
    for (int k = 0; k < 10; ++k)
      EXPECT_EQ(cycle(*hw, fb, hold), edp::CycleStatus::ok) << hw->fault_text();
    return hw->read_inputs();
  };
  std::uint32_t in = inputs_after(0);
  EXPECT_EQ(in & 0xFFFF0000U, 0U);
  in = inputs_after(0x0001U);  // output 0: column drive, line 0 -> lower arm drive, line 0
  EXPECT_EQ(in & 0xFFFF0000U, 1U << 24U) << std::hex << in;
  in = inputs_after(0x8000U);  // output 15: lower arm drive, line 7 -> column drive, line 7
  EXPECT_EQ(in & 0xFFFF0000U, 1U << 23U) << std::hex << in;
  in = inputs_after(0x8001U);
  EXPECT_EQ(in & 0xFFFF0000U, (1U << 23U) | (1U << 24U)) << std::hex << in;
  in = inputs_after(0);
  EXPECT_EQ(in & 0xFFFF0000U, 0U) << std::hex << in;
  hw->deactivate();
  // The emulator saw each change of the drives' output lines.
  const std::string out = emu.output();
  EXPECT_NE(out.find("robot 'irb6' axis 'column' outputs 0x01"), std::string::npos) << out;
  EXPECT_NE(out.find("robot 'irb6' axis 'lower_arm' outputs 0x80"), std::string::npos) << out;
}

// An emergency stop switches the drives' output lines to their safe state (here: off) in the
// servo cycle after it, through the servo loop as the EDP runs it: RPDO2 goes out in that cycle,
// before its SYNC. configs/scenes/irb6.toml wires the column drive's output line 0 to the lower
// arm drive's input line 0 (EDP input bit 24), so the drives' own state is read back.
TEST(CanPlugin, AnEmergencyStopSwitchesTheDrivesOutputsOffInTheNextCycle) {
  const std::string url = bus_url();
  Emulator emu(url);
  auto hw = plugin(url);
  const RobotModel model = test::stock_model("irb6");
  edp::ServoLoop servo(*hw, model, 0.002);
  servo.set_stop_outputs(0, 0);
  servo.enable_trace(5000);
  servo.start();
  const auto input_24_is = [&](bool on) -> std::optional<std::int64_t> {
    const auto until = std::chrono::steady_clock::now() + 3s;
    while (std::chrono::steady_clock::now() < until) {
      const edp::Reading r = servo.latest();
      if (((r.inputs >> 24U) & 1U) == (on ? 1U : 0U)) return r.cycle;
      std::this_thread::sleep_for(200us);
    }
    return std::nullopt;
  };
  ASSERT_TRUE(servo.request_outputs(0x0001));
  const auto on_at = input_24_is(true);
  ASSERT_TRUE(on_at.has_value()) << emu.output();
  const std::int64_t before = servo.latest().cycle;
  servo.emergency_stop();
  // Every cycle planned after this one sees the stop.
  const std::int64_t after = servo.latest().cycle;
  const auto off_at = input_24_is(false);
  ASSERT_TRUE(off_at.has_value()) << emu.output();
  // Written (RPDO2 sent, before that cycle's SYNC) in the cycle after the stop; the drives'
  // answer takes the emulator's time, so it is printed, not bounded.
  std::int64_t written = -1;
  for (const edp::TraceSample& t : servo.trace())
    if (t.cycle > before && t.outputs == 0) {
      written = t.cycle;
      break;
    }
  EXPECT_GE(written, before + 1);
  EXPECT_LE(written, after + 1) << "stop between cycles " << before << " and " << after;
  std::printf(
      "outputs written in cycle %+lld after the stop, line 0 read back on the other "
      "drive in cycle %+lld\n",
      static_cast<long long>(written - before), static_cast<long long>(*off_at - before));
  EXPECT_FALSE(servo.request_outputs(0x0001));  // refused while the stop holds
  servo.release_emergency_stop();
  std::this_thread::sleep_for(50ms);
  EXPECT_EQ((servo.latest().inputs >> 24U) & 1U, 0U) << "a release must restore nothing";
  servo.stop();
  const std::string out = emu.output();
  EXPECT_NE(out.find("robot 'irb6' axis 'column' outputs 0x01"), std::string::npos) << out;
  EXPECT_NE(out.find("robot 'irb6' axis 'column' outputs 0x00"), std::string::npos) << out;
}

TEST(CanPlugin, InjectedDriveFaultIsAPluginFaultNamingTheDrive) {
  const std::string url = bus_url();
  Emulator emu(url, {"--fault", "drive:irb6/wrist_roll@0.1=0x2310"});
  auto hw = plugin(url);
  hw->activate();
  std::vector<edp::AxisFeedback> fb(5);
  ASSERT_EQ(hw->read(fb), edp::CycleStatus::ok) << hw->fault_text();
  std::vector<double> target(5);
  for (std::size_t i = 0; i < 5; ++i) target[i] = fb[i].position;
  edp::CycleStatus status = edp::CycleStatus::ok;
  for (int k = 0; k < 300 && status == edp::CycleStatus::ok; ++k) status = cycle(*hw, fb, target);
  ASSERT_EQ(status, edp::CycleStatus::fault);
  const std::string text = hw->fault_text();
  EXPECT_NE(text.find("node 5 (axis 'wrist_roll')"), std::string::npos) << text;
  EXPECT_NE(text.find("EMCY 0x2310 (continuous over-current)"), std::string::npos) << text;
  // A new bring-up (what SYNCHRO does after a fault) resets the drive.
  hw->deactivate();
  hw->activate();
  ASSERT_EQ(cycle(*hw, fb, target), edp::CycleStatus::ok) << hw->fault_text();
  hw->deactivate();
}

// What kill -9 of the EDP does to its drives: the master's SYNCs and heartbeats stop, and every
// drive, configured at bring-up as a consumer of both (docs/hil.md, "Drive supervision"),
// quick-stops on its own (EMCY 0x8130 heartbeat or 0x8100 SYNC). Over vcan0 in the qemu test too.
TEST(CanPlugin, AMasterThatFallsSilentMakesEveryDriveQuickStop) {
  const std::string url = bus_url();
  Emulator emu(url, {}, /*lock_step=*/false);
  auto hw = plugin(url);
  hw->activate();
  std::vector<edp::AxisFeedback> fb(5);
  ASSERT_EQ(hw->read(fb), edp::CycleStatus::ok) << hw->fault_text();
  std::vector<double> target(5);
  for (std::size_t i = 0; i < 5; ++i) target[i] = fb[i].position;
  for (int k = 1; k <= 50; ++k) {
    target[0] += 0.0002 * std::min(k, 25);  // the column speeds up to 0.05 rad per 4 ms cycle
    ASSERT_EQ(cycle(*hw, fb, target), edp::CycleStatus::ok) << hw->fault_text();
  }
  // The master falls silent here, as if its process were killed (no deactivate()).
  const auto silent_at = std::chrono::steady_clock::now();
  int reacted = 0;
  std::string out;
  while (std::chrono::steady_clock::now() - silent_at < 3s && reacted < 5) {
    std::this_thread::sleep_for(10ms);
    out = emu.output();
    reacted = 0;
    for (const char* axis : {"column", "lower_arm", "upper_arm", "wrist_pitch", "wrist_roll"})
      if (out.find(std::string("'") + axis + "' (node") != std::string::npos &&
          std::regex_search(out, std::regex(std::string("'") + axis +
                                            "' \\(node [0-9]+ on [^)]*\\): master lost")))
        ++reacted;
  }
  EXPECT_EQ(reacted, 5) << out;
  EXPECT_TRUE(out.find("EMCY 0x8130") != std::string::npos ||
              out.find("EMCY 0x8100") != std::string::npos)
      << out;
  EXPECT_NE(out.find("quick stop"), std::string::npos) << out;
  std::printf(
      "master silent: %d drives reacted within %.0f ms\n", reacted,
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - silent_at)
          .count());
}

TEST(CanPlugin, NoDrivesIsAClearError) {
  const std::string url = bus_url();
  auto hw = plugin(url);
  try {
    hw->activate();
    FAIL() << "activate succeeded without drives";
  } catch (const HardwareError& e) {
    EXPECT_NE(std::string(e.what()).find(url + " node 1 (axis 'column'): no boot-up message"),
              std::string::npos)
        << e.what();
  }
}

// Homing by the drives' own homing mode (CiA 402 mode 6) through the plugin, on the emulator's
// MuJoCo axes: configs/scenes/irb6.toml's lower arm (node 2) and wrist roll (node 5) have
// emu-pp-split.eds drives, whose file has homing; each axis powers on 0.05 rad above its
// synchronisation position, where its home switch is on.
namespace {

constexpr double kLowerArmSynchro = -1.5707963267948966;

void homing_rows(Params& p) {
  // Lower arm: method 19, home where the switch goes off moving down, the offset its joint
  // position there. Wrist roll: method 20, off the switch first, then up onto it; offset 0.
  p.set("homing",
        std::vector<std::vector<double>>{{2, 19, 0.2, 0.05, 1.0, kLowerArmSynchro, 10.0},
                                         {5, 20, 0.2, 0.05, 1.0, 0.0, 10.0}},
        {"cell.toml", 30});
  p.set_row_locations("homing", {{"cell.toml", 30}, {"cell.toml", 31}});
}

}  // namespace

TEST(CanPlugin, DrivesHomeByTheirHomingModeAndEndAtTheOffset) {
  const std::string url = bus_url();
  Emulator emu(url);
  auto hw = plugin(url, homing_rows);
  auto* homing = dynamic_cast<edp::DriveHoming*>(hw.get());
  ASSERT_NE(homing, nullptr);
  EXPECT_EQ(homing->self_homing_axes(), (1U << 1U) | (1U << 4U));
  hw->activate();
  std::vector<edp::AxisFeedback> fb(5);
  ASSERT_EQ(hw->read(fb), edp::CycleStatus::ok) << hw->fault_text();
  std::vector<double> before(5);
  for (std::size_t i = 0; i < 5; ++i) before[i] = fb[i].position;
  EXPECT_TRUE(fb[1].synchro_switch);  // 0.05 rad above the switch's edge
  const auto began = std::chrono::steady_clock::now();
  homing->home_axes();
  const double took =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - began).count();
  // Held where the homing left them: the homed axes count from their home points.
  std::vector<double> hold(5);
  ASSERT_EQ(hw->read(fb), edp::CycleStatus::ok) << hw->fault_text();
  for (std::size_t i = 0; i < 5; ++i) hold[i] = fb[i].position;
  for (int k = 0; k < 50; ++k)
    ASSERT_EQ(cycle(*hw, fb, hold), edp::CycleStatus::ok) << hw->fault_text();
  // The lower arm stands at its switch's edge, which is its synchronisation position, and the
  // drive says so: its offset (within the MuJoCo servo's sag under gravity and the 1 ms step).
  EXPECT_NEAR(fb[1].position, kLowerArmSynchro, 2e-3);
  EXPECT_NEAR(fb[4].position, 0.0, 2e-3);
  // The axes not homed did not move; the homed ones stood still before the last 50 cycles.
  for (const std::size_t i : {0U, 2U, 3U}) EXPECT_NEAR(fb[i].position, before[i], 1e-4) << i;
  for (std::size_t i = 0; i < 5; ++i) EXPECT_NEAR(fb[i].position, hold[i], 1e-4) << i;
  EXPECT_NEAR(fb[1].velocity, 0.0, 1e-3);
  // Then driven from there as before.
  for (int k = 1; k <= 100; ++k) {
    std::vector<double> target = hold;
    target[1] += 0.05 * std::min(1.0, k / 50.0);
    ASSERT_EQ(cycle(*hw, fb, target), edp::CycleStatus::ok) << hw->fault_text();
  }
  EXPECT_NEAR(fb[1].position, hold[1] + 0.05, 2e-3);
  EXPECT_TRUE(fb[1].synchro_switch);  // above the edge again
  std::printf(
      "two drives homed in %.2f s; lower arm at %.5f rad (synchronisation position "
      "%.5f rad)\n",
      took, hold[1], kLowerArmSynchro);
  hw->deactivate();
}

TEST(CanPlugin, AnEmergencyStopDuringHomingQuickStopsTheDrivesAndIsAFault) {
  const std::string url = bus_url();
  Emulator emu(url);
  auto hw = plugin(url, [](Params& p) {
    // Wrist roll: method 20 at a crawl, so that the stop comes mid-homing.
    p.set("homing", std::vector<std::vector<double>>{{5, 20, 0.2, 0.02, 1.0, 0.0, 20.0}},
          {"cell.toml", 30});
    p.set_row_locations("homing", {{"cell.toml", 30}});
  });
  hw->activate();
  std::vector<edp::AxisFeedback> fb(5);
  ASSERT_EQ(hw->read(fb), edp::CycleStatus::ok) << hw->fault_text();
  std::string what;
  std::thread stopper([&] {
    std::this_thread::sleep_for(800ms);
    hw->emergency_stop(true);  // as the EDP's emergency-stop listener does
  });
  try {
    dynamic_cast<edp::DriveHoming&>(*hw).home_axes();
    what = "no error";
  } catch (const HardwareError& e) {
    what = e.what();
  }
  stopper.join();
  EXPECT_NE(what.find("drive node 5 (axis 'wrist_roll') on " + url +
                      ": homing by method 20 failed after "),
            std::string::npos)
      << what;
  EXPECT_NE(what.find("stopped by the emergency stop (quick stop)"), std::string::npos) << what;
  // A fault as the others: the plugin reports it and holds the drives quick-stopped.
  std::vector<double> hold(5);
  for (std::size_t i = 0; i < 5; ++i) hold[i] = fb[i].position;
  EXPECT_EQ(cycle(*hw, fb, hold), edp::CycleStatus::fault);
  EXPECT_EQ(hw->fault_text(), what);
  const double at = fb[4].position;
  for (int k = 0; k < 50; ++k) (void)cycle(*hw, fb, hold);
  EXPECT_NEAR(fb[4].position, at, 2e-3);  // ramped down from 0.02 rad/s: 0.2 mrad at most
  EXPECT_NEAR(fb[4].velocity, 0.0, 1e-3);
  // A new bring-up (the EDP's SYNCHRO after a fault) clears it.
  hw->emergency_stop(false);
  hw->deactivate();
  hw->activate();
  ASSERT_EQ(hw->read(fb), edp::CycleStatus::ok) << hw->fault_text();
  hw->deactivate();
}

TEST(CanPlugin, HomingRowsAreCheckedAgainstTheDrivesFilesAtTheirRows) {
  const std::string url = bus_url();
  auto hw = edp::make_hardware("can");
  try {
    hw->check(plugin_setup(url, [](Params& p) {
      p.set("homing",
            std::vector<std::vector<double>>{
                {3, 19, 0.2, 0.05, 1.0, 0.0, 10.0},  // upper arm: emu-ip.eds has no 0x6098
                {9, 19, 0.2, 0.05, 1.0, 0.0, 10.0},  // no such node
                {5, 19, 0.2, 0.05, 1.0},             // too short
                {3, 20, 0.2, 0.05, 1.0, 0.0, 10.0},  // node 3 again
            },
            {"cell.toml", 30});
      p.set_row_locations(
          "homing", {{"cell.toml", 30}, {"cell.toml", 31}, {"cell.toml", 32}, {"cell.toml", 33}});
    }));
    FAIL() << "no error";
  } catch (const ConfigError& e) {
    const std::string what = e.what();
    for (const std::string line : {
             "cell.toml:30: error: node 3 (axis 'upper_arm'): ",
             "emu-ip.eds has no object 0x6098 (homing method), which mrroc writes at SYNCHRO to "
             "home the axis by the drive's homing mode (config 'homing')",
             "cell.toml:31: error: 'homing' names node 9, which is none of robot 'irb6''s nodes",
             "cell.toml:32: error: each row of 'homing' is [node",
             "cell.toml:33: error: 'homing' has a second row for node 3 (the first is at "
             "cell.toml:30)",
         })
      EXPECT_NE(what.find(line), std::string::npos) << "expected: " << line << "\n" << what;
  }
  // Rows the files allow pass (what mrroc-launch --check runs).
  EXPECT_NO_THROW(hw->check(plugin_setup(url, homing_rows)));
}
