#pragma once
/// @file
/// The MP's robots: an image of each robot (kept current from the ECPs' replies) and the link to
/// its ECP, with the MP-level Move and Wait of the paper (section 4): the MP works on images of
/// several robots; on this level Move sends every robot's next pose each macro-step (continuous
/// coordination), and the sporadic commands (START_TASK, NEXT_STATE) run whole ECP tasks.
/// No LCM here: the links to the ECP live behind a pointer, in src/mp/robot.cpp.

#include <condition_variable>
#include <cstdint>
#include <exception>
#include <functional>
#include <limits>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "mrroc/ecp/generator.hpp"
#include "mrroc/msg/mp_command.hpp"

namespace mrroc::comm {
class Bus;
}  // namespace mrroc::comm

namespace mrroc::mp {

/// What MP generators see of one robot. Units: rad, m.
struct RobotImage {
  std::string name;
  bool synchronised = false;
  std::vector<double> joints;          ///< measured, from the last ECP reply
  std::vector<double> desired_joints;  ///< commanded, from the last ECP reply
  edp::ArmRepresentation arm_type = edp::ArmRepresentation::joint;
  std::vector<double> arm;  ///< the last NEXT_POSE reading, in arm_type
  /// From the EDP's robot_state_t broadcast (every 20 ms), in the images Robot::state_image makes
  /// (mp::Wait hands them to its condition): also while the ECP runs a task of its own.
  bool moving = false;
  std::vector<double> joint_velocities;  ///< measured [rad/s]
  std::int64_t state_servo_step = -1;    ///< servo step of the state copied in; -1: none yet

  /// The NEXT_POSE the MP sends this macro-step; a generator sets `commanded` to include the
  /// robot in the step.
  ecp::MpCommand command;
  bool commanded = false;
};

/// Thrown when an ECP answers ERROR (its class, code and text are kept: error_class(), code()).
/// An error the EDP reported comes with the EDP's code (edp::error_code) and class
/// (edp::error_class_of): a non-fatal one refused a command before anything moved, and the MP
/// may retry or try another.
class EcpFailed : public RemoteError {
 public:
  EcpFailed(const std::string& robot, const ecp::EcpReply& reply);
};

/// The MP's link to one robot's ECP. Long commands (START_TASK, NEXT_STATE, NEXT_POSE,
/// END_MOTION) and operator commands (STOP, PAUSE, RESUME) use separate request/reply clients,
/// so that a STOP is never queued behind a running task.
class Robot {
 public:
  Robot(comm::Bus& bus, const std::string& robot_name);
  ~Robot();
  Robot(const Robot&) = delete;
  Robot& operator=(const Robot&) = delete;

  [[nodiscard]] const std::string& name() const { return image_.name; }
  [[nodiscard]] RobotImage& image() { return image_; }
  [[nodiscard]] const RobotImage& image() const { return image_; }

  /// Runs the ECP's configured task; returns when it terminated. @throws EcpFailed, TimeoutError.
  void start_task();
  /// Runs the ECP task `state` with TOML `arguments`; returns when it terminated.
  void next_state(const std::string& state, const std::string& arguments = {});
  /// Sends image().command (one macro-step) and updates the image from the reply.
  void next_pose();
  /// Ends a series of NEXT_POSE: the ECP reads the robot's state into the image.
  void end_motion();
  /// STOP to the ECP (on the control link). When the ECP does not answer it (TimeoutError after
  /// 10 attempts of 100 ms), the task's command waiting for that ECP ends at once and further
  /// commands to it throw ecp::TaskStopped while the stop lasts, instead of waiting for a silent
  /// ECP (12 attempts of 250 ms each).
  void stop();
  void pause();
  void resume();
  /// An image of the robot from the newest authentic robot_state_t of its EDP (name, joints,
  /// desired joints, velocities, synchronised, moving, servo step); `state_servo_step` -1 and no
  /// joints when none has arrived yet. Thread-safe: image() belongs to the thread that sends the
  /// robot's commands, which may be running a task while the MP waits (mp::Running).
  [[nodiscard]] RobotImage state_image() const;

