#pragma once
/// @file
/// ECP -> EDP instructions and EDP replies as plain C++ values (paper, section 5).
/// Units: rad and m; arm and tool vectors are laid out as described for each representation.

#include <cstdint>
#include <string>
#include <vector>

#include "mrroc/core/error.hpp"

namespace mrroc::edp {

enum class InstructionType : std::int8_t { set = 1, get = 2, set_get = 3, synchro = 4, query = 5 };

/// What a SET changes or a GET reads (bit mask).
namespace item {
inline constexpr std::uint8_t arm = 1;
inline constexpr std::uint8_t tool = 2;
inline constexpr std::uint8_t model = 4;     ///< kinematic model and local corrector
inline constexpr std::uint8_t servo = 8;     ///< servo algorithm and parameters
inline constexpr std::uint8_t outputs = 16;  ///< binary outputs (SET)
inline constexpr std::uint8_t inputs = 32;   ///< binary inputs (GET)
inline constexpr std::uint8_t timing = 64;   ///< servo-loop timing statistics (GET)
/// The device-dependent command (SET) and reply (GET) of the hardware plugin's device, e.g. a
/// gripper (docs/edp.md, "Devices").
inline constexpr std::uint8_t device = 128;
}  // namespace item

/// Arm and tool representations.
/// - frame: 12 values, the 3x4 homogeneous matrix [R | p] row by row [-, m]
/// - xyz_euler_zyz: x, y, z [m], then Euler Z-Y-Z angles [rad]
/// - xyz_angle_axis: x, y, z [m], then the rotation vector (axis * angle) [rad]
/// - joint: one joint coordinate per axis [rad or m]
/// - motor: one motor shaft angle per axis [rad]
enum class ArmRepresentation : std::int8_t {
  frame = 1,
  xyz_euler_zyz = 2,
  xyz_angle_axis = 3,
  joint = 4,
  motor = 5
};

enum class MotionType : std::int8_t { absolute = 1, relative = 2 };

/// Name of a representation for messages ("JOINT", "MOTOR", ...).
const char* to_string(ArmRepresentation r);
const char* to_string(InstructionType t);

struct Instruction {
  InstructionType type = InstructionType::query;
  std::uint8_t set = 0;  ///< item:: bits changed by SET / SET_GET
  std::uint8_t get = 0;  ///< item:: bits read by GET / SET_GET

  ArmRepresentation set_arm_type = ArmRepresentation::joint;
  ArmRepresentation get_arm_type = ArmRepresentation::joint;
  MotionType motion_type = MotionType::absolute;
  int motion_steps = 1;      ///< servo steps of the macro-step (>= 1)
  int value_in_step_no = 2;  ///< step producing the QUERY reply (1..motion_steps+1)
  std::vector<double> arm;

  ArmRepresentation tool_type = ArmRepresentation::frame;
  std::vector<double> tool;

  int kinematic_model_no = 0;
  int corrector_no = 0;

  std::vector<std::int8_t> servo_algorithm;
  std::vector<std::int8_t> servo_parameters_no;

  std::uint32_t output_values = 0;

  /// SET DEVICE: one value per command field of the plugin's device, in its order and units
  /// (Hardware::device(); e.g. a gripper's opening [m] and force [N]).
  std::vector<double> device;

