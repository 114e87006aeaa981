// mrroc-edp: the Effector Driver Process of one robot.
#include <fmt/format.h>

#include <chrono>
#include <cstdio>
#include <mutex>
#include <thread>

#include "collision_guard.hpp"
#include "command_interpreter.hpp"
#include "estop_listener.hpp"
#include "mrroc/comm/auth.hpp"
#include "mrroc/comm/edge.hpp"
#include "mrroc/comm/links.hpp"
#include "mrroc/comm/reporter.hpp"
#include "mrroc/comm/request_reply.hpp"
#include "mrroc/comm/sync_annotations.hpp"
#include "mrroc/config/check.hpp"
#include "mrroc/config/process_set.hpp"
#include "mrroc/core/command_line.hpp"
#include "mrroc/core/plugin_library.hpp"
#include "mrroc/core/process.hpp"
#include "mrroc/edp/arm_kinematics.hpp"
#include "mrroc/edp/hardware.hpp"
#include "mrroc/robot/robot_model.hpp"
#include "servo_loop.hpp"

namespace {

/// How often the EDP sends its servo timing statistics to the SRP.
constexpr std::chrono::seconds kTimingReportPeriod{10};
/// Requests older than this when they arrive are dropped (ServerOptions::max_request_age).
constexpr std::chrono::milliseconds kRequestDeadline{1000};
/// How often the EDP broadcasts its robot_state_t.
constexpr std::chrono::milliseconds kStatePeriod{20};
/// Longest a stop request waits for a moving robot to reach a standstill (below the launcher's
/// default 3 s grace period).
constexpr std::chrono::milliseconds kShutdownRampLimit{2000};
/// Overruns are reported at once, then at most this often.
constexpr std::chrono::seconds kOverrunReportPeriod{1};
/// How long the EDP listens for another EDP of its robot (its robot_state_t, every 20 ms: seven
/// of them) on the set's LCM URL before it starts its servo loop.
constexpr std::chrono::milliseconds kOtherEdpListen{150};

/// Throws when another EDP of `robot` broadcasts its robot_state_t on the bus' URL.
void refuse_if_another_edp(mrroc::comm::Bus& bus, const std::string& robot,
                           const std::string& config_file) {
  struct Seen {
    std::mutex mutex;
    std::string sender;
    std::int64_t servo_step = 0;
  } seen;
  const std::string channel = mrroc::channels::robot_state(robot);
  {
    // A state that does not decode is another EDP's too, but says nothing about whose: dropped.
    // With a key only a state signed with it counts: anybody could send one to keep the EDP
    // from starting.
    const bool keyed = bus.auth() != nullptr;
    mrroc::comm::Subscriber<mrroc::RobotState> sub(
        bus, channel,
        [&seen, keyed](const mrroc::RobotState& m, const mrroc::comm::Received& in) {
          if (keyed && !in.authentic_unreported()) return;
          std::lock_guard lock(seen.mutex);
          seen.sender = in.header().sender;
          seen.servo_step = m.servo_step;
        },
        mrroc::comm::SubscriberOptions::unreported());
    std::this_thread::sleep_for(kOtherEdpListen);
  }
  std::lock_guard lock(seen.mutex);
  if (!seen.sender.empty())
    throw mrroc::Error(fmt::format(
        "another EDP of robot '{}' is running on LCM {}: '{}' broadcasts its state on '{}' (servo "
        "step {}); one EDP per robot and one process set per LCM URL: stop it first, or give "
        "this set ({}) another [system] lcm_url",
        robot, bus.url(), seen.sender, channel, seen.servo_step, config_file));
}

/// What the EDP builds from its config before its servo loop starts, at start and for
/// --check-config: the robot model, the plugin library, the configured hardware
/// (edp::make_configured_hardware; with `open_devices` false a real plugin is not configured)
/// and the arm kinematics.
struct Prepared {
  mrroc::RobotModel model;
  std::unique_ptr<mrroc::edp::Hardware> hardware;
  std::unique_ptr<mrroc::edp::ArmKinematics> kinematics;
  /// Null when the guard is off; `collision_text` says why, or what it guards.
  std::unique_ptr<mrroc::edp::CollisionGuard> collision;
  std::string collision_text;
};
Prepared prepare(const mrroc::RobotConfig& robot, const mrroc::CollisionConfig& collision,
                 bool open_devices) {
  using namespace mrroc;
  Prepared p;
  p.model = load_robot_model(robot.model_dir);
  if (!robot.edp.library.empty()) load_plugin_library(robot.edp.library, robot.edp.where);
  ConfigErrorList errors;
  errors.run(robot.edp.where,
             [&] { p.hardware = edp::make_configured_hardware(robot, p.model, open_devices); });
  errors.run(SourceLocation::whole_file((robot.model_dir / "parameters.toml").string()),
             [&] { p.kinematics = edp::make_arm_kinematics(p.model); });
  // The model the robot is simulated with (the mujoco plugin's `mjcf`), else its own.
  errors.run(robot.edp.where, [&] {
    const std::filesystem::path mjcf = robot.edp.params.has("mjcf")
                                           ? robot.model_dir / robot.edp.params.get_string("mjcf")
                                           : p.model.mjcf;
    p.collision = edp::CollisionGuard::make(p.model, robot, collision, mjcf, p.collision_text);
    if (p.collision) p.collision_text = p.collision->describe();
  });
  errors.throw_if_any();
  return p;
}

/// The plugin's declaration, as the ready status and --check-config give it to the launcher
/// (launch/main.cpp reads it): "plugin 'can' drives real devices" or "plugin 'mujoco' drives
/// no real devices".
std::string devices_declaration(const mrroc::edp::Hardware& hardware) {
  return fmt::format("plugin '{}' drives {}", hardware.name(),
                     hardware.drives_real_devices() ? "real devices" : "no real devices");
}

/// --check-config: the process set's errors and this EDP's (prepare), one per line on stderr;
/// nothing is started, no device opened, nothing sent.
int check(const std::string& config_path, const std::string& robot_name) {
  using namespace mrroc;
  const ProcessSetCheck set = check_process_set(config_path);
  ConfigErrorList errors;
  errors.add(set.errors);
  std::string devices;
  if (!set.broken_process("edp/" + robot_name)) {
    errors.run(SourceLocation::whole_file(set.config.file.string()), [&] {
      const Prepared p = prepare(set.config.robot(robot_name), set.config.collision, false);
      devices = devices_declaration(*p.hardware);
    });
  }
  for (const auto& error : errors.errors()) std::fprintf(stderr, "%s\n", error.what());
  if (!errors.empty()) return kExitConfigErrors;
  // The launcher's --check reads the declaration (restarts of an EDP on real devices wait for
  // an operator).
  std::printf("mrroc-edp: edp/%s: config is valid; %s\n", robot_name.c_str(), devices.c_str());
  return 0;
}

int run(const std::string& config_path, const std::string& robot_name) {
  using namespace mrroc;
  const ProcessSetConfig config = load_process_set(config_path);
  const RobotConfig& robot = config.robot(robot_name);
  apply_cpu_affinity(robot.edp.options.cpus);
  // Before any thread exists: the bus and command threads inherit it (the servo thread raises
  // itself to 80).
  const std::string scheduling = apply_priority(robot.edp.options.priority);
  const std::string process = "edp/" + robot.name;

  comm::Bus bus(config.lcm_url);
  comm::enable_auth_from_file(bus, config.auth_key_file);
  bus.start();
  // Before the EDP says anything (its status would reach the other set) or configures anything:
  // one EDP per robot on this LCM URL. Refusing ends the EDP with exit code 2 (main).
  refuse_if_another_edp(bus, robot.name, config.file.string());
  Reporter reporter(bus, process, robot.name);
  try {
    Prepared prepared = prepare(robot, config.collision, true);
    const RobotModel& model = prepared.model;
    const std::unique_ptr<edp::Hardware> hardware = std::move(prepared.hardware);
    const std::unique_ptr<edp::ArmKinematics> kinematics = std::move(prepared.kinematics);

    const std::string memory = lock_memory();
    edp::ServoLoop servo(*hardware, model, robot.edp.servo_period_s);
    servo.set_limit_guard(kinematics.get());
    if (robot.edp.lock_step) servo.set_lock_step(true);
    if (const std::uint32_t named = robot.edp.safe_outputs | robot.edp.kept_outputs;
        named != 0 && (!hardware->binary_io() || (named & ~hardware->output_lines()) != 0))
      throw ConfigError(
          robot.edp.where,
          fmt::format(
              "[robot.edp] safe_outputs = {:#x}, kept_outputs = {:#x} name output lines plugin "
              "'{}' does not have ({})",
              robot.edp.safe_outputs, robot.edp.kept_outputs, hardware->name(),
              hardware->binary_io() ? fmt::format("its lines are {:#x}", hardware->output_lines())
                                    : std::string("it has no binary outputs")));
    servo.set_stop_outputs(robot.edp.safe_outputs, robot.edp.kept_outputs);
    servo.set_lookahead(robot.edp.lookahead);
    servo.set_unsynchronised_limits({robot.edp.unsynchronised_velocity_fraction,
                                     robot.edp.unsynchronised_acceleration_fraction,
                                     robot.edp.unsynchronised_max_move});
    servo.start();
    // Its own socket and thread; the robot is stopped from here until the stop's state is heard.
    edp::EstopListener estop(servo, robot.name, config.lcm_url, config.auth_key_file,
                             edp::EstopListener::priority_for(robot.edp.options.priority),
                             [&reporter](int code, const std::string& text) {
                               reporter.report(Severity::warning, code, text);
                             });
    edp::CommandInterpreter interpreter(servo, model, *kinematics, robot.edp.servo_period_s);
    interpreter.set_collision_guard(prepared.collision.get());
    // A request that took longer than kRequestDeadline to arrive is dropped, not executed: its
    // client has given up on it or re-sent it (every attempt carries its own send time).
    comm::ServerOptions server_options;
    server_options.max_request_age = kRequestDeadline;
    comm::EdpServer server(bus, process, channels::edp_command(robot.name),
                           channels::edp_reply(robot.name), server_options);

    std::this_thread::sleep_for(std::chrono::milliseconds(20));  // let the loop settle its policy
    // The EDP starts stopped and waits (at most EstopListener::kStateWait) for the stop's state:
    // the latch holder (mrroc-launch) announces it every 150 ms.
    const auto wait_start = std::chrono::steady_clock::now();
    const bool heard = estop.wait_state(edp::EstopListener::kStateWait);
    const long waited_ms = std::lround(
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - wait_start)
            .count());
    std::string estop_text;
    if (!heard)
      estop_text = fmt::format(
          "emergency stop ENGAGED: no emergency stop state heard within {} ms (no mrroc-launch "
          "announces it): motion refused until an authentic release (mrroc-ui release)",
          edp::EstopListener::kStateWait.count());
    else if (servo.emergency_stopped())
      estop_text = fmt::format(
          "emergency stop ENGAGED ({}; heard after {} ms): motion refused "
          "until an authentic release",
          estop.reason(), waited_ms);
    else
      estop_text = fmt::format("emergency stop released (heard after {} ms{})", waited_ms,
                               estop.announcer().empty() ? "" : " from " + estop.announcer());
    reporter.info(fmt::format(
        "ready: plugin '{}', {} axes, kinematics '{}', servo period {:.3f} "
        "ms, {}, lookahead {} macro-step{}, communication {}, emergency "
        "stop listener {}, {}; {}; {}",
        hardware->name(), model.axes(), kinematics->name(), robot.edp.servo_period_s * 1e3,
        servo.timing().scheduling, robot.edp.lookahead, robot.edp.lookahead == 1 ? "" : "s",
        scheduling, estop.scheduling(), memory, estop_text,
        prepared.collision ? prepared.collision_text
                           : "collision guard " + prepared.collision_text));
    reporter.set_state(ProcessState::ready, devices_declaration(*hardware));

    bool hardware_fault_reported = false;
    bool estop_reported = servo.emergency_stopped();  // the ready line said so
    std::int64_t lost_reported = 0;
    std::int64_t planned_reported = 0;
    std::uint64_t expired_reported = 0;
    std::thread commands([&] {
      while (!stop_requested()) {
        auto in = server.wait_request(std::chrono::milliseconds(100));
        if (servo.faulted() != hardware_fault_reported) {
          hardware_fault_reported = servo.faulted();
          if (hardware_fault_reported)
            reporter.report(Severity::error, edp::error_code::hardware_fault,
                            fmt::format("plugin '{}' of robot '{}' faulted; the robot is held: {}",
                                        hardware->name(), robot.name, servo.fault_text()));
          else
            reporter.info("hardware fault reset");
        }
        if (servo.emergency_stopped() != estop_reported) {
          estop_reported = servo.emergency_stopped();
          if (estop_reported)
            reporter.report(Severity::error, edp::error_code::emergency_stop,
                            "EMERGENCY STOP: robot brought to a standstill: " + estop.reason());
          else
            reporter.warning("emergency stop released");
        }
        if (const std::int64_t planned = servo.planned_stops(); planned != planned_reported) {
          planned_reported = planned;
          reporter.info(
              fmt::format("the task paused or stopped mid-motion ({} so far): the robot "
                          "was brought to rest within its acceleration limits",
                          planned));
        }
        if (const std::int64_t lost = servo.lost_successors(); lost != lost_reported) {
          lost_reported = lost;
          reporter.warning(
              fmt::format("no next macro-step from the ECP in time ({} so far): the "
                          "robot was brought to a standstill",
                          lost));
        }
        if (!in) continue;
        if (!in->request) {
          edp::Reply r;
          r.type = edp::ReplyType::error;
          r.error_code = edp::error_code::malformed;
          r.error_class = edp::error_class_of(r.error_code);
          r.error_text = "malformed instruction dropped: " + in->decode_error;
          reporter.report(Severity::warning, r.error_code, r.error_text);
          in->responder.reply(r);
          continue;
        }
        const edp::Reply reply = interpreter.execute(*in->request, in->responder.client());
        if (interpreter.owner_changed())
          reporter.info(fmt::format("driven by '{}' from now on", interpreter.owner()));
        if (const std::uint64_t expired = server.stats().expired; expired != expired_reported) {
          reporter.warning(
              fmt::format("{} request(s) arrived more than {} ms after they were sent "
                          "and were dropped, not executed",
                          expired - expired_reported, kRequestDeadline.count()));
          expired_reported = expired;
        }
        if (reply.type == edp::ReplyType::error)
          reporter.report(Severity::warning, reply.error_code, reply.error_text);
        else if (in->request->type == edp::InstructionType::synchro)
          reporter.info("synchronising");
        in->responder.reply(reply);
      }
    });
    reporter.set_state(ProcessState::running);
    auto report_timing = [&] {
      const edp::TimingStats t = servo.timing();
      reporter.report(t.overruns > 0 ? Severity::warning : Severity::info, 0,
                      fmt::format("servo loop: {} cycles of {:.0f} us, lateness p50 {:.1f} us, "
                                  "p99 {:.1f} us, max {:.1f} us, {} overruns{}",
                                  t.cycles, t.period_us, t.lateness_p50_us, t.lateness_p99_us,
                                  t.lateness_max_us, t.overruns,
                                  prepared.collision ? "; " + prepared.collision->statistics_text()
                                                     : std::string()));
    };
    // The robot's state goes out every kStatePeriod (console, recordings, plots); timing
    // statistics go to the SRP every kTimingReportPeriod and when the EDP stops; an overrun (a
    // cycle that woke more than one period late: a stalled loop) is reported at once.
    RobotState state;
    comm::Envelope state_header;
    state_header.sender = comm::unique_endpoint_name(process);
    state.robot = robot.name;
    state.servo_period_s = robot.edp.servo_period_s;
    const std::size_t axes = model.axes();
    state.q.resize(axes);
    state.dq.resize(axes);
    state.q_desired.resize(axes);
    const std::string state_channel = channels::robot_state(robot.name);
    auto next_report = std::chrono::steady_clock::now() + kTimingReportPeriod;
    auto next_state = std::chrono::steady_clock::now();
    auto overrun_quiet_until = std::chrono::steady_clock::now();
    std::int64_t overruns_unreported = 0;
    double worst_unreported_us = 0;
    double worst_work_us = 0;       // the longest cycle's work since the last overrun report
    double worst_lock_wait_us = 0;  // the servo thread's longest wait for its lock, likewise
    // Shutdown never stops a moving robot dead: on SIGINT/SIGTERM a robot in motion is first
    // brought to a standstill within its acceleration limits (the emergency-stop ramp), for at
    // most kShutdownRampLimit, while its state still goes out; then the servo loop stops.
    bool ramping = false;
    std::chrono::steady_clock::time_point ramp_start;
    std::int64_t ramp_first_step = 0;
    bool last_state = false;
    for (;;) {
      if (stop_requested() && !last_state) {
        const auto t = std::chrono::steady_clock::now();
        if (!ramping) {
          // A motion before SYNCHRO is ramped down as well (within its reduced limits); a
          // synchronisation search is abandoned where it is (ServoLoop::emergency_stop).
          if (servo.faulted() || servo.stopped()) break;
          ramping = true;
          ramp_start = t;
          ramp_first_step = servo.latest().cycle;
          estop.hold_for_shutdown();  // no announcement may release it now
        } else if (const bool still = servo.stopped();
                   still || t - ramp_start > kShutdownRampLimit) {
          const std::int64_t steps = servo.latest().cycle - ramp_first_step;
          const long ms =
              std::lround(std::chrono::duration<double, std::milli>(t - ramp_start).count());
          if (still)
            reporter.info(
                fmt::format("stopping: the robot was moving; brought to a standstill "
                            "within its acceleration limits in {} servo steps ({} ms)",
                            steps, ms));
          else
            reporter.warning(
                fmt::format("stopping: the robot was still moving after {} ms of "
                            "ramping down; the servo loop stops holding its last "
                            "setpoint",
                            ms));
          last_state = true;  // one more broadcast shows where the ramp left the robot
        }
      }
      next_state += kStatePeriod;
      std::this_thread::sleep_until(next_state);
      const auto now = std::chrono::steady_clock::now();
      if (now > next_state + kStatePeriod) next_state = now;  // fell behind: do not burst
      const edp::Reading reading = servo.latest();
      const edp::TimingWindow window = servo.take_timing_window();
      for (std::size_t i = 0; i < axes; ++i) {
        state.q[i] = reading.joints[i];
        state.dq[i] = reading.velocities[i];
        state.q_desired[i] = reading.desired[i];
      }
      state.synchronised = reading.synchronised;
      state.moving = servo.moving() || !servo.stopped();
      state.estop = servo.emergency_stopped();
      state.fault = servo.faulted();
      state.error = state.fault ? servo.fault_text() : std::string{};
      state.servo_step = reading.cycle;
      state.lateness_mean_us = window.lateness_mean_us;
      state.lateness_max_us = window.lateness_max_us;
      state.overruns = window.overruns_total;
      ++state_header.seq;
      state_header.utime = now_utime();
      comm::broadcast(bus, state_channel, state_header, state);
      if (last_state) break;

      overruns_unreported += window.overruns;
      worst_unreported_us = std::max(worst_unreported_us, window.worst_overrun_us);
      worst_work_us = std::max(worst_work_us, window.worst_work_us);
      worst_lock_wait_us = std::max(worst_lock_wait_us, window.worst_lock_wait_us);
      if (overruns_unreported > 0 && now >= overrun_quiet_until) {
        // The cycles' own work and lock waits beside the lateness: short ones mean the thread
        // was ready and the host (or a thread above it) did not run it.
        reporter.report(
            Severity::warning, edp::error_code::servo_overrun,
            fmt::format("servo loop overrun: {} cycle(s) woke more than one period "
                        "({:.0f} us) late, the worst {:.0f} us; {}; the longest cycle worked "
                        "{:.0f} us and waited {:.0f} us for its lock{}",
                        overruns_unreported, robot.edp.servo_period_s * 1e6, worst_unreported_us,
                        hardware->simulated()
                            ? (servo.caught_up_steps() > 0
                                   ? fmt::format("missed periods were skipped, and the simulation "
                                                 "makes them up between cycles ({} so far)",
                                                 servo.caught_up_steps())
                                   : std::string("missed periods were skipped"))
                            : fmt::format("missed periods were skipped, and a motion makes up "
                                          "their servo steps ({} so far)",
                                          servo.caught_up_steps()),
                        worst_work_us, worst_lock_wait_us,
                        worst_work_us < robot.edp.servo_period_s * 1e6
                            ? " (the thread was ready and not run: a host stall or a thread "
                              "above it)"
                            : ""));
        overruns_unreported = 0;
        worst_unreported_us = 0;
        worst_work_us = 0;
        worst_lock_wait_us = 0;
        overrun_quiet_until = now + kOverrunReportPeriod;
      }
      if (now >= next_report) {
        report_timing();
        next_report += kTimingReportPeriod;
      }
    }
    reporter.set_state(ProcessState::stopping);
    servo.stop();  // wakes a command waiting for a reading
    commands.join();
    report_timing();
    reporter.set_state(ProcessState::finished);
  } catch (const std::exception& e) {
    ConfigErrorList errors;  // every error of a ConfigErrors, one report each
    errors.add(e, {});
    for (const auto& error : errors.errors()) reporter.report(Severity::fatal, 0, error.what());
    reporter.set_state(ProcessState::failed, errors.errors().front().what());
    return 1;
  }
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  mrroc::CommandLine cli(
      "mrroc-edp",
      "mrroc-edp: Effector Driver Process. Interprets SET/GET/SET_GET/SYNCHRO/QUERY from its ECP, "
      "runs the servo loop and drives the robot through a hardware plugin. Normally started by "
      "mrroc-launch.");
  std::string config;
  std::string robot;
  cli.option("-c,--config", config, "process-set config file (TOML)").required();
  cli.option("-r,--robot", robot, "name of the robot ([[robot]] name in the config)").required();
  bool check_config = false;
  cli.flag("--check-config", check_config,
           "check the config as the EDP does at start (robot model, plugin library, plugin name, "
           "[robot.edp.params], the plugin's model files, kinematics), print every error as "
           "file:line and exit (0 valid, 2 errors); nothing is started, no device is opened (a "
           "plugin of real devices is not configured) and nothing is sent (mrroc-launch --check "
           "runs it)");
  if (const auto exit_code = cli.parse(argc, argv)) return *exit_code;
  mrroc::install_stop_handlers();
  try {
    if (check_config) return check(config, robot);
    return run(config, robot);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "mrroc-edp: %s\n", e.what());
    return 2;
  }
}
