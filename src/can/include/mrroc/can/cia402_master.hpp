#pragma once
/// @file
/// The master side of mrroc's drive protocol (canopen.hpp): brings a robot's CiA 402 drives on
/// one CAN bus to operation enabled and streams cyclic synchronous positions to them (or, in
/// cyclic synchronous velocity, velocities made from the positions: kCsvCorrectionCycles).
///
/// Bring-up (`bring_up`, blocking, not for the servo loop), drive by drive, as each one's plan
/// (drive_setup.hpp, from its EDS/DCF) says: NMT reset communication and its boot-up message;
/// its device type (a CiA 402 drive) and, when the config gives one, its identity (0x1018);
/// its PDOs mapped by SDO (each read first, written only where it differs, read back), the
/// drive's other PDOs switched off; the mode (cyclic synchronous position, interpolated
/// position or cyclic synchronous velocity), the interpolation period (= the cycle), the
/// following-error window and time, the quick-stop deceleration and the heartbeat time, where the
/// drive has them; the config's own SDO writes; a drive in fault is reset. Then it starts the nodes
/// (NMT, each by its node id: never all nodes, so other drives on the bus keep their state) and
/// steps the drives through shutdown -> switch on -> enable operation with the target held at each
/// drive's actual position, so nothing moves.
///
/// Supervision (CiA 301/402): the master produces its own heartbeat (COB-ID 0x700 + `master_node`,
/// every `master_heartbeat_ms`, from `send` and while waiting for SDO answers) and bring-up makes
/// every drive a consumer of it and of the SYNC: 0x1016 sub 1 = master_node << 16 |
/// heartbeat_consumer_ms, 0x1006 = the cycle [us], 0x1029 sub 1 = 1 (a communication error
/// leaves the NMT state as it is, so the drive's TPDOs and EMCY still show what happened),
/// 0x6007 = 3 (quick stop on a communication error), 0x605A = 6 (quick stop ramps at 0x6085 and
/// holds). Each value is read back; a drive that does not keep it is refused. So a drive whose
/// master dies (no heartbeat, no SYNC) ramps to a standstill at its quick-stop deceleration.
///
/// Cycle (`receive` then `send`, from the servo loop; no allocation, no blocking): `receive`
/// drains the bus and checks each drive; `send` sends one RPDO1 per drive, an RPDO2 with its
/// digital outputs to each drive whose outputs changed (`set_outputs`) or whose refresh is due
/// (every canopen::kOutputRefreshCycles cycles, staggered over the drives), and then SYNC. A
/// drive answers each SYNC with a TPDO1, so `receive` in the next cycle sees positions and
/// digital inputs sampled at the last SYNC (one cycle old); its statusword comes in TPDO2, when
/// it changes and every canopen::kStatuswordEventTimerMs (bring-up reads it first by SDO).
/// That is mrroc's own mapping; with PDOs the config chooses (DriveRequest::pdos) the master
/// encodes and decodes every PDO by its plan's mapping: each RPDO with the controlword or the
/// target every cycle, one with only the outputs as RPDO2 above, and whatever TPDOs carry the
/// statusword, the position, the inputs (and velocity and torque actual values, DriveStatus).
///
/// Digital outputs (canopen.hpp), for the drives that have 0x60FE and unless
/// `MasterOptions::digital_lines` is false: bring-up maps RPDO2, writes each such drive's output
/// mask 0x60FE sub 2 (its 8 lines) and then its outputs sub 1 (the lines set so far, 0 at first)
/// and reads both back. `switch_outputs_off` (the EDP's exit) switches every drive's outputs off
/// by SDO.
///
/// Homing (`home`, blocking, from the thread that runs the cycle; the EDP's SYNCHRO of drives
/// whose plan has `homing`): the drive's own homing mode (CiA 402 mode 6) by the book, the cycle
/// going on meanwhile (see `home`).
///
/// Faults (after which `faulted()` is true and `fault_text()` says which drive, which axis and
/// why): an EMCY with a non-zero code; a statusword in fault; a drive that left operation enabled
/// by itself; no TPDO from a drive for `silent_cycles` cycles; the bus going bus-off (error frame
/// or failed send); a boot-up message from a drive (it rebooted and lost its configuration). On a
/// fault the master quick-stops every other drive.
#include <atomic>
#include <chrono>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "mrroc/can/bus.hpp"
#include "mrroc/can/canopen.hpp"
#include "mrroc/can/drive_setup.hpp"
#include "mrroc/core/time.hpp"

