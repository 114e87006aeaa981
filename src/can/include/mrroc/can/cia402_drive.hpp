#pragma once
/// @file
/// One emulated CiA 402 servo drive: the slave side of mrroc's drive protocol (canopen.hpp).
///
/// The drive is pure protocol and drive logic; the axis it moves is someone else's (the cell
/// emulator's MuJoCo world, or a simple model in a test). Each physics step the owner samples the
/// axis into an `AxisSample`, calls `update()`, and servoes the axis to `demand()` (with
/// `demand_velocity()` as feed-forward) while `powered()`; when not powered the holding brake is
/// applied (the owner holds the axis where `demand()` says: the position where the brake fell in).
///
/// Behaviour:
///  - NMT: boot-up message at power-on, then pre-operational (SDO only); start -> operational
///    (PDOs, SYNC); stop; reset node (back to power-on) and reset communication.
///  - Its object dictionary is its EDS/DCF (`DriveConfig::eds`, eds.hpp; mrroc's emulated drive,
///    configs/drives/emu-csp.eds, when none is given): the objects that exist, their access,
///    type, limits and defaults, its PDOs' default mappings and the modes it supports (0x6502).
///    SDO (expedited; segmented upload and download of strings, up to kMaxSegmentedBytes)
///    answers as a device does: abort 0x06020000
///    for an object the file lacks, 0x06090011 a sub-index, 0x06010002 a write of a read-only
///    object, 0x06010001 a read of a write-only one, 0x06070010 a wrong length, 0x06090031 /
///    0x06090032 a value above / below the file's limits, 0x06040041 a mapping of an object that
///    cannot be mapped, 0x06040042 a mapping longer than 64 bits, 0x06010000 a mapping changed
///    while its PDO is on or its count is not 0 (CiA 301's order: COB-ID bit 31, count 0,
///    entries, count, COB-ID), 0x06090030 a mode the file does not list. A segmented download:
///    0x05030000 a segment whose toggle bit did not alternate, 0x05040001 a segment without an
///    initiation, 0x06070012 / 0x06070013 more / fewer bytes than announced (or than a number's
///    length), 0x05040005 more than kMaxSegmentedBytes.
///  - PDOs as their communication and mapping objects say (any number, any mapping of up to 64
///    bits): RPDOs of transmission type 0..240 take effect at the next SYNC, 254/255 at once;
///    TPDOs of type 1..240 are sampled and sent every n-th SYNC, type 0 at a SYNC when their data
///    changed, 254/255 when their data changed (no sooner than the inhibit time, sub 3) and when
///    the event timer (sub 5) runs out.
///  - CiA 402 device control (transitions 2-12, 15, 16). Modes that move the axis: 8 (cyclic
///    synchronous position, target 0x607A), 9 (cyclic synchronous velocity, 0x60FF), 7
///    (interpolated position, target 0x60C1 sub 1, while controlword bit 4 "enable ip mode" is
///    set) and 6 (homing, below); in the other modes the file lists the drive holds its
///    position.
///  - CSP and IP: at each SYNC the demand moves linearly from the previous target to the new one
///    over one interpolation period (0x60C2), so the axis follows a ramp, not steps.
///  - Monitors (operation enabled): following error |demand - actual| > 0x6065 counts for longer
///    than 0x6066 ms -> fault, EMCY 0x8611; |force| above the current limit for longer than
///    `over_current_time_s` -> fault, EMCY 0x2310. A fault stops the axis (brake) at once.
///  - Supervision of the master (CiA 301), while the node is NMT operational:
///    heartbeat consumer 0x1016 sub 1 (producer node << 16 | time ms; armed by the first
///    heartbeat of that node, re-armed by the next one): no heartbeat for longer than the time ->
///    EMCY 0x8130; SYNC supervision with 0x1006 (cycle period, us; armed by the first SYNC):
///    no SYNC for longer than `sync_loss_periods` periods, and never less than the heartbeat
///    consumer time -> EMCY 0x8100. Either communication
///    error then changes the NMT state as 0x1029 sub 1 says (0 pre-operational, 1 none,
///    2 stopped) and, in operation enabled, reacts as 0x6007 says (0 none, 1 fault (brake),
///    2 disable voltage (brake), 3 quick stop as 0x605A says). Never configured (0x1016 sub 1 = 0,
///    0x1006 = 0, the power-on values) the drive is not supervised, as a real one: the master
///    writes and reads back these objects at bring-up.
///  - Quick stop: the demand decelerates at 0x6085 from the axis' velocity to standstill; then
///    quick stop option code 0x605A 6 holds in quick stop active (until enable operation or
///    disable voltage), 2 goes to switch on disabled (brake).
///  - Homing (mode 6, where the file's 0x6502 lists it): controlword bit 4 from 0 to 1 in
///    operation enabled starts the method in 0x6098, at the speeds 0x6099 sub 1 (search for the
///    switch) and sub 2 (search for zero) and the acceleration 0x609A; at the home point the
///    position becomes the home offset 0x607C. Methods 19 and 20 (home switch on the positive
///    side: the home point where it goes off moving down, or on moving up), 21 and 22 (the same
///    on the negative side), each starting in the direction the switch's state says (the axis'
///    home switch, 0x60FD bit 2), the last approach at the zero search speed; the axis then
///    returns to the home point and stops there. 35 and 37: the position where the axis stands is
///    the home point (nothing moves). Other methods are refused (SDO abort 0x06090030): the
///    axis has no limit switches (17, 18) and no index pulse. Statusword in homing mode: bit 12
///    homing attained, bit 13 homing error, bit 10 target reached (at standstill, not homing);
///    a search that travels farther than `DriveConfig::homing_search_range` without its edge is a
///    homing error (the axis ramps down and stops). Bit 4 back to 0 interrupts the homing (the
///    axis ramps down); leaving operation enabled (quick stop, fault) ends it.
///  - Digital lines: 0x60FD shows the home switch and the axis' 8 input lines
///    (`AxisSample::input_lines`); 0x60FE sub 1 and sub 2 (outputs and their mask, by SDO or
///    PDO), where the file has it, set the 8 output lines (`output_lines()`).
///    Outputs hold through faults and communication errors; power-on and NMT reset node clear
///    them and their mask.
///  - Heartbeat every 0x1017 ms when non-zero.
///  - Fault injection: `inject_fault(code)` (drive fault with that EMCY code), `set_silent(true)`
///    (the node neither sends nor receives: a dead or disconnected node).
#include <linux/can.h>

