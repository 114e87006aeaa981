#pragma once
/// @file
/// The `virtual:<name>` backend of mrroc::can::Bus (private to the library and its tests).
///
/// A bus is a POSIX shared-memory object `/mrroc-can-<name>` (on Linux the file
/// `/dev/shm/mrroc-can-<name>`) holding a broadcast ring of `kVirtualBusSlots` frames:
///  - a sender claims the next ring position with an atomic fetch_add on the shared write index,
///    writes the frame into that slot under a per-slot sequence number (seqlock) and publishes it;
///  - every node keeps its own read position; a node that falls more than the ring size behind
///    loses the oldest frames, counted in `BusStats::overruns`;
///  - a claimed slot that stays unpublished for `kVirtualBusStallNs` (its sender died or stalled
///    between claiming and publishing) is skipped and counted as an overrun, so that a crashed
///    node cannot block the others;
///  - `receive` sleeps on a futex in the shared object (not a private one) and senders wake it.
/// The object is created by the first node and kept when the last one leaves (nodes may join and
/// leave at any time); a later node reuses it after checking its header (magic, version, sizes).
/// Creation and the header check are serialised with flock(2), which the kernel releases when a
/// process dies.
///
/// Depends only on the C++ standard library, POSIX / Linux and mrroc/core/error.hpp, so that it
/// can be compiled into a statically linked test program.
#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>
#include <string_view>

#include "mrroc/can/bus.hpp"

namespace mrroc::can::detail {

/// Frames a node may fall behind before it loses the oldest ones.
inline constexpr std::uint32_t kVirtualBusSlots = 4096;
/// Longest bus name [characters]; names use [A-Za-z0-9_-].
inline constexpr std::size_t kVirtualBusNameMax = 64;
/// A claimed but unpublished slot is skipped by readers after this long [ns].
inline constexpr std::int64_t kVirtualBusStallNs = 10'000'000;

/// Environment variable that puts every virtual bus of a process (and of the processes it
/// starts) into a namespace of its own: with MRROC_CAN_NAMESPACE=t1, `virtual:cell1` is the
/// object "/mrroc-can-t1.cell1". Same character rules and limit as bus names.
inline constexpr const char* kVirtualBusNamespaceVariable = "MRROC_CAN_NAMESPACE";

/// The shared-memory object's name for a bus name: "/mrroc-can-<name>", or
/// "/mrroc-can-<namespace>.<name>" when MRROC_CAN_NAMESPACE is set.
std::string virtual_bus_object(std::string_view name);

/// Opens (creating it if needed) the virtual bus `name` (already validated) as a new node.
/// @throws mrroc::HardwareError when the shared-memory object cannot be created or mapped, or
/// exists with another layout (left by another mrroc version).
std::unique_ptr<Bus> open_virtual_bus(std::string_view url, std::string_view name);

/// Fault injection for tests: claims the next ring position as a sender would and never
/// publishes it, like a sender that died right after claiming (`marked` = false) or while
/// writing the slot (`marked` = true). `bus` must be a virtual bus.
void abandon_claim_for_test(Bus& bus, bool marked);

}  // namespace mrroc::can::detail
