#pragma once
/// @file
/// Codecs of the messages that are not request/reply links of the control path (codec.hpp has
/// those): emergency stop, robot state, SRP messages and history, process status, the
/// operator's commands to the MP, the launcher's table and commands, and the cell emulator's
/// scene objects. Like codec.hpp,
/// `decode` validates every enumeration, count and size and throws `DecodeError` naming the
/// message, the field and the value. The header (sender, time, sequence) is not part of the
/// plain values: broadcasts set it from an `Envelope` and subscribers see it (comm/edge.hpp).
///
/// `MessageTraits<Plain>::Lcm` names the LCM type of each plain message type, for
/// the typed publisher and subscriber of comm/edge.hpp and the typed links of comm/links.hpp.

#include "mrroc/comm/codec.hpp"
#include "mrroc/msg/emergency_stop.hpp"
#include "mrroc/msg/launch.hpp"
#include "mrroc/msg/operator.hpp"
#include "mrroc/msg/robot_state.hpp"
#include "mrroc/msg/scene_objects.hpp"
#include "mrroc/msg/system.hpp"
#include "mrroc_lcm/emergency_stop_t.hpp"
#include "mrroc_lcm/launch_command_t.hpp"
#include "mrroc_lcm/launch_process_t.hpp"
#include "mrroc_lcm/launch_status_t.hpp"
#include "mrroc_lcm/operator_command_t.hpp"
#include "mrroc_lcm/operator_reply_t.hpp"
#include "mrroc_lcm/process_status_t.hpp"
#include "mrroc_lcm/robot_state_t.hpp"
#include "mrroc_lcm/scene_object_t.hpp"
#include "mrroc_lcm/scene_objects_t.hpp"
#include "mrroc_lcm/srp_history_reply_t.hpp"
#include "mrroc_lcm/srp_history_request_t.hpp"
#include "mrroc_lcm/srp_message_t.hpp"

namespace mrroc::comm {

/// Most entries in one srp_history_reply_t (the SRP never sends more).
inline constexpr int kMaxHistoryEntries = 500;
/// Most processes in one launch_status_t.
inline constexpr int kMaxLaunchProcesses = 4096;
/// Most objects in one scene_objects_t.
inline constexpr int kMaxSceneObjects = 256;

mrroc_lcm::emergency_stop_t encode(const EmergencyStop& in);
EmergencyStop decode(const mrroc_lcm::emergency_stop_t& msg);

/// @throws Error when the joint vectors differ in length or have more than kMaxVector values.
mrroc_lcm::robot_state_t encode(const RobotState& in);
RobotState decode(const mrroc_lcm::robot_state_t& msg);

mrroc_lcm::srp_message_t encode(const SrpMessage& in);
SrpMessage decode(const mrroc_lcm::srp_message_t& msg);
/// `utime` is not encoded (the header carries the time of sending); decode takes header.utime.
mrroc_lcm::process_status_t encode(const ProcessStatus& in);
ProcessStatus decode(const mrroc_lcm::process_status_t& msg);
mrroc_lcm::srp_history_request_t encode(const SrpHistoryRequest& in);
SrpHistoryRequest decode(const mrroc_lcm::srp_history_request_t& msg);
/// @throws Error with more than kMaxHistoryEntries entries.
mrroc_lcm::srp_history_reply_t encode(const SrpHistoryReply& in);
SrpHistoryReply decode(const mrroc_lcm::srp_history_reply_t& msg);

mrroc_lcm::operator_command_t encode(const mp::OperatorCommand& in);
mp::OperatorCommand decode(const mrroc_lcm::operator_command_t& msg);
mrroc_lcm::operator_reply_t encode(const mp::OperatorReply& in);
mp::OperatorReply decode(const mrroc_lcm::operator_reply_t& msg);

/// `utime` is not encoded (the header carries it); decode takes header.utime. @throws Error
/// with more than kMaxLaunchProcesses rows.
mrroc_lcm::launch_status_t encode(const launch::LaunchStatus& in);
launch::LaunchStatus decode(const mrroc_lcm::launch_status_t& msg);
mrroc_lcm::launch_command_t encode(const launch::LaunchCommand& in);
launch::LaunchCommand decode(const mrroc_lcm::launch_command_t& msg);

/// @throws Error with more than kMaxSceneObjects objects or a size of the wrong count for its
/// shape. decode also refuses values that are not finite and a size not above 0.
mrroc_lcm::scene_objects_t encode(const SceneObjects& in);
SceneObjects decode(const mrroc_lcm::scene_objects_t& msg);

/// The LCM type of a plain message type (specialised for each of them below).
template <class Plain>
struct MessageTraits;

#define MRROC_MESSAGE_TRAITS(PLAIN, LCM) \
  template <>                            \
  struct MessageTraits<PLAIN> {          \
    using Lcm = mrroc_lcm::LCM;          \
  }
MRROC_MESSAGE_TRAITS(edp::Instruction, edp_instruction_t);
MRROC_MESSAGE_TRAITS(edp::Reply, edp_reply_t);
MRROC_MESSAGE_TRAITS(ecp::MpCommand, mp_ecp_command_t);
MRROC_MESSAGE_TRAITS(ecp::EcpReply, ecp_mp_reply_t);
MRROC_MESSAGE_TRAITS(vsp::Request, vsp_command_t);
MRROC_MESSAGE_TRAITS(vsp::Reply, vsp_reply_t);
MRROC_MESSAGE_TRAITS(vsp::RawSample, raw_sensor_t);
MRROC_MESSAGE_TRAITS(EmergencyStop, emergency_stop_t);
MRROC_MESSAGE_TRAITS(RobotState, robot_state_t);
MRROC_MESSAGE_TRAITS(SrpMessage, srp_message_t);
MRROC_MESSAGE_TRAITS(ProcessStatus, process_status_t);
MRROC_MESSAGE_TRAITS(SrpHistoryRequest, srp_history_request_t);
MRROC_MESSAGE_TRAITS(SrpHistoryReply, srp_history_reply_t);
MRROC_MESSAGE_TRAITS(mp::OperatorCommand, operator_command_t);
MRROC_MESSAGE_TRAITS(mp::OperatorReply, operator_reply_t);
MRROC_MESSAGE_TRAITS(launch::LaunchStatus, launch_status_t);
MRROC_MESSAGE_TRAITS(launch::LaunchCommand, launch_command_t);
MRROC_MESSAGE_TRAITS(SceneObjects, scene_objects_t);
#undef MRROC_MESSAGE_TRAITS
// header_t, launch_process_t and scene_object_t are parts of other messages (the header:
// Envelope, edge.hpp; a launch_process_t: launch::ProcessRow inside launch::LaunchStatus; a
// scene_object_t: SceneObjectPose inside SceneObjects).

}  // namespace mrroc::comm
