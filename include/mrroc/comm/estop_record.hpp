#pragma once
/// @file
/// One robot's emergency stop as followed from the operators' commands and the latch's
/// announcements (emergency_stop_t, docs/operating.md "Emergency stop"), kept the same way by the
/// latch holder (mrroc-launch) and by each EDP.
///
/// No time a sender writes orders anything here: a command is named by its sender and number
/// (EstopCommandRef), and a stop ends only on an operator's RELEASE or on a latch's RELEASED that
/// names every ENGAGE this record holds. A forged ENGAGE (from anybody) can stop a robot, which is
/// always safe, but cannot make a later announcement release one.

#include <cstddef>
#include <deque>
#include <optional>
#include <string>
#include <vector>

#include "mrroc/msg/emergency_stop.hpp"

namespace mrroc::comm {

class EstopRecord {
 public:
  /// The most ENGAGEs held at once; more and the record holds until an operator's RELEASE.
  static constexpr std::size_t kMaxHeld = kMaxEstopEngages;
  /// How many ENGAGEs released and RELEASEs obeyed are remembered (to know their late copies).
  static constexpr std::size_t kRemembered = 64;

  /// An ENGAGE named `ref` (a command's copies share it; id 0: a command without a number, whose
  /// copies count as one while held and which is never known as released). True when it is new:
  /// false for a copy of an ENGAGE held or released.
  bool engage(const EstopCommandRef& ref);
  /// An authentic RELEASE named `ref`: every ENGAGE held is ended and returned; nothing for a copy
  /// of a RELEASE already obeyed.
  std::optional<std::vector<EstopCommandRef>> release(const EstopCommandRef& ref);
  /// A latch's ENGAGED naming `engages` (from `announcer`): holds those not released yet (one
  /// naming none is held as the announcer's, which only an operator's RELEASE ends). True when
  /// something is held now that was not before.
  bool latched_engaged(const std::vector<EstopCommandRef>& engages, const std::string& announcer);
  /// A latch's authentic RELEASED naming the ENGAGEs its RELEASE ended: those are no longer held.
  /// True when this emptied the record (it held something before and holds nothing now).
  bool latched_released(const std::vector<EstopCommandRef>& ended);

  /// The ENGAGEs held, oldest first.
  [[nodiscard]] const std::deque<EstopCommandRef>& held() const { return held_; }
  /// True while any ENGAGE is held (or more were than are kept).
  [[nodiscard]] bool holding() const { return !held_.empty() || overflowed_; }
  /// True when more ENGAGEs came than are kept: only an operator's RELEASE ends the stop.
  [[nodiscard]] bool overflowed() const { return overflowed_; }

 private:
  [[nodiscard]] bool is_held(const EstopCommandRef& ref) const;
  [[nodiscard]] bool was_released(const EstopCommandRef& ref) const;
  void hold(const EstopCommandRef& ref);

  std::deque<EstopCommandRef> held_;
  bool overflowed_ = false;
  std::deque<EstopCommandRef> released_;  ///< ENGAGEs ended, newest last
  std::deque<EstopCommandRef> releases_;  ///< RELEASEs obeyed, newest last
};

}  // namespace mrroc::comm
