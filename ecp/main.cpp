// mrroc-ecp: the Effector Control Process of one robot. Runs the robot's task on START_TASK.
#include <CLI/CLI.hpp>
#include <fmt/format.h>

#include <chrono>
#include <cstdio>
#include <optional>
#include <thread>

#include "mrroc/comm/links.hpp"
#include "mrroc/config/process_set.hpp"
#include "mrroc/core/plugin_library.hpp"
#include "mrroc/core/process.hpp"
#include "mrroc/core/reporter.hpp"
#include "mrroc/ecp/task.hpp"
#include "mrroc/robot/robot_model.hpp"

namespace {

using namespace mrroc;

ecp::EcpReply error_reply(ecp::ErrorClass cls, int code, const std::string& text) {
  ecp::EcpReply r;
  r.type = ecp::EcpReplyType::error;
  r.error_class = cls;
  r.error_code = code;
  r.error_text = text;
  return r;
}

int run(const std::string& config_path, const std::string& robot_name) {
  const ProcessSetConfig config = load_process_set(config_path);
  const RobotConfig& robot_config = config.robot(robot_name);
  apply_cpu_affinity(robot_config.ecp.options.cpus);
  const std::string process = "ecp/" + robot_config.name;

  comm::Bus bus(config.lcm_url);
  bus.start();
  Reporter reporter(bus, process, robot_config.name);
  try {
    ecp::Robot robot(bus, process, robot_config.name, load_robot_model(robot_config.model_dir));
    ecp::TaskContext context{robot, reporter, robot_config.ecp.args,
                             robot_config.edp.servo_period_s};
    if (!robot_config.ecp.library.empty())
      load_plugin_library(robot_config.ecp.library, robot_config.ecp.where);
    std::unique_ptr<ecp::EcpTask> task;
    try {
      task = ecp::make_ecp_task(robot_config.ecp.name, context);
    } catch (const ConfigError& e) {
      const std::string text = e.what();
      if (text.find(": error: ") != std::string::npos) throw;
      throw ConfigError(fmt::format("{}: error: {}", robot_config.ecp.where.str(), text));
    }
    comm::EcpServer server(bus, process, channels::ecp_command(robot_config.name),
                           channels::ecp_reply(robot_config.name));
    reporter.info(fmt::format("ready: task '{}'", robot_config.ecp.name));
    reporter.set_state(ProcessState::ready);

    std::thread task_thread;
    std::atomic<bool> task_running{false};
    while (!stop_requested()) {
      auto in = server.wait_request(std::chrono::milliseconds(100));
      if (!in) continue;
      if (!in->request) {
        reporter.report(Severity::warning, ecp::error_code::malformed,
                        "malformed MP command dropped: " + in->decode_error);
        in->responder.reply(error_reply(ecp::ErrorClass::non_fatal, ecp::error_code::malformed,
                                        "malformed command: " + in->decode_error));
        continue;
      }
      const ecp::MpCommand& command = *in->request;
      switch (command.type) {
        case ecp::MpCommandType::start_task: {
          if (task_running) {
            in->responder.reply(
                error_reply(ecp::ErrorClass::non_fatal, ecp::error_code::task_running,
                            "START_TASK refused: task running"));
            break;
          }
          if (task_thread.joinable()) task_thread.join();
          robot.clear_stop();  // a STOP ends one task run, not the next one
          task_running = true;
          reporter.set_state(ProcessState::running);
          reporter.info(fmt::format("task '{}' started", robot_config.ecp.name));
          // The reply to START_TASK is sent when the task ends (TASK_TERMINATED or ERROR);
          // until then the MP's re-sends are answered IN_PROGRESS.
          task_thread = std::thread([&, responder = in->responder] {
            ecp::EcpReply reply;
            try {
              task->main_task();
              reply.type = ecp::EcpReplyType::task_terminated;
              reporter.info(fmt::format("task '{}' terminated", robot_config.ecp.name));
            } catch (const ecp::TaskStopped& e) {
              reply = error_reply(ecp::ErrorClass::non_fatal, ecp::error_code::stopped, e.what());
              reporter.report(Severity::warning, ecp::error_code::stopped, e.what());
            } catch (const TimeoutError& e) {
              reply = error_reply(ecp::ErrorClass::system, ecp::error_code::timeout, e.what());
              reporter.report(Severity::error, ecp::error_code::timeout, e.what());
            } catch (const RemoteError& e) {
              reply = error_reply(ecp::ErrorClass::fatal, e.code(), e.what());
              reporter.report(Severity::error, e.code(), e.what());
            } catch (const std::exception& e) {
              reply = error_reply(ecp::ErrorClass::fatal, ecp::error_code::task_error, e.what());
              reporter.report(Severity::error, ecp::error_code::task_error, e.what());
            }
            reply.synchronised = robot.image().synchronised;
            reply.joints = robot.image().joints;
            responder.reply(reply);
            reporter.set_state(ProcessState::ready);
            task_running = false;
          });
          break;
        }
        case ecp::MpCommandType::stop:
          robot.request_stop();
          in->responder.reply(ecp::EcpReply{});
          break;
        default:
          in->responder.reply(error_reply(
              ecp::ErrorClass::non_fatal, ecp::error_code::not_supported,
              fmt::format("{} is not supported by this ECP shell yet", to_string(command.type))));
      }
    }
    reporter.set_state(ProcessState::stopping);
    robot.request_stop();
    if (task_thread.joinable()) task_thread.join();
    reporter.set_state(ProcessState::finished);
  } catch (const std::exception& e) {
    reporter.report(Severity::fatal, 0, e.what());
    reporter.set_state(ProcessState::failed, e.what());
    return 1;
  }
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{
      "mrroc-ecp: Effector Control Process. Runs the robot's task (generators, Move, Wait) on "
      "the MP's START_TASK and drives the robot's EDP. Normally started by mrroc-launch."};
  std::string config;
  std::string robot;
  app.add_option("-c,--config", config, "process-set config file (TOML)")->required();
  app.add_option("-r,--robot", robot, "name of the robot ([[robot]] name in the config)")
      ->required();
  CLI11_PARSE(app, argc, argv);
  mrroc::install_stop_handlers();
  try {
    return run(config, robot);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "mrroc-ecp: %s\n", e.what());
    return 2;
  }
}
