#pragma once
/// @file
/// The EDP's hardware plugin interface: what the servo loop needs from a robot's axes.
///
/// Units: joint positions in rad (revolute) or m (prismatic), velocities per second.
/// Positions handed across this interface are *raw axis positions*: what incremental encoders
/// report, with their zero wherever the axis was at power-on. The EDP learns the offset to joint
/// coordinates during SYNCHRO from each axis' synchronisation switch
/// (`AxisFeedback::synchro_switch`).
///
/// Lifecycle (called by the EDP, never concurrently):
///   configure(params) -> activate() -> { read(); write(); }* -> deactivate()
/// `read` and `write` are called once per servo cycle from the servo thread; they must not
/// allocate, block on the network, or throw (they report through `CycleStatus`). The calls that
/// may block for long (the reset after a fault: `deactivate` then `activate`; `home_axes`) come
/// from the EDP's recovery thread, never from the servo thread, and no cycle call is made while
/// one runs.

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "mrroc/config/params.hpp"
#include "mrroc/core/time.hpp"

namespace mrroc {
struct RobotConfig;
struct RobotModel;
}  // namespace mrroc

namespace mrroc::edp {

/// Result of one servo-cycle call into a plugin.
enum class CycleStatus { ok, fault };

/// What the servo loop learns about one axis each cycle.
struct AxisFeedback {
  double position = 0.0;        ///< raw axis position (encoder zero at power-on) [rad]
  double velocity = 0.0;        ///< [rad/s]
  bool synchro_switch = false;  ///< state of the axis' synchronisation switch
};

/// Most fields a device's command or reply may have (the servo loop keeps them in fixed arrays).
inline constexpr std::size_t kMaxDeviceFields = 8;

/// One number of a device's command or reply (e.g. a gripper's opening).
struct DeviceField {
  std::string name;  ///< e.g. "opening"
  std::string unit;  ///< e.g. "m", "N", "-" for a flag (0 or 1)
  /// Range a SET DEVICE value must lie in [unit] (command fields; unused for reply fields).
  double min = 0.0;
  double max = 0.0;
};

/// The device a plugin drives beside the robot's axes (the paper's device-dependent buffers and
/// images, e.g. a gripper): what a SET DEVICE commands and what a GET DEVICE returns. An empty
/// `name` means the plugin has no device.
struct DeviceDescription {
  std::string name;                  ///< e.g. "gripper"
  std::vector<DeviceField> command;  ///< at most kMaxDeviceFields
  std::vector<DeviceField> reply;    ///< at most kMaxDeviceFields
};

/// What a plugin is given at configure time.
struct HardwareSetup {
  std::string robot;                             ///< robot name from the config, e.g. "irb6"
  std::filesystem::path model_dir;               ///< robots/<name>/ folder (URDF, MJCF, parameters)
  double servo_period_s = kDefaultServoPeriodS;  ///< servo period [s]
  std::vector<double>
      synchro_positions;  ///< joint position at which each axis' switch toggles [rad]
  Params params;          ///< the plugin's own table from the config
};

/// Base class of every EDP hardware plugin.
class Hardware {
 public:
  virtual ~Hardware() = default;

  /// Plugin name as written in the config (`plugin = "mujoco"`).
  [[nodiscard]] virtual std::string name() const = 0;
  /// Number of axes; valid after configure().
  [[nodiscard]] virtual std::size_t axis_count() const = 0;

  /// Load models, open devices. @throws HardwareError or ConfigError with a clear message.
  virtual void configure(const HardwareSetup& setup) = 0;
  /// Checks `setup` as configure() would, opening no device: what `mrroc-edp --check-config`
  /// (and so `mrroc-launch --check`) runs for a plugin that drives real devices (`simulated()`
  /// false); simulated hardware is configured instead. The default checks nothing, so a plugin
  /// of real devices should read and check its parameters here too (every key, unknown keys
  /// rejected). @throws ConfigError as configure().
  virtual void check(const HardwareSetup& setup) { (void)setup; }
  /// Power the drives; after this, read/write are called every cycle.
  virtual void activate() = 0;
  /// Stop and power down. Must be safe to call more than once.
  virtual void deactivate() = 0;

