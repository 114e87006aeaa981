#pragma once
/// @file
/// Stock conditions: initial conditions for Wait (paper, section 3), also usable as terminal
/// conditions of a guarded move (GuardedMoveGenerator takes a `Condition&`).
///
/// Conditions are checked from the task thread; only OperatorTriggerCondition::trigger/reset may
/// be called from other threads.

#include <atomic>
#include <chrono>
#include <cstdint>
#include <functional>
#include <optional>

#include "mrroc/ecp/generator.hpp"

namespace mrroc::ecp {

/// A monotonic clock, injectable for tests (default: std::chrono::steady_clock::now).
using SteadyClock = std::function<std::chrono::steady_clock::time_point()>;

/// True once `seconds` have passed since the first check (or since restart()).
class DelayCondition : public Condition {
 public:
  /// @param seconds  >= 0 [s]. @throws Error for a negative or non-finite delay.
  explicit DelayCondition(double seconds, SteadyClock clock = {});

  bool check(const SensorList& sensors) override;
  /// The next check starts the delay anew.
  void restart() { start_.reset(); }
  /// Seconds since the delay started (0 before the first check).
  [[nodiscard]] double elapsed_s() const;

 private:
  std::chrono::steady_clock::duration delay_;
  SteadyClock clock_;
  std::optional<std::chrono::steady_clock::time_point> start_;
};

/// True when a reading crosses a threshold, with optional hysteresis (a Schmitt trigger):
/// - above: becomes true when reading >= threshold, false again only when
///   reading <= threshold - hysteresis;
/// - below: becomes true when reading <= threshold, false again only when
///   reading >= threshold + hysteresis.
/// Hysteresis 0 makes it a plain comparison. Readings are in the sensor's unit.
class SensorThresholdCondition : public Condition {
 public:
  enum class Direction : std::int8_t { above, below };

  /// @param reading  returns the current reading (e.g. from a sensor image, refreshed by Wait
  ///   and Move before every check). @throws Error when `reading` is empty, the threshold is
  ///   not finite or the hysteresis is negative or not finite.
  SensorThresholdCondition(std::function<double()> reading, double threshold,
                           Direction direction = Direction::above, double hysteresis = 0.0);

  /// @throws GeneratorError when the reading is not a number (a failed sensor).
  bool check(const SensorList& sensors) override;
  [[nodiscard]] bool state() const { return state_; }
  /// The last reading checked.
  [[nodiscard]] double last_reading() const { return last_; }

 private:
  std::function<double()> reading_;
  double threshold_;
  Direction direction_;
  double hysteresis_;
  bool state_ = false;
  double last_ = 0.0;
};

/// True once trigger() has been called (latched until reset()). trigger() and reset() may be
/// called from any thread, e.g. by the shell on an operator command, while the task thread
/// checks.
class OperatorTriggerCondition : public Condition {
 public:
  void trigger() { triggered_.store(true, std::memory_order_release); }
  void reset() { triggered_.store(false, std::memory_order_release); }
  bool check(const SensorList& sensors) override;

 private:
  std::atomic<bool> triggered_{false};
};

/// True when every joint velocity of the robot image is below a threshold in `consecutive`
/// readings in a row.
///
/// A reading counts once: a check that finds the same reading as the previous check (the same
/// servo_cycle) neither advances nor resets the count, so a stale image never reports a stop.
/// Wait refreshes the sensor images, not the robot image; give a `refresh` function (e.g.
/// `[&robot] { robot.read_state(); }`) to read the robot before every check, or use the
/// condition inside a Move, which refreshes the image every macro-step.
class RobotStoppedCondition : public Condition {
 public:
  /// @param velocity_threshold  [rad/s], > 0.  @param consecutive  >= 1.
  /// The image must outlive the condition. @throws Error for parameters out of range.
  RobotStoppedCondition(const RobotImage& image, double velocity_threshold, int consecutive = 3,
                        std::function<void()> refresh = {});

  /// False while the image has no joint velocities.
  bool check(const SensorList& sensors) override;
  /// Readings in a row below the threshold so far.
  [[nodiscard]] int count() const { return count_; }

 private:
  const RobotImage& image_;
  double threshold_;
  int consecutive_;
  std::function<void()> refresh_;
  int count_ = 0;
  std::optional<std::int64_t> last_cycle_;
};

/// True when the robot's binary input `line` is `state` (paper, section 3: an initial condition
/// on the robot image). In Wait the image's inputs are read from the EDP (GET INPUTS) before
/// every check; in a guarded move the macro-step's image is used, which holds inputs only when
/// the move's generator asks for them: a check of an image without inputs throws GeneratorError
/// (rather than waiting for ever). With a timeout, a check after `timeout_s` seconds without the
/// state throws GeneratorError naming the line, the state awaited and the time.
class InputCondition : public RobotCondition {
 public:
  /// @param line  0..31.  @param timeout_s  [s], >= 0; 0 waits for ever.
  /// @throws Error for a line or a timeout out of range.
  explicit InputCondition(int line, bool state = true, double timeout_s = 0.0,
                          SteadyClock clock = {});

  [[nodiscard]] std::uint8_t items() const override { return edp::item::arm | edp::item::inputs; }
  bool holds(const RobotImage& robot, const SensorList& sensors) override;
  /// Seconds from the first check to the last (0 before the first check).
  [[nodiscard]] double waited_s() const;
  [[nodiscard]] int line() const { return line_; }

 private:
  int line_;
  bool state_;
  double timeout_s_;
  SteadyClock clock_;
  std::optional<std::chrono::steady_clock::time_point> start_;
  std::chrono::steady_clock::time_point last_{};
};

}  // namespace mrroc::ecp
