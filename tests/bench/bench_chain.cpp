// B1: macro-step round trip MP -> ECP -> EDP (MuJoCo) -> ECP -> MP against a bare LCM
// two-process round trip; B4: macro-steps per second when not paced against the rate of a bare LCM
// three-process chain (driver -> relay -> echo -> relay -> driver).
//
// Value: this program starts the real mrroc-edp (plugin "mujoco", IRb-6, 2 ms servo period) and
// mrroc-ecp (task "follow_mp") from a generated config, waits for both to report ready, and acts as
// the MP with mrroc::mp::Robot: START_TASK once (the ECP synchronises the robot), then timed
// next_pose() calls, each one NEXT_POSE macro-step in JOINT coordinates:
//  - B1, paced: isolated macro-steps of 1 servo step, alternating the column between two positions
//    1.5 urad apart (half as far as the column's acceleration limit allows a move of one step
//    from rest to rest), read after the motion stopped (value_in_step_no = motion_steps + 1 = 2): a
//    macro-step read in its last step (value_in_step_no = motion_steps) promises a successor
//    within the same servo cycle, which a paced MP never sends, and the EDP then brings the robot
//    to a standstill on its own;
//  - B4, unpaced: a continuous motion of the column at 0.05 rad/s (reached from rest at
//    0.5 rad/s^2) in macro-steps of 2 servo steps
//    read in step 1 (value_in_step_no = 1), each sent as soon as the previous reply arrives, so
//    that it is queued in the EDP before the running one ends.
// Other macro-step parameters: bench_chain SAMPLES B1_STEPS B1_VALUE B4_STEPS B4_VALUE.
//
// Baselines (no mrroc code): raw lcm::LCM publish/subscribe of a 64-byte message between this
// program and child processes it starts (this executable again, in a forwarding role): an echo
// (two processes) and a relay + echo (three processes, a chain of four hops as MP -> ECP -> EDP).
// Same LCM URL as the process set, same pacing, same count, nothing pinned, default scheduling.
// Half of each baseline runs before the process set is started and half after it stopped, so slow
// drift of the host affects both sides alike and no mrroc process is alive during a baseline.
//
// Pacing (B1): 200 Hz on average; each deadline is shifted by a golden-ratio sequence over one
// servo period, so that the MP's phase against the EDP's servo clock is sampled evenly (a fixed
// 5 ms pace on a 2 ms servo clock would hit only two phases). B4 is not paced.
//
// CPU time (from /proc/<pid>/task/*/schedstat) of every process during the unpaced series is
// reported per macro-step and per bare round trip; for the EDP, the CPU time its servo loop takes
// while idle (measured for 1 s before the series) is subtracted.
//
// The process set is run a second time with a 1 ms servo period (half the samples), to show how
// the round trip depends on the wait for the servo cycle.
//
// Usage (inside scripts/netns-run): bench_chain [samples [b1_steps b1_value b4_steps b4_value]]
// (default 2000 1 2 2 1)
// Prints "RESULT B1 ..." and "RESULT B4 ...".
#include <fcntl.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <mutex>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include <lcm/lcm-cpp.hpp>

#include "bench_args.hpp"
#include "bench_release.hpp"
#include "mrroc/comm/bus.hpp"
#include "mrroc/comm/reporter.hpp"
#include "mrroc/comm/request_reply.hpp"
#include "mrroc/core/error.hpp"
#include "mrroc/core/time.hpp"
#include "mrroc/mp/robot.hpp"
#include "mrroc_lcm/emergency_stop_t.hpp"

extern char** environ;

namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

constexpr const char* kUrl = "udpm://239.255.76.67:7667?ttl=0";
constexpr std::int64_t kPacePeriodNs = 5'000'000;  // 200 Hz
constexpr std::size_t kPayloadBytes = 64;

std::int64_t now_ns() {
  timespec t{};
  clock_gettime(CLOCK_MONOTONIC, &t);
  return static_cast<std::int64_t>(t.tv_sec) * 1'000'000'000LL + t.tv_nsec;
}

double percentile(std::vector<double> v, double p) {
  if (v.empty()) return 0.0;
  std::sort(v.begin(), v.end());
  return v[static_cast<std::size_t>(p * static_cast<double>(v.size() - 1))];
}

