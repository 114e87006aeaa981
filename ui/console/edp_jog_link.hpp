#pragma once
// The console's EDP client for jogging (edp::Client, endpoint ui/jog/<robot>#<pid>): the one
// place where the console talks to an EDP.

#include <memory>
#include <string>

#include "console/jog.hpp"

namespace mrroc::comm {
class Bus;
}

namespace mrroc::ui {

/// A JogLink over the bus to the EDP of `robot` (250 ms per attempt, 8 attempts).
std::unique_ptr<JogLink> make_edp_jog_link(comm::Bus& bus, const std::string& robot);

}  // namespace mrroc::ui
