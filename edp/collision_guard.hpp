#pragma once
/// @file
/// The EDP's collision guard: a kinematic copy of its robot's MJCF model with the fixed objects
/// of the cell, in which every SET ARM is checked, where it is accepted (command thread), before
/// anything is queued (docs/edp.md, "Collision guard").
///
/// Geometry: every geom of the robot's bodies (the top-level bodies of the MJCF that hold one of
/// its axes' joints; the model's world geoms, e.g. its floor, and free objects are left out) as
/// MuJoCo compiles it, at the robot's `base` pose in the cell, and the `[[collision.object]]`
/// boxes of `[collision]`. Distances are MuJoCo's own (`mj_kinematics` + `mj_collision` with
/// every geom's `margin` set to the clearance: every pair closer than the clearance is a contact
/// carrying its distance); no distance algorithm of our own.
///
/// Allowed pairs: links joined by a joint (MuJoCo's parent filter), pairs closer than the
/// clearance at the synchronisation pose (touching by design, e.g. the IRb-6's roll link in the
/// end of its upper arm; as MoveIt's setup assistant marks "default" pairs), and the configured
/// `allow` pairs naming this robot's links.
///
/// Joints of the robot's bodies that are not axes (a gripper's fingers) are held at their
/// reference position. Robots whose axes are coupled (closed loops: the RNT) are not guarded yet:
/// `CollisionGuard::make` returns null and says why.
///
/// Units: m, rad. Not thread-safe: one guard per command thread.

#include <atomic>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "mrroc/config/process_set.hpp"
#include "mrroc/robot/robot_model.hpp"

namespace mrroc::edp {

/// The closest pair of one check.
struct Proximity {
  std::string first;    ///< e.g. "link 'upper_arm_link'"
  std::string second;   ///< e.g. "'table'" or "link 'column_link'"
  double distance = 0;  ///< [m]; negative: penetration
};

class CollisionGuard {
 public:
  /// The guard of `robot` in the cell of `config`, or null (with `why_not` set) when the set
  /// turns it off or the robot's model cannot be guarded yet. `mjcf`: the model file the robot is
  /// simulated with (its `[robot.edp.params] mjcf`, else the robot's own).
  /// @throws ConfigError at the `allow` entry naming a link this robot's model does not have, at
  /// a `[[collision.object]]` closer than the clearance to a link at the robot's synchronisation
  /// pose (unless allowed), or when the model cannot be loaded.
  static std::unique_ptr<CollisionGuard> make(const RobotModel& model, const RobotConfig& robot,
                                              const CollisionConfig& config,
                                              const std::filesystem::path& mjcf,
                                              std::string& why_not);

  CollisionGuard(const RobotModel& model, const RobotConfig& robot, const CollisionConfig& config,
                 const std::filesystem::path& mjcf);
  ~CollisionGuard();
  CollisionGuard(const CollisionGuard&) = delete;
  CollisionGuard& operator=(const CollisionGuard&) = delete;

  /// The closest pair that is not allowed and closer than the clearance at joint position `q`
  /// (one value per axis), or nothing.
  [[nodiscard]] std::optional<Proximity> closest(std::span<const double> q);

  /// Checks the straight line from `start` to `target` in `steps` servo steps (the path the
  /// interpreter checks the limits on), at the servo steps chosen by `sample_stride`, and the
  /// target. A pair already closer than the clearance at `start` may stay so but not come
  /// closer (the robot can be moved out of it).
  /// @throws CommandError(error_code::collision) naming both bodies, the distance, the clearance
  /// and the servo step.
  void check_path(std::span<const double> start, std::span<const double> target, int steps);

  /// Servo steps between two checked steps of a macro-step: no point of any link moves more than
  /// half the clearance between them (`reach` bounds how far a point moves per rad of each
  /// joint), so a pose between two checked steps is within a quarter of the clearance of one of
  /// them and no contact can be missed.
  [[nodiscard]] int sample_stride(std::span<const double> start, std::span<const double> target,
                                  int steps) const;

  [[nodiscard]] double clearance() const { return clearance_; }
  /// What is guarded, for the EDP's ready line: links, objects, clearance, allowed pairs.
  [[nodiscard]] std::string describe() const;
  /// Per axis: the farthest any geometry moved by the joint reaches from its axis [m] (1 for a
  /// prismatic joint: m per m).
  [[nodiscard]] const std::vector<double>& reach() const { return reach_; }
  /// Checked poses since construction (for the cost per macro-step). Any thread.
  [[nodiscard]] long poses_checked() const {
    return poses_checked_.load(std::memory_order_relaxed);
  }

  /// What `check_path` cost since construction, for the EDP's timing report. Any thread (the
  /// figures are updated one by one, so a reading during a check may mix two checks).
  struct Statistics {
    long paths = 0;      ///< check_path calls, refused ones included
    long refused = 0;    ///< of them
    long poses = 0;      ///< poses checked, closest() included
    double mean_us = 0;  ///< wall-clock time per check_path
    double max_us = 0;
  };
  [[nodiscard]] Statistics statistics() const;
  /// "collision guard: N paths checked, M refusals, P poses, mean X us, max Y us per path" (no
  /// "refused": the tests and scripts that look for a refusal in a set's output search for it).
  [[nodiscard]] std::string statistics_text() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
  double clearance_ = 0;
  std::vector<double> reach_;
  std::atomic<long> poses_checked_{0};
  std::atomic<long> paths_{0};
  std::atomic<long> refused_{0};
  std::atomic<long long> path_ns_{0};
  std::atomic<long long> max_path_ns_{0};
};

}  // namespace mrroc::edp
