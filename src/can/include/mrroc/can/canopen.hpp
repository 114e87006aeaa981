#pragma once
/// @file
/// The subset of CANopen (CiA 301) and of the drive profile CiA 402 that mrroc's drives speak.
/// docs/hil.md describes it for users; this header is the reference for the numbers.
///
/// Identifiers: the predefined connection set with 11-bit COB-IDs, node ids 1..127.
///   NMT 0x000, SYNC 0x080, EMCY 0x080+n, TPDO1 0x180+n, TPDO2 0x280+n, RPDO1 0x200+n,
///   RPDO2 0x300+n, SDO server->client 0x580+n, SDO client->server 0x600+n, heartbeat /
///   boot-up 0x700+n.
///
/// The PDOs the master maps into every drive at bring-up (drive_setup.hpp; standard objects only):
///   RPDO1 (master -> drive, 6 bytes, every cycle): 0x6040 controlword (u16), the position
///         target (i32): 0x607A target position, or 0x60C1 sub 1 in interpolated position mode.
///   RPDO2 (master -> drive, 4 bytes, when the outputs change and every kOutputRefreshCycles
///         cycles; drives with outputs only): 0x60FE sub 1 digital outputs (u32; lines 0..7 are
///         bits 16..23).
///   TPDO1 (drive -> master, 8 bytes, every SYNC): 0x6064 position actual value (i32), 0x60FD
///         digital inputs (u32): sampled together, so that the home switch's edge comes with
///         the position it was seen at.
///   TPDO2 (drive -> master, 2 bytes, event-driven: when it changes and at least every
///         kStatuswordEventTimerMs): 0x6041 statusword (u16).
/// RPDOs are synchronous (transmission type 1): a drive applies the RPDOs received before a SYNC
/// at that SYNC; TPDOs are sampled at the SYNC.
///
/// Digital lines. 0x60FD (u32, read only) is CiA 402's digital inputs: bit 2 home switch, bits
/// 16..23 the drive's input lines 0..7 (manufacturer-specific bits). 0x60FE (CiA 402 digital
/// outputs) sub 1 is the outputs (u32, lines 0..7 in bits 16..23), sub 2 the bit mask of the
/// outputs the master may drive (power-on 0: none; the master writes kUserLineMask). A drive
/// drives line k while bit 16 + k is set in both; the other bits are ignored.
/// All multi-byte values are little-endian, as CANopen specifies.
#include <linux/can.h>

#include <array>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <string_view>

