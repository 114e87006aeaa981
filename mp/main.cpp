// mrroc-mp: the Master Process. Runs the MP part of the task, coordinating the robots' ECPs, and
// serves the operator's commands (START, PAUSE, RESUME, STOP, TERMINATE, STATUS from mrroc-ui).
#include <fmt/format.h>

#include <atomic>
#include <chrono>
#include <cstdio>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <thread>

#include "mrroc/comm/auth.hpp"
#include "mrroc/comm/links.hpp"
#include "mrroc/comm/reporter.hpp"
#include "mrroc/comm/request_reply.hpp"
#include "mrroc/config/check.hpp"
#include "mrroc/config/process_set.hpp"
#include "mrroc/core/command_line.hpp"
#include "mrroc/core/plugin_library.hpp"
#include "mrroc/core/process.hpp"
#include "mrroc/core/time.hpp"
#include "mrroc/mp/task.hpp"

namespace {

using namespace mrroc;
using Command = mp::OperatorCommandType;
using State = mp::TaskState;
using Reply = mp::OperatorReply;

/// The MP shell: one run of the MP task at a time on a worker thread; the main thread answers the
/// operator's commands and sends PAUSE, RESUME and STOP to every ECP.
class MpShell {
 public:
  MpShell(const ProcessSetConfig& config, comm::Bus& bus, Reporter& reporter)
      : config_(config),
        reporter_(reporter),
        context_{{}, reporter, config.mp.args, config, &bus},
        server_(bus, "mp", channels::mp_command, channels::mp_reply) {
    for (const auto& robot : config.robots) {
      robots_.push_back(std::make_unique<mp::Robot>(bus, robot.name));
      context_.robots.push_back(robots_.back().get());
    }
    // An unknown task name or bad arguments fail before "ready", every error found (an
    // argument's own location, else the [mp] table's); `mrroc-mp --check-config` runs this too.
    ConfigErrorList errors;
    errors.add(mp::check_mp_task(config.mp.name, context_, config.mp.name_where, config.mp.where));
    errors.throw_if_any();
  }

  MpShell(const MpShell&) = delete;
  MpShell& operator=(const MpShell&) = delete;
  ~MpShell() {
    if (worker_.joinable()) worker_.join();
  }

  /// Runs until the task ended ("auto") or the operator terminated the MP ("operator").
  /// Returns the exit code: 0 when the last run finished (or none ran), 1 otherwise.
  int run() {
    const bool operator_mode = config_.mp_waits_for_operator;
    reporter_.set_state(ProcessState::ready);
    if (operator_mode)
      reporter_.info(fmt::format("task '{}' waits for START (mrroc-ui start or the console)",
                                 config_.mp.name));
    else
      start_run();
    bool stop_sent = false;
    for (;;) {
      if (auto in = server_.wait_request(std::chrono::milliseconds(20))) handle(*in);
      collect_run();
      if (stop_requested() && !stop_sent) {
        stop_sent = true;
        if (running()) {
          reporter_.warning("stop requested: sending STOP to every ECP");
          stop_run("stop requested");
        }
      }
      std::lock_guard lock(mutex_);
      const bool idle =
          state_ != State::running && state_ != State::paused && state_ != State::stopping;
      if (idle && (!operator_mode || terminate_ || stop_requested())) break;
    }
    std::lock_guard lock(mutex_);
    return state_ == State::failed ? 1 : 0;
  }

 private:
  std::unique_ptr<mp::MpTask> make_task() {
    try {
      return mp::make_mp_task(config_.mp.name, context_);
    } catch (const ConfigError& e) {
      throw e.at(config_.mp.where);  // an argument's own location, else the [mp] table's
    }
  }

  bool running() const {
    std::lock_guard lock(mutex_);
    return state_ == State::running || state_ == State::paused || state_ == State::stopping;
  }

  void start_run() {
    if (worker_.joinable()) worker_.join();
    mp::clear_task_stop();
    std::unique_ptr<mp::MpTask> task = make_task();
    {
      std::lock_guard lock(mutex_);
      state_ = State::running;
      ++runs_;
      started_utime_ = now_utime();
      last_error_.clear();
      done_ = false;
      stopped_by_operator_ = false;
    }
    reporter_.set_state(ProcessState::running);
    reporter_.info(fmt::format("task '{}' started with {} robot(s){}", config_.mp.name,
                               config_.robots.size(),
                               runs_ > 1 ? fmt::format(" (run {})", runs_) : std::string{}));
    worker_ = std::thread([this, t = std::move(task)] {
      std::string failure;
      try {
        t->main_task();
      } catch (const std::exception& e) {
        failure = e.what();
        if (failure.empty()) failure = "task failed";
      }
      std::lock_guard lock(mutex_);
      last_error_ = failure;
      done_ = true;
    });
  }

