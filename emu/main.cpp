// mrroc-axis-emu: the cell emulator. One MuJoCo world holds the whole cell (a scene file: several
// robots, the conveyor, objects); every axis appears on its CAN bus as an emulated CiA 402 drive
// (include/mrroc/can/cia402_drive.hpp), so that an EDP with the `can` plugin cannot tell it from
// real drives. Runs in real time, or lock-step (physics advances with the masters' SYNCs, as
// fast as they come). Faults can be injected (emu/faults.hpp). The scene's raw sensors (strain
// gauges, range finders, encoders, an emulated camera: emu/sensors.hpp) are sampled from the
// physics and published on LCM for the VSPs; the scene objects' poses for the console's 3D
// view (emu/object_poses.hpp). The drives' digital input lines follow the scene's wires (light
// barriers, grasps, loop-backs: emu/drives.hpp); their output lines are printed when they change.
// docs/hil.md.
#include <fmt/format.h>
#include <linux/can/error.h>
#include <pthread.h>
#include <sched.h>
#include <sys/prctl.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <ctime>
#include <iostream>
#include <map>
#include <memory>
#include <optional>
#include <random>
#include <string>
#include <thread>
#include <vector>

#include "cell_world.hpp"
#include "config_check.hpp"
#include "drives.hpp"
#include "faults.hpp"
#include "mrroc/can/bus.hpp"
#include "mrroc/can/canopen.hpp"
#include "mrroc/can/cia402_drive.hpp"
#include "mrroc/comm/auth.hpp"
#include "mrroc/comm/bus.hpp"
#include "mrroc/comm/reporter.hpp"
#include "mrroc/config/check.hpp"
#include "mrroc/config/process_set.hpp"
#include "mrroc/core/command_line.hpp"
#include "mrroc/core/error.hpp"
#include "mrroc/core/process.hpp"
#include "mrroc/core/time.hpp"
#include "object_poses.hpp"
#include "sensors.hpp"

namespace {

/// Real time: the longest hold-up of this process whose physics steps are made up afterwards [s]
/// (a shared host stops a CPU for up to 60 ms: docs/operating.md).
constexpr double kMaxCatchUpS = 0.1;

using namespace mrroc;
namespace co = can::canopen;

struct Options {
  std::filesystem::path scene;
  bool lock_step = false;
  std::vector<std::string> faults;
  std::map<std::string, std::string> buses;
  std::string lcm_url;
  std::filesystem::path auth_key_file;  ///< the set's key: raw samples are signed with it
  std::vector<int> cpus;
  int priority = 0;  ///< the process' threads; its stepping thread runs at 70 regardless
  double run_for_s = 0.0;
  bool print_scene = false;
};

struct Port;

struct Drive {
  std::size_t robot = 0;
  std::size_t axis = 0;
  std::unique_ptr<can::Cia402Drive> drive;
  co::DriveState reported = co::DriveState::switch_on_disabled;
  std::uint8_t outputs_reported = 0;  ///< the output lines last printed
  Port* port = nullptr;
};

struct Port {
  std::string url;
  std::unique_ptr<can::Bus> bus;
  std::vector<Drive*> drives;
  std::uint64_t syncs = 0;
  double period_s = kDefaultServoPeriodS;
  /// Real time: a frame received that was sent after the physics step now due; it is dispatched
  /// after that step (run_real_time).
  bool held = false;
  can::Received held_frame;
};

struct RobotRun {
  std::vector<Drive*> drives;
  emu::RobotDrives wiring;
  double enabled_at = -1.0;  ///< sim time all drives first reached operation enabled
  bool off = false;          ///< bus-off
  double off_until = -1.0;
  double drop = 0.0;
  std::uint64_t dropped = 0;
  std::vector<double> targets, feed_forward, position, velocity, force;
  std::vector<std::uint8_t> outputs, inputs;  ///< per axis: the drives' digital lines
};

struct Scheduled {
  emu::FaultSpec spec;
  std::size_t robot = 0;
  std::size_t axis = 0;
  bool done = false;
};

class Emulator {
 public:
  Emulator(const Options& options, Reporter* reporter, comm::Bus* lcm)
      : options_(options), reporter_(reporter), lcm_(lcm), world_(options.scene) {}

