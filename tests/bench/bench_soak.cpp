// B5: the soak. Two robots and two virtual sensors at 1 kHz for 10 minutes (by default), counting
// every lost or late reply.
//
// The process set (generated config, real processes): two EDPs (plugin "mujoco", IRb-6 "arm_a"
// and "arm_b", servo period 1 ms = 1 kHz), two ECPs (task "follow_mp"), two VSPs (mrroc-vsp:
// "wrist" with plugin "force_torque" and "range" with plugin "range", both periodic with a 1 ms
// period). This program plays the sensor hardware: it publishes the raw samples of the two
// devices the VSPs read ("soak_gauges": six strain-gauge voltages; "soak_range": one distance in
// m) at 1 kHz as raw_sensor_t on mrroc/raw/<device>. It also acts as the MP:
//  - robots: a continuous motion of both arms (joints 1, 2, 4, 5: q = q_sync + A (1 - cos(2 pi t /
//    P)) / 2 with A = 0.2, 0.1, 0.3, 0.4 rad and P = 10 s) made of NEXT_POSE macro-steps in JOINT
//    coordinates of `steps` servo steps read in step `value` (default 20 and 10): one thread per
//    robot sends that robot's next macro-step as soon as its reply arrives, and the EDP queues it
//    behind the running one. The two robots are not made to wait for each other (mp::Move waits
//    for every robot's reply before the next step): with two servo clocks, a robot that once
//    stopped for a late successor restarts in the phase of the other robot's reply and its next
//    successor then always comes one link latency too late (a trial run of this program with
//    such a wait after every step: after the first lost successor, about 250 per robot per
//    minute);
//  - sensors: GET_READING to both VSPs at 1 kHz (one thread per VSP, absolute 1 ms deadlines).
//
// What is counted over the whole run (any of them makes the exit code 1):
//  - lost: a request/reply call that needed a resend (the clients' LinkStats) or ended in a
//    TimeoutError or an ERROR reply (ECP: the attempt timeout is 250 ms, as mp::Robot's; VSP:
//    40 ms, 3 attempts, as ecp::VirtualSensor's);
//  - robot late: with the motion continuous, the readings of one robot come `steps` servo periods
//    apart; the EDP has (steps - value) periods of queued motion left when it takes a reading
//    (10 ms by default), and the reply, the MP's next NEXT_POSE and the ECP's SET must all be
//    through within that time. The EDP itself decides whether they were: when the running
//    macro-step ends with nothing queued it brings the robot to a standstill and reports a "lost
//    successor" to the SRP; every one counts as a late reply. A reply that comes more than twice
//    the macro-step (40 ms by default) after the previous reply of the same robot is late too,
//    whatever the EDP saw;
//  - VSP late: a reply that comes later than `vsp_deadline_ms` (default 10 ms: ten periods of the
//    1 kHz query) after the request, or a reading that is not valid or older than the VSP's
//    stale_after_ms (50 ms);
//  - EDP servo overruns (robot_state_t.overruns, cycles whose work did not fit in one period)
//    during the soak are reported, not counted as replies (the servo loop does not reply).
//
// Scheduling: with --rt (what scripts/soak, scripts/bench and the ctest use) this program runs with
// SCHED_FIFO priority 10 before it starts any thread or process, so that every thread of it, of
// the baseline's echo and of the process set inherits that policy (the EDP's servo thread sets
// its own SCHED_FIFO 80); a shared host's ordinary (SCHED_OTHER) load then cannot hold the 1 kHz
// loops back. Without --rt everything runs with the default policy, as the other benchmarks, and
// a busy host makes replies late. Nothing is pinned. Where SCHED_FIFO is refused (not root), the
// run says so and goes on with the default policy.
//
// Baseline (no mrroc code, same run): a bare LCM ping of 64 bytes at 1 kHz between this program
// and a child echo process (this executable again) for `baseline_seconds` (default: the soak's
// duration), before the process set starts, counted against the VSP deadline (late) and 120 ms
// (lost). Same LCM URL and scheduling (--rt or not) as the process set, nothing pinned.
//
// Usage (inside scripts/netns-run):
//   bench_soak [--rt] [--allow-late=N] [--excuse-host-stalls]
//              [seconds [baseline_seconds [steps value [vsp_deadline_ms]]]]
//   (defaults 600 600 20 10 10)
// Prints "RESULT B5 ..." and "NOTE B5 ..."; exits 0 only when nothing was lost or late (up to
// --allow-late late replies; with --excuse-host-stalls, late replies inside a host stall are not
// counted against it).
//
// Host stalls (the machine's own floor, measured during the soak): one probe thread per CPU,
// pinned to it, SCHED_FIFO 99 with --rt, wakes every 1 ms; a wake-up 5 ms or more late means that
// CPU ran nothing of the soak either (a virtual machine's CPU taken by the hypervisor, for
// instance). Each late reply has a window (robot: from the previous reply to this one; VSP: the
// call; stale reading: the call and the 60 ms before; lost successor: the two macro-steps before
// the EDP's report); one that overlaps a stall (2 ms margin) is counted as "inside a host stall".
// Stalls are only taken for the host's when the probes ran with SCHED_FIFO 99 and saw the host
// stall during the baseline too, when it ran nothing but the 1 kHz ping (a soak that starved the
// CPUs could otherwise stall the probes by itself).
#include <fcntl.h>
#include <pthread.h>
#include <sched.h>
#include <signal.h>
#include <spawn.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
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

#include "bench_release.hpp"
#include "mrroc/comm/bus.hpp"
#include "mrroc/comm/codec.hpp"
#include "mrroc/comm/links.hpp"
#include "mrroc/comm/reporter.hpp"
#include "mrroc/comm/request_reply.hpp"
#include "mrroc/config/process_set.hpp"
#include "mrroc/core/error.hpp"
#include "mrroc/core/time.hpp"
#include "mrroc_lcm/emergency_stop_t.hpp"
#include "mrroc_lcm/robot_state_t.hpp"

extern char** environ;

namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

constexpr const char* kUrl = "udpm://239.255.76.67:7667?ttl=0";
constexpr std::size_t kPayloadBytes = 64;
constexpr std::int64_t kPeriodNs = 1'000'000;  // 1 kHz: servo, sensor queries, raw samples
constexpr int kStaleAfterMs = 50;
constexpr int kBaselineLostMs = 120;
constexpr std::int64_t kStallNs = 5'000'000;  // a probe's wake-up this late is a host stall
const char* const kRobots[2] = {"arm_a", "arm_b"};
const char* const kVsps[2] = {"wrist", "range"};

