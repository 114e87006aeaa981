#pragma once
/// @file
/// The `mujoco` EDP hardware plugin: a robot's axes simulated with MuJoCo 2.2.
///
/// Axes are the model's *actuators*: one axis per actuator, in actuator order, and each actuator
/// is a position servo on one hinge or slide joint (its *actuator joint*). When parameters.toml
/// lists robot.joint_names and the model has more actuators than names, the axes are the first
/// of them and the two after them are a gripper device (see device()). Joints of bodies outside
/// the robot's kinematic tree (e.g. a part to grasp on slide joints) are simulated, but are not
/// axes and get no gravity feed-forward. Other joints are
/// passive; they may belong to closed kinematic loops that the model closes with equality
/// constraints (e.g. a parallelogram `<connect>`). Each `write()` sets the actuators' targets and
/// advances the simulation by exactly one servo period (an integer number of MuJoCo steps).
/// Optional gravity/Coriolis feed-forward: `qfrc_applied = qfrc_bias` on every degree of freedom
/// before each step (in a closed loop this equals the motor torques that balance gravity, since
/// the loop reactions are internal forces).
///
/// Joint coordinates and the coupling. The EDP works in joint coordinates q (the serial-equivalent
/// chain of the URDF). `<model_dir>/parameters.toml` may declare a linear coupling between them
/// and the actuator joints' positions a:
///     [robot.transmission]
///     coupling = [[...], ...]     # n x n matrix M (n = number of actuators), a = M q
/// (default: identity). The plugin commands actuator i with (M q_setpoint)_i and reports
/// q = M^-1 a, velocities likewise. Example (RNT parallelogram): the elbow actuator drives the
/// absolute forearm angle a2 = q1 + q2, so its row is (0, 1, 1, 0, ...) and the reported elbow
/// joint is a2 - a1.
///
/// Raw positions behave like incremental encoders zeroed at power-on:
///   raw = joint position q - joint position at power-on.
/// The synchronisation switch of axis i is closed (true) while the joint position q_i is strictly
/// above `HardwareSetup::synchro_positions[i]`.
///
/// Plugin parameters (the `Params` table of `HardwareSetup`; unknown keys are rejected):
///   - `mjcf` (string, optional): MJCF file name relative to the model folder; default is
///     `robot.mjcf` of `<model_dir>/parameters.toml`.
///   - `initial_joint_positions` (list of numbers, rad, optional): joint pose q at power-on;
///     default = synchronisation pose + 0.05 rad on every axis, clamped into the joint range.
///   - `gravity_compensation` (bool, default true).
/// Unknown keys throw `ConfigError` ("unknown key 'x' in [robot.edp.params]").
///
/// `HardwareSetup::synchro_positions` may be left empty: the plugin then uses
/// `robot.synchro_joint_positions` of `<model_dir>/parameters.toml`. When that file exists and
/// lists `robot.joint_names`, they must equal the axis names (the actuator names; an unnamed
/// actuator is named after its joint).
///
/// Joint ranges: an axis' range is that of the model joint with the axis' name when there is one
/// (for a coupled axis, normally its passive serial joint), else that of its actuator joint when
/// the axis is uncoupled. The power-on pose must lie in those ranges, and M q in the actuator
/// joints' ranges. At configure time the plugin closes every kinematic loop at the power-on pose:
/// it holds the actuator joints at M q and solves the equality constraints for the passive joints
/// (Gauss-Newton from the model's qpos0, continued in small steps). It then checks that the loops
/// are closed (violation below `kLoopClosureTolerance`), that the passive joints are inside their
/// ranges and that a joint named like a coupled axis is at that axis' position (so the coupling
/// matches the model).
///
/// Cycle calls: `read()` works once configured (also while inactive, reporting the frozen state);
/// `write()` needs `activate()`. An unstable simulation (non-finite state, a MuJoCo warning, or a
/// closed loop opening by more than `kLoopOpenFault`) is reported as `CycleStatus::fault` by every
/// later `read()`/`write()` until `activate()` resets the simulation to the power-on pose.
/// Setpoints outside an actuator's range are clamped by its `ctrlrange`.

#include <array>
#include <cstddef>
#include <filesystem>
#include <span>
#include <string>
#include <vector>

#include <mujoco/mujoco.h>

