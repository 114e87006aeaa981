#pragma once
/// @file
/// A CAN bus as the drives' side of the EDP sees it: classical CAN frames (`struct can_frame` of
/// <linux/can.h>) sent to and received from every other node on one bus.
///
/// Two backends carry identical frames and are chosen by a URL-like string:
///   - `socketcan:<interface>` (e.g. `socketcan:can0`, `socketcan:vcan0`): the kernel's AF_CAN /
///     CAN_RAW socket, with receive filters, error frames (CAN_ERR_FLAG) and kernel timestamps.
///   - `virtual:<name>` (e.g. `virtual:cell1`): a bus in user space that needs no kernel support.
///     Every process (or Bus object) that opens the same name is a node on that bus; each node
///     receives every frame sent by the other nodes after it joined, in one order for all of them,
///     never its own frames (as CAN_RAW with CAN_RAW_RECV_OWN_MSGS off). Nodes may join and leave
///     at any time. Names: 1-64 characters of A-Z a-z 0-9 _ -. The bus is the POSIX shared-memory
///     object /dev/shm/mrroc-can-<name>, a ring of 4096 frames: a node that falls more than that
///     behind loses the oldest frames (`BusStats::overruns`); a sender that dies half-way through
///     a send delays the other nodes by at most 10 ms. Filters and error-frame delivery follow
///     CAN_RAW; error frames may be sent (an emulator signals bus-off that way). A child process
///     opens its own node (a Bus object is not shared across fork). The environment variable
///     MRROC_CAN_NAMESPACE=<ns> (same rules as names) moves every virtual bus of the process and
///     its children to /dev/shm/mrroc-can-<ns>.<name>, e.g. to run two cells or tests side by side.
///
/// Threading: one Bus object is used by one thread at a time. `send` and `receive` do not allocate
/// and never throw, so they may be called from a servo loop.
#include <linux/can.h>

#include <chrono>
#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <string_view>

namespace mrroc::can {

/// One received frame.
struct Received {
  can_frame frame{};
  /// Time stamp [ns since the epoch, CLOCK_REALTIME]: SocketCAN: the kernel's receive time
  /// stamp (SO_TIMESTAMPNS); virtual bus: the time the sender put the frame on the bus.
  std::int64_t timestamp_ns = 0;
  /// The frame is an error frame (CAN_ERR_FLAG set in `frame.can_id`; see <linux/can/error.h>).
  [[nodiscard]] bool is_error() const noexcept { return (frame.can_id & CAN_ERR_FLAG) != 0U; }
};

/// Outcome of `Bus::send`.
enum class SendResult {
  sent,     ///< handed to the bus
  busy,     ///< transmit queue full; try again next cycle
  bus_off,  ///< the controller is bus-off (or the interface is down)
  error,    ///< any other failure (see `Bus::last_error()`)
};

/// Frame counters of one node.
struct BusStats {
  std::uint64_t sent = 0;
  std::uint64_t received = 0;      ///< data/remote frames delivered by `receive`
  std::uint64_t error_frames = 0;  ///< error frames delivered by `receive`
  /// Frames lost because this node read too slowly (SocketCAN: the socket's SO_RXQ_OVFL drop
  /// count, reported with the next frame read; virtual bus: ring positions skipped).
  std::uint64_t overruns = 0;
  std::uint64_t send_failures = 0;  ///< `send` calls that did not return `SendResult::sent`
};

/// One node on a CAN bus.
class Bus {
 public:
  virtual ~Bus() = default;
  Bus() = default;
  Bus(const Bus&) = delete;
  Bus& operator=(const Bus&) = delete;

  /// The URL the bus was opened with, e.g. "virtual:cell1".
  [[nodiscard]] virtual std::string url() const = 0;

  /// Sends one frame (data, remote or, on the virtual bus, error frame). Never blocks.
  virtual SendResult send(const can_frame& frame) noexcept = 0;

  /// Waits up to `timeout` for the next frame that passes the filters. Returns false on timeout
  /// (a zero timeout polls). Error frames are delivered only when `receive_error_frames(true)`.
  virtual bool receive(Received& out, std::chrono::nanoseconds timeout) noexcept = 0;

  /// Replaces the receive filters (CAN_RAW semantics: a frame passes when
  /// `(frame.can_id & mask) == (filter.can_id & mask)` for any filter; an empty list passes
  /// nothing; the default after opening passes every frame). @throws mrroc::HardwareError.
  virtual void set_filters(std::span<const can_filter> filters) = 0;

  /// Asks for error frames (bus-off, controller problems, ...). Default off.
  virtual void receive_error_frames(bool enable) = 0;

  [[nodiscard]] virtual BusStats stats() const noexcept = 0;
  /// Text of the last failed operation (for `SendResult::error` and friends).
  [[nodiscard]] virtual std::string last_error() const = 0;
};

/// Opens a bus by URL. @throws mrroc::ConfigError for a malformed URL or an unknown scheme (the
/// text names the URL and the known schemes) and mrroc::HardwareError when the bus cannot be opened
/// (e.g. "socketcan:can0: no such interface", or AF_CAN not supported by the running kernel).
std::unique_ptr<Bus> open_bus(std::string_view url);
/// Checks a bus URL as open_bus() does, without opening anything (a config check).
/// @throws mrroc::ConfigError as open_bus() for a malformed URL or an unknown scheme.
void check_bus_url(std::string_view url);

}  // namespace mrroc::can