#include <array>
#include <cstdint>
#include <functional>
#include <limits>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "mrroc/can/canopen.hpp"
#include "mrroc/can/drive_setup.hpp"
#include "mrroc/can/eds.hpp"
#include "mrroc/core/time.hpp"

namespace mrroc::can {

struct DriveConfig {
  std::uint8_t node = 1;  ///< node id 1..127
  /// The drive's EDS/DCF; null: mrroc's emulated drive (default_drive_eds()).
  std::shared_ptr<const eds::Dictionary> eds;
  double counts_per_unit = 100000.0;              ///< encoder counts per rad (or per m)
  std::uint32_t following_error_window = 20000;   ///< [counts] (0x6065; 0 switches it off)
  std::uint16_t following_error_timeout_ms = 10;  ///< 0x6066
  double current_limit = std::numeric_limits<double>::infinity();  ///< |force| limit [N m or N]
  double over_current_time_s = 0.05;     ///< how long the limit may be exceeded
  double quick_stop_deceleration = 5.0;  ///< [units/s^2] (0x6085 is in counts/s^2)
  /// 0x60C2 (the master sets it to its cycle)
  double interpolation_period_s = kDefaultServoPeriodS;
  /// SYNC supervision: no SYNC for this many 0x1006 periods, and for no less than the
  /// heartbeat consumer time 0x1016 the master set, is a communication error. A drive's own
  /// (manufacturer) setting; the master's consumer time makes the two supervisions agree (a
  /// master stalled by its host stops both its heartbeat and its SYNCs).
  double sync_loss_periods = 25.0;
  /// Homing: the farthest a search for the switch's edge travels before the drive reports a
  /// homing error [units] (a real drive's manufacturer-specific limit).
  double homing_search_range = 2.0;
};

/// What the owner samples from the axis every physics step.
struct AxisSample {
  double position = 0.0;  ///< [rad or m], the axis' own coordinate
  double velocity = 0.0;  ///< [units/s]
  double force = 0.0;     ///< motor torque or force [N m or N]
  bool home_switch = false;
  std::uint8_t input_lines = 0;  ///< the drive's digital input lines 0..7 (bit k = line k)
};

class Cia402Drive {
 public:
  using Output = std::function<void(const can_frame&)>;
  /// The longest value a segmented download may carry [bytes].
  static constexpr std::size_t kMaxSegmentedBytes = 1024;