  /// Notices the end of a run: reports it and resets the ECPs' pause.
  void collect_run() {
    bool ended = false;
    bool paused = false;
    std::string error;
    bool by_operator = false;
    {
      std::lock_guard lock(mutex_);
      if (!done_ || !worker_.joinable()) return;
      ended = true;
      paused = paused_ecps_;
      paused_ecps_ = false;
      error = last_error_;
      by_operator = stopped_by_operator_;
      if (!error.empty() && by_operator) error = "task stopped by the operator (" + error + ")";
      last_error_ = error;
      state_ = error.empty() ? State::finished : State::failed;
      done_ = false;
    }
    worker_.join();
    if (!ended) return;
    if (paused) for_each_robot("RESUME", [](mp::Robot& r) { r.resume(); });
    if (error.empty()) {
      reporter_.info(fmt::format("task '{}' finished", config_.mp.name));
      reporter_.set_state(config_.mp_waits_for_operator ? ProcessState::ready
                                                        : ProcessState::finished);
    } else {
      reporter_.report(by_operator ? Severity::warning : Severity::fatal, 0, error);
      reporter_.set_state(
          config_.mp_waits_for_operator ? ProcessState::ready : ProcessState::failed, error);
    }
  }

  void for_each_robot(const char* what, const std::function<void(mp::Robot&)>& action) {
    for (mp::Robot* robot : context_.robots) {
      try {
        action(*robot);
      } catch (const std::exception& e) {
        reporter_.warning(fmt::format("{} to ecp/{}: {}", what, robot->name(), e.what()));
      }
    }
  }

  void stop_run(const std::string& why) {
    {
      std::lock_guard lock(mutex_);
      state_ = State::stopping;
      stopped_by_operator_ = true;
    }
    reporter_.warning(fmt::format("{}: stopping task '{}'", why, config_.mp.name));
    mp::request_task_stop();
    for_each_robot("STOP", [](mp::Robot& r) { r.stop(); });
  }

  Reply snapshot(bool accepted, const std::string& text) const {
    std::lock_guard lock(mutex_);
    Reply r;
    r.accepted = accepted;
    r.state = state_;
    r.task = config_.mp.name;
    r.runs = runs_;
    r.started_utime = started_utime_;
    r.text = text.empty() ? last_error_ : text;
    return r;
  }

  void handle(comm::OperatorServer::Incoming& in) {
    if (!in.request) {
      in.responder.reply(snapshot(false, "unknown operator command: " + in.decode_error));
      return;
    }
    const Command command = in.request->type;
    const char* name = mp::to_string(command);
    State state = State::idle;
    {
      std::lock_guard lock(mutex_);
      state = state_;
    }
    auto refuse = [&](const std::string& why) {
      in.responder.reply(snapshot(
          false, fmt::format("{} refused: {} (state {})", name, why, mp::to_string(state))));
    };
    const bool active =
        state == State::running || state == State::paused || state == State::stopping;
    switch (command) {
      case Command::status: in.responder.reply(snapshot(true, {})); return;
      case Command::start:
        if (!config_.mp_waits_for_operator)
          return refuse("the task starts by itself ([mp] start = \"auto\")");
        if (active) return refuse("the task is already running");
        if (terminate_) return refuse("the MP is terminating");
        reporter_.info("START from the operator");
        start_run();
        in.responder.reply(snapshot(true, "task started"));
        return;
      case Command::pause:
        if (state != State::running) return refuse("no task is running");
        reporter_.info("PAUSE from the operator: every robot holds before its next macro-step");
        {
          std::lock_guard lock(mutex_);
          state_ = State::paused;
          paused_ecps_ = true;
        }
        for_each_robot("PAUSE", [](mp::Robot& r) { r.pause(); });
        in.responder.reply(snapshot(true, "task paused"));
        return;
      case Command::resume:
        if (state != State::paused) return refuse("the task is not paused");
        reporter_.info("RESUME from the operator");
        for_each_robot("RESUME", [](mp::Robot& r) { r.resume(); });
        {
          std::lock_guard lock(mutex_);
          if (state_ == State::paused) state_ = State::running;
          paused_ecps_ = false;
        }
        in.responder.reply(snapshot(true, "task resumed"));
        return;
      case Command::stop:
        if (state != State::running && state != State::paused) return refuse("no task is running");
        stop_run("STOP from the operator");
        in.responder.reply(snapshot(true, "task stopping"));
        return;
      case Command::terminate: {
        reporter_.warning("TERMINATE from the operator: the MP ends");
        {
          std::lock_guard lock(mutex_);
          terminate_ = true;
        }
        if (state == State::running || state == State::paused) stop_run("TERMINATE");
        Reply r = snapshot(true, "MP terminating");
        r.state = State::terminating;
        in.responder.reply(r);
        return;
      }
    }
  }

