// The reader of the MP task "state_machine"'s file: TOML to MachineStates, every error of the
// file collected (each table read on its own) before the task may start.
#include "state_machine_file.hpp"

#include <fmt/format.h>
#include <fmt/ranges.h>

#include <algorithm>
#include <cmath>
#include <deque>
#include <memory>
#include <set>
#include <sstream>

#include <toml++/toml.h>

#include "mrroc/comm/bus.hpp"
#include "mrroc/config/check.hpp"
#include "mrroc/core/nearest_name.hpp"
#include "mrroc/core/plugin_library.hpp"
#include "mrroc/ecp/task.hpp"
#include "mrroc/robot/robot_model.hpp"

namespace mrroc::mp {

std::string StateCondition::describe() const {
  std::string range;
  if (above && below)
    range = fmt::format(" in ({}, {})", *above, *below);
  else if (above)
    range = fmt::format(" above {}", *above);
  else if (below)
    range = fmt::format(" below {}", *below);
  switch (kind) {
    case Kind::joint: return fmt::format("{} joint {}{}", robot, joint, range);
    case Kind::moving: return fmt::format("{} {}", robot, moving ? "moving" : "standing");
    case Kind::sensor: return fmt::format("{} value '{}'{}", sensor, value, range);
  }
  return {};
}

namespace {

namespace fs = std::filesystem;

const std::vector<const char*> kStateKeys = {
    "start_tasks", "robot",        "subtask",  "args",      "run",     "wait",
    "delay",       "timeout",      "report",   "message",   "next",    "when",
    "on_timeout",  "on_non_fatal", "on_fatal", "on_system", "on_error"};

class Reader {
 public:
  Reader(fs::path file, const TaskContext& context, ConfigErrorList& errors)
      : file_(std::move(file)), context_(context), errors_(errors) {}

  StateMachine read() {
    StateMachine machine;
    machine.file = file_;
    toml::table root;
    try {
      root = toml::parse_file(file_.string());
    } catch (const toml::parse_error& e) {
      errors_.add(
          ConfigError(SourceLocation{file_.string(), static_cast<int>(e.source().begin.line)},
                      std::string(e.description())));
      return machine;
    }
    only_keys(root, "the state machine", {"initial", "state"});
    const toml::node* initial = root.get("initial");
    SourceLocation initial_where = whole();
    if (initial == nullptr)
      errors_.add(ConfigError(whole(), "missing key 'initial' (the name of the first state)"));
    else if (!initial->is_string())
      errors_.add(ConfigError(where(*initial), "'initial' must be a state's name"));
    else {
      machine.initial = **initial->as_string();
      initial_where = where(*initial);
    }
    const toml::node* states = root.get("state");
    if (states == nullptr || !states->is_table() || states->as_table()->empty()) {
      errors_.add(ConfigError(states != nullptr ? where(*states) : whole(),
                              "no states: write each as a table [state.<name>]"));
      return machine;
    }
    for (const auto& [key, node] : *states->as_table()) {
      const std::string name(key.str());
      if (!node.is_table()) {
        errors_.add(ConfigError(where(node), fmt::format("state '{}' must be a table", name)));
        continue;
      }
      if (name == kStateDone || name == kStateFailed) {
        errors_.add(ConfigError(where(node), fmt::format("'{}' is a state of every machine; it "
                                                         "cannot be written",
                                                         name)));
        continue;
      }
      names_.push_back(name);
    }
    for (const auto& [key, node] : *states->as_table()) {
      const std::string name(key.str());
      if (node.is_table() && name != kStateDone && name != kStateFailed)
        machine.states[name] = state(name, *node.as_table());
    }
    if (!machine.initial.empty()) {
      check_target(Transition{machine.initial, initial_where}, "initial state");
      if (machine.initial == kStateDone || machine.initial == kStateFailed)
        errors_.add(ConfigError(initial_where, "the initial state must be one of the file's"));
    }
    check_reached(machine);
    return machine;
  }

 private:
  SourceLocation where(const toml::node& node) const {
    return SourceLocation{file_.string(), static_cast<int>(node.source().begin.line)};
  }
  SourceLocation whole() const { return SourceLocation{file_.string(), 1}; }

