// The name -> factory registry of ECP tasks, and the virtual sensors of an ECP task.
#include <cxxabi.h>

#include <algorithm>
#include <cstdlib>
#include <optional>

#include <fmt/format.h>
#include <fmt/ranges.h>

#include "../core/registry.hpp"
#include "mrroc/config/check.hpp"
#include "mrroc/ecp/task.hpp"

namespace mrroc {

namespace {
detail::Registry<ecp::EcpTaskFactory>& ecp_registry() {
  static detail::Registry<ecp::EcpTaskFactory> r("ECP task");
  return r;
}
// The robot class of each task registered with one (MRROC_REGISTER_ECP_TASK_WITH_ROBOT).
detail::Registry<ecp::RobotFactory>& robot_registry() {
  static detail::Registry<ecp::RobotFactory> r("ECP robot class");
  return r;
}
}  // namespace

void ecp::register_ecp_task(const std::string& name, EcpTaskFactory factory, RobotFactory robot) {
  ecp_registry().add(name, std::move(factory));
  if (robot) robot_registry().add(name, std::move(robot));
}

std::unique_ptr<ecp::Robot> ecp::make_task_robot(const std::string& task, comm::Bus& bus,
                                                 const std::string& process,
                                                 const std::string& robot, RobotModel model) {
  // An unknown name is checked as the task it suggests (check_ecp_task): that task's robot.
  const std::string name =
      ecp_registry().has(task) ? task : ecp_registry().nearest(task).value_or(task);
  if (robot_registry().has(name))
    return robot_registry().get(name)(bus, process, robot, std::move(model));
  return std::make_unique<Robot>(bus, process, robot, std::move(model));
}
std::unique_ptr<ecp::EcpTask> ecp::make_ecp_task(const std::string& name, TaskContext& context) {
  return ecp_registry().get(name)(context);
}

std::vector<ConfigError> ecp::check_ecp_task(const std::string& name, const TaskContext& context,
                                             const SourceLocation& name_where,
                                             const SourceLocation& where) {
  ConfigErrorList errors;
  EcpTaskFactory factory;
  std::string checked_as = name;
  if (!errors.run(name_where, [&] { factory = ecp_registry().get(name); })) {
    // A name near a known one (the error suggests it): the arguments are checked against that
    // task, so that their own mistakes show in the same run.
    const std::optional<std::string> near = ecp_registry().nearest(name);
    if (!near) return errors.errors();
    checked_as = *near;
    factory = ecp_registry().get(checked_as);
  }
  // A copy of the arguments that collects every unknown key and every optional argument of
  // another type instead of throwing at the first.
  ConfigErrorList argument_errors;
  Params args = context.args;
  args.collect_errors(&argument_errors);
  TaskContext built{context.robot, context.reporter, args,    context.servo_period_s,
                    context.bus,   context.process,  nullptr, context.vsps};
  argument_errors.run(where, [&] { (void)factory(built); });
  args.collect_unknown_keys(nullptr);
  errors.add(checked_as == name ? argument_errors.errors()
                                : noted(argument_errors.errors(),
                                        fmt::format("(checked as ECP task '{}')", checked_as)));
  return errors.errors();
}

}  // namespace mrroc

namespace mrroc::ecp {

std::string detail::class_name(const std::type_info& type) {
  int status = 0;
  char* readable = abi::__cxa_demangle(type.name(), nullptr, nullptr, &status);
  std::string name = status == 0 && readable != nullptr ? readable : type.name();
  std::free(readable);  // NOLINT(cppcoreguidelines-no-malloc): __cxa_demangle's malloc
  return name;
}

namespace {

/// Empty when `vsps` is unknown or has `vsp`; else why not.
std::string missing_vsp(const std::vector<std::string>* vsps, const std::string& vsp) {
  if (vsps == nullptr || std::find(vsps->begin(), vsps->end(), vsp) != vsps->end()) return {};
  return fmt::format("VSP '{}' is not in the process set ({})", vsp,
                     vsps->empty() ? std::string("it has no [[vsp]]")
                                   : fmt::format("its [[vsp]] are: {}", fmt::join(*vsps, ", ")));
}

}  // namespace

std::string TaskContext::sensor_argument(const std::string& key,
                                         const std::string& fallback) const {
  std::string name = args.get_string(key, fallback);
  const std::string why = missing_vsp(vsps, name);
  if (!why.empty())
    throw ConfigError(args.has(key) ? args.location_of(key) : args.location(),
                      fmt::format("'{}' = \"{}\": {}", key, name, why));
  return name;
}

std::unique_ptr<VirtualSensor> TaskContext::sensor(const std::string& vsp) const {
  if (bus == nullptr) throw Error("this task context has no LCM bus for virtual sensors");
  if (const std::string why = missing_vsp(vsps, vsp); !why.empty()) throw Error(why);
  return std::make_unique<VirtualSensor>(*bus, vsp, process.empty() ? "ecp" : process);
}

void TaskContext::follow_mp_with(std::unique_ptr<FollowGenerator> generator) const {
  if (follow_slot == nullptr)
    throw Error("this task context cannot follow the MP: no ECP shell serves the MP here");
  *follow_slot = std::move(generator);
}

}  // namespace mrroc::ecp
