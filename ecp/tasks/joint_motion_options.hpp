#pragma once
// The motion options of the stock ECP tasks that visit joint poses, read from their arguments:
// velocity_scale, acceleration_scale and motion_steps (defaults: JointPosesOptions'), with the
// EDP's servo period.
#include <algorithm>
#include <cstdint>
#include <limits>

#include "mrroc/config/check.hpp"
#include "mrroc/config/params.hpp"
#include "mrroc/ecp/generators/joint_poses.hpp"

namespace mrroc::ecp {

/// The options; each one of another type or out of range is added to `errors` at its own
/// argument (and its default used), so that the task's other arguments are checked too.
inline JointPosesOptions joint_motion_options(const Params& args, double servo_period_s,
                                              ConfigErrorList& errors) {
  JointPosesOptions options;
  const JointPosesOptions defaults;
  errors.run(args.location_of("velocity_scale"), [&] {
    options.velocity_scale = args.get_double("velocity_scale", defaults.velocity_scale);
  });
  errors.run(args.location_of("acceleration_scale"), [&] {
    options.acceleration_scale = args.get_double("acceleration_scale", defaults.acceleration_scale);
  });
  errors.run(args.location_of("motion_steps"), [&] {
    // Clamped to int, so that a huge value stays out of range instead of wrapping into it.
    options.motion_steps = static_cast<int>(
        std::clamp<std::int64_t>(args.get_int("motion_steps", defaults.motion_steps),
                                 std::numeric_limits<int>::min(), std::numeric_limits<int>::max()));
  });
  options.servo_period_s = servo_period_s;
  for (const auto& [key, why] : options.out_of_range())
    errors.add(ConfigError(args.location_of(key), why));
  return options;
}

}  // namespace mrroc::ecp
