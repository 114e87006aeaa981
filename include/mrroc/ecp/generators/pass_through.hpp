#pragma once
/// @file
/// Stock generator for tightly cooperating robots (paper, section 2: "the MP must generate the
/// trajectory for all the robots; the ECPs only transfer the MP commands to adequate EDPs"):
/// executes, macro-step by macro-step, the SET ARM instructions handed to it by the shell, after
/// checking that each is well formed.

#include <chrono>
#include <condition_variable>
#include <cstddef>
#include <deque>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <vector>

#include "mrroc/ecp/generator.hpp"
#include "mrroc/edp/arm_kinematics.hpp"
#include "mrroc/msg/edp_instruction.hpp"
#include "mrroc/robot/robot_model.hpp"

namespace mrroc::ecp {

/// Supplies the next instruction, or nothing to end the motion. Called from the task thread,
/// once per macro-step; it may block until the next pose is there.
using InstructionSource = std::function<std::optional<edp::Instruction>()>;

/// A thread-safe FIFO of instructions between the shell (producer, e.g. the thread receiving the
/// MP's poses) and a PassThroughGenerator (consumer, the task thread).
class InstructionQueue {
 public:
  /// Appends an instruction. @throws Error after close().
  void push(edp::Instruction instruction);
  /// No more instructions: the consumer ends its motion once the queue is empty.
  void close();
  /// The next instruction; nothing when the queue is closed and empty.
  /// @throws TimeoutError when nothing arrives within `timeout` (the producer fell behind).
  std::optional<edp::Instruction> pop(std::chrono::milliseconds timeout);
  [[nodiscard]] std::size_t size() const;
  [[nodiscard]] bool closed() const;

 private:
  mutable std::mutex mutex_;
  std::condition_variable ready_;
  std::deque<edp::Instruction> queue_;
  bool closed_ = false;
};

struct PassThroughOptions {
  /// Representations accepted for SET ARM; empty: all the robot supports (JOINT, MOTOR, and the
  /// Cartesian ones when it has Cartesian kinematics).
  std::vector<edp::ArmRepresentation> representations;
  /// Check absolute targets against the limits before forwarding them (JOINT: joint and linkage
  /// limits; MOTOR: motor limits, then the joints; Cartesian: inverse kinematics from the robot
  /// image's desired joints, with the tool, kinematic model and corrector last SET through this
  /// generator, by default the EDP's defaults: no tool, model 0, no corrector). Relative targets
  /// are not checked here. The EDP checks every target anyway; checking here names the
  /// pass-through pose in the error.
  bool check_limits = true;
};

/// Forwards the instructions of an `InstructionSource` unchanged.
///
/// Every instruction must be a SET or SET_GET that sets the arm (item::arm; other items may be
/// set too), with an arm vector of the size its representation needs, finite values,
/// motion_steps in 1..100000 and value_in_step_no in 1..motion_steps + 1. A malformed one ends
/// the motion with CommandError (bad_argument) naming its number (1 = the first) and the problem;
/// the instructions before it have been executed.
class PassThroughGenerator : public Generator {
 public:
  /// The model must outlive the generator.
  PassThroughGenerator(const RobotModel& model, InstructionSource source,
                       PassThroughOptions options = {});
  /// Reads `queue` with `timeout` per macro-step; the queue must outlive the generator.
  PassThroughGenerator(const RobotModel& model, InstructionQueue& queue,
                       std::chrono::milliseconds timeout, PassThroughOptions options = {});

  bool first_step(RobotImage& robot, const SensorList& sensors) override;
  bool next_step(RobotImage& robot, const SensorList& sensors) override;

  /// Instructions forwarded in the current motion.
  [[nodiscard]] std::size_t forwarded() const { return forwarded_; }

  /// The check applied to every instruction (`number` names it in the error text), public for
  /// shells that want to refuse an MP pose before queueing it. A tool or kinematic model the
  /// instruction SETs is taken over into the generator's kinematics (as the EDP will) before its
  /// arm target is checked, and only if the whole instruction passes. Not thread-safe: call it
  /// from the thread that runs the generator (or on a generator of its own).
  /// @throws CommandError (bad_argument, out_of_limits).
  void validate(const edp::Instruction& instruction, std::size_t number,
                const std::vector<double>& desired_joints);

 private:
  bool forward(RobotImage& robot);

  const RobotModel& model_;
  std::unique_ptr<edp::ArmKinematics> kinematics_;
  InstructionSource source_;
  PassThroughOptions options_;
  std::size_t forwarded_ = 0;
};

}  // namespace mrroc::ecp
