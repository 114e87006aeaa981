#pragma once
/// @file
/// The `socketcan:<interface>` backend of mrroc::can::Bus (private to the library and its tests):
/// a CAN_RAW socket of the kernel's AF_CAN, bound to one interface, non-blocking, with kernel
/// receive timestamps (SO_TIMESTAMPNS) and receive-queue overflow counts (SO_RXQ_OVFL).
///
/// Depends only on the C++ standard library, POSIX / Linux and mrroc/core/error.hpp.
#include <memory>
#include <string_view>

#include "mrroc/can/bus.hpp"

namespace mrroc::can::detail {

/// Opens a CAN_RAW socket on `interface` (a valid interface name, at most IFNAMSIZ - 1
/// characters). @throws mrroc::HardwareError naming the URL, the interface and the cause: AF_CAN
/// or CAN_RAW not supported by the running kernel, no such interface, not a CAN interface, ...
std::unique_ptr<Bus> open_socketcan_bus(std::string_view url, std::string_view interface);

}  // namespace mrroc::can::detail
