#pragma once
/// @file
/// What the master configures in one drive, planned from the drive's EDS/DCF (eds.hpp) and the
/// process set's config, and checked against the file before anything is sent.
///
/// The master maps, by SDO at bring-up (CiA 301: COB-ID invalid, mapping count 0, entries,
/// count, transmission type, COB-ID valid; each read back), whatever the drive's defaults are:
///   RPDO1  controlword 0x6040 + the position target: 0x607A (cyclic synchronous position) or
///          0x60C1 sub 1 (interpolated position); synchronous (type 1), every cycle.
///   RPDO2  digital outputs 0x60FE sub 1, when the drive has them; synchronous, sent when the
///          outputs change and every canopen::kOutputRefreshCycles cycles.
///   TPDO1  position actual value 0x6064 + digital inputs 0x60FD (all 32 bits: bit 2 home
///          switch, bits 16..23 the drive's input lines); synchronous, every SYNC: the home
///          switch's edge comes with the position it was sampled at (the EDP's synchronisation
///          takes the axis' offset from that pair).
///   TPDO2  statusword 0x6041; event-driven (type 255): sent when it changes, and at least every
///          canopen::kStatuswordEventTimerMs (its event timer, sub 5), so that a frame lost on
///          the way is repaired.
/// A PDO already configured so (the drive's defaults, or a DCF) is only read, not written. Every
/// other RPDO and TPDO of the drive is switched off (COB-ID bit 31), so that a drive's default
/// TPDOs do not load the bus. COB-IDs are the predefined connection set's (0x200 + node,
/// 0x300 + node, 0x180 + node, 0x280 + node).
///
/// The config may choose a drive's RPDOs or TPDOs instead (DriveRequest::pdos, the `can`
/// plugin's `rpdo` and `tpdo` rows): each is checked against the file at its row (the PDO and
/// the objects exist, the objects can be mapped, RPDO entries writable and TPDO entries
/// readable, their widths, at most 64 bits, valid transmission types and COB-IDs), RPDOs map only
/// what the master sends (controlword, the mode's target, digital outputs), and what the servo
/// loop needs must be mapped somewhere (controlword and target; statusword, position actual and
/// digital inputs, the last two every SYNC; the outputs when used).
///
/// Objects the master needs from every drive: 0x1000, 0x1016 sub 1, 0x1017, 0x6040, 0x6041,
/// 0x6060, 0x6064, 0x60FD (home switch) and the target of the mode, all of them mappable where
/// they are mapped; the PDO objects (0x1400/0x1600 x 1..2, 0x1800/0x1A00 x 1..2) with room for
/// two entries, and TPDO2's event timer (0x1801 sub 5). Used when present (and then checked):
/// 0x1006, 0x1029 sub 1, 0x6007, 0x605A, 0x6065, 0x6066, 0x6085, 0x60C2, 0x60FE. With homing by
/// the drive (DriveRequest::homing): 0x6098, 0x6099 sub 1 and 2, 0x609A, 0x607C (writable),
/// 0x6061 (readable), and homing (bit 5) in the file's 0x6502.
#include <array>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "mrroc/can/canopen.hpp"
#include "mrroc/can/eds.hpp"
#include "mrroc/core/error.hpp"

