#include <fmt/format.h>

#include <cmath>

#include "mrroc/core/error.hpp"
#include "mrroc/ecp/conditions.hpp"
#include "mrroc/ecp/generators/errors.hpp"
#include "mrroc/ecp/robot_image.hpp"

namespace mrroc::ecp {

InputCondition::InputCondition(int line, bool state, double timeout_s, SteadyClock clock)
    : line_(line), state_(state), timeout_s_(timeout_s), clock_(std::move(clock)) {
  if (line < 0 || line > 31)
    throw Error(fmt::format("input condition: line {} is outside 0..31", line));
  if (!(std::isfinite(timeout_s) && timeout_s >= 0.0))
    throw Error(fmt::format("input condition: timeout {} s is not a number >= 0", timeout_s));
  if (!clock_) clock_ = [] { return std::chrono::steady_clock::now(); };
}

bool InputCondition::holds(const RobotImage& robot, const SensorList&) {
  last_ = clock_();
  if (!start_) start_ = last_;
  if (!robot.inputs)
    throw GeneratorError(fmt::format(
        "input condition on line {}: the robot image has no inputs (read them with item INPUTS: "
        "Wait does; a guarded move's generator must ask for them)",
        line_));
  if ((((*robot.inputs >> static_cast<unsigned>(line_)) & 1U) != 0U) == state_) return true;
  if (timeout_s_ > 0.0 && waited_s() >= timeout_s_)
    throw GeneratorError(fmt::format("input {} did not turn {} within {:.1f} s", line_,
                                     state_ ? "on" : "off", timeout_s_));
  return false;
}

double InputCondition::waited_s() const {
  if (!start_) return 0.0;
  return std::chrono::duration<double>(last_ - *start_).count();
}

}  // namespace mrroc::ecp
