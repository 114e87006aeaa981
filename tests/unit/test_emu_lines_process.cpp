/// @file
/// The drives' digital lines through the real cell emulator (mrroc-axis-emu, lock-step, scene
/// configs/scenes/conveyor-pick.toml, a virtual bus): a master sets the IRb-6 column drive's
/// output 0 by SDO, the scene's loop-back wire brings it back on input 1 in the drive's TPDO1,
/// and the emulator prints the wires at start and the outputs when they change.
#include <unistd.h>

#include <chrono>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include <gtest/gtest.h>

#include "emu_process.hpp"
#include "mrroc/can/bus.hpp"
#include "mrroc/can/canopen.hpp"

namespace {

namespace co = mrroc::can::canopen;
using namespace std::chrono_literals;

/// The master's side of one node on the bus.
class Master {
 public:
  Master(const std::string& url, std::uint8_t node)
      : bus_(mrroc::can::open_bus(url)), node_(node) {}

  /// An expedited SDO download, confirmed by the drive.
  void write(std::uint16_t index, std::uint8_t sub, std::uint32_t value) {
    co::SdoRequest request;
    request.write = true;
    request.index = index;
    request.subindex = sub;
    request.value = value;
    request.size = 4;
    ASSERT_EQ(bus_->send(co::encode_request(node_, request)), mrroc::can::SendResult::sent);
    const auto until = std::chrono::steady_clock::now() + 2s;
    mrroc::can::Received r;
    while (std::chrono::steady_clock::now() < until) {
      if (!bus_->receive(r, 100ms) || r.frame.can_id != co::sdo_response_id(node_)) continue;
      const auto response = co::decode_response(r.frame);
      ASSERT_TRUE(response.has_value());
      ASSERT_FALSE(response->abort) << std::hex << "abort 0x" << response->abort_code;
      ASSERT_TRUE(response->write_confirmed);
      return;
    }
    FAIL() << "no SDO response from node " << int{node_};
  }

  void start() {
    ASSERT_EQ(bus_->send(co::nmt_frame(co::NmtCommand::start, 0)), mrroc::can::SendResult::sent);
  }

  /// Sends `count` SYNCs, each answered by the node's TPDO1; 0x60FD of the last one, nullopt
  /// when a TPDO1 did not come.
  std::optional<std::uint32_t> sync(int count) {
    std::optional<std::uint32_t> inputs;
    for (int i = 0; i < count; ++i) {
      can_frame sync{};
      sync.can_id = co::kSyncId;
      if (bus_->send(sync) != mrroc::can::SendResult::sent) return std::nullopt;
      inputs.reset();
      const auto until = std::chrono::steady_clock::now() + 2s;
      mrroc::can::Received r;
      while (!inputs && std::chrono::steady_clock::now() < until) {
        if (!bus_->receive(r, 100ms) || r.frame.can_id != co::tpdo1_id(node_)) continue;
        if (const auto pdo = co::decode_tpdo1(r.frame)) inputs = pdo->inputs;
      }
      if (!inputs) return std::nullopt;
    }
    return inputs;
  }

 private:
  std::unique_ptr<mrroc::can::Bus> bus_;
  std::uint8_t node_;
};

std::uint32_t lines(std::uint32_t digital_inputs) {
  return (digital_inputs & co::kUserLineMask) >> co::kUserLineShift;
}

TEST(EmuLines, LoopBackInputFollowsTheOutputTheMasterSetsAndTheEmulatorPrintsIt) {
  const std::string pid = std::to_string(::getpid());
  const std::string url = "virtual:emu-lines-" + pid;
  const std::string scene =
      (std::filesystem::path(MRROC_SOURCE_DIR) / "configs/scenes/conveyor-pick.toml").string();
  const mrroc::test::EmuProcess emulator(
      {"--scene", scene, "--bus", "irb6=" + url, "--bus", "conveyor=virtual:emu-belt-" + pid},
      /*lock_step=*/true);
  EXPECT_NE(emulator.startup().find("mrroc-axis-emu: robot 'irb6' axis 'column' input 0: "
                                    "presence of 'part' in x 0.35..0.45 y -0.75..-0.55 z "
                                    "0.70..1.00 m\n"),
            std::string::npos);
  EXPECT_NE(emulator.startup().find(
                "mrroc-axis-emu: robot 'irb6' axis 'column' input 1: output 0 of axis 'column'\n"),
            std::string::npos);
  Master master(url, 1);  // the column's drive
  master.start();
  auto inputs = master.sync(3);
  ASSERT_TRUE(inputs.has_value()) << "no TPDO1 from the column's drive";
  EXPECT_EQ(lines(*inputs), 0U) << "outputs off at power-on; the part (s = 0) far from the barrier";
  // Output 0 on: 0x60FE sub 2 (the mask) and sub 1.
  master.write(co::od::kDigitalOutputs, 2, co::kUserLineMask);
  master.write(co::od::kDigitalOutputs, 1, 1U << co::kUserLineShift);
  inputs = master.sync(3);
  ASSERT_TRUE(inputs.has_value());
  EXPECT_EQ(lines(*inputs), 0x02U) << "input 1 follows output 0";
  const std::string on = emulator.output_with("outputs 0x01");
  EXPECT_NE(on.find("mrroc-axis-emu: robot 'irb6' axis 'column' outputs 0x01 at t = "),
            std::string::npos)
      << on;
  // Outputs 1..7 on, 0 off: input 1 off again, and the change printed.
  master.write(co::od::kDigitalOutputs, 1, 0xFEU << co::kUserLineShift);
  inputs = master.sync(3);
  ASSERT_TRUE(inputs.has_value());
  EXPECT_EQ(lines(*inputs), 0U);
  const std::string off = emulator.output_with("outputs 0xFE");
  EXPECT_NE(off.find("mrroc-axis-emu: robot 'irb6' axis 'column' outputs 0xFE at t = "),
            std::string::npos)
      << off;
  EXPECT_EQ(off.find("axis 'lower_arm' outputs"), std::string::npos) << "only the column's changed";
}

}  // namespace