  /// Sample the axes (beginning of a cycle). `out.size() == axis_count()`.
  virtual CycleStatus read(std::span<AxisFeedback> out) = 0;
  /// Command the axes for the coming period (raw axis positions). For simulated hardware this also
  /// advances simulated time by one servo period. `setpoints.size() == axis_count()`.
  virtual CycleStatus write(std::span<const double> setpoints) = 0;

  /// True when write_outputs() and read_inputs() reach the controller's binary lines. Otherwise
  /// the EDP refuses SET OUTPUTS and GET INPUTS (error not_supported) instead of ignoring the
  /// outputs and answering inputs that are always 0.
  [[nodiscard]] virtual bool binary_io() const { return false; }
  /// The output lines that exist (bit i = line i), when binary_io(): the EDP refuses a SET
  /// OUTPUTS that sets any other line (error bad_argument, naming the line). Default: all 32.
  [[nodiscard]] virtual std::uint32_t output_lines() const { return 0xFFFFFFFFU; }
  /// Binary outputs of the robot controller (bit i = line i). Called from the servo thread.
  virtual void write_outputs(std::uint32_t values) { (void)values; }
  /// Binary inputs of the robot controller (bit i = line i). Called from the servo thread.
  [[nodiscard]] virtual std::uint32_t read_inputs() const { return 0; }

  /// The device the plugin drives beside the axes; valid after configure(), read once when the
  /// EDP's servo loop is made. The default (empty name): none, and the EDP refuses SET DEVICE and
  /// GET DEVICE (error not_supported).
  [[nodiscard]] virtual DeviceDescription device() const { return {}; }
  /// Commands the device with one value per `device().command` field, each already checked
  /// against its range. Called from the servo thread before write(); must not allocate.
  virtual void write_device(std::span<const double> command) { (void)command; }
  /// Measures the device: one value per `device().reply` field. Called from the servo thread
  /// after read(); must not allocate.
  virtual void read_device(std::span<double> reply) const { (void)reply; }

  /// Servo algorithms the plugin offers (numbered 0..n-1; 0 is the default).
  [[nodiscard]] virtual int servo_algorithm_count() const { return 1; }
  /// Parameter sets of one algorithm (numbered 0..n-1; 0 is the default).
  [[nodiscard]] virtual int servo_parameter_set_count(int algorithm) const {
    (void)algorithm;
    return 1;
  }
  /// Switches one axis to an algorithm and parameter set (already validated against the counts).
  /// Called from the servo thread; must not allocate.
  virtual void set_servo(std::size_t axis, int algorithm, int parameter_set) {
    (void)axis;
    (void)algorithm;
    (void)parameter_set;
  }

  /// Emergency stop engaged (true) or released (false). The EDP's servo loop brings the axes to
  /// a standstill itself; a plugin whose drives have their own quick stop uses it here. Called
  /// from the EDP's emergency-stop listener thread (ENGAGE, release) and from its main thread
  /// (the stop it starts in, and the one it holds while it ends), never from the servo thread,
  /// so concurrently with read/write: keep it to an atomic flag.
  virtual void emergency_stop(bool engaged) { (void)engaged; }

