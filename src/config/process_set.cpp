#include "mrroc/config/process_set.hpp"

#include <fmt/format.h>
#include <sched.h>

#include <regex>
#include <set>
#include <toml++/toml.h>

namespace mrroc {

namespace {

namespace fs = std::filesystem;

class Reader {
 public:
  explicit Reader(fs::path file) : file_(std::move(file)) {}

  SourceLocation where(const toml::node& node) const {
    return SourceLocation{file_.string(), static_cast<int>(node.source().begin.line)};
  }

  [[noreturn]] void fail(const toml::node& node, const std::string& text) const {
    throw ConfigError(fmt::format("{}: error: {}", where(node).str(), text));
  }

  enum class Kind { any, folder, file };

  /// Fails at `node` unless `path` exists (as a folder or a regular file, if asked); a path the
  /// system cannot even look up (name too long, no permission) fails with the system's reason.
  void require_path(const toml::node& node, const fs::path& path, Kind kind,
                    const std::string& what) const {
    std::error_code ec;
    const fs::file_status status = fs::status(path, ec);
    if (ec && ec != std::errc::no_such_file_or_directory && ec != std::errc::not_a_directory)
      fail(node, fmt::format("{} '{}' cannot be looked up: {}", what, path.string(), ec.message()));
    const bool found = kind == Kind::folder ? fs::is_directory(status)
                       : kind == Kind::file ? fs::is_regular_file(status)
                                            : fs::exists(status);
    if (!found) fail(node, fmt::format("{} '{}' not found", what, path.string()));
  }

  /// Rejects keys of `table` not in `allowed`.
  void only_keys(const toml::table& table, const std::string& table_name,
                 std::initializer_list<const char*> allowed) const {
    for (const auto& [key, node] : table) {
      bool known = false;
      for (const char* a : allowed) known = known || key.str() == a;
      if (!known) {
        std::string list;
        for (const char* a : allowed) list += (list.empty() ? "" : ", ") + std::string(a);
        fail(node, fmt::format("unknown key '{}' in [{}] (allowed: {})", key.str(), table_name,
                               list));
      }
    }
  }

  const toml::table& table(const toml::table& parent, const char* key,
                           const std::string& parent_name) const {
    const toml::node* node = parent.get(key);
    if (node == nullptr)
      throw ConfigError(fmt::format("{}: error: missing table [{}{}{}]", where(parent).str(),
                                    parent_name, parent_name.empty() ? "" : ".", key));
    if (!node->is_table()) fail(*node, fmt::format("'{}' must be a table", key));
    return *node->as_table();
  }

  std::string string(const toml::table& t, const char* key, const std::string& table_name,
                     std::optional<std::string> fallback = std::nullopt) const {
    const toml::node* node = t.get(key);
    if (node == nullptr) {
      if (fallback) return *fallback;
      throw ConfigError(fmt::format("{}: error: missing key '{}' in [{}]", where(t).str(), key,
                                    table_name));
    }
    if (!node->is_string()) fail(*node, fmt::format("'{}' must be a string", key));
    return **node->as_string();
  }

  double number(const toml::table& t, const char* key, double fallback, double min, double max,
                const char* unit) const {
    const toml::node* node = t.get(key);
    if (node == nullptr) return fallback;
    double v = 0;
    if (node->is_floating_point())
      v = **node->as_floating_point();
    else if (node->is_integer())
      v = static_cast<double>(**node->as_integer());
    else
      fail(*node, fmt::format("'{}' must be a number [{}]", key, unit));
    if (!(v >= min && v <= max))
      fail(*node, fmt::format("'{}' = {} {} is outside {}..{} {}", key, v, unit, min, max, unit));
    return v;
  }

  ProcessOptions options(const toml::table& t) const {
    ProcessOptions o;
    o.stop_grace_s = number(t, "stop_grace_s", 3.0, 0.0, 60.0, "s");
    if (const toml::node* cpus = t.get("cpus")) {
      const toml::array* arr = cpus->as_array();
      if (arr == nullptr) fail(*cpus, "'cpus' must be a list of CPU numbers");
      for (const auto& c : *arr) {
        if (!c.is_integer() || c.as_integer()->get() < 0 || c.as_integer()->get() >= CPU_SETSIZE)
          fail(c, fmt::format("'cpus' must be a list of CPU numbers (integers 0..{})",
                              CPU_SETSIZE - 1));
        o.cpus.push_back(static_cast<int>(c.as_integer()->get()));
      }
    }
    return o;
  }

