// Stock MP task "state_machine": a task written as data. Its states and transitions come from a
// TOML file (state_machine_file.hpp; docs/writing-a-task.md, "Tasks as state machines"), read
// and checked whole when the task is built, so that `mrroc-launch --check` reports every
// mistake of the file before anything starts.
//
// [mp.args]: file = "tasks/name.fsm.toml" (relative to the config file's folder).
#include <fmt/format.h>

#include <chrono>
#include <cmath>
#include <exception>
#include <map>
#include <mutex>
#include <optional>

#include "mrroc/config/check.hpp"
#include "mrroc/ecp/robot_image.hpp"
#include "mrroc/ecp/virtual_sensor.hpp"
#include "mrroc/mp/task.hpp"
#include "state_machine_file.hpp"

namespace mrroc::mp {

namespace {

namespace fs = std::filesystem;

/// How a state's action ended.
struct Outcome {
  enum class Kind { success, timeout, error };
  Kind kind = Kind::success;
  ErrorClass error_class = ErrorClass::none;
  std::string text;  ///< the error's (or the timeout's) description
};

/// The class of the error `error` (RemoteError: the peer's; no reply in time, or anything
/// else: system). A STOP of the task is no error of a state: it is thrown on.
ErrorClass class_of(const std::exception_ptr& error, std::string& text) {
  try {
    std::rethrow_exception(error);
  } catch (const ecp::TaskStopped&) {
    throw;
  } catch (const RemoteError& e) {
    text = e.what();
    return e.error_class();
  } catch (const std::exception& e) {
    text = e.what();
    return ErrorClass::system;
  }
}

/// The image value a condition tests, from `robots` (state images) and `sensors`.
class ConditionTest : public Condition {
 public:
  ConditionTest(const StateCondition& spec, const RobotList& robots, ecp::VirtualSensor* sensor)
      : spec_(spec), sensor_(sensor) {
    for (std::size_t i = 0; i < robots.size(); ++i)
      if (robots[i]->name() == spec.robot) index_ = i;
  }

  bool check(const ImageList& robots, const ecp::SensorList& /*sensors*/) override {
    if (spec_.kind == StateCondition::Kind::sensor) return in_range(sensor_->value(spec_.value));
    const RobotImage& image = *robots.at(index_);
    if (image.state_servo_step < 0) return false;  // no state of the robot yet
    if (spec_.kind == StateCondition::Kind::moving) return image.moving == spec_.moving;
    if (spec_.joint >= image.joints.size()) return false;
    return in_range(image.joints[spec_.joint]);
  }

  /// The tested value as it was last seen, for the reports.
  [[nodiscard]] std::string seen() const {
    return std::isnan(last_) ? std::string{} : fmt::format(" ({:.4f})", last_);
  }

 private:
  bool in_range(double v) {
    last_ = v;
    return (!spec_.above || v > *spec_.above) && (!spec_.below || v < *spec_.below);
  }

  const StateCondition& spec_;
  ecp::VirtualSensor* sensor_;
  std::size_t index_ = 0;
  double last_ = std::nan("");
};

}  // namespace

class StateMachineTask : public MpTask {
 public:
  explicit StateMachineTask(TaskContext& context) : context_(context) {
    const Params& a = context.args;
    std::string name;
    ConfigErrorList errors;
    errors.run(a.location(), [&] { name = a.get_string("file"); });
    errors.run(a.location(), [&] { a.reject_unread("mp.args"); });
    errors.throw_if_any();
    fs::path file = name;
    if (file.is_relative()) file = context.config.file.parent_path() / file;
    if (!fs::is_regular_file(file))
      throw ConfigError(a.location_of("file"),
                        fmt::format("state machine file '{}' not found", file.string()));
    machine_ = read_state_machine(file.lexically_normal(), context);
  }

