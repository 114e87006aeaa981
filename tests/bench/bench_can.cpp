// B6: round trip of one classical 8-byte CAN frame between two processes over the virtual CAN bus
// (mrroc::can::open_bus("virtual:...")) against the same ping-pong over UDP loopback sockets.
//
// Value: this program (the "EDP" side) and a child process (the "axis emulator" side, forked
// before anything else runs) are two nodes of one virtual bus. The parent sends a request frame
// (id 0x601, 8 bytes: a sequence number) and waits in Bus::receive for the reply; the child
// waits in Bus::receive, and answers each request with id 0x581 and the same 8 bytes, as a
// CANopen SDO server would. Timed: from before send to the matching reply returned by receive.
//
// Baseline: the same exchange of the same 16 bytes (a struct can_frame) as UDP datagrams between
// two sockets on 127.0.0.1, both sides blocking in recv, the echo also a forked child.
//
// Same run, same pacing, nothing pinned, default scheduling for both, both echo processes alive
// throughout: the two transports take turns every 0.5 ms (clock_nanosleep to absolute
// deadlines), so that each one sends a request every 1 ms (a servo-like cycle) and the load of
// the shared host hits both alike. An unpaced series (requests back to back, alternating blocks
// of 1000 per transport) is reported in the note.
//
// Usage (inside scripts/netns-run: a private network namespace and /dev/shm):
//   bench_can [samples]   (default 8000 per transport)
// Prints "RESULT B6 ..." and "NOTE B6 ...".
#include <arpa/inet.h>
#include <netinet/in.h>
#include <signal.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cerrno>
#include <chrono>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <memory>
#include <string>
#include <vector>

#include "bench_args.hpp"
#include "mrroc/can/bus.hpp"
#include "mrroc/core/error.hpp"

namespace {

using namespace std::chrono_literals;

constexpr canid_t kRequestId = 0x601;
constexpr canid_t kReplyId = 0x581;
constexpr canid_t kStopId = 0x000;           // NMT: the echo stops
constexpr std::int64_t kPeriodNs = 500'000;  // 2 kHz: each transport at 1 kHz

std::int64_t now_ns() {
  timespec t{};
  clock_gettime(CLOCK_MONOTONIC, &t);
  return static_cast<std::int64_t>(t.tv_sec) * 1'000'000'000LL + t.tv_nsec;
}

double percentile(std::vector<double> v, double p) {
  if (v.empty()) return 0.0;
  std::sort(v.begin(), v.end());
  return v[static_cast<std::size_t>(p * static_cast<double>(v.size() - 1))];
}

/// Deadlines every kPeriodNs.
class Pacer {
 public:
  Pacer() : next_(now_ns() + kPeriodNs) {}
  void wait() {
    timespec wake{};
    wake.tv_sec = static_cast<time_t>(next_ / 1'000'000'000LL);
    wake.tv_nsec = static_cast<long>(next_ % 1'000'000'000LL);
    while (clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &wake, nullptr) == EINTR) {
    }
    next_ += kPeriodNs;
    const std::int64_t now = now_ns();
    if (next_ < now) next_ = now + kPeriodNs;  // fell behind: do not burst
  }

 private:
  std::int64_t next_;
};

can_frame make_frame(canid_t id, std::uint64_t payload) {
  can_frame f{};
  f.can_id = id;
  f.len = 8;
  std::memcpy(f.data, &payload, sizeof payload);
  return f;
}

std::uint64_t payload_of(const can_frame& f) {
  std::uint64_t v = 0;
  std::memcpy(&v, f.data, sizeof v);
  return v;
}

struct Series {
  std::vector<double> us;
  int lost = 0;
};

/// One round trip transport: the parent's side.
class Pinger {
 public:
  virtual ~Pinger() = default;
  Pinger() = default;
  Pinger(const Pinger&) = delete;
  Pinger& operator=(const Pinger&) = delete;
  /// One request and its reply; false when none came within 1 s.
  virtual bool ping(std::uint64_t seq) = 0;
  virtual void stop() = 0;
};

// ---- Virtual CAN bus ----

int run_can_echo(const std::string& url) {
  auto bus = mrroc::can::open_bus(url);
  const std::array<can_filter, 2> filters{{{kRequestId, CAN_SFF_MASK}, {kStopId, CAN_SFF_MASK}}};
  bus->set_filters(filters);
  if (bus->send(make_frame(kReplyId, ~0ULL)) != mrroc::can::SendResult::sent) return 3;  // ready
  mrroc::can::Received r;
  for (;;) {
    if (!bus->receive(r, 10s)) return 2;
    if (r.frame.can_id == kStopId) return 0;
    can_frame reply = r.frame;
    reply.can_id = kReplyId;
    if (bus->send(reply) != mrroc::can::SendResult::sent) return 4;
  }
}

class CanPinger final : public Pinger {
 public:
  explicit CanPinger(const std::string& url) : bus_(mrroc::can::open_bus(url)) {
    const std::array<can_filter, 1> replies{{{kReplyId, CAN_SFF_MASK}}};
    bus_->set_filters(replies);
  }
  void wait_ready() {
    mrroc::can::Received r;
    if (!bus_->receive(r, 10s)) throw mrroc::Error("the virtual-bus echo never said ready");
  }
  bool ping(std::uint64_t seq) override {
    if (bus_->send(make_frame(kRequestId, seq)) != mrroc::can::SendResult::sent) return false;
    const std::int64_t until = now_ns() + 1'000'000'000LL;
    mrroc::can::Received r;
    for (;;) {
      const std::int64_t left = until - now_ns();
      if (left <= 0 || !bus_->receive(r, std::chrono::nanoseconds(left))) return false;
      if (payload_of(r.frame) == seq) return true;
    }
  }
  void stop() override { (void)bus_->send(make_frame(kStopId, 0)); }
  [[nodiscard]] mrroc::can::BusStats stats() const { return bus_->stats(); }

