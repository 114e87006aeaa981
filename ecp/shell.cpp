#include "shell.hpp"

#include <fmt/format.h>
#include <fmt/ranges.h>

#include "mrroc/config/check.hpp"
#include "mrroc/core/process.hpp"
#include "mrroc/ecp/errors.hpp"
#include "mrroc/ecp/generator.hpp"
#include "mrroc/robot/robot_model.hpp"

namespace mrroc::ecp {

namespace {

EcpReply error_reply(ErrorClass cls, int code, const std::string& text) {
  EcpReply r;
  r.type = EcpReplyType::error;
  r.error_class = cls;
  r.error_code = code;
  r.error_text = text;
  return r;
}

}  // namespace

EcpShell::EcpShell(comm::Bus& bus, const RobotConfig& config, Reporter& reporter,
                   std::vector<std::string> vsps)
    : bus_(bus),
      config_(config),
      reporter_(reporter),
      vsps_(std::move(vsps)),
      process_("ecp/" + config.name),
      robot_(make_task_robot(config.ecp.name, bus, process_, config.name,
                             load_robot_model(config.model_dir))),
      // Commands are dispatched on the bus thread as they arrive (dispatch never blocks: a task,
      // sub-task or macro-step goes to the worker), one thread hand-off less than a queue.
      server_(bus, process_, channels::ecp_command(config.name), channels::ecp_reply(config.name),
              [this](comm::EcpServer::Incoming in) { serve(std::move(in)); }) {
  // Build the configured task once now, so that a wrong name or argument fails before "ready"
  // (every error found; `mrroc-ecp --check-config` runs this constructor too).
  TaskContext context{*robot_, reporter_, config_.ecp.args, config_.edp.servo_period_s,
                      &bus_,   process_,  nullptr,          &vsps_};
  ConfigErrorList errors;
  // An argument's own location, else the [robot.ecp] table's.
  errors.add(check_ecp_task(config_.ecp.name, context, config_.ecp.name_where, config_.ecp.where));
  errors.throw_if_any();
  worker_ = std::thread([this] { worker_loop(); });
}

EcpShell::~EcpShell() {
  robot_->request_stop();
  {
    std::lock_guard lock(mutex_);
    closing_ = true;
  }
  cv_.notify_all();
  if (worker_.joinable()) worker_.join();
}

void EcpShell::worker_loop() {
  std::unique_lock lock(mutex_);
  for (;;) {
    cv_.wait(lock, [&] { return job_ || closing_; });
    if (!job_) return;
    auto job = std::move(job_);
    job_ = nullptr;
    lock.unlock();
    job();
    lock.lock();
  }
}

bool EcpShell::start_activity(const std::string& what, std::function<EcpReply()> body,
                              const Responder& responder) {
  {
    std::lock_guard lock(mutex_);
    if (busy_) return false;
    busy_ = true;
    job_ = [this, what, body = std::move(body), responder] {
      EcpReply reply;
      try {
        reply = body();
      } catch (const TaskError& e) {
        reply = error_reply(e.error_class(), e.code(), e.what());
        reporter_.report(
            e.error_class() == ErrorClass::non_fatal ? Severity::warning : Severity::error,
            e.code(), what + ": " + e.what());
      } catch (const TaskStopped& e) {
        reply = error_reply(ErrorClass::non_fatal, error_code::stopped, e.what());
        reporter_.report(Severity::warning, error_code::stopped, what + ": " + e.what());
      } catch (const TimeoutError& e) {
        reply = error_reply(ErrorClass::system, error_code::timeout, e.what());
        reporter_.report(Severity::error, error_code::timeout, what + ": " + e.what());
      } catch (const RemoteError& e) {
        // The EDP's (or VSP's) own class: a refusal before anything moved is non-fatal, a drive
        // fault or an emergency stop fatal, a failed link or message system.
        reply = error_reply(e.error_class(), e.code(), e.what());
        reporter_.report(Severity::error, e.code(), what + ": " + e.what());
      } catch (const ConfigError& e) {
        reply = error_reply(ErrorClass::non_fatal, error_code::task_error, e.what());
        reporter_.report(Severity::error, error_code::task_error, what + ": " + e.what());
      } catch (const CommandError& e) {
        reply = error_reply(ErrorClass::non_fatal, e.code(), e.what());
        reporter_.report(Severity::error, e.code(), what + ": " + e.what());
      } catch (const std::exception& e) {
        reply = error_reply(ErrorClass::fatal, error_code::task_error, e.what());
        reporter_.report(Severity::error, error_code::task_error, what + ": " + e.what());
      }
      if (reply.joints.empty()) {
        reply.synchronised = robot_->image().synchronised;
        reply.joints = robot_->image().joints;
        reply.desired_joints = robot_->image().desired_joints;
      }
      // Free the worker before answering: the MP may send its next command at once.
      {
        std::lock_guard done(mutex_);
        busy_ = false;
      }
      responder.reply(reply);
    };
  }
  cv_.notify_all();
  return true;
}

EcpReply EcpShell::state_reply(EcpReplyType type) const {
  EcpReply r;
  r.type = type;
  const RobotImage& image = robot_->image();
  r.synchronised = image.synchronised;
  r.joints = image.joints;
  r.desired_joints = image.desired_joints;
  r.arm_type = image.arm_type;
  r.arm = image.arm;
  return r;
}

EcpReply EcpShell::run_task(const std::string& name, const Params& args) {
  // A run (task or sub-task) drives the robot from its first instruction, whoever drove it last
  // (the console's jogs between runs, which it makes only while the MP is idle; docs/edp.md).
  robot_->take_over_next();
  follow_.reset();  // a new run: the MP's poses pass unchanged unless this task says otherwise
  TaskContext context{*robot_, reporter_, args,     config_.edp.servo_period_s,
                      &bus_,   process_,  &follow_, &vsps_};
  std::unique_ptr<EcpTask> task = make_ecp_task(name, context);
  reporter_.info(fmt::format("task '{}' started", name));
  task->main_task();
  reporter_.info(fmt::format("task '{}' terminated", name));
  return state_reply(EcpReplyType::task_terminated);
}

EcpReply EcpShell::next_pose(const MpCommand& command) {
  if (robot_->stop_requested()) throw TaskStopped("task stopped on request");
  robot_->wait_while_paused();
  if (!robot_->image().synchronised) robot_->synchronise();
  MpCommand pose = command;
  if (follow_) {
    const SensorList sensors = follow_->sensors();
    for (Sensor* s : sensors) s->initiate_reading();
    for (Sensor* s : sensors) s->get_reading();
    follow_->correct(pose, robot_->image(), sensors);
  }
  edp::Instruction& c = robot_->image().command;
  c = edp::Instruction{};
  c.type = edp::InstructionType::set_get;
  c.set = edp::item::arm;
  c.get = edp::item::arm;
  c.set_arm_type = pose.arm_type;
  c.get_arm_type = pose.arm_type;
  c.motion_type = pose.motion_type;
  c.motion_steps = pose.motion_steps;
  c.value_in_step_no = pose.value_in_step_no;
  c.arm = pose.arm;
  robot_->execute();
  return state_reply(EcpReplyType::acknowledge);
}

EcpReply EcpShell::end_motion() {
  robot_->read_state();
  if (follow_) follow_->end_motion(robot_->image());
  return state_reply(EcpReplyType::acknowledge);
}

void EcpShell::dispatch(const MpCommand& command, const Responder& responder) {
  const char* name = to_string(command.type);
  auto busy = [&] {
    responder.reply(error_reply(ErrorClass::non_fatal, error_code::task_running,
                                fmt::format("{} refused: another command is running", name)));
  };
  switch (command.type) {
    case MpCommandType::start_task:
      robot_->clear_stop();  // a STOP ends one run, not the next one
      if (!start_activity(
              fmt::format("task '{}'", config_.ecp.name),
              [this] { return run_task(config_.ecp.name, config_.ecp.args); }, responder))
        busy();
      break;
    case MpCommandType::next_state: {
      robot_->clear_stop();
      const std::string state = command.state_name;
      const std::string arguments = command.arguments;
      const std::string origin = fmt::format("NEXT_STATE '{}' arguments", state);
      if (!start_activity(
              fmt::format("sub-task '{}'", state),
              [this, state, arguments, origin] {
                const Params args = params_from_toml(arguments, origin);
                return run_task(state, args);
              },
              responder))
        busy();
      break;
    }
    case MpCommandType::next_pose:
      if (!start_activity(
              "NEXT_POSE", [this, command] { return next_pose(command); }, responder))
        busy();
      break;
    case MpCommandType::end_motion:
      // The end of a continuous motion also ends a STOP that stopped it.
      if (!start_activity(
              "END_MOTION",
              [this] {
                robot_->clear_stop();
                return end_motion();
              },
              responder))
        busy();
      break;
    // Operator commands answer at once, without the robot image (the worker may be updating it).
    case MpCommandType::stop:
      robot_->request_stop();
      reporter_.warning("STOP from the MP");
      responder.reply(EcpReply{});
      break;
    case MpCommandType::pause:
      robot_->pause();
      reporter_.info("paused");
      responder.reply(EcpReply{});
      break;
    case MpCommandType::resume:
      robot_->resume();
      reporter_.info("resumed");
      responder.reply(EcpReply{});
      break;
  }
}

void EcpShell::serve(comm::EcpServer::Incoming in) {
  {
    std::lock_guard lock(serve_mutex_);
    if (!serving_) {
      // Before "ready" (served then) or while stopping (never: the process ends).
      early_.push_back(std::move(in));
      return;
    }
  }
  if (!in.request) {
    reporter_.report(Severity::warning, error_code::malformed,
                     "malformed MP command dropped: " + in.decode_error);
    in.responder.reply(error_reply(ErrorClass::non_fatal, error_code::malformed,
                                   "malformed command: " + in.decode_error));
    return;
  }
  dispatch(*in.request, in.responder);
}

void EcpShell::run(const std::string& scheduling) {
  reporter_.info(fmt::format("ready: task '{}', {}", config_.ecp.name, scheduling));
  reporter_.set_state(ProcessState::ready);
  std::vector<comm::EcpServer::Incoming> early;
  {
    std::lock_guard lock(serve_mutex_);
    serving_ = true;
    early.swap(early_);
  }
  for (auto& in : early) serve(std::move(in));
  while (!stop_requested()) std::this_thread::sleep_for(std::chrono::milliseconds(100));
  {
    std::lock_guard lock(serve_mutex_);
    serving_ = false;
  }
  reporter_.set_state(ProcessState::stopping);
  robot_->request_stop();
}

}  // namespace mrroc::ecp
