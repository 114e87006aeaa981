#include "mrroc/config/process_set.hpp"

#include "mrroc/config/check.hpp"

#include "collision_reader.hpp"

#include <arpa/inet.h>
#include <fmt/format.h>
#include <netinet/in.h>
#include <sched.h>

#include <algorithm>
#include <csignal>
#include <functional>

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
  /// `sink`: collect every error there (each table read on its own, `check_process_set`);
  /// null: throw at the first. `broken`: the processes whose tables had an error go there.
  explicit Reader(fs::path file, ConfigErrorList* sink = nullptr,
                  std::set<std::string>* broken = nullptr)
      : file_(std::move(file)), sink_(sink), broken_(broken) {}

  /// Runs `f`, which reads one table (or part of one). Without a sink its error is thrown; with
  /// one it is collected and false returned, so that the reading goes on with the next table.
  template <class F>
  bool guard(F&& f) const {
    if (sink_ == nullptr) {
      f();
      return true;
    }
    return sink_->run(SourceLocation{}, std::forward<F>(f));
  }

  /// Marks `process` as one whose table had an error (collecting only).
  void mark_broken(const std::string& process) const {
    if (broken_ != nullptr) broken_->insert(process);
  }

  SourceLocation where(const toml::node& node) const {
    return SourceLocation{file_.string(), static_cast<int>(node.source().begin.line)};
  }

  [[noreturn]] void fail(const toml::node& node, const std::string& text) const {
    throw ConfigError(where(node), text);
  }

  enum class Kind { any, folder, file };

  /// Fails at `node` unless `path` exists (as a folder or a regular file, if asked); a path the
  /// system cannot even look up (name too long, no permission) fails with the system's reason.
  void require_path(const toml::node& node, const fs::path& path, Kind kind,
                    const std::string& what, const std::string& how_to_make = {}) const {
    std::error_code ec;
    const fs::file_status status = fs::status(path, ec);
    if (ec && ec != std::errc::no_such_file_or_directory && ec != std::errc::not_a_directory)
      fail(node, fmt::format("{} '{}' cannot be looked up: {}", what, path.string(), ec.message()));
    const bool found = kind == Kind::folder ? fs::is_directory(status)
                       : kind == Kind::file ? fs::is_regular_file(status)
                                            : fs::exists(status);
    if (!found) fail(node, fmt::format("{} '{}' not found{}", what, path.string(), how_to_make));
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
        const std::string text =
            fmt::format("unknown key '{}' in [{}] (allowed: {})", key.str(), table_name, list);
        if (sink_ == nullptr) fail(node, text);
        sink_->add(ConfigError(where(node), text));  // and the other keys are read as usual
      }
    }
  }

  const toml::table& table(const toml::table& parent, const char* key,
                           const std::string& parent_name) const {
    const toml::node* node = parent.get(key);
    if (node == nullptr)
      throw ConfigError(where(parent), fmt::format("missing table [{}{}{}]", parent_name,
                                                   parent_name.empty() ? "" : ".", key));
    if (!node->is_table()) fail(*node, fmt::format("'{}' must be a table", key));
    return *node->as_table();
  }

  std::string string(const toml::table& t, const char* key, const std::string& table_name,
                     std::optional<std::string> fallback = std::nullopt) const {
    const toml::node* node = t.get(key);
    if (node == nullptr) {
      if (fallback) return *fallback;
      throw ConfigError(where(t), fmt::format("missing key '{}' in [{}]", key, table_name));
    }
    if (!node->is_string()) fail(*node, fmt::format("'{}' must be a string", key));
    return **node->as_string();
  }

  /// The number at `key` in min..max [unit], or nothing when `key` is absent.
  std::optional<double> number(const toml::table& t, const char* key, double min, double max,
                               const char* unit) const {
    const toml::node* node = t.get(key);
    if (node == nullptr) return std::nullopt;
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

  // The set_* readers overwrite `field` only when `key` is given: a key left out keeps the
  // default of the config struct's member initialiser (include/mrroc/config/process_set.hpp).

  void set_number(const toml::table& t, const char* key, double& field, double min, double max,
                  const char* unit) const {
    if (const std::optional<double> v = number(t, key, min, max, unit)) field = *v;
  }

  /// A count, read as a number (a fraction is cut off).
  void set_count(const toml::table& t, const char* key, int& field, double min, double max,
                 const char* unit) const {
    if (const std::optional<double> v = number(t, key, min, max, unit))
      field = static_cast<int>(*v);
  }

  /// A period given in milliseconds, stored in seconds.
  void set_ms(const toml::table& t, const char* key, double& field_s, double min_ms,
              double max_ms) const {
    if (const std::optional<double> v = number(t, key, min_ms, max_ms, "ms")) field_s = *v / 1000.0;
  }

  void set_boolean(const toml::table& t, const char* key, bool& field) const {
    const toml::node* node = t.get(key);
    if (node == nullptr) return;
    if (!node->is_boolean()) fail(*node, fmt::format("'{}' must be true or false", key));
    field = **node->as_boolean();
  }

  void set_string(const toml::table& t, const char* key, const std::string& table_name,
                  std::string& field) const {
    if (t.get(key) != nullptr) field = string(t, key, table_name);
  }

  /// A path relative to the config file's folder (an empty string leaves `field` as it is).
  void set_path(const toml::table& t, const char* key, const std::string& table_name,
                fs::path& field) const {
    if (const std::string path = string(t, key, table_name, std::string{}); !path.empty())
      field = resolve(path);
  }

  /// `keys` plus the keys of ProcessOptions (every process' table accepts them).
  static std::vector<const char*> with_options(std::vector<const char*> keys) {
    for (const char* k : {"cpus", "priority", "stop_grace_s", "stop_signal", "host", "group",
                          "restart", "max_restarts", "restart_backoff_s", "required"})
      keys.push_back(k);
    return keys;
  }

  ProcessOptions options(const toml::table& t, const std::string& default_group) const {
    ProcessOptions o;
    o.group = default_group;
    set_number(t, "stop_grace_s", o.stop_grace_s, 0.0, 60.0, "s");
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
    if (const toml::node* h = t.get("host")) {
      o.host = string(t, "host", "");
      o.host_where = where(*h);
      if (o.host.empty())
        fail(*h, "'host' must not be empty (\"local\" or a [[launch.host]] name)");
    }
    set_string(t, "group", "", o.group);
    if (const toml::node* node = t.get("restart")) {
      const std::string restart = string(t, "restart", "");
      if (restart == "never")
        o.restart = RestartPolicy::never;
      else if (restart == "on-failure")
        o.restart = RestartPolicy::on_failure;
      else if (restart == "always")
        o.restart = RestartPolicy::always;
      else
        fail(*node,
             fmt::format("restart '{}' must be \"never\", \"on-failure\" or \"always\"", restart));
    }
    set_count(t, "max_restarts", o.max_restarts, 0, kMaxRestartsLimit, "restarts");
    set_number(t, "restart_backoff_s", o.restart_backoff_s, 0.0, 30.0, "s");
    if (o.restart_backoff_s < kMinRestartBackoffS)
      fail(*t.get("restart_backoff_s"),
           fmt::format("'restart_backoff_s' = {} s is below the minimum of {} s (a process that "
                       "keeps failing must not be restarted in a tight loop)",
                       o.restart_backoff_s, kMinRestartBackoffS));
    set_boolean(t, "required", o.required);
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
        if (const toml::array& arr = *node.as_array(); !arr.empty() && arr[0].is_array()) {
          std::vector<SourceLocation> rows;
          for (const auto& row : arr) rows.push_back(where(row));
          p.set_row_locations(k, std::move(rows));
        }
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
    c.name_where = where(*t.get("task"));
    set_path(t, "library", table_name, c.library);
    if (!c.library.empty()) require_path(*t.get("library"), c.library, Kind::any, "task library");
    c.args = table_params(t, "args", table_name + ".args");
    c.options = options(t, group);
    return c;
  }

  fs::path resolve(const std::string& path) const {
    fs::path p(path);
    if (p.is_relative()) p = file_.parent_path() / p;
    return p.lexically_normal();
  }

  // One reader per table of the process set (docs/configs.md).

  void system(const toml::table& root, ProcessSetConfig& config) const {
    const toml::table& t = table(root, "system", "");
    only_keys(t, "system", {"name", "lcm_url", "ready_timeout_s", "auth_key_file"});
    config.name = string(t, "name", "system");
    set_string(t, "lcm_url", "system", config.lcm_url);
    if (!config.lcm_url.empty() && config.lcm_url.find("://") == std::string::npos)
      fail(*t.get("lcm_url"),
           fmt::format("lcm_url '{}' is not a URL (expected e.g. udpm://239.255.76.67:7667?ttl=0)",
                       config.lcm_url));
    set_number(t, "ready_timeout_s", config.ready_timeout_s, 0.1, 600.0, "s");
    set_path(t, "auth_key_file", "system", config.auth_key_file);
    if (!config.auth_key_file.empty())
      require_path(*t.get("auth_key_file"), config.auth_key_file, Kind::file,
                   "authentication key file",
                   fmt::format(" (make it once: openssl rand -hex 32 > '{0}'; chmod 600 '{0}'; "
                               "the same file on every computer of the set)",
                               config.auth_key_file.string()));
  }

  /// [srp] (optional: `node` null).
  SrpConfig srp(const toml::node* node) const {
    SrpConfig c;
    if (node == nullptr) {
      c.options = options(toml::table{}, "srp");
      return c;
    }
    if (!node->is_table()) fail(*node, "'srp' must be a table");
    const toml::table& t = *node->as_table();
    only_keys(t, "srp", with_options({"log", "log_max_kb", "log_keep", "history"}));
    c.options = options(t, "srp");
    set_path(t, "log", "srp", c.log);
    set_number(t, "log_max_kb", c.log_max_kb, 1.0, 1e7, "KiB");
    set_count(t, "log_keep", c.log_keep, 0, 100, "files");
    set_count(t, "history", c.history, 10, 1e6, "messages");
    return c;
  }

  /// [ui] (optional: `node` null).
  UiConfig ui(const toml::node* node) const {
    UiConfig c;
    if (node == nullptr) {
      c.options = options(toml::table{}, "ui");
      return c;
    }
    if (!node->is_table()) fail(*node, "'ui' must be a table");
    const toml::table& t = *node->as_table();
    only_keys(t, "ui", with_options({"web", "bind", "port", "token_file", "teach_dir", "hosts"}));
    c.where = where(t);
    c.options = options(t, "ui");
    set_boolean(t, "web", c.web);
    set_string(t, "bind", "ui", c.bind);
    set_count(t, "port", c.port, 1, 65535, "(TCP port)");
    set_path(t, "token_file", "ui", c.token_file);
    if (!c.token_file.empty())
      require_path(*t.get("token_file"), c.token_file, Kind::file, "console token file");
    if (!is_loopback(c.bind) && c.token_file.empty())
      fail(*t.get("bind"), fmt::format("bind '{}' is not a loopback address: the console then "
                                       "needs 'token_file' (a file holding the access token)",
                                       c.bind));
    set_path(t, "teach_dir", "ui", c.teach_dir);
    if (const toml::node* hosts = t.get("hosts")) {
      const toml::array* arr = hosts->as_array();
      if (arr == nullptr || !arr->is_homogeneous(toml::node_type::string))
        fail(*hosts, "'hosts' must be a list of host names or addresses (e.g. [\"cell-pc\"])");
      for (const auto& h : *arr) {
        const std::string name = **h.as_string();
        in6_addr v6{};
        const bool ipv6 = inet_pton(AF_INET6, name.c_str(), &v6) == 1;
        if (name.empty() || (!ipv6 && name.find_first_of(" :/[]@") != std::string::npos))
          fail(h, fmt::format("host '{}' must be a name or an address, without port, scheme or "
                              "path (an IPv6 address without brackets)",
                              name));
        c.hosts.push_back(name);
      }
    }
    return c;
  }

  /// [launch] (optional: `node` null).
  LaunchConfig launch(const toml::node* node) const {
    LaunchConfig c;
    if (node == nullptr) return c;
    if (!node->is_table()) fail(*node, "'launch' must be a table");
    const toml::table& t = *node->as_table();
    only_keys(t, "launch", {"log_dir", "log_max_kb", "log_keep", "record", "host"});
    set_path(t, "log_dir", "launch", c.log_dir);
    set_number(t, "log_max_kb", c.log_max_kb, 1.0, 1e7, "KiB");
    set_count(t, "log_keep", c.log_keep, 0, 100, "files");
    set_path(t, "record", "launch", c.record);
    if (const toml::node* hosts = t.get("host")) {
      const toml::array* list = hosts->as_array();
      if (list == nullptr || !list->is_array_of_tables())
        fail(*hosts, "'launch.host' must be an array of tables ([[launch.host]])");
      std::set<std::string> host_names{"local"};
      for (const auto& entry : *list) {
        c.hosts.push_back(host(*entry.as_table(), host_names));
      }
    }
    return c;
  }

  /// One [[launch.host]]; `names`: the host names so far.
  HostConfig host(const toml::table& h, std::set<std::string>& names) const {
    only_keys(h, "launch.host", {"name", "command", "address", "quote"});
    HostConfig c;
    c.where = where(h);
    c.name = string(h, "name", "launch.host");
    if (!names.insert(c.name).second)
      fail(*h.get("name"),
           fmt::format("host name '{}' is used twice (\"local\" is reserved)", c.name));
    c.address = string(h, "address", "launch.host", c.name);
    if (!is_valid_host_address(c.address)) {
      const char* key = h.get("address") != nullptr ? "address" : "name";
      fail(*h.get(key),
           fmt::format("'{}' = '{}' is not a host address: a host name, an IPv4 or IPv6 address "
                       "(IPv6 also in brackets), user@ one of these or a network namespace name "
                       "(letters, digits, '.', '-', '_', not starting with '-'; no spaces or "
                       "shell characters)",
                       key, c.address));
    }
    if (const toml::node* cmd = h.get("command")) {
      const toml::array* words = cmd->as_array();
      if (words == nullptr || words->empty() || !words->is_homogeneous(toml::node_type::string))
        fail(*cmd,
             "'command' must be a non-empty list of strings, e.g. [\"ip\", \"netns\", "
             "\"exec\", \"{host}\"]");
      c.command.clear();
      for (const auto& w : *words) c.command.emplace_back(**w.as_string());
      c.quote = false;  // a command of one's own gets its words as they are, unless asked
    }
    const bool ssh = is_ssh_command(c.command);
    if (ssh) {
      if (const std::string option = ssh_option_without_input(c.command); !option.empty())
        fail(*h.get("command"),
             fmt::format("'command' gives ssh option -{}, which takes away the remote program's "
                         "input: the launcher stops a program on an ssh host by closing that "
                         "input",
                         option));
      c.quote = true;  // the remote shell reads the command line: always one quoted word
    }
    if (const toml::node* quote = h.get("quote")) {
      set_boolean(h, "quote", c.quote);
      if (ssh && !c.quote)
        fail(*quote,
             "'quote' = false does not go with an ssh command: the remote shell reads the "
             "command line, which is therefore always one shell-quoted word (leave 'quote' out)");
    }
    return c;
  }

  /// "n" or "f" when the ssh command line `command` gives option -n or -f (stdin from
  /// /dev/null) after its ssh word, else "". Options with an argument (-o X, -oX, -p 22, ...) are
  /// skipped; the scan ends at "--" or at the first word that is not an option.
  static std::string ssh_option_without_input(const std::vector<std::string>& command) {
    constexpr std::string_view with_argument = "BbcDEeFIiJLlmOoPpQRSWw";
    for (std::size_t i = ssh_word(command) + 1; i < command.size(); ++i) {
      const std::string& word = command[i];
      if (word == "--" || word.size() < 2 || word[0] != '-') break;
      for (std::size_t k = 1; k < word.size(); ++k) {
        if (word[k] == 'n' || word[k] == 'f') return std::string(1, word[k]);
        if (with_argument.find(word[k]) != std::string_view::npos) {
          if (k + 1 == word.size()) ++i;  // the argument is the next word
          break;
        }
      }
    }
    return {};
  }

  /// [emulator].
  EmulatorConfig emulator(const toml::node& node) const {
    if (!node.is_table()) fail(node, "'emulator' must be a table");
    const toml::table& t = *node.as_table();
    only_keys(t, "emulator", with_options({"scene", "lock_step", "faults"}));
    EmulatorConfig c;
    c.where = where(t);
    c.scene = resolve(string(t, "scene", "emulator"));
    require_path(*t.get("scene"), c.scene, Kind::file, "scene file");
    set_boolean(t, "lock_step", c.lock_step);
    if (const toml::node* faults = t.get("faults")) {
      const toml::array* arr = faults->as_array();
      if (arr == nullptr || !arr->is_homogeneous(toml::node_type::string))
        fail(*faults, "'faults' must be a list of strings (see mrroc-axis-emu --help)");
      for (const auto& f : *arr) c.faults.emplace_back(**f.as_string());
    }
    c.options = options(t, "emu");
    return c;
  }

  /// [[vsp]], every entry.
  std::vector<VspConfig> vsps(const toml::node& node) const {
    const toml::array* list = node.as_array();
    if (list == nullptr || !list->is_array_of_tables())
      fail(node, "'vsp' must be an array of tables ([[vsp]])");
    std::vector<VspConfig> out;
    std::set<std::string> names;
    for (const auto& entry : *list) out.push_back(vsp(*entry.as_table(), names));
    return out;
  }

  /// One [[vsp]]; `names`: the VSP names so far.
  VspConfig vsp(const toml::table& t, std::set<std::string>& names) const {
    only_keys(t, "vsp",
              with_options({"name", "plugin", "library", "sources", "mode", "period_ms",
                            "stale_after_ms", "params"}));
    VspConfig c;
    c.where = where(t);
    if (!guard([&] {
          c.name = string(t, "name", "vsp");
          if (!std::regex_match(c.name, process_name_re()))
            fail(*t.get("name"), fmt::format("VSP name '{}' must match [a-z][a-z0-9_]* and have at "
                                             "most 31 characters",
                                             c.name));
          if (!names.insert(c.name).second)
            fail(*t.get("name"), fmt::format("VSP name '{}' is used twice", c.name));
          c.plugin = string(t, "plugin", "vsp");
          c.plugin_where = where(*t.get("plugin"));
          set_path(t, "library", "vsp", c.library);
          if (!c.library.empty())
            require_path(*t.get("library"), c.library, Kind::any, "sensor plugin library");
          const toml::node* sources = t.get("sources");
          if (sources == nullptr)
            throw ConfigError(where(t),
                              fmt::format("missing key 'sources' in [[vsp]] '{}' (the raw "
                                          "sensor devices that feed it)",
                                          c.name));
          const toml::array* arr = sources->as_array();
          if (arr == nullptr || arr->empty() || !arr->is_homogeneous(toml::node_type::string))
            fail(*sources, "'sources' must be a non-empty list of raw sensor device names");
          for (const auto& s : *arr) c.sources.emplace_back(**s.as_string());
          if (const toml::node* node = t.get("mode")) {
            const std::string mode = string(t, "mode", "vsp");
            if (mode != "on_demand" && mode != "periodic")
              fail(*node, fmt::format("mode '{}' must be \"on_demand\" or \"periodic\"", mode));
            c.periodic = mode == "periodic";
          }
          set_ms(t, "period_ms", c.period_s, 1.0, 10000.0);
          set_ms(t, "stale_after_ms", c.stale_after_s, 1.0, 60000.0);
          c.params = table_params(t, "params", "vsp.params");
          c.options = options(t, "vsp");
        }))
      mark_broken("vsp/" + c.name);
    return c;
  }

  /// [mp].
  void mp(const toml::table& root, ProcessSetConfig& config) const {
    const toml::table& t = table(root, "mp", "");
    config.mp = task(t, "mp", "mp", {"start"});
    if (const toml::node* node = t.get("start")) {
      const std::string start = string(t, "start", "mp");
      if (start != "auto" && start != "operator")
        fail(*node,
             fmt::format(
                 "start '{}' must be \"auto\" or \"operator\" (wait for START from mrroc-ui)",
                 start));
      config.mp_waits_for_operator = start == "operator";
    }
  }

  /// [[robot]], every entry (at least one).
  std::vector<RobotConfig> robots(const toml::table& root) const {
    const toml::node* node = root.get("robot");
    if (node == nullptr)
      throw ConfigError(SourceLocation::whole_file(file_.string()), "no [[robot]] defined");
    const toml::array* list = node->as_array();
    if (list == nullptr || !list->is_array_of_tables())
      fail(*node, "'robot' must be an array of tables ([[robot]])");
    std::vector<RobotConfig> out;
    std::set<std::string> names;
    for (const auto& entry : *list) out.push_back(robot(*entry.as_table(), names));
    return out;
  }

  /// One [[robot]]; `names`: the robot names so far. Collecting, an error in the robot's own
  /// keys marks its EDP and ECP broken, one in [robot.edp] or [robot.ecp] that process only.
  RobotConfig robot(const toml::table& t, std::set<std::string>& names) const {
    only_keys(t, "robot", {"name", "model", "base", "edp", "ecp"});
    RobotConfig c;
    c.where = where(t);
    bool own = guard([&] {
      c.name = string(t, "name", "robot");
      if (!std::regex_match(c.name, process_name_re()))
        fail(*t.get("name"), fmt::format("robot name '{}' must match [a-z][a-z0-9_]* and have at "
                                         "most 31 characters",
                                         c.name));
      if (!names.insert(c.name).second)
        fail(*t.get("name"), fmt::format("robot name '{}' is used twice", c.name));
    });
    own = guard([&] {
            c.model_dir = resolve(string(t, "model", "robot"));
            require_path(*t.get("model"), c.model_dir, Kind::folder, "robot model folder");
          }) &&
          own;
    own = guard([&] {
            if (const toml::node* base = t.get("base")) {
              const toml::array* values = base->as_array();
              if (values == nullptr || values->size() != 6)
                fail(*base, "'base' must be [x, y, z, rx, ry, rz] (m, rotation vector in rad)");
              const std::vector<double> v = numbers(*values, "base");
              std::copy(v.begin(), v.end(), c.base.begin());
            }
          }) &&
          own;
    if (!guard([&] { c.edp = edp(table(t, "edp", "robot")); }) || !own)
      mark_broken("edp/" + c.name);
    if (!guard([&] { c.ecp = task(table(t, "ecp", "robot"), "robot.ecp", "ecp"); }) || !own)
      mark_broken("ecp/" + c.name);
    return c;
  }

  /// [robot.edp].
  EdpConfig edp(const toml::table& t) const {
    only_keys(t, "robot.edp",
              with_options({"plugin", "library", "servo_period_ms", "lookahead", "lock_step",
                            "safe_outputs", "kept_outputs", "unsynchronised_velocity_fraction",
                            "unsynchronised_acceleration_fraction", "unsynchronised_max_move",
                            "params"}));
    EdpConfig c;
    c.where = where(t);
    c.plugin = string(t, "plugin", "robot.edp");
    c.plugin_where = where(*t.get("plugin"));
    set_path(t, "library", "robot.edp", c.library);
    if (!c.library.empty())
      require_path(*t.get("library"), c.library, Kind::any, "hardware plugin library");
    set_ms(t, "servo_period_ms", c.servo_period_s, 0.1, 100.0);
    if (const toml::node* la = t.get("lookahead")) {
      if (!la->is_integer())
        fail(*la, fmt::format("'lookahead' must be an integer (macro-steps queued ahead of the "
                              "servo loop, 1..{})",
                              kMaxLookahead));
      const std::int64_t v = **la->as_integer();
      if (v < 1 || v > kMaxLookahead)
        fail(*la, fmt::format("'lookahead' = {} macro-steps is outside 1..{} (1: the paper's "
                              "one successor)",
                              v, kMaxLookahead));
      c.lookahead = static_cast<int>(v);
    }
    set_boolean(t, "lock_step", c.lock_step);
    set_output_mask(t, "safe_outputs", c.safe_outputs,
                    "the state of each binary output line during an emergency stop");
    set_output_mask(t, "kept_outputs", c.kept_outputs,
                    "the binary output lines an emergency stop leaves as they are");
    set_fraction(t, "unsynchronised_velocity_fraction", c.unsynchronised_velocity_fraction,
                 "every joint's max_joint_velocity, kept to before SYNCHRO");
    set_fraction(t, "unsynchronised_acceleration_fraction", c.unsynchronised_acceleration_fraction,
                 "every joint's max_joint_acceleration, kept to before SYNCHRO");
    set_number(t, "unsynchronised_max_move", c.unsynchronised_max_move, 0.001, 1.0, "rad (or m)");
    c.params = table_params(t, "params", "robot.edp.params");
    c.options = options(t, "edp");
    return c;
  }

  /// A fraction (0.01..1) of `of` at `key`, when given.
  void set_fraction(const toml::table& t, const char* key, double& field, const char* of) const {
    const toml::node* n = t.get(key);
    if (n == nullptr) return;
    if (!n->is_number()) fail(*n, fmt::format("'{}' must be a number: a fraction of {}", key, of));
    const double v =
        n->is_integer() ? static_cast<double>(**n->as_integer()) : **n->as_floating_point();
    if (!(v >= 0.01 && v <= 1.0))
      fail(*n, fmt::format("'{}' = {} is outside 0.01..1 (a fraction of {})", key, v, of));
    field = v;
  }

  /// A mask of binary output lines (bit i = line i, 0..0xFFFFFFFF) at `key`, when given.
  void set_output_mask(const toml::table& t, const char* key, std::uint32_t& out,
                       const char* what) const {
    const toml::node* n = t.get(key);
    if (n == nullptr) return;
    if (!n->is_integer())
      fail(*n, fmt::format("'{}' must be an integer: {}, bit i = line i (e.g. 0x5 for lines 0 "
                           "and 2)",
                           key, what));
    const std::int64_t v = **n->as_integer();
    if (v < 0 || v > 0xFFFFFFFFLL)
      fail(*n,
           fmt::format("'{}' = {:#x} is outside 0..0xffffffff ({}, bit i = line i)", key, v, what));
    out = static_cast<std::uint32_t>(v);
  }

  /// The parameters at `key` of `t` (a table), located at `t` when there are none.
  Params table_params(const toml::table& t, const char* key, const std::string& table_name) const {
    const toml::node* node = t.get(key);
    if (node == nullptr) return Params(where(t));
    if (!node->is_table()) fail(*node, fmt::format("'{}' must be a table", key));
    return params(*node->as_table(), table_name);
  }

  /// Names of robots and VSPs: they are parts of process and channel names (LCM channel names are
  /// at most 63 characters).
  static const std::regex& process_name_re() {
    static const std::regex re("[a-z][a-z0-9_]{0,30}");
    return re;
  }

 private:
  fs::path file_;
  ConfigErrorList* sink_;
  std::set<std::string>* broken_;
};

}  // namespace

