#pragma once
// A path of points cut into macro-steps, for the MP tasks that generate Cartesian paths
// (carry_bar, tool_path): straight segments, each rest to rest with the quintic time law
// s(t) = 10 t^3 - 15 t^4 + 6 t^5, whose peak speed is 1.875 times its mean.
#include <fmt/format.h>

#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <utility>
#include <vector>

#include "mrroc/config/params.hpp"
#include "mrroc/core/error.hpp"

namespace mrroc::mp {

/// The task argument 'path': at least two points [x, y, z] (m). @throws ConfigError at the row
/// or the key that is wrong.
inline std::vector<Eigen::Vector3d> read_path_points(const Params& args) {
  const auto rows = args.get_double_rows("path");
  for (std::size_t i = 0; i < rows.size(); ++i)
    if (rows[i].size() != 3)
      throw ConfigError(args.location_of_row("path", i),
                        fmt::format("every 'path' point is [x, y, z] (m); point {} has {} values",
                                    i + 1, rows[i].size()));
  std::vector<Eigen::Vector3d> points;
  for (const auto& p : rows) points.emplace_back(p[0], p[1], p[2]);
  if (points.size() < 2)
    throw ConfigError(args.location_of("path"),
                      fmt::format("'path' needs at least two points, it has {}", points.size()));
  return points;
}

class StraightPath {
 public:
  /// `peak_speeds`: one per segment [m/s, > 0]; `macro_step_s`: the macro-step's duration [s].
  StraightPath(std::vector<Eigen::Vector3d> points, std::vector<double> peak_speeds,
               double macro_step_s)
      : points_(std::move(points)), speeds_(std::move(peak_speeds)), macro_step_s_(macro_step_s) {}

  /// The point at the end of the next macro-step; false when the path is done.
  bool next(Eigen::Vector3d& point) {
    if (!started_) {
      started_ = true;
      if (!begin(0)) return false;
    } else if (macro_ >= macros_ && !begin(segment_ + 1)) {
      return false;
    }
    ++macro_;
    const double tau = static_cast<double>(macro_) / macros_;
    const double s = tau * tau * tau * (10.0 + tau * (-15.0 + 6.0 * tau));
    point = from_ + (to_ - from_) * s;
    return true;
  }

  /// The rest of this path from `here` (where it was left, at rest): a segment from `here` to
  /// the end of the current segment, at its speed but taking at least `min_first_s` (a short
  /// remainder at the full speed would start from rest too abruptly), then the segments not
  /// begun yet.
  [[nodiscard]] StraightPath rest_from(const Eigen::Vector3d& here, double min_first_s) const {
    const std::size_t next = started_ ? segment_ + 1 : 0;
    std::vector<Eigen::Vector3d> points{here};
    std::vector<double> speeds;
    for (std::size_t k = std::max<std::size_t>(next, 1); k < points_.size(); ++k) {
      points.push_back(points_[k]);
      speeds.push_back(speeds_[k - 1]);
    }
    if (speeds.empty()) {  // at the path's end: stay there
      points.push_back(points_.back());
      speeds.push_back(speeds_.back());
    }
    StraightPath rest(std::move(points), std::move(speeds), macro_step_s_);
    rest.min_first_s_ = min_first_s;
    return rest;
  }

  /// How far along its first segment the point next() gave last is, by the time law (0..1); 1
  /// from the second segment on.
  [[nodiscard]] double first_segment_share() const {
    if (!started_ || segment_ > 0) return started_ ? 1.0 : 0.0;
    const double tau = static_cast<double>(macro_) / macros_;
    return tau * tau * tau * (10.0 + tau * (-15.0 + 6.0 * tau));
  }

  /// How long the whole path takes [s], in whole macro-steps (a path not begun yet).
  [[nodiscard]] double duration_s() const {
    StraightPath copy(points_, speeds_, macro_step_s_);
    copy.min_first_s_ = min_first_s_;
    double total = 0.0;
    for (std::size_t k = 0; copy.begin(k); ++k) total += copy.macros_ * macro_step_s_;
    return total;
  }

  /// Whether the point next() gave last is the path's end.
  [[nodiscard]] bool at_end() const {
    return started_ && segment_ + 2 == points_.size() && macro_ == macros_;
  }

 private:
  bool begin(std::size_t segment) {
    if (segment + 1 >= points_.size()) return false;
    segment_ = segment;
    from_ = points_[segment];
    to_ = points_[segment + 1];
    double duration = 1.875 * (to_ - from_).norm() / speeds_[segment];
    if (segment == 0) duration = std::max(duration, min_first_s_);
    macros_ = std::max(1, static_cast<int>(std::ceil(duration / macro_step_s_)));
    macro_ = 0;
    return true;
  }

  std::vector<Eigen::Vector3d> points_;
  std::vector<double> speeds_;
  double macro_step_s_;
  double min_first_s_ = 0.0;  ///< the first segment takes at least this long [s]
  bool started_ = false;
  std::size_t segment_ = 0;
  int macro_ = 0;
  int macros_ = 1;
  Eigen::Vector3d from_ = Eigen::Vector3d::Zero();
  Eigen::Vector3d to_ = Eigen::Vector3d::Zero();
};

}  // namespace mrroc::mp