  const ProcessSetConfig& config_;
  Reporter& reporter_;
  std::vector<std::unique_ptr<mp::Robot>> robots_;
  mp::TaskContext context_;
  comm::OperatorServer server_;
  std::thread worker_;

  mutable std::mutex mutex_;
  State state_ = State::idle;
  std::int32_t runs_ = 0;
  std::int64_t started_utime_ = 0;
  std::string last_error_;
  bool done_ = false;
  bool paused_ecps_ = false;
  bool stopped_by_operator_ = false;
  bool terminate_ = false;
};

/// What the MP builds before it reports ready, at start and for --check-config: the task
/// library, the robots' links and the task, built once (every error found).
std::unique_ptr<MpShell> prepare(const ProcessSetConfig& config, comm::Bus& bus,
                                 Reporter& reporter) {
  if (!config.mp.library.empty()) load_plugin_library(config.mp.library, config.mp.where);
  return std::make_unique<MpShell>(config, bus, reporter);
}

int run(const std::string& config_path) {
  const ProcessSetConfig config = load_process_set(config_path);
  apply_cpu_affinity(config.mp.options.cpus);
  const std::string scheduling = apply_priority(config.mp.options.priority);
  comm::Bus bus(config.lcm_url);
  comm::enable_auth_from_file(bus, config.auth_key_file);
  bus.start();
  Reporter reporter(bus, "mp");
  // The MP has no ready line of its own: say so only when the system refused the priority.
  if (scheduling.rfind("SCHED_OTHER (", 0) == 0)
    reporter.warning(fmt::format("runs {}", scheduling));
  try {
    const std::unique_ptr<MpShell> shell = prepare(config, bus, reporter);
    const int code = shell->run();
    if (config.mp_waits_for_operator)
      reporter.set_state(code == 0 ? ProcessState::finished : ProcessState::failed);
    return code;
  } catch (const std::exception& e) {
    ConfigErrorList errors;
    errors.add(e, {});
    for (const auto& error : errors.errors()) reporter.report(Severity::fatal, 0, error.what());
    reporter.set_state(ProcessState::failed, errors.errors().front().what());
    return 1;
  }
}

/// --check-config: the process set's errors and the MP's (prepare), one per line on stderr,
/// nothing started and nothing sent beyond the process (kCheckLcmUrl).
int check(const std::string& config_path) {
  const ProcessSetCheck set = check_process_set(config_path);
  ConfigErrorList errors;
  errors.add(set.errors);
  if (!set.broken_process("mp")) {
    errors.run(SourceLocation::whole_file(set.config.file.string()), [&] {
      comm::Bus bus(kCheckLcmUrl);
      Reporter reporter(bus, "mp");
      (void)prepare(set.config, bus, reporter);
    });
  }
  for (const auto& error : errors.errors()) std::fprintf(stderr, "%s\n", error.what());
  if (!errors.empty()) return kExitConfigErrors;
  std::printf("mrroc-mp: mp: config is valid\n");
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  mrroc::CommandLine cli(
      "mrroc-mp",
      "mrroc-mp: Master Process. Runs the MP task named in the config and coordinates the ECPs. "
      "With [mp] start = \"auto\" (the default) the task starts at once and the MP exits when "
      "it ends; with start = \"operator\" the MP waits for START and serves START, PAUSE, RESUME, "
      "STOP, TERMINATE and STATUS from mrroc-ui (channel mrroc/mp/cmd) until TERMINATE. Exit "
      "code: 0 when the (last) run finished or none ran, 1 when it failed or was stopped, 2 on "
      "a config error or a bad command line. Normally started by mrroc-launch.");
  std::string config;
  bool check_config = false;
  cli.option("-c,--config", config, "process-set config file (TOML)").required();
  cli.flag("--check-config", check_config,
           "check the config as the MP does at start (task library, task name and every "
           "argument), print every error as file:line and exit (0 valid, 2 errors); nothing is "
           "started and nothing is sent (mrroc-launch --check runs it)");
  if (const auto exit_code = cli.parse(argc, argv)) return *exit_code;
  mrroc::install_stop_handlers();
  try {
    if (check_config) return check(config);
    return run(config);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "mrroc-mp: %s\n", e.what());
    return 2;
  }
}
