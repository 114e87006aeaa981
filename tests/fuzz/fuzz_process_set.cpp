// The process-set config parser (mrroc::parse_process_set, the validation load_process_set runs on
// a file's content). The input is the file's content; the file is named as if it lay in configs/
// of the source tree, so that the real robot models (../robots/<name>) resolve.
//
// Properties (docs/fuzzing.md):
// - the only exception is ConfigError, reading "<file>:<line>: error: " with line >= 1 (the one
//   whole-file error, "<file>: error: no [[robot]] defined", has no line);
// - an accepted file holds what the schema promises: at least one robot; robot and VSP names
//   unique and [a-z][a-z0-9_]{0,30}; model folders, libraries and the emulator's scene that
//   exist; VSPs with sources; periods, timeouts and grace periods in range; CPUs >= 0; every table
//   and parameter located in the file at a line >= 1; robot(name) and vsp(name) find each one and
//   throw ConfigError for an unknown name;
// - parsing is deterministic.
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <optional>
#include <regex>
#include <set>
#include <string>
#include <string_view>

#include "fuzz_common.hpp"
#include "mrroc/config/process_set.hpp"

namespace {

namespace fs = std::filesystem;

const fs::path& config_file() {
  static const fs::path file =
      fs::path(MRROC_SOURCE_DIR) / "configs" / "fuzz-input-does-not-exist.toml";
  return file;
}

void check_error(const mrroc::ConfigError& e) {
  const std::string file = config_file().lexically_normal().string();
  const std::string_view text = e.what();
  if (text == file + ": error: no [[robot]] defined") return;
  fuzz::expect(
      fuzz::has_location_prefix(text, file),
      fmt::format("ConfigError without '{}:<line>: error: ': {}", file, fuzz::escaped(text)));
}

void check_params(const mrroc::Params& p, const std::string& file, const char* table) {
  fuzz::expect(p.location().file == file && p.location().line >= 1,
               fmt::format("[{}] located at {}", table, p.location().str()));
  for (const auto& [key, value] : p.values()) {
    const mrroc::SourceLocation at = p.location_of(key);
    fuzz::expect(at.file == file && at.line >= 1,
                 fmt::format("[{}] key {} located at {}", table, fuzz::escaped(key), at.str()));
  }
  fuzz::expect(p.unread_keys().size() == p.values().size(), "a fresh Params has read keys");
}

void check_options(const mrroc::ProcessOptions& o, const char* table) {
  fuzz::expect(o.stop_grace_s >= 0.0 && o.stop_grace_s <= 60.0,
               fmt::format("[{}] stop_grace_s {} outside 0..60", table, o.stop_grace_s));
  for (const int cpu : o.cpus)
    fuzz::expect(cpu >= 0, fmt::format("[{}] negative CPU {} accepted", table, cpu));
  fuzz::expect(o.stop_signal >= 1 && o.stop_signal <= 64,
               fmt::format("[{}] stop_signal {} accepted", table, o.stop_signal));
  fuzz::expect(o.max_restarts >= 0 && o.max_restarts <= 1000,
               fmt::format("[{}] max_restarts {} outside 0..1000", table, o.max_restarts));
  fuzz::expect(o.restart_backoff_s >= 0.0 && o.restart_backoff_s <= 30.0,
               fmt::format("[{}] restart_backoff_s {} outside 0..30", table, o.restart_backoff_s));
  fuzz::expect(!o.host.empty(), fmt::format("[{}] empty host accepted", table));
}

void check_task(const mrroc::TaskConfig& t, const std::string& file, const char* table) {
  fuzz::expect(t.where.file == file && t.where.line >= 1,
               fmt::format("[{}] located at {}", table, t.where.str()));
  fuzz::expect(t.library.empty() || fs::exists(t.library),
               fmt::format("[{}] library {} accepted but missing", table, t.library.string()));
  check_params(t.args, file, table);
  check_options(t.options, table);
}

void check_vsps(const mrroc::ProcessSetConfig& c, const std::string& file) {
  static const std::regex name_re("[a-z][a-z0-9_]{0,30}");
  std::set<std::string> names;
  for (const auto& v : c.vsps) {
    fuzz::expect(std::regex_match(v.name, name_re),
                 fmt::format("VSP name {} accepted", fuzz::escaped(v.name)));
    fuzz::expect(names.insert(v.name).second, fmt::format("VSP name {} twice", v.name));
    fuzz::expect(v.where.file == file && v.where.line >= 1, "[[vsp]] not located");
    fuzz::expect(v.library.empty() || fs::exists(v.library),
                 "sensor plugin library accepted but missing");
    fuzz::expect(!v.sources.empty(), fmt::format("VSP {} without sources accepted", v.name));
    fuzz::expect(v.period_s >= 0.001 && v.period_s <= 10.0,
                 fmt::format("VSP period {} s accepted", v.period_s));
    fuzz::expect(v.stale_after_s >= 0.001 && v.stale_after_s <= 60.0,
                 fmt::format("VSP stale_after {} s accepted", v.stale_after_s));
    check_params(v.params, file, "vsp.params");
    check_options(v.options, "vsp");
    const mrroc::VspConfig* found = nullptr;
    fuzz::no_throw("ProcessSetConfig::vsp", [&] { found = &c.vsp(v.name); });
    fuzz::expect(found == &v, "vsp(name) returns another VSP");
  }
  bool unknown_refused = false;
  fuzz::guarded<mrroc::ConfigError>(
      "ProcessSetConfig::vsp (unknown name)", [&] { (void)c.vsp("no such vsp"); },
      [&](const mrroc::ConfigError&) { unknown_refused = true; });
  fuzz::expect(unknown_refused, "vsp() of an unknown name did not throw ConfigError");
}

std::string summary(const mrroc::ProcessSetConfig& c) {
  std::string out = fmt::format("{} {} {} {} {}", c.name, c.lcm_url, c.ready_timeout_s, c.mp.name,
                                c.robots.size());
  for (const auto& r : c.robots)
    out += fmt::format(" {} {} {} {} {} {}", r.name, r.model_dir.string(), r.edp.plugin,
                       r.edp.servo_period_s, r.ecp.name, r.edp.params.values().size());
  for (const auto& v : c.vsps)
    out += fmt::format(" {} {} {} {} {}", v.name, v.plugin, v.sources.size(), v.period_s,
                       v.stale_after_s);
  if (c.emulator) out += " " + c.emulator->scene.string();
  return out;
}

void check_config(const mrroc::ProcessSetConfig& c) {
  const std::string file = config_file().lexically_normal().string();
  fuzz::expect(c.file.string() == file, "config.file is not the file parsed");
  fuzz::expect(c.lcm_url.empty() || c.lcm_url.find("://") != std::string::npos,
               fmt::format("lcm_url {} accepted", fuzz::escaped(c.lcm_url)));
  fuzz::expect(c.ready_timeout_s >= 0.1 && c.ready_timeout_s <= 600.0,
               fmt::format("ready_timeout_s {} accepted", c.ready_timeout_s));
  check_task(c.mp, file, "mp");
  check_options(c.srp.options, "srp");
  fuzz::expect(c.srp.log_keep >= 0 && c.srp.log_keep <= 100 && c.srp.history >= 10 &&
                   c.srp.history <= 1000000,
               fmt::format("[srp] log_keep {} history {} accepted", c.srp.log_keep, c.srp.history));
  fuzz::expect(c.ui.port >= 1 && c.ui.port <= 65535,
               fmt::format("[ui] port {} accepted", c.ui.port));
  if (c.emulator) {
    fuzz::expect(fs::is_regular_file(c.emulator->scene),
                 fmt::format("emulator scene {} accepted", c.emulator->scene.string()));
    fuzz::expect(c.emulator->where.file == file && c.emulator->where.line >= 1,
                 "[emulator] not located");
    check_options(c.emulator->options, "emulator");
  }
  check_vsps(c, file);
  fuzz::expect(!c.robots.empty(), "a process set without robots accepted");
  static const std::regex name_re("[a-z][a-z0-9_]{0,30}");
  std::set<std::string> names;
  for (const auto& r : c.robots) {
    fuzz::expect(std::regex_match(r.name, name_re),
                 fmt::format("robot name {} accepted", fuzz::escaped(r.name)));
    fuzz::expect(names.insert(r.name).second, fmt::format("robot name {} twice", r.name));
    fuzz::expect(r.model_dir.is_absolute() && fs::is_directory(r.model_dir),
                 fmt::format("robot model folder {} accepted", r.model_dir.string()));
    fuzz::expect(r.where.file == file && r.where.line >= 1, "[[robot]] not located");
    fuzz::expect(r.edp.servo_period_s >= 0.0001 && r.edp.servo_period_s <= 0.1,
                 fmt::format("servo period {} s accepted", r.edp.servo_period_s));
    fuzz::expect(r.edp.library.empty() || fs::exists(r.edp.library),
                 "hardware plugin library accepted but missing");
    fuzz::expect(r.edp.where.file == file && r.edp.where.line >= 1, "[robot.edp] not located");
    check_params(r.edp.params, file, "robot.edp.params");
    check_options(r.edp.options, "robot.edp");
    check_task(r.ecp, file, "robot.ecp");
    const mrroc::RobotConfig* found = nullptr;
    fuzz::no_throw("ProcessSetConfig::robot", [&] { found = &c.robot(r.name); });
    fuzz::expect(found == &r, "robot(name) returns another robot");
  }
  bool unknown_refused = false;
  fuzz::guarded<mrroc::ConfigError>(
      "ProcessSetConfig::robot (unknown name)", [&] { (void)c.robot("no such robot"); },
      [&](const mrroc::ConfigError&) { unknown_refused = true; });
  fuzz::expect(unknown_refused, "robot() of an unknown name did not throw ConfigError");
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string_view text(reinterpret_cast<const char*>(data), size);
  std::optional<mrroc::ProcessSetConfig> config;
  std::string first_error;
  fuzz::guarded<mrroc::ConfigError>(
      "parse_process_set", [&] { config = mrroc::parse_process_set(text, config_file()); },
      [&](const mrroc::ConfigError& e) {
        check_error(e);
        first_error = e.what();
      });
  // Deterministic: the same text gives the same result.
  std::optional<mrroc::ProcessSetConfig> again;
  std::string second_error;
  fuzz::guarded<mrroc::ConfigError>(
      "parse_process_set (again)", [&] { again = mrroc::parse_process_set(text, config_file()); },
      [&](const mrroc::ConfigError& e) { second_error = e.what(); });
  fuzz::expect(config.has_value() == again.has_value() && first_error == second_error,
               "parsing the same text twice gave different results");
  if (!config) return 0;
  check_config(*config);
  fuzz::expect(summary(*config) == summary(*again),
               "parsing the same text twice gave different configs");
  return 0;
}
