#pragma once
// Collects what a bus reports about the messages it dropped (Bus::set_drop_sink), for tests.

#include <mutex>
#include <string>
#include <utility>
#include <vector>

#include "mrroc/comm/bus.hpp"

namespace mrroc::test {

/// Collects the codes and texts a bus reports about dropped messages.
struct Drops {
  std::mutex mutex;
  std::vector<std::pair<int, std::string>> seen;
  void attach(comm::Bus& bus) {
    bus.set_drop_sink([this](int code, const std::string& text) {
      std::lock_guard lock(mutex);
      seen.emplace_back(code, text);
    });
  }
  std::vector<std::pair<int, std::string>> get() {
    std::lock_guard lock(mutex);
    return seen;
  }
};

}  // namespace mrroc::test
