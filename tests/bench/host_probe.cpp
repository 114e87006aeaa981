// host_probe: the host's own stalls, as a reference for the EDP's servo overruns
// (scripts/stall-check). One thread per online CPU, pinned to it, SCHED_FIFO 99 where allowed
// (above every thread of a process set: the EDP's servo thread has 80), wakes every 1 ms on an
// absolute deadline; a wake-up `threshold_ms` or more late means that CPU ran nothing else either
// (a virtual machine's CPU taken by the hypervisor, or the kernel busy). Each such stall is printed
// at once, one line, with the wall-clock time (CLOCK_REALTIME) it ended:
//   STALL cpu=1 late_ms=12.4 end_unix_s=1764260000.123456
// and at the end (after `seconds`, or SIGINT/SIGTERM):
//   PROBE cpus=2 policy=SCHED_FIFO 99 wakeups=1199000 stalls=17 worst_ms=14.1
// Usage: host_probe [seconds (default 600)] [threshold_ms (default 5)]
#include <pthread.h>
#include <sched.h>
#include <signal.h>
#include <time.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <csignal>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

namespace {

std::atomic<bool> g_stop{false};
void on_signal(int) { g_stop = true; }

std::int64_t now_ns(clockid_t clock) {
  timespec t{};
  clock_gettime(clock, &t);
  return static_cast<std::int64_t>(t.tv_sec) * 1000000000LL + t.tv_nsec;
}

struct Totals {
  std::mutex mutex;
  long long wakeups = 0;
  long long stalls = 0;
  double worst_ms = 0.0;
  bool fifo = true;
};

void probe(int cpu, double seconds, double threshold_ms, Totals& totals) {
  cpu_set_t set;
  CPU_ZERO(&set);
  CPU_SET(static_cast<std::size_t>(cpu), &set);
  pthread_setaffinity_np(pthread_self(), sizeof set, &set);
  sched_param sp{};
  sp.sched_priority = 99;
  const bool fifo = pthread_setschedparam(pthread_self(), SCHED_FIFO, &sp) == 0;
  constexpr std::int64_t kPeriodNs = 1000000;
  const auto threshold_ns = static_cast<std::int64_t>(threshold_ms * 1e6);
  std::int64_t deadline = now_ns(CLOCK_MONOTONIC);
  const std::int64_t end = deadline + static_cast<std::int64_t>(seconds * 1e9);
  long long wakeups = 0;
  long long stalls = 0;
  double worst_ms = 0.0;
  while (!g_stop.load(std::memory_order_relaxed) && deadline < end) {
    deadline += kPeriodNs;
    timespec wake{};
    wake.tv_sec = static_cast<time_t>(deadline / 1000000000LL);
    wake.tv_nsec = static_cast<long>(deadline % 1000000000LL);
    while (clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &wake, nullptr) == EINTR) {
    }
    const std::int64_t late = now_ns(CLOCK_MONOTONIC) - deadline;
    ++wakeups;
    if (late >= threshold_ns) {
      ++stalls;
      const double late_ms = static_cast<double>(late) / 1e6;
      worst_ms = std::max(worst_ms, late_ms);
      std::printf("STALL cpu=%d late_ms=%.1f end_unix_s=%.6f\n", cpu, late_ms,
                  static_cast<double>(now_ns(CLOCK_REALTIME)) / 1e9);
      std::fflush(stdout);
    }
    if (late > kPeriodNs) deadline += (late / kPeriodNs) * kPeriodNs;  // no burst after a stall
  }
  std::lock_guard lock(totals.mutex);
  totals.wakeups += wakeups;
  totals.stalls += stalls;
  totals.worst_ms = std::max(totals.worst_ms, worst_ms);
  totals.fifo = totals.fifo && fifo;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc > 1 && (std::strcmp(argv[1], "--help") == 0 || std::strcmp(argv[1], "-h") == 0)) {
    std::printf(
        "usage: host_probe [seconds (600)] [threshold_ms (5)]\n"
        "One SCHED_FIFO 99 thread per CPU wakes every 1 ms; prints every wake-up threshold_ms or\n"
        "more late (STALL cpu=N late_ms=X end_unix_s=T) and a PROBE summary line.\n");
    return 0;
  }
  if (argc > 1 && std::strcmp(argv[1], "--version") == 0) {
    std::printf("host_probe (mrroc benchmarks)\n");
    return 0;
  }
  const double seconds = argc > 1 ? std::atof(argv[1]) : 600.0;
  const double threshold_ms = argc > 2 ? std::atof(argv[2]) : 5.0;
  if (!(seconds > 0.0) || !(threshold_ms > 0.0)) {
    std::fprintf(stderr, "host_probe: seconds and threshold_ms must be positive numbers\n");
    return 2;
  }
  std::signal(SIGINT, on_signal);
  std::signal(SIGTERM, on_signal);
  const long cpus = sysconf(_SC_NPROCESSORS_ONLN);
  Totals totals;
  std::vector<std::thread> threads;
  for (int c = 0; c < cpus; ++c)
    threads.emplace_back(probe, c, seconds, threshold_ms, std::ref(totals));
  for (auto& t : threads) t.join();
  std::printf("PROBE cpus=%ld policy=%s wakeups=%lld stalls=%lld worst_ms=%.1f\n", cpus,
              totals.fifo ? "SCHED_FIFO 99" : "SCHED_OTHER (SCHED_FIFO refused)", totals.wakeups,
              totals.stalls, totals.worst_ms);
  return 0;
}
