#include "launch_plan.hpp"

#include <signal.h>
#include <string.h>

#include <algorithm>
#include <cmath>

#include <fmt/format.h>

#include "mrroc/comm/bus.hpp"
#include "mrroc/core/error.hpp"

namespace mrroc::launch {

namespace fs = std::filesystem;

bool declares_real_devices(std::string_view declaration) {
  constexpr std::string_view real = " drives real devices";
  return declaration.size() >= real.size() &&
         declaration.substr(declaration.size() - real.size()) == real;
}

std::string shell_quote(std::string_view word) {
  const bool safe = !word.empty() && std::all_of(word.begin(), word.end(), [](char ch) {
    return (ch >= 'a' && ch <= 'z') || (ch >= 'A' && ch <= 'Z') || (ch >= '0' && ch <= '9') ||
           std::string_view("_-./:=@%+,").find(ch) != std::string_view::npos;
  });
  if (safe) return std::string(word);
  std::string out = "'";
  for (const char ch : word) {
    if (ch == '\'') {
      out += "'\\''";
    } else {
      out += ch;
    }
  }
  out += '\'';
  return out;
}

std::string_view remote_stop_script() {
  // One line (it is shown in `mrroc-launch --check`). Arguments: SIGNAL GRACE PROGRAM ARGS...
  // The script's own stdin moves to descriptor 3 for the watcher; the program gets /dev/null.
  // Both the script and the watcher catch SIGNAL (which the watcher sends to the whole process
  // group) so that they live on: the script to return the program's status, the watcher to
  // send SIGKILL after GRACE. A program that ends by itself ends the watcher.
  return "s=$1 g=$2; shift 2; trap : \"$s\"; exec 3<&0 </dev/null; "
         "{ trap : \"$s\"; while read -r _ <&3; do :; done; kill -s \"$s\" 0; sleep \"$g\"; "
         "kill -s KILL 0; } >/dev/null 2>&1 & w=$!; exec 3<&-; \"$@\"; r=$?; "
         "kill -s KILL \"$w\" 2>/dev/null; exit \"$r\"";
}

std::vector<std::string> host_command(const HostConfig& host, const std::vector<std::string>& env,
                                      const std::vector<std::string>& command,
                                      const RemoteStop& stop) {
  // ssh in any word: a wrapper in front of it (sudo, env) does not change what ssh does.
  const std::size_t ssh_at = ssh_word(host.command);
  const bool ssh = ssh_at < host.command.size();
  // ssh: "--" before the destination (the last word with "{host}" after ssh's), unless ssh's
  // words have one.
  std::size_t destination = host.command.size();
  const auto ssh_words = host.command.begin() + static_cast<std::ptrdiff_t>(ssh ? ssh_at : 0);
  if (ssh && std::find(ssh_words, host.command.end(), "--") == host.command.end())
    for (std::size_t i = ssh_at + 1; i < host.command.size(); ++i)
      if (host.command[i].find("{host}") != std::string::npos) destination = i;
  std::vector<std::string> argv;
  for (std::size_t i = 0; i < host.command.size(); ++i) {
    std::string word = host.command[i];
    for (std::size_t at = word.find("{host}"); at != std::string::npos;
         at = word.find("{host}", at + host.address.size()))
      word.replace(at, 6, host.address);
    if (i == destination) argv.emplace_back("--");
    argv.push_back(std::move(word));
  }
  std::vector<std::string> inner;
  if (ssh) {
    const char* abbrev = ::sigabbrev_np(stop.signal);
    // exec: the login shell must not stay in the process group the script signals.
    inner = {"exec",
             "sh",
             "-c",
             std::string(remote_stop_script()),
             "mrroc-remote",
             abbrev != nullptr ? abbrev : std::to_string(stop.signal),
             std::to_string(std::lround(std::ceil(std::max(stop.grace_s, 0.0))))};
  }
  if (!env.empty()) {
    inner.emplace_back("env");
    inner.insert(inner.end(), env.begin(), env.end());
  }
  inner.insert(inner.end(), command.begin(), command.end());
  if (ssh || host.quote) {
    std::string line;
    for (const auto& w : inner) line += (line.empty() ? "" : " ") + shell_quote(w);
    argv.push_back(std::move(line));
  } else {
    argv.insert(argv.end(), inner.begin(), inner.end());
  }
  return argv;
}

fs::path log_file_of(const fs::path& log_dir, const std::string& name) {
  std::string file = name;
  std::replace(file.begin(), file.end(), '/', '_');
  return log_dir / (file + ".log");
}

int lcm_url_ttl(const std::string& url) {
  const std::size_t query = url.find('?');
  if (query == std::string::npos) return 0;
  std::size_t at = query + 1;
  while (at < url.size()) {
    std::size_t end = url.find('&', at);
    if (end == std::string::npos) end = url.size();
    const std::string_view item = std::string_view(url).substr(at, end - at);
    if (item.rfind("ttl=", 0) == 0) {
      int ttl = 0;
      const std::string_view digits = item.substr(4);
      for (const char ch : digits) {
        if (ch < '0' || ch > '9') return 1;  // not a number LCM reads: assume it leaves the host
        ttl = std::min(ttl * 10 + (ch - '0'), 255);
      }
      return ttl;
    }
    at = end + 1;
  }
  return 0;
}

std::string unprotected_network_warning(const ProcessSetConfig& config) {
  if (!config.auth_key_file.empty()) return {};
  const std::string url = comm::resolve_lcm_url(config.lcm_url);
  const int ttl = lcm_url_ttl(url);
  std::vector<std::string> reasons;
  if (ttl > 0)
    reasons.push_back(
        fmt::format("its LCM URL {} has ttl={} (its messages leave this computer)", url, ttl));
  if (!config.launch.hosts.empty()) {
    std::string names;
    for (const auto& h : config.launch.hosts) names += (names.empty() ? "" : ", ") + h.name;
    reasons.push_back(
        fmt::format("it runs processes on other computers ([[launch.host]] {})", names));
  }
  if (reasons.empty()) return {};
  std::string why = reasons[0];
  if (reasons.size() > 1) why += " and " + reasons[1];
  return fmt::format(
      "warning: set '{}' ({}) has no [system] auth_key_file, but {}: anyone on that network can "
      "start and stop its task, move its robots, release an emergency stop and forge their "
      "states. Give it a key: openssl rand -hex 32 > set.key; chmod 600 set.key; auth_key_file "
      "= \"set.key\" in [system] (docs/configs.md)",
      config.name, config.file.string(), why);
}

std::string signal_text(int signal) {
  if (const char* abbrev = ::sigabbrev_np(signal)) return fmt::format("SIG{}", abbrev);
  return fmt::format("signal {}", signal);
}

std::vector<PlannedProcess> make_plan(const ProcessSetConfig& config, const PlanOptions& options) {
  const std::string cfg = config.file.string();
  auto exe = [&](const char* name) { return (options.bin_dir / name).string(); };
  std::vector<PlannedProcess> plan;
  auto add = [&](std::string name, const ProcessOptions& o, std::vector<std::string> command) {
    PlannedProcess p;
    p.name = std::move(name);
    p.group = o.group;
    p.host = o.host;
    p.options = o;
    p.command = std::move(command);
    plan.push_back(std::move(p));
  };

  const fs::path record = !options.record.empty() ? options.record : config.launch.record;
  if (!record.empty()) {
    ProcessOptions o;
    o.group = "record";
    o.required = false;
    o.stop_signal = SIGINT;
    o.stop_grace_s = 5.0;
    add("record", o,
        {"lcm-logger", "--lcm-url=" + comm::resolve_lcm_url(config.lcm_url), "--force", "--quiet",
         record.string()});
    plan.back().reports_ready = false;
  }
  std::vector<std::string> srp{exe("mrroc-srp"), "--config", cfg};
  if (!options.srp_log.empty()) {
    srp.emplace_back("--log");
    srp.push_back(options.srp_log);
  }
  add("srp", config.srp.options, srp);
  if (config.emulator)
    add("emu", config.emulator->options, {exe("mrroc-axis-emu"), "--config", cfg});
  for (const auto& v : config.vsps)
    add("vsp/" + v.name, v.options, {exe("mrroc-vsp"), "--config", cfg, "--vsp", v.name});
  for (const auto& r : config.robots) {
    add("edp/" + r.name, r.edp.options, {exe("mrroc-edp"), "--config", cfg, "--robot", r.name});
    plan.back().edp = true;
  }
  for (const auto& r : config.robots)
    add("ecp/" + r.name, r.ecp.options, {exe("mrroc-ecp"), "--config", cfg, "--robot", r.name});
  if (config.ui.web) add("ui", config.ui.options, {exe("mrroc-ui"), "serve", "--config", cfg});
  add("mp", config.mp.options, {exe("mrroc-mp"), "--config", cfg});

  for (auto& p : plan) {
    ChildSpec& s = p.spec;
    s.name = p.name;
    s.stop_grace = std::chrono::milliseconds(std::lround(p.options.stop_grace_s * 1000.0));
    s.stop_signal = p.options.stop_signal;
    if (!config.launch.log_dir.empty()) {
      s.log_file = log_file_of(config.launch.log_dir, p.name);
      s.log_max_bytes =
          static_cast<std::uintmax_t>(std::llround(config.launch.log_max_kb * 1024.0));
      s.log_keep = config.launch.log_keep;
    }
    if (p.host == "local") {
      s.argv = p.command;
      if (!config.lcm_url.empty()) s.env.push_back("LCM_DEFAULT_URL=" + config.lcm_url);
      continue;
    }
    const auto host = std::find_if(config.launch.hosts.begin(), config.launch.hosts.end(),
                                   [&](const HostConfig& h) { return h.name == p.host; });
    if (host == config.launch.hosts.end())
      throw ConfigError(
          SourceLocation::whole_file(cfg),
          fmt::format("{} runs on host '{}', which is not a [[launch.host]]", p.name, p.host));
    // ssh passes no environment: it travels in the command line. Through ssh the launcher
    // stops a process by closing its input; the remote side then sends the stop signal.
    s.argv = host_command(*host, {"LCM_DEFAULT_URL=" + comm::resolve_lcm_url(config.lcm_url)},
                          p.command, RemoteStop{p.options.stop_signal, p.options.stop_grace_s});
    s.stop_by_closing_input = is_ssh_command(host->command);
  }
  return plan;
}

}  // namespace mrroc::launch
