// B2: lateness of the EDP's servo-loop wake-ups against a bare absolute-time clock_nanosleep
// loop; B7: heap allocations on the servo thread.
//
// The real ServoLoop runs in-process on the real MuJoCo plugin (IRb-6, 2 ms), driven by the
// real CommandInterpreter: SYNCHRO, then back-to-back joint macro-steps (10 servo steps each,
// reading in step 9, as the stock generators send them) for the whole run. At the same time a
// bare loop -- clock_nanosleep(TIMER_ABSTIME) on CLOCK_MONOTONIC, nothing else -- runs on its own
// thread with the same period and the same scheduling policy (SCHED_FIFO 80 if the system grants
// it, else SCHED_OTHER with timer slack 1 ns, as the servo loop does), half a period out of phase
// with the servo loop, so that both see the same host for the same time. Neither is pinned.
// Lateness = wake-up time - absolute deadline. The servo loop's p50/p99 come from its own
// TimingStats; the bare loop's from its samples, with the same percentile rule. A second, identical
// bare loop (the control, a quarter period after the servo loop) shows how far two loops that run
// the same code differ on this host in the same run: the noise floor of the comparison.
//
// Allocations: malloc, calloc, realloc and the aligned variants are interposed (forwarding to
// glibc) and counted when called on the servo thread, from 20 ms after the start (thread set-up)
// until the loop is stopped. operator new and MuJoCo's allocations all go through them.
//
// Usage: bench_servo [seconds]   (default 30)
// Prints "RESULT B2 ..." and "RESULT B7 ...".
#include <pthread.h>
#include <sched.h>
#include <sys/prctl.h>
#include <time.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include "bench_args.hpp"
#include "command_interpreter.hpp"
#include "mrroc/edp/arm_kinematics.hpp"
#include "mrroc/edp/hardware.hpp"
#include "mrroc/robot/robot_model.hpp"
#include "servo_loop.hpp"

// ---- Allocation counting on one thread (B7). ----

namespace {
std::atomic<long> g_allocations{0};
std::atomic<std::thread::id> g_watched{};
inline void count_allocation() {
  if (g_watched.load(std::memory_order_relaxed) == std::this_thread::get_id())
    g_allocations.fetch_add(1, std::memory_order_relaxed);
}
}  // namespace

extern "C" {
void* __libc_malloc(std::size_t size);
void* __libc_calloc(std::size_t count, std::size_t size);
void* __libc_realloc(void* p, std::size_t size);
void* __libc_memalign(std::size_t alignment, std::size_t size);
void __libc_free(void* p);

void* malloc(std::size_t size) noexcept {
  count_allocation();
  return __libc_malloc(size);
}
void* calloc(std::size_t count, std::size_t size) noexcept {
  count_allocation();
  return __libc_calloc(count, size);
}
void* realloc(void* p, std::size_t size) noexcept {
  count_allocation();
  return __libc_realloc(p, size);
}
void free(void* p) noexcept { __libc_free(p); }
void* aligned_alloc(std::size_t alignment, std::size_t size) noexcept {
  count_allocation();
  return __libc_memalign(alignment, size);
}
void* memalign(std::size_t alignment, std::size_t size) noexcept {
  count_allocation();
  return __libc_memalign(alignment, size);
}
int posix_memalign(void** out, std::size_t alignment, std::size_t size) noexcept {
  count_allocation();
  void* p = __libc_memalign(alignment, size);
  if (p == nullptr) return ENOMEM;
  *out = p;
  return 0;
}
}

