#pragma once
/// @file
/// A robot's state (robot_state_t, channel <robot>/edp/state), broadcast by its EDP every 20 ms:
/// the values of the last servo step.

#include <cstdint>
#include <string>
#include <vector>

namespace mrroc {

struct RobotState {
  std::string robot;
  bool synchronised = false;
  bool moving = false;            ///< a macro-step runs or the robot still decelerates
  bool estop = false;             ///< the emergency stop is engaged for this robot
  bool fault = false;             ///< the hardware reported a fault (SYNCHRO resets it)
  std::string error;              ///< the last fault or refused command, "" if none
  std::int64_t servo_step = 0;    ///< servo steps since the EDP started
  double servo_period_s = 0.0;    ///< [s]
  std::vector<double> q;          ///< measured joint positions [rad]
  std::vector<double> dq;         ///< measured joint velocities [rad/s] (one per joint)
  std::vector<double> q_desired;  ///< joint positions commanded in this step [rad] (one per joint)
  double lateness_mean_us = 0.0;  ///< servo wake-up lateness since the previous state [us]
  double lateness_max_us = 0.0;   ///< [us]
  std::int64_t overruns = 0;      ///< cycles since the EDP started that did not fit in a period
};

}  // namespace mrroc
