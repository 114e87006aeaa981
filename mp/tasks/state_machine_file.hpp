#pragma once
/// @file
/// A task written as data: the states of the MP task "state_machine", read from a TOML file
/// (docs/writing-a-task.md, "Tasks as state machines"). Each state does one thing through the MP
/// API (START_TASK, NEXT_STATE with a sub-task of an ECP, Wait on a condition, a delay) and
/// names the state that follows on success, on an error of each class, on a timeout and when a
/// condition holds. `done` and `failed` end the task.
///
/// The file is checked whole before anything starts: every error is reported at once, each at
/// its `file:line`.

#include <filesystem>
#include <limits>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "mrroc/core/error.hpp"
#include "mrroc/mp/task.hpp"

namespace mrroc::mp {

/// The two states every machine has without writing them.
inline constexpr const char* kStateDone = "done";
inline constexpr const char* kStateFailed = "failed";

/// A test of the robots' or the sensors' images: `robot`'s joint `joint` [rad | m], whether
/// `robot` moves, or value `value` of VSP `sensor`'s reading. The value condition holds when it
/// is above `above` and below `below` (each where given).
struct StateCondition {
  enum class Kind { joint, moving, sensor };
  Kind kind = Kind::joint;
  std::string robot;
  std::size_t joint = 0;
  bool moving = false;
  std::string sensor;
  std::string value;
  std::optional<double> above;
  std::optional<double> below;
  SourceLocation where;

  /// "conveyor joint 0 in (1.198, 1.202)", for the task's reports.
  [[nodiscard]] std::string describe() const;
};

/// The name of the state a transition goes to, and where it was written.
struct Transition {
  std::string target;
  SourceLocation where;
};

/// One robot's job in a state: NEXT_STATE `subtask` with TOML `arguments` to its ECP.
struct SubtaskStep {
  std::string robot;
  std::string subtask;
  std::string arguments;  ///< TOML `key = value` lines, as NEXT_STATE carries them
  SourceLocation where;
};

struct MachineState {
  /// What the state does: nothing (a decision on its `when` conditions), START_TASK to robots,
  /// NEXT_STATE to robots (all at once), a wait for a condition, a delay.
  enum class Action { none, start_tasks, subtasks, wait, delay };

  std::string name;
  SourceLocation where;
  Action action = Action::none;
  std::vector<std::string> start_robots;  ///< start_tasks
  std::vector<SubtaskStep> steps;         ///< subtasks: at most one per robot
  std::optional<StateCondition> wait;     ///< wait
  double delay_s = 0.0;                   ///< delay [s]
  /// The longest the action may take [s]; then the robots still at work get STOP and the
  /// machine goes to `on_timeout` (infinity: no limit).
  double timeout_s = std::numeric_limits<double>::infinity();
  std::string report;   ///< reported when the action succeeded (empty: nothing)
  std::string message;  ///< the failure's text when this state goes to `failed`

  Transition next;  ///< on success, when no `when` condition holds
  std::vector<std::pair<StateCondition, Transition>> when;  ///< tested in order after success
  std::optional<Transition> on_timeout;
  std::optional<Transition> on_non_fatal;
  std::optional<Transition> on_fatal;
  std::optional<Transition> on_system;
  std::optional<Transition> on_error;  ///< an error of a class without its own transition
};

struct StateMachine {
  std::filesystem::path file;
  std::string initial;
  std::map<std::string, MachineState> states;
};

/// Reads and checks the state machine in `file` for the robots, VSPs and ECP tasks of
/// `context`: every target state known, the initial state given and known, every state reached
/// from it, robots and VSPs of the process set, joints of the robot's model, each sub-task a
/// registered ECP task whose constructor accepts its arguments (as the ECP would at NEXT_STATE,
/// for the robot class of that ECP's configured task).
/// @throws ConfigErrors with every error found, each at its `file:line`.
[[nodiscard]] StateMachine read_state_machine(const std::filesystem::path& file,
                                              const TaskContext& context);

}  // namespace mrroc::mp
