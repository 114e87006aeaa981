#pragma once
// The SRP's persistent log: one JSON object per line, rotated by size.

#include <cstdint>
#include <filesystem>
#include <fstream>
#include <string>

#include "history.hpp"

namespace mrroc::srp {

/// One JSON line for an entry: {"n", "kind" ("message"|"status"), "time" (ISO 8601, UTC, us),
/// "utime" [us since the epoch], "process", "robot", "severity" (name), "code", "text"}.
/// Invalid UTF-8 in a text is replaced (U+FFFD), never an error.
std::string json_line(const Entry& entry);

/// "2026-11-22T06:35:19.123456Z" for a utime [us since the Unix epoch].
std::string iso8601_utc(std::int64_t utime);

/// Appends lines to `path`. Before a line would make the file larger than `max_bytes`, the file
/// is rotated: path.(keep-1) -> path.keep, ..., path -> path.1, and a new file is started; the line
/// goes whole into the new file (a single line larger than the limit gets a file of its own).
/// `keep = 0` keeps no old file. Lines are flushed one by one.
class RotatingLog {
 public:
  /// @throws mrroc::Error naming the path when the file cannot be opened.
  RotatingLog(std::filesystem::path path, std::uintmax_t max_bytes, int keep);
  /// @throws mrroc::Error naming the path when the line cannot be written or a rotation cannot
  /// open the new file.
  void write(const std::string& line);
  [[nodiscard]] const std::filesystem::path& path() const { return path_; }
  [[nodiscard]] int rotations() const { return rotations_; }

 private:
  void open();
  void rotate();
  std::filesystem::path path_;
  std::uintmax_t max_bytes_;
  int keep_;
  std::ofstream out_;
  std::uintmax_t size_ = 0;
  int rotations_ = 0;
};

}  // namespace mrroc::srp
