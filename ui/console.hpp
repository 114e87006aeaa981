#pragma once
// The web operator console (`mrroc-ui serve`): an HTTP server with a JSON API and the page of
// ui/web/ (docs/operating.md). It listens to the set's status, SRP messages, robot states and
// the launcher's process table, polls the MP's state, and sends operator commands, emergency
// stops, jog motions (to the EDP) and records taught poses.

#include <filesystem>
#include <map>
#include <memory>
#include <string>
#include <string_view>

#include "mrroc/config/process_set.hpp"

namespace mrroc::ui {

/// The page's files (ui/web/), embedded at build time (generated web_assets.cpp).
const std::map<std::string, std::string_view>& web_assets();

struct ConsoleOptions {
  std::string bind = "127.0.0.1";
  int port = 8080;
  /// Every /api request must carry it (header `Authorization: Bearer TOKEN`); empty: none.
  std::string token;
  std::filesystem::path teach_dir;  ///< where "Record pose" writes; empty: current folder
  double jog_max_step_rad = 0.2;    ///< largest jog step accepted [rad]
  /// A jog stays within this fraction of the axis' velocity and acceleration limits.
  double jog_velocity_fraction = 0.25;
};

/// Reads the token file: its first line without surrounding blanks, at least 16 characters.
/// @throws Error naming the file when it cannot be read or the token is too short.
std::string read_token_file(const std::filesystem::path& file);

class Console {
 public:
  /// Opens the bus, subscribes and loads the robots' models. @throws Error, ConfigError.
  Console(const ProcessSetConfig& config, ConsoleOptions options);
  ~Console();
  Console(const Console&) = delete;
  Console& operator=(const Console&) = delete;

  /// Binds, reports READY as process "ui", serves until SIGINT/SIGTERM (stop_requested()).
  /// @returns the process' exit code; @throws Error naming the address when it cannot bind.
  int run();

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace mrroc::ui