namespace mrroc::can {

/// One axis (one drive) of the robot.
struct MasterAxis {
  std::string name;                      ///< axis name, for messages
  std::uint8_t node = 1;                 ///< CANopen node id 1..127
  double counts_per_unit = 100000.0;     ///< encoder counts per rad (or m)
  std::string unit = "rad";              ///< of the axis' positions: "rad" or "m", for messages
  double quick_stop_deceleration = 5.0;  ///< [units/s^2]
  double following_error_window = 0.2;   ///< [units]
  std::uint16_t following_error_timeout_ms = 10;
  /// What to configure in the drive, from its EDS/DCF (plan_drive); without a file (plan.eds
  /// null) the master plans the drive from mrroc's emulated drive's file (default_drive_eds()).
  DrivePlan plan;
};

struct MasterOptions {
  /// cycle; must be a whole number of milliseconds (0x60C2)
  double period_s = kDefaultServoPeriodS;
  int silent_cycles = 10;  ///< cycles without a TPDO before a drive counts as silent
  std::chrono::milliseconds sdo_timeout{100};
  int sdo_attempts = 3;
  std::uint16_t heartbeat_ms = 100;  ///< producer heartbeat the drives are told to send
  std::uint8_t master_node = canopen::kDefaultMasterNode;  ///< node id of the master's heartbeat
  std::uint16_t master_heartbeat_ms = 10;  ///< the master's heartbeat period (1..1000 ms)
  /// Drives' heartbeat consumer time for the master (0x1016); must exceed master_heartbeat_ms.
  std::uint16_t heartbeat_consumer_ms = 50;
  /// Use the drives' digital output lines (RPDO2, 0x60FE) where they have them; false: none.
  bool digital_lines = true;
  /// How long a drive may take to send its boot-up message after NMT reset communication.
  std::chrono::milliseconds boot_up_timeout{1000};
};

/// What the master knows about one drive after `receive`.
struct DriveStatus {
  double position = 0.0;  ///< [units] from the encoder's zero (power-on), sampled at the last SYNC
  std::uint16_t statusword = 0;
  canopen::DriveState state = canopen::DriveState::not_ready_to_switch_on;
  bool home_switch = false;
  std::uint8_t input_lines = 0;  ///< the drive's 8 digital input lines (bit k = line k)
  /// cycle number of the last TPDO with the position (and the inputs, sampled with it)
  std::uint64_t last_tpdo_cycle = 0;
  /// The position [units] of the TPDO before the last one with it, and that TPDO's cycle (0:
  /// none yet): with the last, a velocity over the drive's last two samples, however many cycles
  /// passed between them and whether or not anyone read status() in between (a homing, a late
  /// TPDO).
  double previous_position = 0.0;
  std::uint64_t previous_tpdo_cycle = 0;
  std::uint64_t last_statusword_cycle = 0;  ///< cycle number of the last TPDO with the statusword
  std::uint16_t last_emcy = 0;
  /// 0x606C velocity actual value [units/s], where a TPDO maps it (else 0).
  double velocity_actual = 0.0;
  /// 0x6077 torque actual value [per mille of the rated torque], where a TPDO maps it (else 0).
  std::int16_t torque_actual = 0;
};

class Cia402Master {
 public:
  Cia402Master(Bus& bus, std::vector<MasterAxis> axes, const MasterOptions& options);