  /// The axes the hardware homes by itself (bit i = axis i), e.g. drives that run their own
  /// homing mode (CiA 402 mode 6): after home_axes() their raw positions are joint coordinates
  /// (the position reference is the hardware's), so SYNCHRO takes them as synchronised (offset
  /// 0) and searches the synchronisation switches of the other axes only. Valid after
  /// configure(); constant until the next configure(). Any thread; no side effects. The default,
  /// none: SYNCHRO searches every axis' switch.
  [[nodiscard]] virtual std::uint32_t self_homing_axes() const { return 0; }
  /// Homes the axes of self_homing_axes(), all at once, holding the others where they stand.
  /// Called by the servo loop at SYNCHRO (only when self_homing_axes() is not 0), from the EDP's
  /// recovery thread (SCHED_FIFO 70 where allowed), never from the servo thread and never
  /// concurrently with read() and write(): it blocks for as long as the homing takes (the servo
  /// cycles make no plugin call meanwhile; the plugin keeps its devices supervised itself) and
  /// must end soon after emergency_stop(true), which may come from another thread meanwhile. After
  /// it the next read() returns the new raw positions. After activate(). The default homes nothing
  /// and throws: a plugin that names self-homing axes implements it.
  /// @throws HardwareError naming the axis or device, what failed and after how long; the plugin
  /// then holds its axes still and reports a fault (read()) until the next activate().
  virtual void home_axes();

  /// True for simulated hardware whose time advances only in write(): the servo loop may then
  /// run lock-step (`[robot.edp] lock_step = true`), cycles back to back instead of one per
  /// period. Real drives keep their own clock and must answer false (the default).
  [[nodiscard]] virtual bool simulated() const { return false; }

  /// True when the plugin drives devices that move something real: drives, amplifiers, a bus
  /// with emulated drives behind it counts too (the plugin cannot tell). After such an EDP ends,
  /// `mrroc-launch` restarts it only when an operator acknowledges (`mrroc-ui restart`): a
  /// restarted EDP enables its devices again. The EDP announces it in its ready status. The
  /// default, true, is the safe answer for a plugin that does not say; simulations answer false.
  /// Any thread; no side effects.
  [[nodiscard]] virtual bool drives_real_devices() const { return true; }

  /// Text of the last fault (read after a `CycleStatus::fault`).
  [[nodiscard]] virtual std::string fault_text() const { return {}; }
};

using HardwareFactory = std::function<std::unique_ptr<Hardware>()>;

/// Registry of hardware plugins by name.
void register_hardware(const std::string& name, HardwareFactory factory);
/// @throws ConfigError listing the known plugins when `name` is unknown.
std::unique_ptr<Hardware> make_hardware(const std::string& name);
std::vector<std::string> hardware_names();

/// The hardware of `robot` as mrroc-edp makes it at start, and as `mrroc-edp --check-config`
/// (run by `mrroc-launch --check`) checks it: the plugin named in [robot.edp] (unknown: an error
/// at `plugin`, suggesting the nearest known name when one is near, and the parameters' errors
/// against that plugin, opening no device, each noted "(checked as hardware plugin 'name')"),
/// `lock_step` only for simulated hardware, then `configure()` with the robot's
/// setup (its [robot.edp.params], every unknown key reported, and the plugin's model files).
/// With `open_devices` false (the check) a plugin that drives real devices (`simulated()`
/// false) is made and its check() runs instead of configure(), which would open them.
/// @throws ConfigError, or ConfigErrors with every error found.
std::unique_ptr<Hardware> make_configured_hardware(const RobotConfig& robot,
                                                   const RobotModel& model, bool open_devices);

namespace detail {
struct HardwareRegistrar {
  HardwareRegistrar(const char* name, HardwareFactory factory) {
    register_hardware(name, std::move(factory));
  }
};
}  // namespace detail

}  // namespace mrroc::edp

/// Registers a hardware plugin class under a name: `MRROC_REGISTER_HARDWARE("mujoco",
/// MujocoHardware)`.
#define MRROC_REGISTER_HARDWARE(NAME, CLASS)                                              \
  static const ::mrroc::edp::detail::HardwareRegistrar mrroc_hardware_registrar_##CLASS { \
    NAME, [] { return std::unique_ptr<::mrroc::edp::Hardware>(new CLASS()); }             \
  }