  void setup() {
    const std::vector<emu::RobotDrives> wiring =
        emu::read_drive_wiring(options_.scene, world_, options_.buses);
    robots_.resize(world_.robot_count());
    for (std::size_t k = 0; k < world_.robot_count(); ++k) {
      const emu::CellRobot& robot = world_.robot(k);
      const emu::RobotDrives& w = wiring[k];
      Port* port = nullptr;
      for (auto& p : ports_)
        if (p->url == w.bus) port = p.get();
      if (port == nullptr) {
        ports_.push_back(std::make_unique<Port>());
        port = ports_.back().get();
        port->url = w.bus;
        port->bus = can::open_bus(w.bus);
      }
      RobotRun& run = robots_[k];
      const std::size_t n = robot.axis_count();
      run.targets.assign(n, 0.0);
      run.feed_forward.assign(n, 0.0);
      run.position.assign(n, 0.0);
      run.velocity.assign(n, 0.0);
      run.force.assign(n, 0.0);
      run.outputs.assign(n, 0);
      run.inputs.assign(n, 0);
      run.wiring = w;
      for (std::size_t i = 0; i < n; ++i) {
        can::DriveConfig c;
        c.node = static_cast<std::uint8_t>(w.nodes[i]);
        c.counts_per_unit = w.counts_per_unit;
        c.current_limit = w.current_limit[i];
        if (i < w.eds.size()) c.eds = w.eds[i];
        auto d = std::make_unique<Drive>();
        d->robot = k;
        d->axis = i;
        d->port = port;
        d->drive = std::make_unique<can::Cia402Drive>(c, [this, port, k](const can_frame& f) {
          RobotRun& r = robots_[k];
          if (r.off) return;
          if (r.drop > 0.0 && uniform_(random_) < r.drop) {
            ++r.dropped;
            return;
          }
          (void)port->bus->send(f);
        });
        port->drives.push_back(d.get());
        run.drives.push_back(d.get());
        drives_.push_back(std::move(d));
      }
      std::vector<std::string> products;
      for (const Drive* d : run.drives) {
        const std::string name = d->drive->description().device().product_name;
        if (std::find(products.begin(), products.end(), name) == products.end())
          products.push_back(name);
      }
      std::cout << fmt::format(
          "mrroc-axis-emu: robot '{}': {} drives on {} (nodes {}), {} counts "
          "per unit, {}\n",
          robot.name, n, w.bus, fmt::join(w.nodes, ","), w.counts_per_unit,
          fmt::join(products, ", "));
      for (const emu::InputWire& input : w.inputs)
        std::cout << "mrroc-axis-emu: " << emu::describe_input(robot, input) << "\n";
    }
    setup_sensors();
    grips_reported_.assign(world_.grasp_count(), false);
    if (lcm_ != nullptr)  // the objects' poses for the console's 3D view (object_poses.hpp)
      poses_ = std::make_unique<emu::ObjectPosePublisher>(
          lcm_->lcm(), emu::load_scene(options_.scene), world_, "emu#" + std::to_string(::getpid()),
          lcm_->auth());
    std::vector<std::string> devices;
    for (std::size_t i = 0; i < sensors_->size(); ++i) devices.push_back(sensors_->config(i).name);
    for (const std::string& text : options_.faults) {
      const emu::ResolvedFault fault = emu::resolve_fault(text, world_, devices);
      Scheduled s;
      s.spec = fault.spec;
      s.robot = fault.robot;
      s.axis = fault.axis;
      schedule_.push_back(s);
    }
    // Power on every drive where its axis is.
    for (std::size_t k = 0; k < robots_.size(); ++k) {
      sample(k);
      for (Drive* d : robots_[k].drives) d->drive->power_on(axis_sample(k, d->axis), world_.time());
    }
  }

  void run() {
    if (options_.lock_step)
      run_lock_step();
    else
      run_real_time();
  }

  /// The grasped objects' peak internal forces (emu/cell_world.hpp, "Grasps").
  void print_grips() const {
    for (std::size_t i = 0; i < world_.held_object_count(); ++i)
      std::cout << fmt::format(
          "mrroc-axis-emu: object '{}': peak internal force {:.2f} N at t = {:.3f} s\n",
          world_.held_object(i), world_.peak_internal_force(i), world_.peak_internal_force_time(i));
  }

