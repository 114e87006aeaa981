#pragma once
/// @file
/// Gripper: an example of a robot class derived from ecp::Robot to add a device's own command
/// and reply fields (the paper's device-dependent buffers and images). It drives the two-finger
/// gripper of the `mujoco` plugin's robots/irb6/irb6_gripper.xml (docs/edp.md, "Devices"):
///
///   command fields (SET DEVICE): opening [m] the fingers move to, force [N] they may push with
///   reply fields (GET DEVICE):   opening [m], opening speed [m/s], grip force [N],
///                                holding (1: stopped on an object before closing fully)
///
/// Task code calls `gripper.close(force)`, `gripper.open()` and reads `gripper.width()` and
/// `gripper.holding()`; the arm is driven as any Robot's (Move with a generator).

#include <string>
#include <vector>

#include "mrroc/ecp/robot.hpp"

namespace mrroc::ecp {

class Gripper : public Robot {
 public:
  using Robot::Robot;

  /// The fingers' widest opening [m] and largest force [N], as the plugin declares them.
  static constexpr double kMaxOpening = 0.08;
  static constexpr double kMaxForce = 60.0;
  /// Force the fingers open with [N].
  static constexpr double kOpenForce = 10.0;
  /// The fingers count as stopped below this opening speed [m/s].
  static constexpr double kStoppedSpeed = 0.002;

  /// Closes the fingers with at most `force_n` [N] and waits until they stop: on a part
  /// (holding()) or closed. A PAUSE holds it before the command, as Move. @throws EdpRefused
  /// (e.g. a force above kMaxForce, naming the limit), TimeoutError when they do not stop within
  /// 10 s, TaskStopped.
  void close(double force_n);
  /// Opens the fingers fully and waits until they stop.
  void open();
  /// Reads the device (GET DEVICE) into width(), speed(), force() and holding().
  void read_device();

  /// Measured opening between the fingers [m] (as of the last reply with the device part).
  [[nodiscard]] double width() const { return width_; }
  /// Measured opening speed [m/s] (negative: closing).
  [[nodiscard]] double speed() const { return speed_; }
  /// Measured grip force [N].
  [[nodiscard]] double force() const { return force_; }
  /// The fingers stopped on an object before closing fully.
  [[nodiscard]] bool holding() const { return holding_; }

 protected:
  void write_device_command(std::vector<double>& command) const override;
  void read_device_reply(const std::vector<double>& reply) override;

 private:
  /// SET DEVICE with the command fields, then GET DEVICE until the fingers stopped.
  void move_fingers(double opening_m, double force_n);

  // Command fields (sent with every SET DEVICE).
  double command_opening_ = kMaxOpening;
  double command_force_ = kOpenForce;
  // Reply fields (from every GET DEVICE).
  double width_ = 0.0;
  double speed_ = 0.0;
  double force_ = 0.0;
  bool holding_ = false;
};

}  // namespace mrroc::ecp
