#pragma once
/// @file
/// The EDP's command interpreter: the MRROC++ instruction state machine on top of the servo loop.
///
/// - SET, GET, SET_GET and SYNCHRO are answered at once with ACKNOWLEDGE (accepted) or ERROR
///   (refused: nothing moves). An accepted instruction must be followed by QUERY, whose reply
///   carries the result: for SET ARM the reading taken in step `value_in_step_no`, for SYNCHRO
///   the state after synchronisation, for GET the current reading.
/// - An instruction with `with_query` is answered with that result directly (one exchange; no
///   QUERY follows).
/// - With a lookahead of D macro-steps (ServoLoop::set_lookahead), the result of a SET ARM that
///   promises a successor (value_in_step_no < motion_steps) is the reading taken in step
///   value_in_step_no of the macro-step D - 1 places before it, so the client may run up to D
///   macro-steps ahead of the robot; a SET ARM that promises none is answered with its own
///   reading (docs/edp.md, "Lookahead").
/// - Any other instruction while a QUERY is due is refused with "query expected"; a QUERY with
///   nothing due is refused with "query unexpected".
/// - One owner at a time (execute with a client name): instructions of any other client are
///   refused (`not_owner`) unless it takes over (`take_over`) while the robot is at rest, or the
///   owner has been silent for the lease with the robot at rest.
/// - SET DEVICE and GET DEVICE reach the plugin's device (Hardware::device()); a plugin without
///   one refuses them (`not_supported`). Every commanded field must be finite and inside its
///   range (`bad_argument`, `out_of_limits`, naming field, value, unit and limit), the command
///   must have one value per field, and SET DEVICE is refused during an emergency stop. It needs
///   no SYNCHRO.
/// - Before SYNCHRO only RELATIVE MOTOR and JOINT moves are accepted (the position is unknown;
///   docs/edp.md, "Motion before synchronisation"): each joint's change at most
///   `[robot.edp] unsynchronised_max_move` (no joint limit can be checked), planned by the
///   servo loop within its reduced velocity and acceleration limits; ABSOLUTE and Cartesian
///   moves are refused ("not synchronised"). SYNCHRO is refused while such a move still runs,
///   and a second SYNCHRO is refused ("already synchronised").
/// - A SET applies MODEL first, then TOOL, then ARM (so an arm target in the same SET uses the new
///   model and tool); if any item is refused, none is applied.
/// - Arm targets in every representation become joint targets (inverse kinematics for frames,
///   the transmission for motors); RELATIVE targets are relative to where the motion already
///   queued ends (joint/motor: added; frames: composed in the current tool frame). The macro-step
///   is interpolated linearly in joint coordinates, and every interpolation step is checked
///   against the joint (and linkage) and motor limits before anything moves.

#include <chrono>
#include <optional>
#include <string>

#include "mrroc/edp/arm_kinematics.hpp"
#include "mrroc/msg/edp_instruction.hpp"
#include "mrroc/robot/robot_model.hpp"
#include "servo_loop.hpp"

namespace mrroc::edp {

class CollisionGuard;

class CommandInterpreter {
 public:
  CommandInterpreter(ServoLoop& servo, const RobotModel& model, ArmKinematics& kinematics,
                     double servo_period_s);

  /// Executes one instruction and returns the reply to send. Blocks for a QUERY until its
  /// reading is ready. Never throws: refusals become ERROR replies.
  Reply execute(const Instruction& instruction);
  /// The same, from client `client` (its endpoint name): only the EDP's owner is obeyed. The
  /// first client becomes the owner; another one takes over with `take_over` while the robot is
  /// at rest, or without it once the owner has been silent for `owner_lease_s` with the robot at
  /// rest (a client that died or gave up). A change of owner forgets the QUERY due to the old one.
  Reply execute(const Instruction& instruction, const std::string& client);
  /// The client whose instructions are obeyed ("" before the first).
  [[nodiscard]] const std::string& owner() const { return owner_; }
  /// Set when the last execute() changed the owner (for the EDP's report).
  [[nodiscard]] bool owner_changed() const { return owner_changed_; }
  void set_owner_lease(double seconds) { owner_lease_s_ = seconds; }
  /// Checks every SET ARM's path with `guard` too (null: no collision check); the guard must
  /// outlive the interpreter.
  void set_collision_guard(CollisionGuard* guard) { collision_ = guard; }

 private:
  enum class Due { nothing, arm_reading, synchro, get };
  Reply accept(const Instruction& instruction);
  Reply query();
  void validate_servo(const Instruction& instruction) const;
  /// SET DEVICE: one finite value per command field of the plugin's device, each in its range.
  void validate_device(const Instruction& instruction) const;
  std::vector<double> arm_target(const Instruction& instruction) const;
  /// SET ARM MOTOR or JOINT: one finite value per axis. @throws CommandError (bad_argument).
  void check_axis_values(const Instruction& instruction) const;
  /// The target of a SET ARM before SYNCHRO, in raw axis positions: RELATIVE MOTOR or JOINT
  /// only, each joint's change at most ServoLoop::unsynchronised_limits().max_move.
  /// @throws CommandError (not_synchronised, out_of_limits, bad_argument).
  std::vector<double> unsynchronised_target(const Instruction& instruction) const;
  void check_path(const std::vector<double>& start, const std::vector<double>& target,
                  int steps) const;
  std::vector<double> arm_values(const std::vector<double>& joints, ArmRepresentation type) const;
  Reply reading_reply(const Reading& reading) const;
  static Reply error(int code, const std::string& text);

  ServoLoop& servo_;
  const RobotModel& model_;
  ArmKinematics& kinematics_;
  double period_s_;
  Due due_ = Due::nothing;
  std::uint64_t due_macro_step_ = 0;
  std::uint64_t due_at_ = 0;            ///< the macro-step whose reading answers due_macro_step_
  std::uint64_t refusal_reported_ = 0;  ///< the newest refused macro-step a client was told of
  ArmRepresentation due_arm_type_ = ArmRepresentation::joint;
  std::uint8_t due_get_ = 0;
  ArmRepresentation due_tool_type_ = ArmRepresentation::frame;
  std::string owner_;
  std::chrono::steady_clock::time_point owner_seen_{};
  double owner_lease_s_ = 2.0;
  bool owner_changed_ = false;
  CollisionGuard* collision_ = nullptr;
};

}  // namespace mrroc::edp
