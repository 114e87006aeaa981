#pragma once
/// @file
/// MP -> ECP commands and ECP -> MP replies as plain C++ values.

#include <cstdint>
#include <string>
#include <vector>

#include "mrroc/core/error.hpp"
#include "mrroc/msg/edp_instruction.hpp"

namespace mrroc::ecp {

enum class MpCommandType : std::int8_t {
  start_task = 1,
  next_pose = 2,
  end_motion = 3,
  next_state = 4,
  stop = 5,
  pause = 6,
  resume = 7
};
const char* to_string(MpCommandType t);

struct MpCommand {
  MpCommandType type = MpCommandType::start_task;
  std::string state_name;  ///< NEXT_STATE: sub-task name
  std::string arguments;   ///< NEXT_STATE / START_TASK arguments
  // NEXT_POSE
  edp::ArmRepresentation arm_type = edp::ArmRepresentation::joint;
  edp::MotionType motion_type = edp::MotionType::absolute;
  int motion_steps = 1;
  int value_in_step_no = 2;
  std::vector<double> arm;
};

enum class EcpReplyType : std::int8_t { acknowledge = 1, task_terminated = 2, error = 3 };
/// Error classes, as the task API's exceptions (non-fatal, fatal, system): mrroc::ErrorClass.
using mrroc::ErrorClass;

/// Error codes of ECP replies. Errors the EDP reported are passed on with the EDP's code
/// (edp::error_code, 1..99); the ECP's own codes start at 101.
namespace error_code {
inline constexpr int malformed = 101;      ///< the MP command could not be decoded
inline constexpr int task_running = 102;   ///< START_TASK while the task runs
inline constexpr int stopped = 103;        ///< the task was stopped on request
inline constexpr int timeout = 104;        ///< a link (EDP) did not answer
inline constexpr int task_error = 105;     ///< any other error thrown by the task
inline constexpr int not_supported = 106;  ///< a command this ECP shell does not handle
inline constexpr int sensor_invalid =
    107;  ///< a virtual sensor gave no valid reading (stale, dead)
}  // namespace error_code

struct EcpReply {
  EcpReplyType type = EcpReplyType::acknowledge;
  int error_code = 0;
  ErrorClass error_class = ErrorClass::none;
  std::string error_text;
  bool synchronised = false;
  std::vector<double> joints;          ///< measured joint positions [rad]
  std::vector<double> desired_joints;  ///< commanded joint positions [rad]
  /// NEXT_POSE replies: the EDP's reading in the pose's representation.
  edp::ArmRepresentation arm_type = edp::ArmRepresentation::joint;
  std::vector<double> arm;
};

}  // namespace mrroc::ecp
