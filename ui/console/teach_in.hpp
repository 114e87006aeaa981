#pragma once
// Teach-in: "Record pose" appends a robot's measured joint positions (its last robot_state_t)
// to a trajectory file in the teach folder, written by ecp::TrajectoryFile (docs/operating.md,
// "Teach-in").

#include <cstddef>
#include <filesystem>
#include <string>
#include <vector>

#include "console/common.hpp"
#include "console/state.hpp"

namespace mrroc::ui {

struct TeachResult {
  std::filesystem::path file;
  std::size_t points = 0;    ///< poses in the file now
  std::vector<double> pose;  ///< the pose recorded [rad]
  std::string text;          ///< "pose 2 of irb6 recorded in /.../irb6.traj"
};

/// @throws ApiError 400 unless `file` is a plain file name (letters, digits, '_', '.', '-'; not
/// starting with '.' or '-'; at most 100 characters).
void check_trajectory_file_name(const std::string& file);

class TeachIn {
 public:
  /// @param dir  where the files go (created when missing); empty: the current folder.
  TeachIn(const ConsoleState& state, const std::filesystem::path& dir, ReportFn report);

  [[nodiscard]] const std::filesystem::path& dir() const { return dir_; }

  /// Appends the robot's pose to `file` in dir() (the API's default is "<robot>.traj"): under
  /// an exclusive lock on `.<file>.lock` beside it (concurrent requests, of this console or
  /// another, each add their pose), written to a temporary file of a unique name and renamed
  /// over the file. Called from any HTTP thread.
  /// @throws ApiError 400 (file name), 404 (unknown robot), 409 (no fresh state, not
  /// synchronised, or the file holds another robot's or another representation's poses), 500
  /// (the file cannot be locked or written).
  TeachResult record(const std::string& robot, const std::string& file);

 private:
  const ConsoleState& state_;
  std::filesystem::path dir_;
  ReportFn report_;
};

}  // namespace mrroc::ui
