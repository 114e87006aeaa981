// mrroc-ui: operator commands. Today: the emergency stop (engage, release) for every robot or
// one robot of a process set; the web console and task commands are not implemented yet.
#include <CLI/CLI.hpp>
#include <fmt/format.h>

#include <chrono>
#include <cstdio>
#include <thread>

#include "mrroc/comm/bus.hpp"
#include "mrroc/comm/request_reply.hpp"
#include "mrroc/comm/sync_annotations.hpp"
#include "mrroc/config/process_set.hpp"
#include "mrroc/core/reporter.hpp"
#include "mrroc/core/time.hpp"
#include "mrroc_lcm/emergency_stop_t.hpp"

namespace {

using namespace mrroc;

int send_emergency_stop(const std::string& config_path, bool engage, const std::string& robot,
                        const std::string& reason) {
  const ProcessSetConfig config = load_process_set(config_path);
  if (!robot.empty()) (void)config.robot(robot);  // a typo in the robot name is an error
  comm::Bus bus(config.lcm_url);
  Reporter reporter(bus, "ui");
  mrroc_lcm::emergency_stop_t m{};
  m.header.sender = comm::unique_endpoint_name("ui");
  m.header.kind = mrroc_lcm::header_t::BROADCAST;
  m.action = engage ? mrroc_lcm::emergency_stop_t::ENGAGE : mrroc_lcm::emergency_stop_t::RELEASE;
  m.robot = robot;
  m.reason = reason;
  // UDP may drop a datagram: send it a few times (EDPs act on the first, ignore the others).
  for (int i = 0; i < 5; ++i) {
    m.header.seq = i + 1;
    m.header.utime = now_utime();
    comm::detail::published();
    bus.lcm().publish(channels::emergency_stop, &m);
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  const std::string what = fmt::format("{} {} for {}", engage ? "EMERGENCY STOP" : "emergency stop released",
                                       reason.empty() ? "" : "(" + reason + ")",
                                       robot.empty() ? "every robot" : "robot " + robot);
  if (engage)
    reporter.report(Severity::error, 10, what);
  else
    reporter.warning(what);
  std::printf("mrroc-ui: %s\n", what.c_str());
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{
      "mrroc-ui: operator commands for a running process set. 'estop' brings every robot (or "
      "one) to a standstill within its acceleration limits and holds it; 'release' allows "
      "motion again. (Task commands and the web console are not implemented yet.)"};
  app.require_subcommand(1);
  std::string config;
  std::string robot;
  std::string reason = "operator";
  for (const char* name : {"estop", "release"}) {
    CLI::App* sub = app.add_subcommand(name, std::string(name) == "estop"
                                                 ? "engage the emergency stop"
                                                 : "release the emergency stop");
    sub->add_option("-c,--config", config, "process-set config file (TOML)")->required();
    sub->add_option("-r,--robot", robot, "only this robot (default: every robot)");
    sub->add_option("--reason", reason, "text sent to the SRP");
  }
  CLI11_PARSE(app, argc, argv);
  try {
    const bool engage = app.got_subcommand("estop");
    return send_emergency_stop(config, engage, robot, reason);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "mrroc-ui: %s\n", e.what());
    return 2;
  }
}