#include "mrroc/edp/hardware.hpp"
#include "mrroc/sim/robot_axes.hpp"

namespace mrroc::edp {

class MujocoHardware : public Hardware {
 public:
  /// Offset of the default power-on pose from the synchronisation pose on every axis [rad].
  static constexpr double kDefaultPowerOnOffset = sim::kDefaultPowerOnOffset;
  /// Largest equality-constraint violation accepted after closing the loops at power-on [m or rad].
  static constexpr double kLoopClosureTolerance = sim::kLoopClosureTolerance;
  /// Largest coupling error accepted between a coupled axis and the joint of the same name [rad].
  static constexpr double kCouplingTolerance = sim::kCouplingTolerance;
  /// An equality-constraint violation above this during the simulation is a fault [m or rad].
  static constexpr double kLoopOpenFault = sim::kLoopOpenFault;

  MujocoHardware() = default;
  ~MujocoHardware() override;
  MujocoHardware(const MujocoHardware&) = delete;
  MujocoHardware& operator=(const MujocoHardware&) = delete;
  MujocoHardware(MujocoHardware&&) = delete;
  MujocoHardware& operator=(MujocoHardware&&) = delete;

  [[nodiscard]] std::string name() const override { return "mujoco"; }
  /// Simulated time advances one servo period per write(): lock-step capable.
  [[nodiscard]] bool simulated() const override { return true; }
  [[nodiscard]] bool drives_real_devices() const override { return false; }
  [[nodiscard]] std::size_t axis_count() const override { return axes_; }

  void configure(const HardwareSetup& setup) override;
  void activate() override;
  void deactivate() override;

  CycleStatus read(std::span<AxisFeedback> out) override;
  CycleStatus write(std::span<const double> setpoints) override;

  [[nodiscard]] std::string fault_text() const override;

  /// Servo algorithm 0: the MJCF position servo with gravity feed-forward. Algorithm 1: the same
  /// plus velocity feed-forward (the commanded velocity times the joint's damping). The
  /// parameter sets of both scale the position gain kp: 0 nominal (x1), 1 soft (x0.25),
  /// 2 stiff (x2).
  [[nodiscard]] int servo_algorithm_count() const override { return 2; }
  [[nodiscard]] int servo_parameter_set_count(int algorithm) const override;
  void set_servo(std::size_t axis, int algorithm, int parameter_set) override;
  static constexpr std::array<double, 3> kServoGainScale = {1.0, 0.25, 2.0};

  /// Emulated I/O: inputs 0..15 are the axes' synchronisation switches, inputs 16..31 read back
  /// outputs 0..15.
  [[nodiscard]] bool binary_io() const override { return true; }
  /// Outputs 0..15: the ones the loop-back plug wires to inputs 16..31.
  [[nodiscard]] std::uint32_t output_lines() const override { return 0xFFFFU; }
  void write_outputs(std::uint32_t values) override { outputs_ = values; }
  [[nodiscard]] std::uint32_t read_inputs() const override;

  /// The gripper device, when the model has one: the two actuators after the arm's (whose
  /// names are robot.joint_names of parameters.toml), each on a finger's slide joint whose
  /// position is half the opening (robots/irb6/irb6_gripper.xml).
  ///   command: opening [m] (0 .. the sum of the finger joints' upper range ends), force [N]
  ///            (0 .. the smaller upper end of the actuators' forcerange): each finger is
  ///            servoed to half the opening, pushing with at most the force.
  ///   reply:   opening [m], opening speed [m/s], grip force [N] (the mean over the two fingers
  ///            of the normal forces of their contacts with bodies outside the robot), holding
  ///            (1: both fingers press on one object with at least kHoldingForce, have stopped
  ///            (|speed| < kStoppedSpeed) and are kHoldingMargin or more short of the commanded
  ///            opening, i.e. stopped on the object before closing fully).
  /// At power-on the fingers are open, pushing with kGripperPowerOnForce. No device (empty
  /// name) without those actuators.
  [[nodiscard]] DeviceDescription device() const override;
  void write_device(std::span<const double> command) override;
  void read_device(std::span<double> reply) const override;
  static constexpr double kHoldingForce = 0.5;          ///< [N]
  static constexpr double kStoppedSpeed = 0.002;        ///< [m/s]
  static constexpr double kHoldingMargin = 0.001;       ///< [m]
  static constexpr double kGripperPowerOnForce = 10.0;  ///< [N]

