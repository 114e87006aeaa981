/// @file
/// Reading the drive wiring of a scene and evaluating its input wires (see drives.hpp).
#include "drives.hpp"

#include <fmt/format.h>
#include <fmt/ranges.h>

#include <toml++/toml.h>
#include <algorithm>
#include <cmath>
#include <set>

#include "mrroc/core/error.hpp"

namespace mrroc::emu {
namespace {

constexpr std::array<const char*, 3> kSourceNames = {"presence", "grasp", "output"};
constexpr const char* kSourceList = "presence, grasp or output";
constexpr const char* kBodyHint =
    "objects by their name, a robot's bodies as '<robot>/<body>', e.g. 'irb6/roll_link'";

/// The keys of each source, besides axis, line, source and invert.
const std::vector<std::string>& source_keys(InputSource source) {
  static const std::vector<std::string> presence = {"object", "region"};
  static const std::vector<std::string> grasp = {"object", "grasp"};
  static const std::vector<std::string> output = {"from_axis", "from_line"};
  switch (source) {
    case InputSource::presence: return presence;
    case InputSource::grasp: return grasp;
    case InputSource::output: return output;
  }
  return presence;
}

/// Reads one [[scene.robot.drives.input]] table of robot `robot`; every error names the file,
/// line, robot and key.
class InputReader {
 public:
  InputReader(const std::filesystem::path& file, const toml::table& table, const CellRobot& robot)
      : file_(file), table_(table), robot_(robot) {}

  [[nodiscard]] SourceLocation at(const toml::node& node) const {
    return SourceLocation{file_.string(), static_cast<int>(node.source().begin.line)};
  }
  [[noreturn]] void fail(const toml::node& node, const std::string& text) const {
    throw ConfigError(
        at(node), fmt::format("robot '{}', [[scene.robot.drives.input]]: {}", robot_.name, text));
  }
  [[nodiscard]] const toml::node* find(const char* key) const { return table_.get(key); }
  [[nodiscard]] const toml::node& need(const char* key, const std::string& what) const {
    const toml::node* node = find(key);
    if (node == nullptr) fail(table_, fmt::format("missing key '{}' ({})", key, what));
    return *node;
  }
  [[nodiscard]] std::string text(const toml::node& node, const char* key) const {
    if (!node.is_string()) fail(node, fmt::format("'{}' must be a string", key));
    return std::string(**node.as_string());
  }

  /// An axis name or 0-based index.
  [[nodiscard]] std::size_t axis(const char* key) const {
    const toml::node& node = need(key, "the drive: an axis name or 0-based index");
    if (node.is_integer()) {
      const auto number = node.value<std::int64_t>();
      if (number && *number >= 0 && static_cast<std::size_t>(*number) < robot_.axis_count())
        return static_cast<std::size_t>(*number);
      fail(node, fmt::format("'{}' = {}: robot '{}' has no axis {} (axes 0..{}: {})", key,
                             number.value_or(-1), robot_.name, number.value_or(-1),
                             robot_.axis_count() - 1, fmt::join(robot_.axis_names, ", ")));
    }
    if (!node.is_string()) fail(node, fmt::format("'{}' must be an axis name or index", key));
    const std::string name(**node.as_string());
    for (std::size_t i = 0; i < robot_.axis_count(); ++i)
      if (robot_.axis_names[i] == name) return i;
    fail(node, fmt::format("'{}' = \"{}\": robot '{}' has no axis '{}' (axes: {})", key, name,
                           robot_.name, name, fmt::join(robot_.axis_names, ", ")));
  }

  /// A line number 0 .. kDriveLines - 1.
  [[nodiscard]] int line(const char* key, const char* what) const {
    const toml::node& node = need(key, what);
    const auto number = node.value<std::int64_t>();
    if (!node.is_integer() || !number)
      fail(node, fmt::format("'{}' must be an integer in 0..{} ({})", key, kDriveLines - 1, what));
    if (*number < 0 || *number >= kDriveLines)
      fail(node,
           fmt::format("'{}' = {} is outside 0..{} ({})", key, *number, kDriveLines - 1, what));
    return static_cast<int>(*number);
  }