  /// The grooves the cutters left (emu/cell_world.hpp, "Cutting").
  void print_grooves() const {
    for (std::size_t c = 0; c < world_.cut_count(); ++c) {
      const emu::CutSummary& s = world_.cut_summary(c);
      std::cout << fmt::format(
          "mrroc-axis-emu: board '{}' cut by '{}': {} strokes, cut length {:.3f} m, max depth "
          "{:.2f} mm, peak force {:.1f} N, {:.2f} s cutting{}\n",
          world_.cut(c).object, world_.cut(c).cutter, s.strokes, s.length, s.max_depth * 1e3,
          s.peak_force, s.cutting_time, world_.groove_full(c) ? " (groove record full)" : "");
    }
  }

  [[nodiscard]] std::uint64_t steps() const { return steps_; }
  [[nodiscard]] std::uint64_t samples_published() const {
    return publisher_ ? publisher_->published() : 0;
  }

 private:
  /// The scene's raw sensor devices, published on LCM (without LCM they are only sampled).
  void setup_sensors() {
    sensors_ = std::make_unique<emu::SensorDevices>(options_.scene, world_);
    for (std::size_t i = 0; i < sensors_->size(); ++i)
      std::cout << "mrroc-axis-emu: " << sensors_->describe(i) << "\n";
    if (sensors_->size() == 0) return;
    if (lcm_ == nullptr) {
      const std::size_t n = sensors_->size();
      report_warning(fmt::format("no LCM: {} raw sensor device(s) sampled, not published", n));
      return;
    }
    publisher_ = std::make_unique<emu::RawSamplePublisher>(
        lcm_->lcm(), *sensors_, "emu#" + std::to_string(::getpid()), lcm_->auth());
  }

  /// After a physics step: the samples that are due, published.
  void sample_sensors() {
    if (sensors_->size() == 0) return;
    const std::int64_t now = now_utime();
    for (const std::size_t i : sensors_->update(world_, now)) {
      if (!silenced_.empty() && std::find(silenced_.begin(), silenced_.end(),
                                          sensors_->config(i).name) != silenced_.end())
        continue;
      if (publisher_ && !publisher_->publish(i, sensors_->sample(i), now) &&
          !publish_failure_reported_) {
        publish_failure_reported_ = true;
        const std::string& name = sensors_->config(i).name;
        report_warning(fmt::format("sensor '{}': LCM refused a raw sample (and maybe more)", name));
      }
    }
  }

  can::AxisSample axis_sample(std::size_t k, std::size_t i) const {
    const RobotRun& r = robots_[k];
    return {r.position[i], r.velocity[i], r.force[i], world_.synchro_switch(k, i), r.inputs[i]};
  }

  /// Robot k's axes and the drives' input lines, from the world now and the drives' outputs.
  void sample(std::size_t k) {
    RobotRun& r = robots_[k];
    world_.actuator_positions(k, r.position);
    world_.actuator_velocities(k, r.velocity);
    world_.actuator_forces(k, r.force);
    for (std::size_t i = 0; i < r.drives.size(); ++i)
      r.outputs[i] = r.drives[i]->drive->output_lines();
    (void)emu::evaluate_inputs(r.wiring, world_, r.outputs, r.inputs);
  }

  /// A drive's output lines, printed when they changed.
  void watch_outputs(Drive& d, double now) {
    const std::uint8_t outputs = d.drive->output_lines();
    if (outputs == d.outputs_reported) return;
    d.outputs_reported = outputs;
    std::cout << fmt::format(
                     "mrroc-axis-emu: robot '{}' axis '{}' outputs 0x{:02X} at t = {:.3f} "
                     "s\n",
                     world_.robot(d.robot).name, world_.robot(d.robot).axis_names[d.axis], outputs,
                     now)
              << std::flush;
  }

  void dispatch(Port& port, const can::Received& r) {
    const double now = world_.time();
    if (!r.is_error() && (r.frame.can_id & CAN_SFF_MASK) == co::kSyncId) ++port.syncs;
    for (Drive* d : port.drives) {
      if (robots_[d->robot].off) continue;
      d->drive->on_frame(r.frame, now);
    }
  }

