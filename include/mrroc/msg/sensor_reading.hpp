#pragma once
/// @file
/// Plain values of the virtual-sensor link and of raw sensor samples (the LCM types stay in
/// comm/codec.hpp). A VSP aggregates raw samples of one or more receptors (raw sensors) into a
/// reading, which Move and Wait hand to generators and conditions through the sensor image.
#include <cstdint>
#include <string>
#include <vector>

namespace mrroc::vsp {

/// One sample of a raw sensor device (channel mrroc/raw/<device>).
struct RawSample {
  std::string device;
  std::int64_t sample_utime = 0;  ///< when the sample was taken [us since the epoch]
  std::int64_t sample_no = 0;
  bool valid = true;
  std::vector<double> values;
  std::vector<std::string> names;
  std::vector<std::string> units;
};

/// A virtual sensor's reading.
struct Reading {
  bool valid = false;
  std::string invalid_reason;  ///< when not valid, e.g. "source left_wrist_gauges stale for 120 ms"
  std::int64_t reading_utime = 0;  ///< oldest raw sample the reading is built from [us]
  std::int64_t age_us = 0;         ///< age when the VSP replied [us]
  std::int64_t reading_no = 0;     ///< readings made since CONFIGURE
  std::vector<double> values;
  std::vector<std::string> names;
  std::vector<std::string> units;

  /// Value by name. @throws mrroc::Error naming the value and the ones there are.
  [[nodiscard]] double value(const std::string& name) const;
};

enum class Command : std::int8_t {
  configure = 1,
  initiate_reading = 2,
  get_reading = 3,
  terminate = 4
};
const char* to_string(Command c);

struct Request {
  Command command = Command::get_reading;
  std::string arguments;  ///< TOML `key = value` lines
};

enum class ReplyKind : std::int8_t { acknowledge = 0, reading = 1, error = 2 };

struct Reply {
  ReplyKind kind = ReplyKind::acknowledge;
  int error_code = 0;
  std::string error_text;
  Reading reading;  ///< for ReplyKind::reading
};

/// VSP error codes (Reply::error_code).
namespace error_code {
inline constexpr int bad_argument = 1;    ///< CONFIGURE/INITIATE arguments not understood
inline constexpr int not_configured = 2;  ///< GET_READING before any reading was made
inline constexpr int terminated = 3;      ///< after TERMINATE
inline constexpr int sensor_fault = 4;    ///< the plugin failed
}  // namespace error_code

}  // namespace mrroc::vsp
