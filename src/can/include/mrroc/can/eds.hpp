#pragma once
/// @file
/// Electronic data sheets and device configuration files of CANopen devices (CiA 306): the
/// object dictionary a drive has, as its vendor describes it (EDS) or as it is to be configured
/// (DCF: the same file with `ParameterValue`s and a `[DeviceComissioning]` section).
///
/// What is read:
///  - sections `[1018]` (an object), `[1018sub2]` (a sub-object; hexadecimal sub-index),
///    `[1600Name]` / `[1600Value]` (the names and values of an object written with
///    `CompactSubObj`), `[DeviceInfo]`, `[DeviceComissioning]`, and the lists
///    `[MandatoryObjects]`, `[OptionalObjects]`, `[ManufacturerObjects]` (every object listed must
///    have its section). Other sections (`[FileInfo]`, `[Comments]`, `[DummyUsage]`, tools'
///    own) are skipped. Section names and keys are case-insensitive; `;` starts a comment line.
///  - keys of an object or sub-object: `ParameterName`, `ObjectType` (0x7 VAR, 0x8 ARRAY, 0x9
///    RECORD; VAR when absent), `SubNumber`, `CompactSubObj`, `DataType`, `AccessType` (ro, wo,
///    rw, rwr, rww, const), `PDOMapping`, `DefaultValue`, `ParameterValue` (a DCF's value: it
///    wins over the default), `LowLimit`, `HighLimit`.
///  - numbers in decimal, hexadecimal (`0x`) or octal (a leading `0`), negative for signed types;
///    a value may add `$NODEID` (`$NODEID+0x180`, `0x200+$NODEID`): it is kept as a formula and
///    `Dictionary::value` adds the node id it is given.
///  - the modes a CiA 402 drive supports from `0x6502` (supported drive modes), when the file
///    has it.
/// Every error is a mrroc::ConfigError naming `file:line`.
#include <cstdint>
#include <filesystem>
#include <map>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "mrroc/core/error.hpp"

