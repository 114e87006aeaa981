// The CAN frame decoders of both ends of the drive protocol, fed hostile frames as a bus would
// deliver them: the EDP `can` plugin's CiA 402 master (Cia402Master::receive, which decodes
// TPDOs, EMCYs, heartbeats and SDO responses) and the cell emulator's drive (Cia402Drive::on_frame:
// NMT, SYNC, RPDOs, SDO requests), plus every canopen decoder on every frame.
//
// Input: records of 14 bytes: can_id (4, little endian), dlc (1), data (8), op (1):
//   op bit 0: the frame goes to the drive (else to the master's bus);
//   op bits 1-3: simulated time advance before it [ms];
//   op bit 4: after it, one cycle (drive: update(); master: send());
//   op bit 5/6/7: set CAN_EFF_FLAG / CAN_RTR_FLAG / CAN_ERR_FLAG on can_id.
// The drive's answers go back onto the master's bus (they meet on one wire).
//
// Properties (docs/fuzzing.md):
// - nothing throws (both ends are noexcept on this path) and nothing crashes;
// - a decoder that accepts a frame gives back a frame that encodes to the same payload;
// - every frame the drive or the master sends is a valid classical frame (dlc <= 8, a standard
//   11-bit identifier, no error/remote flag) and the master's SYNC is 0x080;
// - the drive's demand and demand velocity stay finite; its statusword decodes to the state it
//   reports; the master's fault text is a terminated string; its drive positions are finite.
#include <linux/can.h>

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <deque>
#include <string>
#include <vector>

#include "fuzz_common.hpp"
#include "mrroc/can/bus.hpp"
#include "mrroc/can/canopen.hpp"
#include "mrroc/can/cia402_drive.hpp"
#include "mrroc/can/cia402_master.hpp"

namespace {

using namespace mrroc::can;

void check_sent(const can_frame& f, const char* who) {
  fuzz::expect(f.can_dlc <= 8, fmt::format("{} sent dlc {}", who, f.can_dlc));
  fuzz::expect((f.can_id & (CAN_EFF_FLAG | CAN_RTR_FLAG | CAN_ERR_FLAG)) == 0U,
               fmt::format("{} sent can_id 0x{:x} with a flag", who, f.can_id));
  fuzz::expect(f.can_id <= CAN_SFF_MASK, fmt::format("{} sent can_id 0x{:x}", who, f.can_id));
}

/// One wire in memory: what is queued is what receive() returns, in order.
class FuzzBus final : public Bus {
 public:
  std::string url() const override { return "virtual:fuzz"; }
  SendResult send(const can_frame& frame) noexcept override {
    check_sent(frame, "the master");
    ++sent_;
    return SendResult::sent;
  }
  bool receive(Received& out, std::chrono::nanoseconds) noexcept override {
    if (queue_.empty()) return false;
    out = queue_.front();
    queue_.pop_front();
    return true;
  }
  void set_filters(std::span<const can_filter>) override {}
  void receive_error_frames(bool) override {}
  BusStats stats() const noexcept override { return {}; }
  std::string last_error() const override { return {}; }

  void put(const can_frame& frame, std::int64_t now_ns) {
    if (queue_.size() < 4096) queue_.push_back({frame, now_ns});
  }
  std::size_t sent() const { return sent_; }