  /// Brings every drive to operation enabled at its actual position.
  /// @throws mrroc::HardwareError naming the bus, node, axis and the step that failed.
  void bring_up(std::chrono::milliseconds timeout);
  /// Homes every drive whose plan has `homing` by its own homing mode (CiA 402 mode 6), all of
  /// them at once; the other drives hold where they are. After `bring_up`, from the thread that
  /// runs the cycle; blocking for as long as the homing takes, while the cycle goes on every
  /// period (RPDOs with the held targets, SYNC, the master's heartbeat; one cycle between any two
  /// SDO transfers, so that no drive misses its SYNC). Per homing drive: SDO writes of 0x6098
  /// method, 0x6099 sub 1 and 2 speeds, 0x609A acceleration, 0x607C home offset (each read back);
  /// disable operation (switched on; the mode is changed out of operation enabled), 0x6060 = 6
  /// and 0x6061 read back; enable operation; controlword bit 4 from 0 to 1 (homing operation
  /// start); then it waits for statusword bit 12 (homing attained) with bit 10 (target reached),
  /// seen in a statusword the drive sent after the start. Then it disables operation again,
  /// writes the plan's mode (0x6061 read back) and enables operation with the target at the
  /// drive's actual position (the new reference: the home offset at the home point), so that
  /// nothing jumps.
  /// `stop` is read every cycle: once it is set, every drive is quick-stopped (the homing drives'
  /// quick stop ramps them down at 0x6085) and the homing fails.
  /// @throws mrroc::HardwareError naming the drive (bus, node, axis), the method and the time since
  /// the homing began, on statusword bit 13 (homing error), on the drive's `timeout_s`, on an SDO
  /// abort (a method the drive does not have: no motion), on a fault while homing (EMCY, fault
  /// state, silence, bus-off: its text, as every fault's), and on `stop` (these two name the first
  /// drive still homing, and the others still homing after the text). Then `faulted()` is
  /// true with the same text: the drives are quick-stopped and held, and a new `bring_up` (the
  /// EDP's SYNCHRO after a fault) is needed.
  void home(const std::atomic<bool>& stop);
  /// Whether any drive's plan asks for homing by the drive (`home`).
  [[nodiscard]] bool homes_by_drive() const noexcept;
  /// Inside `home` (the drives in homing mode or on the way there and back).
  [[nodiscard]] bool homing() const noexcept { return homing_; }

  /// Switches the output lines off (an SDO write of 0x60FE sub 1 to each drive that had lines on
  /// or to switch on; blocking, for
  /// the end of the controller's run: the drives hold their outputs otherwise). The lines given
  /// to `set_outputs` are kept and written again by the next bring-up. Never throws.
  void switch_outputs_off() noexcept;
  /// Disables the drives (brakes on) and sends them to NMT pre-operational (each of its own
  /// nodes, none other). Never throws.
  void shut_down() noexcept;

  /// Drains the bus; updates every drive's status; detects faults.
  void receive() noexcept;
  /// Each drive's RPDOs with its controlword and target [units from the encoder's zero] (and
  /// its outputs when they changed or are due), then SYNC.
  /// A target beyond the drive's position range (INTEGER32 counts) is a fault naming it, its
  /// unit and the range; the drive holds its last target.
  /// While `quick_stop` is set the drives are told to quick-stop (targets are ignored by them);
  /// clearing it re-enables them (the caller must then send targets at the actual positions).
  void send(std::span<const double> targets, bool quick_stop) noexcept;

  /// The drive's 8 digital output lines (bit k = line k), sent from the next `send` on.
  void set_outputs(std::size_t axis, std::uint8_t lines) noexcept { outputs_[axis] = lines; }
  /// The output lines last given to `set_outputs`.
  [[nodiscard]] std::uint8_t outputs(std::size_t axis) const noexcept { return outputs_[axis]; }