  void physics_step() {
    for (std::size_t k = 0; k < robots_.size(); ++k) {
      RobotRun& r = robots_[k];
      for (std::size_t i = 0; i < r.drives.size(); ++i) {
        r.targets[i] = r.drives[i]->drive->demand();
        r.feed_forward[i] = r.drives[i]->drive->demand_velocity();
      }
      (void)world_.set_targets(k, r.targets);
      (void)world_.set_velocity_feed_forward(k, r.feed_forward);
    }
    if (!world_.step() && !world_fault_reported_) {
      world_fault_reported_ = true;
      report_error(co::emcy::kDeviceHardware, std::string("physics: ") + world_.fault_text());
      for (auto& d : drives_) d->drive->inject_fault(co::emcy::kDeviceHardware, world_.time());
    }
    ++steps_;
    const double now = world_.time();
    for (std::size_t g = 0; g < world_.grasp_count(); ++g) {
      if (grips_reported_[g] || !world_.grasp_engaged(g)) continue;
      grips_reported_[g] = true;
      std::cout << fmt::format("mrroc-axis-emu: object '{}' grasped by '{}' at t = {:.3f} s\n",
                               world_.grasp(g).object, world_.grasp(g).gripper, now)
                << std::flush;
    }
    for (std::size_t k = 0; k < robots_.size(); ++k) {
      sample(k);
      RobotRun& r = robots_[k];
      if (r.off && r.off_until >= 0.0 && now >= r.off_until) {
        r.off = false;
        report_warning(
            fmt::format("robot '{}': drives back on the bus after bus-off", world_.robot(k).name));
      }
      bool all_enabled = true;
      for (Drive* d : r.drives) {
        d->drive->update(axis_sample(k, d->axis), now);
        all_enabled = all_enabled && d->drive->state() == co::DriveState::operation_enabled;
        watch(*d);
        watch_outputs(*d, now);
      }
      if (all_enabled && r.enabled_at < 0.0) {
        r.enabled_at = now;
        std::cout << fmt::format(
                         "mrroc-axis-emu: robot '{}': all drives operation enabled at "
                         "t = {:.3f} s\n",
                         world_.robot(k).name, now)
                  << std::flush;
      }
    }
    inject_due_faults(now);
    sample_sensors();
    if (poses_) (void)poses_->update(world_, now_utime());
  }

  void watch(Drive& d) {
    const co::DriveState state = d.drive->state();
    if (state == d.reported) return;
    d.reported = state;
    if (state == co::DriveState::fault) {
      const std::uint16_t code = d.drive->last_emcy();
      report_error(code, fmt::format("robot '{}' axis {} '{}' (node {} on {}): drive fault, EMCY "
                                     "0x{:04X} {}",
                                     world_.robot(d.robot).name, d.axis,
                                     world_.robot(d.robot).axis_names[d.axis], d.drive->node(),
                                     d.port->url, code, co::describe_emcy(code)));
    } else if (const std::uint16_t code = d.drive->communication_error();
               code != 0 && state != co::DriveState::operation_enabled) {
      // The drive's supervision of its master (0x1016 heartbeat, 0x1006 SYNC) reacted.
      report_error(code, fmt::format("robot '{}' axis {} '{}' (node {} on {}): master lost, EMCY "
                                     "0x{:04X} {}: {} at t = {:.3f} s (wall clock {:.6f} s)",
                                     world_.robot(d.robot).name, d.axis,
                                     world_.robot(d.robot).axis_names[d.axis], d.drive->node(),
                                     d.port->url, code, co::describe_emcy(code),
                                     co::to_string(state), d.drive->communication_error_at(),
                                     std::chrono::duration<double>(
                                         std::chrono::system_clock::now().time_since_epoch())
                                         .count()));
    }
  }

  void inject_due_faults(double now) {
    for (Scheduled& s : schedule_) {
      RobotRun& r = robots_[s.robot];
      if (s.done || r.enabled_at < 0.0 || now < r.enabled_at + s.spec.at_s) continue;
      s.done = true;
      report_warning(fmt::format("injecting fault {}", s.spec.text));
      switch (s.spec.kind) {
        case emu::FaultKind::drive: r.drives[s.axis]->drive->inject_fault(s.spec.code, now); break;
        case emu::FaultKind::silent: r.drives[s.axis]->drive->set_silent(true); break;
        case emu::FaultKind::sensor: silenced_.push_back(s.spec.device); break;
        case emu::FaultKind::drop: r.drop = s.spec.fraction; break;
        case emu::FaultKind::bus_off: {
          can_frame f{};
          f.can_id = CAN_ERR_FLAG | CAN_ERR_BUSOFF;
          f.len = CAN_ERR_DLC;
          (void)r.drives.front()->port->bus->send(f);
          r.off = true;
          r.off_until = s.spec.duration_s > 0.0 ? now + s.spec.duration_s : -1.0;
          break;
        }
      }
    }
  }

