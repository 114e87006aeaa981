/// @file
/// Parsing of fault-injection specs (see faults.hpp).
#include "faults.hpp"

#include <charconv>
#include <cmath>

#include <fmt/format.h>
#include <fmt/ranges.h>

#include <algorithm>

#include "cell_world.hpp"
#include "mrroc/core/error.hpp"

namespace mrroc::emu {
namespace {

[[noreturn]] void bad(std::string_view spec, const std::string& why) {
  throw ConfigError("fault '" + std::string(spec) + "': " + why +
                    " (forms: drive:<robot>/<axis>@<s>[=<hex code>], silent:<robot>/<axis>@<s>, "
                    "drop:<robot>@<s>=<fraction>, busoff:<robot>@<s>[+<s>], sensor:<device>@<s>)");
}

double number(std::string_view spec, std::string_view text, const char* what) {
  double value = 0.0;
  const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), value);
  if (ec != std::errc() || end != text.data() + text.size() || !std::isfinite(value))
    bad(spec, std::string(what) + " '" + std::string(text) + "' is not a number");
  return value;
}

}  // namespace

FaultSpec parse_fault(std::string_view spec) {
  FaultSpec f;
  f.text = std::string(spec);
  const std::size_t colon = spec.find(':');
  if (colon == std::string_view::npos) bad(spec, "missing ':' after the kind");
  const std::string_view kind = spec.substr(0, colon);
  if (kind == "drive")
    f.kind = FaultKind::drive;
  else if (kind == "silent")
    f.kind = FaultKind::silent;
  else if (kind == "drop")
    f.kind = FaultKind::drop;
  else if (kind == "busoff")
    f.kind = FaultKind::bus_off;
  else if (kind == "sensor")
    f.kind = FaultKind::sensor;
  else
    bad(spec, "unknown kind '" + std::string(kind) + "'");
  std::string_view rest = spec.substr(colon + 1);
  const std::size_t at = rest.find('@');
  if (at == std::string_view::npos) bad(spec, "missing '@<seconds>'");
  std::string_view target = rest.substr(0, at);
  std::string_view tail = rest.substr(at + 1);
  const bool per_axis = f.kind == FaultKind::drive || f.kind == FaultKind::silent;
  const std::size_t slash = target.find('/');
  if (per_axis) {
    if (slash == std::string_view::npos || slash == 0 || slash + 1 == target.size())
      bad(spec, "needs <robot>/<axis>");
    f.robot = std::string(target.substr(0, slash));
    f.axis = std::string(target.substr(slash + 1));
  } else if (f.kind == FaultKind::sensor) {
    if (slash != std::string_view::npos || target.empty()) bad(spec, "needs <device>");
    f.device = std::string(target);
  } else {
    if (slash != std::string_view::npos || target.empty()) bad(spec, "needs <robot> (no axis)");
    f.robot = std::string(target);
  }
  std::string_view time = tail;
  std::string_view value;
  const std::size_t sep = tail.find_first_of("=+");
  if (sep != std::string_view::npos) {
    time = tail.substr(0, sep);
    value = tail.substr(sep + 1);
    const char c = tail[sep];
    if ((c == '=' && f.kind != FaultKind::drive && f.kind != FaultKind::drop) ||
        (c == '+' && f.kind != FaultKind::bus_off))
      bad(spec, fmt::format("'{}' does not apply to {}", c, kind));
  }
  f.at_s = number(spec, time, "time");
  if (f.at_s < 0.0) bad(spec, fmt::format("time {} s must be >= 0 s", time));
  if (f.kind == FaultKind::drive && !value.empty()) {
    std::string_view hex = value;
    if (hex.substr(0, 2) == "0x" || hex.substr(0, 2) == "0X") hex.remove_prefix(2);
    unsigned code = 0;
    const auto [end, ec] = std::from_chars(hex.data(), hex.data() + hex.size(), code, 16);
    if (ec != std::errc() || end != hex.data() + hex.size() || code == 0 || code > 0xFFFF)
      bad(spec, "EMCY code '" + std::string(value) + "' must be a hex number in 0x0001..0xFFFF");
    f.code = static_cast<std::uint16_t>(code);
  }
  if (f.kind == FaultKind::drop) {
    if (value.empty()) bad(spec, "drop needs '=<fraction>'");
    f.fraction = number(spec, value, "fraction");
    if (f.fraction < 0.0 || f.fraction > 1.0)
      bad(spec, "fraction " + std::string(value) + " must be in 0..1");
  }
  if (f.kind == FaultKind::bus_off && !value.empty()) {
    f.duration_s = number(spec, value, "duration");
    if (f.duration_s <= 0.0) bad(spec, "duration " + std::string(value) + " s must be > 0 s");
  }
  return f;
}

ResolvedFault resolve_fault(std::string_view spec, const CellWorld& world,
                            const std::vector<std::string>& sensors) {
  ResolvedFault r;
  r.spec = parse_fault(spec);
  const std::string text(spec);
  if (r.spec.kind == FaultKind::sensor) {
    if (std::find(sensors.begin(), sensors.end(), r.spec.device) == sensors.end())
      throw ConfigError(
          fmt::format("fault '{}': the scene has no raw sensor device '{}'{}", text, r.spec.device,
                      sensors.empty() ? std::string(" (it has none)")
                                      : fmt::format(" (devices: {})", fmt::join(sensors, ", "))));
    return r;
  }
  try {
    r.robot = world.robot_index(r.spec.robot);
  } catch (const Error& e) {
    throw ConfigError(fmt::format("fault '{}': {}", text, e.what()));
  }
  if (!r.spec.axis.empty()) {
    const CellRobot& robot = world.robot(r.robot);
    bool found = false;
    for (std::size_t i = 0; i < robot.axis_count(); ++i)
      if (robot.axis_names[i] == r.spec.axis || std::to_string(i) == r.spec.axis) {
        r.axis = i;
        found = true;
      }
    if (!found)
      throw ConfigError(fmt::format("fault '{}': robot '{}' has no axis '{}' (axes: {})", text,
                                    robot.name, r.spec.axis, fmt::join(robot.axis_names, ", ")));
  }
  return r;
}

}  // namespace mrroc::emu