bool is_loopback(std::string_view host) {
  if (host == "localhost") return true;
  const std::string text(host);
  in_addr v4{};
  if (inet_pton(AF_INET, text.c_str(), &v4) == 1) return (ntohl(v4.s_addr) >> 24) == 127;
  in6_addr v6{};
  return inet_pton(AF_INET6, text.c_str(), &v6) == 1 && IN6_IS_ADDR_LOOPBACK(&v6);
}

std::size_t ssh_word(const std::vector<std::string>& command) {
  for (std::size_t i = 0; i < command.size(); ++i) {
    const std::string& word = command[i];
    const std::size_t slash = word.rfind('/');
    if (std::string_view(word).substr(slash == std::string::npos ? 0 : slash + 1) == "ssh")
      return i;
  }
  return command.size();
}

bool is_ssh_command(const std::vector<std::string>& command) {
  return ssh_word(command) < command.size();
}

bool is_valid_host_address(std::string_view address) {
  auto plain = [](std::string_view text) {  // host name, IPv4 address, namespace or user name
    return !text.empty() && text.front() != '-' &&
           std::all_of(text.begin(), text.end(), [](char ch) {
             return (ch >= 'a' && ch <= 'z') || (ch >= 'A' && ch <= 'Z') ||
                    (ch >= '0' && ch <= '9') || ch == '.' || ch == '-' || ch == '_';
           });
  };
  auto ipv6 = [&](std::string_view text) {  // with an optional %zone (an interface name)
    const std::size_t percent = text.find('%');
    if (percent != std::string_view::npos && !plain(text.substr(percent + 1))) return false;
    const std::string bare(text.substr(0, percent));
    in6_addr v6{};
    return inet_pton(AF_INET6, bare.c_str(), &v6) == 1;
  };
  std::string_view host = address;
  if (const std::size_t at = address.find('@'); at != std::string_view::npos) {
    if (!plain(address.substr(0, at))) return false;
    host = address.substr(at + 1);
  }
  if (host.size() >= 2 && host.front() == '[' && host.back() == ']')
    return ipv6(host.substr(1, host.size() - 2));
  if (host.find(':') != std::string_view::npos) return ipv6(host);
  return plain(host);
}

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
    throw ConfigError(SourceLocation{origin, static_cast<int>(e.source().begin.line)},
                      std::string(e.description()));
  }
}