  [[nodiscard]] std::size_t axis_count() const noexcept { return axes_.size(); }
  /// The drive has digital outputs the master drives (0x60FE sub 1 mapped into an RPDO).
  [[nodiscard]] bool has_outputs(std::size_t axis) const noexcept {
    return options_.digital_lines && axes_[axis].plan.outputs;
  }
  [[nodiscard]] const DrivePlan& plan(std::size_t axis) const noexcept { return axes_[axis].plan; }
  /// What the last bring-up did to the drive, one line: "node 2 (axis 'lower_arm'): EMU-PP-3
  /// (emu-pp-split.eds), cyclic synchronous position; PDOs written: RPDO1, TPDO1, TPDO2; switched
  /// off: TPDO3".
  [[nodiscard]] const std::string& bring_up_report(std::size_t axis) const noexcept {
    return reports_[axis];
  }
  [[nodiscard]] const DriveStatus& status(std::size_t axis) const noexcept { return status_[axis]; }
  [[nodiscard]] bool faulted() const noexcept { return faulted_; }
  [[nodiscard]] const char* fault_text() const noexcept { return fault_; }
  [[nodiscard]] std::uint64_t cycle() const noexcept { return cycle_; }
  /// Cyclic synchronous velocity: the position correction's time constant, in cycles. Each
  /// cycle's velocity is the targets' difference over the period plus (where the drive should
  /// have been at the last SYNC - where it was) / (this many periods).
  static constexpr int kCsvCorrectionCycles = 8;
  /// Drives' velocity targets at the last `send` [counts/s] (cyclic synchronous velocity).
  [[nodiscard]] std::int32_t velocity_counts(std::size_t axis) const noexcept {
    return velocities_[axis];
  }
  /// Drives' targets at the last `send` [counts]; for tests.
  [[nodiscard]] std::int32_t target_counts(std::size_t axis) const noexcept {
    return targets_[axis];
  }

  /// Expedited SDO transfers (blocking; for bring-up and tools). @throws mrroc::HardwareError.
  std::uint32_t sdo_read(std::uint8_t node, std::uint16_t index, std::uint8_t subindex);
  void sdo_write(std::uint8_t node, std::uint16_t index, std::uint8_t subindex, std::uint32_t value,
                 std::uint8_t size);
  /// A value of any length (strings: 0x1008 device name, ...), segmented where it is longer than
  /// 4 bytes. @throws mrroc::HardwareError naming the abort code.
  std::string sdo_read_bytes(std::uint8_t node, std::uint16_t index, std::uint8_t subindex);
  /// Writes a value of any length (strings, domains): expedited up to 4 bytes, else segmented
  /// (CiA 301: initiate with the size, then segments of 7 bytes with alternating toggle bits).
  /// @throws mrroc::HardwareError naming the object, the segment and the abort code; the client
  /// aborts the transfer itself (0x05040000 time-out, 0x05030000 toggle bit) when the server
  /// answers late or out of order.
  void sdo_write_bytes(std::uint8_t node, std::uint16_t index, std::uint8_t subindex,
                       std::string_view data);

 private:
  void handle(const Received& frame) noexcept;
  /// One expedited SDO transfer with retries; frames of other kinds are handled meanwhile.
  canopen::SdoResponse sdo_transfer(std::uint8_t node, const canopen::SdoRequest& request);
  void set_fault(std::size_t axis, const char* what) noexcept;
  /// Bring-up of one drive over SDO (pre-operational).
  void configure_drive(std::size_t axis);
  void configure_pdo(std::size_t axis, const PdoPlan& pdo);
  void wait_boot_up(std::size_t axis);
  /// Sends `command` to each of this master's nodes, one NMT frame per node id in the axes'
  /// order: never to all nodes (node id 0), since the bus may carry other drives (another
  /// robot's, another master's).
  void nmt_own_nodes(canopen::NmtCommand command) noexcept;
  /// Writes and reads back; @throws naming the object and both values when they differ.
  void write_checked(std::size_t axis, std::uint16_t index, std::uint8_t sub, std::uint32_t value,
                     std::uint8_t size);
  /// Waits for one SDO response frame of `node` (other frames are handled meanwhile).
  bool sdo_frame(std::uint8_t node, can_frame& out);
  [[nodiscard]] std::string who(std::size_t axis) const;
  /// A position [units] in counts, or nullopt outside the drives' INTEGER32 range.
  [[nodiscard]] std::optional<std::int32_t> counts(std::size_t axis,
                                                   double position) const noexcept;
  /// A configured quantity in drive units, checked against the object's range.
  /// @throws HardwareError naming the quantity, its value, unit and the limit.
  [[nodiscard]] std::uint32_t unsigned_counts(std::size_t axis, const char* what, double value,
                                              const char* unit, std::uint16_t index) const;
  /// Decodes a TPDO of the axis' drive by its mapping (`handle`).
  void decode_tpdo(std::size_t axis, std::size_t pdo, const can_frame& frame) noexcept;
  /// The drive's statusword from a TPDO: its state, and a fault when it left operation enabled.
  void on_statusword(std::size_t axis, std::uint16_t statusword) noexcept;
  void cycle_once(std::uint16_t controlword, std::span<const std::int32_t> targets);
  /// Sends the master's heartbeat when it is due (no allocation, no blocking).
  void heartbeat_if_due() noexcept;
  /// One cycle of `home`: RPDOs (the homing drives' controlwords from controlword_override_,
  /// the others enable operation, or quick stop when `quick_stop`), SYNC, a period's sleep, then
  /// `receive`.
  void homing_cycle(bool quick_stop);

