#pragma once
/// @file
/// The `mujoco` EDP hardware plugin: a robot's axes simulated with MuJoCo 2.2.
///
/// The model is an MJCF file in the robot's model folder with one hinge joint and one position
/// actuator per axis (axis order = joint order in the model). Each `write()` sets the actuators'
/// targets and advances the simulation by exactly one servo period (an integer number of MuJoCo
/// steps). Optional gravity/Coriolis feed-forward: `qfrc_applied = qfrc_bias` before each step.
///
/// Raw positions behave like incremental encoders zeroed at power-on:
///   raw = true joint position - true joint position at power-on.
/// The synchronisation switch of axis i is closed (true) while the true joint position is strictly
/// above `HardwareSetup::synchro_positions[i]`.
///
/// Plugin parameters (the `Params` table of `HardwareSetup`; unknown keys are rejected):
///   - `mjcf` (string, optional): MJCF file name relative to the model folder; default is
///     `robot.mjcf` of `<model_dir>/parameters.toml`.
///   - `initial_joint_positions` (list of numbers, rad, optional): true joint pose at power-on;
///     default = synchronisation pose + 0.05 rad on every axis, clamped into the joint range.
///   - `gravity_compensation` (bool, default true).
/// Unknown keys throw `ConfigError` ("unknown key 'x' in [robot.edp.params]").
///
/// `HardwareSetup::synchro_positions` may be left empty: the plugin then uses
/// `robot.synchro_joint_positions` of `<model_dir>/parameters.toml`. When that file exists and
/// lists `robot.joint_names`, they must equal the model's joint names.
///
/// Cycle calls: `read()` works once configured (also while inactive, reporting the frozen state);
/// `write()` needs `activate()`. An unstable simulation (non-finite state or a MuJoCo warning) is
/// reported as `CycleStatus::fault` by every later `read()`/`write()` until `activate()` resets the
/// simulation to the power-on pose. Setpoints outside the joint range are clamped by the
/// actuators' `ctrlrange`.

#include <array>
#include <cstddef>
#include <filesystem>
#include <span>
#include <string>
#include <vector>

#include <mujoco/mujoco.h>

#include "mrroc/edp/hardware.hpp"

namespace mrroc::edp {

class MujocoHardware : public Hardware {
 public:
  /// Offset of the default power-on pose from the synchronisation pose on every axis [rad].
  static constexpr double kDefaultPowerOnOffset = 0.05;

  MujocoHardware() = default;
  ~MujocoHardware() override;
  MujocoHardware(const MujocoHardware&) = delete;
  MujocoHardware& operator=(const MujocoHardware&) = delete;
  MujocoHardware(MujocoHardware&&) = delete;
  MujocoHardware& operator=(MujocoHardware&&) = delete;

  [[nodiscard]] std::string name() const override { return "mujoco"; }
  [[nodiscard]] std::size_t axis_count() const override { return axes_; }

  void configure(const HardwareSetup& setup) override;
  void activate() override;
  void deactivate() override;

  CycleStatus read(std::span<AxisFeedback> out) override;
  CycleStatus write(std::span<const double> setpoints) override;

  [[nodiscard]] std::string fault_text() const override;

  /// The loaded model and its data (nullptr before configure()).
  [[nodiscard]] const mjModel* model() const { return model_; }
  [[nodiscard]] const mjData* data() const { return data_; }

  /// True (simulated) joint positions [rad]; empty before configure().
  [[nodiscard]] std::vector<double> true_joint_positions() const;
  /// True joint positions at power-on (raw position zero) [rad].
  [[nodiscard]] const std::vector<double>& power_on_positions() const { return power_on_; }
  /// Joint positions at which the synchronisation switches toggle [rad].
  [[nodiscard]] const std::vector<double>& synchro_positions() const { return synchro_; }
  /// Path of the loaded MJCF file.
  [[nodiscard]] const std::filesystem::path& mjcf_path() const { return mjcf_path_; }
  /// MuJoCo steps per servo period.
  [[nodiscard]] int substeps() const { return substeps_; }
  [[nodiscard]] bool active() const { return active_; }

 private:
  void release() noexcept;
  void reset_to_power_on() noexcept;
  [[gnu::format(printf, 2, 3)]] void set_fault(const char* format, ...) noexcept;
  [[nodiscard]] bool state_is_finite() const noexcept;
  /// False (with the fault text set) when the simulation went unstable.
  [[nodiscard]] bool check_stable() noexcept;
  [[nodiscard]] int warning_total() const noexcept;

  mjModel* model_ = nullptr;
  mjData* data_ = nullptr;
  std::filesystem::path mjcf_path_;
  std::size_t axes_ = 0;
  int substeps_ = 0;
  bool gravity_compensation_ = true;
  bool active_ = false;

  // Per axis (axis i = joint i of the model); all sized in configure().
  std::vector<int> qpos_adr_;
  std::vector<int> dof_adr_;
  std::vector<int> actuator_;
  std::vector<double> power_on_;
  std::vector<double> synchro_;

  int warnings_at_activate_ = 0;
  std::array<char, 512> fault_{};
};

}  // namespace mrroc::edp
