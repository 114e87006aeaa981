#pragma once
/// @file
/// Stock generator: visits a list of joint poses, each segment with a quintic (minimum-jerk-like)
/// time scaling, so velocity and acceleration are continuous and zero at every pose.

#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "mrroc/core/time.hpp"
#include "mrroc/edp/arm_kinematics.hpp"

#include "mrroc/ecp/generator.hpp"
#include "mrroc/robot/robot_model.hpp"

namespace mrroc::ecp {

struct JointPosesOptions {
  double velocity_scale = 0.5;      ///< fraction of the model's max joint velocity (0..1]
  double acceleration_scale = 0.5;  ///< fraction of the model's max joint acceleration (0..1]
  int motion_steps = 10;            ///< servo steps per macro-step (>= 2)
  double servo_period_s = kDefaultServoPeriodS;  ///< EDP servo period [s]

  /// Every option outside its range, each as its name (the task argument's, e.g.
  /// "velocity_scale") and why ("velocity_scale 2 is outside (0, 1]"); empty when all are in
  /// range. The one check of these ranges: the generator throws the first.
  [[nodiscard]] std::vector<std::pair<std::string, std::string>> out_of_range() const;
};

class JointPosesGenerator : public Generator {
 public:
  /// Checks every pose, and the joint-space path between consecutive poses, against the robot's
  /// joint, linkage and motor limits (the path from the current pose to the first one is checked
  /// in first_step, before the first command).
  /// @throws CommandError when a pose has the wrong size or a pose or path leaves a limit, and
  /// `Error` for options out of range; nothing moves in either case.
  JointPosesGenerator(const RobotModel& model, std::vector<std::vector<double>> poses,
                      JointPosesOptions options = {});

  bool first_step(RobotImage& robot, const SensorList& sensors) override;
  bool next_step(RobotImage& robot, const SensorList& sensors) override;
  /// Re-plans the segment to the current pose from where the robot stands, from rest.
  bool resume(RobotImage& robot, const SensorList& sensors) override;

  /// Quintic time scaling s(tau) = 10 tau^3 - 15 tau^4 + 6 tau^5, tau in [0, 1].
  static double scaling(double tau);
  /// Shortest duration [s] of a quintic move by `distance` [rad] under the limits.
  static double segment_duration(double distance, double max_velocity, double max_acceleration);

  /// Number of macro-steps of the segment being executed.
  [[nodiscard]] int segment_macro_steps() const { return segment_steps_; }

 private:
  void begin_segment(const std::vector<double>& from);
  void check_segment(const std::vector<double>& from, const std::vector<double>& to,
                     const std::string& what) const;
  void command(RobotImage& robot);

  const RobotModel& model_;
  std::unique_ptr<edp::ArmKinematics> kinematics_;
  std::vector<std::vector<double>> poses_;
  JointPosesOptions options_;
  std::size_t pose_ = 0;
  std::vector<double> from_;
  int segment_steps_ = 0;
  int macro_step_ = 0;
};

}  // namespace mrroc::ecp
