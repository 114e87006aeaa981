#pragma once
/// @file
/// A per-process log file of `mrroc-launch`: the child's output lines, each with a UTC time
/// stamp ("2026-11-22T06:35:15.123Z text"), appended to `name.log` and rotated when the file
/// grows beyond its limit (`name.log` -> `name.log.1` -> ... -> `name.log.N`, the oldest dropped).

#include <chrono>
#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <string_view>

namespace mrroc::launch {

class LogFile {
 public:
  /// Opens (creates, appends to) `path`; creates its folder if needed. `max_bytes` >= 1;
  /// `keep` is the number of rotated files kept (0: the file is emptied instead of rotated).
  /// A file that cannot be opened again after a rotation (its folder removed, a full or
  /// read-only file system) is tried again at the first line after each `retry` interval; the
  /// lines in between are lost and counted (`errors()`, `lost_lines()`), and `take_notice()`
  /// says so once when it fails and once when it is open again.
  /// @throws mrroc::Error naming the path and the reason when the file cannot be opened.
  LogFile(std::filesystem::path path, std::uintmax_t max_bytes, int keep,
          std::chrono::milliseconds retry = std::chrono::seconds(1));
  ~LogFile();
  LogFile(const LogFile&) = delete;
  LogFile& operator=(const LogFile&) = delete;
  LogFile(LogFile&&) = delete;
  LogFile& operator=(LogFile&&) = delete;

  /// Writes "<UTC time stamp> <line>\n". Rotates first when the file already holds
  /// `max_bytes` or more. Write errors are counted, not thrown (a full disk must not stop the
  /// set); see `errors()`.
  void write_line(std::string_view line);

  [[nodiscard]] const std::filesystem::path& path() const { return path_; }
  [[nodiscard]] std::uintmax_t size() const { return size_; }
  [[nodiscard]] int rotations() const { return rotations_; }
  [[nodiscard]] int errors() const { return errors_; }
  /// Lines not written because the file was not open.
  [[nodiscard]] std::uint64_t lost_lines() const { return lost_lines_; }
  /// What the owner should report since the last call: "cannot open the log file '...' again:
  /// ...; its lines are lost until it opens (tried again every 1.0 s)", or "the log file '...'
  /// is open again (N lines lost)". Nothing when nothing changed.
  [[nodiscard]] std::optional<std::string> take_notice();

  /// "path.N" (the N-th rotated file).
  [[nodiscard]] static std::filesystem::path rotated(const std::filesystem::path& path, int n);

 private:
  void open();
  void rotate();
  /// Opens the file again after a failure; true when it is open.
  bool reopen();

  std::filesystem::path path_;
  std::uintmax_t max_bytes_;
  int keep_;
  int fd_ = -1;
  std::uintmax_t size_ = 0;
  int rotations_ = 0;
  int errors_ = 0;
  std::chrono::milliseconds retry_;
  std::chrono::steady_clock::time_point next_try_{};
  std::uint64_t lost_lines_ = 0;
  std::uint64_t lost_since_failure_ = 0;
  std::optional<std::string> notice_;
};

}  // namespace mrroc::launch
