#include "console/teach_in.hpp"

#include <fcntl.h>
#include <fmt/format.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
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

namespace {

/// `.NAME` + `suffix` beside `file` (appended piece by piece: GCC 12's -O3 warns,
/// -Wstringop-overflow, about the temporaries of `"." + std::string`, a false positive).
std::filesystem::path hidden_sibling(const std::filesystem::path& file, const char* suffix) {
  std::string name(1, '.');
  name += file.filename().string();
  name += suffix;
  return file.parent_path() / name;
}

/// An exclusive flock(2) on `<dir>/.<file>.lock`, held while the file is read, appended to and
/// replaced: two requests (threads of this console, or two consoles) never both read the old
/// file and so lose one of the two poses.
class FileLock {
 public:
  explicit FileLock(const std::filesystem::path& file) {
    const std::filesystem::path lock = hidden_sibling(file, ".lock");
    fd_ = ::open(lock.c_str(), O_RDWR | O_CREAT | O_CLOEXEC | O_NOFOLLOW, 0600);
    if (fd_ < 0)
      throw ApiError(500, fmt::format("cannot open the lock file '{}': {}", lock.string(),
                                      std::strerror(errno)));
    while (::flock(fd_, LOCK_EX) != 0) {
      if (errno == EINTR) continue;
      const int e = errno;
      ::close(fd_);
      throw ApiError(500, fmt::format("cannot lock '{}': {}", lock.string(), std::strerror(e)));
    }
  }
  ~FileLock() { ::close(fd_); }  // releases the lock
  FileLock(const FileLock&) = delete;
  FileLock& operator=(const FileLock&) = delete;

 private:
  int fd_ = -1;
};

/// Writes `text` to `path` whole: into a temporary file of a name of its own in the same folder
/// (mkostemp: no other writer's, no file or link planted there), flushed to the disk, then
/// renamed over `path`.
void replace_file(const std::filesystem::path& path, const std::string& text) {
  std::string temporary = hidden_sibling(path, ".XXXXXX").string();
  const int fd = ::mkostemp(temporary.data(), O_CLOEXEC);  // mode 0600
  if (fd < 0)
    throw ApiError(500, fmt::format("cannot write '{}': cannot create a temporary file beside "
                                    "it: {}",
                                    path.string(), std::strerror(errno)));
  std::size_t done = 0;
  int error = 0;
  while (done < text.size()) {
    const ssize_t n = ::write(fd, text.data() + done, text.size() - done);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) {
      error = n < 0 ? errno : EIO;
      break;
    }
    done += static_cast<std::size_t>(n);
  }
  if (error == 0 && ::fchmod(fd, 0644) != 0) error = errno;  // as a file written by ofstream
  if (error == 0 && ::fsync(fd) != 0) error = errno;
  if (::close(fd) != 0 && error == 0) error = errno;
  if (error == 0 && ::rename(temporary.c_str(), path.c_str()) != 0) error = errno;
  if (error != 0) {
    ::unlink(temporary.c_str());
    throw ApiError(500, fmt::format("cannot write '{}': {}", path.string(), std::strerror(error)));
  }
}

}  // namespace

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
  const FileLock lock(path);  // until the file is replaced
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
  replace_file(path, trajectory.to_text());
  const std::string text =
      fmt::format("pose {} of {} recorded in {}", trajectory.points.size(), robot, path.string());
  report_(Severity::info, "teach-in: " + text);
  return TeachResult{path, trajectory.points.size(), q, text};
}

}  // namespace mrroc::ui
