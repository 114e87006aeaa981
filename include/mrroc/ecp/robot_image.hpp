#pragma once
/// @file
/// What generators and conditions see of a robot: its image (paper, section 3), and the errors a
/// motion ends with. No LCM, no config reader: a user's generator compiles against this alone
/// (ecp::Robot, mrroc/ecp/robot.hpp, fills the image in through its EDP client, edp::Client).

#include <cstdint>
#include <optional>
#include <vector>

#include <Eigen/Geometry>

#include "mrroc/core/error.hpp"
#include "mrroc/edp/client.hpp"
#include "mrroc/msg/edp_instruction.hpp"
#include "mrroc/robot/robot_model.hpp"

namespace mrroc::ecp {

class Robot;

/// Servo steps of one macro-step that moves the joints by `delta` from rest to rest within
/// `fraction` (0, 1] of each joint's velocity and acceleration limits, as the EDP moves it (it
/// accelerates uniformly over the first half and decelerates over the second: peak velocity
/// 2 d / T, acceleration 4 d / T^2; docs/edp.md, "Acceleration"), lasting at least `min_s`.
/// The console's jogs use it.
int rest_to_rest_steps(const RobotModel& model, const std::vector<double>& delta, double fraction,
                       double period_s, double min_s = 0.0);

/// The servo loop's timing, as GET TIMING returns it.
struct ServoTiming {
  std::int64_t cycles = 0;
  std::int64_t overruns = 0;  ///< cycles woken more than one period late
  double period_us = 0;
  double lateness_p50_us = 0;
  double lateness_p99_us = 0;
  double lateness_max_us = 0;
};

/// What generators see of a robot. Joint values in rad.
struct RobotImage {
  bool synchronised = false;
  std::vector<double> joints;            ///< measured (from the EDP's last reply)
  std::vector<double> desired_joints;    ///< commanded (from the EDP's last reply)
  std::vector<double> joint_velocities;  ///< measured [rad/s]
  int step_no = 0;                       ///< step of the macro-step the reading was taken in
  /// Macro-steps queued in the EDP when the reading was taken (the running one included): with
  /// a lookahead above 1 the reading is older than the command just sent (docs/edp.md).
  int macro_steps_ahead = 0;
  std::int64_t servo_cycle = 0;
  /// The last reading in the representation the command asked for (GET ARM), e.g. a frame.
  edp::ArmRepresentation arm_type = edp::ArmRepresentation::joint;
  std::vector<double> arm;

  /// What the latest GET of each item returned; empty until an instruction asked for it (a
  /// task's first reading, Robot::read_state and synchronise, asks for TOOL and MODEL).
  std::optional<Eigen::Isometry3d> tool;  ///< GET TOOL: the tool frame in the flange frame [m]
  std::optional<int> kinematic_model_no;  ///< GET MODEL: 0 = nominal
  std::optional<int> corrector_no;        ///< GET MODEL: 0 = none
  std::optional<std::vector<std::int8_t>> servo_algorithm;      ///< GET SERVO, per axis
  std::optional<std::vector<std::int8_t>> servo_parameters_no;  ///< GET SERVO, per axis
  std::optional<std::uint32_t> inputs;                          ///< GET INPUTS: bit i = line i
  std::optional<ServoTiming> timing;                            ///< GET TIMING
  /// GET DEVICE: the reply fields of the EDP plugin's device, in its order and units (a robot
  /// class derived from Robot reads them into its own fields: Robot::read_device_reply).
  std::optional<std::vector<double>> device;

  /// The instruction the next exchange sends (a generator fills it in each step).
  edp::Instruction command;
};

/// Thrown when the EDP refuses an instruction (code and text are the EDP's): edp::Client's error.
using EdpRefused = edp::Refused;

/// Thrown inside Move/Wait when the task is asked to stop.
class TaskStopped : public Error {
 public:
  using Error::Error;
};

}  // namespace mrroc::ecp
