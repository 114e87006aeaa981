// mrroc-ui: operator interface. The shell answers --help; operator commands are not implemented
// yet (the launcher starts and stops the task).
#include <CLI/CLI.hpp>

#include <cstdio>

int main(int argc, char** argv) {
  CLI::App app{
      "mrroc-ui: operator interface (not implemented yet: this build only reserves the binary; "
      "it exits with status 3)."};
  std::string config;
  app.add_option("-c,--config", config, "process-set config file (TOML)");
  CLI11_PARSE(app, argc, argv);
  std::fprintf(stderr, "mrroc-ui: the operator interface is not implemented yet\n");
  return 3;
}
