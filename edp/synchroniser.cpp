#include "synchroniser.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "motion_blend.hpp"

namespace mrroc::edp {

namespace {
constexpr double kSynchroSpeed = 0.1;              // joint speed while searching a switch [rad/s]
constexpr double kSynchroSearchRange = 0.4;        // farthest a switch may be from the start [rad]
constexpr double kSynchroAccelerationShare = 0.5;  // of each joint's acceleration limit
}  // namespace

void Synchroniser::begin(std::span<const AxisFeedback> feedback, const AxisArray& desired,
                         AxisArray& offset, std::uint32_t homed) {
  for (std::size_t i = 0; i < axes_; ++i) {
    switch_found_[i] = i < 32 && (homed & (1U << i)) != 0U;
    if (switch_found_[i]) offset[i] = 0.0;
    switch_initial_[i] = feedback[i].synchro_switch;
    // A pressed switch is released by moving down, a released one pressed by moving up.
    search_direction_[i] = feedback[i].synchro_switch ? -1.0 : 1.0;
    search_start_[i] = desired[i];
    speed_[i] = 0.0;
  }
  phase_ = Phase::search;
}

Synchroniser::Result Synchroniser::step(std::span<const AxisFeedback> feedback, double period_s,
                                        AxisArray& desired, AxisArray& offset,
                                        std::span<char> text) {
  if (phase_ == Phase::search) {
    bool all_at_rest = true;
    for (std::size_t i = 0; i < axes_; ++i) {
      const double dv = kSynchroAccelerationShare * model_.max_acceleration[i] * period_s;
      if (!switch_found_[i] && feedback[i].synchro_switch != switch_initial_[i]) {
        // The switch toggled: here the axis is at its synchronisation position.
        switch_found_[i] = true;
        offset[i] = model_.synchro_joint_positions[i] - feedback[i].position;
      }
      const double top = std::min(kSynchroSpeed, model_.max_velocity[i]);
      speed_[i] = switch_found_[i] ? std::max(speed_[i] - dv, 0.0) : std::min(speed_[i] + dv, top);
      desired[i] += search_direction_[i] * speed_[i] * period_s;
      all_at_rest = all_at_rest && switch_found_[i] && speed_[i] == 0.0;
      if (!switch_found_[i] && std::abs(desired[i] - search_start_[i]) > kSynchroSearchRange) {
        std::snprintf(text.data(), text.size(),
                      "synchronisation: axis %zu (%s) switch not found within %.2f rad", i,
                      model_.joint_names[i].c_str(), kSynchroSearchRange);
        phase_ = Phase::idle;
        return Result::failed;
      }
    }
    if (all_at_rest) {
      // Switch to joint coordinates and approach the synchronisation pose from rest to rest.
      approach_steps_ = 1;
      for (std::size_t i = 0; i < axes_; ++i) {
        desired[i] += offset[i];
        approach_start_[i] = desired[i];
        approach_steps_ = std::max(
            approach_steps_, shortest_rest_to_rest_steps(
                                 model_.synchro_joint_positions[i] - desired[i],
                                 std::min(kSynchroSpeed, model_.max_velocity[i]),
                                 kSynchroAccelerationShare * model_.max_acceleration[i], period_s));
      }
      approach_step_no_ = 0;
      phase_ = Phase::approach;
    }
    return Result::running;
  }
  if (phase_ == Phase::approach) {
    ++approach_step_no_;
    const double duration = approach_steps_ * period_s;
    const double s = static_cast<double>(approach_step_no_) / approach_steps_;
    for (std::size_t i = 0; i < axes_; ++i)
      desired[i] = approach_step_no_ >= approach_steps_
                       ? model_.synchro_joint_positions[i]
                       : blend_position(approach_start_[i], model_.synchro_joint_positions[i], 0.0,
                                        0.0, duration, s);
    if (approach_step_no_ >= approach_steps_) {
      phase_ = Phase::idle;
      return Result::done;
    }
  }
  return Result::running;
}

}  // namespace mrroc::edp
