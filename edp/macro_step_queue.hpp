#pragma once
/// @file
/// The EDP's queue of macro-steps waiting for the servo loop (lookahead): a ring of fixed
/// capacity allocated with the loop, so that handing a macro-step to the servo thread never
/// allocates. Not thread-safe by itself: the servo loop guards it with its mutex.

#include <array>
#include <cstddef>
#include <cstdint>

#include "mrroc/config/process_set.hpp"

namespace mrroc::edp {

inline constexpr std::size_t kMaxAxes = 16;
using AxisArray = std::array<double, kMaxAxes>;

/// One macro-step: from where the previous one ended (or where the robot stands) to `target`, in
/// `steps` servo steps, each joint on a cubic in time that joins the previous macro-step's
/// velocity without exceeding its acceleration limit (motion_blend.hpp).
struct MacroStep {
  std::uint64_t id = 0;
  AxisArray start{};
  AxisArray target{};
  AxisArray start_velocity{};  ///< set when it starts (motion_blend.hpp)
  AxisArray end_velocity{};    ///< chosen when it starts
  int steps = 1;
  int value_in_step_no = 1;
  int step = 0;  ///< servo steps done (whole ones: the floor of `progress`)
  /// Servo steps done, fractional while the servo loop catches up on its time line after a
  /// stall (docs/edp.md, "Catch-up"); equal to `step` otherwise.
  double progress = 0.0;
  /// Its reading comes before its last step: the ECP promised the next macro-step in time.
  [[nodiscard]] bool promises_successor() const { return value_in_step_no < steps; }
};

class MacroStepQueue {
 public:
  /// Room for the deepest lookahead, plus the macro-step a client sends while the oldest one it
  /// was answered for still runs.
  static constexpr std::size_t kCapacity = static_cast<std::size_t>(kMaxLookahead) + 2;

  [[nodiscard]] bool empty() const { return size_ == 0; }
  [[nodiscard]] bool full() const { return size_ == kCapacity; }
  [[nodiscard]] std::size_t size() const { return size_; }
  /// The oldest macro-step (precondition: !empty()).
  [[nodiscard]] const MacroStep& front() const { return slots_[head_]; }
  /// The newest macro-step (precondition: !empty()).
  [[nodiscard]] const MacroStep& back() const { return slots_[(head_ + size_ - 1) % kCapacity]; }
  /// The i-th oldest (precondition: i < size()).
  [[nodiscard]] const MacroStep& at(std::size_t i) const { return slots_[(head_ + i) % kCapacity]; }
  /// Appends (precondition: !full()).
  void push(const MacroStep& step) {
    slots_[(head_ + size_) % kCapacity] = step;
    ++size_;
  }
  /// Removes the oldest (precondition: !empty()).
  MacroStep pop() {
    const MacroStep out = slots_[head_];
    head_ = (head_ + 1) % kCapacity;
    --size_;
    return out;
  }
  void clear() {
    head_ = 0;
    size_ = 0;
  }

 private:
  std::array<MacroStep, kCapacity> slots_{};
  std::size_t head_ = 0;
  std::size_t size_ = 0;
};

}  // namespace mrroc::edp
