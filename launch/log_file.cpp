#include "log_file.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <ctime>
#include <string>
#include <system_error>
#include <utility>

#include <fmt/format.h>

#include "mrroc/core/error.hpp"

namespace mrroc::launch {

namespace fs = std::filesystem;

LogFile::LogFile(fs::path path, std::uintmax_t max_bytes, int keep, std::chrono::milliseconds retry)
    : path_(std::move(path)),
      max_bytes_(max_bytes < 1 ? 1 : max_bytes),
      keep_(keep < 0 ? 0 : keep),
      retry_(retry) {
  std::error_code ec;
  // A folder made here is its owner's alone (0700): the logs may hold what the processes print,
  // a generated console token among it. A folder that exists keeps its permissions.
  if (path_.has_parent_path() && !fs::exists(path_.parent_path(), ec)) {
    fs::create_directories(path_.parent_path(), ec);
    if (!ec) fs::permissions(path_.parent_path(), fs::perms::owner_all, ec);
  }
  if (ec)
    throw Error(fmt::format("cannot create the log folder '{}': {}", path_.parent_path().string(),
                            ec.message()));
  open();
}

LogFile::~LogFile() {
  if (fd_ >= 0) ::close(fd_);
}

fs::path LogFile::rotated(const fs::path& path, int n) {
  return fs::path(path.string() + "." + std::to_string(n));
}

void LogFile::open() {
  fd_ = ::open(path_.c_str(), O_WRONLY | O_CREAT | O_APPEND | O_CLOEXEC, 0600);
  if (fd_ < 0)
    throw Error(
        fmt::format("cannot open the log file '{}': {}", path_.string(), std::strerror(errno)));
  // A file made earlier with wider permissions is narrowed to its owner too.
  (void)::fchmod(fd_, 0600);
  struct stat st {};
  size_ = ::fstat(fd_, &st) == 0 ? static_cast<std::uintmax_t>(st.st_size) : 0;
}

void LogFile::rotate() {
  ::close(fd_);
  fd_ = -1;
  std::error_code ec;
  if (keep_ == 0) {
    fs::remove(path_, ec);
  } else {
    fs::remove(rotated(path_, keep_), ec);
    for (int n = keep_ - 1; n >= 1; --n) {
      if (fs::exists(rotated(path_, n), ec))
        fs::rename(rotated(path_, n), rotated(path_, n + 1), ec);
    }
    fs::rename(path_, rotated(path_, 1), ec);
  }
  if (ec) ++errors_;
  ++rotations_;
  lost_since_failure_ = 0;
  (void)reopen();
}

bool LogFile::reopen() {
  next_try_ = std::chrono::steady_clock::now() + retry_;
  try {
    // A folder removed while the set ran is made again, its owner's alone as at the start.
    std::error_code ec;
    if (path_.has_parent_path() && !fs::exists(path_.parent_path(), ec) &&
        fs::create_directories(path_.parent_path(), ec))
      fs::permissions(path_.parent_path(), fs::perms::owner_all, ec);
    open();
  } catch (const Error& e) {
    ++errors_;
    if (lost_since_failure_ == 0 && !notice_)
      notice_ = fmt::format("{}; its lines are lost until it opens (tried again every {:.1f} s)",
                            e.what(), std::chrono::duration<double>(retry_).count());
    return false;
  }
  if (lost_since_failure_ > 0)
    notice_ = fmt::format("the log file '{}' is open again ({} line{} lost)", path_.string(),
                          lost_since_failure_, lost_since_failure_ == 1 ? "" : "s");
  lost_since_failure_ = 0;
  return true;
}

std::optional<std::string> LogFile::take_notice() { return std::exchange(notice_, std::nullopt); }

void LogFile::write_line(std::string_view line) {
  if (fd_ >= 0 && size_ >= max_bytes_) rotate();
  if (fd_ < 0 && (std::chrono::steady_clock::now() < next_try_ || !reopen())) {
    ++errors_;
    ++lost_lines_;
    ++lost_since_failure_;
    return;
  }
  timespec now{};
  ::clock_gettime(CLOCK_REALTIME, &now);
  std::tm utc{};
  ::gmtime_r(&now.tv_sec, &utc);
  char stamp[32];
  std::strftime(stamp, sizeof stamp, "%Y-%m-%dT%H:%M:%S", &utc);
  const std::string text = fmt::format("{}.{:03}Z {}\n", stamp, now.tv_nsec / 1000000, line);
  std::size_t done = 0;
  while (done < text.size()) {
    const ssize_t n = ::write(fd_, text.data() + done, text.size() - done);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) {
      ++errors_;
      break;
    }
    done += static_cast<std::size_t>(n);
  }
  size_ += done;
}

}  // namespace mrroc::launch
