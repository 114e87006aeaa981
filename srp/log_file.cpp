#include "log_file.hpp"

#include <ctime>
#include <system_error>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "mrroc/core/error.hpp"

namespace mrroc::srp {

std::string iso8601_utc(std::int64_t utime) {
  std::int64_t seconds = utime / 1000000;
  std::int64_t micros = utime % 1000000;
  if (micros < 0) {
    micros += 1000000;
    --seconds;
  }
  const auto t = static_cast<std::time_t>(seconds);
  std::tm utc{};
  gmtime_r(&t, &utc);
  return fmt::format("{:04}-{:02}-{:02}T{:02}:{:02}:{:02}.{:06}Z", utc.tm_year + 1900,
                     utc.tm_mon + 1, utc.tm_mday, utc.tm_hour, utc.tm_min, utc.tm_sec, micros);
}

std::string json_line(const Entry& entry) {
  const SrpMessage& m = entry.message;
  nlohmann::ordered_json j;
  j["n"] = entry.number;
  j["kind"] = entry.status ? "status" : "message";
  j["time"] = iso8601_utc(m.utime);
  j["utime"] = m.utime;
  j["process"] = m.process;
  j["robot"] = m.robot;
  j["severity"] = to_string(m.severity);
  j["code"] = m.code;
  j["text"] = m.text;
  return j.dump(-1, ' ', false, nlohmann::json::error_handler_t::replace);
}

RotatingLog::RotatingLog(std::filesystem::path path, std::uintmax_t max_bytes, int keep)
    : path_(std::move(path)), max_bytes_(max_bytes), keep_(keep) {
  open();
}

void RotatingLog::open() {
  if (path_.has_parent_path()) {
    std::error_code ec;
    std::filesystem::create_directories(path_.parent_path(), ec);
  }
  out_.open(path_, std::ios::app | std::ios::binary);
  if (!out_) throw Error(fmt::format("cannot open SRP log file '{}'", path_.string()));
  std::error_code ec;
  size_ = std::filesystem::exists(path_, ec) ? std::filesystem::file_size(path_, ec) : 0;
  if (ec) size_ = 0;
}

void RotatingLog::rotate() {
  out_.close();
  const auto numbered = [&](int i) {
    return std::filesystem::path(path_.string() + "." + std::to_string(i));
  };
  std::error_code ec;
  if (keep_ <= 0) {
    std::filesystem::remove(path_, ec);
  } else {
    std::filesystem::remove(numbered(keep_), ec);
    for (int i = keep_ - 1; i >= 1; --i) {
      if (std::filesystem::exists(numbered(i), ec))
        std::filesystem::rename(numbered(i), numbered(i + 1), ec);
    }
    std::filesystem::rename(path_, numbered(1), ec);
  }
  ++rotations_;
  open();
}

void RotatingLog::write(const std::string& line) {
  const std::uintmax_t bytes = line.size() + 1;
  if (size_ > 0 && size_ + bytes > max_bytes_) rotate();
  out_ << line << '\n';
  out_.flush();
  size_ += bytes;
  if (!out_) {  // disk full, file system gone: say so, and try again with the next line
    out_.clear();
    throw Error(fmt::format("cannot write SRP log file '{}'", path_.string()));
  }
}

}  // namespace mrroc::srp
