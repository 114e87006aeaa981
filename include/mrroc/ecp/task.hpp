#pragma once
/// @file
/// ECP tasks: the user's code run by the ECP shell on START_TASK. A task is a class with
/// `main_task()`, registered under a name with MRROC_REGISTER_ECP_TASK and chosen in the config
/// (`[robot.ecp] task = "name"`). No LCM and no TOML parser here: a task plugin compiles
/// against the task API alone (the package test checks it).

#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "mrroc/comm/reporter.hpp"
#include "mrroc/config/params.hpp"
#include "mrroc/ecp/generator.hpp"
#include "mrroc/ecp/robot.hpp"
#include "mrroc/ecp/virtual_sensor.hpp"

namespace mrroc::comm {
class Bus;
}  // namespace mrroc::comm

namespace mrroc::ecp {

struct TaskContext {
  Robot& robot;
  Reporter& reporter;
  const Params& args;        ///< [robot.ecp.args]
  double servo_period_s;     ///< the EDP's servo period [s]
  comm::Bus* bus = nullptr;  ///< the ECP's LCM connection (for virtual sensors)
  std::string process;       ///< the ECP's process name, e.g. "ecp/irb6"
  /// Where the shell keeps the generator that corrects the MP's NEXT_POSE commands (null where
  /// no MP drives this robot, e.g. when a config is checked).
  std::unique_ptr<FollowGenerator>* follow_slot = nullptr;
  /// The names of the process set's VSPs ([[vsp]] name), which sensor() and sensor_argument()
  /// check a name against (null: not checked, e.g. a context a test builds by hand).
  const std::vector<std::string>* vsps = nullptr;

  /// The image of the VSP named `vsp` ([[vsp]] name): a client of it, for Move and Wait.
  /// @throws Error when the context has no bus, or when `vsps` is known and lacks `vsp`.
  [[nodiscard]] std::unique_ptr<VirtualSensor> sensor(const std::string& vsp) const;
  /// The task argument `key` (default `fallback`) that names a VSP, checked against `vsps`, so
  /// that a config naming a VSP the set does not have fails its check (`mrroc-launch --check`)
  /// instead of when the task first reads the sensor. Call it from the task's constructor.
  /// @throws ConfigError at the argument (or at the arguments' table for the default) naming the
  ///   VSP and listing the set's.
  [[nodiscard]] std::string sensor_argument(const std::string& key,
                                            const std::string& fallback) const;
  /// From now on, every NEXT_POSE of the MP passes through `generator` before it goes to the
  /// EDP (FollowGenerator), until the next START_TASK or NEXT_STATE. Typically the last thing a
  /// task's main_task() does. @throws Error where the shell gave no slot (follow_slot).
  void follow_mp_with(std::unique_ptr<FollowGenerator> generator) const;
};

class EcpTask {
 public:
  virtual ~EcpTask() = default;
  /// Runs the task; returns when done. Throw to report an error.
  virtual void main_task() = 0;
};

using EcpTaskFactory = std::function<std::unique_ptr<EcpTask>(TaskContext&)>;
void register_ecp_task(const std::string& name, EcpTaskFactory factory);
/// @throws ConfigError listing the known task names.
std::unique_ptr<EcpTask> make_ecp_task(const std::string& name, TaskContext& context);

/// What the ECP checks of its task before it reports ready, and what `mrroc-ecp --check-config`
/// (run by `mrroc-launch --check`) checks: the task `name` is built once with `context` (no
/// motion, no request). Returns every error found: an unknown name (at `name_where`), every
/// unknown key of the arguments, and the first other error the task's constructor throws (types,
/// ranges, poses against the limits), each at its own location, else at `where`.
std::vector<ConfigError> check_ecp_task(const std::string& name, const TaskContext& context,
                                        const SourceLocation& name_where,
                                        const SourceLocation& where);

namespace detail {
struct EcpTaskRegistrar {
  EcpTaskRegistrar(const char* name, EcpTaskFactory f) { register_ecp_task(name, std::move(f)); }
};
}  // namespace detail

}  // namespace mrroc::ecp

/// Registers an ECP task class (constructor taking `TaskContext&`) under a name.
#define MRROC_REGISTER_ECP_TASK(NAME, CLASS)                                             \
  static const ::mrroc::ecp::detail::EcpTaskRegistrar mrroc_ecp_task_registrar_##CLASS { \
    NAME, [](::mrroc::ecp::TaskContext& c) {                                             \
      return std::unique_ptr<::mrroc::ecp::EcpTask>(new CLASS(c));                       \
    }                                                                                    \
  }