  void main_task() override {
    Reporter& log = context_.reporter;
    open_sensors();
    std::string current = machine_.initial;
    log.info(fmt::format("state machine '{}': initial state '{}'",
                         machine_.file.filename().string(), current));
    for (;;) {
      if (task_stop_requested()) throw ecp::TaskStopped("task stopped on request");
      const MachineState& state = machine_.states.at(current);
      Outcome outcome = run(state);
      std::optional<std::pair<std::string, std::string>> chosen;
      if (outcome.kind == Outcome::Kind::success) {
        // A sensor that cannot be read for a 'when' condition is an error of the state.
        try {
          chosen = decide(state);
        } catch (const ecp::TaskStopped&) {
          throw;
        } catch (...) {
          outcome.kind = Outcome::Kind::error;
          outcome.error_class = class_of(std::current_exception(), outcome.text);
        }
      }
      const auto [next, why] = chosen ? *chosen : transition(state, outcome);
      if (outcome.kind == Outcome::Kind::success && !state.report.empty()) log.info(state.report);
      log.info(fmt::format("state '{}' -> '{}' ({})", state.name, next, why));
      if (next == kStateDone) return;
      if (next == kStateFailed) {
        std::string text = state.message.empty()
                               ? fmt::format("state machine failed in state '{}'", state.name)
                               : state.message;
        if (!outcome.text.empty()) text += fmt::format(" ({})", outcome.text);
        throw Error(text);
      }
      current = next;
    }
  }

 private:
  /// The VSP clients the machine's sensor conditions read, one per VSP.
  void open_sensors() {
    const auto open = [&](const StateCondition& c) {
      if (c.kind == StateCondition::Kind::sensor && sensors_.count(c.sensor) == 0)
        sensors_[c.sensor] = context_.sensor(c.sensor);
    };
    for (const auto& [name, s] : machine_.states) {
      if (s.wait) open(*s.wait);
      for (const auto& [c, t] : s.when) open(c);
    }
  }

  ecp::VirtualSensor* sensor_of(const StateCondition& c) {
    return c.kind == StateCondition::Kind::sensor ? sensors_.at(c.sensor).get() : nullptr;
  }

  /// The target of the first of `state`'s `when` conditions that holds now, and why; else the
  /// success transition `next`.
  std::pair<std::string, std::string> decide(const MachineState& state) {
    for (const auto& [condition, to] : state.when) {
      ConditionTest test(condition, context_.robots, sensor_of(condition));
      const ImageList images = state_images();
      if (ecp::VirtualSensor* s = sensor_of(condition)) {
        s->initiate_reading();
        s->get_reading();
      }
      if (test.check(images, ecp::SensorList{}))
        return {to.target, fmt::format("{} holds{}", condition.describe(), test.seen())};
    }
    return {state.next.target, "succeeded"};
  }

  /// The state after `state` ended with `outcome` (not a success), and why it was chosen.
  std::pair<std::string, std::string> transition(const MachineState& state,
                                                 const Outcome& outcome) {
    switch (outcome.kind) {
      case Outcome::Kind::success: return decide(state);
      case Outcome::Kind::timeout:
        if (state.on_timeout) return {state.on_timeout->target, outcome.text};
        throw TimeoutError(outcome.text);
      case Outcome::Kind::error: {
        const std::optional<Transition>& by_class =
            outcome.error_class == ErrorClass::non_fatal ? state.on_non_fatal
            : outcome.error_class == ErrorClass::fatal   ? state.on_fatal
                                                         : state.on_system;
        const std::optional<Transition>& to = by_class ? by_class : state.on_error;
        const std::string why =
            fmt::format("{} error: {}", to_string(outcome.error_class), outcome.text);
        if (to) return {to->target, why};
        throw Error(fmt::format("state '{}': {}", state.name, outcome.text));
      }
    }
    return {kStateFailed, "?"};
  }

  ImageList state_images() {
    images_.clear();
    for (Robot* r : context_.robots) images_.push_back(r->state_image());
    ImageList list;
    for (RobotImage& i : images_) list.push_back(&i);
    return list;
  }

  Outcome run(const MachineState& state) {
    switch (state.action) {
      case MachineState::Action::none: return {};
      case MachineState::Action::start_tasks: {
        std::map<std::string, const SubtaskStep*> none;
        return run_robots(state, state.start_robots, none);
      }
      case MachineState::Action::subtasks: {
        std::vector<std::string> robots;
        std::map<std::string, const SubtaskStep*> steps;
        for (const SubtaskStep& s : state.steps) {
          robots.push_back(s.robot);
          steps[s.robot] = &s;
        }
        return run_robots(state, robots, steps);
      }
      case MachineState::Action::wait: return wait(state, *state.wait);
      case MachineState::Action::delay: {
        Delay delay(state.delay_s);
        Wait(RobotList{}, ecp::SensorList{}, delay);
        return {};
      }
    }
    return {};
  }