  void only_keys(const toml::table& table, const std::string& what,
                 const std::vector<const char*>& allowed) {
    for (const auto& [key, node] : table) {
      const std::string k(key.str());
      if (std::find_if(allowed.begin(), allowed.end(), [&](const char* a) { return k == a; }) !=
          allowed.end())
        continue;
      const std::vector<std::string> known(allowed.begin(), allowed.end());
      const std::optional<std::string> near = nearest_name(k, known);
      errors_.add(ConfigError(
          where(node), fmt::format("unknown key '{}' in {}{}", k, what,
                                   near ? fmt::format("; did you mean '{}'?", *near)
                                        : fmt::format(" (allowed: {})", fmt::join(known, ", ")))));
    }
  }

  std::string string_of(const toml::node& node, const std::string& key) {
    if (!node.is_string())
      throw ConfigError(where(node), fmt::format("'{}' must be a string", key));
    return std::string(**node.as_string());
  }

  double number_of(const toml::node& node, const std::string& key, const char* unit) {
    if (node.is_floating_point()) return **node.as_floating_point();
    if (node.is_integer()) return static_cast<double>(**node.as_integer());
    throw ConfigError(where(node), fmt::format("'{}' must be a number [{}]", key, unit));
  }

  /// The robot named at `node`, one of the process set's.
  std::string robot_at(const toml::node& node, const std::string& key) {
    std::string name = string_of(node, key);
    std::vector<std::string> known;
    for (const Robot* r : context_.robots) known.push_back(r->name());
    if (std::find(known.begin(), known.end(), name) == known.end()) {
      const std::optional<std::string> near = nearest_name(name, known);
      throw ConfigError(
          where(node),
          fmt::format("unknown robot '{}' (the process set has: {}){}", name,
                      known.empty() ? "none" : fmt::format("{}", fmt::join(known, ", ")),
                      near ? fmt::format("; did you mean '{}'?", *near) : ""));
    }
    return name;
  }

  /// Where the transition `t` goes must be a state of the file, `done` or `failed`.
  void check_target(const Transition& t, const std::string& what) {
    if (t.target == kStateDone || t.target == kStateFailed) return;
    if (std::find(names_.begin(), names_.end(), t.target) != names_.end()) return;
    std::vector<std::string> known = names_;
    known.emplace_back(kStateDone);
    known.emplace_back(kStateFailed);
    const std::optional<std::string> near = nearest_name(t.target, known);
    errors_.add(ConfigError(
        t.where, fmt::format("{} '{}' is no state of the machine{}", what, t.target,
                             near ? fmt::format("; did you mean '{}'?", *near)
                                  : fmt::format(" (states: {})", fmt::join(known, ", ")))));
  }

  std::optional<Transition> transition(const toml::table& t, const char* key,
                                       const std::string& state) {
    const toml::node* node = t.get(key);
    if (node == nullptr) return std::nullopt;
    Transition out;
    if (!errors_.run({}, [&] { out = Transition{string_of(*node, key), where(*node)}; }))
      return std::nullopt;
    check_target(out, fmt::format("'{}' of state '{}':", key, state));
    return out;
  }

  /// The number of joints of robot `name` (its model loaded once).
  std::size_t joints_of(const std::string& name) {
    auto it = joints_.find(name);
    if (it == joints_.end())
      it = joints_
               .emplace(name,
                        load_robot_model(context_.config.robot(name).model_dir).joint_names.size())
               .first;
    return it->second;
  }

