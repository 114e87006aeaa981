#pragma once
/// @file
/// The operator's commands to the MP and its answers (operator_command_t / operator_reply_t on
/// mrroc/mp/cmd and mrroc/mp/reply, over request/reply) as plain values.

#include <cstdint>
#include <string>

namespace mrroc::mp {

enum class OperatorCommandType : std::int8_t {
  start = 1,      ///< start the MP task (only when [mp] start = "operator")
  pause = 2,      ///< every ECP holds before its next motion
  resume = 3,     ///< continue after PAUSE
  stop = 4,       ///< stop the running task (the robots hold); START may follow
  terminate = 5,  ///< stop the task if running, then end the MP (and the set)
  status = 6,     ///< only report the state
};
/// "START", "PAUSE", ...
const char* to_string(OperatorCommandType c);

struct OperatorCommand {
  OperatorCommandType type = OperatorCommandType::status;
};

/// The MP task's state.
enum class TaskState : std::int8_t {
  idle = 1,  ///< waiting for START
  running = 2,
  paused = 3,
  stopping = 4,
  finished = 5,  ///< the last run finished
  failed = 6,    ///< the last run failed or was stopped
  terminating = 7,
};
/// "IDLE", "RUNNING", ...
const char* to_string(TaskState s);

struct OperatorReply {
  bool accepted = false;  ///< false: the command does not apply in this state (see text)
  TaskState state = TaskState::idle;  ///< after the command
  std::string task;                   ///< the MP task's name
  int runs = 0;                       ///< how many times the task was started
  std::int64_t started_utime = 0;     ///< start of the current or last run [us], 0 if none
  std::string text;                   ///< why a command was refused, or the last run's error
};

}  // namespace mrroc::mp
