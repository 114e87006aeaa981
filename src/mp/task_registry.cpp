// The name -> factory registry of MP tasks, and the robots and virtual sensors of an MP task.
#include <fmt/format.h>

#include <optional>

#include "../core/registry.hpp"
#include "mrroc/config/check.hpp"
#include "mrroc/ecp/virtual_sensor.hpp"
#include "mrroc/mp/task.hpp"

namespace mrroc {

namespace {
detail::Registry<mp::MpTaskFactory>& mp_registry() {
  static detail::Registry<mp::MpTaskFactory> r("MP task");
  return r;
}
}  // namespace

mp::Robot& mp::TaskContext::robot(const std::string& name) const {
  std::string known;
  for (Robot* r : robots) {
    if (r->name() == name) return *r;
    known += (known.empty() ? "" : ", ") + r->name();
  }
  throw ConfigError(fmt::format("the MP task needs robot '{}', the process set has: {}", name,
                                known.empty() ? "none" : known));
}

void mp::register_mp_task(const std::string& name, MpTaskFactory factory) {
  mp_registry().add(name, std::move(factory));
}
std::unique_ptr<mp::MpTask> mp::make_mp_task(const std::string& name, TaskContext& context) {
  return mp_registry().get(name)(context);
}

std::vector<ConfigError> mp::check_mp_task(const std::string& name, const TaskContext& context,
                                           const SourceLocation& name_where,
                                           const SourceLocation& where) {
  ConfigErrorList errors;
  MpTaskFactory factory;
  std::string checked_as = name;
  if (!errors.run(name_where, [&] { factory = mp_registry().get(name); })) {
    // A name near a known one (the error suggests it): the arguments are checked against that
    // task, so that their own mistakes show in the same run.
    const std::optional<std::string> near = mp_registry().nearest(name);
    if (!near) return errors.errors();
    checked_as = *near;
    factory = mp_registry().get(checked_as);
  }
  // A copy of the arguments that collects every unknown key and every optional argument of
  // another type instead of throwing at the first.
  ConfigErrorList argument_errors;
  Params args = context.args;
  args.collect_errors(&argument_errors);
  TaskContext built{context.robots, context.reporter, args, context.config, context.bus};
  argument_errors.run(where, [&] { (void)factory(built); });
  args.collect_unknown_keys(nullptr);
  errors.add(checked_as == name ? argument_errors.errors()
                                : noted(argument_errors.errors(),
                                        fmt::format("(checked as MP task '{}')", checked_as)));
  return errors.errors();
}

}  // namespace mrroc

namespace mrroc::mp {

std::unique_ptr<ecp::VirtualSensor> TaskContext::sensor(const std::string& vsp) const {
  if (bus == nullptr) throw Error("this task context has no LCM bus for virtual sensors");
  (void)config.vsp(vsp);  // a VSP of this process set, else a ConfigError naming the known ones
  return std::make_unique<ecp::VirtualSensor>(*bus, vsp, "mp");
}

}  // namespace mrroc::mp