  StateCondition condition(const toml::node& node, const std::string& what,
                           const std::vector<const char*>& extra_keys = {}) {
    if (!node.is_table())
      throw ConfigError(where(node),
                        fmt::format("{} must be a table such as {{ robot = \"conveyor\", joint = "
                                    "0, above = 1.19 }}",
                                    what));
    const toml::table& t = *node.as_table();
    std::vector<const char*> keys = {"robot", "joint", "moving", "sensor",
                                     "value", "above", "below"};
    keys.insert(keys.end(), extra_keys.begin(), extra_keys.end());
    only_keys(t, what, keys);
    StateCondition c;
    c.where = where(node);
    ConfigErrorList local;
    for (const char* bound : {"above", "below"})
      if (const toml::node* b = t.get(bound))
        local.run({}, [&] {
          (bound[0] == 'a' ? c.above : c.below) = number_of(*b, bound, "rad | m | sensor unit");
        });
    const toml::node* robot = t.get("robot");
    const toml::node* sensor = t.get("sensor");
    if ((robot == nullptr) == (sensor == nullptr)) {
      local.add(ConfigError(c.where, fmt::format("{} names either a 'robot' or a 'sensor'", what)));
    } else if (robot != nullptr) {
      local.run({}, [&] { c.robot = robot_at(*robot, "robot"); });
      const toml::node* joint = t.get("joint");
      const toml::node* moving = t.get("moving");
      if ((joint == nullptr) == (moving == nullptr)) {
        local.add(ConfigError(c.where, fmt::format("{} of a robot tests either a 'joint' (with "
                                                   "'above' and/or 'below') or 'moving'",
                                                   what)));
      } else if (joint != nullptr) {
        c.kind = StateCondition::Kind::joint;
        local.run({}, [&] {
          if (!joint->is_integer() || **joint->as_integer() < 0)
            throw ConfigError(where(*joint), "'joint' must be a joint's index (0, 1, ...)");
          c.joint = static_cast<std::size_t>(**joint->as_integer());
          if (!c.robot.empty() && c.joint >= joints_of(c.robot))
            throw ConfigError(where(*joint),
                              fmt::format("robot '{}' has no joint {} (it has {}: 0..{})", c.robot,
                                          c.joint, joints_of(c.robot), joints_of(c.robot) - 1));
        });
        if (!c.above && !c.below)
          local.add(ConfigError(c.where, fmt::format("{} on a joint needs 'above' and/or "
                                                     "'below' [rad | m]",
                                                     what)));
      } else {
        c.kind = StateCondition::Kind::moving;
        local.run({}, [&] {
          if (!moving->is_boolean())
            throw ConfigError(where(*moving), "'moving' must be true or false");
          c.moving = **moving->as_boolean();
        });
        if (c.above || c.below)
          local.add(ConfigError(c.where,
                                "'above' and 'below' go with 'joint' or 'value', not "
                                "with 'moving'"));
      }
      if (t.get("value") != nullptr)
        local.add(ConfigError(where(*t.get("value")), "'value' goes with 'sensor'"));
    } else {
      c.kind = StateCondition::Kind::sensor;
      local.run({}, [&] {
        c.sensor = string_of(*sensor, "sensor");
        try {
          (void)context_.config.vsp(c.sensor);
        } catch (const ConfigError& e) {
          throw ConfigError(where(*sensor), e.message());
        }
      });
      if (const toml::node* value = t.get("value"))
        local.run({}, [&] { c.value = string_of(*value, "value"); });
      else
        local.add(ConfigError(c.where, fmt::format("{} on a sensor needs 'value' (the name of "
                                                   "a value of its reading)",
                                                   what)));
      if (!c.above && !c.below)
        local.add(
            ConfigError(c.where, fmt::format("{} on a sensor needs 'above' and/or 'below'", what)));
      for (const char* k : {"joint", "moving"})
        if (t.get(k) != nullptr)
          local.add(ConfigError(where(*t.get(k)), fmt::format("'{}' goes with 'robot'", k)));
    }
    local.throw_if_any();
    return c;
  }

