#include "mrroc/ecp/conditions.hpp"

namespace mrroc::ecp {

bool OperatorTriggerCondition::check(const SensorList&) {
  return triggered_.load(std::memory_order_acquire);
}

}  // namespace mrroc::ecp
