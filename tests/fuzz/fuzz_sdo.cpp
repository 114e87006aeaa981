// The master's SDO client (Cia402Master::sdo_read_bytes: expedited and segmented uploads;
// sdo_write_bytes: expedited and segmented downloads; aborts) answered by a hostile server: the
// input is cut into 8-byte SDO responses of node 1 (COB-ID 0x581), each handed to the client as
// it waits for its next frame; a byte before each selects a length (its low 4 bits, 0..8; longer
// is 8) and, with bit 4, another node's identifier. The client reads 0x1008, then writes 18
// bytes (segmented: 7, 7, 4) and then 3 bytes (expedited) to 0x2100, each taking its answers
// from where the one before left off.
//
// Properties (docs/fuzzing.md):
// - the client returns a value of at most 4096 bytes (or completes a write) or throws
//   mrroc::HardwareError (a named abort code, a segment out of order, no answer, a length that
//   differs from the announced one); nothing else escapes, nothing crashes or hangs;
// - every frame the client sends is an SDO request to node 1 (COB-ID 0x601, 8 bytes) or the
//   master's heartbeat.
#include <linux/can.h>

#include <chrono>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <deque>
#include <string>

#include "fuzz_common.hpp"
#include "mrroc/can/bus.hpp"
#include "mrroc/can/canopen.hpp"
#include "mrroc/can/cia402_master.hpp"
#include "mrroc/core/error.hpp"

namespace {

using namespace mrroc::can;

/// Hands out the queued responses, one per receive, as a server would answer.
class ServerBus final : public Bus {
 public:
  std::string url() const override { return "virtual:fuzz-sdo"; }
  SendResult send(const can_frame& f) noexcept override {
    const bool request = f.can_id == canopen::sdo_request_id(1) && f.can_dlc == 8;
    const bool heartbeat = f.can_id == canopen::heartbeat_id(canopen::kDefaultMasterNode);
    fuzz::expect(request || heartbeat, "the client sent something else than a request to node 1");
    return SendResult::sent;
  }
  bool receive(Received& out, std::chrono::nanoseconds) noexcept override {
    if (queue_.empty()) return false;
    out.frame = queue_.front();
    queue_.pop_front();
    return true;
  }
  void set_filters(std::span<const can_filter>) override {}
  void receive_error_frames(bool) override {}
  BusStats stats() const noexcept override { return {}; }
  std::string last_error() const override { return {}; }
  std::deque<can_frame> queue_;
};

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  ServerBus bus;
  for (std::size_t at = 0; at + 9 <= size && bus.queue_.size() < 700; at += 9) {
    can_frame f{};
    f.can_id = (data[at] & 0x10U) != 0U ? canopen::sdo_response_id(2) : canopen::sdo_response_id(1);
    f.can_dlc = static_cast<std::uint8_t>(std::min<unsigned>(data[at] & 0x0FU, 8U));
    std::memcpy(f.data, data + at + 1, 8);
    bus.queue_.push_back(f);
  }
  std::vector<MasterAxis> axes(1);
  axes[0].name = "a0";
  axes[0].node = 1;
  MasterOptions options;
  options.sdo_timeout = std::chrono::milliseconds(1);
  options.sdo_attempts = 1;
  Cia402Master master(bus, axes, options);
  try {
    const std::string value = master.sdo_read_bytes(1, 0x1008, 0);
    fuzz::expect(value.size() <= 4096 + 7, "a value longer than the client's limit");
  } catch (const mrroc::HardwareError&) {
  }
  for (const char* text : {"mrroc's axis label", "abc"}) {
    try {
      master.sdo_write_bytes(1, 0x2100, 0, text);
    } catch (const mrroc::HardwareError&) {
    }
  }
  return 0;
}