  /// The TOML table `args` as Params located in the file, for the sub-task's check.
  Params params_of(const toml::table& args) {
    Params p(where(args));
    for (const auto& [key, node] : args) {
      const std::string k(key.str());
      const SourceLocation at = where(node);
      if (node.is_boolean()) {
        p.set(k, **node.as_boolean(), at);
      } else if (node.is_integer()) {
        p.set(k, static_cast<std::int64_t>(**node.as_integer()), at);
      } else if (node.is_floating_point()) {
        p.set(k, **node.as_floating_point(), at);
      } else if (node.is_string()) {
        p.set(k, std::string(**node.as_string()), at);
      } else if (node.is_array()) {
        const toml::array& arr = *node.as_array();
        if (!arr.empty() && arr.is_homogeneous(toml::node_type::string)) {
          std::vector<std::string> out;
          for (const auto& n : arr) out.emplace_back(**n.as_string());
          p.set(k, out, at);
        } else if (!arr.empty() && arr[0].is_array()) {
          std::vector<std::vector<double>> rows;
          std::vector<SourceLocation> row_where;
          for (const auto& row : arr) {
            if (!row.is_array())
              throw ConfigError(where(row),
                                fmt::format("'{}' must be a list of lists of numbers", k));
            rows.push_back(numbers(*row.as_array(), k));
            row_where.push_back(where(row));
          }
          p.set(k, rows, at);
          p.set_row_locations(k, std::move(row_where));
        } else {
          p.set(k, numbers(arr, k), at);
        }
      } else {
        throw ConfigError(
            at, fmt::format("argument '{}' must be a boolean, number, string or list", k));
      }
    }
    return p;
  }

  std::vector<double> numbers(const toml::array& arr, const std::string& key) {
    std::vector<double> out;
    for (const auto& n : arr) out.push_back(number_of(n, key, "number"));
    return out;
  }

  /// The ECP image of `robot` that the check of its sub-tasks builds them with: the robot class
  /// of its ECP's configured task, on an in-process bus (nothing leaves the MP).
  ecp::Robot& check_robot(const std::string& robot) {
    auto it = check_robots_.find(robot);
    if (it != check_robots_.end()) return *it->second;
    const RobotConfig& config = context_.config.robot(robot);
    if (!config.ecp.library.empty()) load_plugin_library(config.ecp.library, config.ecp.where);
    if (!check_bus_) check_bus_ = std::make_unique<comm::Bus>(kCheckLcmUrl);
    return *check_robots_
                .emplace(robot, ecp::make_task_robot(config.ecp.name, *check_bus_, "mp", robot,
                                                     load_robot_model(config.model_dir)))
                .first->second;
  }

  /// Checks `step` as its ECP would at NEXT_STATE: the name registered, the arguments accepted.
  void check_subtask(const SubtaskStep& step, const toml::node* args_node,
                     const SourceLocation& name_where) {
    Params args(step.where);
    if (args_node != nullptr) {
      if (!args_node->is_table()) {
        errors_.add(ConfigError(where(*args_node),
                                "'args' must be a table of the sub-task's "
                                "arguments"));
        return;
      }
      if (!errors_.run({}, [&] { args = params_of(*args_node->as_table()); })) return;
    }
    errors_.run(step.where, [&] {
      ecp::Robot& robot = check_robot(step.robot);
      std::vector<std::string> vsps;
      for (const VspConfig& v : context_.config.vsps) vsps.push_back(v.name);
      const ecp::TaskContext check{robot,
                                   context_.reporter,
                                   args,
                                   context_.config.robot(step.robot).edp.servo_period_s,
                                   check_bus_.get(),
                                   "ecp/" + step.robot,
                                   nullptr,
                                   &vsps};
      errors_.add(ecp::check_ecp_task(step.subtask, check, name_where,
                                      args_node != nullptr ? where(*args_node) : step.where));
    });
  }

  /// Reads one robot's job: `robot`, `subtask`, `args` of table `t`.
  std::optional<SubtaskStep> step(const toml::table& t, const SourceLocation& at) {
    SubtaskStep s;
    s.where = at;
    const toml::node* robot = t.get("robot");
    const toml::node* subtask = t.get("subtask");
    bool ok = true;
    if (robot == nullptr || subtask == nullptr) {
      errors_.add(ConfigError(at, "a sub-task needs 'robot' and 'subtask' (an ECP task's name)"));
      return std::nullopt;
    }
    ok = errors_.run({}, [&] { s.robot = robot_at(*robot, "robot"); }) && ok;
    ok = errors_.run({}, [&] { s.subtask = string_of(*subtask, "subtask"); }) && ok;
    const toml::node* args = t.get("args");
    if (args != nullptr && args->is_table()) {
      toml::table copy = *args->as_table();
      copy.is_inline(false);
      std::ostringstream text;
      text << copy;
      s.arguments = text.str() + "\n";
    }
    if (ok) check_subtask(s, args, where(*subtask));
    return s;
  }

