#pragma once
// The web operator console (`mrroc-ui serve`): an HTTP server with a JSON API and the page of
// ui/web/ (docs/operating.md). It composes the parts of ui/console/: the state (state.hpp) fed
// from the bus (bus_feed.hpp), the HTTP API (http_api.hpp), jogging (jog.hpp, through
// edp_jog_link.hpp) and teach-in (teach_in.hpp); itself it sends the operator commands and the
// emergency stops and reports to the SRP as process "ui".

#include <filesystem>
#include <memory>
#include <string>

#include "console/jog.hpp"
#include "mrroc/config/process_set.hpp"

namespace mrroc::ui {

/// How `mrroc-ui serve` runs the console; the rest comes from the set's [ui] table (where
/// teach-in files go, the token file).
struct ConsoleOptions {
  std::string bind = UiConfig{}.bind;
  int port = UiConfig{}.port;
  /// Every /api request must carry it (header `Authorization: Bearer TOKEN` or `?token=`): the
  /// token of [ui] token_file. Empty: the console generates one at start (generate_token), prints
  /// the page's URL with it on standard output and writes it to generated_token_file() until it
  /// ends.
  std::string token;
  JogOptions jog;
};

class Console {
 public:
  /// Opens the bus, subscribes and loads the robots' models. @throws Error, ConfigError.
  Console(const ProcessSetConfig& config, ConsoleOptions options);
  ~Console();
  Console(const Console&) = delete;
  Console& operator=(const Console&) = delete;

  /// Binds, writes a generated token's file, reports READY as process "ui", prints the URL,
  /// serves until SIGINT/SIGTERM (stop_requested()), removes the token's file.
  /// @returns the process' exit code; @throws Error naming the address when it cannot bind.
  int run();

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace mrroc::ui
