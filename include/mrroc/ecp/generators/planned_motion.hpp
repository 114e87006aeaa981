#pragma once
/// @file
/// Base of the stock generators that plan a whole motion before its first command: the plan
/// holds one target per macro-step, every target (and the joint-space path the EDP interpolates
/// between consecutive targets) has been checked against the robot's joint, linkage and motor
/// limits, and the generator then only sends the targets one by one.
///
/// Macro-steps follow the paper's value_in_step_no pattern: every command but the last reads the
/// arm in step early_reading_step(motion_steps) (seamless consecutive macro-steps), the last one
/// after the stop (motion_steps + 1).

#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "mrroc/core/time.hpp"
#include "mrroc/ecp/generator.hpp"
#include "mrroc/ecp/generators/motion_profile.hpp"
#include "mrroc/edp/arm_kinematics.hpp"
#include "mrroc/msg/edp_instruction.hpp"
#include "mrroc/robot/robot_model.hpp"

namespace mrroc::ecp {

/// One segment of a plan: a move between two rest poses (or a dwell at one pose).
struct PlannedSegment {
  std::size_t first_macro_step = 0;      ///< index into MotionPlan::targets
  std::size_t macro_steps = 0;           ///< number of macro-steps of the segment
  std::optional<MotionProfile> profile;  ///< empty for a dwell (no motion, only time)
};

/// Every macro-step of a motion, computed before its first command.
struct MotionPlan {
  edp::ArmRepresentation representation = edp::ArmRepresentation::joint;
  int motion_steps = 10;                         ///< servo steps per macro-step
  double servo_period_s = kDefaultServoPeriodS;  ///< [s]
  std::vector<double> start_joints;              ///< where the plan starts [rad]
  std::vector<double> start;                     ///< the same, in `representation`
  std::vector<std::vector<double>> targets;      ///< SET ARM values of each macro-step (absolute)
  std::vector<std::vector<double>> joints;       ///< joints of each macro-step target [rad]
  std::vector<PlannedSegment> segments;

  /// Settings the first command also SETs (Cartesian plans: the tool and kinematic model the
  /// plan was checked with), as item:: bits (0: none).
  std::uint8_t first_command_sets = 0;
  std::vector<double> tool;  ///< FRAME values, when first_command_sets has item::tool
  int kinematic_model_no = 0;
  int corrector_no = 0;

  /// Duration of one macro-step [s].
  [[nodiscard]] double macro_step_s() const { return motion_steps * servo_period_s; }
  [[nodiscard]] std::size_t size() const { return targets.size(); }
  /// Duration of the whole motion [s].
  [[nodiscard]] double duration_s() const {
    return static_cast<double>(targets.size()) * macro_step_s();
  }
};

/// A generator that sends a precomputed `MotionPlan`.
/// first_step plans from the robot image's desired joints (the pose the EDP's next macro-step
/// starts from) and sends the first target; next_step sends the following ones.
class PlannedMotionGenerator : public Generator {
 public:
  /// @throws CommandError (checks failed: nothing was commanded) and `Error` when the robot
  ///   image has no desired joint position; see each generator's `make_plan`.
  bool first_step(RobotImage& robot, const SensorList& sensors) final;
  bool next_step(RobotImage& robot, const SensorList& sensors) final;
  /// After a PAUSE or a late macro-step left the robot off the plan (Move calls it with the
  /// robot image read again): a joint-space rest-to-rest move (quintic, within half of every
  /// joint's velocity and acceleration limits) from where the robot stands to the end of the
  /// segment it was in (every segment ends at rest), then the rest of the plan as planned.
  /// false when nothing was sent yet or everything was; @throws CommandError when that move
  /// would leave the limits.
  bool resume(RobotImage& robot, const SensorList& sensors) final;

  /// The plan first_step would make from `start_joints` [rad], without commanding anything.
  /// @throws as first_step.
  [[nodiscard]] MotionPlan plan_from(const std::vector<double>& start_joints) const;
  /// The plan of the current (or last) motion; empty before first_step.
  [[nodiscard]] const MotionPlan& plan() const { return plan_; }
  /// Macro-steps commanded so far in the current motion.
  [[nodiscard]] std::size_t macro_steps_sent() const { return sent_; }

  [[nodiscard]] const RobotModel& model() const { return model_; }

 protected:
  /// The model (and the kinematics made from it) must outlive the generator.
  /// @throws ConfigError when the robot's kinematics cannot be made.
  explicit PlannedMotionGenerator(const RobotModel& model);

  /// Plans every macro-step from `start_joints` (size checked). Implementations check every
  /// target before returning. @throws CommandError naming the segment, macro-step, joint, value
  /// and limit.
  [[nodiscard]] virtual MotionPlan make_plan(const std::vector<double>& start_joints) const = 0;

  [[nodiscard]] const edp::ArmKinematics& kinematics() const { return *kinematics_; }
  [[nodiscard]] edp::ArmKinematics& kinematics() { return *kinematics_; }

 private:
  void command(RobotImage& robot);

  const RobotModel& model_;
  std::unique_ptr<edp::ArmKinematics> kinematics_;
  MotionPlan plan_;
  std::size_t sent_ = 0;
  /// JOINT targets of the move back onto the plan (resume), sent before plan target `sent_`.
  std::vector<std::vector<double>> rejoin_;
  std::size_t rejoin_sent_ = 0;
};

namespace detail {

/// Checks what the EDP checks for one macro-step from `from` to `to` (joints [rad]), with the
/// same function (edp::check_straight_path): the target's joint and linkage limits, and the joint
/// and motor limits of every one of the `motion_steps` joint-space interpolation steps (a failing
/// one named "servo step k of N"); allocation-free while it passes.
/// @throws CommandError (out_of_limits) naming the axis.
void check_macro_step_path(const edp::ArmKinematics& kinematics, const std::vector<double>& from,
                           const std::vector<double>& to, int motion_steps);

/// Mean joint velocities of each macro-step and their changes, against limits.
struct JointRates {
  /// Largest |mean velocity| / limit and |velocity change per macro-step duration| / limit over
  /// all macro-steps and axes (the motion starts and ends at rest).
  double velocity_ratio = 0.0;
  double acceleration_ratio = 0.0;
  /// Where the largest ratio of each kind occurs (macro-step index into `joints`, axis).
  std::size_t velocity_step = 0, velocity_axis = 0;
  std::size_t acceleration_step = 0, acceleration_axis = 0;
  double velocity = 0.0;      ///< the mean velocity there [rad/s]
  double acceleration = 0.0;  ///< the velocity change per macro-step duration there [rad/s^2]
};
/// Rates of the macro-steps `joints[first .. first + count)` starting from `before` at rest and
/// ending at rest.
JointRates joint_rates(const std::vector<double>& before,
                       const std::vector<std::vector<double>>& joints, std::size_t first,
                       std::size_t count, double macro_step_s,
                       const std::vector<double>& max_velocity,
                       const std::vector<double>& max_acceleration);

/// `throw CommandError(code, prefix + what)` for a caught CommandError; other errors pass.
[[noreturn]] void rethrow_with_context(const std::string& prefix);

/// Checks motion_steps (2..1000) and servo_period_s (> 0). @throws Error.
void check_macro_step_options(int motion_steps, double servo_period_s, const char* generator);

}  // namespace detail

}  // namespace mrroc::ecp
