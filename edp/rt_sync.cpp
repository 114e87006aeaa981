#include "rt_sync.hpp"

#include <linux/futex.h>
#include <sys/syscall.h>
#include <unistd.h>

#include <cerrno>
#include <climits>
#include <ctime>

#include "mrroc/core/error.hpp"

namespace mrroc::edp {

PiMutex::PiMutex() {
  pthread_mutexattr_t attr;
  pthread_mutexattr_init(&attr);
  pthread_mutexattr_setprotocol(&attr, PTHREAD_PRIO_INHERIT);
  const int rc = pthread_mutex_init(&mutex_, &attr);
  pthread_mutexattr_destroy(&attr);
  if (rc != 0) throw Error("servo loop: a priority-inheriting mutex could not be created");
}

PiMutex::~PiMutex() { pthread_mutex_destroy(&mutex_); }

void PiMutex::lock() { pthread_mutex_lock(&mutex_); }
void PiMutex::unlock() { pthread_mutex_unlock(&mutex_); }
bool PiMutex::try_lock() { return pthread_mutex_trylock(&mutex_) == 0; }

namespace {
long futex(std::atomic<std::uint32_t>* word, int op, std::uint32_t value, const timespec* timeout) {
  // std::atomic<uint32_t> has the size and alignment of its value on Linux targets.
  static_assert(sizeof(std::atomic<std::uint32_t>) == sizeof(std::uint32_t));
  return syscall(SYS_futex, reinterpret_cast<std::uint32_t*>(word), op, value, timeout, nullptr, 0);
}
}  // namespace

void Wakeup::notify() {
  counter_.fetch_add(1, std::memory_order_acq_rel);
  futex(&counter_, FUTEX_WAKE_PRIVATE, INT_MAX, nullptr);
}

void Wakeup::wait_for(std::uint32_t seen, std::chrono::nanoseconds timeout) const {
  if (timeout.count() <= 0) return;
  timespec t{};
  t.tv_sec = static_cast<time_t>(timeout.count() / 1000000000LL);
  t.tv_nsec = static_cast<long>(timeout.count() % 1000000000LL);
  // Returns at once (EAGAIN) when the counter already moved: no lost wake-up.
  futex(&counter_, FUTEX_WAIT_PRIVATE, seen, &t);
}

}  // namespace mrroc::edp
