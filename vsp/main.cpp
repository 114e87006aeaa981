// mrroc-vsp: Virtual Sensor Process. The shell answers --help; sensor plugins and the reading
// protocol (CONFIGURE, INITIATE_READING, GET_READING, TERMINATE) are not implemented yet.
#include <CLI/CLI.hpp>

#include <cstdio>

int main(int argc, char** argv) {
  CLI::App app{
      "mrroc-vsp: Virtual Sensor Process (not implemented yet: this build only reserves the "
      "binary; it exits with status 3)."};
  std::string config;
  app.add_option("-c,--config", config, "process-set config file (TOML)");
  CLI11_PARSE(app, argc, argv);
  std::fprintf(stderr, "mrroc-vsp: virtual sensor processes are not implemented yet\n");
  return 3;
}
