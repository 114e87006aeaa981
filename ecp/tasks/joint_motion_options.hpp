#pragma once
// The motion options of the stock ECP tasks that visit joint poses, read from their arguments:
// velocity_scale, acceleration_scale and motion_steps (defaults: JointPosesOptions'), with the
// EDP's servo period.
#include "mrroc/config/params.hpp"
#include "mrroc/ecp/generators/joint_poses.hpp"

namespace mrroc::ecp {

inline JointPosesOptions joint_motion_options(const Params& args, double servo_period_s) {
  JointPosesOptions options;
  options.velocity_scale = args.get_double("velocity_scale", options.velocity_scale);
  options.acceleration_scale = args.get_double("acceleration_scale", options.acceleration_scale);
  options.motion_steps = static_cast<int>(args.get_int("motion_steps", options.motion_steps));
  options.servo_period_s = servo_period_s;
  return options;
}

}  // namespace mrroc::ecp
