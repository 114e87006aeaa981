// The SocketCAN backend: one CAN_RAW socket (see socketcan.hpp).
#include "socketcan.hpp"

#include <linux/can/error.h>
#include <linux/can/raw.h>
#include <net/if.h>
#include <poll.h>
#include <sys/socket.h>
#include <sys/time.h>
#include <time.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <string>

#include "mrroc/core/error.hpp"

namespace mrroc::can::detail {

namespace {

std::int64_t clock_ns(clockid_t clock) {
  timespec t{};
  clock_gettime(clock, &t);
  return static_cast<std::int64_t>(t.tv_sec) * 1'000'000'000LL + t.tv_nsec;
}

const char* errno_name(int error) {
  switch (error) {
    case EAFNOSUPPORT: return "EAFNOSUPPORT";
    case EPROTONOSUPPORT: return "EPROTONOSUPPORT";
    case ENODEV: return "ENODEV";
    case ENXIO: return "ENXIO";
    case ENETDOWN: return "ENETDOWN";
    case ENOBUFS: return "ENOBUFS";
    case EAGAIN: return "EAGAIN";
    case EINVAL: return "EINVAL";
    case EPERM: return "EPERM";
    case EACCES: return "EACCES";
    case EMSGSIZE: return "EMSGSIZE";
    default: return "errno";
  }
}

class SocketCan final : public Bus {
 public:
  SocketCan(std::string url, std::string interface)
      : url_(std::move(url)), interface_(std::move(interface)) {
    fd_ = ::socket(PF_CAN, SOCK_RAW | SOCK_NONBLOCK | SOCK_CLOEXEC, CAN_RAW);
    if (fd_ < 0) {
      const int e = errno;
      if (e == EAFNOSUPPORT)
        throw HardwareError(url_ +
                            ": AF_CAN not supported by the running kernel (EAFNOSUPPORT); "
                            "load the can and can_raw modules, or use a virtual:<name> bus");
      if (e == EPROTONOSUPPORT)
        throw HardwareError(url_ +
                            ": CAN_RAW not supported by the running kernel "
                            "(EPROTONOSUPPORT); load the can_raw module");
      fail("socket(PF_CAN, SOCK_RAW, CAN_RAW)", e);
    }
    try {
      const unsigned index = if_nametoindex(interface_.c_str());
      if (index == 0) {
        const int e = errno;
        if (e == ENODEV || e == ENXIO)
          throw HardwareError(url_ + ": no such interface '" + interface_ + "' (" + errno_name(e) +
                              ")");
        fail("if_nametoindex", e);
      }
      const int on = 1;
      // Kernel receive time stamps, nanoseconds; microseconds where an old kernel lacks those.
      stamp_ns_ = setsockopt(fd_, SOL_SOCKET, SO_TIMESTAMPNS, &on, sizeof on) == 0;
      if (!stamp_ns_ && setsockopt(fd_, SOL_SOCKET, SO_TIMESTAMP, &on, sizeof on) != 0)
        fail("setsockopt(SO_TIMESTAMP)", errno);
      if (setsockopt(fd_, SOL_SOCKET, SO_RXQ_OVFL, &on, sizeof on) != 0)
        fail("setsockopt(SO_RXQ_OVFL)", errno);
      sockaddr_can address{};
      address.can_family = AF_CAN;
      address.can_ifindex = static_cast<int>(index);
      if (::bind(fd_, reinterpret_cast<const sockaddr*>(&address), sizeof address) != 0) {
        const int e = errno;
        if (e == ENODEV)
          throw HardwareError(url_ + ": interface '" + interface_ +
                              "' is not a CAN interface (bind: ENODEV)");
        fail("bind", e);
      }
    } catch (...) {
      ::close(fd_);
      throw;
    }
  }

  SocketCan(const SocketCan&) = delete;
  SocketCan& operator=(const SocketCan&) = delete;
  ~SocketCan() override { ::close(fd_); }

  [[nodiscard]] std::string url() const override { return url_; }

  SendResult send(const can_frame& frame) noexcept override {
    for (;;) {
      const ssize_t n = ::send(fd_, &frame, sizeof frame, MSG_DONTWAIT);
      if (n == static_cast<ssize_t>(sizeof frame)) {
        ++stats_.sent;
        return SendResult::sent;
      }
      const int e = n < 0 ? errno : EMSGSIZE;
      if (e == EINTR) continue;
      ++stats_.send_failures;
      remember("send", e);
      if (e == EAGAIN || e == EWOULDBLOCK || e == ENOBUFS) return SendResult::busy;
      if (e == ENETDOWN) return SendResult::bus_off;
      return SendResult::error;
    }
  }