  Cia402Drive(const DriveConfig& config, Output output);

  /// Powers the drive: the encoder counts from `sample.position` (incremental encoder), boot-up
  /// message, NMT pre-operational, switch on disabled.
  void power_on(const AxisSample& sample, double now_s);
  /// Every frame seen on the bus (the drive picks what concerns it).
  void on_frame(const can_frame& frame, double now_s);
  /// Once per physics step, after sampling the axis.
  void update(const AxisSample& sample, double now_s);

  /// Position the axis should be at now [units] (servo target, or the brake's hold position).
  [[nodiscard]] double demand() const noexcept { return demand_; }
  /// Velocity feed-forward for the demand [units/s] (0 when not powered).
  [[nodiscard]] double demand_velocity() const noexcept {
    return powered() ? demand_velocity_ : 0.0;
  }
  /// Motor torque on (operation enabled or quick stop active); otherwise the brake holds.
  [[nodiscard]] bool powered() const noexcept;

  [[nodiscard]] canopen::DriveState state() const noexcept { return state_; }
  [[nodiscard]] canopen::NmtState nmt_state() const noexcept { return nmt_; }
  [[nodiscard]] std::uint16_t statusword() const noexcept;
  [[nodiscard]] std::uint8_t node() const noexcept { return config_.node; }
  /// The drive's EDS/DCF.
  [[nodiscard]] const eds::Dictionary& description() const noexcept { return *eds_; }
  [[nodiscard]] std::uint16_t last_emcy() const noexcept { return last_emcy_; }
  [[nodiscard]] std::uint64_t syncs() const noexcept { return syncs_; }
  /// EMCY code of the last communication error the supervision reacted to (0x8130 heartbeat,
  /// 0x8100 SYNC lost), 0 when none since the drive was last enabled or powered on.
  [[nodiscard]] std::uint16_t communication_error() const noexcept { return comm_error_; }
  /// When that error was detected [s] (the time base of `update`).
  [[nodiscard]] double communication_error_at() const noexcept { return comm_error_at_s_; }
  /// Interpolation period (0x60C2) [s]: the master's cycle.
  [[nodiscard]] double interpolation_period_s() const noexcept {
    return config_.interpolation_period_s;
  }
  [[nodiscard]] std::int32_t counts(double position) const noexcept;
  /// The output lines the drive drives (bit k = line k): 0x60FE sub 1 under its mask sub 2.
  [[nodiscard]] std::uint8_t output_lines() const noexcept {
    return static_cast<std::uint8_t>((outputs_ & output_mask_ & canopen::kUserLineMask) >>
                                     canopen::kUserLineShift);
  }
  /// 0x60FD as the drive reports it now.
  [[nodiscard]] std::uint32_t digital_inputs() const noexcept;

