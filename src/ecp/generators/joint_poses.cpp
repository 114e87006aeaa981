#include "mrroc/ecp/generators/joint_poses.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>

#include "mrroc/core/error.hpp"

namespace mrroc::ecp {

namespace {
// Peak velocity and acceleration of the quintic scaling for a unit move in unit time.
constexpr double kPeakVelocity = 1.875;
constexpr double kPeakAcceleration = 5.773502691896258;  // 10 / sqrt(3)
}  // namespace

double JointPosesGenerator::scaling(double tau) {
  tau = std::clamp(tau, 0.0, 1.0);
  return tau * tau * tau * (10.0 + tau * (-15.0 + 6.0 * tau));
}

double JointPosesGenerator::segment_duration(double distance, double max_velocity,
                                             double max_acceleration) {
  distance = std::abs(distance);
  return std::max(kPeakVelocity * distance / max_velocity,
                  std::sqrt(kPeakAcceleration * distance / max_acceleration));
}

std::vector<std::pair<std::string, std::string>> JointPosesOptions::out_of_range() const {
  std::vector<std::pair<std::string, std::string>> bad;
  if (!(velocity_scale > 0.0 && velocity_scale <= 1.0))
    bad.emplace_back("velocity_scale",
                     fmt::format("velocity_scale {} is outside (0, 1]", velocity_scale));
  if (!(acceleration_scale > 0.0 && acceleration_scale <= 1.0))
    bad.emplace_back("acceleration_scale",
                     fmt::format("acceleration_scale {} is outside (0, 1]", acceleration_scale));
  if (motion_steps < 2 || motion_steps > 1000)
    bad.emplace_back("motion_steps",
                     fmt::format("motion_steps {} is outside 2..1000", motion_steps));
  return bad;
}

JointPosesGenerator::JointPosesGenerator(const RobotModel& model,
                                         std::vector<std::vector<double>> poses,
                                         JointPosesOptions options)
    : model_(model),
      kinematics_(edp::make_arm_kinematics(model)),
      poses_(std::move(poses)),
      options_(options) {
  if (const auto bad = options_.out_of_range(); !bad.empty()) throw Error(bad.front().second);
  for (std::size_t i = 0; i < poses_.size(); ++i)
    model_.check_joint_limits(poses_[i], fmt::format("pose {}", i + 1).c_str());
  for (std::size_t i = 1; i < poses_.size(); ++i)
    check_segment(poses_[i - 1], poses_[i], fmt::format("path from pose {} to {}", i, i + 1));
}

void JointPosesGenerator::check_segment(const std::vector<double>& from,
                                        const std::vector<double>& to,
                                        const std::string& what) const {
  // The EDP refuses a macro-step leaving a limit; checking the whole segment here refuses the
  // motion before its first macro-step. Joint-space paths can leave a motor range in the middle
  // (nonlinear transmissions), so the path is sampled finely, not only at its ends.
  constexpr int kSamples = 200;
  std::vector<double> q(to.size());
  for (int k = 0; k <= kSamples; ++k) {
    const double s = static_cast<double>(k) / kSamples;
    for (std::size_t j = 0; j < q.size(); ++j) q[j] = from[j] + (to[j] - from[j]) * s;
    kinematics_->check_joint_limits(q, what.c_str());
    kinematics_->check_motor_limits(kinematics_->motors_from_joints(q), what.c_str());
  }
}

void JointPosesGenerator::begin_segment(const std::vector<double>& from) {
  from_ = from;
  const auto& to = poses_[pose_];
  double duration = 0.0;
  for (std::size_t j = 0; j < to.size(); ++j)
    duration = std::max(
        duration,
        segment_duration(to[j] - from_[j], model_.max_velocity[j] * options_.velocity_scale,
                         model_.max_acceleration[j] * options_.acceleration_scale));
  const double macro_step_s = options_.motion_steps * options_.servo_period_s;
  segment_steps_ = std::max(1, static_cast<int>(std::ceil(duration / macro_step_s - 1e-9)));
  macro_step_ = 0;
}

void JointPosesGenerator::command(RobotImage& robot) {
  ++macro_step_;
  const auto& to = poses_[pose_];
  const double s = scaling(static_cast<double>(macro_step_) / segment_steps_);
  edp::Instruction& c = robot.command;
  c = edp::Instruction{};
  c.type = edp::InstructionType::set;
  c.set = edp::item::arm;
  c.set_arm_type = edp::ArmRepresentation::joint;
  c.motion_type = edp::MotionType::absolute;
  c.motion_steps = options_.motion_steps;
  const bool last = pose_ + 1 == poses_.size() && macro_step_ == segment_steps_;
  // Reading early keeps consecutive macro-steps seamless; the very last one reads after the stop.
  c.value_in_step_no = last ? options_.motion_steps + 1 : early_reading_step(options_.motion_steps);
  c.arm.resize(to.size());
  for (std::size_t j = 0; j < to.size(); ++j) c.arm[j] = from_[j] + (to[j] - from_[j]) * s;
  if (macro_step_ == segment_steps_) c.arm = to;  // exactly the pose, free of rounding
}

bool JointPosesGenerator::first_step(RobotImage& robot, const SensorList&) {
  if (poses_.empty()) return false;
  if (robot.desired_joints.size() != model_.axes())
    throw Error("robot image has no desired joint position (read the robot state first)");
  pose_ = 0;
  check_segment(robot.desired_joints, poses_[0], "path to pose 1");
  begin_segment(robot.desired_joints);
  command(robot);
  return true;
}

bool JointPosesGenerator::resume(RobotImage& robot, const SensorList&) {
  if (pose_ >= poses_.size() || robot.desired_joints.size() != model_.axes()) return false;
  check_segment(robot.desired_joints, poses_[pose_],
                fmt::format("path from where the robot stopped to pose {}", pose_ + 1));
  begin_segment(robot.desired_joints);
  command(robot);
  return true;
}

bool JointPosesGenerator::next_step(RobotImage& robot, const SensorList&) {
  if (macro_step_ >= segment_steps_) {
    if (++pose_ >= poses_.size()) return false;
    begin_segment(poses_[pose_ - 1]);
  }
  command(robot);
  return true;
}

}  // namespace mrroc::ecp