  MachineState state(const std::string& name, const toml::table& t) {
    MachineState s;
    s.name = name;
    s.where = where(t);
    const std::string what = fmt::format("state '{}'", name);
    only_keys(t, what, kStateKeys);
    std::vector<std::string> actions;
    for (const char* a : {"start_tasks", "subtask", "run", "wait", "delay"})
      if (t.get(a) != nullptr) actions.emplace_back(a);
    if (actions.size() > 1)
      errors_.add(ConfigError(s.where, fmt::format("{} does {}: one action per state (chain "
                                                   "states for more)",
                                                   what, fmt::join(actions, " and "))));
    if (t.get("robot") != nullptr && t.get("subtask") == nullptr)
      errors_.add(ConfigError(where(*t.get("robot")), fmt::format("{}: 'robot' without "
                                                                  "'subtask'",
                                                                  what)));
    if (t.get("args") != nullptr && t.get("subtask") == nullptr)
      errors_.add(
          ConfigError(where(*t.get("args")), fmt::format("{}: 'args' without 'subtask'", what)));
    const std::string action = actions.empty() ? "" : actions.front();
    if (action == "start_tasks") {
      s.action = MachineState::Action::start_tasks;
      const toml::node& list = *t.get("start_tasks");
      if (!list.is_array() || list.as_array()->empty())
        errors_.add(ConfigError(where(list), "'start_tasks' must be a list of robots' names"));
      else
        for (const auto& r : *list.as_array())
          errors_.run({}, [&] { s.start_robots.push_back(robot_at(r, "start_tasks")); });
    } else if (action == "subtask") {
      s.action = MachineState::Action::subtasks;
      if (auto one = step(t, s.where)) s.steps.push_back(*one);
    } else if (action == "run") {
      s.action = MachineState::Action::subtasks;
      const toml::node& list = *t.get("run");
      if (!list.is_array() || list.as_array()->empty()) {
        errors_.add(ConfigError(where(list),
                                "'run' must be a list of sub-tasks, { robot = "
                                "\"...\", subtask = \"...\", args = { ... } }"));
      } else {
        std::set<std::string> robots;
        for (const auto& item : *list.as_array()) {
          if (!item.is_table()) {
            errors_.add(ConfigError(where(item),
                                    "each of 'run' must be a table { robot, "
                                    "subtask, args }"));
            continue;
          }
          only_keys(*item.as_table(), fmt::format("a sub-task of {}", what),
                    {"robot", "subtask", "args"});
          if (auto one = step(*item.as_table(), where(item))) {
            if (!one->robot.empty() && !robots.insert(one->robot).second)
              errors_.add(ConfigError(
                  one->where,
                  fmt::format("{} gives robot '{}' two sub-tasks at once", what, one->robot)));
            s.steps.push_back(*one);
          }
        }
      }
    } else if (action == "wait") {
      s.action = MachineState::Action::wait;
      errors_.run({}, [&] { s.wait = condition(*t.get("wait"), "'wait'"); });
    } else if (action == "delay") {
      s.action = MachineState::Action::delay;
      errors_.run({}, [&] {
        s.delay_s = number_of(*t.get("delay"), "delay", "s");
        if (!(std::isfinite(s.delay_s) && s.delay_s >= 0.0))
          throw ConfigError(where(*t.get("delay")),
                            fmt::format("'delay' = {} s must be >= 0 s", s.delay_s));
      });
    }
    if (const toml::node* timeout = t.get("timeout"))
      errors_.run({}, [&] {
        s.timeout_s = number_of(*timeout, "timeout", "s");
        if (!(s.timeout_s > 0.0))
          throw ConfigError(where(*timeout),
                            fmt::format("'timeout' = {} s must be above 0 s", s.timeout_s));
        if (s.action == MachineState::Action::none || s.action == MachineState::Action::delay)
          throw ConfigError(where(*timeout), fmt::format("{}: 'timeout' limits a state's "
                                                         "start_tasks, subtask, run or wait",
                                                         what));
      });
    for (const char* k : {"report", "message"})
      if (const toml::node* text = t.get(k))
        errors_.run({}, [&] { (k[0] == 'r' ? s.report : s.message) = string_of(*text, k); });
    if (auto next = transition(t, "next", name))
      s.next = *next;
    else if (t.get("next") == nullptr)
      errors_.add(ConfigError(s.where, fmt::format("{} has no 'next' (the state after it "
                                                   "succeeded: a state, \"done\" or \"failed\")",
                                                   what)));
    s.on_timeout = transition(t, "on_timeout", name);
    if (s.on_timeout && !std::isfinite(s.timeout_s) && t.get("timeout") == nullptr)
      errors_.add(ConfigError(s.on_timeout->where,
                              fmt::format("{}: 'on_timeout' without a 'timeout'", what)));
    s.on_non_fatal = transition(t, "on_non_fatal", name);
    s.on_fatal = transition(t, "on_fatal", name);
    s.on_system = transition(t, "on_system", name);
    s.on_error = transition(t, "on_error", name);
    if (const toml::node* when = t.get("when")) {
      if (!when->is_array()) {
        errors_.add(
            ConfigError(where(*when), "'when' must be a list of conditions, each with its 'next'"));
      } else {
        for (const auto& item : *when->as_array()) {
          errors_.run({}, [&] {
            StateCondition c = condition(item, "a 'when' condition", {"next"});
            const toml::node* next = item.as_table()->get("next");
            if (next == nullptr)
              throw ConfigError(c.where, "a 'when' condition needs its 'next' state");
            Transition to{string_of(*next, "next"), where(*next)};
            check_target(to, fmt::format("'when' of state '{}': 'next'", name));
            s.when.emplace_back(std::move(c), std::move(to));
          });
        }
      }
    }
    if (s.action == MachineState::Action::none && s.when.empty() && actions.empty())
      errors_.add(ConfigError(s.where, fmt::format("{} does nothing: give it one of start_tasks, "
                                                   "subtask, run, wait, delay, or 'when' "
                                                   "conditions",
                                                   what)));
    return s;
  }