namespace mrroc::can::canopen {

// --- Identifiers -------------------------------------------------------------------------------
inline constexpr canid_t kNmtId = 0x000;
inline constexpr canid_t kSyncId = 0x080;
inline constexpr canid_t emcy_id(std::uint8_t node) { return 0x080U + node; }
inline constexpr canid_t tpdo1_id(std::uint8_t node) { return 0x180U + node; }
inline constexpr canid_t tpdo2_id(std::uint8_t node) { return 0x280U + node; }
inline constexpr canid_t rpdo1_id(std::uint8_t node) { return 0x200U + node; }
inline constexpr canid_t rpdo2_id(std::uint8_t node) { return 0x300U + node; }
inline constexpr canid_t sdo_response_id(std::uint8_t node) { return 0x580U + node; }
inline constexpr canid_t sdo_request_id(std::uint8_t node) { return 0x600U + node; }
inline constexpr canid_t heartbeat_id(std::uint8_t node) { return 0x700U + node; }
inline constexpr std::uint8_t kMaxNode = 127;

/// Function code (upper 4 bits of the 11-bit id) and node id of a frame.
struct CobId {
  std::uint16_t function = 0;  ///< e.g. 0x180 for TPDO1
  std::uint8_t node = 0;       ///< 0 for NMT and SYNC
};
CobId split_id(canid_t id);

// --- NMT ---------------------------------------------------------------------------------------
enum class NmtCommand : std::uint8_t {
  start = 0x01,
  stop = 0x02,
  enter_pre_operational = 0x80,
  reset_node = 0x81,
  reset_communication = 0x82,
};
/// NMT state as a heartbeat or boot-up message carries it.
enum class NmtState : std::uint8_t {
  boot_up = 0x00,
  stopped = 0x04,
  operational = 0x05,
  pre_operational = 0x7F,
};
can_frame nmt_frame(NmtCommand command, std::uint8_t node /* 0 = all nodes */);
can_frame sync_frame();
can_frame heartbeat_frame(std::uint8_t node, NmtState state);
std::string_view to_string(NmtState state);

// --- Object dictionary indices used --------------------------------------------------------------
namespace od {
inline constexpr std::uint16_t kDeviceType = 0x1000;     ///< u32; CiA 402 servo: 0x00020192
inline constexpr std::uint16_t kErrorRegister = 0x1001;  ///< u8
/// u32 communication cycle period [us]: the SYNC period; a drive supervises SYNC with it (0: off).
inline constexpr std::uint16_t kCommunicationCyclePeriod = 0x1006;
/// Consumer heartbeat time: sub 0 = entries (1), sub 1 = u32 (producer node << 16 | time [ms]);
/// time 0 or node 0: not monitored.
inline constexpr std::uint16_t kConsumerHeartbeatTime = 0x1016;
inline constexpr std::uint16_t kHeartbeatTime = 0x1017;  ///< u16, producer heartbeat [ms]
/// Error behaviour: sub 0 = 1, sub 1 = u8 NMT reaction to a communication error while
/// operational: 0 enter pre-operational, 1 no change, 2 enter stopped.
inline constexpr std::uint16_t kErrorBehaviour = 0x1029;
inline constexpr std::uint16_t kIdentity = 0x1018;  ///< sub 1 vendor, 2 product, 3 revision
/// i16 abort connection option code (CiA 402): the device control reaction to a communication
/// error (heartbeat or SYNC lost): 0 none, 1 fault, 2 disable voltage, 3 quick stop.
inline constexpr std::uint16_t kAbortConnectionOption = 0x6007;
inline constexpr std::uint16_t kControlword = 0x6040;            ///< u16
inline constexpr std::uint16_t kStatusword = 0x6041;             ///< u16
inline constexpr std::uint16_t kModesOfOperation = 0x6060;       ///< i8
inline constexpr std::uint16_t kModesDisplay = 0x6061;           ///< i8
inline constexpr std::uint16_t kPositionActual = 0x6064;         ///< i32 [counts]
inline constexpr std::uint16_t kFollowingErrorWindow = 0x6065;   ///< u32 [counts]
inline constexpr std::uint16_t kFollowingErrorTimeout = 0x6066;  ///< u16 [ms]
inline constexpr std::uint16_t kCurrentActual = 0x6078;          ///< i16 [per mille of rated]
inline constexpr std::uint16_t kTargetPosition = 0x607A;         ///< i32 [counts]
/// i16 quick stop option code: 2 ramp at 0x6085, then switch on disabled; 6 ramp at 0x6085,
/// then stay in quick stop active (holding). Only these two are implemented.
inline constexpr std::uint16_t kQuickStopOption = 0x605A;
inline constexpr std::uint16_t kQuickStopDeceleration = 0x6085;  ///< u32 [counts/s^2]
inline constexpr std::uint16_t kDigitalInputs = 0x60FD;          ///< u32, bit 2 home, 16..23 lines
/// Digital outputs: sub 0 = 2, sub 1 = u32 outputs, sub 2 = u32 bit mask (lines in bits 16..23)
inline constexpr std::uint16_t kDigitalOutputs = 0x60FE;
inline constexpr std::uint16_t kInterpolationPeriod = 0x60C2;  ///< sub 1: u8 value, sub 2: i8 exp
inline constexpr std::uint16_t kInterpolationData = 0x60C1;    ///< sub 1: i32 target [counts]
inline constexpr std::uint16_t kTargetVelocity = 0x60FF;       ///< i32 [counts/s] (CSV)
inline constexpr std::uint16_t kVelocityActual = 0x606C;       ///< i32 [counts/s]
inline constexpr std::uint16_t kTorqueActual = 0x6077;         ///< i16 [per mille of rated]
inline constexpr std::uint16_t kErrorCode = 0x603F;            ///< u16, the last EMCY's code
inline constexpr std::uint16_t kHomeOffset = 0x607C;           ///< i32 [counts]
inline constexpr std::uint16_t kHomingMethod = 0x6098;         ///< i8
inline constexpr std::uint16_t kHomingSpeeds =
    0x6099;  ///< sub 1 switch, sub 2 zero: u32 [counts/s]
inline constexpr std::uint16_t kHomingAcceleration = 0x609A;  ///< u32 [counts/s^2]
inline constexpr std::uint32_t kServoDeviceType = 0x00020192;
}  // namespace od

/// Values of the supervision objects.
namespace abort_connection {
inline constexpr std::int16_t kNoAction = 0;
inline constexpr std::int16_t kFault = 1;
inline constexpr std::int16_t kDisableVoltage = 2;
inline constexpr std::int16_t kQuickStop = 3;
}  // namespace abort_connection
namespace quick_stop_option {
inline constexpr std::int16_t kRampThenDisabled = 2;
inline constexpr std::int16_t kRampThenHold = 6;
}  // namespace quick_stop_option
namespace error_behaviour {
inline constexpr std::uint8_t kPreOperational = 0;
inline constexpr std::uint8_t kNoChange = 1;
inline constexpr std::uint8_t kStopped = 2;
}  // namespace error_behaviour
/// The master's default node id for its own heartbeat (0x700 + id); no drive may use it.
inline constexpr std::uint8_t kDefaultMasterNode = 0x7F;

/// Modes of operation (0x6060) used.
inline constexpr std::int8_t kModeHoming = 6;
inline constexpr std::int8_t kModeInterpolatedPosition = 7;
inline constexpr std::int8_t kModeCyclicSyncPosition = 8;
inline constexpr std::int8_t kModeCyclicSyncVelocity = 9;

// --- CiA 402 drive state machine -----------------------------------------------------------------
enum class DriveState {
  not_ready_to_switch_on,
  switch_on_disabled,
  ready_to_switch_on,
  switched_on,
  operation_enabled,
  quick_stop_active,
  fault_reaction_active,
  fault,
};
std::string_view to_string(DriveState state);
/// Decodes the state bits of a statusword (CiA 402 table of statusword patterns).
DriveState decode_state(std::uint16_t statusword);

namespace statusword {
inline constexpr std::uint16_t kReadyToSwitchOn = 1U << 0;
inline constexpr std::uint16_t kSwitchedOn = 1U << 1;
inline constexpr std::uint16_t kOperationEnabled = 1U << 2;
inline constexpr std::uint16_t kFault = 1U << 3;
inline constexpr std::uint16_t kVoltageEnabled = 1U << 4;
inline constexpr std::uint16_t kQuickStop = 1U << 5;  ///< 0 = quick stop active
inline constexpr std::uint16_t kSwitchOnDisabled = 1U << 6;
inline constexpr std::uint16_t kWarning = 1U << 7;
inline constexpr std::uint16_t kRemote = 1U << 9;
inline constexpr std::uint16_t kTargetReached = 1U << 10;
inline constexpr std::uint16_t kFollowingTarget = 1U << 12;  ///< CSP: drive follows the target
inline constexpr std::uint16_t kIpModeActive = 1U << 12;     ///< IP: interpolation active
inline constexpr std::uint16_t kFollowingError = 1U << 13;   ///< CSP: following error
inline constexpr std::uint16_t kHomingAttained = 1U << 12;   ///< homing mode: homing attained
inline constexpr std::uint16_t kHomingError = 1U << 13;      ///< homing mode: homing error
}  // namespace statusword
/// The state bits (0-3, 5, 6) of a statusword for a state.
std::uint16_t state_bits(DriveState state);

/// Device control commands (controlword bits 0-3 and 7).
enum class DriveCommand {
  none,               ///< a pattern that is no command (e.g. 0x0000 is disable voltage: see below)
  shutdown,           ///< 0bxxxx x110 -> ready to switch on
  switch_on,          ///< 0bxxxx 0111 -> switched on
  disable_voltage,    ///< 0bxxxx xx0x -> switch on disabled
  quick_stop,         ///< 0bxxxx x01x -> quick stop active / switch on disabled
  disable_operation,  ///< 0bxxxx 0111 from operation enabled -> switched on (same bits as switch
                      ///< on)
  enable_operation,   ///< 0bxxxx 1111 -> operation enabled
  fault_reset,        ///< bit 7 (rising edge) -> switch on disabled
};
namespace controlword {
inline constexpr std::uint16_t kShutdown = 0x0006;
inline constexpr std::uint16_t kSwitchOn = 0x0007;
inline constexpr std::uint16_t kEnableOperation = 0x000F;
inline constexpr std::uint16_t kDisableVoltage = 0x0000;
inline constexpr std::uint16_t kQuickStop = 0x0002;
inline constexpr std::uint16_t kFaultReset = 0x0080;
/// Operation mode specific bit 4: in interpolated position mode, "enable ip mode".
inline constexpr std::uint16_t kEnableIpMode = 0x0010;
/// Bit 4 in homing mode: homing operation start (0 -> 1 starts, 1 -> 0 interrupts).
inline constexpr std::uint16_t kHomingStart = 0x0010;
}  // namespace controlword
/// Decodes bits 0-3 and 7 of a controlword (bit 7 counts as fault reset here; the edge is the
/// drive's business).
DriveCommand decode_command(std::uint16_t controlword);
/// The state a drive goes to on `command` in `state` (CiA 402 transitions 2-12, 15, 16), or
/// nullopt when the command does not apply there.
std::optional<DriveState> transition(DriveState state, DriveCommand command);

// --- PDOs ----------------------------------------------------------------------------------------
struct Rpdo1 {
  std::uint16_t controlword = 0;
  std::int32_t target_position = 0;  ///< [counts]
};
struct Rpdo2 {
  std::uint32_t outputs = 0;  ///< 0x60FE sub 1: lines 0..7 in bits 16..23
};
struct Tpdo1 {
  std::int32_t position_actual = 0;  ///< [counts]
  std::uint32_t inputs = 0;          ///< 0x60FD
};
struct Tpdo2 {
  std::uint16_t statusword = 0;
};
inline constexpr std::uint16_t kHomeSwitchBit = 1U << 2;
/// A drive's digital lines (inputs and outputs): 8, in bits 16..23 of 0x60FD and 0x60FE.
inline constexpr unsigned kUserLineShift = 16;
inline constexpr unsigned kUserLines = 8;
inline constexpr std::uint32_t kUserLineMask = 0xFFU << kUserLineShift;
/// The master refreshes each drive's outputs (RPDO2) at least this often [cycles], so that a
/// lost frame is repaired (a drive holds its outputs between RPDO2s).
inline constexpr std::uint64_t kOutputRefreshCycles = 50;
/// A drive sends its statusword (TPDO2) at least this often [ms] (its event timer), as well as
/// when it changes, so that a lost frame is repaired.
inline constexpr std::uint16_t kStatuswordEventTimerMs = 20;
can_frame encode(std::uint8_t node, const Rpdo1& pdo);
can_frame encode(std::uint8_t node, const Rpdo2& pdo);
can_frame encode(std::uint8_t node, const Tpdo1& pdo);
can_frame encode(std::uint8_t node, const Tpdo2& pdo);
/// Decode a PDO's payload; nullopt when the length is wrong.
std::optional<Rpdo1> decode_rpdo1(const can_frame& frame);
std::optional<Rpdo2> decode_rpdo2(const can_frame& frame);
std::optional<Tpdo1> decode_tpdo1(const can_frame& frame);
std::optional<Tpdo2> decode_tpdo2(const can_frame& frame);

// --- EMCY ----------------------------------------------------------------------------------------
namespace emcy {
inline constexpr std::uint16_t kErrorReset = 0x0000;
inline constexpr std::uint16_t kContinuousOverCurrent = 0x2310;
inline constexpr std::uint16_t kDeviceHardware = 0x5000;
inline constexpr std::uint16_t kPositionSensor = 0x7305;  ///< incremental sensor 1 fault
inline constexpr std::uint16_t kCommunication = 0x8100;   ///< communication (SYNC lost)
inline constexpr std::uint16_t kHeartbeatError = 0x8130;  ///< life guard / heartbeat error
inline constexpr std::uint16_t kRecoveredFromBusOff = 0x8140;
inline constexpr std::uint16_t kFollowingError = 0x8611;
}  // namespace emcy
struct Emergency {
  std::uint16_t code = 0;
  std::uint8_t error_register = 0;
  std::array<std::uint8_t, 5> manufacturer{};
};
can_frame encode_emcy(std::uint8_t node, const Emergency& emergency);
std::optional<Emergency> decode_emcy(const can_frame& frame);
/// A short English description of an EMCY error code ("following error", ...).
std::string_view describe_emcy(std::uint16_t code);

// --- SDO (expedited transfers only: values of up to 4 bytes) -----------------------------------
namespace sdo_abort {
inline constexpr std::uint32_t kToggleBit = 0x05030000;
inline constexpr std::uint32_t kTimeout = 0x05040000;
inline constexpr std::uint32_t kCommandSpecifier = 0x05040001;
inline constexpr std::uint32_t kReadOnly = 0x06010002;
inline constexpr std::uint32_t kUnsupportedAccess = 0x06010000;
inline constexpr std::uint32_t kWriteOnly = 0x06010001;
inline constexpr std::uint32_t kNoObject = 0x06020000;
inline constexpr std::uint32_t kNotMappable = 0x06040041;
inline constexpr std::uint32_t kPdoTooLong = 0x06040042;
inline constexpr std::uint32_t kOutOfMemory = 0x05040005;
inline constexpr std::uint32_t kLengthMismatch = 0x06070010;
inline constexpr std::uint32_t kLengthTooHigh = 0x06070012;
inline constexpr std::uint32_t kLengthTooLow = 0x06070013;
inline constexpr std::uint32_t kNoSubindex = 0x06090011;
inline constexpr std::uint32_t kValueRange = 0x06090030;
inline constexpr std::uint32_t kValueTooHigh = 0x06090031;
inline constexpr std::uint32_t kValueTooLow = 0x06090032;
inline constexpr std::uint32_t kDeviceState = 0x08000022;
}  // namespace sdo_abort
std::string_view describe_sdo_abort(std::uint32_t code);

struct SdoRequest {
  bool write = false;  ///< download (write) or upload (read)
  std::uint16_t index = 0;
  std::uint8_t subindex = 0;
  std::uint32_t value = 0;  ///< for a write
  std::uint8_t size = 0;    ///< bytes of value for a write (1, 2 or 4)
};
struct SdoResponse {
  std::uint16_t index = 0;
  std::uint8_t subindex = 0;
  bool abort = false;
  std::uint32_t abort_code = 0;
  std::uint32_t value = 0;  ///< for an upload response
  std::uint8_t size = 0;
  bool write_confirmed = false;  ///< download response
};
can_frame encode_request(std::uint8_t node, const SdoRequest& request);
can_frame encode_response(std::uint8_t node, const SdoResponse& response);
/// nullopt for a frame that is no expedited SDO request the server understands (a segmented
/// transfer, bad length): the caller answers with an abort (kCommandSpecifier).
std::optional<SdoRequest> decode_request(const can_frame& frame);
std::optional<SdoResponse> decode_response(const can_frame& frame);

// --- Bus load
// --------------------------------------------------------------------------------------
/// Bits on the wire of a classical base-format frame with `bytes` data bytes, including the
/// 3-bit interframe space: nominal (no stuff bits) and worst case (every possible stuff bit).
struct FrameBits {
  int nominal = 0;
  int worst = 0;
};
FrameBits frame_bits(int bytes);
/// Bus load of one robot's cyclic traffic: one SYNC, an RPDO1 and a TPDO1 per axis each cycle,
/// plus heartbeats and, with `output_refresh`, the outputs' refresh (an RPDO2 per axis every
/// kOutputRefreshCycles cycles) and the statusword's refresh (a TPDO2 per axis every
/// kStatuswordEventTimerMs), all averaged over the cycles. A change of the outputs or of a
/// statusword adds one RPDO2 or TPDO2 per drive concerned, in that cycle only; it is not
/// counted. Loads are
/// fractions of the bus' capacity (0.7 = 70 %).
struct BusLoad {
  int frames_per_cycle = 0;
  double bits_per_cycle_nominal = 0.0;
  double bits_per_cycle_worst = 0.0;
  double load_nominal = 0.0;
  double load_worst = 0.0;
};
BusLoad cyclic_bus_load(std::size_t axes, double period_s, double bitrate_bps,
                        double heartbeat_period_s, bool output_refresh = true);
/// Largest worst-case load the EDP accepts without a warning (see docs/hil.md).
inline constexpr double kRecommendedMaxLoad = 0.70;

}  // namespace mrroc::can::canopen
