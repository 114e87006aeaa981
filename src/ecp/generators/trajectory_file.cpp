#include "mrroc/ecp/generators/trajectory_file.hpp"

#include <fmt/format.h>

#include <charconv>
#include <cmath>
#include <fstream>
#include <sstream>
#include <system_error>

#include "mrroc/core/error.hpp"
#include "mrroc/kinematics/pose.hpp"

namespace mrroc::ecp {

namespace {

constexpr std::string_view kMagic = "# mrroc trajectory v";
constexpr std::size_t kMaxAxes = 64;

// A token as it may appear in an error text: printable, at most 40 characters.
std::string printable(std::string_view token) {
  std::string out = "'";
  std::size_t shown = 0;
  for (const char c : token) {
    if (shown++ == 40) {
      out += "...";
      break;
    }
    const auto u = static_cast<unsigned char>(c);
    if (u >= 0x20 && u < 0x7f)
      out += c;
    else
      out += fmt::format("\\x{:02x}", u);
  }
  return out + "'";
}

bool is_space(char c) { return c == ' ' || c == '\t' || c == '\r' || c == '\v' || c == '\f'; }

std::vector<std::string_view> split(std::string_view s) {
  std::vector<std::string_view> tokens;
  std::size_t i = 0;
  while (i < s.size()) {
    while (i < s.size() && is_space(s[i])) ++i;
    const std::size_t begin = i;
    while (i < s.size() && !is_space(s[i])) ++i;
    if (i > begin) tokens.push_back(s.substr(begin, i - begin));
  }
  return tokens;
}

/// A finite number filling the whole token (an optional leading '+' is accepted).
std::optional<double> to_number(std::string_view token) {
  if (token.size() > 1 && token.front() == '+' && token[1] != '-' && token[1] != '+')
    token.remove_prefix(1);
  double value = 0.0;
  const char* end = token.data() + token.size();
  const auto [ptr, ec] = std::from_chars(token.data(), end, value);
  if (ec != std::errc() || ptr != end || !std::isfinite(value)) return std::nullopt;
  return value;
}

bool valid_robot_name(std::string_view name) {
  if (name.empty() || name.size() > 64) return false;
  for (const char c : name)
    if (!((c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '_' ||
          c == '-' || c == '.'))
      return false;
  return true;
}

bool is_cartesian(edp::ArmRepresentation r) {
  return r == edp::ArmRepresentation::frame || r == edp::ArmRepresentation::xyz_euler_zyz ||
         r == edp::ArmRepresentation::xyz_angle_axis;
}

const char* value_unit(edp::ArmRepresentation r) {
  switch (r) {
    case edp::ArmRepresentation::joint: return "joint values [rad]";
    case edp::ArmRepresentation::motor: return "motor shaft angles [rad]";
    case edp::ArmRepresentation::frame: return "values of the 3x4 matrix [R | p] row by row [-, m]";
    case edp::ArmRepresentation::xyz_euler_zyz:
      return "values x y z [m] and Euler Z-Y-Z angles [rad]";
    case edp::ArmRepresentation::xyz_angle_axis:
      return "values x y z [m] and a rotation vector [rad]";
  }
  return "values";
}

class Parser {
 public:
  Parser(std::string_view text, std::string name) : text_(text), name_(std::move(name)) {}

  TrajectoryFile parse() {
    TrajectoryFile file;
    bool header = false;
    std::size_t pos = 0;
    while (pos <= text_.size()) {
      std::size_t end = text_.find('\n', pos);
      if (end == std::string_view::npos) end = text_.size();
      std::string_view line = text_.substr(pos, end - pos);
      pos = end + 1;
      ++line_;
      if (line_ == 1 && line.starts_with("\xEF\xBB\xBF")) line.remove_prefix(3);  // UTF-8 BOM
      if (!header) {
        parse_header(line, file);
        header = true;
        continue;
      }
      parse_pose(line, file);
      if (end == text_.size()) break;
    }
    if (!header) {
      line_ = 1;
      fail(fmt::format("empty file: expected the header '{}{} representation=... axes=...'", kMagic,
                       TrajectoryFile::kVersion));
    }
    return file;
  }

 private:
  [[noreturn]] void fail(const std::string& text) const {
    throw ConfigError(SourceLocation{name_, static_cast<int>(line_)}, text);
  }

  void parse_header(std::string_view line, TrajectoryFile& file) const {
    if (!line.starts_with(kMagic))
      fail(
          fmt::format("the first line must be the header '{}{} representation=... axes=...', "
                      "found {}",
                      kMagic, TrajectoryFile::kVersion, printable(line)));
    const std::vector<std::string_view> tokens = split(line.substr(kMagic.size()));
    if (tokens.empty()) fail("header: the format version is missing after 'v'");
    int version = 0;
    const auto [ptr, ec] =
        std::from_chars(tokens[0].data(), tokens[0].data() + tokens[0].size(), version);
    if (ec != std::errc() || ptr != tokens[0].data() + tokens[0].size() || version < 1)
      fail(
          fmt::format("header: format version {} is not a positive integer", printable(tokens[0])));
    if (version > TrajectoryFile::kVersion)
      fail(fmt::format("header: format version {} is newer than the supported version {}", version,
                       TrajectoryFile::kVersion));
    bool have_representation = false;
    bool have_axes = false;
    bool have_robot = false;
    for (std::size_t i = 1; i < tokens.size(); ++i) {
      const std::string_view token = tokens[i];
      const std::size_t eq = token.find('=');
      if (eq == std::string_view::npos)
        fail(fmt::format("header: {} is not key=value (keys: representation, axes, robot)",
                         printable(token)));
      const std::string_view key = token.substr(0, eq);
      const std::string_view value = token.substr(eq + 1);
      if (key == "representation") {
        if (have_representation) fail("header: representation is given twice");
        const auto r = representation_from_string(value);
        if (!r)
          fail(
              fmt::format("header: representation {} is not one of JOINT, MOTOR, FRAME, "
                          "XYZ_EULER_ZYZ, XYZ_ANGLE_AXIS",
                          printable(value)));
        file.representation = *r;
        have_representation = true;
      } else if (key == "axes") {
        if (have_axes) fail("header: axes is given twice");
        std::size_t axes = 0;
        const auto [p, e] = std::from_chars(value.data(), value.data() + value.size(), axes);
        if (e != std::errc() || p != value.data() + value.size() || axes < 1 || axes > kMaxAxes)
          fail(fmt::format("header: axes {} is not an integer in 1..{}", printable(value),
                           kMaxAxes));
        file.axes = axes;
        have_axes = true;
      } else if (key == "robot") {
        if (have_robot) fail("header: robot is given twice");
        if (!valid_robot_name(value))
          fail(
              fmt::format("header: robot {} is not a name of 1..64 letters, digits, '_', '-', "
                          "'.'",
                          printable(value)));
        file.robot = std::string(value);
        have_robot = true;
      } else {
        fail(fmt::format("header: unknown key {} (keys: representation, axes, robot)",
                         printable(key)));
      }
    }
    if (!have_representation) fail("header: representation=... is missing");
    if (!have_axes) fail("header: axes=... is missing");
  }

  void parse_pose(std::string_view line, TrajectoryFile& file) const {
    const std::size_t comment = line.find('#');
    if (comment != std::string_view::npos) line = line.substr(0, comment);
    const std::vector<std::string_view> tokens = split(line);
    if (tokens.empty()) return;
    const std::size_t expected = file.values_per_point();
    TrajectoryPoint point;
    for (const std::string_view token : tokens) {
      const std::size_t eq = token.find('=');
      if (eq == std::string_view::npos) {
        if (point.duration_s || point.velocity_scale)
          fail(fmt::format("value {} after an option: the {} {} come first", printable(token),
                           expected, value_unit(file.representation)));
        const auto value = to_number(token);
        if (!value)
          fail(fmt::format("value {} {} is not a finite number (expected {} {})",
                           point.values.size() + 1, printable(token), expected,
                           value_unit(file.representation)));
        if (point.values.size() == expected)
          fail(fmt::format(
              "too many values: {} has {} values, expected {} {} (header: "
              "representation={} axes={})",
              printable(token), point.values.size() + 1, expected, value_unit(file.representation),
              edp::to_string(file.representation), file.axes));
        point.values.push_back(*value);
        continue;
      }
      const std::string_view key = token.substr(0, eq);
      const std::string_view text = token.substr(eq + 1);
      const auto value = to_number(text);
      if (key == "duration") {
        if (point.duration_s) fail("duration= is given twice");
        if (!value || *value <= 0.0)
          fail(fmt::format("duration {} is not a number of seconds > 0", printable(text)));
        point.duration_s = *value;
      } else if (key == "velocity_scale") {
        if (point.velocity_scale) fail("velocity_scale= is given twice");
        if (!value || *value <= 0.0 || *value > 1.0)
          fail(fmt::format("velocity_scale {} is not a number in (0, 1]", printable(text)));
        point.velocity_scale = *value;
      } else {
        fail(
            fmt::format("unknown option {} (expected duration=SECONDS or "
                        "velocity_scale=FRACTION)",
                        printable(key)));
      }
    }
    if (point.duration_s && point.velocity_scale)
      fail("a pose has either duration= or velocity_scale=, not both");
    if (point.values.size() != expected)
      fail(
          fmt::format("too few values: the pose has {}, expected {} {} (header: "
                      "representation={} axes={})",
                      point.values.size(), expected, value_unit(file.representation),
                      edp::to_string(file.representation), file.axes));
    if (file.representation == edp::ArmRepresentation::frame) {
      try {
        (void)kinematics::frame_from_values(point.values);
      } catch (const CommandError& e) {
        fail(fmt::format("the pose is not a frame: {}", e.what()));
      }
    }
    file.points.push_back(std::move(point));
  }

  std::string_view text_;
  std::string name_;
  std::size_t line_ = 0;
};

}  // namespace

std::optional<edp::ArmRepresentation> representation_from_string(std::string_view name) {
  for (const auto r :
       {edp::ArmRepresentation::joint, edp::ArmRepresentation::motor, edp::ArmRepresentation::frame,
        edp::ArmRepresentation::xyz_euler_zyz, edp::ArmRepresentation::xyz_angle_axis})
    if (name == edp::to_string(r)) return r;
  return std::nullopt;
}

std::size_t TrajectoryFile::values_per_point() const {
  return is_cartesian(representation) ? kinematics::representation_size(representation) : axes;
}

TrajectoryFile TrajectoryFile::parse(std::string_view text, const std::string& name) {
  return Parser(text, name).parse();
}

TrajectoryFile TrajectoryFile::load(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in)
    throw ConfigError(SourceLocation::whole_file(path.string()),
                      "trajectory file cannot be opened for reading");
  std::ostringstream buffer;
  buffer << in.rdbuf();
  if (in.bad())
    throw ConfigError(SourceLocation::whole_file(path.string()), "trajectory file cannot be read");
  return parse(buffer.str(), path.string());
}

std::string TrajectoryFile::to_text() const {
  const auto fail = [](const std::string& text) { throw Error("trajectory: " + text); };
  if (!representation_from_string(edp::to_string(representation)))
    fail(fmt::format("representation {} is unknown", static_cast<int>(representation)));
  if (axes < 1 || axes > kMaxAxes) fail(fmt::format("axes {} is outside 1..{}", axes, kMaxAxes));
  if (!robot.empty() && !valid_robot_name(robot))
    fail(fmt::format("robot {} is not a name of 1..64 letters, digits, '_', '-', '.'",
                     printable(robot)));
  std::string out = fmt::format("{}{} representation={} axes={}", kMagic, kVersion,
                                edp::to_string(representation), axes);
  if (!robot.empty()) out += " robot=" + robot;
  out += '\n';
  const std::size_t expected = values_per_point();
  for (std::size_t i = 0; i < points.size(); ++i) {
    const TrajectoryPoint& p = points[i];
    if (p.values.size() != expected)
      fail(fmt::format("point {} has {} values, {} expected", i + 1, p.values.size(), expected));
    for (std::size_t j = 0; j < p.values.size(); ++j) {
      if (!std::isfinite(p.values[j]))
        fail(fmt::format("point {} value {} is not finite", i + 1, j + 1));
      out += fmt::format("{}{}", j == 0 ? "" : " ", p.values[j]);
    }
    if (p.duration_s && p.velocity_scale)
      fail(fmt::format("point {} has both a duration and a velocity scale", i + 1));
    if (p.duration_s) {
      if (!(std::isfinite(*p.duration_s) && *p.duration_s > 0.0))
        fail(fmt::format("point {} duration {} s is not > 0", i + 1, *p.duration_s));
      out += fmt::format(" duration={}", *p.duration_s);
    }
    if (p.velocity_scale) {
      if (!(*p.velocity_scale > 0.0 && *p.velocity_scale <= 1.0))
        fail(fmt::format("point {} velocity_scale {} is outside (0, 1]", i + 1, *p.velocity_scale));
      out += fmt::format(" velocity_scale={}", *p.velocity_scale);
    }
    out += '\n';
  }
  return out;
}

void TrajectoryFile::save(const std::filesystem::path& path) const {
  const std::string text = to_text();
  std::filesystem::path temporary = path;
  temporary += ".tmp";
  {
    std::ofstream out(temporary, std::ios::binary | std::ios::trunc);
    if (!out)
      throw Error(located_message(SourceLocation::whole_file(temporary.string()),
                                  "cannot be opened for writing"));
    out << text;
    out.close();
    if (!out)
      throw Error(located_message(SourceLocation::whole_file(temporary.string()), "write failed"));
  }
  std::error_code ec;
  std::filesystem::rename(temporary, path, ec);
  if (ec) {
    std::filesystem::remove(temporary, ec);
    throw Error(located_message(SourceLocation::whole_file(path.string()),
                                fmt::format("cannot be written ({})", ec.message())));
  }
}

}  // namespace mrroc::ecp
