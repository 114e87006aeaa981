#pragma once
/// @file
/// MP tasks: the user's coordinating code run by the MP shell. Registered with
/// MRROC_REGISTER_MP_TASK and chosen in the config (`[mp] task = "name"`). No LCM and no TOML
/// parser here: a task plugin compiles against the task API alone (the package test checks it).

#include <functional>
#include <map>
#include <memory>
#include <string>

#include "mrroc/comm/reporter.hpp"
#include "mrroc/config/params.hpp"
#include "mrroc/config/process_set.hpp"
#include "mrroc/ecp/virtual_sensor.hpp"
#include "mrroc/mp/robot.hpp"

namespace mrroc::comm {
class Bus;
}  // namespace mrroc::comm

namespace mrroc::mp {

struct TaskContext {
  RobotList robots;  ///< every robot of the process set, in config order
  Reporter& reporter;
  const Params& args;              ///< [mp.args]
  const ProcessSetConfig& config;  ///< the whole process set (robot models, servo periods, ...)
  comm::Bus* bus = nullptr;        ///< the MP's LCM connection (for virtual sensors)

  /// The image of the VSP named `vsp` in the MP: a client of it, for MP-level Move and Wait.
  /// @throws Error when the context has no bus; ConfigError when the set has no VSP `vsp`.
  [[nodiscard]] std::unique_ptr<ecp::VirtualSensor> sensor(const std::string& vsp) const;

  /// @throws ConfigError naming the robots there are.
  [[nodiscard]] Robot& robot(const std::string& name) const;
};

/// The operator's STOP of the current run (mrroc-ui stop): MP-level Move and Wait throw
/// ecp::TaskStopped at their next step, like on SIGTERM, but the MP process goes on and may start
/// the task again. The MP shell clears it before each run.
void request_task_stop();
void clear_task_stop();
[[nodiscard]] bool task_stop_requested();

class MpTask {
 public:
  virtual ~MpTask() = default;
  /// Runs the task. Returns normally on success; throws on failure.
  virtual void main_task() = 0;
};

using MpTaskFactory = std::function<std::unique_ptr<MpTask>(TaskContext&)>;
void register_mp_task(const std::string& name, MpTaskFactory factory);
/// @throws ConfigError listing the known task names.
std::unique_ptr<MpTask> make_mp_task(const std::string& name, TaskContext& context);

/// What the MP checks of its task before it reports ready, and what `mrroc-mp --check-config`
/// (run by `mrroc-launch --check`) checks: the task `name` is built once with `context`.
/// Returns every error found, each at its own location, else at `where`: an unknown name (at
/// `name_where`, suggesting the nearest known one when one is near), every unknown key and
/// every optional argument of another type (Params::collect_errors), and what the
/// constructor throws (a required argument missing or of another type, ranges, poses). A task
/// that checks each argument in its own `ConfigErrorList::run` and throws them together gets
/// every one reported. An unknown name near a known one has its arguments checked against that
/// task, each such error noted "(checked as MP task 'name')".
std::vector<ConfigError> check_mp_task(const std::string& name, const TaskContext& context,
                                       const SourceLocation& name_where,
                                       const SourceLocation& where);

namespace detail {
struct MpTaskRegistrar {
  MpTaskRegistrar(const char* name, MpTaskFactory f) { register_mp_task(name, std::move(f)); }
};
}  // namespace detail

}  // namespace mrroc::mp

#define MRROC_REGISTER_MP_TASK(NAME, CLASS)                                           \
  static const ::mrroc::mp::detail::MpTaskRegistrar mrroc_mp_task_registrar_##CLASS { \
    NAME, [](::mrroc::mp::TaskContext& c) {                                           \
      return std::unique_ptr<::mrroc::mp::MpTask>(new CLASS(c));                      \
    }                                                                                 \
  }
