#include "synchroniser.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>

namespace mrroc::edp {

namespace {
constexpr double kSynchroSpeed = 0.1;        // joint speed while searching a switch [rad/s]
constexpr double kSynchroSearchRange = 0.4;  // farthest a switch may be from the start [rad]
}  // namespace

void Synchroniser::begin(std::span<const AxisFeedback> feedback, const AxisArray& desired) {
  for (std::size_t i = 0; i < axes_; ++i) {
    switch_found_[i] = false;
    switch_initial_[i] = feedback[i].synchro_switch;
    // A pressed switch is released by moving down, a released one pressed by moving up.
    search_direction_[i] = feedback[i].synchro_switch ? -1.0 : 1.0;
    search_start_[i] = desired[i];
  }
  phase_ = Phase::search;
}

Synchroniser::Result Synchroniser::step(std::span<const AxisFeedback> feedback, double period_s,
                                        AxisArray& desired, AxisArray& offset,
                                        std::span<char> text) {
  const double step = kSynchroSpeed * period_s;
  if (phase_ == Phase::search) {
    bool all_found = true;
    for (std::size_t i = 0; i < axes_; ++i) {
      if (switch_found_[i]) continue;
      if (feedback[i].synchro_switch != switch_initial_[i]) {
        // The switch toggled: here the axis is at its synchronisation position.
        switch_found_[i] = true;
        offset[i] = model_.synchro_joint_positions[i] - feedback[i].position;
        desired[i] = feedback[i].position;  // stop searching on this axis
        continue;
      }
      all_found = false;
      desired[i] += search_direction_[i] * step;
      if (std::abs(desired[i] - search_start_[i]) > kSynchroSearchRange) {
        std::snprintf(text.data(), text.size(),
                      "synchronisation: axis %zu (%s) switch not found within %.2f rad", i,
                      model_.joint_names[i].c_str(), kSynchroSearchRange);
        phase_ = Phase::idle;
        return Result::failed;
      }
    }
    if (all_found) {
      // Switch to joint coordinates and approach the synchronisation pose exactly.
      double longest = 0;
      for (std::size_t i = 0; i < axes_; ++i) {
        desired[i] += offset[i];
        longest = std::max(longest, std::abs(model_.synchro_joint_positions[i] - desired[i]));
      }
      approach_steps_left_ = 1 + static_cast<int>(std::ceil(longest / step));
      for (std::size_t i = 0; i < axes_; ++i)
        approach_step_[i] = (model_.synchro_joint_positions[i] - desired[i]) / approach_steps_left_;
      phase_ = Phase::approach;
    }
    return Result::running;
  }
  if (phase_ == Phase::approach) {
    for (std::size_t i = 0; i < axes_; ++i) desired[i] += approach_step_[i];
    if (--approach_steps_left_ <= 0) {
      for (std::size_t i = 0; i < axes_; ++i) desired[i] = model_.synchro_joint_positions[i];
      phase_ = Phase::idle;
      return Result::done;
    }
  }
  return Result::running;
}

}  // namespace mrroc::edp