/// 200 Hz on average; deadline k = start + k * 5 ms + frac(k * golden) * sweep.
class Pacer {
 public:
  explicit Pacer(std::int64_t sweep_ns) : start_(now_ns() + kPacePeriodNs), sweep_(sweep_ns) {}
  void wait() {
    const double phase = std::fmod(static_cast<double>(k_) * 0.6180339887498949, 1.0);
    const std::int64_t deadline = start_ + k_ * kPacePeriodNs +
                                  static_cast<std::int64_t>(phase * static_cast<double>(sweep_));
    ++k_;
    timespec wake{};
    wake.tv_sec = static_cast<time_t>(deadline / 1'000'000'000LL);
    wake.tv_nsec = static_cast<long>(deadline % 1'000'000'000LL);
    while (clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &wake, nullptr) == EINTR) {
    }
  }

 private:
  std::int64_t start_;
  std::int64_t sweep_;
  std::int64_t k_ = 0;
};

/// CPU time [ns] used so far by all threads of `pid`.
double cpu_ns(pid_t pid) {
  double total = 0;
  std::error_code ec;
  for (const auto& task : fs::directory_iterator("/proc/" + std::to_string(pid) + "/task", ec)) {
    std::ifstream in(task.path() / "schedstat");
    double on_cpu = 0;
    if (in >> on_cpu) total += on_cpu;
  }
  return total;
}

// ---- Child processes ----

struct Child {
  std::string name;
  pid_t pid = -1;
  std::string log;
};

Child spawn(const std::string& name, const std::vector<std::string>& args, const std::string& log) {
  std::vector<char*> argv;
  for (const auto& a : args) argv.push_back(const_cast<char*>(a.c_str()));
  argv.push_back(nullptr);
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_addopen(&actions, 1, log.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
  posix_spawn_file_actions_adddup2(&actions, 1, 2);
  Child c{name, -1, log};
  const int rc = posix_spawn(&c.pid, argv[0], &actions, nullptr, argv.data(), environ);
  posix_spawn_file_actions_destroy(&actions);
  if (rc != 0) throw mrroc::Error("cannot start " + args[0] + ": " + std::strerror(rc));
  return c;
}

/// SIGTERM, up to 5 s for the exit, then SIGKILL.
void stop(Child& c) {
  if (c.pid <= 0) return;
  ::kill(c.pid, SIGTERM);
  for (int i = 0; i < 500; ++i) {
    int status = 0;
    if (::waitpid(c.pid, &status, WNOHANG) == c.pid) {
      c.pid = -1;
      return;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  ::kill(c.pid, SIGKILL);
  ::waitpid(c.pid, nullptr, 0);
  c.pid = -1;
}

std::string tail_of(const std::string& path) {
  std::ifstream in(path);
  std::stringstream s;
  s << in.rdbuf();
  std::string text = s.str();
  if (text.size() > 2000) text = text.substr(text.size() - 2000);
  return text;
}

/// Stops the children in reverse order when the scope ends.
class Children {
 public:
  Children() = default;
  Children(const Children&) = delete;
  Children& operator=(const Children&) = delete;
  ~Children() { stop_all(); }
  Child& add(Child c) {
    list_.push_back(std::move(c));
    return list_.back();
  }
  void stop_all() {
    for (auto it = list_.rbegin(); it != list_.rend(); ++it) stop(*it);
    list_.clear();
  }
  [[nodiscard]] std::string logs() const {
    std::string out;
    for (const auto& c : list_) out += "--- " + c.name + " (" + c.log + "):\n" + tail_of(c.log);
    return out;
  }

 private:
  std::vector<Child> list_;
};

// ---- Bare LCM (no mrroc code) ----

/// Forwarding role: every message on in[i] is published unchanged on out[i].
int run_forwarder(const std::vector<std::string>& pairs) {
  lcm::LCM lcm(kUrl);
  if (!lcm.good()) return 1;
  struct Route {
    lcm::LCM* lcm;
    std::string out;
  };
  std::vector<Route> routes;
  routes.reserve(pairs.size() / 2);
  for (std::size_t i = 0; i + 1 < pairs.size(); i += 2) {
    routes.push_back({&lcm, pairs[i + 1]});
    lcm.subscribeFunction<Route*>(
        pairs[i],
        [](const lcm::ReceiveBuffer* rbuf, const std::string&, Route* route) {
          route->lcm->publish(route->out, rbuf->data, rbuf->data_size);
        },
        &routes.back());
  }
  for (;;) lcm.handle();
}

/// The driver's side of a bare ping-pong: publishes on `out`, waits for its echo on `in`.
class RawPinger {
 public:
  RawPinger(const std::string& out, const std::string& in) : lcm_(kUrl), out_(out) {
    if (!lcm_.good()) throw mrroc::Error(std::string("cannot open LCM at ") + kUrl);
    lcm_.subscribeFunction<RawPinger*>(
        in,
        [](const lcm::ReceiveBuffer* rbuf, const std::string&, RawPinger* self) {
          std::uint64_t seq = 0;
          if (rbuf->data_size >= sizeof seq) std::memcpy(&seq, rbuf->data, sizeof seq);
          if (seq == self->seq_) self->answered_ = true;
        },
        this);
  }
  /// One round trip; false when no answer came within `timeout_ms`.
  bool ping(int timeout_ms) {
    std::uint8_t payload[kPayloadBytes] = {};
    ++seq_;
    std::memcpy(payload, &seq_, sizeof seq_);
    answered_ = false;
    lcm_.publish(out_, payload, static_cast<unsigned>(sizeof payload));
    const std::int64_t until = now_ns() + static_cast<std::int64_t>(timeout_ms) * 1'000'000LL;
    while (!answered_) {
      const std::int64_t left_ms = (until - now_ns()) / 1'000'000LL;
      if (left_ms < 0) return false;
      lcm_.handleTimeout(static_cast<int>(left_ms) + 1);
    }
    return true;
  }
  /// Pings until the peer answers (its subscription is up). @throws Error after `seconds`.
  void wait_for_peer(double seconds) {
    const auto until = Clock::now() + std::chrono::duration<double>(seconds);
    while (!ping(100))
      if (Clock::now() > until)
        throw mrroc::Error("bare LCM peer on '" + out_ + "' never answered");
    for (int i = 0; i < 50; ++i) (void)ping(100);  // warm-up
  }

 private:
  lcm::LCM lcm_;
  std::string out_;
  std::uint64_t seq_ = 0;
  bool answered_ = false;
};

struct Series {
  std::vector<double> us;
  int lost = 0;
  double seconds = 0.0;  // wall time of the whole series (unpaced rate)
  /// CPU time per sample [us] of the processes involved (unpaced series).
  std::map<std::string, double> cpu_ns_total;
  void add_cpu(const std::string& who, double ns) { cpu_ns_total[who] += ns; }
  [[nodiscard]] double cpu_us_per_sample(const std::string& who) const {
    auto it = cpu_ns_total.find(who);
    return it == cpu_ns_total.end() || us.empty()
               ? 0.0
               : it->second / 1000.0 / static_cast<double>(us.size());
  }
};

/// Bare two-process round trips, paced (B1 baseline) and three-process chain round trips,
/// unpaced (B4 baseline), `paced` and `unpaced` samples each, appended to the series.
void run_bare(const std::string& self, const fs::path& dir, int paced, int unpaced,
              Series& two_process, Series& chain) {
  Children children;
  children.add(
      spawn("echo", {self, "--forward", "BENCH_PING", "BENCH_PONG"}, (dir / "echo.log").string()));
  const pid_t relay =
      children
          .add(spawn("relay", {self, "--forward", "BENCH_A", "BENCH_B", "BENCH_C", "BENCH_D"},
                     (dir / "relay.log").string()))
          .pid;
  const pid_t echo = children
                         .add(spawn("chain-echo", {self, "--forward", "BENCH_B", "BENCH_C"},
                                    (dir / "chain-echo.log").string()))
                         .pid;
  RawPinger two(std::string("BENCH_PING"), std::string("BENCH_PONG"));
  RawPinger three(std::string("BENCH_A"), std::string("BENCH_D"));
  two.wait_for_peer(10);
  three.wait_for_peer(10);
  Pacer pacer(2'000'000);
  for (int i = 0; i < paced; ++i) {
    pacer.wait();
    const std::int64_t t0 = now_ns();
    if (!two.ping(1000)) {
      ++two_process.lost;
      continue;
    }
    two_process.us.push_back(static_cast<double>(now_ns() - t0) / 1000.0);
  }
  const double cpu0[3] = {cpu_ns(getpid()), cpu_ns(relay), cpu_ns(echo)};
  const std::int64_t start = now_ns();
  for (int i = 0; i < unpaced; ++i) {
    const std::int64_t t0 = now_ns();
    if (!three.ping(1000)) {
      ++chain.lost;
      continue;
    }
    chain.us.push_back(static_cast<double>(now_ns() - t0) / 1000.0);
  }
  chain.seconds += static_cast<double>(now_ns() - start) / 1e9;
  chain.add_cpu("driver", cpu_ns(getpid()) - cpu0[0]);
  chain.add_cpu("relay", cpu_ns(relay) - cpu0[1]);
  chain.add_cpu("echo", cpu_ns(echo) - cpu0[2]);
}

// ---- The process set ----

class ReadyWatch {
 public:
  void on_status(const mrroc::ProcessStatus& s) {
    std::lock_guard lock(mutex_);
    states_[s.process] = s.state;
    cv_.notify_all();
  }
  bool wait_ready(const std::string& process, double seconds) {
    std::unique_lock lock(mutex_);
    return cv_.wait_for(lock, std::chrono::duration<double>(seconds), [&] {
      auto it = states_.find(process);
      return it != states_.end() && (it->second == mrroc::ProcessState::ready ||
                                     it->second == mrroc::ProcessState::running);
    });
  }

 private:
  std::mutex mutex_;
  std::condition_variable cv_;
  std::map<std::string, mrroc::ProcessState> states_;
};

struct ChainFigures {
  Series paced;
  Series unpaced;
  double edp_idle_cpu_us_per_ms = 0;  // the EDP's CPU time while no macro-step runs
  /// Unpaced macro-steps the EDP refused after it had stopped the robot for want of a successor
  /// in time (real time only); the series goes on from where the robot stands.
  int refused_after_late = 0;
};

/// Macro-step parameters (motion_steps, value_in_step_no) of the paced and unpaced series.
struct StepShape {
  int paced_steps = 1;
  int paced_value = 2;
  int unpaced_steps = 2;
  int unpaced_value = 1;
};

ChainFigures run_process_set(const fs::path& bin, const fs::path& dir, double servo_period_ms,
                             bool lock_step, int paced, int unpaced, const StepShape& shape) {
  const fs::path config = dir / "bench-chain.toml";
  std::ofstream(config) << "[system]\nname = \"bench-chain\"\nlcm_url = \"" << kUrl << "\"\n"
                        << "[mp]\ntask = \"start_and_wait\"\n"
                        << "[[robot]]\nname = \"irb6\"\nmodel = \"" << MRROC_SOURCE_DIR
                        << "/robots/irb6\"\n[robot.edp]\nplugin = \"mujoco\"\nservo_period_ms = "
                        << servo_period_ms << "\nlock_step = " << (lock_step ? "true" : "false")
                        << "\n[robot.ecp]\ntask = \"follow_mp\"\n";
  mrroc::comm::Bus bus(kUrl);
  ReadyWatch ready;
  mrroc::SystemListener listener(bus, {},
                                 [&](const mrroc::ProcessStatus& s) { ready.on_status(s); });
  bus.start();
  Children children;
  const pid_t edp =
      children
          .add(spawn("edp/irb6",
                     {(bin / "mrroc-edp").string(), "--config", config.string(), "--robot", "irb6"},
                     (dir / "edp.log").string()))
          .pid;
  const pid_t ecp =
      children
          .add(spawn("ecp/irb6",
                     {(bin / "mrroc-ecp").string(), "--config", config.string(), "--robot", "irb6"},
                     (dir / "ecp.log").string()))
          .pid;
  for (const char* process : {"edp/irb6", "ecp/irb6"})
    if (!ready.wait_ready(process, 30))
      throw mrroc::Error(std::string(process) + " was not ready within 30 s\n" + children.logs());
  mrroc::bench::release_emergency_stops(bus);

  ChainFigures out;
  try {
    mrroc::mp::Robot robot(bus, "irb6");
    robot.start_task();  // follow_mp: synchronises the robot
    mrroc::ecp::MpCommand& c = robot.image().command;
    c.arm_type = mrroc::edp::ArmRepresentation::joint;
    c.motion_type = mrroc::edp::MotionType::absolute;
    c.arm = {0.0, -1.5707963267948966, 0.0, 0.0, 0.0};
    int k = 0;
    // B1: back and forth, each move from rest to rest in paced_steps servo steps, as far as the
    // column's acceleration limit allows with a margin: the EDP estimates a rest-to-rest move of
    // n steps of T as accelerating at 4 d / (n T)^2, so d = 0.5 * 3 rad/s^2 * (n T)^2 / 4 (1.5 urad
    // for one step of 2 ms).
    const double paced_time = shape.paced_steps * servo_period_ms * 1e-3;
    const double back_and_forth = 0.5 * 3.0 * paced_time * paced_time / 4.0;
    auto step = [&] {
      c.motion_steps = shape.paced_steps;
      c.value_in_step_no = shape.paced_value;
      c.arm[0] = (k++ % 2 == 0) ? back_and_forth : 0.0;
      robot.next_pose();
    };
    // B4: the column at 0.05 rad/s, reached from rest at 0.5 rad/s^2 (the first macro-step, with
    // no successor queued yet, accelerates at 3 v / T: 1.5 rad/s^2 at most).
    const double macro_step_time = shape.unpaced_steps * servo_period_ms * 1e-3;
    const double velocity_increment = 0.5 * macro_step_time;
    double velocity = 0.0;
    auto continuous_step = [&] {
      c.motion_steps = shape.unpaced_steps;
      c.value_in_step_no = shape.unpaced_value;
      velocity = std::min(0.05, velocity + velocity_increment);
      c.arm[0] += velocity * macro_step_time;
      try {
        robot.next_pose();
      } catch (const mrroc::mp::EcpFailed&) {
        // In real time a successor that came late made the EDP ramp the robot down past its
        // target, and the next macro-step was refused as too fast from there: go on from where
        // the robot stands (as ecp::Move re-plans), from rest.
        ++out.refused_after_late;
        robot.end_motion();
        c.arm = robot.image().desired_joints;
        velocity = 0.0;
      }
    };
    for (int i = 0; i < 100; ++i) step();  // warm-up
    Pacer pacer(static_cast<std::int64_t>(servo_period_ms * 1e6));
    for (int i = 0; i < paced; ++i) {
      pacer.wait();
      const std::int64_t t0 = now_ns();
      step();
      out.paced.us.push_back(static_cast<double>(now_ns() - t0) / 1000.0);
    }
    // The EDP's CPU time while idle (its servo loop runs all the time), then the unpaced series.
    const double idle0 = cpu_ns(edp);
    const std::int64_t idle_start = now_ns();
    std::this_thread::sleep_for(std::chrono::seconds(1));
    const double edp_idle_ns_per_ns =
        (cpu_ns(edp) - idle0) / static_cast<double>(now_ns() - idle_start);
    const double cpu0[3] = {cpu_ns(getpid()), cpu_ns(ecp), cpu_ns(edp)};
    const std::int64_t start = now_ns();
    for (int i = 0; i < unpaced; ++i) {
      const std::int64_t t0 = now_ns();
      continuous_step();
      out.unpaced.us.push_back(static_cast<double>(now_ns() - t0) / 1000.0);
    }
    const std::int64_t elapsed = now_ns() - start;
    out.unpaced.seconds = static_cast<double>(elapsed) / 1e9;
    out.unpaced.add_cpu("mp", cpu_ns(getpid()) - cpu0[0]);
    out.unpaced.add_cpu("ecp", cpu_ns(ecp) - cpu0[1]);
    out.unpaced.add_cpu("edp",
                        cpu_ns(edp) - cpu0[2] - edp_idle_ns_per_ns * static_cast<double>(elapsed));
    out.edp_idle_cpu_us_per_ms = edp_idle_ns_per_ns * 1000.0;
    robot.end_motion();
  } catch (const std::exception& e) {
    throw mrroc::Error(std::string(e.what()) + "\n" + children.logs());
  }
  children.stop_all();
  bus.stop();
  return out;
}

fs::path own_directory() { return fs::read_symlink("/proc/self/exe").parent_path(); }

}  // namespace

int main(int argc, char** argv) {
  if (argc > 1 && std::strcmp(argv[1], "--forward") == 0)
    return run_forwarder(std::vector<std::string>(argv + 2, argv + argc));
  using mrroc::bench::whole_number;
  if (mrroc::bench::help_requested(
          argc, argv,
          "Usage (inside scripts/netns-run): bench_chain [SAMPLES [B1_STEPS B1_VALUE B4_STEPS "
          "B4_VALUE]]\n"
          "B1: paced macro-step round trip MP->ECP->EDP(MuJoCo)->ECP->MP against a bare LCM\n"
          "two-process round trip; B4: unpaced macro-steps/s against a bare LCM chain.\n"
          "SAMPLES (default 2000) paced macro-steps; B1_STEPS/B1_VALUE (default 1 2) and\n"
          "B4_STEPS/B4_VALUE (default 2 1): motion_steps and value_in_step_no of each series.\n"
          "Prints RESULT B1/B4 and NOTE lines (scripts/bench turns them into "
          "docs/benchmarks.md).\n"))
    return 0;
  if (argc != 1 && argc != 2 && argc != 6) {
    std::fprintf(stderr, "bench_chain: expected 0, 1 or 5 arguments, got %d (see --help)\n",
                 argc - 1);
    return 2;
  }
  const int samples = argc > 1 ? static_cast<int>(whole_number("bench_chain", "SAMPLES", argv[1],
                                                               10, 1000000, "macro-steps"))
                               : 2000;
  StepShape shape;
  if (argc > 5) {
    shape.paced_steps =
        static_cast<int>(whole_number("bench_chain", "B1_STEPS", argv[2], 1, 1000, "servo steps"));
    shape.paced_value = static_cast<int>(
        whole_number("bench_chain", "B1_VALUE", argv[3], 1, shape.paced_steps + 1, "servo steps"));
    shape.unpaced_steps =
        static_cast<int>(whole_number("bench_chain", "B4_STEPS", argv[4], 1, 1000, "servo steps"));
    shape.unpaced_value = static_cast<int>(whole_number("bench_chain", "B4_VALUE", argv[5], 1,
                                                        shape.unpaced_steps + 1, "servo steps"));
  }
  const int chain_samples = 5000;
  try {
    const fs::path bin = own_directory();
    const std::string self = (bin / "bench_chain").string();
    const fs::path dir =
        fs::temp_directory_path() / ("mrroc-bench-chain-" + std::to_string(getpid()));
    fs::create_directories(dir);

    Series bare_two;
    Series bare_chain;
    run_bare(self, dir, samples / 2, chain_samples / 2, bare_two, bare_chain);
    const ChainFigures set = run_process_set(bin, dir, 2.0, false, samples, samples, shape);
    const ChainFigures fast =
        run_process_set(bin, dir, 1.0, false, samples / 2, samples / 2, shape);
    // B4's own set-up: the simulation lock-step, as fast as possible.
    const ChainFigures lock = run_process_set(bin, dir, 2.0, true, samples, samples, shape);
    run_bare(self, dir, samples - samples / 2, chain_samples - chain_samples / 2, bare_two,
             bare_chain);
    fs::remove_all(dir);

    const double b50 = percentile(bare_two.us, 0.5);
    const double b99 = percentile(bare_two.us, 0.99);
    const double v50 = percentile(set.paced.us, 0.5);
    const double v99 = percentile(set.paced.us, 0.99);
    const double f50 = percentile(fast.paced.us, 0.5);
    const double chain50 = percentile(bare_chain.us, 0.5);
    const double chain99 = percentile(bare_chain.us, 0.99);
    const double bare_rate = static_cast<double>(bare_chain.us.size()) / bare_chain.seconds;
    const double set_rate = static_cast<double>(set.unpaced.us.size()) / set.unpaced.seconds;
    const double fast_rate = static_cast<double>(fast.unpaced.us.size()) / fast.unpaced.seconds;
    const double lock_rate = static_cast<double>(lock.unpaced.us.size()) / lock.unpaced.seconds;
    std::printf("B1 macro-step round trip, %d samples each, paced at 200 Hz\n", samples);
    std::printf("  bare LCM two-process round trip: p50 %.1f us, p99 %.1f us (%d lost)\n", b50, b99,
                bare_two.lost);
    std::printf("  MP->ECP->EDP->ECP->MP, servo 2 ms: p50 %.1f us, p99 %.1f us\n", v50, v99);
    std::printf("  MP->ECP->EDP->ECP->MP, servo 1 ms: p50 %.1f us, p99 %.1f us (%zu samples)\n",
                f50, percentile(fast.paced.us, 0.99), fast.paced.us.size());
    std::printf("  MP->ECP->EDP->ECP->MP, lock-step simulation: p50 %.1f us, p99 %.1f us\n",
                percentile(lock.paced.us, 0.5), percentile(lock.paced.us, 0.99));
    std::printf("B4 unpaced\n");
    std::printf(
        "  bare LCM 3-process chain: %.0f round trips/s, p50 %.1f us, p99 %.1f us (%d "
        "lost)\n",
        bare_rate, chain50, chain99, bare_chain.lost);
    std::printf("  macro-steps, servo 2 ms: %.0f /s, p50 %.1f us, p99 %.1f us\n", set_rate,
                percentile(set.unpaced.us, 0.5), percentile(set.unpaced.us, 0.99));
    std::printf("  macro-steps, servo 1 ms: %.0f /s, p50 %.1f us, p99 %.1f us\n", fast_rate,
                percentile(fast.unpaced.us, 0.5), percentile(fast.unpaced.us, 0.99));
    std::printf("  macro-steps, lock-step simulation: %.0f /s, p50 %.1f us, p99 %.1f us\n",
                lock_rate, percentile(lock.unpaced.us, 0.5), percentile(lock.unpaced.us, 0.99));
    std::printf("  CPU per bare chain round trip: driver %.1f us, relay %.1f us, echo %.1f us\n",
                bare_chain.cpu_us_per_sample("driver"), bare_chain.cpu_us_per_sample("relay"),
                bare_chain.cpu_us_per_sample("echo"));
    std::printf(
        "  CPU per macro-step (servo 2 ms): MP %.1f us, ECP %.1f us, EDP %.1f us beyond "
        "its idle servo loop (which takes %.1f us of CPU per ms)\n",
        set.unpaced.cpu_us_per_sample("mp"), set.unpaced.cpu_us_per_sample("ecp"),
        set.unpaced.cpu_us_per_sample("edp"), set.edp_idle_cpu_us_per_ms);
    // With the MP's phase against the servo clock swept evenly, the round trip is a fixed part
    // plus a wait for the servo cycle that grows with the period: fixed ~= 2 RT(1 ms) - RT(2 ms).
    std::printf("  fastest 1 %%: servo 2 ms %.1f us, servo 1 ms %.1f us\n",
                percentile(set.paced.us, 0.01), percentile(fast.paced.us, 0.01));
    // The reading of step v is taken v - 1 servo cycles after the cycle that starts the
    // macro-step; an MP not synchronised with the servo clock waits half a period on average for
    // that first cycle.
    const double wait2 = 2000.0 * (0.5 + (shape.paced_value - 1));
    const double wait1 = 1000.0 * (0.5 + (shape.paced_value - 1));
    std::printf(
        "NOTE B1 one NEXT_POSE = MP->ECP, ECP->EDP SET_GET (with_query), EDP->ECP "
        "reading, ECP->MP: two LCM round trips, and the reading waits for the servo "
        "loop. With motion_steps = %d and value_in_step_no = %d and the MP "
        "paced independently of the servo clock that wait is %.1f servo periods on "
        "average (%.0f us at 2 ms), against a bare round trip of %.0f us. p50 minus that "
        "wait: %.0f us (2 ms servo) and %.0f us (1 ms servo, same run: p50 %.0f us, p99 "
        "%.0f us), i.e. %.1f and %.1f x the bare round trip; fastest 1 %% at 2 ms: %.0f "
        "us. With the simulation lock-step (no servo clock to wait for; [robot.edp] "
        "lock_step = true) the same round trip is p50 %.0f us, p99 %.0f us, i.e. %.1f / "
        "%.1f x the bare round trip. Bare LCM: %d lost of %d; 64-byte raw messages on %s, "
        "the process set's URL.\n",
        shape.paced_steps, shape.paced_value, wait2 / 2000.0, wait2, b50, v50 - wait2, f50 - wait1,
        f50, percentile(fast.paced.us, 0.99), (v50 - wait2) / b50, (f50 - wait1) / b50,
        percentile(set.paced.us, 0.01), percentile(lock.paced.us, 0.5),
        percentile(lock.paced.us, 0.99), percentile(lock.paced.us, 0.5) / b50,
        percentile(lock.paced.us, 0.99) / b99, bare_two.lost, samples, kUrl);
    std::printf(
        "RESULT B1 baseline_p50=%.2f baseline_p99=%.2f value_p50=%.2f value_p99=%.2f "
        "samples=%d unit=us\n",
        b50, b99, v50, v99, samples);
    std::printf(
        "NOTE B4 macro-steps/s of MP->ECP->EDP(MuJoCo, lock-step: [robot.edp] lock_step = "
        "true, servo cycles back to back while there is motion, simulated time standing "
        "still while the EDP waits for a promised successor) when the MP sends NEXT_POSE "
        "back to back (a continuous motion, motion_steps = %d, value_in_step_no = %d) "
        "against round trips/s of a bare LCM chain driver->relay->echo->relay->driver "
        "sent back to back (%d samples, p50 %.0f us, p99 %.0f us). Before lock-step "
        "existed the EDP ran its simulation in real time only, one MuJoCo step per servo "
        "period, so a macro-step of %d servo steps could not take less than %d servo "
        "periods; the same run measures that too: at most %.0f /s with a 2 ms servo "
        "(measured %.0f /s), %.0f /s with 1 ms (measured %.0f /s). CPU time per "
        "macro-step (real time, 2 ms): MP %.0f us, ECP %.0f us, EDP %.0f us beyond its "
        "idle servo loop (%.1f us per ms); lock-step: MP %.0f us, ECP %.0f us, EDP %.0f "
        "us; per bare chain round trip: driver %.0f us, relay %.0f us, echo %.0f us. "
        "Macro-steps refused after a late successor (real time, the series went on from "
        "where the robot stood): %d at 2 ms, %d at 1 ms; lock-step: %d.\n",
        shape.unpaced_steps, shape.unpaced_value, chain_samples, chain50, chain99,
        shape.unpaced_steps, shape.unpaced_steps, 500.0 / shape.unpaced_steps, set_rate,
        1000.0 / shape.unpaced_steps, fast_rate, set.unpaced.cpu_us_per_sample("mp"),
        set.unpaced.cpu_us_per_sample("ecp"), set.unpaced.cpu_us_per_sample("edp"),
        set.edp_idle_cpu_us_per_ms, lock.unpaced.cpu_us_per_sample("mp"),
        lock.unpaced.cpu_us_per_sample("ecp"), lock.unpaced.cpu_us_per_sample("edp"),
        bare_chain.cpu_us_per_sample("driver"), bare_chain.cpu_us_per_sample("relay"),
        bare_chain.cpu_us_per_sample("echo"), set.refused_after_late, fast.refused_after_late,
        lock.refused_after_late);
    std::printf(
        "RESULT B4 baseline_rate=%.1f value_rate=%.1f baseline_p50=%.2f "
        "baseline_p99=%.2f value_p50=%.2f value_p99=%.2f samples=%d unit=/s\n",
        bare_rate, lock_rate, chain50, chain99, percentile(lock.unpaced.us, 0.5),
        percentile(lock.unpaced.us, 0.99), samples);
    return 0;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "bench_chain: %s\n", e.what());
    return 1;
  }
}