  void report_error(int code, const std::string& text) {
    std::cerr << "mrroc-axis-emu: " << text << "\n";
    if (reporter_ != nullptr) reporter_->error(code, text);
  }
  void report_warning(const std::string& text) {
    std::cerr << "mrroc-axis-emu: " << text << "\n";
    if (reporter_ != nullptr) reporter_->warning(text);
  }

  bool done() const {
    return stop_requested() || (options_.run_for_s > 0.0 && world_.time() >= options_.run_for_s);
  }

  /// Dispatches every frame sent up to `until_ns` (CLOCK_MONOTONIC) and holds the first later
  /// one of each bus for the next step.
  void drain_until(std::int64_t until_ns, std::int64_t realtime_minus_monotonic_ns) {
    can::Received r;
    for (auto& p : ports_) {
      if (p->held) {
        if (p->held_frame.timestamp_ns - realtime_minus_monotonic_ns > until_ns) continue;
        p->held = false;
        dispatch(*p, p->held_frame);
      }
      while (p->bus->receive(r, std::chrono::nanoseconds(0))) {
        if (r.timestamp_ns != 0 && r.timestamp_ns - realtime_minus_monotonic_ns > until_ns) {
          p->held = true;
          p->held_frame = r;
          break;
        }
        dispatch(*p, r);
      }
    }
  }

  /// Real time: one physics step per timestep of the monotonic clock, and every frame dispatched
  /// between the steps of the time it was sent. After this process was held up (the host ran
  /// something else), the steps it owes run back to back, each with the frames of its time: so a
  /// drive answers each SYNC with the axis as it was at that SYNC, as a real one, not with one
  /// sample repeated for every SYNC that queued up meanwhile (a master read that as the axis
  /// standing still mid-motion). A hold-up longer than kMaxCatchUpS is not made up:
  /// the world loses that time.
  void run_real_time() {
    const auto step_ns = static_cast<std::int64_t>(std::llround(world_.timestep() * 1e9));
    const auto clock_ns = [](clockid_t clock) {
      timespec t{};
      clock_gettime(clock, &t);
      return static_cast<std::int64_t>(t.tv_sec) * 1000000000LL + t.tv_nsec;
    };
    const auto now_ns = [&] { return clock_ns(CLOCK_MONOTONIC); };
    const auto max_behind_ns = static_cast<std::int64_t>(kMaxCatchUpS * 1e9);
    std::int64_t deadline = now_ns();
    can::Received r;
    while (!done()) {
      deadline += step_ns;
      for (;;) {
        const std::int64_t offset = clock_ns(CLOCK_REALTIME) - now_ns();
        drain_until(deadline, offset);
        const std::int64_t left = deadline - now_ns();
        if (left <= 0) break;
        if (ports_.size() == 1 && !ports_[0]->held) {
          if (ports_[0]->bus->receive(r, std::chrono::nanoseconds(left))) {
            if (r.timestamp_ns != 0 && r.timestamp_ns - offset > deadline) {
              ports_[0]->held = true;
              ports_[0]->held_frame = r;
            } else {
              dispatch(*ports_[0], r);
            }
          }
        } else {
          std::this_thread::sleep_for(
              std::chrono::nanoseconds(std::min<std::int64_t>(left, 200000)));
        }
      }
      physics_step();
      if (now_ns() - deadline > max_behind_ns) deadline = now_ns();
    }
  }

  void run_lock_step() {
    can::Received r;
    while (!done()) {
      bool got = false;
      for (auto& p : ports_) {
        const auto wait =
            ports_.size() == 1 ? std::chrono::nanoseconds(100000000) : std::chrono::nanoseconds(0);
        while (p->bus->receive(r, wait)) {
          dispatch(*p, r);
          got = true;
          if ((r.frame.can_id & CAN_SFF_MASK) == co::kSyncId) break;
        }
      }
      if (!got && ports_.size() > 1) std::this_thread::sleep_for(std::chrono::microseconds(100));
      // Physics catches up with the furthest master (SYNCs times its cycle).
      double target = 0.0;
      for (auto& p : ports_) {
        if (!p->drives.empty()) p->period_s = p->drives.front()->drive->interpolation_period_s();
        target = std::max(target, static_cast<double>(p->syncs) * p->period_s);
      }
      while (world_.time() + 0.5 * world_.timestep() < target && !done()) physics_step();
    }
  }

