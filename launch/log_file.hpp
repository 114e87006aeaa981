#pragma once
/// @file
/// A per-process log file of `mrroc-launch`: the child's output lines, each with a UTC time
/// stamp ("2026-11-22T06:35:15.123Z text"), appended to `name.log` and rotated when the file
/// grows beyond its limit (`name.log` -> `name.log.1` -> ... -> `name.log.N`, the oldest dropped).

#include <cstdint>
#include <filesystem>
#include <string_view>

namespace mrroc::launch {

class LogFile {
 public:
  /// Opens (creates, appends to) `path`; creates its folder if needed. `max_bytes` >= 1;
  /// `keep` is the number of rotated files kept (0: the file is emptied instead of rotated).
  /// @throws mrroc::Error naming the path and the reason when the file cannot be opened.
  LogFile(std::filesystem::path path, std::uintmax_t max_bytes, int keep);
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

  /// "path.N" (the N-th rotated file).
  [[nodiscard]] static std::filesystem::path rotated(const std::filesystem::path& path, int n);

 private:
  void open();
  void rotate();

  std::filesystem::path path_;
  std::uintmax_t max_bytes_;
  int keep_;
  int fd_ = -1;
  std::uintmax_t size_ = 0;
  int rotations_ = 0;
  int errors_ = 0;
};

}  // namespace mrroc::launch