namespace {

using namespace mrroc;
using namespace mrroc::edp;

constexpr double kPeriod = 0.002;
constexpr std::int64_t kPeriodNs = 2'000'000;

std::int64_t now_ns() {
  timespec t{};
  clock_gettime(CLOCK_MONOTONIC, &t);
  return static_cast<std::int64_t>(t.tv_sec) * 1'000'000'000LL + t.tv_nsec;
}

timespec to_timespec(std::int64_t ns) {
  timespec t{};
  t.tv_sec = static_cast<time_t>(ns / 1'000'000'000LL);
  t.tv_nsec = static_cast<long>(ns % 1'000'000'000LL);
  return t;
}

/// The same percentile rule as ServoLoop::timing().
double percentile(std::vector<float> v, double p) {
  if (v.empty()) return 0.0;
  std::sort(v.begin(), v.end());
  return static_cast<double>(v[static_cast<std::size_t>(p * static_cast<double>(v.size() - 1))]);
}

/// The bare loop: the same policy choice as the servo loop, then sleep to absolute deadlines.
struct BareLoop {
  std::vector<float> lateness_us;  // preallocated
  std::size_t count = 0;
  std::int64_t overruns = 0;
  std::string scheduling;
  std::atomic<bool> running{true};

  void run(std::int64_t first_deadline) {
    sched_param sp{};
    sp.sched_priority = 80;
    if (pthread_setschedparam(pthread_self(), SCHED_FIFO, &sp) == 0) {
      scheduling = "SCHED_FIFO 80";
    } else {
      prctl(PR_SET_TIMERSLACK, 1UL, 0UL, 0UL, 0UL);
      scheduling = "SCHED_OTHER, timer slack 1 ns";
    }
    std::int64_t deadline = first_deadline;
    while (running.load(std::memory_order_relaxed) && count < lateness_us.size()) {
      const timespec wake = to_timespec(deadline);
      while (clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &wake, nullptr) == EINTR) {
      }
      const std::int64_t late = now_ns() - deadline;
      lateness_us[count++] = static_cast<float>(static_cast<double>(late) / 1000.0);
      if (late > kPeriodNs) ++overruns;
      deadline += kPeriodNs;
      if (late > kPeriodNs) deadline += (late / kPeriodNs) * kPeriodNs;  // as the servo loop
    }
  }
};

Instruction set_joints(const std::vector<double>& q, int steps, int value_in_step_no) {
  Instruction in;
  in.type = InstructionType::set;
  in.set = item::arm;
  in.set_arm_type = ArmRepresentation::joint;
  in.motion_type = MotionType::absolute;
  in.motion_steps = steps;
  in.value_in_step_no = value_in_step_no;
  in.arm = q;
  return in;
}

}  // namespace

int main(int argc, char** argv) {
  if (mrroc::bench::help_requested(
          argc, argv,
          "Usage: bench_servo [SECONDS]\n"
          "B2: the EDP servo loop's wake-up lateness against a bare clock_nanosleep loop running\n"
          "beside it for SECONDS (default 30); B7: heap allocations on the servo thread.\n"
          "Prints RESULT B2/B7 and NOTE lines.\n"))
    return 0;
  const double seconds = argc > 1 ? static_cast<double>(mrroc::bench::whole_number(
                                        "bench_servo", "SECONDS", argv[1], 1, 86400, "s"))
                                  : 30.0;
  // The counter must see an allocation made on the watched thread.
  g_watched = std::this_thread::get_id();
  {
    auto probe = std::make_unique<volatile int>(1);
    (void)probe;
  }
  g_watched = std::thread::id{};
  if (g_allocations.exchange(0) != 1) {
    std::fprintf(stderr, "bench_servo: the allocation counter does not work\n");
    return 1;
  }
  try {
    const RobotModel model = load_robot_model(std::string(MRROC_SOURCE_DIR) + "/robots/irb6");
    std::unique_ptr<Hardware> hardware = make_hardware("mujoco");
    HardwareSetup setup;
    setup.robot = "irb6";
    setup.model_dir = model.folder;
    setup.servo_period_s = kPeriod;
    setup.synchro_positions = model.synchro_joint_positions;
    hardware->configure(setup);
    ServoLoop servo(*hardware, model, kPeriod);
    const std::unique_ptr<ArmKinematics> kinematics = make_arm_kinematics(model);
    CommandInterpreter interpreter(servo, model, *kinematics, kPeriod);

    BareLoop bare;
    BareLoop control;
    bare.lateness_us.assign(static_cast<std::size_t>(seconds / kPeriod) + 1000, 0.0F);
    control.lateness_us.assign(bare.lateness_us.size(), 0.0F);

    servo.start();
    // The servo loop's first deadline is about one period after start(); the bare loop's half a
    // period later, the control's a quarter period later.
    const std::int64_t servo_first = now_ns() + kPeriodNs;
    std::thread bare_thread([&bare, servo_first] { bare.run(servo_first + kPeriodNs / 2); });
    std::thread control_thread(
        [&control, servo_first] { control.run(servo_first + kPeriodNs / 4); });
    const auto t0 = std::chrono::steady_clock::now();
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
    g_allocations = 0;
    g_watched = servo.servo_thread_id();
    const std::int64_t first_watched_cycle = servo.latest().cycle;

    // Command thread (this one): SYNCHRO, then back-to-back macro-steps of the column along
    // 0.15 (1 - cos(2 pi t / 6 s)) rad until the time is up: from rest, at most 0.16 rad/s and
    // 0.17 rad/s^2 (the column's limits are 1.5 rad/s and 3 rad/s^2), so that the EDP accepts
    // every macro-step as the stock generators' are accepted.
    // An instruction refused ends the run: the threads are stopped before the error is reported.
    std::string refused;
    auto exec = [&](const Instruction& in) {
      const Reply r = interpreter.execute(in);
      if (r.type == ReplyType::error && refused.empty()) refused = r.error_text;
      return r.type != ReplyType::error;
    };
    Instruction query;
    query.type = InstructionType::query;
    Instruction synchro;
    synchro.type = InstructionType::synchro;
    constexpr int kSteps = 10;
    constexpr double kAmplitude = 0.15;                            // [rad]
    constexpr double kOmega = 2.0 * 3.14159265358979323846 / 6.0;  // [rad/s]
    std::vector<double> q = model.synchro_joint_positions;
    double q0 = q[0];
    long macro_steps = 0;
    long profile_steps = 0;  // macro-steps since the profile (re)started from rest
    long restarts = 0;
    const auto end = t0 + std::chrono::duration<double>(seconds);
    if (exec(synchro) && exec(query)) {
      bool going = true;
      while (going && std::chrono::steady_clock::now() < end) {
        const double t = static_cast<double>((profile_steps + 1) * kSteps) * kPeriod;
        q[0] = q0 + kAmplitude * (1.0 - std::cos(kOmega * t));
        going = exec(set_joints(q, kSteps, kSteps - 1)) && exec(query);
        ++macro_steps;
        ++profile_steps;
        if (!going && refused.find("would accelerate") != std::string::npos) {
          // A successor came late (the host held this thread): the EDP ramped the robot down
          // and refused a later macro-step as too abrupt from where the ramp left it. Go on from
          // where the robot stands, from rest, as ecp::Move re-plans; counted.
          ++restarts;
          refused.clear();
          const auto rest_by = std::chrono::steady_clock::now() + std::chrono::seconds(2);
          while (!servo.stopped() && std::chrono::steady_clock::now() < rest_by)
            std::this_thread::sleep_for(std::chrono::milliseconds(1));
          const Reading here = servo.latest();
          for (std::size_t j = 0; j < q.size(); ++j) q[j] = here.desired[j];
          q0 = q[0];
          profile_steps = 0;
          going = true;
        }
      }
      // The last one ends at rest (it may need a few more steps than the others to get there).
      if (going) going = exec(set_joints(q, 10 * kSteps, 10 * kSteps + 1)) && exec(query);
    }
    bare.running = false;
    control.running = false;
    bare_thread.join();
    control_thread.join();
    if (!refused.empty()) {
      servo.stop();
      throw Error("EDP refused an instruction: " + refused);
    }
    const TimingStats t = servo.timing();
    const std::int64_t watched_cycles = servo.latest().cycle - first_watched_cycle;
    const long allocations = g_allocations.load();
    g_watched = std::thread::id{};
    servo.stop();

    const std::vector<float> samples(bare.lateness_us.begin(),
                                     bare.lateness_us.begin() + static_cast<long>(bare.count));
    const double b50 = percentile(samples, 0.5);
    const double b99 = percentile(samples, 0.99);
    const std::vector<float> control_samples(
        control.lateness_us.begin(),
        control.lateness_us.begin() + static_cast<long>(control.count));
    const double c50 = percentile(control_samples, 0.5);
    const double c99 = percentile(control_samples, 0.99);
    std::printf("B2 servo-loop lateness, %.0f s at %.0f us (%s), %ld macro-steps executed\n",
                seconds, kPeriod * 1e6, t.scheduling.c_str(), macro_steps);
    std::printf(
        "  bare clock_nanosleep loop (%s): %zu cycles, p50 %.1f us, p99 %.1f us, "
        "max %.1f us, %lld overruns\n",
        bare.scheduling.c_str(), bare.count, b50, b99, percentile(samples, 1.0),
        static_cast<long long>(bare.overruns));
    std::printf(
        "  control (same bare loop):      %zu cycles, p50 %.1f us, p99 %.1f us, max %.1f "
        "us\n",
        control.count, c50, c99, percentile(control_samples, 1.0));
    std::printf(
        "  EDP servo loop:                %lld cycles, p50 %.1f us, p99 %.1f us, max %.1f "
        "us, %lld overruns\n",
        static_cast<long long>(t.cycles), t.lateness_p50_us, t.lateness_p99_us, t.lateness_max_us,
        static_cast<long long>(t.overruns));
    std::printf(
        "B7 heap allocations on the servo thread: %ld in %lld cycles (SYNCHRO and %ld "
        "macro-steps)\n",
        allocations, static_cast<long long>(watched_cycles), macro_steps);
    std::printf(
        "NOTE B2 %.0f s, period 2 ms, policy %s for both loops (servo loop: %s), run "
        "side by side half a period apart, unpinned; the servo loop executed SYNCHRO and "
        "%ld back-to-back macro-steps meanwhile (restarted from rest after a late successor: "
        "%ld). Cycles woken more than a period late: "
        "bare %lld, servo %lld. Noise floor: an identical second bare loop in the same "
        "run had p50 %.1f us, p99 %.1f us (p99 ratio %.2f against the first).\n",
        seconds, bare.scheduling.c_str(), t.scheduling.c_str(), macro_steps, restarts,
        static_cast<long long>(bare.overruns), static_cast<long long>(t.overruns), c50, c99,
        c99 / b99);
    std::printf(
        "RESULT B2 baseline_p50=%.2f baseline_p99=%.2f value_p50=%.2f value_p99=%.2f "
        "samples=%lld unit=us\n",
        b50, b99, t.lateness_p50_us, t.lateness_p99_us, static_cast<long long>(t.cycles));
    std::printf(
        "NOTE B7 malloc, calloc, realloc and the aligned allocators interposed and "
        "counted on the servo thread over %lld cycles (SYNCHRO, then %ld macro-steps), "
        "from 20 ms after the thread started (its one-time set-up) until stop.\n",
        static_cast<long long>(watched_cycles), macro_steps);
    std::printf("RESULT B7 value=%ld samples=%lld unit=allocations\n", allocations,
                static_cast<long long>(watched_cycles));
    return 0;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "bench_servo: %s\n", e.what());
    return 1;
  }
}