  Options options_;
  Reporter* reporter_;
  comm::Bus* lcm_;
  emu::CellWorld world_;
  std::unique_ptr<emu::SensorDevices> sensors_;
  std::unique_ptr<emu::RawSamplePublisher> publisher_;
  std::unique_ptr<emu::ObjectPosePublisher> poses_;
  bool publish_failure_reported_ = false;
  std::vector<std::unique_ptr<Port>> ports_;
  std::vector<std::unique_ptr<Drive>> drives_;
  std::vector<RobotRun> robots_;
  std::vector<Scheduled> schedule_;
  std::vector<std::string> silenced_;  ///< raw sensor devices that stopped publishing
  std::mt19937 random_{12345};
  std::uniform_real_distribution<double> uniform_{0.0, 1.0};
  bool world_fault_reported_ = false;
  std::vector<bool> grips_reported_;  ///< per grasp: its engagement was printed
  std::uint64_t steps_ = 0;
};

void real_time_priority() {
  sched_param sp{};
  sp.sched_priority = 70;
  if (pthread_setschedparam(pthread_self(), SCHED_FIFO, &sp) != 0)
    prctl(PR_SET_TIMERSLACK, 1UL, 0UL, 0UL, 0UL);
}

}  // namespace

/// --check-config: the process set's errors and the emulator's (emu::check_emulator_config),
/// one per line on stderr; nothing is opened, nothing sent.
int check(const std::string& config_path) {
  using namespace mrroc;
  if (config_path.empty()) {
    std::fprintf(stderr, "mrroc-axis-emu: --check-config needs --config (a process set)\n");
    return kUsageError;
  }
  ConfigErrorList errors;
  try {
    const ProcessSetCheck set = check_process_set(config_path);
    errors.add(set.errors);
    if (!set.broken_process("emu")) errors.add(emu::check_emulator_config(set.config));
  } catch (const std::exception& e) {
    errors.add(e, SourceLocation::whole_file(config_path));
  }
  for (const auto& error : errors.errors()) std::fprintf(stderr, "%s\n", error.what());
  if (!errors.empty()) return kExitConfigErrors;
  std::printf("mrroc-axis-emu: emu: config is valid\n");
  return 0;
}

