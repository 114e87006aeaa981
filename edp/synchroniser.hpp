#pragma once
/// @file
/// The EDP's synchronisation (paper, section 5: SYNCHRO): every axis speeds up to a slow search
/// velocity towards its synchronisation switch; where the switch toggles, the offset between raw
/// axis position and joint coordinate is known and the axis slows down to rest; then the arm
/// approaches the synchronisation pose exactly, from rest to rest. Every velocity change stays
/// within half the joint's acceleration limit. Axes the hardware homed by itself
/// (Hardware::self_homing_axes, homed before `begin`) are taken as found where they stand, with
/// offset 0 (their raw positions are joint coordinates), and only approach the pose.
/// Driven one servo step at a time by the servo loop (under its mutex); allocation-free.

#include <array>
#include <cstddef>
#include <cstdint>
#include <span>

#include "macro_step_queue.hpp"
#include "mrroc/edp/hardware.hpp"
#include "mrroc/robot/robot_model.hpp"

namespace mrroc::edp {

class Synchroniser {
 public:
  enum class Phase { idle, search, approach };
  enum class Result { running, done, failed };

  explicit Synchroniser(const RobotModel& model) : model_(model), axes_(model.axes()) {}

  /// Starts from the raw positions `desired` and the switches as they are now; the axes of
  /// `homed` (bit i = axis i) count as found, their `offset` 0.
  void begin(std::span<const AxisFeedback> feedback, const AxisArray& desired, AxisArray& offset,
             std::uint32_t homed = 0);
  /// One servo step: moves `desired` (raw until the switches are found, then joint
  /// coordinates), fills `offset` (joint = raw + offset). On `failed`, `text` says why.
  Result step(std::span<const AxisFeedback> feedback, double period_s, AxisArray& desired,
              AxisArray& offset, std::span<char> text);
  /// True once every switch was found (desired is in joint coordinates from then on).
  [[nodiscard]] bool found() const { return phase_ == Phase::approach; }
  [[nodiscard]] Phase phase() const { return phase_; }
  void abandon() { phase_ = Phase::idle; }

 private:
  const RobotModel& model_;
  std::size_t axes_;
  Phase phase_ = Phase::idle;
  std::array<bool, kMaxAxes> switch_found_{};
  std::array<bool, kMaxAxes> switch_initial_{};
  std::array<double, kMaxAxes> search_direction_{};
  AxisArray search_start_{};
  AxisArray speed_{};  ///< search speed per axis [rad/s], >= 0
  int approach_steps_ = 0;
  int approach_step_no_ = 0;
  AxisArray approach_start_{};
};

}  // namespace mrroc::edp
