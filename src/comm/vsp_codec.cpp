/// @file
/// Codecs of the virtual-sensor link and of raw sensor samples (see comm/codec.hpp).
#include <fmt/format.h>

#include <cmath>

#include "mrroc/comm/codec.hpp"

namespace mrroc::comm {
namespace {

void check_size(int n, const char* type, const char* what, std::size_t names, std::size_t units,
                std::size_t values) {
  if (n < 0 || n > kMaxSensorValues)
    throw DecodeError(fmt::format("{}: n = {} is outside 0..{}", type, n, kMaxSensorValues));
  const auto count = static_cast<std::size_t>(n);
  if (values != count || names != count || units != count)
    throw DecodeError(fmt::format("{}: {} has {} values, {} names, {} units (n = {})", type, what,
                                  values, names, units, n));
}

void check_finite(const std::vector<double>& values, const std::vector<std::string>& names,
                  const char* type) {
  for (std::size_t i = 0; i < values.size(); ++i)
    if (!std::isfinite(values[i]))
      throw DecodeError(fmt::format("{}: value {} ({}) is not a finite number", type, i, names[i]));
}

/// The n values with their names and units (names and units padded or cut to the values).
template <class Msg>
void put_values(Msg& m, const std::vector<double>& values, const std::vector<std::string>& names,
                const std::vector<std::string>& units) {
  m.n = static_cast<int32_t>(values.size());
  m.values = values;
  m.names = names;
  m.units = units;
  m.names.resize(values.size());
  m.units.resize(values.size());
}

}  // namespace

mrroc_lcm::vsp_command_t encode(const vsp::Request& in) {
  mrroc_lcm::vsp_command_t m{};
  m.command = static_cast<int8_t>(in.command);
  m.arguments = in.arguments;
  return m;
}

vsp::Request decode(const mrroc_lcm::vsp_command_t& m) {
  if (m.command < 1 || m.command > 4)
    throw DecodeError(fmt::format("vsp_command_t: command {} is outside 1..4", m.command));
  return {static_cast<vsp::Command>(m.command), m.arguments};
}

mrroc_lcm::vsp_reply_t encode(const vsp::Reply& in) {
  mrroc_lcm::vsp_reply_t m{};
  m.reply = static_cast<int8_t>(in.kind);
  m.error_code = in.error_code;
  m.error_text = in.error_text;
  const vsp::Reading& r = in.reading;
  m.valid = r.valid ? 1 : 0;
  m.invalid_reason = r.invalid_reason;
  m.reading_utime = r.reading_utime;
  m.age_us = r.age_us;
  m.reading_no = r.reading_no;
  put_values(m, r.values, r.names, r.units);
  return m;
}

vsp::Reply decode(const mrroc_lcm::vsp_reply_t& m) {
  if (m.reply < 0 || m.reply > 2)
    throw DecodeError(fmt::format("vsp_reply_t: reply {} is outside 0..2", m.reply));
  check_size(m.n, "vsp_reply_t", "the reading", m.names.size(), m.units.size(), m.values.size());
  vsp::Reply r;
  r.kind = static_cast<vsp::ReplyKind>(m.reply);
  r.error_code = m.error_code;
  r.error_text = m.error_text;
  r.reading.valid = m.valid != 0;
  r.reading.invalid_reason = m.invalid_reason;
  r.reading.reading_utime = m.reading_utime;
  r.reading.age_us = m.age_us;
  r.reading.reading_no = m.reading_no;
  r.reading.values = m.values;
  r.reading.names = m.names;
  r.reading.units = m.units;
  if (r.reading.valid) check_finite(r.reading.values, r.reading.names, "vsp_reply_t");
  return r;
}

mrroc_lcm::raw_sensor_t encode(const vsp::RawSample& in) {
  mrroc_lcm::raw_sensor_t m{};
  m.device = in.device;
  m.sample_utime = in.sample_utime;
  m.sample_no = in.sample_no;
  m.valid = in.valid ? 1 : 0;
  put_values(m, in.values, in.names, in.units);
  return m;
}

vsp::RawSample decode(const mrroc_lcm::raw_sensor_t& m) {
  check_size(m.n, "raw_sensor_t", "the sample", m.names.size(), m.units.size(), m.values.size());
  if (m.device.empty()) throw DecodeError("raw_sensor_t: empty device name");
  vsp::RawSample s;
  s.device = m.device;
  s.sample_utime = m.sample_utime;
  s.sample_no = m.sample_no;
  s.valid = m.valid != 0;
  s.values = m.values;
  s.names = m.names;
  s.units = m.units;
  if (s.valid) check_finite(s.values, s.names, "raw_sensor_t");
  return s;
}

}  // namespace mrroc::comm