  /// What the master puts into an RPDO entry or takes from a TPDO entry.
  enum class Role : std::uint8_t {
    none,  ///< mapped by the config and not used by the servo loop: decoded and ignored
    controlword,
    target,
    outputs,
    statusword,
    position,
    inputs,
    velocity,
    torque,
  };
  struct Field {
    Role role = Role::none;
    std::uint8_t shift = 0;  ///< bit offset in the frame's data
    std::uint8_t bits = 0;
    bool is_signed = false;
  };
  /// One mapped PDO of a drive, laid out once (no allocation in the cycle).
  struct Layout {
    canid_t id = 0;
    std::uint8_t bytes = 0;
    bool cyclic = false;   ///< RPDO with the controlword or target: sent every cycle
    bool outputs = false;  ///< RPDO with the digital outputs
    std::vector<Field> fields;
  };
  [[nodiscard]] static std::vector<Layout> layouts(const DrivePlan& plan, bool receive);

  Bus& bus_;
  std::vector<MasterAxis> axes_;
  std::vector<std::vector<Layout>> rpdo_layouts_;  ///< per axis
  std::vector<std::vector<Layout>> tpdo_layouts_;  ///< per axis
  MasterOptions options_;
  std::vector<DriveStatus> status_;
  std::vector<std::int32_t> targets_;
  /// Cyclic synchronous velocity: the velocity each drive gets [counts/s] (0 at bring-up, in a
  /// quick stop, at re-enabling), and the last two position targets it came from [units].
  std::vector<std::int32_t> velocities_;
  std::vector<double> last_target_;
  std::vector<double> target_before_;
  std::vector<std::int32_t> held_;     ///< bring-up / re-enable: targets at the actual positions
  std::vector<std::uint8_t> outputs_;  ///< digital output lines to send
  std::vector<std::int16_t> sent_outputs_;  ///< the lines last sent (-1: none yet)
  std::vector<std::uint16_t> enable_command_;
  std::vector<std::string> reports_;
  std::vector<std::string> written_;       ///< bring-up: the PDOs written, of the drive in hand
  std::vector<std::string> switched_off_;  ///< bring-up: the drive's PDOs switched off  ///< enable
                                           ///< operation (+ enable ip mode in IP)
  std::uint64_t cycle_ = 0;
  bool faulted_ = false;
  bool quick_stopping_ = false;
  /// After a quick stop is released: TPDOs sent before the drives saw the re-enable still report
  /// quick stop active; they are accepted until this cycle (excluded).
  std::uint64_t quick_stop_grace_until_ = 0;
  bool enabled_ = false;  ///< bring-up done: drives are expected in operation enabled
  bool homing_ = false;   ///< inside `home`
  /// `home`: the controlword each homing drive gets (-1: the cycle's own).
  std::vector<std::int32_t> controlword_override_;
  /// `home`: the drive is homing (it may leave operation enabled; the master steps it so).
  std::vector<std::uint8_t> homing_axis_;
  std::chrono::steady_clock::time_point next_heartbeat_{};
  char fault_[256] = {};
};

}  // namespace mrroc::can