  /// The loaded model and its data (nullptr before configure()).
  [[nodiscard]] const mjModel* model() const { return model_; }
  [[nodiscard]] const mjData* data() const { return data_; }

  /// True (simulated) joint positions q = M^-1 a [rad]; empty before configure().
  [[nodiscard]] std::vector<double> true_joint_positions() const;
  /// True positions a of the actuator joints, in axis order [rad]; empty before configure().
  [[nodiscard]] std::vector<double> actuator_joint_positions() const;
  /// Model joint id of each axis' actuator joint.
  [[nodiscard]] const std::vector<int>& actuator_joints() const { return robot_.joint; }
  /// The coupling M (a = M q), row-major n x n; identity unless parameters.toml declares one.
  [[nodiscard]] const std::vector<double>& coupling() const { return robot_.coupling.matrix(); }
  /// True when M is not the identity.
  [[nodiscard]] bool coupled() const { return robot_.coupling.coupled(); }
  /// Largest |violation| of the equality constraints [m or rad], as computed at the beginning of
  /// the last MuJoCo step (0 for a model without equality constraints).
  [[nodiscard]] double equality_violation() const noexcept;
  /// True joint positions at power-on (raw position zero) [rad].
  [[nodiscard]] const std::vector<double>& power_on_positions() const { return robot_.power_on; }
  /// Joint positions at which the synchronisation switches toggle [rad].
  [[nodiscard]] const std::vector<double>& synchro_positions() const { return robot_.synchro; }
  /// Path of the loaded MJCF file.
  [[nodiscard]] const std::filesystem::path& mjcf_path() const { return mjcf_path_; }
  /// MuJoCo steps per servo period.
  [[nodiscard]] int substeps() const { return substeps_; }
  [[nodiscard]] bool active() const { return active_; }

 private:
  struct GripperDevice {
    bool present = false;
    std::array<int, 2> actuator{};
    std::array<int, 2> qpos_adr{};
    std::array<int, 2> dof_adr{};
    std::array<int, 2> body{};  ///< each finger's body
    double max_opening = 0.0;   ///< [m]
    double max_force = 0.0;     ///< [N]
    double command_opening = 0.0;
  };
  /// The gripper of the actuators from `first` on (none when there are none).
  /// @throws HardwareError when they are not two force-limited actuators on slide joints.
  static GripperDevice find_gripper(const mjModel* m, int first, const sim::RobotAxes& arm,
                                    const std::filesystem::path& mjcf);
  void set_finger_force(double force_n) noexcept;
  void release() noexcept;
  void reset_to_power_on() noexcept;
  [[gnu::format(printf, 2, 3)]] void set_fault(const char* format, ...) noexcept;
  /// False (with the fault text set) when the simulation went unstable.
  [[nodiscard]] bool check_stable() noexcept;

  mjModel* model_ = nullptr;
  mjData* data_ = nullptr;
  std::filesystem::path mjcf_path_;
  std::size_t axes_ = 0;
  int substeps_ = 0;
  bool gravity_compensation_ = true;
  bool active_ = false;

  // The axes (axis i = actuator i of the model), coupling, synchronisation and power-on poses.
  sim::RobotAxes robot_;
  std::vector<double> power_on_qpos_;  // the whole model state at power-on (loops closed)
  // Scratch buffers of the cycle calls (sized in configure(), so read/write do not allocate).
  std::vector<double> scratch_a_;
  std::vector<double> scratch_q_;

  int warnings_at_activate_ = 0;
  std::vector<double> nominal_kp_;
  std::vector<double> previous_ctrl_;  ///< actuator targets of the previous write()
  std::vector<double> feed_forward_;   ///< velocity feed-forward force per axis [N m]
  std::vector<int> servo_algorithm_;
  bool have_previous_ctrl_ = false;
  std::uint32_t outputs_ = 0;
  std::array<bool, 16> switch_state_{};  ///< as of the last read()
  std::array<char, 512> fault_{};
  GripperDevice gripper_;
  std::vector<bool> compensated_;  ///< per degree of freedom: gravity feed-forward (the robot's)
  int robot_root_ = 0;             ///< root body of the robot's kinematic tree
};

}  // namespace mrroc::edp