  /// Every state must be reached from the initial one by some transition.
  void check_reached(const StateMachine& machine) {
    if (machine.states.count(machine.initial) == 0) return;  // reported already
    std::set<std::string> reached{machine.initial};
    std::deque<std::string> open{machine.initial};
    while (!open.empty()) {
      const MachineState& s = machine.states.at(open.front());
      open.pop_front();
      std::vector<const Transition*> out{&s.next};
      for (const auto* t : {&s.on_timeout, &s.on_non_fatal, &s.on_fatal, &s.on_system, &s.on_error})
        if (*t) out.push_back(&**t);
      for (const auto& [c, t] : s.when) out.push_back(&t);
      for (const Transition* t : out) {
        // A mistyped target (reported already) counts as the state it suggests: the states
        // after it are not reported unreached for that one mistake.
        const std::string target = machine.states.count(t->target) != 0
                                       ? t->target
                                       : nearest_name(t->target, names_).value_or(t->target);
        if (machine.states.count(target) != 0 && reached.insert(target).second)
          open.push_back(target);
      }
    }
    for (const auto& [name, s] : machine.states)
      if (reached.count(name) == 0)
        errors_.add(ConfigError(s.where, fmt::format("state '{}' is never reached from the "
                                                     "initial state '{}'",
                                                     name, machine.initial)));
  }

  fs::path file_;
  const TaskContext& context_;
  ConfigErrorList& errors_;
  std::vector<std::string> names_;  ///< the states written in the file, in its order
  std::map<std::string, std::size_t> joints_;
  std::unique_ptr<comm::Bus> check_bus_;
  std::map<std::string, std::unique_ptr<ecp::Robot>> check_robots_;
};

}  // namespace

StateMachine read_state_machine(const fs::path& file, const TaskContext& context) {
  ConfigErrorList errors;
  StateMachine machine = Reader(file, context, errors).read();
  errors.throw_if_any();
  return machine;
}

}  // namespace mrroc::mp