 private:
  std::unique_ptr<mrroc::can::Bus> bus_;
};

// ---- UDP loopback ----

int udp_socket(sockaddr_in& bound) {
  const int fd = ::socket(AF_INET, SOCK_DGRAM | SOCK_CLOEXEC, 0);
  if (fd < 0) throw mrroc::Error(std::string("UDP socket: ") + std::strerror(errno));
  bound = {};
  bound.sin_family = AF_INET;
  bound.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  bound.sin_port = 0;
  if (::bind(fd, reinterpret_cast<const sockaddr*>(&bound), sizeof bound) != 0)
    throw mrroc::Error(std::string("UDP bind to 127.0.0.1: ") + std::strerror(errno));
  socklen_t size = sizeof bound;
  getsockname(fd, reinterpret_cast<sockaddr*>(&bound), &size);
  return fd;
}

void connect_to(int fd, const sockaddr_in& peer) {
  if (::connect(fd, reinterpret_cast<const sockaddr*>(&peer), sizeof peer) != 0)
    throw mrroc::Error(std::string("UDP connect: ") + std::strerror(errno));
}

int run_udp_echo(int fd) {
  can_frame f{};
  for (;;) {
    const ssize_t n = ::recv(fd, &f, sizeof f, 0);
    if (n != static_cast<ssize_t>(sizeof f)) return 2;
    if (f.can_id == kStopId) return 0;
    f.can_id = kReplyId;
    if (::send(fd, &f, sizeof f, 0) != static_cast<ssize_t>(sizeof f)) return 4;
  }
}

class UdpPinger final : public Pinger {
 public:
  explicit UdpPinger(int fd) : fd_(fd) {
    timeval t{1, 0};
    setsockopt(fd_, SOL_SOCKET, SO_RCVTIMEO, &t, sizeof t);
  }
  ~UdpPinger() override { ::close(fd_); }
  bool ping(std::uint64_t seq) override {
    const can_frame f = make_frame(kRequestId, seq);
    if (::send(fd_, &f, sizeof f, 0) != static_cast<ssize_t>(sizeof f)) return false;
    can_frame reply{};
    for (;;) {
      if (::recv(fd_, &reply, sizeof reply, 0) != static_cast<ssize_t>(sizeof reply)) return false;
      if (payload_of(reply) == seq) return true;
    }
  }
  void stop() override {
    const can_frame f = make_frame(kStopId, 0);
    (void)::send(fd_, &f, sizeof f, 0);
  }