  /// Drive fault with an EMCY code (e.g. canopen::emcy::kDeviceHardware).
  void inject_fault(std::uint16_t code, double now_s);
  /// A silent node sends nothing and ignores every frame.
  void set_silent(bool silent) noexcept { silent_ = silent; }
  [[nodiscard]] bool silent() const noexcept { return silent_; }

 private:
  void send(const can_frame& frame);
  void enter(canopen::DriveState state, double now_s);
  void fault(std::uint16_t code, double now_s);
  void apply_controlword(std::uint16_t controlword, double now_s);
  /// The controlword's device control command (bits 0-3, 7).
  void apply_state_command(std::uint16_t controlword, bool reset_edge, double now_s);
  void on_sync(double now_s);
  void on_sdo(const can_frame& frame, double now_s);
  void on_nmt(const can_frame& frame, double now_s);
  void on_heartbeat(const can_frame& frame, double now_s);
  void communication_error(std::uint16_t code, double now_s);
  void reset_communication_objects() noexcept;
  [[nodiscard]] double position_of(std::int32_t counts) const noexcept;
  /// Homing (mode 6): starts the method in 0x6098 (controlword bit 4 rising).
  void start_homing(double now_s);
  /// One physics step of the homing motion (operation enabled, mode 6).
  void homing_step(double dt);

  /// A PDO that is on (COB-ID bit 31 clear), as its communication and mapping objects say.
  struct ActivePdo {
    int number = 0;
    canid_t id = 0;
    std::uint8_t transmission = 0;
    double inhibit_s = 0.0;
    double event_timer_s = 0.0;
    std::vector<PdoEntry> entries;
    bool pending = false;  ///< RPDO: received since the last SYNC
    can_frame frame{};     ///< RPDO: the one received; TPDO: the one last sent
    std::uint32_t syncs = 0;
    bool sent = false;
    double last_sent_s = 0.0;
  };
  /// The object's value now: the drive's state for the objects it acts on, else the stored one.
  [[nodiscard]] std::uint64_t read_object(std::uint16_t index, std::uint8_t sub) const;
  /// Writes an object (SDO or RPDO; checked against the file by the SDO server already): the
  /// drive acts on it, or stores it. Returns an SDO abort code, 0 when written.
  std::uint32_t write_object(std::uint16_t index, std::uint8_t sub, std::uint64_t raw,
                             double now_s);
  /// The mapping rules of CiA 301 for a write to a PDO's objects; 0 when allowed.
  [[nodiscard]] std::uint32_t check_pdo_write(std::uint16_t index, std::uint8_t sub,
                                              std::uint64_t raw) const;
  [[nodiscard]] bool mappable(const PdoEntry& entry, bool receive) const;
  /// Every object to its file's value (the communication objects 0x1000..0x1FFF only, or all).
  void reset_store(bool communication_only);
  void refresh_pdos();
  void apply_rpdo(const ActivePdo& pdo, const can_frame& frame, double now_s);
  void send_tpdo(ActivePdo& pdo, double now_s, bool only_if_changed);
  [[nodiscard]] std::uint64_t stored(std::uint16_t index, std::uint8_t sub) const;
  void upload_segment(const can_frame& frame);
  /// A segmented download (CiA 301): its initiation, and each segment.
  void initiate_download(const can_frame& frame, double now_s);
  void download_segment(const can_frame& frame, double now_s);
  /// Stores a downloaded value (a string, or a number of the object's length); 0 or an abort.
  std::uint32_t store_download(std::uint16_t index, std::uint8_t sub, const std::string& data,
                               double now_s);
  /// The text of a string object: written by SDO, else the file's.
  [[nodiscard]] std::string text_of(std::uint16_t index, std::uint8_t sub) const;

