#include "mrroc/config/process_set.hpp"

#include <fmt/format.h>
#include <sched.h>

#include <csignal>

#include <toml++/toml.h>
#include <regex>
#include <set>

namespace mrroc {

namespace {

namespace fs = std::filesystem;

/// The highest priority a process' threads may get: the EDP's servo thread runs at 80, above
/// everything the process set starts.
constexpr int kMaxProcessPriority = 79;

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
                 const std::vector<const char*>& allowed) const {
    for (const auto& [key, node] : table) {
      bool known = false;
      for (const char* a : allowed) known = known || key.str() == a;
      if (!known) {
        std::string list;
        for (const char* a : allowed) list += (list.empty() ? "" : ", ") + std::string(a);
        fail(node,
             fmt::format("unknown key '{}' in [{}] (allowed: {})", key.str(), table_name, list));
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
      throw ConfigError(
          fmt::format("{}: error: missing key '{}' in [{}]", where(t).str(), key, table_name));
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

  /// `keys` plus the keys of ProcessOptions (every process' table accepts them).
  static std::vector<const char*> with_options(std::vector<const char*> keys) {
    for (const char* k : {"cpus", "priority", "stop_grace_s", "stop_signal", "host", "group",
                          "restart", "max_restarts", "restart_backoff_s", "required"})
      keys.push_back(k);
    return keys;
  }

  bool boolean(const toml::table& t, const char* key, bool fallback) const {
    const toml::node* node = t.get(key);
    if (node == nullptr) return fallback;
    if (!node->is_boolean()) fail(*node, fmt::format("'{}' must be true or false", key));
    return **node->as_boolean();
  }

  ProcessOptions options(const toml::table& t, const std::string& default_group) const {
    ProcessOptions o;
    o.group = default_group;
    o.stop_grace_s = number(t, "stop_grace_s", 3.0, 0.0, 60.0, "s");
    if (const toml::node* sig = t.get("stop_signal")) {
      static const std::pair<const char*, int> names[] = {
          {"SIGTERM", SIGTERM}, {"SIGINT", SIGINT},   {"SIGHUP", SIGHUP},  {"SIGQUIT", SIGQUIT},
          {"SIGUSR1", SIGUSR1}, {"SIGUSR2", SIGUSR2}, {"SIGKILL", SIGKILL}};
      const std::string text = string(t, "stop_signal", "", std::string{});
      bool found = false;
      for (const auto& [name, number] : names)
        if (text == name) {
          o.stop_signal = number;
          found = true;
        }
      if (!found)
        fail(*sig, fmt::format("stop_signal '{}' is not one of SIGTERM, SIGINT, SIGHUP, SIGQUIT, "
                               "SIGUSR1, SIGUSR2, SIGKILL",
                               text));
    }
    o.host = string(t, "host", "", std::string("local"));
    if (const toml::node* h = t.get("host")) o.host_where = where(*h);
    if (o.host.empty())
      fail(*t.get("host"), "'host' must not be empty (\"local\" or a [[launch.host]] name)");
    o.group = string(t, "group", "", default_group);
    const std::string restart = string(t, "restart", "", std::string("never"));
    if (restart == "never")
      o.restart = RestartPolicy::never;
    else if (restart == "on-failure")
      o.restart = RestartPolicy::on_failure;
    else if (restart == "always")
      o.restart = RestartPolicy::always;
    else
      fail(*t.get("restart"), fmt::format("restart '{}' must be \"never\", \"on-failure\" or "
                                          "\"always\"",
                                          restart));
    o.max_restarts =
        static_cast<int>(number(t, "max_restarts", 3, 0, kMaxRestartsLimit, "restarts"));
    o.restart_backoff_s = number(t, "restart_backoff_s", 0.5, 0.0, 30.0, "s");
    if (o.restart_backoff_s < kMinRestartBackoffS)
      fail(*t.get("restart_backoff_s"),
           fmt::format("'restart_backoff_s' = {} s is below the minimum of {} s (a process that "
                       "keeps failing must not be restarted in a tight loop)",
                       o.restart_backoff_s, kMinRestartBackoffS));
    o.required = boolean(t, "required", true);
    if (const toml::node* prio = t.get("priority")) {
      if (!prio->is_integer())
        fail(*prio, fmt::format("'priority' must be an integer (a SCHED_FIFO priority 0..{}; 0: "
                                "the normal scheduler)",
                                kMaxProcessPriority));
      if (**prio->as_integer() < 0 || **prio->as_integer() > kMaxProcessPriority)
        fail(*prio,
             fmt::format("'priority' = {} is outside 0..{} (SCHED_FIFO priority; 0: the "
                         "normal scheduler; {} belongs to the EDP's servo thread)",
                         **prio->as_integer(), kMaxProcessPriority, kMaxProcessPriority + 1));
      o.priority = static_cast<int>(**prio->as_integer());
    }
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
        fail(node,
             fmt::format("'{}' in [{}] must be a boolean, number, string or list", k, table_name));
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

  TaskConfig task(const toml::table& t, const std::string& table_name, const std::string& group,
                  std::vector<const char*> extra_keys = {}) const {
    extra_keys.insert(extra_keys.end(), {"task", "library", "args"});
    only_keys(t, table_name, with_options(extra_keys));
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
    c.options = options(t, group);
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

const char* to_string(RestartPolicy policy) {
  switch (policy) {
    case RestartPolicy::never: return "never";
    case RestartPolicy::on_failure: return "on-failure";
    case RestartPolicy::always: return "always";
  }
  return "?";
}

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
void check_hosts(const ProcessSetConfig& config) {
  auto check = [&](const ProcessOptions& o, const std::string& process) {
    if (o.host == "local") return;
    for (const auto& h : config.launch.hosts)
      if (h.name == o.host) return;
    throw ConfigError(
        fmt::format("{}: error: {} runs on host '{}', which is not a [[launch.host]] "
                    "(hosts: local{})",
                    o.host_where.file.empty() ? config.file.string() : o.host_where.str(), process,
                    o.host, [&] {
                      std::string s;
                      for (const auto& h : config.launch.hosts) s += ", " + h.name;
                      return s;
                    }()));
  };
  check(config.srp.options, "srp");
  check(config.ui.options, "ui");
  check(config.mp.options, "mp");
  if (config.emulator) check(config.emulator->options, "emu");
  for (const auto& v : config.vsps) check(v.options, "vsp/" + v.name);
  for (const auto& r : config.robots) {
    check(r.edp.options, "edp/" + r.name);
    check(r.ecp.options, "ecp/" + r.name);
  }
}

ProcessSetConfig process_set_from_table(const toml::table& root, const fs::path& file) {
  ProcessSetConfig config;
  config.file = file;
  Reader r(config.file);
  r.only_keys(root, "top level",
              {"system", "srp", "emulator", "vsp", "mp", "robot", "ui", "launch"});

  const toml::table& system = r.table(root, "system", "");
  r.only_keys(system, "system", {"name", "lcm_url", "ready_timeout_s", "auth_key_file"});
  config.name = r.string(system, "name", "system");
  config.lcm_url = r.string(system, "lcm_url", "system", std::string{});
  if (!config.lcm_url.empty() && config.lcm_url.find("://") == std::string::npos)
    r.fail(*system.get("lcm_url"),
           fmt::format("lcm_url '{}' is not a URL (expected e.g. udpm://239.255.76.67:7667?ttl=0)",
                       config.lcm_url));
  config.ready_timeout_s = r.number(system, "ready_timeout_s", 10.0, 0.1, 600.0, "s");
  if (const std::string key = r.string(system, "auth_key_file", "system", std::string{});
      !key.empty()) {
    config.auth_key_file = r.resolve(key);
    r.require_path(*system.get("auth_key_file"), config.auth_key_file, Reader::Kind::file,
                   "authentication key file");
  }

  if (const toml::node* srp = root.get("srp")) {
    if (!srp->is_table()) r.fail(*srp, "'srp' must be a table");
    const toml::table& t = *srp->as_table();
    r.only_keys(t, "srp", Reader::with_options({"log", "log_max_kb", "log_keep", "history"}));
    config.srp.options = r.options(t, "srp");
    if (const std::string log = r.string(t, "log", "srp", std::string{}); !log.empty())
      config.srp.log = r.resolve(log);
    config.srp.log_max_kb = r.number(t, "log_max_kb", 4096.0, 1.0, 1e7, "KiB");
    config.srp.log_keep = static_cast<int>(r.number(t, "log_keep", 5, 0, 100, "files"));
    config.srp.history = static_cast<int>(r.number(t, "history", 10000, 10, 1e6, "messages"));
  } else {
    config.srp.options = r.options(toml::table{}, "srp");
  }

  config.ui.options = r.options(toml::table{}, "ui");
  if (const toml::node* ui = root.get("ui")) {
    if (!ui->is_table()) r.fail(*ui, "'ui' must be a table");
    const toml::table& t = *ui->as_table();
    r.only_keys(t, "ui", Reader::with_options({"web", "bind", "port", "token_file", "teach_dir"}));
    config.ui.where = r.where(t);
    config.ui.options = r.options(t, "ui");
    config.ui.web = r.boolean(t, "web", false);
    config.ui.bind = r.string(t, "bind", "ui", std::string("127.0.0.1"));
    config.ui.port = static_cast<int>(r.number(t, "port", 8080, 1, 65535, "(TCP port)"));
    if (const std::string token = r.string(t, "token_file", "ui", std::string{}); !token.empty()) {
      config.ui.token_file = r.resolve(token);
      r.require_path(*t.get("token_file"), config.ui.token_file, Reader::Kind::file,
                     "console token file");
    }
    const bool loopback = config.ui.bind == "127.0.0.1" || config.ui.bind == "localhost" ||
                          config.ui.bind == "::1" || config.ui.bind.rfind("127.", 0) == 0;
    if (!loopback && config.ui.token_file.empty())
      r.fail(*t.get("bind"), fmt::format("bind '{}' is not a loopback address: the console then "
                                         "needs 'token_file' (a file holding the access token)",
                                         config.ui.bind));
    if (const std::string dir = r.string(t, "teach_dir", "ui", std::string{}); !dir.empty())
      config.ui.teach_dir = r.resolve(dir);
  }

  if (const toml::node* launch = root.get("launch")) {
    if (!launch->is_table()) r.fail(*launch, "'launch' must be a table");
    const toml::table& t = *launch->as_table();
    r.only_keys(t, "launch", {"log_dir", "log_max_kb", "log_keep", "record", "host"});
    if (const std::string dir = r.string(t, "log_dir", "launch", std::string{}); !dir.empty())
      config.launch.log_dir = r.resolve(dir);
    config.launch.log_max_kb = r.number(t, "log_max_kb", 1024.0, 1.0, 1e7, "KiB");
    config.launch.log_keep = static_cast<int>(r.number(t, "log_keep", 3, 0, 100, "files"));
    if (const std::string rec = r.string(t, "record", "launch", std::string{}); !rec.empty())
      config.launch.record = r.resolve(rec);
    if (const toml::node* hosts = t.get("host")) {
      const toml::array* list = hosts->as_array();
      if (list == nullptr || !list->is_array_of_tables())
        r.fail(*hosts, "'launch.host' must be an array of tables ([[launch.host]])");
      std::set<std::string> host_names{"local"};
      for (const auto& node : *list) {
        const toml::table& h = *node.as_table();
        r.only_keys(h, "launch.host", {"name", "command", "address", "quote"});
        HostConfig host;
        host.where = r.where(h);
        host.name = r.string(h, "name", "launch.host");
        if (!host_names.insert(host.name).second)
          r.fail(*h.get("name"), fmt::format("host name '{}' is used twice (\"local\" is "
                                             "reserved)",
                                             host.name));
        host.address = r.string(h, "address", "launch.host", host.name);
        host.command = {"ssh", "-o", "BatchMode=yes", "{host}"};
        if (const toml::node* cmd = h.get("command")) {
          const toml::array* words = cmd->as_array();
          if (words == nullptr || words->empty() || !words->is_homogeneous(toml::node_type::string))
            r.fail(*cmd,
                   "'command' must be a non-empty list of strings, e.g. [\"ip\", \"netns\", "
                   "\"exec\", \"{host}\"]");
          host.command.clear();
          for (const auto& w : *words) host.command.emplace_back(**w.as_string());
        }
        host.quote = r.boolean(h, "quote", h.get("command") == nullptr);
        config.launch.hosts.push_back(std::move(host));
      }
    }
  }

  if (const toml::node* emu = root.get("emulator")) {
    if (!emu->is_table()) r.fail(*emu, "'emulator' must be a table");
    const toml::table& t = *emu->as_table();
    r.only_keys(t, "emulator", Reader::with_options({"scene", "lock_step", "faults"}));
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
    e.options = r.options(t, "emu");
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
      r.only_keys(t, "vsp",
                  Reader::with_options({"name", "plugin", "library", "sources", "mode", "period_ms",
                                        "stale_after_ms", "params"}));
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
        throw ConfigError(
            fmt::format("{}: error: missing key 'sources' in [[vsp]] '{}' (the raw "
                        "sensor devices that feed it)",
                        r.where(t).str(), v.name));
      const toml::array* arr = sources->as_array();
      if (arr == nullptr || arr->empty() || !arr->is_homogeneous(toml::node_type::string))
        r.fail(*sources, "'sources' must be a non-empty list of raw sensor device names");
      for (const auto& s : *arr) v.sources.emplace_back(**s.as_string());
      const std::string mode = r.string(t, "mode", "vsp", std::string("on_demand"));
      if (mode != "on_demand" && mode != "periodic")
        r.fail(*t.get("mode"),
               fmt::format("mode '{}' must be \"on_demand\" or \"periodic\"", mode));
      v.periodic = mode == "periodic";
      v.period_s = r.number(t, "period_ms", 10.0, 1.0, 10000.0, "ms") / 1000.0;
      v.stale_after_s = r.number(t, "stale_after_ms", 100.0, 1.0, 60000.0, "ms") / 1000.0;
      if (const toml::node* p = t.get("params")) {
        if (!p->is_table()) r.fail(*p, "'params' must be a table");
        v.params = r.params(*p->as_table(), "vsp.params");
      } else {
        v.params = Params(r.where(t));
      }
      v.options = r.options(t, "vsp");
      config.vsps.push_back(std::move(v));
    }
  }

  {
    const toml::table& mp = r.table(root, "mp", "");
    config.mp = r.task(mp, "mp", "mp", {"start"});
    const std::string start = r.string(mp, "start", "mp", std::string("auto"));
    if (start != "auto" && start != "operator")
      r.fail(
          *mp.get("start"),
          fmt::format("start '{}' must be \"auto\" or \"operator\" (wait for START from mrroc-ui)",
                      start));
    config.mp_waits_for_operator = start == "operator";
  }

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
    r.only_keys(edp, "robot.edp",
                Reader::with_options(
                    {"plugin", "library", "servo_period_ms", "lookahead", "lock_step", "params"}));
    robot.edp.where = r.where(edp);
    robot.edp.plugin = r.string(edp, "plugin", "robot.edp");
    if (const std::string lib = r.string(edp, "library", "robot.edp", std::string{});
        !lib.empty()) {
      robot.edp.library = r.resolve(lib);
      r.require_path(*edp.get("library"), robot.edp.library, Reader::Kind::any,
                     "hardware plugin library");
    }
    robot.edp.servo_period_s =
        r.number(edp, "servo_period_ms", kDefaultServoPeriodS * 1000.0, 0.1, 100.0, "ms") / 1000.0;
    if (const toml::node* la = edp.get("lookahead")) {
      if (!la->is_integer())
        r.fail(*la, fmt::format("'lookahead' must be an integer (macro-steps queued ahead of the "
                                "servo loop, 1..{})",
                                kMaxLookahead));
      const std::int64_t v = **la->as_integer();
      if (v < 1 || v > kMaxLookahead)
        r.fail(*la, fmt::format("'lookahead' = {} macro-steps is outside 1..{} (1: the paper's "
                                "one successor)",
                                v, kMaxLookahead));
      robot.edp.lookahead = static_cast<int>(v);
    }
    if (const toml::node* ls = edp.get("lock_step")) {
      if (!ls->is_boolean()) r.fail(*ls, "'lock_step' must be true or false");
      robot.edp.lock_step = **ls->as_boolean();
    }
    if (const toml::node* p = edp.get("params")) {
      if (!p->is_table()) r.fail(*p, "'params' must be a table");
      robot.edp.params = r.params(*p->as_table(), "robot.edp.params");
    } else {
      robot.edp.params = Params(r.where(edp));
    }
    robot.edp.options = r.options(edp, "edp");
    robot.ecp = r.task(r.table(t, "ecp", "robot"), "robot.ecp", "ecp");
    config.robots.push_back(std::move(robot));
  }
  check_hosts(config);
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
