#pragma once
// Checks of the motion a robot made, from the robot states its EDP broadcast (StateWatch).
#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <string>
#include <vector>

#include "mrroc/robot/robot_model.hpp"
#include "state_watch.hpp"

namespace mrroc::test {

/// Checks the commanded motion one EDP broadcast: velocities within the limits everywhere;
/// accelerations within the limits after the half-second dwell that follows an MP's approach
/// (carry_bar, tool_path: the approach itself is one long macro-step from standstill, whose
/// start no EDP check shapes yet). Returns the number of states after the dwell checked.
inline int check_motion(const std::vector<StateWatch::Sample>& states, const RobotModel& model,
                        double period_s, const std::string& robot) {
  struct Rate {
    std::int64_t step;
    double dt;
    std::vector<double> v;
  };
  std::vector<Rate> rates;
  for (std::size_t k = 1; k < states.size(); ++k) {
    const auto& a = states[k - 1];
    const auto& b = states[k];
    if (!a.synchronised || !b.synchronised || b.servo_step <= a.servo_step) continue;
    const double dt = static_cast<double>(b.servo_step - a.servo_step) * period_s;
    std::vector<double> v(model.axes());
    for (std::size_t j = 0; j < v.size(); ++j) {
      v[j] = (b.q_desired[j] - a.q_desired[j]) / dt;
      EXPECT_LE(std::abs(v[j]), model.max_velocity[j] * 1.0001)
          << robot << " joint " << j << " commanded at " << v[j] << " rad/s, limit "
          << model.max_velocity[j] << " rad/s";
    }
    rates.push_back({b.servo_step, dt, v});
  }
  // The dwell: the last run of still states lasting 0.4 s or more that motion follows (before
  // it come the synchronisation and the approach, after it only the carry).
  std::size_t carry = rates.size();
  std::size_t still_from = rates.size();
  for (std::size_t k = 0; k < rates.size(); ++k) {
    bool still = true;
    for (double x : rates[k].v) still = still && x == 0.0;
    if (still) {
      if (still_from == rates.size()) still_from = k;
      continue;
    }
    if (still_from != rates.size() &&
        static_cast<double>(rates[k].step - rates[still_from].step) * period_s >= 0.4)
      carry = k;
    still_from = rates.size();
  }
  int checked = 0;
  for (std::size_t k = carry + 1; k < rates.size(); ++k) {
    const double dt = 0.5 * (rates[k].dt + rates[k - 1].dt);
    for (std::size_t j = 0; j < model.axes(); ++j) {
      const double a = (rates[k].v[j] - rates[k - 1].v[j]) / dt;
      EXPECT_LE(std::abs(a), model.max_acceleration[j] * 1.0001)
          << robot << " joint " << j << " commanded acceleration " << a << " rad/s^2 at servo step "
          << rates[k].step << ", limit " << model.max_acceleration[j] << " rad/s^2";
    }
    ++checked;
  }
  return checked;
}

}  // namespace mrroc::test