  Params params(const toml::table& t, const std::string& table_name) const {
    Params p(where(t));
    for (const auto& [key, node] : t) {
      const std::string k(key.str());
      const SourceLocation at = where(node);
      if (node.is_boolean()) {
        p.set(k, **node.as_boolean(), at);
      } else if (node.is_integer()) {
        p.set(k, static_cast<std::int64_t>(**node.as_integer()), at);
      } else if (node.is_floating_point()) {
        p.set(k, **node.as_floating_point(), at);
      } else if (node.is_string()) {
        p.set(k, std::string(**node.as_string()), at);
      } else if (node.is_array()) {
        p.set(k, array_value(*node.as_array(), k), at);
      } else {
        fail(node, fmt::format("'{}' in [{}] must be a boolean, number, string or list", k,
                               table_name));
      }
    }
    return p;
  }

  ParamValue array_value(const toml::array& arr, const std::string& key) const {
    if (arr.empty()) return std::vector<double>{};
    if (arr.is_homogeneous(toml::node_type::string)) {
      std::vector<std::string> out;
      for (const auto& n : arr) out.emplace_back(**n.as_string());
      return out;
    }
    if (arr[0].is_array()) {
      std::vector<std::vector<double>> rows;
      for (const auto& n : arr) {
        if (!n.is_array()) fail(n, fmt::format("'{}' must be a list of lists of numbers", key));
        rows.push_back(numbers(*n.as_array(), key));
      }
      return rows;
    }
    return numbers(arr, key);
  }

  std::vector<double> numbers(const toml::array& arr, const std::string& key) const {
    std::vector<double> out;
    for (const auto& n : arr) {
      if (n.is_floating_point())
        out.push_back(**n.as_floating_point());
      else if (n.is_integer())
        out.push_back(static_cast<double>(**n.as_integer()));
      else
        fail(n, fmt::format("'{}' must contain only numbers", key));
    }
    return out;
  }

  TaskConfig task(const toml::table& t, const std::string& table_name) const {
    only_keys(t, table_name, {"task", "library", "args", "cpus", "stop_grace_s"});
    TaskConfig c;
    c.where = where(t);
    c.name = string(t, "task", table_name);
    const std::string lib = string(t, "library", table_name, std::string{});
    if (!lib.empty()) {
      c.library = resolve(lib);
      require_path(*t.get("library"), c.library, Kind::any, "task library");
    }
    if (const toml::node* args = t.get("args")) {
      if (!args->is_table()) fail(*args, "'args' must be a table");
      c.args = params(*args->as_table(), table_name + ".args");
    } else {
      c.args = Params(where(t));
    }
    c.options = options(t);
    return c;
  }

  fs::path resolve(const std::string& path) const {
    fs::path p(path);
    if (p.is_relative()) p = file_.parent_path() / p;
    return p.lexically_normal();
  }