  DriveConfig config_;
  Output output_;
  std::shared_ptr<const eds::Dictionary> eds_;
  std::map<std::uint32_t, std::uint64_t> store_;  ///< index << 8 | sub
  std::vector<ActivePdo> rpdos_;
  std::vector<ActivePdo> tpdos_;
  /// A segmented upload in progress (strings): its data, how much is sent, the toggle bit.
  std::string upload_;
  std::size_t upload_at_ = 0;
  bool upload_toggle_ = false;
  bool uploading_ = false;
  /// A segmented download in progress: its object, the bytes so far, the size announced (0:
  /// none), the toggle bit the next segment must carry.
  std::uint16_t download_index_ = 0;
  std::uint8_t download_sub_ = 0;
  std::string download_;
  std::size_t download_size_ = 0;
  bool download_toggle_ = false;
  bool downloading_ = false;
  /// String objects written by SDO (index << 8 | sub); the file's value until then.
  std::map<std::uint32_t, std::string> texts_;
  std::uint32_t supported_modes_ = 0;

  canopen::NmtState nmt_ = canopen::NmtState::boot_up;
  canopen::DriveState state_ = canopen::DriveState::not_ready_to_switch_on;
  bool silent_ = false;
  double zero_ = 0.0;  ///< axis position at power-on (encoder zero) [units]
  AxisSample sample_{};
  std::uint32_t outputs_ = 0;      ///< 0x60FE sub 1
  std::uint32_t output_mask_ = 0;  ///< 0x60FE sub 2
  std::uint16_t controlword_ = 0;
  std::int8_t mode_ = canopen::kModeCyclicSyncPosition;
  std::int32_t target_ = 0;
  bool target_valid_ = false;
  /// Cyclic synchronous velocity: 0x60FF [counts/s], applied at each SYNC.
  std::int32_t target_velocity_ = 0;
  // Interpolation from `from_` to `to_` starting at `segment_start_s_`.
  double from_ = 0.0;
  double to_ = 0.0;
  double segment_start_s_ = 0.0;
  double demand_ = 0.0;
  double demand_velocity_ = 0.0;
  double last_update_s_ = 0.0;
  double last_sync_s_ = 0.0;
  double following_error_since_s_ = -1.0;
  double over_current_since_s_ = -1.0;
  bool following_error_ = false;
  /// Homing (mode 6): what the homing motion is doing.
  enum class HomingPhase : std::uint8_t {
    idle,      ///< not started, or attained
    search,    ///< at the switch search speed, away from the final approach's direction
    reverse,   ///< ramping down before the final approach
    approach,  ///< at the zero search speed towards the switch's edge
    settle,    ///< back to the home point, to stop there
    stopping,  ///< interrupted or failed: ramping down
  };
  HomingPhase homing_phase_ = HomingPhase::idle;
  bool homing_attained_ = false;       ///< statusword bit 12
  bool homing_error_ = false;          ///< statusword bit 13
  double homing_direction_ = 1.0;      ///< of the final approach: +1 or -1
  bool homing_switch_before_ = false;  ///< the switch's state before the home point's edge
  double homing_start_ = 0.0;          ///< where the search began [units]
  double home_ = 0.0;                  ///< the home point [units]
  std::uint16_t heartbeat_ms_ = 0;
  double next_heartbeat_s_ = 0.0;
  std::uint16_t last_emcy_ = 0;
  std::uint64_t syncs_ = 0;
  // Supervision objects and state.
  std::uint32_t consumer_heartbeat_ = 0;                                        ///< 0x1016 sub 1
  std::uint32_t cycle_period_us_ = 0;                                           ///< 0x1006
  std::uint8_t error_behaviour_ = canopen::error_behaviour::kPreOperational;    ///< 0x1029 sub 1
  std::int16_t abort_connection_ = canopen::abort_connection::kFault;           ///< 0x6007
  std::int16_t quick_stop_option_ = canopen::quick_stop_option::kRampThenHold;  ///< 0x605A
  bool heartbeat_armed_ = false;
  double last_heartbeat_s_ = 0.0;
  bool sync_armed_ = false;
  std::uint16_t comm_error_ = 0;
  double comm_error_at_s_ = 0.0;
};

}  // namespace mrroc::can
