#pragma once
/// @file
/// Link fault injection: drop and duplicate outgoing messages with given probabilities.
/// Used by tests (and by fault-injection runs) on the real request/reply code path.

#include <cstdint>
#include <mutex>
#include <random>

namespace mrroc::comm {

struct LinkFaults {
  double drop = 0.0;       ///< probability [0..1] that a published message is not sent
  double duplicate = 0.0;  ///< probability [0..1] that a published message is sent twice
  std::uint64_t seed = 1;  ///< random seed (runs are repeatable)

  [[nodiscard]] bool active() const { return drop > 0.0 || duplicate > 0.0; }
};

/// Link faults for every link of the process from the environment variable MRROC_LINK_FAULTS,
/// e.g. "drop=0.1,duplicate=0.05,seed=7" (fault-injection runs of whole process sets); none when
/// unset. @throws Error naming the variable and the bad value.
LinkFaults link_faults_from_environment();

/// Decides, per message, how many copies to send (0, 1 or 2). Thread-safe.
class FaultDice {
 public:
  explicit FaultDice(const LinkFaults& faults) : faults_(faults), rng_(faults.seed) {}
  int copies() {
    if (!faults_.active()) return 1;
    std::lock_guard lock(mutex_);
    std::uniform_real_distribution<double> u(0.0, 1.0);
    if (u(rng_) < faults_.drop) return 0;
    return u(rng_) < faults_.duplicate ? 2 : 1;
  }

 private:
  LinkFaults faults_;
  std::mutex mutex_;
  std::mt19937_64 rng_;
};

}  // namespace mrroc::comm
