#include "console/teach_in.hpp"

#include <fmt/format.h>

#include <regex>
#include <system_error>

#include "mrroc/ecp/generators/trajectory_file.hpp"

namespace mrroc::ui {

void check_trajectory_file_name(const std::string& file) {
  static const std::regex good_name("[A-Za-z0-9_][A-Za-z0-9_.-]{0,99}");
  if (!std::regex_match(file, good_name))
    throw ApiError(400, fmt::format("trajectory file name '{}' is not a plain file name "
                                    "(letters, digits, '_', '.', '-'; at most 100)",
                                    file));
}

TeachIn::TeachIn(const ConsoleState& state, const std::filesystem::path& dir, ReportFn report)
    : state_(state),
      dir_(dir.empty() ? std::filesystem::current_path() : dir),
      report_(std::move(report)) {}

TeachResult TeachIn::record(const std::string& robot, const std::string& file) {
  check_trajectory_file_name(file);
  const std::size_t index = state_.robot_index(robot);
  const RobotModel& model = state_.robots()[index].model;
  const std::optional<RobotReading> reading = state_.reading(index);
  if (!reading || !reading->fresh())
    throw ApiError(
        409, fmt::format("no robot_state_t from EDP {} in the last {} s", robot, kStateFreshS));
  if (!reading->state.synchronised)
    throw ApiError(409, fmt::format("{} is not synchronised: its joint positions are not "
                                    "known yet",
                                    robot));
  const std::vector<double>& q = reading->state.q;
  std::error_code ec;
  std::filesystem::create_directories(dir_, ec);
  const std::filesystem::path path = dir_ / file;
  ecp::TrajectoryFile trajectory;
  if (std::filesystem::exists(path)) {
    trajectory = ecp::TrajectoryFile::load(path);
    if (trajectory.representation != edp::ArmRepresentation::joint ||
        trajectory.axes != model.axes() ||
        (!trajectory.robot.empty() && trajectory.robot != model.name))
      throw ApiError(409, fmt::format("'{}' holds a {} trajectory of {} axes for robot '{}', "
                                      "not JOINT poses of {} ({} axes)",
                                      path.string(), edp::to_string(trajectory.representation),
                                      trajectory.axes, trajectory.robot, model.name, model.axes()));
  } else {
    trajectory.representation = edp::ArmRepresentation::joint;
    trajectory.axes = model.axes();
    trajectory.robot = model.name;
  }
  ecp::TrajectoryPoint point;
  point.values = q;
  trajectory.points.push_back(point);
  trajectory.save(path);
  const std::string text =
      fmt::format("pose {} of {} recorded in {}", trajectory.points.size(), robot, path.string());
  report_(Severity::info, "teach-in: " + text);
  return TeachResult{path, trajectory.points.size(), q, text};
}

}  // namespace mrroc::ui
