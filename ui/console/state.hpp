#pragma once
// What the web console knows of the running set: each robot's latest robot state and its
// recent samples, the cell emulator's scene objects, the launcher's process table, every process'
// last status, the SRP's messages and the MP's state. The bus feed (bus_feed.hpp) writes it from
// the bus thread and the poller; the HTTP threads, the jog and the teach-in read it. Every method
// is thread-safe; readers get copies (snapshots), never references into the guarded data.

#include <chrono>
#include <cstdint>
#include <deque>
#include <map>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include "mrroc/comm/reporter.hpp"
#include "mrroc/msg/launch.hpp"
#include "mrroc/msg/robot_state.hpp"
#include "mrroc/msg/scene_objects.hpp"
#include "mrroc/robot/robot_model.hpp"
#include "operator.hpp"

namespace mrroc::ui {

using SteadyClock = std::chrono::steady_clock;

inline constexpr std::size_t kMaxSamples = 1500;  ///< robot states kept: 30 s at 50 Hz
/// A robot state this many servo steps or more behind the newest sample means the EDP started
/// again (its samples are dropped); a state less far behind is a repeat and is not a sample.
inline constexpr std::int64_t kRestartSteps = 1000;
inline constexpr std::size_t kMaxLog = 5000;  ///< SRP messages kept
inline constexpr double kStateFreshS = 1.0;   ///< a robot state older than this is stale [s]
inline constexpr double kLaunchFreshS = 3.0;  ///< the launcher broadcasts every second [s]
/// The MP's state is unknown when its last answer is older than this [s]. The console asks the
/// MP for it every 0.4 s and a call gives up after 3 x 150 ms (bus_feed.cpp), forgetting it
/// (on_mp_silent): an older answer means the asking stopped or hangs, and a task may have started
/// since.
inline constexpr double kMpFreshS = 2.0;

/// [s] from `t` to now.
double seconds_since(SteadyClock::time_point t);

/// A robot of the set: fixed when the console starts.
struct ConsoleRobot {
  std::string name;
  RobotModel model;
  double servo_period_s = kDefaultServoPeriodS;  ///< the EDP's configured period [s]
  bool cartesian = false;  ///< its kinematics offer FRAME etc. (the console's tool jogs)
  /// Its EDP's limits before SYNCHRO ([robot.edp] unsynchronised_*): the smaller of the
  /// velocity and acceleration fractions, and the largest joint change of one move [rad | m].
  double unsynchronised_fraction = 0.1;
  double unsynchronised_max_move = 0.1;
};

/// One robot state as the plots need it.
struct Sample {
  std::int64_t step = 0;
  std::int64_t utime = 0;
  std::vector<double> q;   ///< [rad]
  std::vector<double> dq;  ///< [rad/s]
  double lateness_mean_us = 0.0;
  double lateness_max_us = 0.0;
};

/// The latest robot state of a robot, when it was sent and when it came.
struct RobotReading {
  RobotState state;
  std::int64_t utime = 0;  ///< time of sending [us since the Unix epoch] (its envelope's)
  SteadyClock::time_point received{};
  [[nodiscard]] bool fresh() const { return seconds_since(received) <= kStateFreshS; }
};

/// The MP's last answer and when it came.
struct MpReading {
  MpStatus status;
  SteadyClock::time_point received{};
  [[nodiscard]] double age_s() const { return seconds_since(received); }
  [[nodiscard]] bool fresh() const { return age_s() <= kMpFreshS; }
};

/// The cell emulator's latest scene objects and their poses (scene_objects_t), when they were
/// sent and when they came.
struct ObjectsReading {
  SceneObjects objects;
  std::int64_t utime = 0;  ///< time of sending [us since the Unix epoch] (its envelope's)
  std::int64_t seq = 0;    ///< the emulator's number of the message
  SteadyClock::time_point received{};
};

/// One SRP message and its number in the console's log.
struct LogEntry {
  std::int64_t number = 0;
  SrpMessage message;
};

/// The messages numbered above `after` with at least a severity (ConsoleState::messages).
struct LogView {
  std::int64_t last = 0;  ///< number of the newest message kept, 0 if none
  int epoch = 1;          ///< changes when the log was renumbered (the SRP's history merged in)
  bool history_loaded = false;
  std::int64_t srp_last = 0;  ///< the SRP's own number of its newest message (from its history)
  std::vector<LogEntry> entries;
};

/// A process' last status and how long ago it came.
struct SeenProcess {
  ProcessStatus status;
  double silent_s = 0.0;
};

/// Everything /api/state shows, copied at one moment.
struct StateSnapshot {
  std::optional<MpStatus> mp;  ///< the MP's last answer while fresh (kMpFreshS)
  std::string mp_error;        ///< why the last STATUS got no answer, or how old the last one is
  /// The launcher's table, when one came in the last kLaunchFreshS.
  std::optional<launch::LaunchStatus> launch;
  std::map<std::string, SeenProcess> processes;
  struct Robot {
    std::optional<RobotReading> reading;
    double age_s = 0.0;  ///< of `reading` [s]
  };
  std::vector<Robot> robots;  ///< in the order of ConsoleState::robots()
  std::int64_t log_last = 0;
  int log_epoch = 1;
  bool history_loaded = false;
};

class ConsoleState {
 public:
  /// @param set_name  the set's name, for the error naming an unknown robot
  ConsoleState(std::string set_name, std::vector<ConsoleRobot> robots);

