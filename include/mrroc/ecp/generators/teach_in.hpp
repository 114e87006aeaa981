#pragma once
/// @file
/// Teach-in: record poses of a robot into a `TrajectoryFile`, and play a trajectory back with
/// the stock interpolation (JOINT, MOTOR) or straight Cartesian lines (FRAME, XYZ_EULER_ZYZ,
/// XYZ_ANGLE_AXIS).

#include <cstdint>
#include <filesystem>
#include <memory>
#include <optional>

#include <Eigen/Geometry>

#include "mrroc/ecp/generators/cartesian_path.hpp"
#include "mrroc/ecp/generators/interpolation.hpp"
#include "mrroc/ecp/generators/planned_motion.hpp"
#include "mrroc/ecp/generators/trajectory_file.hpp"
#include "mrroc/ecp/robot_image.hpp"

namespace mrroc::ecp {

/// Appends the robot image's current pose to a trajectory.
class TeachInRecorder {
 public:
  /// Which joints of the image to record.
  enum class Source : std::int8_t {
    measured,  ///< RobotImage::joints (where the arm is; e.g. after jogging or guiding by hand)
    desired    ///< RobotImage::desired_joints (where it was commanded to be)
  };

  /// @param tool  tool frame in the flange frame for Cartesian representations.
  /// @throws Error for an unknown representation; CommandError (not_supported) for a Cartesian
  ///   one on a robot without Cartesian kinematics. The model must outlive the recorder.
  explicit TeachInRecorder(const RobotModel& model,
                           edp::ArmRepresentation representation = edp::ArmRepresentation::joint,
                           Source source = Source::measured,
                           const Eigen::Isometry3d& tool = Eigen::Isometry3d::Identity());

  /// Appends the image's pose (converted to the representation) with an optional duration [s]
  /// (> 0) or velocity scale ((0, 1]) of the move to it, and returns it.
  /// @throws Error when the image has no joints of the robot's size, or for a bad duration/scale.
  const TrajectoryPoint& record(const RobotImage& image, std::optional<double> duration_s = {},
                                std::optional<double> velocity_scale = {});
  /// Drops the last recorded pose (none: no effect).
  void remove_last();
  void clear();

  [[nodiscard]] const TrajectoryFile& trajectory() const { return trajectory_; }
  /// @throws Error as TrajectoryFile::save.
  void save(const std::filesystem::path& path) const { trajectory_.save(path); }

 private:
  const RobotModel& model_;
  std::unique_ptr<edp::ArmKinematics> kinematics_;
  Source source_;
  TrajectoryFile trajectory_;
};

/// Options of the playback. The representation of the generators is the file's.
struct TeachInPlaybackOptions {
  InterpolationOptions interpolation;  ///< for JOINT and MOTOR files
  CartesianOptions cartesian;          ///< for Cartesian files (straight lines between poses)
};

/// Replays a trajectory from the robot's current pose: one segment per point (at rest at every
/// point), with the point's duration or velocity scale. Every check of the underlying generator
/// is made before the first command.
class TeachInPlaybackGenerator : public PlannedMotionGenerator {
 public:
  /// @throws CommandError (bad_argument) when the trajectory was recorded for another robot
  ///   (`robot` differs from the model's name, or `axes` from its number of axes) or a point is
  ///   malformed; others as InterpolationGenerator / CartesianPathGenerator.
  TeachInPlaybackGenerator(const RobotModel& model, const TrajectoryFile& trajectory,
                           TeachInPlaybackOptions options = {});

 protected:
  [[nodiscard]] MotionPlan make_plan(const std::vector<double>& start_joints) const override;

 private:
  std::unique_ptr<PlannedMotionGenerator> playback_;
};

}  // namespace mrroc::ecp