 private:
  fs::path file_;
};

}  // namespace

Params params_from_toml(const std::string& text, const std::string& origin) {
  Reader r(origin);
  try {
    const toml::table table = toml::parse(text, origin);
    return r.params(table, origin);
  } catch (const toml::parse_error& e) {
    throw ConfigError(
        fmt::format("{}:{}: error: {}", origin, e.source().begin.line, e.description()));
  }
}

const VspConfig& ProcessSetConfig::vsp(const std::string& vsp_name) const {
  std::string known;
  for (const auto& v : vsps) {
    if (v.name == vsp_name) return v;
    known += (known.empty() ? "" : ", ") + v.name;
  }
  throw ConfigError(fmt::format("{}: error: no [[vsp]] named '{}' (known: {})", file.string(),
                                vsp_name, known.empty() ? "none" : known));
}

const RobotConfig& ProcessSetConfig::robot(const std::string& robot_name) const {
  for (const auto& r : robots)
    if (r.name == robot_name) return r;
  std::string known;
  for (const auto& r : robots) known += (known.empty() ? "" : ", ") + r.name;
  throw ConfigError(fmt::format("{}: error: no robot named '{}' (robots: {})", file.string(),
                                robot_name, known.empty() ? "none" : known));
}

namespace {

/// Validates a parsed process-set file; `file` is its absolute path.
ProcessSetConfig process_set_from_table(const toml::table& root, const fs::path& file) {
  ProcessSetConfig config;
  config.file = file;
  Reader r(config.file);
  r.only_keys(root, "top level", {"system", "srp", "emulator", "vsp", "mp", "robot"});

  const toml::table& system = r.table(root, "system", "");
  r.only_keys(system, "system", {"name", "lcm_url", "ready_timeout_s"});
  config.name = r.string(system, "name", "system");
  config.lcm_url = r.string(system, "lcm_url", "system", std::string{});
  if (!config.lcm_url.empty() && config.lcm_url.find("://") == std::string::npos)
    r.fail(*system.get("lcm_url"),
           fmt::format("lcm_url '{}' is not a URL (expected e.g. udpm://239.255.76.67:7667?ttl=0)",
                       config.lcm_url));
  config.ready_timeout_s = r.number(system, "ready_timeout_s", 10.0, 0.1, 600.0, "s");

  if (const toml::node* srp = root.get("srp")) {
    if (!srp->is_table()) r.fail(*srp, "'srp' must be a table");
    r.only_keys(*srp->as_table(), "srp", {"cpus", "stop_grace_s"});
    config.srp = r.options(*srp->as_table());
  }

  if (const toml::node* emu = root.get("emulator")) {
    if (!emu->is_table()) r.fail(*emu, "'emulator' must be a table");
    const toml::table& t = *emu->as_table();
    r.only_keys(t, "emulator", {"scene", "lock_step", "faults", "cpus", "stop_grace_s"});
    EmulatorConfig e;
    e.where = r.where(t);
    e.scene = r.resolve(r.string(t, "scene", "emulator"));
    r.require_path(*t.get("scene"), e.scene, Reader::Kind::file, "scene file");
    if (const toml::node* ls = t.get("lock_step")) {
      if (!ls->is_boolean()) r.fail(*ls, "'lock_step' must be true or false");
      e.lock_step = **ls->as_boolean();
    }
    if (const toml::node* faults = t.get("faults")) {
      const toml::array* arr = faults->as_array();
      if (arr == nullptr || !arr->is_homogeneous(toml::node_type::string))
        r.fail(*faults, "'faults' must be a list of strings (see mrroc-axis-emu --help)");
      for (const auto& f : *arr) e.faults.emplace_back(**f.as_string());
    }
    e.options = r.options(t);
    config.emulator = std::move(e);
  }

  if (const toml::node* vsps = root.get("vsp")) {
    const toml::array* list = vsps->as_array();
    if (list == nullptr || !list->is_array_of_tables())
      r.fail(*vsps, "'vsp' must be an array of tables ([[vsp]])");
    static const std::regex vsp_name_re("[a-z][a-z0-9_]{0,30}");
    std::set<std::string> vsp_names;
    for (const auto& node : *list) {
      const toml::table& t = *node.as_table();
      r.only_keys(t, "vsp", {"name", "plugin", "library", "sources", "mode", "period_ms",
                             "stale_after_ms", "params", "cpus", "stop_grace_s"});
      VspConfig v;
      v.where = r.where(t);
      v.name = r.string(t, "name", "vsp");
      if (!std::regex_match(v.name, vsp_name_re))
        r.fail(*t.get("name"), fmt::format("VSP name '{}' must match [a-z][a-z0-9_]* and have at "
                                           "most 31 characters",
                                           v.name));
      if (!vsp_names.insert(v.name).second)
        r.fail(*t.get("name"), fmt::format("VSP name '{}' is used twice", v.name));
      v.plugin = r.string(t, "plugin", "vsp");
      if (const std::string lib = r.string(t, "library", "vsp", std::string{}); !lib.empty()) {
        v.library = r.resolve(lib);
        r.require_path(*t.get("library"), v.library, Reader::Kind::any, "sensor plugin library");
      }
      const toml::node* sources = t.get("sources");
      if (sources == nullptr)
        throw ConfigError(fmt::format("{}: error: missing key 'sources' in [[vsp]] '{}' (the raw "
                                      "sensor devices that feed it)",
                                      r.where(t).str(), v.name));
      const toml::array* arr = sources->as_array();
      if (arr == nullptr || arr->empty() || !arr->is_homogeneous(toml::node_type::string))
        r.fail(*sources, "'sources' must be a non-empty list of raw sensor device names");
      for (const auto& s : *arr) v.sources.emplace_back(**s.as_string());
      const std::string mode = r.string(t, "mode", "vsp", std::string("on_demand"));
      if (mode != "on_demand" && mode != "periodic")
        r.fail(*t.get("mode"), fmt::format("mode '{}' must be \"on_demand\" or \"periodic\"", mode));
      v.periodic = mode == "periodic";
      v.period_s = r.number(t, "period_ms", 10.0, 1.0, 10000.0, "ms") / 1000.0;
      v.stale_after_s = r.number(t, "stale_after_ms", 100.0, 1.0, 60000.0, "ms") / 1000.0;
      if (const toml::node* p = t.get("params")) {
        if (!p->is_table()) r.fail(*p, "'params' must be a table");
        v.params = r.params(*p->as_table(), "vsp.params");
      } else {
        v.params = Params(r.where(t));
      }
      v.options = r.options(t);
      config.vsps.push_back(std::move(v));
    }
  }

  config.mp = r.task(r.table(root, "mp", ""), "mp");

  const toml::node* robots = root.get("robot");
  if (robots == nullptr)
    throw ConfigError(fmt::format("{}: error: no [[robot]] defined", config.file.string()));
  const toml::array* list = robots->as_array();
  if (list == nullptr || !list->is_array_of_tables())
    r.fail(*robots, "'robot' must be an array of tables ([[robot]])");
  static const std::regex name_re("[a-z][a-z0-9_]{0,30}");
  std::set<std::string> names;
  for (const auto& node : *list) {
    const toml::table& t = *node.as_table();
    r.only_keys(t, "robot", {"name", "model", "base", "edp", "ecp"});
    RobotConfig robot;
    robot.where = r.where(t);
    robot.name = r.string(t, "name", "robot");
    if (!std::regex_match(robot.name, name_re))
      r.fail(*t.get("name"), fmt::format("robot name '{}' must match [a-z][a-z0-9_]* and have at "
                                         "most 31 characters",
                                         robot.name));
    if (!names.insert(robot.name).second)
      r.fail(*t.get("name"), fmt::format("robot name '{}' is used twice", robot.name));
    robot.model_dir = r.resolve(r.string(t, "model", "robot"));
    r.require_path(*t.get("model"), robot.model_dir, Reader::Kind::folder, "robot model folder");

    if (const toml::node* base = t.get("base")) {
      const toml::array* values = base->as_array();
      if (values == nullptr || values->size() != 6)
        r.fail(*base, "'base' must be [x, y, z, rx, ry, rz] (m, rotation vector in rad)");
      const std::vector<double> v = r.numbers(*values, "base");
      std::copy(v.begin(), v.end(), robot.base.begin());
    }
    const toml::table& edp = r.table(t, "edp", "robot");
    r.only_keys(edp, "robot.edp", {"plugin", "library", "servo_period_ms", "params", "cpus",
                                   "stop_grace_s"});
    robot.edp.where = r.where(edp);
    robot.edp.plugin = r.string(edp, "plugin", "robot.edp");
    if (const std::string lib = r.string(edp, "library", "robot.edp", std::string{}); !lib.empty()) {
      robot.edp.library = r.resolve(lib);
      r.require_path(*edp.get("library"), robot.edp.library, Reader::Kind::any,
                     "hardware plugin library");
    }
    robot.edp.servo_period_s = r.number(edp, "servo_period_ms", 2.0, 0.1, 100.0, "ms") / 1000.0;
    if (const toml::node* p = edp.get("params")) {
      if (!p->is_table()) r.fail(*p, "'params' must be a table");
      robot.edp.params = r.params(*p->as_table(), "robot.edp.params");
    } else {
      robot.edp.params = Params(r.where(edp));
    }
    robot.edp.options = r.options(edp);
    robot.ecp = r.task(r.table(t, "ecp", "robot"), "robot.ecp");
    config.robots.push_back(std::move(robot));
  }
  return config;
}

[[noreturn]] void throw_parse_error(const fs::path& file, const toml::parse_error& e) {
  throw ConfigError(
      fmt::format("{}:{}: error: {}", file.string(), e.source().begin.line, e.description()));
}

}  // namespace

ProcessSetConfig load_process_set(const fs::path& path) {
  if (std::error_code ec; !fs::exists(path, ec))
    throw ConfigError(fmt::format("{}: error: config file not found{}", path.string(),
                                  ec ? " (" + ec.message() + ")" : std::string{}));
  const fs::path file = fs::absolute(path).lexically_normal();
  toml::table root;
  try {
    root = toml::parse_file(file.string());
  } catch (const toml::parse_error& e) {
    throw_parse_error(file, e);
  }
  return process_set_from_table(root, file);
}

ProcessSetConfig parse_process_set(std::string_view text, const fs::path& path) {
  const fs::path file = fs::absolute(path).lexically_normal();
  toml::table root;
  try {
    root = toml::parse(text, file.string());
  } catch (const toml::parse_error& e) {
    throw_parse_error(file, e);
  }
  return process_set_from_table(root, file);
}

}  // namespace mrroc