  /// The set's robots (fixed: safe to read without a lock).
  [[nodiscard]] const std::vector<ConsoleRobot>& robots() const { return robots_; }
  /// The robot named `name`. @throws ApiError 404 naming the set's robots.
  [[nodiscard]] const ConsoleRobot& robot(const std::string& name) const;
  /// Its index in robots(). @throws ApiError 404 as robot().
  [[nodiscard]] std::size_t robot_index(const std::string& name) const;

  // --- written by the bus feed ------------------------------------------------------------------

  /// A robot state of robots()[index], sent at `utime` [us since the Unix epoch]; ignored when
  /// its number of joints is not the model's. A servo step not above the last sample's starts
  /// the samples again (the EDP restarted).
  void on_robot_state(std::size_t index, const RobotState& state, std::int64_t utime,
                      SteadyClock::time_point received = SteadyClock::now());
  void on_launch_status(const launch::LaunchStatus& status,
                        SteadyClock::time_point received = SteadyClock::now());
  /// The emulator's scene objects, message number `seq`, sent at `utime`.
  void on_scene_objects(const SceneObjects& objects, std::int64_t utime, std::int64_t seq,
                        SteadyClock::time_point received = SteadyClock::now());
  /// A live SRP message: numbered next; the oldest beyond kMaxLog are dropped.
  void on_message(const SrpMessage& message);
  void on_process_status(const ProcessStatus& status,
                         SteadyClock::time_point received = SteadyClock::now());
  /// The MP's answer to a command or STATUS.
  void on_mp_status(const MpStatus& status, SteadyClock::time_point received = SteadyClock::now());
  /// No MP answered STATUS: forget its state, keep `error` to show.
  void on_mp_silent(const std::string& error);
  /// The SRP's history (oldest first) and its newest number: put before the live messages,
  /// dropping live ones that are also in it, numbered again from 1 (the epoch changes).
  void merge_history(const std::vector<SrpMessage>& history, std::int64_t srp_last);
  [[nodiscard]] bool history_loaded() const;

  // --- read by the HTTP part, the jog and the teach-in -----------------------------------------

  [[nodiscard]] StateSnapshot snapshot() const;
  /// The latest robot state of robots()[index], nothing before the first.
  [[nodiscard]] std::optional<RobotReading> reading(std::size_t index) const;
  /// The samples of robots()[index] after servo step `after`, oldest first.
  [[nodiscard]] std::vector<Sample> samples_after(std::size_t index, std::int64_t after) const;
  /// The messages numbered above `after` with severity >= `min_severity`, the newest `max`.
  [[nodiscard]] LogView messages(std::int64_t after, int min_severity, std::size_t max) const;
  /// The MP's last answer while it is fresh (kMpFreshS): nothing before the first, after
  /// on_mp_silent, or when the last is older (the MP's state is unknown).
  [[nodiscard]] std::optional<MpStatus> mp() const;
  /// The MP's last answer and when it came, stale or not; nothing before the first or after
  /// on_mp_silent.
  [[nodiscard]] std::optional<MpReading> mp_reading() const;
  /// Why the last STATUS got no answer ("" after an answer).
  [[nodiscard]] std::string mp_error() const;
  /// The latest scene objects, nothing before the first (a set without an emulator's scene).
  [[nodiscard]] std::optional<ObjectsReading> scene_objects() const;
  /// True once a robot state received after `since` shows robots()[index] at rest.
  [[nodiscard]] bool at_rest_since(std::size_t index, SteadyClock::time_point since) const;
  /// The servo step each robot (or only `robot`, when not empty) is in now, estimated from its
  /// last robot state and its period; robots with none are left out.
  [[nodiscard]] std::map<std::string, std::int64_t> estimated_servo_steps(
      const std::string& robot) const;

 private:
  struct RobotData {
    std::optional<RobotReading> reading;
    std::deque<Sample> samples;
  };
  std::string set_name_;
  std::vector<ConsoleRobot> robots_;
  mutable std::mutex mutex_;
  std::vector<RobotData> data_;  // parallel to robots_
  std::optional<launch::LaunchStatus> launch_;
  SteadyClock::time_point launch_received_{};
  std::optional<ObjectsReading> objects_;
  std::map<std::string, std::pair<ProcessStatus, SteadyClock::time_point>> processes_;
  std::deque<LogEntry> log_;
  std::int64_t log_next_ = 1;
  int log_epoch_ = 1;
  bool history_loaded_ = false;
  std::int64_t srp_last_ = 0;
  std::optional<MpReading> mp_;
  std::string mp_error_;
};

}  // namespace mrroc::ui
