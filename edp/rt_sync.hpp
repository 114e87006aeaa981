#pragma once
/// @file
/// The two synchronisation primitives between the EDP's servo thread and the threads that talk
/// to it (command, bus, state broadcast), chosen so that the servo thread never waits on them:
///
/// - `PiMutex`: a priority-inheriting mutex. Every critical section on it copies a few hundred
///   bytes at most, and a thread holding it while the SCHED_FIFO servo thread asks for it runs
///   at the servo thread's priority until it lets go, so a command thread preempted by a busy
///   host cannot hold the servo thread back (no priority inversion).
/// - `Wakeup`: an event counter on a futex. `notify()` never blocks (one FUTEX_WAKE system call),
///   unlike `std::condition_variable::notify_all`, whose mutex a preempted waiter may hold;
///   `wait_for(seen, timeout)` sleeps until the counter moves from `seen`, so a notification
///   between checking a condition and sleeping is never lost.

#include <pthread.h>

#include <atomic>
#include <chrono>
#include <cstdint>

namespace mrroc::edp {

/// A priority-inheriting mutex (Lockable: use with std::lock_guard / std::unique_lock).
class PiMutex {
 public:
  PiMutex();
  ~PiMutex();
  PiMutex(const PiMutex&) = delete;
  PiMutex& operator=(const PiMutex&) = delete;
  void lock();
  void unlock();
  bool try_lock();

 private:
  pthread_mutex_t mutex_;
};

/// An event counter that wakes every thread waiting for it to change.
class Wakeup {
 public:
  /// The counter now; pass it to wait_for() after checking the condition it guards.
  [[nodiscard]] std::uint32_t value() const { return counter_.load(std::memory_order_acquire); }
  /// Moves the counter and wakes every waiter. Never blocks.
  void notify();
  /// Sleeps until the counter differs from `seen`, or `timeout` passed. May wake spuriously:
  /// callers re-check their condition.
  void wait_for(std::uint32_t seen, std::chrono::nanoseconds timeout) const;

 private:
  mutable std::atomic<std::uint32_t> counter_{0};
};

/// Waits until `ready()` (checked under `mutex`) or `timeout`; returns the last `ready()`.
template <class Ready>
bool wait_until_ready(PiMutex& mutex, const Wakeup& wakeup, std::chrono::nanoseconds timeout,
                      Ready&& ready) {
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  for (;;) {
    const std::uint32_t seen = wakeup.value();
    {
      mutex.lock();
      const bool ok = ready();
      mutex.unlock();
      if (ok) return true;
    }
    const auto now = std::chrono::steady_clock::now();
    if (now >= deadline) return false;
    wakeup.wait_for(seen, deadline - now);
  }
}

}  // namespace mrroc::edp
