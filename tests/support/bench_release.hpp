#pragma once
// Benchmarks start their EDPs without a launcher, so no latch announces the emergency stop's
// state and the EDPs start stopped (docs/operating.md, "Emergency stop"): release them as
// `mrroc-ui release` would.
#include <unistd.h>

#include <chrono>
#include <string>
#include <thread>

#include "mrroc/comm/bus.hpp"
#include "mrroc/comm/request_reply.hpp"
#include "mrroc/config/process_set.hpp"
#include "mrroc/core/time.hpp"
#include "mrroc_lcm/emergency_stop_t.hpp"

namespace mrroc::bench {

inline void release_emergency_stops(comm::Bus& bus) {
  mrroc_lcm::emergency_stop_t release{};
  release.header.sender = "bench#" + std::to_string(::getpid());
  release.header.kind = mrroc_lcm::header_t::BROADCAST;
  release.action = mrroc_lcm::emergency_stop_t::RELEASE;
  for (int i = 0; i < 3; ++i) {
    release.header.utime = now_utime();
    comm::publish(bus, channels::emergency_stop, release);
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
}

}  // namespace mrroc::bench
