#pragma once
/// @file
/// ECP tasks: the user's code run by the ECP shell on START_TASK. A task is a class with
/// `main_task()`, registered under a name with MRROC_REGISTER_ECP_TASK and chosen in the config
/// (`[robot.ecp] task = "name"`). No LCM and no TOML parser here: a task plugin compiles
/// against the task API alone (the package test checks it).

#include <functional>
#include <memory>
#include <string>
#include <typeinfo>
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

namespace detail {
/// The readable name of a class ("mrroc::ecp::Gripper").
std::string class_name(const std::type_info& type);
}  // namespace detail

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

  /// The robot as the class the task drives (a robot class derived from Robot, e.g. Gripper,
  /// made by the ECP shell for a task registered with MRROC_REGISTER_ECP_TASK_WITH_ROBOT).
  /// @throws Error naming the class when the robot is not one (e.g. a sub-task that needs a
  /// gripper run by an ECP whose configured task drives a plain Robot).
  template <class R>
  [[nodiscard]] R& robot_as() const {
    if (auto* r = dynamic_cast<R*>(&robot)) return *r;
    throw Error("this task needs robot '" + robot.name() + "' to be a " +
                detail::class_name(typeid(R)) +
                ", the ECP's configured task ([robot.ecp] task) "
                "drives a " +
                detail::class_name(typeid(robot)) +
                " (a task names its robot class with MRROC_REGISTER_ECP_TASK_WITH_ROBOT)");
  }
};

class EcpTask {
 public:
  virtual ~EcpTask() = default;
  /// Runs the task; returns when done. Throw to report an error.
  virtual void main_task() = 0;
};

using EcpTaskFactory = std::function<std::unique_ptr<EcpTask>(TaskContext&)>;
/// Makes the robot a task drives: the ECP shell's client of the EDP (process: the ECP's process
/// name, robot: the robot's name in the process set).
using RobotFactory = std::function<std::unique_ptr<Robot>(
    comm::Bus& bus, const std::string& process, const std::string& robot, RobotModel model)>;
/// `robot`: the class of robot the task drives (empty: a plain Robot).
void register_ecp_task(const std::string& name, EcpTaskFactory factory, RobotFactory robot = {});
/// The robot the ECP shell makes for its configured task `task`: the class that task was
/// registered with, else a plain Robot. For an unknown name (reported by check_ecp_task), that
/// of the nearest known name, against which check_ecp_task checks the arguments.
std::unique_ptr<Robot> make_task_robot(const std::string& task, comm::Bus& bus,
                                       const std::string& process, const std::string& robot,
                                       RobotModel model);
/// @throws ConfigError listing the known task names.
std::unique_ptr<EcpTask> make_ecp_task(const std::string& name, TaskContext& context);

/// What the ECP checks of its task before it reports ready, and what `mrroc-ecp --check-config`
/// (run by `mrroc-launch --check`) checks: the task `name` is built once with `context` (no
/// motion, no request). Returns every error found, each at its own location, else at `where`:
/// an unknown name (at `name_where`, suggesting the nearest known one when one is near), every
/// unknown key and every optional argument of another type (Params::collect_errors), and
/// what the task's constructor throws (a required argument missing or of another type, ranges,
/// poses against the limits). A task that checks each argument in its own
/// `ConfigErrorList::run` and throws them together (ConfigErrors) gets every one reported, as
/// the stock tasks do; one that throws at its first error gets that one. An unknown name near a
/// known one has its arguments checked against that task, each such error noted "(checked as
/// ECP task 'name')".
std::vector<ConfigError> check_ecp_task(const std::string& name, const TaskContext& context,
                                        const SourceLocation& name_where,
                                        const SourceLocation& where);

namespace detail {
struct EcpTaskRegistrar {
  EcpTaskRegistrar(const char* name, EcpTaskFactory f, RobotFactory robot = {}) {
    register_ecp_task(name, std::move(f), std::move(robot));
  }
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

/// Registers an ECP task class that drives a robot of class ROBOT (derived from ecp::Robot, with
/// Robot's first constructor): the ECP shell whose configured task it is makes its robot a ROBOT,
/// and the task reaches it with `context.robot_as<ROBOT>()`.
#define MRROC_REGISTER_ECP_TASK_WITH_ROBOT(NAME, CLASS, ROBOT)                            \
  static const ::mrroc::ecp::detail::EcpTaskRegistrar mrroc_ecp_task_registrar_##CLASS {  \
    NAME,                                                                                 \
        [](::mrroc::ecp::TaskContext& c) {                                                \
          return std::unique_ptr<::mrroc::ecp::EcpTask>(new CLASS(c));                    \
        },                                                                                \
        [](::mrroc::comm::Bus& bus, const std::string& process, const std::string& robot, \
           ::mrroc::RobotModel model) {                                                   \
          return std::unique_ptr<::mrroc::ecp::Robot>(                                    \
              new ROBOT(bus, process, robot, std::move(model)));                          \
        }                                                                                 \
  }
