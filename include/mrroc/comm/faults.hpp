#pragma once
/// @file
/// Link fault injection: drop, duplicate and delay outgoing messages with given probabilities.
/// Used by tests (and by fault-injection runs) on the real request/reply code path.

#include <cstdint>
#include <mutex>
#include <random>

namespace mrroc::comm {

struct LinkFaults {
  double drop = 0.0;       ///< probability [0..1] that a published message is not sent
  double duplicate = 0.0;  ///< probability [0..1] that a published message is sent twice
  std::uint64_t seed = 1;  ///< random seed (runs are repeatable)
  double delay = 0.0;      ///< probability [0..1] that a copy is held back (and so reordered)
  double delay_ms = 20.0;  ///< a held-back copy waits a random time up to this [ms]

  [[nodiscard]] bool active() const { return drop > 0.0 || duplicate > 0.0 || delay > 0.0; }
};

/// What happens to one published message.
struct FaultPlan {
  int copies = 1;                     ///< 0, 1 or 2
  std::int64_t delay_us[2] = {0, 0};  ///< per copy: 0 = at once
};

/// Link faults for every link of the process from the environment variable MRROC_LINK_FAULTS,
/// e.g. "drop=0.1,duplicate=0.05,seed=7" (fault-injection runs of whole process sets); none when
/// unset. @throws Error naming the variable and the bad value.
LinkFaults link_faults_from_environment();

/// Decides, per message, how many copies to send (0, 1 or 2). Thread-safe.
class FaultDice {
 public:
  explicit FaultDice(const LinkFaults& faults) : faults_(faults), rng_(faults.seed) {}
  int copies() { return plan().copies; }
  FaultPlan plan() {
    FaultPlan p;
    if (!faults_.active()) return p;
    std::lock_guard lock(mutex_);
    std::uniform_real_distribution<double> u(0.0, 1.0);
    if (u(rng_) < faults_.drop) {
      p.copies = 0;
      return p;
    }
    p.copies = u(rng_) < faults_.duplicate ? 2 : 1;
    for (int i = 0; i < p.copies; ++i)
      if (faults_.delay > 0.0 && u(rng_) < faults_.delay)
        p.delay_us[i] = static_cast<std::int64_t>(u(rng_) * faults_.delay_ms * 1000.0) + 1;
    return p;
  }

 private:
  LinkFaults faults_;
  std::mutex mutex_;
  std::mt19937_64 rng_;
};

}  // namespace mrroc::comm