const VspConfig& ProcessSetConfig::vsp(const std::string& vsp_name) const {
  std::string known;
  for (const auto& v : vsps) {
    if (v.name == vsp_name) return v;
    known += (known.empty() ? "" : ", ") + v.name;
  }
  throw ConfigError(
      SourceLocation::whole_file(file.string()),
      fmt::format("no [[vsp]] named '{}' (known: {})", vsp_name, known.empty() ? "none" : known));
}

const RobotConfig& ProcessSetConfig::robot(const std::string& robot_name) const {
  for (const auto& r : robots)
    if (r.name == robot_name) return r;
  std::string known;
  for (const auto& r : robots) known += (known.empty() ? "" : ", ") + r.name;
  throw ConfigError(
      SourceLocation::whole_file(file.string()),
      fmt::format("no robot named '{}' (robots: {})", robot_name, known.empty() ? "none" : known));
}

namespace {

/// Validates a parsed process-set file; `file` is its absolute path.
void check_hosts(const ProcessSetConfig& config) {
  auto check = [&](const ProcessOptions& o, const std::string& process) {
    if (o.host == "local") return;
    for (const auto& h : config.launch.hosts)
      if (h.name == o.host) return;
    throw ConfigError(
        o.host_where.known() ? o.host_where : SourceLocation::whole_file(config.file.string()),
        fmt::format("{} runs on host '{}', which is not a [[launch.host]] (hosts: local{})",
                    process, o.host, [&] {
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

/// Reads the tables of `root`; `sink` and `broken` as for Reader (null: throw at the first error).
ProcessSetConfig process_set_from_table(const toml::table& root, const fs::path& file,
                                        ConfigErrorList* sink = nullptr,
                                        std::set<std::string>* broken = nullptr) {
  ProcessSetConfig config;
  config.file = file;
  const Reader r(config.file, sink, broken);
  r.only_keys(root, "top level",
              {"system", "srp", "emulator", "vsp", "mp", "robot", "ui", "launch", "collision"});
  r.guard([&] { r.system(root, config); });
  r.guard([&] { config.srp = r.srp(root.get("srp")); });
  r.guard([&] { config.ui = r.ui(root.get("ui")); });
  r.guard([&] { config.launch = r.launch(root.get("launch")); });
  if (const toml::node* emu = root.get("emulator"))
    if (!r.guard([&] { config.emulator = r.emulator(*emu); })) r.mark_broken("emu");
  if (const toml::node* vsps = root.get("vsp")) r.guard([&] { config.vsps = r.vsps(*vsps); });
  if (!r.guard([&] { r.mp(root, config); })) r.mark_broken("mp");
  r.guard([&] { config.robots = r.robots(root); });
  r.guard([&] {
    std::vector<std::string> robot_names;
    for (const RobotConfig& robot : config.robots) robot_names.push_back(robot.name);
    config.collision = config_detail::read_collision(root.get("collision"), file, robot_names);
  });
  r.guard([&] { check_hosts(config); });
  return config;
}

[[noreturn]] void throw_parse_error(const fs::path& file, const toml::parse_error& e) {
  throw ConfigError(SourceLocation{file.string(), static_cast<int>(e.source().begin.line)},
                    std::string(e.description()));
}

}  // namespace

ProcessSetConfig load_process_set(const fs::path& path) {
  if (std::error_code ec; !fs::exists(path, ec))
    throw ConfigError(
        SourceLocation::whole_file(path.string()),
        fmt::format("config file not found{}", ec ? " (" + ec.message() + ")" : std::string{}));
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

namespace mrroc {

namespace {

ProcessSetCheck check_parsed(const std::function<toml::table()>& parse, const fs::path& file) {
  ProcessSetCheck out;
  out.config.file = file;
  ConfigErrorList errors;
  toml::table root;
  try {
    root = parse();
  } catch (const toml::parse_error& e) {
    out.errors.emplace_back(SourceLocation{file.string(), static_cast<int>(e.source().begin.line)},
                            std::string(e.description()));
    return out;
  }
  out.config = process_set_from_table(root, file, &errors, &out.broken);
  out.errors = errors.errors();
  return out;
}

}  // namespace

ProcessSetCheck check_process_set(const fs::path& path) {
  if (std::error_code ec; !fs::exists(path, ec)) {
    ProcessSetCheck out;
    out.config.file = path;
    out.errors.emplace_back(
        SourceLocation::whole_file(path.string()),
        fmt::format("config file not found{}", ec ? " (" + ec.message() + ")" : std::string{}));
    return out;
  }
  const fs::path file = fs::absolute(path).lexically_normal();
  return check_parsed([&] { return toml::parse_file(file.string()); }, file);
}

ProcessSetCheck check_process_set_text(std::string_view text, const fs::path& path) {
  const fs::path file = fs::absolute(path).lexically_normal();
  return check_parsed([&] { return toml::parse(text, file.string()); }, file);
}

}  // namespace mrroc
