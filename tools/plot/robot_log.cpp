#include "robot_log.hpp"

#include <array>
#include <fstream>

#include <fmt/format.h>
#include <lcm/lcm-cpp.hpp>

#include "mrroc/comm/edge.hpp"
#include "mrroc/core/error.hpp"

namespace mrroc::plot {

namespace {

/// Every event of an LCM log starts with this word (big-endian).
constexpr std::array<unsigned char, 4> kLogSync{0xED, 0xA1, 0xDA, 0x01};

void check_is_log(const std::filesystem::path& file) {
  std::error_code ec;
  if (!std::filesystem::exists(file, ec))
    throw Error(fmt::format("log file '{}' does not exist", file.string()));
  if (std::filesystem::is_directory(file, ec))
    throw Error(fmt::format("'{}' is a directory, not an LCM log file", file.string()));
  std::ifstream in(file, std::ios::binary);
  if (!in) throw Error(fmt::format("cannot open log file '{}'", file.string()));
  std::array<char, 4> head{};
  in.read(head.data(), head.size());
  const auto got = in.gcount();
  if (got == 0) throw Error(fmt::format("log file '{}' is empty", file.string()));
  bool sync = got == 4;
  for (std::size_t i = 0; sync && i < 4; ++i)
    sync = static_cast<unsigned char>(head[i]) == kLogSync[i];
  if (!sync)
    throw Error(fmt::format(
        "'{}' is not an LCM log file (it does not start with the event sync word 0xEDA1DA01; "
        "record one with lcm-logger)",
        file.string()));
}

bool ends_with(const std::string& s, const std::string& suffix) {
  return s.size() > suffix.size() &&
         s.compare(s.size() - suffix.size(), suffix.size(), suffix) == 0;
}

}  // namespace

RobotLog read_robot_log(const std::filesystem::path& file) {
  check_is_log(file);
  lcm::LogFile log(file.string(), "r");
  if (!log.good()) throw Error(fmt::format("cannot open log file '{}'", file.string()));
  RobotLog out;
  bool have_first = false;
  const std::string suffix = kStateSuffix;
  while (const lcm::LogEvent* event = log.readNextEvent()) {
    ++out.events;
    if (!ends_with(event->channel, suffix)) continue;
    comm::Envelope header;
    const std::optional<RobotState> decoded =
        comm::decode_bytes<RobotState>(event->data, event->datalen, &header);
    if (!decoded) {
      ++out.malformed;
      continue;
    }
    const RobotState& state = *decoded;
    const std::string robot = event->channel.substr(0, event->channel.size() - suffix.size());
    const std::int64_t utime = header.utime > 0 ? header.utime : event->timestamp;
    if (!have_first) {
      out.first_utime = utime;
      have_first = true;
    }
    RobotSeries& series = out.robots[robot];
    if (series.robot.empty()) {
      series.robot = robot;
      series.n_joints = state.q.size();
    }
    if (state.q.size() != series.n_joints) {
      ++series.other_joint_counts;
      continue;
    }
    StateSample s;
    s.t_s = static_cast<double>(utime - out.first_utime) * 1e-6;
    s.servo_step = state.servo_step;
    s.q = state.q;
    s.dq = state.dq;
    s.q_desired = state.q_desired;
    s.lateness_mean_us = state.lateness_mean_us;
    s.lateness_max_us = state.lateness_max_us;
    s.overruns = state.overruns;
    series.samples.push_back(std::move(s));
  }
  return out;
}

}  // namespace mrroc::plot
