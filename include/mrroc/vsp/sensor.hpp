#pragma once
/// @file
/// The sensor plugin interface of the VSP (Virtual Sensor Process). A plugin aggregates the raw
/// samples of its sources (receptors: raw sensor devices publishing on mrroc/raw/<device>) into
/// one reading; the VSP shell (`mrroc-vsp`) serves it with CONFIGURE, INITIATE_READING,
/// GET_READING and TERMINATE, marks readings invalid when a source goes stale and reports to the
/// SRP. Which raw sensors feed which virtual sensor is configuration ([[vsp]] sources), not code.
///
/// Lifecycle (the shell serialises every call):
///   configure(setup) -> { on_sample(...)* | command(args) | make_reading(context) }*
/// `on_sample` runs for every raw sample of every source; `make_reading` on INITIATE_READING (on
/// demand) or every period (periodic). Errors: ConfigError for bad parameters or arguments (they
/// name the key, value, unit and limit), any other exception from make_reading is reported as a
/// sensor fault and the reading is invalid.
#include <cstddef>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "mrroc/config/params.hpp"
#include "mrroc/msg/sensor_reading.hpp"

namespace mrroc {
struct VspConfig;
}  // namespace mrroc

namespace mrroc::vsp {

struct SensorSetup {
  std::string name;                  ///< the VSP's name, e.g. "wrist_force"
  std::vector<std::string> sources;  ///< raw sensor devices, in the config's order
  Params params;                     ///< [vsp.params]
};

class SensorPlugin {
 public:
  virtual ~SensorPlugin() = default;
  [[nodiscard]] virtual std::string plugin_name() const = 0;
  /// Reads the parameters; checks the number of sources. @throws ConfigError.
  virtual void configure(const SensorSetup& setup) = 0;
  /// A raw sample of `sources[source]`, also one the device marked not valid (`sample.valid`):
  /// the plugin decides what that means (a camera that sees nothing is not a fault).
  virtual void on_sample(std::size_t source, const RawSample& sample) = 0;
  /// CONFIGURE's arguments (e.g. `zero = true`). The default accepts none.
  /// @throws ConfigError naming an unknown or bad argument.
  virtual void command(const Params& args) { args.reject_unread("CONFIGURE arguments"); }
  /// A reading from the latest samples; `context` are INITIATE_READING's arguments (e.g. the
  /// sensor's orientation for gravity compensation). Fill valid/values/names/units;
  /// the shell adds times, numbers and staleness.
  virtual Reading make_reading(const Params& context) = 0;
};

using SensorFactory = std::function<std::unique_ptr<SensorPlugin>()>;
void register_sensor(const std::string& name, SensorFactory factory);
/// @throws ConfigError listing the known plugins when `name` is unknown.
std::unique_ptr<SensorPlugin> make_sensor(const std::string& name);
std::vector<std::string> sensor_names();

/// The sensor plugin of a [[vsp]] as mrroc-vsp makes it at start, and as `mrroc-vsp
/// --check-config` (run by `mrroc-launch --check`) checks it: made by its name (unknown: an error
/// at `plugin`, suggesting the nearest known name when one is near, and the parameters'
/// errors against that plugin, each noted "(checked as sensor plugin 'name')").
/// @throws ConfigError, or ConfigErrors for an unknown name with its parameters' errors.
std::unique_ptr<SensorPlugin> make_sensor(const VspConfig& vsp);
/// Configures `plugin` with the VSP's name, sources and [vsp.params], every unknown key of the
/// parameters reported. @throws ConfigError, or ConfigErrors with every error found.
void configure_sensor(SensorPlugin& plugin, const VspConfig& vsp);

namespace detail {
struct SensorRegistrar {
  SensorRegistrar(const char* name, SensorFactory factory) {
    register_sensor(name, std::move(factory));
  }
};
}  // namespace detail

}  // namespace mrroc::vsp

/// Registers a sensor plugin class: `MRROC_REGISTER_SENSOR("force_torque", ForceTorque)`.
#define MRROC_REGISTER_SENSOR(NAME, CLASS)                                            \
  static const ::mrroc::vsp::detail::SensorRegistrar mrroc_sensor_registrar_##CLASS { \
    NAME, [] { return std::unique_ptr<::mrroc::vsp::SensorPlugin>(new CLASS()); }     \
  }