  bool receive(Received& out, std::chrono::nanoseconds timeout) noexcept override {
    // Clamped to 10^15 ns (11.6 days) so that the deadline cannot overflow.
    const std::int64_t timeout_ns =
        std::clamp<std::int64_t>(timeout.count(), 0, 1'000'000'000'000'000LL);
    const std::int64_t deadline = clock_ns(CLOCK_MONOTONIC) + timeout_ns;
    for (;;) {
      if (read_one(out)) return true;
      if (last_read_errno_ != EAGAIN && last_read_errno_ != EWOULDBLOCK &&
          last_read_errno_ != EINTR)
        return false;
      const std::int64_t left = deadline - clock_ns(CLOCK_MONOTONIC);
      if (left <= 0) return false;
      pollfd p{fd_, POLLIN, 0};
      timespec wait{};
      wait.tv_sec = static_cast<time_t>(left / 1'000'000'000LL);
      wait.tv_nsec = static_cast<long>(left % 1'000'000'000LL);
      const int r = ::ppoll(&p, 1, &wait, nullptr);
      if (r < 0 && errno != EINTR) {
        remember("ppoll", errno);
        return false;
      }
    }
  }

  void set_filters(std::span<const can_filter> filters) override {
    if (filters.size() > CAN_RAW_FILTER_MAX)
      throw HardwareError(url_ + ": " + std::to_string(filters.size()) +
                          " receive filters, the limit is " + std::to_string(CAN_RAW_FILTER_MAX) +
                          " (CAN_RAW_FILTER_MAX)");
    if (setsockopt(fd_, SOL_CAN_RAW, CAN_RAW_FILTER, filters.empty() ? nullptr : filters.data(),
                   static_cast<socklen_t>(filters.size() * sizeof(can_filter))) != 0)
      fail("setsockopt(CAN_RAW_FILTER) with " + std::to_string(filters.size()) + " filters", errno);
  }

  void receive_error_frames(bool enable) override {
    const can_err_mask_t mask = enable ? CAN_ERR_MASK : 0U;
    if (setsockopt(fd_, SOL_CAN_RAW, CAN_RAW_ERR_FILTER, &mask, sizeof mask) != 0)
      fail("setsockopt(CAN_RAW_ERR_FILTER)", errno);
  }

  [[nodiscard]] BusStats stats() const noexcept override { return stats_; }
  [[nodiscard]] std::string last_error() const override { return last_error_; }

 private:
  [[noreturn]] void fail(const std::string& what, int error) const {
    throw HardwareError(url_ + ": " + what + " on interface '" + interface_ +
                        "': " + std::strerror(error) + " (" + errno_name(error) + ")");
  }

  void remember(const char* what, int error) noexcept {
    std::snprintf(last_error_, sizeof last_error_, "%s: %s: %s (%s)", url_.c_str(), what,
                  std::strerror(error), errno_name(error));
  }

  /// One non-blocking recvmsg; false with last_read_errno_ set when nothing was read.
  bool read_one(Received& out) noexcept {
    can_frame frame{};
    iovec io{&frame, sizeof frame};
    msghdr message{};
    message.msg_iov = &io;
    message.msg_iovlen = 1;
    message.msg_control = control_;
    message.msg_controllen = sizeof control_;
    const ssize_t n = ::recvmsg(fd_, &message, MSG_DONTWAIT);
    if (n < 0) {
      last_read_errno_ = errno;
      if (last_read_errno_ != EAGAIN && last_read_errno_ != EWOULDBLOCK &&
          last_read_errno_ != EINTR)
        remember("recvmsg", last_read_errno_);
      return false;
    }
    last_read_errno_ = 0;
    if (n != static_cast<ssize_t>(sizeof frame)) {  // CAN FD frames are not enabled
      last_read_errno_ = EMSGSIZE;
      remember("recvmsg (not a classical CAN frame)", EMSGSIZE);
      return false;
    }
    std::int64_t stamp = 0;
    for (cmsghdr* c = CMSG_FIRSTHDR(&message); c != nullptr; c = CMSG_NXTHDR(&message, c)) {
      if (c->cmsg_level != SOL_SOCKET) continue;
      if (c->cmsg_type == SCM_TIMESTAMPNS) {
        timespec t{};
        std::memcpy(&t, CMSG_DATA(c), sizeof t);
        stamp = static_cast<std::int64_t>(t.tv_sec) * 1'000'000'000LL + t.tv_nsec;
      } else if (c->cmsg_type == SCM_TIMESTAMP) {
        timeval t{};
        std::memcpy(&t, CMSG_DATA(c), sizeof t);
        stamp = static_cast<std::int64_t>(t.tv_sec) * 1'000'000'000LL + t.tv_usec * 1000LL;
      } else if (c->cmsg_type == SO_RXQ_OVFL) {
        std::uint32_t dropped = 0;  // frames the socket dropped so far (wraps at 2^32)
        std::memcpy(&dropped, CMSG_DATA(c), sizeof dropped);
        stats_.overruns += static_cast<std::uint32_t>(dropped - dropped_seen_);
        dropped_seen_ = dropped;
      }
    }
    out.frame = frame;
    out.timestamp_ns = stamp != 0 ? stamp : clock_ns(CLOCK_REALTIME);
    if (out.is_error())
      ++stats_.error_frames;
    else
      ++stats_.received;
    return true;
  }

  std::string url_;
  std::string interface_;
  int fd_ = -1;
  bool stamp_ns_ = false;
  int last_read_errno_ = 0;
  std::uint32_t dropped_seen_ = 0;
  BusStats stats_;
  alignas(cmsghdr) unsigned char control_[CMSG_SPACE(sizeof(timespec)) +
                                          CMSG_SPACE(sizeof(std::uint32_t)) + 64];
  char last_error_[256] = "";
};

}  // namespace

std::unique_ptr<Bus> open_socketcan_bus(std::string_view url, std::string_view interface) {
  return std::make_unique<SocketCan>(std::string(url), std::string(interface));
}

}  // namespace mrroc::can::detail