  void reject_unknown(InputSource source, const std::string& source_name) const {
    static const std::vector<std::string> common = {"axis", "line", "source", "invert"};
    const std::vector<std::string>& own = source_keys(source);
    for (const auto& [key, node] : table_) {
      const std::string name(key.str());
      if (std::find(common.begin(), common.end(), name) != common.end() ||
          std::find(own.begin(), own.end(), name) != own.end())
        continue;
      for (std::size_t s = 0; s < kSourceNames.size(); ++s) {
        const std::vector<std::string>& other = source_keys(static_cast<InputSource>(s));
        if (std::find(other.begin(), other.end(), name) != other.end())
          fail(node, fmt::format("'{}' is a key of source \"{}\", not of \"{}\" (its keys: {})",
                                 name, kSourceNames[s], source_name, fmt::join(own, ", ")));
      }
      fail(node, fmt::format("unknown key '{}' (allowed: {}, {})", name, fmt::join(common, ", "),
                             fmt::join(own, ", ")));
    }
  }

 private:
  const std::filesystem::path& file_;
  const toml::table& table_;
  const CellRobot& robot_;
};

InputWire read_input(const std::filesystem::path& file, const toml::table& table,
                     const CellWorld& world, const CellRobot& robot) {
  const InputReader r(file, table, robot);
  InputWire w;
  w.where = r.at(table);
  const toml::node& source = r.need("source", kSourceList);
  const std::string source_name = r.text(source, "source");
  const auto* known = std::find(kSourceNames.begin(), kSourceNames.end(), source_name);
  if (known == kSourceNames.end())
    r.fail(source, fmt::format("'source' = \"{}\" is not {}", source_name, kSourceList));
  w.source = static_cast<InputSource>(known - kSourceNames.begin());
  r.reject_unknown(w.source, source_name);
  w.axis = r.axis("axis");
  w.line = r.line("line", "the drive's input line; 0x60FD bit 16 + line");
  if (const toml::node* invert = r.find("invert")) {
    if (!invert->is_boolean()) r.fail(*invert, "'invert' must be true or false");
    w.invert = **invert->as_boolean();
  }
  switch (w.source) {
    case InputSource::presence: {
      const toml::node& object = r.need("object", "the object whose origin the barrier sees");
      w.object = r.text(object, "object");
      w.body = world.body_id(w.object);
      if (w.body <= 0)
        r.fail(object, fmt::format("'object' = \"{}\" is not a body of the scene ({})", w.object,
                                   kBodyHint));
      const char* shape = "[x0, x1, y0, y1, z0, z1] (m, world frame)";
      const toml::node& region = r.need("region", shape);
      const toml::array* list = region.as_array();
      if (list == nullptr || list->size() != 6)
        r.fail(region, fmt::format("'region' must be {} ({})", shape,
                                   list == nullptr ? std::string("not a list")
                                                   : fmt::format("{} values", list->size())));
      for (std::size_t i = 0; i < 6; ++i) {
        const auto v = (*list)[i].value<double>();
        if (!(*list)[i].is_number() || !v || !std::isfinite(*v))
          r.fail(region, "every value of 'region' must be a finite number [m]");
        w.region[i] = *v;
      }
      for (std::size_t i = 0; i < 3; ++i)
        if (!(w.region[2 * i] < w.region[2 * i + 1]))
          r.fail(region, fmt::format("'region' {} range {} .. {} m is empty", "xyz"[i],
                                     w.region[2 * i], w.region[2 * i + 1]));
      break;
    }
    case InputSource::grasp: {
      const toml::node& object = r.need("object", "an object with [[scene.object.grasp]] entries");
      w.object = r.text(object, "object");
      try {
        (void)world.held_object_index(w.object);
      } catch (const Error& e) {
        r.fail(object, e.what());
      }
      std::vector<std::size_t> all;
      for (std::size_t g = 0; g < world.grasp_count(); ++g)
        if (world.grasp(g).object == w.object) all.push_back(g);
      w.grasps = all;
      if (const toml::node* grasp = r.find("grasp")) {
        const auto number = grasp->value<std::int64_t>();
        if (!grasp->is_integer() || !number)
          r.fail(*grasp,
                 "'grasp' must be an integer: the index of the object's "
                 "[[scene.object.grasp]]");
        if (*number < 0 || static_cast<std::size_t>(*number) >= all.size())
          r.fail(*grasp, fmt::format("'grasp' = {} is outside 0..{}: object '{}' has {} "
                                     "[[scene.object.grasp]]",
                                     *number, all.size() - 1, w.object, all.size()));
        w.grasp = static_cast<int>(*number);
        w.grasps = {all[static_cast<std::size_t>(*number)]};
      }
      break;
    }
    case InputSource::output:
      w.from_axis = r.axis("from_axis");
      w.from_line = r.line("from_line",
                           "the output line of drive 'from_axis'; 0x60FE bit 16 + "
                           "line");
      break;
  }
  return w;
}

/// The robot's [[scene.robot.drives.input]] tables; each axis' line wired once.
std::vector<InputWire> read_inputs(const std::filesystem::path& file, const toml::node& node,
                                   const CellWorld& world, const CellRobot& robot) {
  const toml::array* list = node.as_array();
  if (list == nullptr || !list->is_array_of_tables())
    throw ConfigError(SourceLocation{file.string(), static_cast<int>(node.source().begin.line)},
                      fmt::format("robot '{}': 'input' must be [[scene.robot.drives.input]] "
                                  "tables",
                                  robot.name));
  std::vector<InputWire> out;
  for (const toml::node& element : *list) {
    InputWire w = read_input(file, *element.as_table(), world, robot);
    for (const InputWire& other : out)
      if (other.axis == w.axis && other.line == w.line)
        throw ConfigError(
            SourceLocation{file.string(),
                           static_cast<int>(element.as_table()->get("line")->source().begin.line)},
            fmt::format("robot '{}', [[scene.robot.drives.input]]: 'line' = {}: input line {} of "
                        "axis '{}' is wired twice (first at {})",
                        robot.name, w.line, w.line, robot.axis_names[w.axis], other.where.str()));
    out.push_back(std::move(w));
  }
  return out;
}

}  // namespace

std::vector<RobotDrives> read_drive_wiring(const std::filesystem::path& file,
                                           const CellWorld& world,
                                           const std::map<std::string, std::string>& overrides) {
  toml::table root;
  try {
    root = toml::parse_file(file.string());
  } catch (const toml::parse_error& e) {
    throw ConfigError(SourceLocation{file.string(), static_cast<int>(e.source().begin.line)},
                      std::string(e.description()));
  }
  const auto fail = [&](const toml::node& node, const std::string& text) {
    return ConfigError(SourceLocation{file.string(), static_cast<int>(node.source().begin.line)},
                       text);
  };
  const toml::array* robots = root["scene"]["robot"].as_array();
  std::vector<RobotDrives> out;
  std::set<std::pair<std::string, int>> used;
  for (std::size_t k = 0; k < world.robot_count(); ++k) {
    const CellRobot& robot = world.robot(k);
    const std::size_t n = robot.axis_count();
    RobotDrives d;
    d.bus = "virtual:" + robot.name;
    for (std::size_t i = 0; i < n; ++i) d.nodes.push_back(static_cast<int>(i + 1));
    for (std::size_t i = 0; i < n; ++i) {
      const double limit = robot.force_limits[i].upper;
      d.current_limit.push_back(std::isfinite(limit) && limit > 0.0 ? limit : INFINITY);
    }
    const toml::table* t = nullptr;
    if (robots != nullptr && k < robots->size() && (*robots)[k].is_table())
      t = (*robots)[k].as_table()->get_as<toml::table>("drives");
    if (t != nullptr) {
      for (const auto& [key, node] : *t)
        if (key != "bus" && key != "nodes" && key != "counts_per_unit" && key != "current_limit" &&
            key != "input" && key != "eds")
          throw fail(node, fmt::format("unknown key '{}' in [scene.robot.drives] (allowed: bus, "
                                       "nodes, counts_per_unit, current_limit, eds, input)",
                                       key.str()));
      if (const toml::node* eds = t->get("eds")) {
        // One file for every drive, or one per axis; relative to the scene file.
        std::vector<std::string> names;
        if (const toml::array* list = eds->as_array()) {
          for (const auto& v : *list) names.push_back(v.value<std::string>().value_or(""));
        } else {
          names.assign(n, eds->value<std::string>().value_or(""));
        }
        if (names.size() != n ||
            std::any_of(names.begin(), names.end(), [](const auto& x) { return x.empty(); }))
          throw fail(*eds, fmt::format("'eds' must be a file name or {} file names (robot '{}' "
                                       "has {} axes)",
                                       n, robot.name, n));
        std::map<std::string, std::shared_ptr<const can::eds::Dictionary>> loaded;
        for (const std::string& name : names) {
          std::filesystem::path path(name);
          if (path.is_relative()) path = file.parent_path() / path;
          auto& slot = loaded[path.lexically_normal().string()];
          if (!slot) {
            try {
              slot = std::make_shared<can::eds::Dictionary>(
                  can::eds::Dictionary::load(path.lexically_normal()));
            } catch (const ConfigError& e) {
              if (e.where().line > 0) throw;  // the EDS file's own line
              throw fail(*eds, e.message() + " (" + path.lexically_normal().string() + ")");
            }
          }
          d.eds.push_back(slot);
        }
      }
      if (const toml::node* bus = t->get("bus")) {
        if (!bus->is_string()) throw fail(*bus, "'bus' must be a string such as \"virtual:cell1\"");
        d.bus = **bus->as_string();
      }
      if (const toml::node* nodes = t->get("nodes")) {
        const toml::array* list = nodes->as_array();
        if (list == nullptr || list->size() != n)
          throw fail(*nodes, fmt::format("'nodes' must list {} node ids (robot '{}' has {} axes)",
                                         n, robot.name, n));
        d.nodes.clear();
        for (const auto& v : *list) {
          const auto id = v.value<std::int64_t>();
          if (!id || *id < 1 || *id > 127) throw fail(v, "node ids must be integers in 1..127");
          d.nodes.push_back(static_cast<int>(*id));
        }
      }
      if (const toml::node* counts = t->get("counts_per_unit")) {
        const auto v = counts->value<double>();
        if (!v || !(*v > 0.0) || !std::isfinite(*v))
          throw fail(*counts, "'counts_per_unit' must be a positive number [counts per rad or m]");
        d.counts_per_unit = *v;
      }
      if (const toml::node* limit = t->get("current_limit")) {
        std::vector<double> values;
        if (const toml::array* list = limit->as_array()) {
          for (const auto& v : *list) values.push_back(v.value<double>().value_or(-1.0));
        } else {
          values.assign(n, limit->value<double>().value_or(-1.0));
        }
        if (values.size() != n)
          throw fail(*limit, fmt::format("'current_limit' must be one number or {} numbers [N m "
                                         "or N]",
                                         n));
        for (const double v : values)
          if (!(v > 0.0)) throw fail(*limit, "'current_limit' values must be positive [N m or N]");
        d.current_limit = values;
      }
      if (const toml::node* inputs = t->get("input"))
        d.inputs = read_inputs(file, *inputs, world, robot);
    }
    if (const auto it = overrides.find(robot.name); it != overrides.end()) d.bus = it->second;
    for (const int node : d.nodes)
      if (!used.insert({d.bus, node}).second)
        throw ConfigError(SourceLocation::whole_file(file.string()),
                          fmt::format("node id {} is used twice on bus {} (robot '{}')", node,
                                      d.bus, robot.name));
    out.push_back(std::move(d));
  }
  for (const auto& [name, url] : overrides) {
    bool known = false;
    for (std::size_t k = 0; k < world.robot_count(); ++k)
      known = known || world.robot(k).name == name;
    if (!known)
      throw ConfigError("--bus " + name + "=" + url + ": the scene has no robot '" + name + "'");
  }
  return out;
}

bool evaluate_inputs(const RobotDrives& wiring, const CellWorld& world,
                     std::span<const std::uint8_t> outputs,
                     std::span<std::uint8_t> inputs) noexcept {
  const std::size_t n = wiring.nodes.size();
  if (outputs.size() != n || inputs.size() != n) return false;
  std::fill(inputs.begin(), inputs.end(), std::uint8_t{0});
  for (const InputWire& w : wiring.inputs) {
    bool on = false;
    switch (w.source) {
      case InputSource::presence: {
        const std::array<double, 3> p = world.body_pose(w.body).position;
        on = true;
        for (std::size_t i = 0; i < 3; ++i)
          on = on && p[i] >= w.region[2 * i] && p[i] <= w.region[2 * i + 1];
        break;
      }
      case InputSource::grasp:
        for (const std::size_t g : w.grasps) on = on || world.grasp_engaged(g);
        break;
      case InputSource::output:
        on = w.from_axis < n && ((outputs[w.from_axis] >> w.from_line) & 1U) != 0;
        break;
    }
    if (on != w.invert && w.axis < n)
      inputs[w.axis] = static_cast<std::uint8_t>(inputs[w.axis] | (1U << w.line));
  }
  return true;
}

std::string describe_input(const CellRobot& robot, const InputWire& w) {
  std::string what;
  switch (w.source) {
    case InputSource::presence:
      what = fmt::format("presence of '{}' in x {:.2f}..{:.2f} y {:.2f}..{:.2f} z {:.2f}..{:.2f} m",
                         w.object, w.region[0], w.region[1], w.region[2], w.region[3], w.region[4],
                         w.region[5]);
      break;
    case InputSource::grasp:
      what = w.grasp < 0 ? fmt::format("any grasp of '{}' engaged", w.object)
                         : fmt::format("grasp {} of '{}' engaged", w.grasp, w.object);
      break;
    case InputSource::output:
      what = fmt::format("output {} of axis '{}'", w.from_line, robot.axis_names[w.from_axis]);
      break;
  }
  return fmt::format("robot '{}' axis '{}' input {}: {}{}", robot.name, robot.axis_names[w.axis],
                     w.line, w.invert ? "not " : "", what);
}

}  // namespace mrroc::emu
