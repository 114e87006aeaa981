#pragma once
// The robot states an EDP broadcasts (robot_state_t on <robot>/edp/state), as the operator's
// console sees them: the last one, the fastest commanded motion, every one with its arrival time.
#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "launch_helpers.hpp"
#include "mrroc/comm/bus.hpp"
#include "mrroc/comm/codec.hpp"
#include "mrroc/comm/request_reply.hpp"
#include "mrroc/config/process_set.hpp"
#include "mrroc/robot/robot_model.hpp"
#include "mrroc_lcm/robot_state_t.hpp"

namespace mrroc::test {

/// Fastest measured joint velocity of a state [rad/s].
inline double max_speed(const mrroc_lcm::robot_state_t& s) {
  double v = 0;
  for (double d : s.dq) v = std::max(v, std::abs(d));
  return v;
}

/// The robot states the EDP broadcasts, as the console sees them.
class StateWatch {
 public:
  explicit StateWatch(comm::Bus& bus, const std::string& robot = "irb6") : bus_(bus) {
    sub_ = bus_.subscribe<StateWatch*>(channels::robot_state(robot), &StateWatch::on_state, this);
  }
  ~StateWatch() { bus_.unsubscribe(sub_); }
  StateWatch(const StateWatch&) = delete;
  StateWatch& operator=(const StateWatch&) = delete;

  mrroc_lcm::robot_state_t last() const {
    std::lock_guard lock(mutex_);
    return last_;
  }
  int count() const {
    std::lock_guard lock(mutex_);
    return count_;
  }
  /// Per joint, the fastest commanded motion between two consecutive states [rad/s].
  std::vector<double> max_desired_rate() const {
    std::lock_guard lock(mutex_);
    return max_rate_;
  }
  /// One received state, with the time it arrived.
  struct Sample {
    Clock::time_point at;
    std::int64_t servo_step = 0;
    bool synchronised = false;
    bool moving = false;
    double max_speed = 0;  ///< fastest measured joint [rad/s]
    std::vector<double> q_desired;
    std::vector<double> q;      ///< measured joints
    std::int64_t overruns = 0;  ///< the servo loop's overruns since it started
  };
  std::vector<Sample> history() const {
    std::lock_guard lock(mutex_);
    return history_;
  }
  /// Waits until `pred(state)` holds for a state received after the call; returns it.
  template <class Pred>
  std::optional<mrroc_lcm::robot_state_t> wait_for(Pred pred, std::chrono::milliseconds timeout) {
    const int from = count();
    const auto until = Clock::now() + timeout;
    while (Clock::now() < until) {
      {
        std::lock_guard lock(mutex_);
        if (count_ > from && pred(last_)) return last_;
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(5));
    }
    return std::nullopt;
  }

 private:
  static void on_state(const lcm::ReceiveBuffer* buffer, const std::string&, StateWatch* self) {
    mrroc_lcm::robot_state_t s;
    if (!comm::detail::decode_received(buffer, s)) return;
    std::lock_guard lock(self->mutex_);
    if (self->count_ > 0 && s.servo_step > self->last_.servo_step && s.synchronised &&
        self->last_.synchronised && s.q_desired.size() == self->last_.q_desired.size()) {
      const double dt =
          static_cast<double>(s.servo_step - self->last_.servo_step) * s.servo_period_s;
      self->max_rate_.resize(s.q_desired.size(), 0.0);
      for (std::size_t i = 0; i < s.q_desired.size(); ++i)
        self->max_rate_[i] =
            std::max(self->max_rate_[i], std::abs(s.q_desired[i] - self->last_.q_desired[i]) / dt);
    }
    self->last_ = s;
    ++self->count_;
    self->history_.push_back({Clock::now(), s.servo_step, s.synchronised != 0, s.moving != 0,
                              max_speed(s), s.q_desired, s.q, s.overruns});
  }
  comm::Bus& bus_;
  mrroc::comm::Subscription* sub_ = nullptr;
  mutable std::mutex mutex_;
  mrroc_lcm::robot_state_t last_{};
  int count_ = 0;
  std::vector<double> max_rate_;
  std::vector<Sample> history_;
};

struct MotionCheck {
  int states = 0;
  double worst_velocity_share = 0.0;      ///< largest |v| / limit over joints and states
  double worst_acceleration_share = 0.0;  ///< largest |a| / limit
};

/// Commanded joint velocities and accelerations between the synchronised states the EDP
/// broadcast, against the model's limits (a gtest failure per state and joint beyond them).
inline MotionCheck check_commanded_motion(const std::vector<StateWatch::Sample>& states,
                                          const RobotModel& model, double period_s) {
  MotionCheck out;
  std::vector<double> previous;
  double previous_dt = 0.0;
  for (std::size_t k = 1; k < states.size(); ++k) {
    const auto& a = states[k - 1];
    const auto& b = states[k];
    if (!a.synchronised || !b.synchronised || b.servo_step <= a.servo_step) {
      previous.clear();
      continue;
    }
    const double dt = static_cast<double>(b.servo_step - a.servo_step) * period_s;
    std::vector<double> v(model.axes());
    for (std::size_t j = 0; j < v.size(); ++j) {
      v[j] = (b.q_desired[j] - a.q_desired[j]) / dt;
      const double share = std::abs(v[j]) / model.max_velocity[j];
      out.worst_velocity_share = std::max(out.worst_velocity_share, share);
      EXPECT_LE(share, 1.0001) << "joint " << j << " commanded at " << v[j] << " rad/s, limit "
                               << model.max_velocity[j] << " rad/s, servo step " << b.servo_step;
      if (!previous.empty()) {
        const double acc = (v[j] - previous[j]) / (0.5 * (dt + previous_dt));
        const double acc_share = std::abs(acc) / model.max_acceleration[j];
        out.worst_acceleration_share = std::max(out.worst_acceleration_share, acc_share);
        EXPECT_LE(acc_share, 1.0001)
            << "joint " << j << " commanded acceleration " << acc << " rad/s^2, limit "
            << model.max_acceleration[j] << " rad/s^2, servo step " << b.servo_step;
      }
    }
    previous = v;
    previous_dt = dt;
    ++out.states;
  }
  return out;
}

}  // namespace mrroc::test
