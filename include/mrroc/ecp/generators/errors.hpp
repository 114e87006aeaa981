#pragma once
/// @file
/// Errors of the stock generators and conditions that arise while a motion runs (as opposed to
/// `CommandError`, which they throw when they refuse a motion before its first command).

#include <string>

#include "mrroc/core/error.hpp"

namespace mrroc::ecp {

/// A stock generator or condition could not go on after the motion had started (a guarded move
/// ran out of distance, a sensor delivered a reading that is not a number, ...). The robot stops
/// at the last commanded pose; the shell handles the exception like any other task error.
class GeneratorError : public Error {
 public:
  using Error::Error;
};

/// A guarded move travelled its whole maximum distance without its terminal condition becoming
/// true (the error condition of the move). The robot stands at the end of the distance.
class GuardedMoveExhausted : public GeneratorError {
 public:
  GuardedMoveExhausted(const std::string& what, double distance)
      : GeneratorError(what), distance_(distance) {}
  /// The distance travelled [rad for JOINT/MOTOR moves (Euclidean norm), m for Cartesian ones].
  [[nodiscard]] double distance() const { return distance_; }

 private:
  double distance_;
};

}  // namespace mrroc::ecp
