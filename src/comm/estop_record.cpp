#include "mrroc/comm/estop_record.hpp"

#include <algorithm>

namespace mrroc::comm {

namespace {
void remember(std::deque<EstopCommandRef>& list, const EstopCommandRef& ref) {
  if (ref.id == 0) return;  // a command without a number has no copies to know
  list.push_back(ref);
  while (list.size() > EstopRecord::kRemembered) list.pop_front();
}
bool contains(const std::deque<EstopCommandRef>& list, const EstopCommandRef& ref) {
  return std::find(list.begin(), list.end(), ref) != list.end();
}
}  // namespace

bool EstopRecord::is_held(const EstopCommandRef& ref) const { return contains(held_, ref); }

bool EstopRecord::was_released(const EstopCommandRef& ref) const {
  return ref.id != 0 && contains(released_, ref);
}

void EstopRecord::hold(const EstopCommandRef& ref) {
  held_.push_back(ref);
  if (held_.size() > kMaxHeld) {
    held_.pop_front();
    overflowed_ = true;
  }
}

bool EstopRecord::engage(const EstopCommandRef& ref) {
  if (was_released(ref) || is_held(ref)) return false;
  hold(ref);
  return true;
}

std::optional<std::vector<EstopCommandRef>> EstopRecord::release(const EstopCommandRef& ref) {
  if (ref.id != 0 && contains(releases_, ref)) return std::nullopt;
  remember(releases_, ref);
  std::vector<EstopCommandRef> ended(held_.begin(), held_.end());
  for (const EstopCommandRef& e : held_) remember(released_, e);
  held_.clear();
  overflowed_ = false;
  return ended;
}

bool EstopRecord::latched_engaged(const std::vector<EstopCommandRef>& engages,
                                  const std::string& announcer) {
  const bool before = holding();
  if (engages.empty()) {
    const EstopCommandRef anonymous{announcer, 0};
    if (!is_held(anonymous)) hold(anonymous);
  }
  for (const EstopCommandRef& e : engages)
    if (!was_released(e) && !is_held(e)) hold(e);
  return !before && holding();
}

bool EstopRecord::latched_released(const std::vector<EstopCommandRef>& ended) {
  if (!holding()) return false;
  for (const EstopCommandRef& e : ended) {
    if (e.id == 0) continue;  // only a command with a number can be named
    auto it = std::find(held_.begin(), held_.end(), e);
    if (it == held_.end()) continue;
    held_.erase(it);
    remember(released_, e);
  }
  return !holding();
}

}  // namespace mrroc::comm