  /// START_TASK (no step) or NEXT_STATE to every robot of `names` at once; waits for all, at
  /// most the state's timeout (then STOP to those still at work).
  Outcome run_robots(const MachineState& state, const std::vector<std::string>& names,
                     const std::map<std::string, const SubtaskStep*>& steps) {
    RobotList robots;
    for (const std::string& n : names) robots.push_back(&context_.robot(n));
    std::mutex mutex;
    std::exception_ptr first_error;
    std::string failed_robot;
    const auto job = [&](Robot& r) {
      try {
        const auto it = steps.find(r.name());
        if (it == steps.end()) {
          context_.reporter.info(fmt::format("START_TASK -> ecp/{}", r.name()));
          r.start_task();
        } else {
          r.next_state(it->second->subtask, it->second->arguments);
        }
      } catch (...) {
        std::lock_guard lock(mutex);
        if (!first_error) {
          first_error = std::current_exception();
          failed_robot = r.name();
        }
      }
    };
    bool timed_out = false;
    {
      Running running(robots, job);
      const auto deadline =
          std::chrono::steady_clock::now() +
          std::chrono::duration<double>(std::isfinite(state.timeout_s) ? state.timeout_s : 1e9);
      for (std::size_t done = 0; done < robots.size(); ++done) {
        const double left =
            std::chrono::duration<double>(deadline - std::chrono::steady_clock::now()).count();
        try {
          (void)running.wait_any(std::isfinite(state.timeout_s) ? std::max(0.0, left)
                                                                : state.timeout_s);
        } catch (const TimeoutError&) {
          timed_out = true;
          for (Robot* r : robots) r->stop();  // those done ignore it
          break;
        }
      }
    }  // every job has ended here
    if (task_stop_requested()) throw ecp::TaskStopped("task stopped on request");
    if (timed_out)
      return {Outcome::Kind::timeout, ErrorClass::none,
              fmt::format("state '{}' took longer than its timeout of {} s", state.name,
                          state.timeout_s)};
    if (first_error) {
      Outcome o{Outcome::Kind::error, ErrorClass::none, {}};
      o.error_class = class_of(first_error, o.text);
      o.text = fmt::format("{}: {}", failed_robot, o.text);
      return o;
    }
    return {};
  }

  Outcome wait(const MachineState& state, const StateCondition& spec) {
    ConditionTest test(spec, context_.robots, sensor_of(spec));
    ecp::SensorList sensors;
    if (ecp::VirtualSensor* s = sensor_of(spec)) sensors.push_back(s);
    try {
      Wait(context_.robots, sensors, test, 0.02, state.timeout_s);
    } catch (const TimeoutError&) {
      return {Outcome::Kind::timeout, ErrorClass::none,
              fmt::format("{} did not hold within {} s{}", spec.describe(), state.timeout_s,
                          test.seen())};
    } catch (const ecp::TaskStopped&) {
      throw;
    } catch (...) {
      Outcome o{Outcome::Kind::error, ErrorClass::none, {}};
      o.error_class = class_of(std::current_exception(), o.text);
      return o;
    }
    context_.reporter.info(fmt::format("{} holds{}", spec.describe(), test.seen()));
    return {};
  }

  /// Holds when `delay_s` has passed since it was made.
  class Delay : public Condition {
   public:
    explicit Delay(double delay_s)
        : end_(std::chrono::steady_clock::now() +
               std::chrono::duration_cast<std::chrono::steady_clock::duration>(
                   std::chrono::duration<double>(delay_s))) {}
    bool check(const ImageList& /*robots*/, const ecp::SensorList& /*sensors*/) override {
      return std::chrono::steady_clock::now() >= end_;
    }

   private:
    std::chrono::steady_clock::time_point end_;
  };

  TaskContext& context_;
  StateMachine machine_;
  std::map<std::string, std::unique_ptr<ecp::VirtualSensor>> sensors_;
  std::vector<RobotImage> images_;
};

MRROC_REGISTER_MP_TASK("state_machine", StateMachineTask);

}  // namespace mrroc::mp
