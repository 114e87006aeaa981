/// @file
/// CANopen / CiA 402 frame codecs and the drive state machine's transition table.
#include "mrroc/can/canopen.hpp"

#include <cstring>

namespace mrroc::can::canopen {
namespace {

void put16(std::uint8_t* p, std::uint16_t v) {
  p[0] = static_cast<std::uint8_t>(v & 0xFFU);
  p[1] = static_cast<std::uint8_t>(v >> 8U);
}
void put32(std::uint8_t* p, std::uint32_t v) {
  for (unsigned i = 0; i < 4; ++i) p[i] = static_cast<std::uint8_t>((v >> (8U * i)) & 0xFFU);
}
std::uint16_t get16(const std::uint8_t* p) {
  return static_cast<std::uint16_t>(p[0] | (static_cast<unsigned>(p[1]) << 8U));
}
std::uint32_t get32(const std::uint8_t* p) {
  return static_cast<std::uint32_t>(p[0]) | (static_cast<std::uint32_t>(p[1]) << 8U) |
         (static_cast<std::uint32_t>(p[2]) << 16U) | (static_cast<std::uint32_t>(p[3]) << 24U);
}
can_frame frame(canid_t id, std::uint8_t length) {
  can_frame f{};
  f.can_id = id;
  f.len = length;
  return f;
}
/// A standard data frame (not RTR, not error, not extended) of exactly `length` bytes.
bool plain(const can_frame& f, std::uint8_t length) {
  return (f.can_id & (CAN_EFF_FLAG | CAN_RTR_FLAG | CAN_ERR_FLAG)) == 0U && f.len == length;
}

}  // namespace

CobId split_id(canid_t id) {
  const auto sid = static_cast<std::uint16_t>(id & CAN_SFF_MASK);
  if (sid == kNmtId || sid == kSyncId) return {sid, 0};
  return {static_cast<std::uint16_t>(sid & 0x780U), static_cast<std::uint8_t>(sid & 0x7FU)};
}

can_frame nmt_frame(NmtCommand command, std::uint8_t node) {
  can_frame f = frame(kNmtId, 2);
  f.data[0] = static_cast<std::uint8_t>(command);
  f.data[1] = node;
  return f;
}
can_frame sync_frame() { return frame(kSyncId, 0); }
can_frame heartbeat_frame(std::uint8_t node, NmtState state) {
  can_frame f = frame(heartbeat_id(node), 1);
  f.data[0] = static_cast<std::uint8_t>(state);
  return f;
}

std::string_view to_string(NmtState state) {
  switch (state) {
    case NmtState::boot_up: return "boot-up";
    case NmtState::stopped: return "stopped";
    case NmtState::operational: return "operational";
    case NmtState::pre_operational: return "pre-operational";
  }
  return "unknown";
}

std::string_view to_string(DriveState state) {
  switch (state) {
    case DriveState::not_ready_to_switch_on: return "not ready to switch on";
    case DriveState::switch_on_disabled: return "switch on disabled";
    case DriveState::ready_to_switch_on: return "ready to switch on";
    case DriveState::switched_on: return "switched on";
    case DriveState::operation_enabled: return "operation enabled";
    case DriveState::quick_stop_active: return "quick stop active";
    case DriveState::fault_reaction_active: return "fault reaction active";
    case DriveState::fault: return "fault";
  }
  return "unknown";
}

DriveState decode_state(std::uint16_t sw) {
  if ((sw & 0x4FU) == 0x00U) return DriveState::not_ready_to_switch_on;
  if ((sw & 0x4FU) == 0x40U) return DriveState::switch_on_disabled;
  if ((sw & 0x4FU) == 0x0FU) return DriveState::fault_reaction_active;
  if ((sw & 0x4FU) == 0x08U) return DriveState::fault;
  if ((sw & 0x6FU) == 0x21U) return DriveState::ready_to_switch_on;
  if ((sw & 0x6FU) == 0x23U) return DriveState::switched_on;
  if ((sw & 0x6FU) == 0x27U) return DriveState::operation_enabled;
  if ((sw & 0x6FU) == 0x07U) return DriveState::quick_stop_active;
  return DriveState::not_ready_to_switch_on;
}

std::uint16_t state_bits(DriveState state) {
  switch (state) {
    case DriveState::not_ready_to_switch_on: return 0x0000;
    case DriveState::switch_on_disabled: return 0x0040;
    case DriveState::ready_to_switch_on: return 0x0021;
    case DriveState::switched_on: return 0x0023;
    case DriveState::operation_enabled: return 0x0027;
    case DriveState::quick_stop_active: return 0x0007;
    case DriveState::fault_reaction_active: return 0x000F;
    case DriveState::fault: return 0x0008;
  }
  return 0;
}

DriveCommand decode_command(std::uint16_t cw) {
  if ((cw & 0x80U) != 0U) return DriveCommand::fault_reset;
  if ((cw & 0x02U) == 0U) return DriveCommand::disable_voltage;
  if ((cw & 0x06U) == 0x02U) return DriveCommand::quick_stop;
  if ((cw & 0x0FU) == 0x06U || (cw & 0x0FU) == 0x0EU) return DriveCommand::shutdown;
  if ((cw & 0x0FU) == 0x07U) return DriveCommand::switch_on;  // or disable operation
  if ((cw & 0x0FU) == 0x0FU) return DriveCommand::enable_operation;
  return DriveCommand::none;
}

std::optional<DriveState> transition(DriveState s, DriveCommand c) {
  using S = DriveState;
  using C = DriveCommand;
  switch (c) {
    case C::none: return std::nullopt;
    case C::fault_reset:  // 15
      return s == S::fault ? std::optional(S::switch_on_disabled) : std::nullopt;
    case C::disable_voltage:  // 7, 9, 10, 12
      if (s == S::ready_to_switch_on || s == S::switched_on || s == S::operation_enabled ||
          s == S::quick_stop_active)
        return S::switch_on_disabled;
      return std::nullopt;
    case C::quick_stop:  // 7, 10, 11
      if (s == S::ready_to_switch_on || s == S::switched_on) return S::switch_on_disabled;
      if (s == S::operation_enabled) return S::quick_stop_active;
      return std::nullopt;
    case C::shutdown:  // 2, 6, 8
      if (s == S::switch_on_disabled || s == S::switched_on || s == S::operation_enabled)
        return S::ready_to_switch_on;
      return std::nullopt;
    case C::switch_on:
    case C::disable_operation:  // 3, 5
      if (s == S::ready_to_switch_on || s == S::operation_enabled) return S::switched_on;
      return std::nullopt;
    case C::enable_operation:  // 4, 16 (and 3+4 at once from ready to switch on)
      if (s == S::switched_on || s == S::quick_stop_active || s == S::ready_to_switch_on)
        return S::operation_enabled;
      return std::nullopt;
  }
  return std::nullopt;
}

can_frame encode(std::uint8_t node, const Rpdo1& pdo) {
  can_frame f = frame(rpdo1_id(node), 6);
  put16(f.data, pdo.controlword);
  put32(f.data + 2, static_cast<std::uint32_t>(pdo.target_position));
  return f;
}
can_frame encode(std::uint8_t node, const Rpdo2& pdo) {
  can_frame f = frame(rpdo2_id(node), 4);
  put32(f.data, pdo.outputs);
  return f;
}
can_frame encode(std::uint8_t node, const Tpdo1& pdo) {
  can_frame f = frame(tpdo1_id(node), 8);
  put32(f.data, static_cast<std::uint32_t>(pdo.position_actual));
  put32(f.data + 4, pdo.inputs);
  return f;
}
can_frame encode(std::uint8_t node, const Tpdo2& pdo) {
  can_frame f = frame(tpdo2_id(node), 2);
  put16(f.data, pdo.statusword);
  return f;
}
std::optional<Rpdo1> decode_rpdo1(const can_frame& f) {
  if (!plain(f, 6)) return std::nullopt;
  return Rpdo1{get16(f.data), static_cast<std::int32_t>(get32(f.data + 2))};
}
std::optional<Rpdo2> decode_rpdo2(const can_frame& f) {
  if (!plain(f, 4)) return std::nullopt;
  return Rpdo2{get32(f.data)};
}
std::optional<Tpdo1> decode_tpdo1(const can_frame& f) {
  if (!plain(f, 8)) return std::nullopt;
  return Tpdo1{static_cast<std::int32_t>(get32(f.data)), get32(f.data + 4)};
}
std::optional<Tpdo2> decode_tpdo2(const can_frame& f) {
  if (!plain(f, 2)) return std::nullopt;
  return Tpdo2{get16(f.data)};
}

can_frame encode_emcy(std::uint8_t node, const Emergency& e) {
  can_frame f = frame(emcy_id(node), 8);
  put16(f.data, e.code);
  f.data[2] = e.error_register;
  std::memcpy(f.data + 3, e.manufacturer.data(), e.manufacturer.size());
  return f;
}
std::optional<Emergency> decode_emcy(const can_frame& f) {
  if (!plain(f, 8)) return std::nullopt;
  Emergency e;
  e.code = get16(f.data);
  e.error_register = f.data[2];
  std::memcpy(e.manufacturer.data(), f.data + 3, e.manufacturer.size());
  return e;
}
std::string_view describe_emcy(std::uint16_t code) {
  switch (code) {
    case emcy::kErrorReset: return "error reset / no error";
    case emcy::kContinuousOverCurrent: return "continuous over-current";
    case emcy::kDeviceHardware: return "device hardware";
    case emcy::kPositionSensor: return "position sensor (incremental encoder) fault";
    case emcy::kCommunication: return "communication error (SYNC lost)";
    case emcy::kHeartbeatError: return "heartbeat / life guard error";
    case emcy::kRecoveredFromBusOff: return "recovered from bus-off";
    case emcy::kFollowingError: return "following error";
    // CiA 301 and the drive profile CiA 402's error codes drives commonly send.
    case 0x1000: return "generic error";
    case 0x2110: return "short circuit / earth leakage (input)";
    case 0x2220: return "continuous over-current (device input side)";
    case 0x2311: return "continuous over-current no. 1";
    case 0x2320: return "short circuit / earth leakage (motor side)";
    case 0x2350: return "load level fault (I2t, thermal state)";
    case 0x3110: return "mains over-voltage";
    case 0x3120: return "mains under-voltage";
    case 0x3210: return "DC link over-voltage";
    case 0x3220: return "DC link under-voltage";
    case 0x4210: return "excess temperature device";
    case 0x4310: return "excess temperature drive";
    case 0x5113: return "supply voltage low";
    case 0x5441: return "safety: safe torque off active";
    case 0x6010: return "software reset (watchdog)";
    case 0x6320: return "parameter error";
    case 0x7121: return "motor blocked";
    case 0x7300: return "sensor";
    case 0x7310: return "speed sensor";
    case 0x7320: return "position sensor";
    case 0x8110: return "CAN overrun (objects lost)";
    case 0x8120: return "CAN in error passive mode";
    case 0x8210: return "PDO not processed due to length error";
    case 0x8220: return "PDO length exceeded";
    case 0x8400: return "velocity speed controller (deviation)";
    case 0x8500: return "position controller";
    case 0x8612: return "reference limit (position limit switch)";
    case 0xFF00: return "manufacturer-specific";
    default: break;
  }
  switch (code & 0xF000U) {
    case 0x2000: return "current";
    case 0x3000: return "voltage";
    case 0x4000: return "temperature";
    case 0x5000: return "device hardware";
    case 0x6000: return "device software";
    case 0x7000: return "additional modules";
    case 0x8000: return "monitoring";
    case 0xF000: return "additional functions";
    default: return "generic error";
  }
}

std::string_view describe_sdo_abort(std::uint32_t code) {
  switch (code) {
    case sdo_abort::kToggleBit: return "toggle bit not alternated";
    case sdo_abort::kTimeout: return "SDO protocol timed out";
    case sdo_abort::kCommandSpecifier: return "command specifier not valid or unknown";
    case sdo_abort::kReadOnly: return "attempt to write a read only object";
    case sdo_abort::kUnsupportedAccess: return "unsupported access to an object";
    case sdo_abort::kWriteOnly: return "attempt to read a write only object";
    case sdo_abort::kNoObject: return "object does not exist in the object dictionary";
    case sdo_abort::kNotMappable: return "object cannot be mapped to the PDO";
    case sdo_abort::kPdoTooLong:
      return "the number and length of the objects to be mapped would "
             "exceed the PDO length";
    case sdo_abort::kOutOfMemory: return "out of memory";
    case sdo_abort::kLengthMismatch: return "data type does not match, length does not match";
    case sdo_abort::kLengthTooHigh: return "data type does not match, length too high";
    case sdo_abort::kLengthTooLow: return "data type does not match, length too low";
    case sdo_abort::kNoSubindex: return "sub-index does not exist";
    case sdo_abort::kValueRange: return "value range of parameter exceeded";
    case sdo_abort::kValueTooHigh: return "value of parameter written too high";
    case sdo_abort::kValueTooLow: return "value of parameter written too low";
    case sdo_abort::kDeviceState: return "data cannot be transferred because of the device state";
    default: return "unknown abort code";
  }
}

can_frame encode_request(std::uint8_t node, const SdoRequest& r) {
  can_frame f = frame(sdo_request_id(node), 8);
  if (r.write) {
    const auto unused = static_cast<unsigned>(4 - r.size);
    f.data[0] = static_cast<std::uint8_t>(0x23U | (unused << 2U));  // ccs 1, expedited, size set
    put32(f.data + 4, r.value);
  } else {
    f.data[0] = 0x40;  // ccs 2: initiate upload
  }
  put16(f.data + 1, r.index);
  f.data[3] = r.subindex;
  return f;
}

can_frame encode_response(std::uint8_t node, const SdoResponse& r) {
  can_frame f = frame(sdo_response_id(node), 8);
  put16(f.data + 1, r.index);
  f.data[3] = r.subindex;
  if (r.abort) {
    f.data[0] = 0x80;
    put32(f.data + 4, r.abort_code);
  } else if (r.write_confirmed) {
    f.data[0] = 0x60;  // scs 3: download response
  } else {
    const auto unused = static_cast<unsigned>(4 - r.size);
    f.data[0] = static_cast<std::uint8_t>(0x43U | (unused << 2U));  // scs 2, expedited, size set
    put32(f.data + 4, r.value);
  }
  return f;
}

namespace {
std::uint32_t sized(std::uint32_t raw, std::uint8_t size) {
  return size >= 4 ? raw : raw & ((1U << (8U * size)) - 1U);
}
}  // namespace

std::optional<SdoRequest> decode_request(const can_frame& f) {
  if (!plain(f, 8)) return std::nullopt;
  SdoRequest r;
  r.index = get16(f.data + 1);
  r.subindex = f.data[3];
  const std::uint8_t cs = f.data[0];
  if ((cs & 0xE0U) == 0x40U) return r;  // upload
  if ((cs & 0xE3U) == 0x23U) {          // expedited download with size
    r.write = true;
    r.size = static_cast<std::uint8_t>(4U - ((cs >> 2U) & 0x3U));
    r.value = sized(get32(f.data + 4), r.size);
    return r;
  }
  return std::nullopt;
}

std::optional<SdoResponse> decode_response(const can_frame& f) {
  if (!plain(f, 8)) return std::nullopt;
  SdoResponse r;
  r.index = get16(f.data + 1);
  r.subindex = f.data[3];
  const std::uint8_t cs = f.data[0];
  if (cs == 0x80U) {
    r.abort = true;
    r.abort_code = get32(f.data + 4);
    return r;
  }
  if (cs == 0x60U) {
    r.write_confirmed = true;
    return r;
  }
  if ((cs & 0xE3U) == 0x43U) {
    r.size = static_cast<std::uint8_t>(4U - ((cs >> 2U) & 0x3U));
    r.value = sized(get32(f.data + 4), r.size);
    return r;
  }
  return std::nullopt;
}

FrameBits frame_bits(int bytes) {
  const int nominal = 47 + 8 * bytes;
  const int stuffable = 34 + 8 * bytes;  // SOF .. CRC
  return {nominal, nominal + (stuffable - 1) / 4};
}

BusLoad cyclic_bus_load(std::size_t axes, double period_s, double bitrate_bps,
                        double heartbeat_period_s, bool output_refresh) {
  BusLoad load;
  const auto n = static_cast<int>(axes);
  const FrameBits sync = frame_bits(0);
  const FrameBits rpdo = frame_bits(6);
  const FrameBits outputs = frame_bits(4);
  const FrameBits tpdo = frame_bits(8);
  const FrameBits statusword = frame_bits(2);
  const FrameBits heartbeat = frame_bits(1);
  load.frames_per_cycle = 1 + 2 * n;
  const double heartbeats_per_cycle =
      heartbeat_period_s > 0.0 ? static_cast<double>(n) * period_s / heartbeat_period_s : 0.0;
  // Each drive's outputs are refreshed every kOutputRefreshCycles cycles (an RPDO2), its
  // statusword every kStatuswordEventTimerMs (a TPDO2).
  const double refreshes_per_cycle =
      output_refresh ? static_cast<double>(n) / static_cast<double>(kOutputRefreshCycles) : 0.0;
  const double statuswords_per_cycle =
      static_cast<double>(n) * period_s / (kStatuswordEventTimerMs * 1e-3);
  load.bits_per_cycle_nominal =
      sync.nominal + n * (rpdo.nominal + tpdo.nominal) + heartbeats_per_cycle * heartbeat.nominal +
      refreshes_per_cycle * outputs.nominal + statuswords_per_cycle * statusword.nominal;
  load.bits_per_cycle_worst =
      sync.worst + n * (rpdo.worst + tpdo.worst) + heartbeats_per_cycle * heartbeat.worst +
      refreshes_per_cycle * outputs.worst + statuswords_per_cycle * statusword.worst;
  const double capacity = bitrate_bps * period_s;
  load.load_nominal = load.bits_per_cycle_nominal / capacity;
  load.load_worst = load.bits_per_cycle_worst / capacity;
  return load;
}

}  // namespace mrroc::can::canopen
