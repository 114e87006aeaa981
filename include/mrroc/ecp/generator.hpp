#pragma once
/// @file
/// The user's extension points on the ECP level (paper, sections 3-4): generators for Move and
/// conditions for Wait, plus sensor images.
///
/// Move(robot, sensors, generator), after the paper's figure 4:
///   refresh sensor images; if (!first_step) return;
///   do { execute the robot's command (EDP exchange); refresh sensor images; }
///   while (next_step);
/// Errors are exceptions thrown from anywhere; the shell handles them.

#include <cstdint>
#include <vector>

#include "mrroc/ecp/robot_image.hpp"
#include "mrroc/msg/mp_command.hpp"

namespace mrroc::ecp {

/// The step in which a macro-step that has a successor reads the arm (its `value_in_step_no`): a
/// third of the macro-step before its end (at least one step), so that the ECP's next SET ARM is
/// queued in the EDP before the running macro-step ends even when the machine is busy (the
/// paper's "one step early" leaves a single servo period). The stock generators use it.
constexpr int early_reading_step(int motion_steps) {
  const int lead = motion_steps / 3 > 1 ? motion_steps / 3 : 1;
  return motion_steps - lead > 1 ? motion_steps - lead : 1;
}

/// Image of a virtual sensor, kept current by the shell around each step.
class Sensor {
 public:
  virtual ~Sensor() = default;
  /// Asks the virtual sensor for a new reading (does not wait).
  virtual void initiate_reading() = 0;
  /// Collects the reading into the image.
  virtual void get_reading() = 0;
};
using SensorList = std::vector<Sensor*>;

/// A motion generator: computes the next command from the robot and sensor images and decides
/// the terminal condition.
class Generator {
 public:
  virtual ~Generator() = default;
  /// Prepares the first command in `robot.command`. Returns false when there is nothing to do.
  virtual bool first_step(RobotImage& robot, const SensorList& sensors) = 0;
  /// Called after each exchange with the EDP: prepares the next command, or returns false when
  /// the terminal condition holds.
  virtual bool next_step(RobotImage& robot, const SensorList& sensors) = 0;
  /// The robot stands away from the path this generator planned: after a PAUSE, or when the EDP
  /// brought it to a standstill because a macro-step came late and then refused the planned one
  /// as too fast from there (error `too_fast`). `robot` holds the state just read. Prepare a
  /// command that continues the motion from where the robot stands, from rest, and return true;
  /// return false (the default) when the generator cannot: after a PAUSE the motion then goes on
  /// as planned (the EDP refuses what would exceed a limit), after a refusal Move fails with it.
  virtual bool resume(RobotImage& /*robot*/, const SensorList& /*sensors*/) { return false; }
};

/// An initial condition for Wait.
class Condition {
 public:
  virtual ~Condition() = default;
  /// True when the waiting is over.
  virtual bool check(const SensorList& sensors) = 0;
};

/// The generator of an ECP that follows the MP (tight coordination, paper section 2; the stock
/// task `follow_mp_compliant` in docs/sensors.md): the ECP shell hands it every NEXT_POSE of the
/// MP, after refreshing its sensors, before the command goes to the EDP. It may correct the
/// command in place, e.g. move the commanded tool frame back along a force a wrist sensor feels;
/// the EDP checks the corrected command against every limit, as any other. A task installs one
/// with TaskContext::follow_mp_with(); it stays until the next START_TASK or NEXT_STATE.
class FollowGenerator {
 public:
  virtual ~FollowGenerator() = default;
  /// The sensors whose images the shell refreshes before each correct() (default: none).
  [[nodiscard]] virtual SensorList sensors() { return {}; }
  /// `command`: the MP's NEXT_POSE (representation, motion type, steps, arm values), to correct
  /// in place. `robot`: the image after the previous macro-step. Throw (GeneratorError) to refuse
  /// the command: the MP gets the error and nothing moves.
  virtual void correct(MpCommand& command, const RobotImage& robot, const SensorList& sensors) = 0;
  /// The MP ended the continuous motion (END_MOTION); `robot` holds the state just read. The
  /// robot stands at rest where the MP's image of it now shows it, the corrections made so far
  /// included, and the MP plans its next motion from there (a new Move, or a group's resumption
  /// after a stop: mp::Generator::resume): a correction that keeps adding to the coming poses
  /// what the robot already did would jump from rest. Restart such state here.
  virtual void end_motion(const RobotImage& /*robot*/) {}
};

/// A condition on the robot image as well as on the sensor images (paper, section 3: initial and
/// terminal conditions are predicates on the images). Wait reads the robot from its EDP (a GET of
/// `items()`) before each check; a guarded move hands it the image of the macro-step just done.
/// Example: `image.inputs` shows a part present; a joint passed a value; the robot stands still.
class RobotCondition : public Condition {
 public:
  /// What Wait reads from the EDP before each check: edp::item bits (default: the arm, in
  /// joints; add edp::item::inputs for the binary inputs).
  [[nodiscard]] virtual std::uint8_t items() const { return edp::item::arm; }
  /// True when the waiting (or the guarded move) is over.
  virtual bool holds(const RobotImage& robot, const SensorList& sensors) = 0;
  /// @throws Error: a RobotCondition decides from the robot image too; Wait and guarded moves
  /// call holds().
  bool check(const SensorList& sensors) final;
};

/// Runs a motion. After a PAUSE, and when the EDP refuses a macro-step as too fast after it had
/// to stop the robot (a late macro-step), the generator's `resume` re-plans from where the robot
/// stands (at most 3 refusals in a row). @throws whatever the generator, the EDP link or a stop
/// request throws.
void Move(Robot& robot, const SensorList& sensors, Generator& generator);

/// Waits until `condition` holds, refreshing the sensor images every `period_s` [s], and for a
/// RobotCondition reading its `items()` from the EDP before each check.
void Wait(Robot& robot, const SensorList& sensors, Condition& condition, double period_s = 0.01);

}  // namespace mrroc::ecp