  /// The reply carries the result a QUERY would return (for SET ARM the reading taken in step
  /// `value_in_step_no`, or as the EDP's lookahead allows, see docs/edp.md) and no QUERY follows:
  /// one exchange per macro-step. False: the paper's SET + QUERY sequence.
  bool with_query = false;
  /// No macro-step follows those already sent (the task pauses or stops on purpose): the
  /// stopping ramp at the end of the queue is a planned stop, not a lost successor.
  bool no_successor = false;
  /// The sender takes the EDP over while the robot is at rest (docs/edp.md, "One owner at a
  /// time").
  bool take_over = false;
};

enum class ReplyType : std::int8_t { acknowledge = 1, data = 2, error = 3 };

/// Error codes of EDP replies (docs/messages.md).
namespace error_code {
inline constexpr int none = 0;
inline constexpr int malformed = 1;         ///< the instruction could not be decoded
inline constexpr int query_expected = 2;    ///< a QUERY must follow every other instruction
inline constexpr int query_unexpected = 3;  ///< QUERY without a preceding instruction
inline constexpr int not_synchronised = 4;  ///< motion before SYNCHRO
inline constexpr int already_synchronised = 5;
inline constexpr int out_of_limits = 6;    ///< the path leaves a joint or motor limit
inline constexpr int bad_argument = 7;     ///< wrong size, steps, representation not supported
inline constexpr int hardware_fault = 8;   ///< the hardware plugin reported a fault
inline constexpr int not_supported = 9;    ///< valid instruction that this EDP does not support
inline constexpr int emergency_stop = 10;  ///< motion refused: emergency stop engaged
inline constexpr int servo_overrun = 11;   ///< a servo cycle woke more than one period late
inline constexpr int unauthenticated =
    12;                                ///< a message without a valid HMAC or replayed (SRP report)
inline constexpr int too_fast = 13;    ///< a macro-step would exceed a joint's velocity limit
inline constexpr int too_abrupt = 14;  ///< a macro-step would exceed a joint's acceleration limit
inline constexpr int not_owner = 15;   ///< another client drives this EDP
/// a macro-step would bring a link closer than the clearance to the cell or the robot itself
inline constexpr int collision = 16;
}  // namespace error_code

/// The class of each EDP error code (mrroc::ErrorClass): the one table the EDP answers with.
/// non_fatal: the instruction was refused and nothing moved (a limit, not synchronised, a bad
/// argument, too fast or abrupt, a collision, a QUERY out of order); fatal: the robot cannot go on
/// as it is (a drive fault, an emergency stop, another owner); system: the link or message failed
/// (malformed, not authentic).
constexpr ErrorClass error_class_of(int code) {
  switch (code) {
    case error_code::none: return ErrorClass::none;
    case error_code::query_expected:
    case error_code::query_unexpected:
    case error_code::not_synchronised:
    case error_code::already_synchronised:
    case error_code::out_of_limits:
    case error_code::bad_argument:
    case error_code::not_supported:
    case error_code::too_fast:
    case error_code::too_abrupt:
    case error_code::collision: return ErrorClass::non_fatal;
    case error_code::hardware_fault:
    case error_code::emergency_stop:
    case error_code::servo_overrun:
    case error_code::not_owner: return ErrorClass::fatal;
    case error_code::malformed:
    case error_code::unauthenticated: return ErrorClass::system;
    default: return ErrorClass::fatal;
  }
}

struct Reply {
  ReplyType type = ReplyType::acknowledge;
  int error_code = 0;
  /// ERROR: the class of error_code (error_class_of), none otherwise.
  ErrorClass error_class = ErrorClass::none;
  std::string error_text;
  bool synchronised = false;
  int step_no = 0;               ///< step of the macro-step in which the reading was taken
  std::int64_t servo_cycle = 0;  ///< servo cycle counter at the reading
  /// Macro-steps queued in the EDP when the reading was taken, the running one included: how far
  /// the commands run ahead of the robot (0: it had nothing left to do).
  int macro_steps_ahead = 0;

  ArmRepresentation arm_type = ArmRepresentation::joint;
  std::vector<double> arm;               ///< in arm_type
  std::vector<double> joints;            ///< measured joint positions [rad]
  std::vector<double> desired_joints;    ///< commanded joint positions [rad]
  std::vector<double> joint_velocities;  ///< measured joint velocities [rad/s]

  ArmRepresentation tool_type = ArmRepresentation::frame;
  std::vector<double> tool;
  int kinematic_model_no = 0;
  int corrector_no = 0;
  std::vector<std::int8_t> servo_algorithm;
  std::vector<std::int8_t> servo_parameters_no;
  std::uint32_t input_values = 0;
  /// GET DEVICE: one value per reply field of the plugin's device, in its order and units.
  std::vector<double> device;

  /// Servo-loop timing (filled for GET with item::timing).
  std::int64_t servo_cycles = 0;
  std::int64_t servo_overruns = 0;  ///< cycles woken more than one period late
  double servo_period_us = 0;
  double lateness_p50_us = 0;
  double lateness_p99_us = 0;
  double lateness_max_us = 0;
};

}  // namespace mrroc::edp