namespace mrroc::can::eds {

/// CiA 301 data types (the numbers `DataType` uses).
namespace type {
inline constexpr std::uint16_t kBoolean = 0x0001;
inline constexpr std::uint16_t kInteger8 = 0x0002;
inline constexpr std::uint16_t kInteger16 = 0x0003;
inline constexpr std::uint16_t kInteger32 = 0x0004;
inline constexpr std::uint16_t kUnsigned8 = 0x0005;
inline constexpr std::uint16_t kUnsigned16 = 0x0006;
inline constexpr std::uint16_t kUnsigned32 = 0x0007;
inline constexpr std::uint16_t kReal32 = 0x0008;
inline constexpr std::uint16_t kVisibleString = 0x0009;
inline constexpr std::uint16_t kOctetString = 0x000A;
inline constexpr std::uint16_t kUnicodeString = 0x000B;
inline constexpr std::uint16_t kDomain = 0x000F;
inline constexpr std::uint16_t kInteger24 = 0x0010;
inline constexpr std::uint16_t kReal64 = 0x0011;
inline constexpr std::uint16_t kInteger64 = 0x0015;
inline constexpr std::uint16_t kUnsigned24 = 0x0016;
inline constexpr std::uint16_t kUnsigned64 = 0x001B;
}  // namespace type
/// Bits of a value of the type; 0 for the variable-length types (strings, domain); -1 for a type
/// mrroc does not know.
int bit_size(std::uint16_t data_type) noexcept;
bool is_signed(std::uint16_t data_type) noexcept;
bool is_string(std::uint16_t data_type) noexcept;
/// "UNSIGNED32", ...; "unknown" for a type mrroc does not know.
std::string_view type_name(std::uint16_t data_type) noexcept;

enum class Access : std::uint8_t { ro, wo, rw, rwr, rww, constant };
std::string_view to_string(Access access) noexcept;
inline bool readable(Access a) noexcept { return a != Access::wo; }
inline bool writable(Access a) noexcept {
  return a == Access::wo || a == Access::rw || a == Access::rwr || a == Access::rww;
}

/// Object types (`ObjectType`).
inline constexpr std::uint8_t kVar = 0x7;
inline constexpr std::uint8_t kArray = 0x8;
inline constexpr std::uint8_t kRecord = 0x9;

/// A value as written: a number (raw bits, two's complement in the type's width), a number plus
/// the node id, or text (strings).
struct Value {
  std::uint64_t raw = 0;
  bool plus_node_id = false;
  std::string text;  ///< strings only
  int line = 0;      ///< where it was written
};

/// A sub-object (a VAR's value is its sub 0).
struct Entry {
  std::uint16_t index = 0;
  std::uint8_t sub = 0;
  std::string name;
  std::uint16_t data_type = 0;
  Access access = Access::ro;
  bool pdo_mappable = false;
  std::optional<Value> value;  ///< ParameterValue, else DefaultValue; none when neither given
  std::optional<std::int64_t> low_limit;  ///< as signed, also for unsigned types up to 32 bits
  std::optional<std::int64_t> high_limit;
  int line = 0;  ///< the line of its section header (or of the object's, for a compact one)
};

struct Object {
  std::uint16_t index = 0;
  std::string name;
  std::uint8_t object_type = kVar;
  std::map<std::uint8_t, Entry> entries;  ///< by sub-index
  int line = 0;
};

/// `[DeviceInfo]`: what the vendor says the device is.
struct DeviceInfo {
  std::string vendor_name;
  std::uint32_t vendor_number = 0;
  std::string product_name;
  std::uint32_t product_number = 0;
  std::uint32_t revision_number = 0;
  int rx_pdos = 0;  ///< NrOfRXPDO
  int tx_pdos = 0;  ///< NrOfTXPDO
  std::vector<int> baud_rates_kbit;
};

/// CiA 402 modes of operation (0x6060) and their bits in 0x6502.
namespace mode {
inline constexpr std::int8_t kProfilePosition = 1;
inline constexpr std::int8_t kProfileVelocity = 3;
inline constexpr std::int8_t kHoming = 6;
inline constexpr std::int8_t kInterpolatedPosition = 7;
inline constexpr std::int8_t kCyclicSyncPosition = 8;
inline constexpr std::int8_t kCyclicSyncVelocity = 9;
inline constexpr std::int8_t kCyclicSyncTorque = 10;
}  // namespace mode
/// The bit of 0x6502 that says `mode` is supported (mode 1 -> bit 0, ..., 10 -> bit 9); 0 for
/// manufacturer or unknown modes.
std::uint32_t mode_bit(std::int8_t mode) noexcept;
/// "cyclic synchronous position", ...
std::string_view mode_name(std::int8_t mode) noexcept;

class Dictionary {
 public:
  /// @throws mrroc::ConfigError naming `file:line`.
  static Dictionary parse(std::string_view text, std::string file);
  /// @throws mrroc::ConfigError naming the file (not found, unreadable) or `file:line`.
  static Dictionary load(const std::filesystem::path& path);

  [[nodiscard]] const std::string& file() const noexcept { return file_; }
  [[nodiscard]] const DeviceInfo& device() const noexcept { return device_; }
  /// A DCF's `[DeviceComissioning] NodeID`.
  [[nodiscard]] std::optional<std::uint8_t> node_id() const noexcept { return node_id_; }
  [[nodiscard]] const std::map<std::uint16_t, Object>& objects() const noexcept { return objects_; }
  [[nodiscard]] const Object* object(std::uint16_t index) const noexcept;
  [[nodiscard]] const Entry* entry(std::uint16_t index, std::uint8_t sub) const noexcept;
  /// The entry's number for a device with `node` (its $NODEID added); nullopt when the entry,
  /// or its value, is missing, or the value is text.
  [[nodiscard]] std::optional<std::uint64_t> value(std::uint16_t index, std::uint8_t sub,
                                                   std::uint8_t node) const noexcept;
  /// 0x6502 (supported drive modes) as written; 0 when the file does not have it.
  [[nodiscard]] std::uint32_t supported_modes() const noexcept;
  /// "file:line" of an entry.
  [[nodiscard]] SourceLocation where(const Entry& entry) const { return {file_, entry.line}; }

 private:
  std::string file_;
  DeviceInfo device_;
  std::optional<std::uint8_t> node_id_;
  std::map<std::uint16_t, Object> objects_;
};

/// Whether `raw` (bits as a Value holds them) lies within the entry's type and limits; the
/// reason when not ("above the high limit 100", ...).
std::optional<std::string> out_of_range(const Entry& entry, std::uint64_t raw);
/// The entry's value as a signed number (sign-extended for signed types).
std::int64_t as_signed(const Entry& entry, std::uint64_t raw) noexcept;

}  // namespace mrroc::can::eds
