#pragma once
/// @file
/// One servo step of the EDP's stopping ramp (a late successor, an emergency stop, shutdown).
///
/// All joint velocities are multiplied by one factor per step,
/// k = max(0, max_i(1 - a_max,i T / |v_i|)): the axis that needs longest to stop brakes at its
/// own maximum acceleration and the others in proportion, so the robot stops on the straight
/// continuation, in joint space, of its last motion (a tool in a groove stays in it). The ramp
/// goes on past the last target, where no limit was checked: a step that would leave a joint,
/// linkage or motor limit is not taken, and the ramp ends where it is.

#include <cstddef>
#include <span>

#include "mrroc/edp/arm_kinematics.hpp"
#include "mrroc/robot/robot_model.hpp"

namespace mrroc::edp {

struct RampStep {
  bool moving = false;    ///< the step moves the robot (false: the ramp is over)
  bool at_limit = false;  ///< the step would have left a limit and was not taken
};

/// Computes the next step from `velocity` [rad/s] and writes the new position into `desired`
/// (unchanged when the ramp is over or at a limit). `scratch` holds as many values as `desired`.
/// Allocation-free.
RampStep stopping_ramp_step(std::span<const double> velocity, std::span<double> desired,
                            std::span<double> scratch, const RobotModel& model, double period_s,
                            const ArmKinematics* guard);

/// Moves `desired` on at `velocity` [rad/s] for `duration_s` if the new position is inside the
/// joint limits and the guard's (when not null); otherwise leaves it and returns false. The
/// stopping ramp's steps are taken with it, and so is the part of a cycle's advance past the end
/// of a motion that the ramp follows (servo_loop.cpp). `scratch` holds as many values as
/// `desired`. Allocation-free.
bool move_within_limits(std::span<const double> velocity, double duration_s,
                        std::span<double> desired, std::span<double> scratch,
                        const RobotModel& model, const ArmKinematics* guard);

}  // namespace mrroc::edp