 private:
  ecp::EcpReply checked(const ecp::EcpReply& reply);
  ecp::EcpReply command(const ecp::MpCommand& c);
  ecp::EcpReply control(ecp::MpCommandType type);
  RobotImage image_;
  struct Links;
  std::unique_ptr<Links> links_;
};

using RobotList = std::vector<Robot*>;
using ImageList = std::vector<RobotImage*>;

/// An MP-level generator: computes the next pose of every robot from the robot images and the
/// sensor images (paper, figure 4, on the MP level).
class Generator {
 public:
  virtual ~Generator() = default;
  /// Fills the commands of the first macro-step (set `commanded`). false: nothing to do.
  virtual bool first_step(const ImageList& robots, const ecp::SensorList& sensors) = 0;
  /// Called after every robot's reply: next commands, or false when the terminal condition holds.
  virtual bool next_step(const ImageList& robots, const ecp::SensorList& sensors) = 0;
  /// The robots of the motion were brought to rest away from the path this generator planned:
  /// the queues of their EDPs ran dry (a client held back longer than the lookahead covers) and
  /// the next macro-step was then refused by one of them as too fast or too abrupt from where it
  /// stands (error `too_fast` / `too_abrupt`). Move has ended the motion on every robot of the
  /// group (END_MOTION) and waited until all stood still; `robots` hold their measured and
  /// commanded joints there (start from the commanded ones: the EDP holds the robot there). Prepare
  /// commands that continue the coordinated motion from rest and return true; false (the default)
  /// makes Move fail with the refusal.
  virtual bool resume(const ImageList& /*robots*/, const ecp::SensorList& /*sensors*/) {
    return false;
  }
};

/// Move on the MP level: each macro-step sends NEXT_POSE to every commanded robot at once (one
/// thread per robot) and waits for all replies before the next step; ends every robot's motion
/// with END_MOTION. When a robot's EDP refuses a macro-step as too fast or too abrupt (it had to
/// stop for want of macro-steps), the whole group stops: END_MOTION to every robot, a wait until
/// all stand still (at most 5 s), and the generator's `resume` re-plans from there (at most 3
/// refusals in a row). @throws EcpFailed / TimeoutError from any robot (END_MOTION is sent to
/// every robot first: their EDPs finish the macro-step they run and hold).
void Move(const RobotList& robots, const ecp::SensorList& sensors, Generator& generator);

/// An MP-level condition (paper, section 4): decides from the images of several robots and the
/// sensor images.
class Condition {
 public:
  virtual ~Condition() = default;
  virtual bool check(const ImageList& robots, const ecp::SensorList& sensors) = 0;
};

/// Wait on the MP level: refreshes the sensor images until `condition` holds.
void Wait(const ecp::SensorList& sensors, ecp::Condition& condition, double period_s = 0.01);

/// Wait on the MP level over robots and sensors: every `period_s` refreshes the sensor images and
/// hands `condition` an image of each robot from its EDP's state broadcast (Robot::state_image;
/// the robots' own image() are left to their command threads), until it holds.
/// @throws TimeoutError after `timeout_s` [s] naming it; ecp::TaskStopped on STOP.
void Wait(const RobotList& robots, const ecp::SensorList& sensors, Condition& condition,
          double period_s = 0.02, double timeout_s = std::numeric_limits<double>::infinity());

/// Runs one function per robot at the same time and rethrows the first error after all ended
/// (e.g. `parallel(robots, [](Robot& r) { r.start_task(); })`).
void parallel(const RobotList& robots, const std::function<void(Robot&)>& action);

/// One function per robot running at the same time, the MP waiting for the first to end (the
/// paper's MP hears each ECP as it answers), e.g. two robots' tasks, the one done first given
/// the next job while the other goes on:
///
///   mp::Running tasks(robots, [](mp::Robot& r) { r.start_task(); });
///   mp::Robot& first = tasks.wait_any();   // rethrows the error of the one that failed
///   ...
///   tasks.wait_all();
///
/// The destructor waits for every function (their ECP commands end by themselves or on STOP).
class Running {
 public:
  Running(const RobotList& robots, std::function<void(Robot&)> action);
  ~Running();
  Running(const Running&) = delete;
  Running& operator=(const Running&) = delete;

  /// The next robot whose function ended (in the order they ended; each once).
  /// @throws what that function threw; Error when every robot was already returned;
  /// TimeoutError after `timeout_s` [s].
  Robot& wait_any(double timeout_s = std::numeric_limits<double>::infinity());
  /// Waits for every function not yet returned by wait_any; rethrows the first error among them.
  void wait_all();

 private:
  struct Slot {
    Robot* robot = nullptr;
    bool done = false;
    bool returned = false;
    std::exception_ptr error;
  };
  std::mutex mutex_;
  std::condition_variable ended_;
  std::vector<Slot> slots_;
  std::vector<std::size_t> order_;  ///< indices of the slots in the order they ended
  std::vector<std::thread> threads_;
};

}  // namespace mrroc::mp