namespace mrroc::can {

/// One mapped object: index << 16 | sub << 8 | bits, as mapping entries are written.
struct PdoEntry {
  std::uint16_t index = 0;
  std::uint8_t sub = 0;
  std::uint8_t bits = 0;
  [[nodiscard]] std::uint32_t raw() const noexcept {
    return (static_cast<std::uint32_t>(index) << 16U) | (static_cast<std::uint32_t>(sub) << 8U) |
           bits;
  }
  static PdoEntry from_raw(std::uint32_t raw) noexcept {
    return {static_cast<std::uint16_t>(raw >> 16U), static_cast<std::uint8_t>(raw >> 8U),
            static_cast<std::uint8_t>(raw)};
  }
  bool operator==(const PdoEntry&) const = default;
};

/// PDO transmission types (0x1400/0x1800 sub 2).
namespace transmission {
inline constexpr std::uint8_t kSyncAcyclic = 0;  ///< at a SYNC, when the data changed
inline constexpr std::uint8_t kSyncEvery = 1;    ///< every SYNC (1..240: every n-th)
inline constexpr std::uint8_t kEventManufacturer = 254;
inline constexpr std::uint8_t kEventProfile = 255;
}  // namespace transmission
/// COB-ID bit 31: the PDO does not exist (switched off).
inline constexpr std::uint32_t kPdoInvalid = 0x80000000U;

struct PdoPlan {
  bool receive = false;  ///< RPDO (master -> drive) or TPDO
  int number = 1;        ///< 1-based
  std::uint32_t cob_id = 0;
  std::uint8_t transmission = transmission::kSyncEvery;
  std::uint16_t event_timer_ms = 0;  ///< TPDO of type 254/255: sub 5 (0: none)
  std::vector<PdoEntry> entries;
  SourceLocation where;  ///< the config's row that chose it (none: mrroc's own plan)
  [[nodiscard]] std::uint16_t communication_index() const noexcept {
    return static_cast<std::uint16_t>((receive ? 0x1400 : 0x1800) + number - 1);
  }
  [[nodiscard]] std::uint16_t mapping_index() const noexcept {
    return static_cast<std::uint16_t>((receive ? 0x1600 : 0x1A00) + number - 1);
  }
  /// "RPDO1", "TPDO2"
  [[nodiscard]] std::string name() const;
  /// Whether the PDO maps the object (any width).
  [[nodiscard]] bool maps(std::uint16_t index, std::uint8_t sub = 0) const noexcept {
    for (const PdoEntry& e : entries)
      if (e.index == index && e.sub == sub) return true;
    return false;
  }
  /// Its length on the bus [bytes]: the entries' bits rounded up.
  [[nodiscard]] int bytes() const noexcept {
    int bits = 0;
    for (const PdoEntry& e : entries) bits += e.bits;
    return (bits + 7) / 8;
  }
};

struct DriveIdentity {
  std::uint32_t vendor = 0;
  std::uint32_t product = 0;
  std::optional<std::uint32_t> revision;
};

/// An SDO write the config asks for at bring-up (after the master's own, before enabling).
struct SdoWrite {
  std::uint16_t index = 0;
  std::uint8_t sub = 0;
  std::uint64_t value = 0;
  std::uint8_t size = 0;  ///< bytes, from the object's type in the EDS
  SourceLocation where;   ///< in the config
  /// A string or domain object's value (written segmented when longer than 4 bytes); `value`
  /// and `size` are then unused.
  std::optional<std::string> text;
};

/// One PDO as the config chooses it (the `rpdo` and `tpdo` rows of the `can` plugin): its
/// entries replace mrroc's own mapping of the drive's RPDOs (or TPDOs).
struct PdoRequest {
  bool receive = false;  ///< RPDO or TPDO
  int number = 1;        ///< 1..512
  /// COB-ID: 0 picks the predefined connection set's (PDOs 1..4 only).
  std::uint32_t cob_id = 0;
  std::uint8_t transmission = transmission::kSyncEvery;
  std::uint16_t event_timer_ms = 0;  ///< TPDOs of type 254/255 only
  /// Entries; bits 0: the object's width from the file.
  std::vector<PdoEntry> entries;
  SourceLocation where;  ///< the row in the config
};

/// The drive's own homing (CiA 402 homing mode 6) as the robot's SYNCHRO, as the config asks
/// for it (the `can` plugin's `homing` rows), in the robot's units. plan_drive converts the values
/// to counts with `counts_per_unit` and checks them against the drive's file.
struct HomingRequest {
  std::int64_t method = 0;    ///< CiA 402 homing method (0x6098, INTEGER8): 19..22, 35, 37, ...
  double switch_speed = 0.0;  ///< speed during the search for the switch [units/s] (0x6099 sub 1)
  double zero_speed = 0.0;    ///< speed during the search for zero [units/s] (0x6099 sub 2)
  double acceleration = 0.0;  ///< homing acceleration [units/s^2] (0x609A)
  double offset = 0.0;        ///< home offset [units] (0x607C): the position at the home point
  double timeout_s = 0.0;     ///< the longest the master waits for homing attained [s]
  double counts_per_unit = 100000.0;  ///< the drive's encoder counts per unit
  std::string unit = "rad";           ///< of the axis: "rad" or "m", for messages
  SourceLocation where;               ///< the row in the config
};

/// The drive's homing in drive units, checked against its file (DrivePlan::homing).
struct HomingPlan {
  std::int8_t method = 0;
  std::uint32_t switch_speed = 0;  ///< [counts/s] 0x6099 sub 1
  std::uint32_t zero_speed = 0;    ///< [counts/s] 0x6099 sub 2
  std::uint32_t acceleration = 0;  ///< [counts/s^2] 0x609A
  std::int32_t offset = 0;         ///< [counts] 0x607C
  double timeout_s = 0.0;
  SourceLocation where;
};

/// The longest text an SDO write of the config may carry [bytes].
inline constexpr std::size_t kMaxSdoTextBytes = 1024;

/// What the config asks of one drive.
struct DriveRequest {
  std::uint8_t node = 1;
  std::string axis;  ///< for messages
  /// CSP, IP or CSV; default: CSP if supported, else IP
  std::optional<std::int8_t> mode;
  bool outputs = true;  ///< use 0x60FE when the drive has it
  std::optional<DriveIdentity> identity;
  std::vector<SdoWrite> writes;  ///< index, sub and value; sizes filled in by plan_drive
  /// The config's own PDOs: when any RPDO (TPDO) is given, those are the drive's RPDOs (TPDOs)
  /// and mrroc's own are not used; the other direction keeps mrroc's.
  std::vector<PdoRequest> pdos;
  /// Home by the drive's own homing mode at SYNCHRO (none: the EDP's search for the home switch).
  std::optional<HomingRequest> homing;
  SourceLocation where;  ///< of the drive's settings in the config
};

struct DrivePlan {
  std::shared_ptr<const eds::Dictionary> eds;
  std::uint8_t node = 1;
  std::string axis;
  std::int8_t mode = eds::mode::kCyclicSyncPosition;
  /// The object that takes the target: 0x607A (CSP), 0x60C1 sub 1 (IP) or 0x60FF (CSV: a
  /// velocity, the master's from the servo loop's positions).
  PdoEntry target{0x607A, 0, 32};
  std::vector<PdoPlan> rpdos;         ///< mapped, in the order written (mrroc's: RPDO1, RPDO2)
  std::vector<PdoPlan> tpdos;         ///< mapped (mrroc's: TPDO1, TPDO2)
  std::vector<PdoPlan> switched_off;  ///< every other PDO the drive has (entries empty)
  /// 0x60FE sub 1 is mapped: the master drives the drive's output lines.
  bool outputs = false;
  std::optional<DriveIdentity> identity;
  std::vector<SdoWrite> writes;
  /// Homing by the drive (CiA 402 mode 6) at SYNCHRO; checked: 0x6098, 0x6099 sub 1 and 2,
  /// 0x609A and 0x607C exist and are writable, 0x6061 readable, the file's 0x6502 lists homing
  /// (bit 5), every value within its object's type and limits.
  std::optional<HomingPlan> homing;
  /// Optional objects the drive has (the master writes them only then).
  bool has(std::uint16_t index, std::uint8_t sub = 0) const {
    return eds->entry(index, sub) != nullptr;
  }
  /// The object that takes the target (0x607A, 0x60C1 sub 1 or 0x60FF).
  [[nodiscard]] PdoEntry target_entry() const { return target; }
  /// The mapped PDO that carries the object, or null.
  [[nodiscard]] const PdoPlan* pdo_with(std::uint16_t index, std::uint8_t sub = 0) const {
    for (const auto* list : {&rpdos, &tpdos})
      for (const PdoPlan& p : *list)
        if (p.maps(index, sub)) return &p;
    return nullptr;
  }
};

/// Plans the drive and checks every object the master will touch against its file.
/// @throws ConfigErrors with every problem, each naming the EDS `file:line` (or the config's
/// location for a value the file does not have), the node and the object.
DrivePlan plan_drive(std::shared_ptr<const eds::Dictionary> eds, const DriveRequest& request);

/// Checks that no two PDOs of the drives on one bus (one master) share a COB-ID, and that none
/// uses an identifier CiA 301 reserves or mrroc's bus uses otherwise (NMT, SYNC, EMCY, SDO,
/// heartbeat: 0x000..0x0FF, 0x101..0x180, 0x581..0x5FF, 0x601..0x67F, 0x6E0..0x7FF).
/// @throws ConfigErrors naming both PDOs, their nodes and the config's rows.
void check_pdo_identifiers(const std::vector<DrivePlan>& plans);

/// The cyclic traffic of the planned drives on their bus: SYNC, each RPDO that carries the
/// controlword or the target every cycle, output-only RPDOs every canopen::kOutputRefreshCycles,
/// TPDOs of type n every n-th SYNC (type 0: every SYNC, the worst case), event-driven TPDOs at
/// their event timer, the drives' heartbeats.
canopen::BusLoad pdo_bus_load(const std::vector<DrivePlan>& plans, double period_s,
                              double bitrate_bps, double heartbeat_period_s);

/// An object of a drive: index and sub-index.
struct ObjectId {
  std::uint16_t index = 0;
  std::uint8_t sub = 0;
};
/// The objects the master configures where a drive's file has them (and leaves alone where not).
inline constexpr std::array<ObjectId, 9> kOptionalObjects{{{0x1006, 0},
                                                           {0x1029, 1},
                                                           {0x6007, 0},
                                                           {0x605A, 0},
                                                           {0x6065, 0},
                                                           {0x6066, 0},
                                                           {0x6085, 0},
                                                           {0x60C2, 1},
                                                           {0x60C2, 2}}};

/// A value in drive units: `value` [rad, m, or per second, per second squared] times
/// `counts_per_unit`, rounded to whole counts. Bounded before any cast.
/// @returns nullopt when the product is not finite or lies outside [lowest, highest].
std::optional<std::int64_t> to_drive_units(double value, double counts_per_unit,
                                           std::int64_t lowest, std::int64_t highest) noexcept;

/// The built-in description of mrroc's emulated drive (configs/drives/emu-csp.eds), for drives
/// whose config names no file.
std::shared_ptr<const eds::Dictionary> default_drive_eds();

/// The object's name from the file, or its CiA 301/402 name, with its index:
/// "0x6041 statusword". Never throws.
std::string object_name(const eds::Dictionary* eds, std::uint16_t index, std::uint8_t sub);

}  // namespace mrroc::can
