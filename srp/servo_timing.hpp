#pragma once
// Servo-loop timing of every robot, from the robot_state_t the EDPs broadcast.

#include <cstdint>
#include <map>
#include <string>
#include <vector>

namespace mrroc::srp {

/// One robot_state_t's timing fields.
struct TimingSample {
  std::int64_t servo_step = 0;
  double servo_period_s = 0.0;
  double lateness_mean_us = 0.0;  ///< since the previous state
  double lateness_max_us = 0.0;   ///< since the previous state
  std::int64_t overruns = 0;      ///< since the EDP started
};

/// Timing over a span of time (a 10 s window, or the whole run).
struct TimingSummary {
  std::uint64_t states = 0;       ///< robot_state_t received
  double servo_period_s = 0.0;    ///< of the last state
  double lateness_mean_us = 0.0;  ///< weighted by the servo steps each state covers
  double lateness_max_us = 0.0;
  std::int64_t overruns = 0;        ///< overruns in the span (counted from the second state)
  std::int64_t overruns_total = 0;  ///< the EDP's counter in the last state
  std::int64_t servo_steps = 0;     ///< servo steps the span covers
};

/// "period 2.000 ms, lateness mean 12.3 us, max 85.0 us, overruns 0 (total 0), 500 states"
std::string describe(const TimingSummary& summary);

class ServoTiming {
 public:
  void add(const std::string& robot, const TimingSample& sample);
  /// The window since the last call, per robot with at least one state in it; starts a new window.
  std::map<std::string, TimingSummary> take_window();
  /// Everything since the SRP started, per robot.
  [[nodiscard]] std::map<std::string, TimingSummary> total() const;

 private:
  struct Accumulator {
    TimingSummary summary;
    double weighted_lateness = 0.0;  ///< sum of mean * steps [us]
    double weight = 0.0;
    void add(const TimingSample& sample, std::int64_t steps, std::int64_t new_overruns);
    [[nodiscard]] TimingSummary result() const;
  };
  struct Robot {
    Accumulator window;
    Accumulator all;
    std::int64_t last_step = -1;
    std::int64_t last_overruns = 0;
  };
  std::map<std::string, Robot> robots_;
};

}  // namespace mrroc::srp
