#pragma once
/// @file
/// What the `can` plugin (can_hardware.cpp) offers beyond the Hardware interface: homing by the
/// drives' own homing mode (CiA 402 mode 6) for the axes whose drives the config's `homing` rows
/// name. Reached by `dynamic_cast` from the plugin's `Hardware` (LCM- and TOML-free, as
/// hardware.hpp).
#include <cstdint>

namespace mrroc::edp {

class DriveHoming {
 public:
  virtual ~DriveHoming() = default;

  /// The axes whose drives home themselves (bit i = axis i); valid after configure(). Their raw
  /// positions after `home_axes` are the drives' homed positions: the config's `offset` at the
  /// home point, in the drive's axis coordinates.
  [[nodiscard]] virtual std::uint32_t self_homing_axes() const = 0;

  /// Homes those axes by their drives' homing mode, all at once, the other axes held where they
  /// stand (Cia402Master::home: SDO writes of the homing objects, mode 6, controlword bit 4,
  /// statusword bits 12 and 10, then back to the cyclic mode with the target at the actual
  /// position). Blocking for as long as the homing takes (the drives' `timeout_s` at most), from
  /// the thread that calls read() and write(), never concurrently with them. An emergency stop
  /// (`Hardware::emergency_stop(true)`, from any thread) quick-stops the drives and ends the
  /// homing. After activate().
  /// @throws HardwareError naming the drive, the method and the time (homing error, timeout, a
  /// method the drive refuses, a fault while homing, the emergency stop); the plugin is then
  /// faulted (read() reports it, fault_text() says it) until the next activate().
  virtual void home_axes() = 0;
};

}  // namespace mrroc::edp