std::int64_t now_ns() {
  timespec t{};
  clock_gettime(CLOCK_MONOTONIC, &t);
  return static_cast<std::int64_t>(t.tv_sec) * 1'000'000'000LL + t.tv_nsec;
}

std::int64_t now_utime() {
  timespec t{};
  clock_gettime(CLOCK_REALTIME, &t);
  return static_cast<std::int64_t>(t.tv_sec) * 1'000'000LL + t.tv_nsec / 1000;
}

void sleep_until_ns(std::int64_t deadline) {
  timespec wake{};
  wake.tv_sec = static_cast<time_t>(deadline / 1'000'000'000LL);
  wake.tv_nsec = static_cast<long>(deadline % 1'000'000'000LL);
  while (clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &wake, nullptr) == EINTR) {
  }
}

double percentile(std::vector<double> v, double p) {
  if (v.empty()) return 0.0;
  std::sort(v.begin(), v.end());
  return v[static_cast<std::size_t>(p * static_cast<double>(v.size() - 1))];
}

double max_of(const std::vector<double>& v) {
  return v.empty() ? 0.0 : *std::max_element(v.begin(), v.end());
}

/// A fixed-rate loop: absolute deadlines; slots missed by a late iteration are skipped (counted).
class Ticker {
 public:
  explicit Ticker(std::int64_t start_ns) : next_(start_ns) {}
  void wait() {
    sleep_until_ns(next_);
    next_ += kPeriodNs;
    const std::int64_t now = now_ns();
    if (now >= next_) {
      const std::int64_t missed = (now - next_) / kPeriodNs + 1;
      skipped_ += missed;
      next_ += missed * kPeriodNs;
    }
  }
  [[nodiscard]] std::int64_t skipped() const { return skipped_; }

 private:
  std::int64_t next_;
  std::int64_t skipped_ = 0;
};

// ---- The machine's own floor: host stalls ----

/// One probe thread per online CPU, pinned to it, with SCHED_FIFO 99 where allowed (above every
/// thread of the soak), waking every 1 ms on absolute deadlines. A wake-up at least `threshold`
/// late means that CPU ran none of the soak's threads for that long: the hypervisor took the
/// virtual CPU, or the kernel did. Each such stall is kept as [due, woke] in CLOCK_MONOTONIC ns.
/// A late reply whose time window overlaps a stall is the host's, not the process set's.
class StallProbe {
 public:
  explicit StallProbe(std::int64_t threshold_ns) : threshold_(threshold_ns) {}
  StallProbe(const StallProbe&) = delete;
  StallProbe& operator=(const StallProbe&) = delete;
  ~StallProbe() { stop(); }

  void start(bool rt) {
    const long cpus = sysconf(_SC_NPROCESSORS_ONLN);
    per_cpu_.resize(static_cast<std::size_t>(std::max(1L, cpus)));
    run_.store(true);
    for (std::size_t cpu = 0; cpu < per_cpu_.size(); ++cpu)
      threads_.emplace_back([this, cpu, rt] { probe(cpu, rt); });
  }
  /// Joins the probes; stalls() is complete afterwards.
  void stop() {
    run_.store(false);
    for (auto& t : threads_)
      if (t.joinable()) t.join();
    threads_.clear();
  }
  [[nodiscard]] std::vector<std::pair<std::int64_t, std::int64_t>> stalls() const {
    std::vector<std::pair<std::int64_t, std::int64_t>> all;
    for (const auto& v : per_cpu_) all.insert(all.end(), v.begin(), v.end());
    return all;
  }
  /// Whether a stall overlaps [from, to] (ns).
  [[nodiscard]] bool overlaps(std::int64_t from, std::int64_t to) const {
    for (const auto& v : per_cpu_)
      for (const auto& [due, woke] : v)
        if (woke >= from && due <= to) return true;
    return false;
  }
  [[nodiscard]] std::int64_t threshold_ns() const { return threshold_; }
  [[nodiscard]] bool pinned_rt() const { return pinned_rt_.load(); }

 private:
  void probe(std::size_t cpu, bool rt) {
    cpu_set_t set;
    CPU_ZERO(&set);
    CPU_SET(cpu, &set);
    bool ok = pthread_setaffinity_np(pthread_self(), sizeof set, &set) == 0;
    if (rt) {
      sched_param sp{};
      sp.sched_priority = 99;
      ok = ok && pthread_setschedparam(pthread_self(), SCHED_FIFO, &sp) == 0;
    }
    if (!ok || !rt) pinned_rt_.store(false);
    auto& mine = per_cpu_[cpu];
    mine.reserve(4096);
    std::int64_t next = now_ns() + kPeriodNs;
    while (run_.load(std::memory_order_relaxed)) {
      sleep_until_ns(next);
      const std::int64_t woke = now_ns();
      if (woke - next >= threshold_ && mine.size() < 100000) mine.emplace_back(next, woke);
      next += kPeriodNs;
      if (woke >= next) next = woke + kPeriodNs;
    }
  }

  std::int64_t threshold_;
  std::atomic<bool> run_{false};
  std::atomic<bool> pinned_rt_{true};
  std::vector<std::vector<std::pair<std::int64_t, std::int64_t>>> per_cpu_;
  std::vector<std::thread> threads_;
};

/// A late event and the time window in which whatever made it late happened.
struct LateEvent {
  std::int64_t from_ns = 0;
  std::int64_t to_ns = 0;
};

// ---- Child processes (as in bench_chain) ----

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

// ---- Baseline: bare LCM ping at 1 kHz ----

/// Echo role: every message on BENCH_SOAK_PING is published unchanged on BENCH_SOAK_PONG.
int run_echo() {
  lcm::LCM lcm(kUrl);
  if (!lcm.good()) return 1;
  lcm.subscribeFunction<lcm::LCM*>(
      "BENCH_SOAK_PING",
      [](const lcm::ReceiveBuffer* rbuf, const std::string&, lcm::LCM* l) {
        l->publish("BENCH_SOAK_PONG", rbuf->data, rbuf->data_size);
      },
      &lcm);
  for (;;) lcm.handle();
}

struct Counts {
  std::vector<double> us;  // round trips of the answered requests
  std::int64_t requests = 0;
  std::int64_t lost = 0;
  std::int64_t late = 0;
  std::int64_t skipped = 0;            // 1 kHz slots not used because a reply came after them
  std::vector<LateEvent> late_events;  // one per late reply (or stale reading), with its window
};

Counts run_baseline(const std::string& self, const fs::path& dir, double seconds,
                    double deadline_us) {
  Children children;
  children.add(spawn("echo", {self, "--echo"}, (dir / "echo.log").string()));
  lcm::LCM lcm(kUrl);
  if (!lcm.good()) throw mrroc::Error(std::string("cannot open LCM at ") + kUrl);
  struct State {
    std::uint64_t seq = 0;
    bool answered = false;
  } state;
  lcm.subscribeFunction<State*>(
      "BENCH_SOAK_PONG",
      [](const lcm::ReceiveBuffer* rbuf, const std::string&, State* s) {
        std::uint64_t seq = 0;
        if (rbuf->data_size >= sizeof seq) std::memcpy(&seq, rbuf->data, sizeof seq);
        if (seq == s->seq) s->answered = true;
      },
      &state);
  auto ping = [&](int timeout_ms) {
    std::uint8_t payload[kPayloadBytes] = {};
    ++state.seq;
    std::memcpy(payload, &state.seq, sizeof state.seq);
    state.answered = false;
    lcm.publish("BENCH_SOAK_PING", payload, static_cast<unsigned>(sizeof payload));
    const std::int64_t until = now_ns() + static_cast<std::int64_t>(timeout_ms) * 1'000'000LL;
    while (!state.answered) {
      const std::int64_t left_ms = (until - now_ns()) / 1'000'000LL;
      if (left_ms < 0) return false;
      lcm.handleTimeout(static_cast<int>(left_ms) + 1);
    }
    return true;
  };
  const auto until = Clock::now() + std::chrono::seconds(10);
  while (!ping(100))
    if (Clock::now() > until) throw mrroc::Error("the bare LCM echo never answered");
  for (int i = 0; i < 100; ++i) (void)ping(100);  // warm-up

  Counts out;
  const auto n = static_cast<std::int64_t>(seconds * 1000.0);
  out.us.reserve(static_cast<std::size_t>(n));
  Ticker ticker(now_ns() + kPeriodNs);
  for (std::int64_t i = 0; i < n; ++i) {
    ticker.wait();
    const std::int64_t t0 = now_ns();
    ++out.requests;
    if (!ping(kBaselineLostMs)) {
      ++out.lost;
      continue;
    }
    const double us = static_cast<double>(now_ns() - t0) / 1000.0;
    out.us.push_back(us);
    if (us > deadline_us) ++out.late;
  }
  out.skipped = ticker.skipped();
  return out;
}

// ---- The process set ----

struct Shape {
  int steps = 20;
  int value = 10;
  double vsp_deadline_ms = 10.0;
};

void write_config(const fs::path& file) {
  // Lookahead 4: the last macro-step (read after the stop) is answered when everything queued
  // has run out, (lookahead + 1) macro-steps of up to 40 ms here; with the default 8 that is
  // 360 ms, past the MP client's 250 ms attempt, and its resend would count as a lost reply.
  std::ofstream out(file);
  out << "[system]\nname = \"bench-soak\"\nlcm_url = \"" << kUrl << "\"\n"
      << "[mp]\ntask = \"start_and_wait\"\n";
  for (const char* robot : kRobots)
    out << "[[robot]]\nname = \"" << robot << "\"\nmodel = \"" << MRROC_SOURCE_DIR
        << "/robots/irb6\"\n[robot.edp]\nplugin = \"mujoco\"\nservo_period_ms = 1\nlookahead = 4\n"
        << "[robot.ecp]\ntask = \"follow_mp\"\n";
  out << "[[vsp]]\nname = \"wrist\"\nplugin = \"force_torque\"\nsources = [\"soak_gauges\"]\n"
      << "mode = \"periodic\"\nperiod_ms = 1\nstale_after_ms = " << kStaleAfterMs << "\n"
      << "[vsp.params]\nfilter_hz = 50\n"
      << "[[vsp]]\nname = \"range\"\nplugin = \"range\"\nsources = [\"soak_range\"]\n"
      << "mode = \"periodic\"\nperiod_ms = 1\nstale_after_ms = " << kStaleAfterMs << "\n";
}

class Watch {
 public:
  void on_status(const mrroc::ProcessStatus& s) {
    std::lock_guard lock(mutex_);
    states_[s.process] = s.state;
    cv_.notify_all();
  }
  void on_message(const mrroc::SrpMessage& m) {
    std::lock_guard lock(mutex_);
    if (counting_ && m.text.find("no next macro-step from the ECP in time") != std::string::npos)
      lost_successor_times_.push_back(now_ns());
    if (m.severity != mrroc::Severity::info && counting_)
      problems_.push_back(m.process + ": " + m.text);
  }
  bool wait_ready(const std::string& process, double seconds) {
    std::unique_lock lock(mutex_);
    return cv_.wait_for(lock, std::chrono::duration<double>(seconds), [&] {
      auto it = states_.find(process);
      return it != states_.end() && (it->second == mrroc::ProcessState::ready ||
                                     it->second == mrroc::ProcessState::running);
    });
  }
  void start_counting() {
    std::lock_guard lock(mutex_);
    counting_ = true;
    lost_successor_times_.clear();
    problems_.clear();
  }
  void stop_counting() {
    std::lock_guard lock(mutex_);
    counting_ = false;
  }
  std::int64_t lost_successors() {
    std::lock_guard lock(mutex_);
    return static_cast<std::int64_t>(lost_successor_times_.size());
  }
  std::vector<std::string> problems() {
    std::lock_guard lock(mutex_);
    return problems_;
  }
  /// When each lost successor was reported (CLOCK_MONOTONIC ns at its arrival here).
  std::vector<std::int64_t> lost_successor_times() {
    std::lock_guard lock(mutex_);
    return lost_successor_times_;
  }

 private:
  std::mutex mutex_;
  std::condition_variable cv_;
  std::map<std::string, mrroc::ProcessState> states_;
  std::vector<std::int64_t> lost_successor_times_;
  std::vector<std::string> problems_;
  bool counting_ = false;
};

/// The EDPs' servo-loop overruns, from robot_state_t.
class Overruns {
 public:
  void on_state(const lcm::ReceiveBuffer*, const std::string&, const mrroc_lcm::robot_state_t* m) {
    std::lock_guard lock(mutex_);
    latest_[m->robot] = m->overruns;
  }
  std::map<std::string, std::int64_t> snapshot() {
    std::lock_guard lock(mutex_);
    return latest_;
  }

 private:
  std::mutex mutex_;
  std::map<std::string, std::int64_t> latest_;
};

struct RobotFigures {
  Counts calls;                     // NEXT_POSE round trips
  std::vector<double> interval_us;  // between consecutive replies
  std::string error;
};

struct SetFigures {
  RobotFigures robots[2];
  Counts vsps[2];
  std::int64_t stale = 0;  // invalid or too old readings
  std::int64_t lost_successors = 0;
  std::vector<LateEvent> lost_successor_events;
  std::int64_t overruns = 0;
  std::int64_t raw_published = 0;
  std::int64_t raw_skipped = 0;
  std::vector<std::string> problems;
  std::string errors;
};

mrroc::ecp::MpCommand simple(mrroc::ecp::MpCommandType type) {
  mrroc::ecp::MpCommand c;
  c.type = type;
  return c;
}

void check_ecp_reply(const std::string& robot, const mrroc::ecp::EcpReply& r) {
  if (r.type == mrroc::ecp::EcpReplyType::error)
    throw mrroc::Error("ecp/" + robot + " answered ERROR " + std::to_string(r.error_code) + ": " +
                       r.error_text);
}

SetFigures run_process_set(const fs::path& bin, const fs::path& dir, double seconds,
                           const Shape& shape) {
  const fs::path config = dir / "bench-soak.toml";
  write_config(config);
  mrroc::comm::Bus bus(kUrl);
  Watch watch;
  mrroc::SystemListener listener(
      bus, [&](const mrroc::SrpMessage& m) { watch.on_message(m); },
      [&](const mrroc::ProcessStatus& s) { watch.on_status(s); });
  Overruns overruns;
  for (const char* robot : kRobots)
    bus.lcm().subscribe(mrroc::channels::robot_state(robot), &Overruns::on_state, &overruns);
  bus.start();

  // The raw sensor devices: this program plays the hardware, at 1 kHz from now on.
  std::atomic<bool> raw_run{true};
  std::int64_t raw_published = 0;
  std::int64_t raw_skipped = 0;
  std::thread raw([&] {
    mrroc::vsp::RawSample gauges;
    gauges.device = "soak_gauges";
    gauges.names = {"g0", "g1", "g2", "g3", "g4", "g5"};
    gauges.units = {"V", "V", "V", "V", "V", "V"};
    gauges.values.assign(6, 0.0);
    mrroc::vsp::RawSample range;
    range.device = "soak_range";
    range.names = {"distance"};
    range.units = {"m"};
    range.values = {1.0};
    const std::string gauges_channel = mrroc::channels::raw_sensor(gauges.device);
    const std::string range_channel = mrroc::channels::raw_sensor(range.device);
    Ticker ticker(now_ns() + kPeriodNs);
    std::int64_t n = 0;
    while (raw_run.load()) {
      ticker.wait();
      const double t = static_cast<double>(n) * 1e-3;
      for (std::size_t i = 0; i < 6; ++i)
        gauges.values[i] = 0.01 * std::sin(2.0 * M_PI * 0.5 * t + static_cast<double>(i));
      range.values[0] = 1.0 + 0.2 * std::sin(2.0 * M_PI * 0.2 * t);
      gauges.sample_no = range.sample_no = n++;
      gauges.sample_utime = range.sample_utime = now_utime();
      mrroc::comm::publish(bus, gauges_channel, mrroc::comm::encode(gauges));
      mrroc::comm::publish(bus, range_channel, mrroc::comm::encode(range));
    }
    raw_published = n;
    raw_skipped = ticker.skipped();
  });
  struct RawStopper {
    std::atomic<bool>& run;
    std::thread& thread;
    ~RawStopper() {
      run.store(false);
      if (thread.joinable()) thread.join();
    }
  } raw_stopper{raw_run, raw};

  Children children;
  std::vector<std::string> order;
  for (const char* vsp : kVsps) {
    children.add(spawn(std::string("vsp/") + vsp,
                       {(bin / "mrroc-vsp").string(), "--config", config.string(), "--vsp", vsp},
                       (dir / (std::string("vsp-") + vsp + ".log")).string()));
    order.push_back(std::string("vsp/") + vsp);
  }
  for (const char* robot : kRobots)
    for (const char* kind : {"edp", "ecp"}) {
      const std::string exe = std::string("mrroc-") + kind;
      children.add(spawn(std::string(kind) + "/" + robot,
                         {(bin / exe).string(), "--config", config.string(), "--robot", robot},
                         (dir / (std::string(kind) + "-" + robot + ".log")).string()));
      order.push_back(std::string(kind) + "/" + robot);
    }
  for (const auto& process : order)
    if (!watch.wait_ready(process, 30))
      throw mrroc::Error(process + " was not ready within 30 s\n" + children.logs());
  mrroc::bench::release_emergency_stops(bus);

  SetFigures out;
  try {
    // MP -> ECP links as mp::Robot makes them; VSP links as ecp::VirtualSensor.
    std::vector<std::unique_ptr<mrroc::comm::EcpClient>> ecps;
    for (const char* robot : kRobots)
      ecps.push_back(std::make_unique<mrroc::comm::EcpClient>(
          bus, "mp", std::string("ECP ") + robot, mrroc::channels::ecp_command(robot),
          mrroc::channels::ecp_reply(robot)));
    std::vector<std::unique_ptr<mrroc::comm::VspClient>> vsps;
    for (const char* vsp : kVsps)
      vsps.push_back(std::make_unique<mrroc::comm::VspClient>(
          bus, "mp-sensor", std::string("VSP ") + vsp, mrroc::channels::vsp_command(vsp),
          mrroc::channels::vsp_reply(vsp),
          mrroc::comm::ClientOptions{std::chrono::milliseconds(40), 3, {}}));

    // START_TASK: follow_mp synchronises both robots.
    std::vector<std::vector<double>> start(2);
    {
      std::vector<std::thread> threads;
      std::string errors[2];
      for (std::size_t r = 0; r < 2; ++r)
        threads.emplace_back([&, r] {
          try {
            const auto reply = ecps[r]->call(simple(mrroc::ecp::MpCommandType::start_task));
            check_ecp_reply(kRobots[r], reply);
            start[r] = reply.joints;
          } catch (const std::exception& e) {
            errors[r] = e.what();
          }
        });
      for (auto& t : threads) t.join();
      for (const auto& e : errors)
        if (!e.empty()) throw mrroc::Error("START_TASK: " + e);
    }
    // Both VSPs answer with valid readings before the soak starts (the first period after start).
    for (std::size_t v = 0; v < 2; ++v) {
      mrroc::vsp::Request get;
      get.command = mrroc::vsp::Command::get_reading;
      const auto until = Clock::now() + std::chrono::seconds(5);
      for (;;) {
        const auto rep = vsps[v]->call(get);
        if (rep.kind == mrroc::vsp::ReplyKind::reading && rep.reading.valid) break;
        if (Clock::now() > until)
          throw mrroc::Error(
              std::string("VSP ") + kVsps[v] + " gave no valid reading within 5 s: " +
              (rep.kind == mrroc::vsp::ReplyKind::error ? rep.error_text
                                                        : rep.reading.invalid_reason));
        std::this_thread::sleep_for(std::chrono::milliseconds(10));
      }
    }

    mrroc::comm::LinkStats ecp_stats0[2] = {ecps[0]->stats(), ecps[1]->stats()};
    mrroc::comm::LinkStats vsp_stats0[2] = {vsps[0]->stats(), vsps[1]->stats()};
    std::this_thread::sleep_for(std::chrono::milliseconds(100));  // a robot_state_t of each EDP
    const auto overruns0 = overruns.snapshot();
    watch.start_counting();

    const double period_s = 1e-3;
    const double step_s = shape.steps * period_s;
    const auto cycles = static_cast<std::int64_t>(seconds / step_s);
    const double amplitude[5] = {0.2, 0.1, 0.0, 0.3, 0.4};
    // Whole periods of about 10 s: the motion ends at rest with the run, whatever its length (a
    // run that ended mid-period stopped the arms with a last macro-step too abrupt to take).
    const double motion_period_s =
        seconds / std::max(1.0, std::round(static_cast<double>(seconds) / 10.0));
    const double late_interval_us = 2.0 * shape.steps * period_s * 1e6;
    std::atomic<bool> failed{false};
    auto robot_loop = [&](std::size_t r) {
      RobotFigures& fig = out.robots[r];
      fig.calls.us.reserve(static_cast<std::size_t>(cycles));
      fig.interval_us.reserve(static_cast<std::size_t>(cycles));
      mrroc::ecp::MpCommand c;
      c.type = mrroc::ecp::MpCommandType::next_pose;
      c.arm_type = mrroc::edp::ArmRepresentation::joint;
      c.motion_type = mrroc::edp::MotionType::absolute;
      c.motion_steps = shape.steps;
      c.value_in_step_no = shape.value;
      c.arm = start[r];
      std::int64_t previous = 0;
      try {
        for (std::int64_t k = 1; k <= cycles && !failed.load(); ++k) {
          const double t = static_cast<double>(k) * step_s;
          for (std::size_t j = 0; j < c.arm.size() && j < 5; ++j)
            c.arm[j] = start[r][j] +
                       amplitude[j] * 0.5 * (1.0 - std::cos(2.0 * M_PI * t / motion_period_s));
          // The last macro-step is read after the motion stopped: it promises no successor.
          if (k == cycles) c.value_in_step_no = shape.steps + 1;
          const std::int64_t t0 = now_ns();
          ++fig.calls.requests;
          const auto reply = ecps[r]->call(c);
          const std::int64_t t1 = now_ns();
          check_ecp_reply(kRobots[r], reply);
          fig.calls.us.push_back(static_cast<double>(t1 - t0) / 1000.0);
          if (previous != 0 && k < cycles) {
            const double interval = static_cast<double>(t1 - previous) / 1000.0;
            fig.interval_us.push_back(interval);
            if (interval > late_interval_us) {
              ++fig.calls.late;
              fig.calls.late_events.push_back({previous, t1});
            }
          }
          previous = t1;
        }
      } catch (const std::exception& e) {
        fig.error = e.what();
        ++fig.calls.lost;
        failed.store(true);
      }
    };
    auto vsp_loop = [&](std::size_t v) {
      Counts& fig = out.vsps[v];
      fig.us.reserve(static_cast<std::size_t>(seconds * 1000.0));
      mrroc::vsp::Request get;
      get.command = mrroc::vsp::Command::get_reading;
      const double deadline_us = shape.vsp_deadline_ms * 1000.0;
      const auto n = static_cast<std::int64_t>(seconds * 1000.0);
      Ticker ticker(now_ns() + kPeriodNs);
      for (std::int64_t i = 0; i < n && !failed.load(); ++i) {
        ticker.wait();
        const std::int64_t t0 = now_ns();
        ++fig.requests;
        try {
          const auto rep = vsps[v]->call(get);
          const double us = static_cast<double>(now_ns() - t0) / 1000.0;
          if (rep.kind != mrroc::vsp::ReplyKind::reading) {
            ++fig.lost;
            continue;
          }
          fig.us.push_back(us);
          const std::int64_t t1 = now_ns();
          if (us > deadline_us) {
            ++fig.late;
            fig.late_events.push_back({t0, t1});
          }
          if (!rep.reading.valid || rep.reading.age_us > kStaleAfterMs * 1000LL) {
            ++fig.skipped;
            fig.late_events.push_back({t0 - (kStaleAfterMs + 10) * 1'000'000LL, t1});
          }
        } catch (const std::exception&) {
          ++fig.lost;
        }
      }
      // `skipped` holds the stale readings here; the ticker's skipped slots are reported apart.
      out.stale += fig.skipped;
      fig.skipped = ticker.skipped();
    };
    std::vector<std::thread> threads;
    for (std::size_t r = 0; r < 2; ++r) threads.emplace_back(robot_loop, r);
    for (std::size_t v = 0; v < 2; ++v) threads.emplace_back(vsp_loop, v);
    for (auto& t : threads) t.join();

    for (std::size_t r = 0; r < 2; ++r) {
      const auto s = ecps[r]->stats();
      out.robots[r].calls.lost += static_cast<std::int64_t>(s.resends - ecp_stats0[r].resends);
      if (!out.robots[r].error.empty())
        out.errors += std::string(kRobots[r]) + ": " + out.robots[r].error + "\n";
    }
    for (std::size_t v = 0; v < 2; ++v) {
      const auto s = vsps[v]->stats();
      out.vsps[v].lost += static_cast<std::int64_t>(s.resends - vsp_stats0[v].resends);
    }
    for (std::size_t r = 0; r < 2 && !failed.load(); ++r)
      check_ecp_reply(kRobots[r], ecps[r]->call(simple(mrroc::ecp::MpCommandType::end_motion)));
    std::this_thread::sleep_for(std::chrono::milliseconds(300));  // last states and warnings
    watch.stop_counting();
    const auto overruns1 = overruns.snapshot();
    for (const auto& [robot, n] : overruns1) {
      auto it = overruns0.find(robot);
      out.overruns += n - (it == overruns0.end() ? 0 : it->second);
    }
    out.lost_successors = watch.lost_successors();
    // A lost successor: the reply, the next NEXT_POSE and the ECP's SET had to pass within the
    // last macro-step before the report; the window reaches back two macro-steps.
    const std::int64_t back_ns = 2LL * shape.steps * kPeriodNs;
    for (const std::int64_t t : watch.lost_successor_times())
      out.lost_successor_events.push_back({t - back_ns, t});
    out.problems = watch.problems();
  } catch (const std::exception& e) {
    throw mrroc::Error(std::string(e.what()) + "\n" + children.logs());
  }
  if (!out.errors.empty()) out.errors += children.logs();
  children.stop_all();
  raw_run.store(false);
  raw.join();
  out.raw_published = raw_published;
  out.raw_skipped = raw_skipped;
  bus.stop();
  return out;
}

/// CPU time (user + system) of this process and of its waited-for children, in s.
double cpu_seconds() {
  double total = 0;
  for (const int who : {RUSAGE_SELF, RUSAGE_CHILDREN}) {
    rusage u{};
    getrusage(who, &u);
    total += static_cast<double>(u.ru_utime.tv_sec + u.ru_stime.tv_sec) +
             static_cast<double>(u.ru_utime.tv_usec + u.ru_stime.tv_usec) / 1e6;
  }
  return total;
}

fs::path own_directory() { return fs::read_symlink("/proc/self/exe").parent_path(); }

void usage(FILE* to) {
  std::fprintf(to,
               "Usage: bench_soak [--rt] [--allow-late=N] [--excuse-host-stalls] [SECONDS "
               "[BASELINE_SECONDS [STEPS VALUE "
               "[VSP_DEADLINE_MS]]]]\n"
               "B5 soak: two IRb-6 EDPs (MuJoCo, 1 kHz servo), two ECPs (follow_mp) and two VSPs\n"
               "(force_torque, range; periodic 1 kHz) driven for SECONDS (default 600) by this\n"
               "program as the MP (NEXT_POSE macro-steps of STEPS servo steps read in step VALUE,\n"
               "default 20 and 10, to each robot as soon as its reply came; GET_READING to both\n"
               "VSPs at 1 kHz) and as the raw sensors (raw_sensor_t at 1 kHz). Counts lost and\n"
               "late replies against a bare LCM 1 kHz ping of BASELINE_SECONDS (default SECONDS).\n"
               "A VSP reply is late after VSP_DEADLINE_MS (default 10). Run inside\n"
               "scripts/netns-run. Prints RESULT B5 / NOTE B5 lines; exit code 0 only when\n"
               "nothing was lost or late.\n"
               "--rt: run this program and every process it starts with SCHED_FIFO 10 (the EDPs'\n"
               "servo threads use 80), so that ordinary load on the host cannot delay them.\n"
               "--allow-late=N: exit 0 with up to N late replies (0..1000; lost replies, resends\n"
               "and errors still fail). The figures printed are the same.\n"
               "--excuse-host-stalls: a late reply whose window overlaps a host stall (a probe\n"
               "thread pinned to each CPU, SCHED_FIFO 99 with --rt, woke 5 ms or more late: that\n"
               "CPU ran nothing else either) does not count against --allow-late, provided the\n"
               "probes saw the host stall during the baseline too. Printed apart.\n"
               "Options may come in any order, before SECONDS.\n");
}

bool parse_number(const char* text, double low, double high, const char* what, const char* unit,
                  double& out) {
  char* end = nullptr;
  const double v = std::strtod(text, &end);
  if (end == text || *end != '\0' || !std::isfinite(v) || v < low || v > high) {
    std::fprintf(stderr, "bench_soak: %s '%s' is not a number in %g..%g %s\n", what, text, low,
                 high, unit);
    return false;
  }
  out = v;
  return true;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc > 1 && std::strcmp(argv[1], "--echo") == 0) return run_echo();
  if (argc > 1 && (std::strcmp(argv[1], "--help") == 0 || std::strcmp(argv[1], "-h") == 0)) {
    usage(stdout);
    return 0;
  }
  std::string scheduling = "default policy (SCHED_OTHER)";
  bool rt = false;
  bool excuse_host_stalls = false;
  long allow_late = 0;
  while (argc > 1 && std::strncmp(argv[1], "--", 2) == 0) {
    const char* option = argv[1];
    if (std::strcmp(option, "--rt") == 0) {
      rt = true;
    } else if (std::strcmp(option, "--excuse-host-stalls") == 0) {
      excuse_host_stalls = true;
    } else if (std::strncmp(option, "--allow-late=", 13) == 0) {
      char* end = nullptr;
      allow_late = std::strtol(option + 13, &end, 10);
      if (end == option + 13 || *end != '\0' || allow_late < 0 || allow_late > 1000) {
        std::fprintf(stderr,
                     "bench_soak: --allow-late '%s' is not a whole number of replies in "
                     "0..1000\n",
                     option + 13);
        return 2;
      }
    } else {
      std::fprintf(stderr, "bench_soak: unknown option '%s' (see --help)\n", option);
      return 2;
    }
    --argc;
    ++argv;
  }
  if (rt) {
    sched_param sp{};
    sp.sched_priority = 10;
    if (sched_setscheduler(0, SCHED_FIFO, &sp) == 0) {
      scheduling = "SCHED_FIFO 10 for every process and thread (EDP servo threads 80)";
    } else {
      rt = false;
      scheduling = std::string("default policy (SCHED_FIFO refused: ") + std::strerror(errno) + ")";
      std::fprintf(stderr, "bench_soak: --rt: SCHED_FIFO refused (%s); default policy\n",
                   std::strerror(errno));
    }
  }
  if (argc > 6) {
    usage(stderr);
    return 2;
  }
  if (argc == 4) {
    std::fprintf(stderr, "bench_soak: STEPS '%s' needs VALUE after it (see --help)\n", argv[3]);
    return 2;
  }
  double seconds = 600;
  double baseline_seconds = -1;
  double steps = 20;
  double value = 10;
  Shape shape;
  if (argc > 1 && !parse_number(argv[1], 1, 86400, "SECONDS", "s", seconds)) return 2;
  baseline_seconds = seconds;
  if (argc > 2 && !parse_number(argv[2], 0, 86400, "BASELINE_SECONDS", "s", baseline_seconds))
    return 2;
  if (argc > 4) {
    if (!parse_number(argv[3], 2, 1000, "STEPS", "servo steps", steps)) return 2;
    if (!parse_number(argv[4], 1, steps - 1, "VALUE", "(step number, below STEPS)", value))
      return 2;
    if (steps != std::floor(steps) || value != std::floor(value)) {
      std::fprintf(stderr, "bench_soak: STEPS %g and VALUE %g must be whole numbers\n", steps,
                   value);
      return 2;
    }
  }
  if (argc > 5 && !parse_number(argv[5], 0.1, 1000, "VSP_DEADLINE_MS", "ms", shape.vsp_deadline_ms))
    return 2;
  shape.steps = static_cast<int>(steps);
  shape.value = static_cast<int>(value);
  try {
    const fs::path bin = own_directory();
    const std::string self = (bin / "bench_soak").string();
    const fs::path dir =
        fs::temp_directory_path() / ("mrroc-bench-soak-" + std::to_string(getpid()));
    fs::create_directories(dir);
    const double deadline_us = shape.vsp_deadline_ms * 1000.0;
    std::printf("B5 soak: %.0f s of 2 robots + 2 VSPs at 1 kHz, baseline %.0f s; %s\n", seconds,
                baseline_seconds, scheduling.c_str());
    std::fflush(stdout);
    StallProbe probe(kStallNs);
    probe.start(rt);
    Counts base;
    if (baseline_seconds > 0) base = run_baseline(self, dir, baseline_seconds, deadline_us);
    const std::int64_t soak_start_ns = now_ns();
    std::printf(
        "  bare LCM ping 1 kHz: %lld requests, p50 %.1f us, p99 %.1f us, max %.0f us, %lld "
        "lost, %lld late (> %.1f ms)\n",
        static_cast<long long>(base.requests), percentile(base.us, 0.5), percentile(base.us, 0.99),
        max_of(base.us), static_cast<long long>(base.lost), static_cast<long long>(base.late),
        shape.vsp_deadline_ms);
    std::fflush(stdout);
    const double cpu0 = cpu_seconds();
    const std::int64_t wall0 = now_ns();
    SetFigures set;
    try {
      set = run_process_set(bin, dir, seconds, shape);
    } catch (...) {
      probe.stop();
      throw;
    }
    probe.stop();
    const long cpus = std::max(1L, sysconf(_SC_NPROCESSORS_ONLN));
    const double cpu_share = (cpu_seconds() - cpu0) / (static_cast<double>(now_ns() - wall0) / 1e9 *
                                                       static_cast<double>(cpus));
    fs::remove_all(dir);

    std::int64_t lost = 0;
    std::int64_t late = 0;
    std::vector<double> vsp_us;
    std::vector<double> robot_us;
    std::vector<double> intervals;
    std::int64_t vsp_requests = 0;
    std::int64_t robot_requests = 0;
    std::int64_t vsp_lost = 0, vsp_late = 0, robot_lost = 0, robot_late = 0;
    for (std::size_t r = 0; r < 2; ++r) {
      const RobotFigures& f = set.robots[r];
      std::printf(
          "  robot %s: %lld NEXT_POSE, round trip p50 %.0f us, p99 %.0f us, max %.0f us; "
          "reply interval p50 %.0f us, p99 %.0f us, max %.0f us; %lld lost, %lld late\n",
          kRobots[r], static_cast<long long>(f.calls.requests), percentile(f.calls.us, 0.5),
          percentile(f.calls.us, 0.99), max_of(f.calls.us), percentile(f.interval_us, 0.5),
          percentile(f.interval_us, 0.99), max_of(f.interval_us),
          static_cast<long long>(f.calls.lost), static_cast<long long>(f.calls.late));
      robot_us.insert(robot_us.end(), f.calls.us.begin(), f.calls.us.end());
      intervals.insert(intervals.end(), f.interval_us.begin(), f.interval_us.end());
      robot_requests += f.calls.requests;
      robot_lost += f.calls.lost;
      robot_late += f.calls.late;
    }
    for (std::size_t v = 0; v < 2; ++v) {
      const Counts& f = set.vsps[v];
      std::printf(
          "  VSP %s: %lld GET_READING, round trip p50 %.0f us, p99 %.0f us, max %.0f us; "
          "%lld lost, %lld late; %lld slots of 1 ms skipped\n",
          kVsps[v], static_cast<long long>(f.requests), percentile(f.us, 0.5),
          percentile(f.us, 0.99), max_of(f.us), static_cast<long long>(f.lost),
          static_cast<long long>(f.late), static_cast<long long>(f.skipped));
      vsp_us.insert(vsp_us.end(), f.us.begin(), f.us.end());
      vsp_requests += f.requests;
      vsp_lost += f.lost;
      vsp_late += f.late;
    }
    lost = robot_lost + vsp_lost;
    late = robot_late + vsp_late + set.stale + set.lost_successors;
    // Which late events fall into a host stall (2 ms of margin before each window).
    std::vector<LateEvent> events = set.lost_successor_events;
    for (const auto& r : set.robots)
      events.insert(events.end(), r.calls.late_events.begin(), r.calls.late_events.end());
    for (const auto& v : set.vsps)
      events.insert(events.end(), v.late_events.begin(), v.late_events.end());
    std::int64_t late_in_stalls = 0;
    for (const auto& e : events)
      if (probe.overlaps(e.from_ns - 2'000'000LL, e.to_ns)) ++late_in_stalls;
    std::size_t baseline_stalls = 0;
    double longest_baseline_stall_ms = 0;
    std::vector<std::pair<std::int64_t, std::int64_t>> stalls;
    double longest_stall_ms = 0;
    for (const auto& [due, woke] : probe.stalls()) {
      const double ms = static_cast<double>(woke - due) / 1e6;
      if (due < soak_start_ns) {
        ++baseline_stalls;
        longest_baseline_stall_ms = std::max(longest_baseline_stall_ms, ms);
      } else {
        stalls.emplace_back(due, woke);
        longest_stall_ms = std::max(longest_stall_ms, ms);
      }
    }
    const std::int64_t late_own = late - late_in_stalls;
    // Stalls are taken for the host's only when the probes outranked every thread of the soak and
    // the same probes saw the host stall during the baseline, when it ran nothing but the ping.
    const bool stalls_are_the_hosts = probe.pinned_rt() && baseline_stalls > 0;
    std::printf(
        "  stale or invalid readings: %lld; EDP lost successors: %lld; EDP servo overruns: "
        "%lld; raw samples published: %lld per device (%lld slots skipped)\n",
        static_cast<long long>(set.stale), static_cast<long long>(set.lost_successors),
        static_cast<long long>(set.overruns), static_cast<long long>(set.raw_published),
        static_cast<long long>(set.raw_skipped));
    std::printf(
        "  host stalls (a probe pinned to each CPU%s woke >= %.0f ms late): %zu during the "
        "baseline (the longest %.1f ms), %zu during the soak (the longest %.1f ms); late replies "
        "inside one: %lld of %lld; the soak used %.0f %% of %ld CPUs\n",
        probe.pinned_rt() ? " with SCHED_FIFO 99" : "", static_cast<double>(kStallNs) / 1e6,
        baseline_stalls, longest_baseline_stall_ms, stalls.size(), longest_stall_ms,
        static_cast<long long>(late_in_stalls), static_cast<long long>(late), 100.0 * cpu_share,
        cpus);
    if (excuse_host_stalls && !stalls_are_the_hosts)
      std::printf("  --excuse-host-stalls ignored: %s\n",
                  probe.pinned_rt() ? "the probes saw no host stall during the baseline"
                                    : "the probes could not be pinned with SCHED_FIFO 99 (--rt)");
    for (std::size_t i = 0; i < set.problems.size() && i < 30; ++i)
      std::printf("  SRP: %s\n", set.problems[i].c_str());
    if (set.problems.size() > 30)
      std::printf("  SRP: ... %zu more warnings\n", set.problems.size() - 30);
    if (!set.errors.empty()) std::printf("  errors:\n%s\n", set.errors.c_str());

    const double late_interval_ms = 2.0 * shape.steps;
    std::printf(
        "NOTE B5 %.0f s soak (this run; the full 10 minutes is scripts/soak) of two IRb-6 EDPs "
        "(MuJoCo, 1 ms servo), two ECPs (follow_mp) and two VSPs (force_torque, range; periodic "
        "1 ms) in real processes; bench_soak acts as the MP and plays the raw sensors "
        "(raw_sensor_t "
        "at 1 kHz). Robots: a continuous joint motion in NEXT_POSE macro-steps of %d servo steps "
        "read in step %d, each robot's next one sent as soon as its reply came; %lld replies, "
        "round trip p50 %.0f / "
        "p99 %.0f us; late: every lost successor the EDPs report (the next macro-step was not "
        "queued before the running one ended: %lld), and a reply more than %.0f ms after the "
        "previous one. "
        "VSPs: GET_READING to both at 1 kHz, %lld replies; late beyond %.1f ms or a reading "
        "invalid or older than %d ms (%lld stale). Lost: resends or timeouts (attempts of 250 ms "
        "ECP, 40 ms VSP). Totals: %lld lost, %lld late; EDP servo overruns %lld. Baseline: bare "
        "LCM 64-byte ping at 1 kHz for %.0f s in the same run, %lld lost, %lld late against the "
        "same %.1f ms deadline (max %.0f us). Host stalls (a probe pinned to each CPU, SCHED_FIFO "
        "99 with --rt, woke 5 ms or more late): %zu in the baseline, %zu in the soak (the longest "
        "%.1f ms), %lld late replies inside one; the soak used %.0f %% of %ld CPUs. Scheduling: "
        "%s; nothing pinned (but the probes). value p50/p99 = VSP GET_READING round trip.\n",
        seconds, shape.steps, shape.value, static_cast<long long>(robot_requests),
        percentile(robot_us, 0.5), percentile(robot_us, 0.99),
        static_cast<long long>(set.lost_successors), late_interval_ms,
        static_cast<long long>(vsp_requests), shape.vsp_deadline_ms, kStaleAfterMs,
        static_cast<long long>(set.stale), static_cast<long long>(lost),
        static_cast<long long>(late), static_cast<long long>(set.overruns), baseline_seconds,
        static_cast<long long>(base.lost), static_cast<long long>(base.late), shape.vsp_deadline_ms,
        max_of(base.us), baseline_stalls, stalls.size(), longest_stall_ms,
        static_cast<long long>(late_in_stalls), 100.0 * cpu_share, cpus, scheduling.c_str());
    std::printf(
        "RESULT B5 baseline_p50=%.2f baseline_p99=%.2f value_p50=%.2f value_p99=%.2f "
        "baseline_lost=%lld baseline_late=%lld lost=%lld late=%lld robot_p50=%.2f "
        "robot_p99=%.2f replies=%lld seconds=%.0f overruns=%lld host_stalls=%zu "
        "late_in_stalls=%lld unit=us\n",
        percentile(base.us, 0.5), percentile(base.us, 0.99), percentile(vsp_us, 0.5),
        percentile(vsp_us, 0.99), static_cast<long long>(base.lost),
        static_cast<long long>(base.late), static_cast<long long>(lost),
        static_cast<long long>(late), percentile(robot_us, 0.5), percentile(robot_us, 0.99),
        static_cast<long long>(robot_requests + vsp_requests), seconds,
        static_cast<long long>(set.overruns), stalls.size(),
        static_cast<long long>(late_in_stalls));
    const std::int64_t counted = excuse_host_stalls && stalls_are_the_hosts ? late_own : late;
    const bool ok = lost == 0 && counted <= allow_late && set.errors.empty();
    if (ok && late > 0)
      std::printf(
          "bench_soak: %lld late repl%s tolerated (%lld inside host stalls%s, "
          "--allow-late=%ld); nothing lost\n",
          static_cast<long long>(late), late == 1 ? "y" : "ies",
          static_cast<long long>(late_in_stalls),
          excuse_host_stalls ? ", --excuse-host-stalls" : "", allow_late);
    if (!ok && lost == 0 && set.errors.empty())
      std::printf(
          "bench_soak: %lld late repl%s, %lld of them outside host stalls; %s allows "
          "%ld\n",
          static_cast<long long>(late), late == 1 ? "y" : "ies", static_cast<long long>(late_own),
          excuse_host_stalls ? "--excuse-host-stalls with --allow-late" : "--allow-late",
          allow_late);
    std::fflush(stdout);
    return ok ? 0 : 1;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "bench_soak: %s\n", e.what());
    return 1;
  }
}