int main(int argc, char** argv) {
  mrroc::CommandLine cli(
      "mrroc-axis-emu",
      "mrroc-axis-emu: the cell emulator. One MuJoCo world from a scene file; every axis is an "
      "emulated CANopen CiA 402 drive on a CAN bus (virtual or SocketCAN), so the EDP's `can` "
      "plugin drives it like real hardware. See docs/hil.md.");
  Options options;
  std::string config;
  std::string scene;
  std::vector<std::string> bus_overrides;
  cli.option("-c,--config", config,
             "process-set config file (TOML); its [emulator] table gives the scene, lock_step "
             "and faults");
  cli.option("-s,--scene", scene, "scene file (TOML; configs/scenes/); instead of --config");
  cli.flag("--lock-step", options.lock_step,
           "advance the physics by the masters' SYNCs (as fast as they come) instead of in "
           "real time");
  cli.option("--fault", options.faults,
             "inject a fault (repeatable): drive:<robot>/<axis>@<s>[=<hex code>], "
             "silent:<robot>/<axis>@<s>, drop:<robot>@<s>=<fraction>, busoff:<robot>@<s>[+<s>]; "
             "sensor:<device>@<s>; <s> counts from the robot's drives being enabled");
  cli.option("--bus", bus_overrides,
             "put a robot's drives on another bus: <robot>=<url>, e.g. irb6=socketcan:vcan0 "
             "(repeatable)");
  cli.option("--lcm-url", options.lcm_url, "LCM URL for SRP messages (default: the config's)");
  cli.option("--run-for", options.run_for_s, "stop after this much simulated time [s]").positive();
  cli.flag("--print-scene", options.print_scene, "print the composed MJCF and exit");
  bool check_config = false;
  cli.flag("--check-config", check_config,
           "check the process set's [emulator] part (its scene, drives, sensors, faults, and the "
           "set's robots on emulated buses against it), print every error, and exit (2: errors "
           "found); nothing is opened or sent");
  if (const auto exit_code = cli.parse(argc, argv)) return *exit_code;

  using namespace mrroc;
  if (check_config) return check(config);
  install_stop_handlers();
  std::string process = "emu";
  try {
    if (config.empty() == scene.empty())
      throw ConfigError("give exactly one of --config (a process set with [emulator]) or --scene");
    if (!config.empty()) {
      const ProcessSetConfig set = load_process_set(config);
      if (!set.emulator)
        throw ConfigError(SourceLocation::whole_file(set.file.string()),
                          "no [emulator] table in the process set");
      options.scene = set.emulator->scene;
      options.lock_step = options.lock_step || set.emulator->lock_step;
      options.faults.insert(options.faults.begin(), set.emulator->faults.begin(),
                            set.emulator->faults.end());
      options.cpus = set.emulator->options.cpus;
      options.priority = set.emulator->options.priority;
      if (options.lcm_url.empty()) options.lcm_url = set.lcm_url;
      options.auth_key_file = set.auth_key_file;
    } else {
      options.scene = scene;
    }
    for (const std::string& b : bus_overrides) {
      const std::size_t eq = b.find('=');
      if (eq == std::string::npos || eq == 0 || eq + 1 == b.size())
        throw ConfigError("--bus '" + b + "' must be <robot>=<url>, e.g. irb6=socketcan:vcan0");
      options.buses[b.substr(0, eq)] = b.substr(eq + 1);
    }
    for (const std::string& f : options.faults) (void)emu::parse_fault(f);  // errors before start
  } catch (const Error& e) {
    std::fprintf(stderr, "mrroc-axis-emu: %s\n", e.what());
    return 2;
  }

  if (options.print_scene) {
    try {
      const emu::CellWorld world(options.scene);
      std::cout << world.composed_xml();
      return 0;
    } catch (const Error& e) {
      std::fprintf(stderr, "mrroc-axis-emu: %s\n", e.what());
      return 2;
    }
  }

  apply_cpu_affinity(options.cpus);
  const std::string scheduling = apply_priority(options.priority);
  std::unique_ptr<comm::Bus> lcm;
  std::unique_ptr<Reporter> reporter;
  try {
    lcm = std::make_unique<comm::Bus>(options.lcm_url);
  } catch (const Error& e) {
    std::fprintf(stderr, "mrroc-axis-emu: LCM unavailable (%s); SRP messages only on stderr\n",
                 e.what());
  }
  if (lcm) {
    try {
      comm::enable_auth_from_file(*lcm, options.auth_key_file);  // a bad key file is fatal
    } catch (const Error& e) {
      std::fprintf(stderr, "mrroc-axis-emu: %s\n", e.what());
      return 1;
    }
    lcm->start();
    reporter = std::make_unique<Reporter>(*lcm, process);
  }
  try {
    Emulator emulator(options, reporter.get(), lcm.get());
    emulator.setup();
    std::cout << "mrroc-axis-emu: " << lock_memory() << "; " << scheduling << "; "
              << (options.lock_step ? "lock-step" : "real time") << "\n"
              << std::flush;
    if (reporter) {
      reporter->set_state(ProcessState::ready);
      reporter->info(std::string("cell emulator ready (") +
                     (options.lock_step ? "lock-step" : "real time") + ")");
    }
    real_time_priority();
    emulator.run();
    emulator.print_grips();
    emulator.print_grooves();
    std::cout << fmt::format("mrroc-axis-emu: stopped after {} physics steps, {} raw samples\n",
                             emulator.steps(), emulator.samples_published());
    if (reporter) reporter->set_state(ProcessState::finished);
    return 0;
  } catch (const ConfigError& e) {
    std::fprintf(stderr, "mrroc-axis-emu: %s\n", e.what());
    if (reporter) reporter->error(2, e.what());
    return 2;
  } catch (const Error& e) {
    std::fprintf(stderr, "mrroc-axis-emu: %s\n", e.what());
    if (reporter) {
      reporter->error(3, e.what());
      reporter->set_state(ProcessState::failed, e.what());
    }
    return 3;
  }
}