 private:
  int fd_;
};

// ---- Series ----

void sample(Pinger& p, std::uint64_t& seq, Series& out) {
  const std::int64_t t0 = now_ns();
  if (!p.ping(++seq)) {
    ++out.lost;
    return;
  }
  out.us.push_back(static_cast<double>(now_ns() - t0) / 1000.0);
}

int wait_child(pid_t pid) {
  int status = 0;
  if (waitpid(pid, &status, 0) != pid) return -1000;
  return WIFEXITED(status) ? WEXITSTATUS(status) : -WTERMSIG(status);
}

struct Figures {
  Series udp_paced;
  Series udp_unpaced;
  Series can_paced;
  Series can_unpaced;
  mrroc::can::BusStats stats;
};

Figures run(const std::string& url, int paced, int unpaced) {
  // UDP: two connected sockets on 127.0.0.1; the echo's end goes to the child.
  sockaddr_in a{};
  sockaddr_in b{};
  const int mine = udp_socket(a);
  const int theirs = udp_socket(b);
  connect_to(mine, b);
  connect_to(theirs, a);
  std::fflush(stdout);
  const pid_t udp_echo = fork();
  if (udp_echo < 0) throw mrroc::Error("fork failed");
  if (udp_echo == 0) {
    ::close(mine);
    _exit(run_udp_echo(theirs));
  }
  ::close(theirs);
  UdpPinger udp(mine);

  CanPinger can(url);  // opened before the fork: the echo's ready frame cannot be missed
  std::fflush(stdout);
  const pid_t can_echo = fork();
  if (can_echo < 0) throw mrroc::Error("fork failed");
  if (can_echo == 0) {
    int rc = 5;
    try {
      rc = run_can_echo(url);
    } catch (...) {
    }
    _exit(rc);
  }
  can.wait_ready();

  Figures f;
  std::uint64_t udp_seq = 0;
  std::uint64_t can_seq = 0;
  Series warm_up;
  for (int i = 0; i < 200; ++i) {
    sample(udp, udp_seq, warm_up);
    sample(can, can_seq, warm_up);
  }
  Pacer pacer;
  for (int i = 0; i < 2 * paced; ++i) {
    pacer.wait();
    // Which transport goes first in a pair flips every 1000 pairs.
    if ((i % 2 == 0) == ((i / 2000) % 2 == 0))
      sample(udp, udp_seq, f.udp_paced);
    else
      sample(can, can_seq, f.can_paced);
  }
  constexpr int kBlock = 1000;
  for (int done = 0; done < unpaced; done += kBlock) {
    for (int i = 0; i < kBlock; ++i) sample(udp, udp_seq, f.udp_unpaced);
    for (int i = 0; i < kBlock; ++i) sample(can, can_seq, f.can_unpaced);
  }
  udp.stop();
  can.stop();
  f.stats = can.stats();
  if (const int rc = wait_child(udp_echo); rc != 0)
    throw mrroc::Error("the UDP echo failed (exit code " + std::to_string(rc) + ")");
  if (const int rc = wait_child(can_echo); rc != 0)
    throw mrroc::Error("the virtual-bus echo failed (exit code " + std::to_string(rc) + ")");
  return f;
}

}  // namespace

int main(int argc, char** argv) {
  if (mrroc::bench::help_requested(
          argc, argv,
          "Usage (inside scripts/netns-run): bench_can [SAMPLES]\n"
          "B6: CAN frame round trip over the virtual bus against UDP loopback, SAMPLES (default\n"
          "8000, at least 100) paced round trips per transport, then 20000 unpaced.\n"
          "Prints RESULT B6 and NOTE lines.\n"))
    return 0;
  const int samples = argc > 1 ? static_cast<int>(mrroc::bench::whole_number(
                                     "bench_can", "SAMPLES", argv[1], 100, 10000000, "round trips"))
                               : 8000;
  const int unpaced = 20000;
  try {
    const std::string url = "virtual:bench-b6-" + std::to_string(getpid());
    const Figures f = run(url, samples, unpaced);
    const Series& udp_paced = f.udp_paced;
    const Series& udp_unpaced = f.udp_unpaced;
    const Series& can_paced = f.can_paced;
    const Series& can_unpaced = f.can_unpaced;
    const mrroc::can::BusStats& stats = f.stats;

    const double b50 = percentile(udp_paced.us, 0.5);
    const double b99 = percentile(udp_paced.us, 0.99);
    const double v50 = percentile(can_paced.us, 0.5);
    const double v99 = percentile(can_paced.us, 0.99);
    const double ub50 = percentile(udp_unpaced.us, 0.5);
    const double ub99 = percentile(udp_unpaced.us, 0.99);
    const double uv50 = percentile(can_unpaced.us, 0.5);
    const double uv99 = percentile(can_unpaced.us, 0.99);
    std::printf(
        "B6 round trip of one 8-byte CAN frame between two processes, %d samples each, "
        "each transport paced at 1 kHz, taking turns\n",
        samples);
    std::printf("  UDP loopback:    p50 %.1f us, p99 %.1f us (%d lost)\n", b50, b99,
                udp_paced.lost);
    std::printf("  virtual CAN bus: p50 %.1f us, p99 %.1f us (%d lost)\n", v50, v99,
                can_paced.lost);
    std::printf(
        "  unpaced, %d samples each: UDP p50 %.1f us, p99 %.1f us; virtual CAN p50 %.1f "
        "us, p99 %.1f us (%d lost)\n",
        unpaced, ub50, ub99, uv50, uv99, can_unpaced.lost);
    std::printf("  parent node: %llu sent, %llu received, %llu overruns\n",
                static_cast<unsigned long long>(stats.sent),
                static_cast<unsigned long long>(stats.received),
                static_cast<unsigned long long>(stats.overruns));
    std::printf(
        "NOTE B6 request 0x601 -> reply 0x581 (8 data bytes) between this process and a "
        "forked echo, each blocking in Bus::receive (futex in the shared ring) against the "
        "same 16-byte can_frame as UDP datagrams on 127.0.0.1 (blocking recv), %d samples "
        "each, each transport paced at 1 kHz, the two taking turns every 0.5 ms; nothing "
        "pinned, SCHED_OTHER. Unpaced (back to back, %d each): UDP p50 %.1f / p99 %.1f us, "
        "virtual CAN p50 %.1f / p99 %.1f us (ratio %.2f / %.2f). Lost: UDP %d, virtual "
        "CAN %d. Raw frames only: no CANopen SDO or CiA 402 processing on either side.\n",
        samples, unpaced, ub50, ub99, uv50, uv99, uv50 / ub50, uv99 / ub99,
        udp_paced.lost + udp_unpaced.lost, can_paced.lost + can_unpaced.lost);
    std::printf(
        "RESULT B6 baseline_p50=%.2f baseline_p99=%.2f value_p50=%.2f value_p99=%.2f "
        "samples=%d unit=us\n",
        b50, b99, v50, v99, samples);
    return 0;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "bench_can: %s\n", e.what());
    return 1;
  }
}
