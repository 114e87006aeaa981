#pragma once
/// @file
/// The shortest time in which the EDP moves a joint by `distance` from rest to rest as one
/// macro-step: it accelerates uniformly over the first half and decelerates over the second
/// (docs/edp.md, "Acceleration"), so the velocity peaks at 2 d / T and the acceleration is
/// 4 d / T^2: T >= max(2 |d| / v, 2 sqrt(|d| / a)).

#include <algorithm>
#include <cmath>

namespace mrroc {

inline double rest_to_rest_duration(double distance, double max_velocity, double max_acceleration) {
  const double d = std::abs(distance);
  return std::max(2.0 * d / max_velocity, 2.0 * std::sqrt(d / max_acceleration));
}

}  // namespace mrroc
