#pragma once
// The robot states of an LCM log file (written by lcm-logger): robot_state_t of every robot, from
// the channels "<robot>/edp/state".

#include <cstdint>
#include <filesystem>
#include <map>
#include <string>
#include <vector>

namespace mrroc::plot {

/// One robot_state_t.
struct StateSample {
  double t_s = 0.0;  ///< time since the first robot state of the log [s]
  std::int64_t servo_step = 0;
  std::vector<double> q, dq, q_desired;  ///< [rad], [rad/s], [rad]
  double lateness_mean_us = 0.0;
  double lateness_max_us = 0.0;
  std::int64_t overruns = 0;
};

struct RobotSeries {
  std::string robot;
  std::size_t n_joints = 0;
  std::vector<StateSample> samples;
  std::uint64_t other_joint_counts = 0;  ///< states dropped: n_joints differs from the first
};

struct RobotLog {
  std::map<std::string, RobotSeries> robots;  ///< by robot name (the channel's prefix)
  std::uint64_t events = 0;                   ///< events in the log, of every channel
  std::uint64_t malformed = 0;                ///< events on a state channel that did not decode
  std::int64_t first_utime = 0;  ///< time of the first robot state [us since the epoch]
};

/// Channel suffix of robot_state_t.
inline constexpr const char* kStateSuffix = "/edp/state";

/// Reads every robot_state_t of an LCM log file.
/// @throws mrroc::Error "cannot open ...", "... is empty", "... is not an LCM log file (...)".
RobotLog read_robot_log(const std::filesystem::path& file);

}  // namespace mrroc::plot