 private:
  std::deque<Received> queue_;
  std::size_t sent_ = 0;
};

void check_decoders(const can_frame& f) {
  if (const auto p = canopen::decode_rpdo1(f)) {
    const can_frame again = canopen::encode(static_cast<std::uint8_t>(f.can_id & 0x7F), *p);
    fuzz::expect(canopen::decode_rpdo1(again)->controlword == p->controlword &&
                     canopen::decode_rpdo1(again)->target_position == p->target_position,
                 "RPDO1 round trip");
  }
  if (const auto p = canopen::decode_rpdo2(f)) {
    const auto q =
        canopen::decode_rpdo2(canopen::encode(static_cast<std::uint8_t>(f.can_id & 0x7F), *p));
    fuzz::expect(q && q->outputs == p->outputs, "RPDO2 round trip");
  }
  if (const auto p = canopen::decode_tpdo1(f)) {
    const can_frame again = canopen::encode(static_cast<std::uint8_t>(f.can_id & 0x7F), *p);
    const auto q = canopen::decode_tpdo1(again);
    fuzz::expect(q && q->inputs == p->inputs && q->position_actual == p->position_actual,
                 "TPDO1 round trip");
  }
  if (const auto p = canopen::decode_tpdo2(f)) {
    const can_frame again = canopen::encode(static_cast<std::uint8_t>(f.can_id & 0x7F), *p);
    const auto q = canopen::decode_tpdo2(again);
    fuzz::expect(q && q->statusword == p->statusword, "TPDO2 round trip");
    (void)canopen::decode_state(p->statusword);
  }
  if (const auto e = canopen::decode_emcy(f)) {
    const auto again =
        canopen::decode_emcy(canopen::encode_emcy(static_cast<std::uint8_t>(f.can_id & 0x7F), *e));
    fuzz::expect(again && again->code == e->code && again->error_register == e->error_register &&
                     again->manufacturer == e->manufacturer,
                 "EMCY round trip");
    (void)canopen::describe_emcy(e->code);
  }
  if (const auto r = canopen::decode_request(f)) {
    const auto again = canopen::decode_request(
        canopen::encode_request(static_cast<std::uint8_t>(f.can_id & 0x7F), *r));
    fuzz::expect(again && again->write == r->write && again->index == r->index &&
                     again->subindex == r->subindex,
                 "SDO request round trip");
  }
  if (const auto r = canopen::decode_response(f)) {
    const auto again = canopen::decode_response(
        canopen::encode_response(static_cast<std::uint8_t>(f.can_id & 0x7F), *r));
    fuzz::expect(again && again->abort == r->abort && again->index == r->index &&
                     again->subindex == r->subindex,
                 "SDO response round trip");
    if (r->abort) (void)canopen::describe_sdo_abort(r->abort_code);
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  constexpr std::size_t kRecord = 14;
  FuzzBus bus;
  std::vector<MasterAxis> axes(2);
  axes[0].name = "a0";
  axes[0].node = 1;
  axes[1].name = "a1";
  axes[1].node = 2;
  MasterOptions options;
  Cia402Master master(bus, axes, options);

  double now_s = 0.0;
  std::int64_t now_ns = 0;
  DriveConfig config;
  config.node = 1;
  Cia402Drive drive(config, [&](const can_frame& f) {
    check_sent(f, "the drive");
    bus.put(f, now_ns);
  });
  AxisSample sample;
  fuzz::no_throw("Cia402Drive::power_on", [&] { drive.power_on(sample, now_s); });

  const std::vector<double> targets = {0.0, 0.0};
  for (std::size_t at = 0; at + kRecord <= size && at < kRecord * 2000; at += kRecord) {
    const std::uint8_t* r = data + at;
    can_frame f{};
    std::uint32_t id = 0;
    std::memcpy(&id, r, 4);
    const std::uint8_t op = r[13];
    id &= CAN_EFF_MASK;
    if ((op & 0x20U) == 0U) id &= CAN_SFF_MASK;
    if ((op & 0x20U) != 0U) id |= CAN_EFF_FLAG;
    if ((op & 0x40U) != 0U) id |= CAN_RTR_FLAG;
    if ((op & 0x80U) != 0U) id |= CAN_ERR_FLAG;
    f.can_id = id;
    f.can_dlc = static_cast<std::uint8_t>(r[4] % 16);  // a bus may deliver a dlc above 8
    std::memcpy(f.data, r + 5, 8);
    if (f.can_dlc > 8) f.can_dlc = 8;  // Linux clamps classical frames to 8 data bytes
    now_s += static_cast<double>((op >> 1) & 0x7U) * 1e-3;
    now_ns = static_cast<std::int64_t>(now_s * 1e9);

    check_decoders(f);
    if ((op & 0x01U) != 0U) {
      fuzz::no_throw("Cia402Drive::on_frame", [&] { drive.on_frame(f, now_s); });
      if ((op & 0x10U) != 0U) {
        sample.position = drive.demand();
        fuzz::no_throw("Cia402Drive::update", [&] { drive.update(sample, now_s); });
      }
      fuzz::expect(
          std::isfinite(drive.demand()) && std::isfinite(drive.demand_velocity()),
          fmt::format("drive demand {} velocity {}", drive.demand(), drive.demand_velocity()));
      fuzz::expect(canopen::decode_state(drive.statusword()) == drive.state(),
                   fmt::format("statusword 0x{:04x} does not decode to the drive's state {}",
                               drive.statusword(), canopen::to_string(drive.state())));
    } else {
      bus.put(f, now_ns);
    }
    master.receive();
    if ((op & 0x10U) != 0U) master.send(targets, (op & 0x08U) != 0U);
    fuzz::expect(std::strlen(master.fault_text()) < 256, "master fault text unterminated");
    for (std::size_t i = 0; i < master.axis_count(); ++i)
      fuzz::expect(std::isfinite(master.status(i).position),
                   fmt::format("axis {} position {}", i, master.status(i).position));
  }
  return 0;
}
