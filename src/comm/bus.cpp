#include "mrroc/comm/bus.hpp"

#include <unistd.h>

#include <cstdlib>

#include "mrroc/comm/request_reply.hpp"
#include "mrroc/core/error.hpp"

namespace mrroc::comm {

namespace {
thread_local bool t_on_bus_thread = false;
}

std::string resolve_lcm_url(const std::string& url) {
  if (!url.empty()) return url;
  if (const char* env = std::getenv("LCM_DEFAULT_URL"); env != nullptr && *env != '\0') return env;
  return kDefaultLcmUrl;
}

Bus::Bus(const std::string& url) : url_(resolve_lcm_url(url)) {
  lcm_ = std::make_unique<lcm::LCM>(url_);
  if (!lcm_->good())
    throw Error("cannot open LCM at '" + url_ +
                "' (is there a multicast route, e.g. 'ip route add 224.0.0.0/4 dev lo'?)");
}

Bus::~Bus() { stop(); }

void Bus::start() {
  if (running_.exchange(true)) return;
  thread_ = std::thread([this] {
    t_on_bus_thread = true;
    while (running_.load(std::memory_order_relaxed)) lcm_->handleTimeout(50);
  });
}

void Bus::stop() {
  if (!running_.exchange(false)) return;
  if (thread_.joinable()) thread_.join();
}

bool Bus::on_bus_thread() const { return t_on_bus_thread; }

std::string unique_endpoint_name(const std::string& base) {
  return base + "#" + std::to_string(::getpid());
}

}  // namespace mrroc::comm
