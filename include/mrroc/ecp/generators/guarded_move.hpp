#pragma once
/// @file
/// Stock generator: a guarded move. The robot moves along a direction (in joint or motor
/// coordinates, or a straight line of the tool frame) until a terminal condition holds, e.g. a
/// contact sensor reading; if the condition does not hold when the maximum distance has been
/// travelled, the move ends with `GuardedMoveExhausted` (its error condition).
///
/// The motion to the maximum distance is planned and checked in full before the first command
/// (trapezoidal profile: accelerate, cruise at the guarded speed, decelerate to rest at the
/// maximum distance). The condition is evaluated after every macro-step (on the robot and sensor
/// images of that step); when it holds, no further command is sent, so the robot stops at the
/// target of the macro-step in which the condition was seen, within one macro-step of it. The
/// stop is abrupt (from the guarded speed to rest within one servo step): keep the speed low.

#include <concepts>
#include <functional>
#include <memory>
#include <type_traits>
#include <vector>

#include "mrroc/ecp/generators/cartesian_path.hpp"
#include "mrroc/ecp/generators/errors.hpp"
#include "mrroc/ecp/generators/interpolation.hpp"

namespace mrroc::ecp {

namespace detail {
template <class T>
struct is_std_function : std::false_type {};
template <class R, class... A>
struct is_std_function<std::function<R(A...)>> : std::true_type {};
}  // namespace detail

/// A terminal condition: any callable returning bool (`std::function<bool()>`, a lambda), or a
/// `Condition` (checked with the Move's sensor list; a RobotCondition also with the image of the
/// macro-step just done; it must outlive the generator).
class TerminalCondition {
 public:
  /// @throws Error for an empty std::function or a null function pointer.
  // clang-format off
  template <class F>
    requires(std::is_invocable_r_v<bool, F&> && !std::derived_from<std::decay_t<F>, Condition>)
  TerminalCondition(F f) {  // NOLINT(google-explicit-constructor): converts like std::function
    if constexpr (std::is_pointer_v<F> || detail::is_std_function<F>::value)
      if (!static_cast<bool>(f)) throw Error("guarded move: empty terminal condition");
    check_ = [f = std::move(f)](const RobotImage&, const SensorList&) mutable {
      return static_cast<bool>(f());
    };
  }
  // clang-format on
  TerminalCondition(Condition& condition)  // NOLINT(google-explicit-constructor)
      : check_([&condition](const RobotImage& robot, const SensorList& sensors) {
          if (auto* on_robot = dynamic_cast<RobotCondition*>(&condition))
            return on_robot->holds(robot, sensors);
          return condition.check(sensors);
        }) {}

  [[nodiscard]] bool operator()(const RobotImage& robot, const SensorList& sensors) const {
    return check_(robot, sensors);
  }

 private:
  std::function<bool(const RobotImage&, const SensorList&)> check_;
};

/// Speed, acceleration and reach of a guarded move. Units: rad, rad/s, rad/s^2 along the
/// direction (Euclidean norm over the axes) for JOINT and MOTOR moves; m, m/s, m/s^2 for
/// Cartesian ones.
struct GuardedMotion {
  double speed = 0.05;         ///< cruise speed along the direction (> 0)
  double acceleration = 0.5;   ///< (> 0)
  double max_distance = 0.05;  ///< (> 0): beyond it the move fails
};

class GuardedMoveGenerator : public Generator {
 public:
  /// Moves the joints (`options.representation` JOINT) or the motors (MOTOR) along `direction`
  /// (one value per axis, any length but 0; normalised). Each axis's speed and acceleration are
  /// their share of `motion` (so the norm follows `motion`); the joints stay within the model's
  /// velocity and acceleration limits. Other options as for InterpolationGenerator (its
  /// profile, max_velocity and max_acceleration are ignored).
  /// @throws CommandError, Error as InterpolationGenerator.
  static GuardedMoveGenerator along_axes(const RobotModel& model, std::vector<double> direction,
                                         GuardedMotion motion, TerminalCondition condition,
                                         InterpolationOptions options = {});

  /// Moves the tool frame in a straight line along `direction` (base frame, any length but 0;
  /// normalised) with constant orientation. Other options as for CartesianPathGenerator (its
  /// profile and linear limits are replaced by `motion`).
  /// @throws CommandError, Error as CartesianPathGenerator.
  static GuardedMoveGenerator along_line(const RobotModel& model, const Eigen::Vector3d& direction,
                                         GuardedMotion motion, TerminalCondition condition,
                                         CartesianOptions options = {});

  /// Returns false (nothing to do) when the condition already holds; otherwise plans the whole
  /// move and sends its first macro-step. @throws CommandError when the path to the maximum
  /// distance leaves a limit (nothing moves).
  bool first_step(RobotImage& robot, const SensorList& sensors) override;
  /// Returns false when the condition holds. @throws GuardedMoveExhausted when the maximum
  /// distance has been travelled without it.
  bool next_step(RobotImage& robot, const SensorList& sensors) override;

  /// True when the last motion ended because the condition held.
  [[nodiscard]] bool condition_met() const { return condition_met_; }
  /// Distance commanded so far in the current motion (units of GuardedMotion).
  [[nodiscard]] double distance() const;
  /// The planned motion to the maximum distance.
  [[nodiscard]] const MotionPlan& plan() const { return motion_->plan(); }

 private:
  GuardedMoveGenerator(std::unique_ptr<PlannedMotionGenerator> motion, TerminalCondition condition,
                       GuardedMotion guarded, bool cartesian);

  std::unique_ptr<PlannedMotionGenerator> motion_;
  TerminalCondition condition_;
  GuardedMotion guarded_;
  bool cartesian_;
  bool condition_met_ = false;
};

}  // namespace mrroc::ecp
