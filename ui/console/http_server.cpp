#include <arpa/inet.h>
#include <fmt/format.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <poll.h>
#include <sys/eventfd.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cerrno>
#include <condition_variable>
#include <deque>
#include <functional>
#include <limits>
#include <list>
#include <mutex>
#include <string_view>
#include <system_error>
#include <thread>
#include <unordered_map>
#include <utility>
#include <vector>

// Last: <httplib.h> includes <resolv.h>, which defines `_res`, a name Eigen's headers use.
#include "console/http_server.hpp"

namespace mrroc::ui {

namespace {

using SteadyClock = std::chrono::steady_clock;
using namespace std::chrono_literals;

/// How often a waiting connection looks whether the server stops.
constexpr auto kStopCheck = 50ms;
/// After answering a request whose body it refused, the server reads and drops what the client
/// still sends for at most this long (or this many bytes) before it closes, so that the client
/// can read the answer instead of a connection reset.
constexpr auto kLingerTime = 500ms;
constexpr std::size_t kLingerBytes = 4 * 1024 * 1024;

/// poll() for `events` on `sock` for at most `timeout`; > 0 ready, 0 timeout, < 0 error.
int poll_for(int sock, short events, std::chrono::milliseconds timeout) {
  pollfd p{sock, events, 0};
  int r = 0;
  do {
    r = ::poll(&p, 1, static_cast<int>(std::max<std::int64_t>(0, timeout.count())));
  } while (r < 0 && errno == EINTR);
  if (r > 0 && (p.revents & (POLLERR | POLLNVAL)) != 0 && (p.revents & events) == 0) return -1;
  return r;
}

std::chrono::milliseconds until(SteadyClock::time_point t) {
  return std::max(0ms, std::chrono::ceil<std::chrono::milliseconds>(t - SteadyClock::now()));
}

void ip_and_port(const sockaddr_storage& addr, std::string& ip, int& port) {
  std::array<char, INET6_ADDRSTRLEN> text{};
  if (addr.ss_family == AF_INET) {
    const auto& a = reinterpret_cast<const sockaddr_in&>(addr);
    ::inet_ntop(AF_INET, &a.sin_addr, text.data(), text.size());
    port = ntohs(a.sin_port);
  } else if (addr.ss_family == AF_INET6) {
    const auto& a = reinterpret_cast<const sockaddr_in6&>(addr);
    ::inet_ntop(AF_INET6, &a.sin6_addr, text.data(), text.size());
    port = ntohs(a.sin6_port);
  }
  ip = text.data();
}

void close_socket(int sock) {
  ::shutdown(sock, SHUT_RDWR);
  ::close(sock);
}

/// The address of the peer of `sock` ("" when it cannot be had).
std::string peer_of(int sock) {
  sockaddr_storage addr{};
  socklen_t len = sizeof addr;
  std::string ip;
  int port = 0;
  if (::getpeername(sock, reinterpret_cast<sockaddr*>(&addr), &len) == 0)
    ip_and_port(addr, ip, port);
  return ip;
}

bool equal_ignoring_case(std::string_view a, std::string_view b) {
  return a.size() == b.size() && std::equal(a.begin(), a.end(), b.begin(), [](char x, char y) {
           return std::tolower(static_cast<unsigned char>(x)) ==
                  std::tolower(static_cast<unsigned char>(y));
         });
}

std::string_view trim(std::string_view text) {
  while (!text.empty() && (text.front() == ' ' || text.front() == '\t')) text.remove_prefix(1);
  while (!text.empty() && (text.back() == ' ' || text.back() == '\t')) text.remove_suffix(1);
  return text;
}

}  // namespace

std::optional<BodyRefusal> refuse_declared_body(const httplib::Request& req,
                                                std::size_t max_bytes) {
  if (req.has_header("Transfer-Encoding"))
    return BodyRefusal{411, fmt::format("a request body needs a Content-Length (at most {} bytes); "
                                        "'Transfer-Encoding: {}' is refused",
                                        max_bytes, req.get_header_value("Transfer-Encoding"))};
  if (!req.has_header("Content-Length")) return std::nullopt;
  const std::string text = req.get_header_value("Content-Length");
  const bool number =
      !text.empty() && text.size() <= 19 &&
      std::all_of(text.begin(), text.end(), [](char c) { return c >= '0' && c <= '9'; });
  if (!number)
    return BodyRefusal{400, fmt::format("Content-Length '{}' is not a number of bytes", text)};
  const std::uint64_t length = std::stoull(text);
  if (length > max_bytes)
    return BodyRefusal{413, fmt::format("request body of {} bytes is above the limit of {} bytes",
                                        length, max_bytes)};
  return std::nullopt;
}

ReservedRequest classify_reserved_request(std::string_view bytes, std::size_t max_head_bytes) {
  // Said "other" as soon as the bytes tell, so that anything but a stop is answered at once.
  constexpr std::string_view kStart = "POST /api/estop";
  if (bytes.substr(0, kStart.size()) != kStart.substr(0, std::min(bytes.size(), kStart.size())))
    return ReservedRequest::other;
  if (bytes.size() <= kStart.size()) return ReservedRequest::incomplete;
  // "/api/estop" itself, with a query or none: not "/api/estop/..." or "/api/estopx".
  if (bytes[kStart.size()] != ' ' && bytes[kStart.size()] != '?') return ReservedRequest::other;
  const std::size_t head_end = bytes.find("\r\n\r\n");
  if (head_end == std::string_view::npos)
    return bytes.size() > max_head_bytes ? ReservedRequest::other : ReservedRequest::incomplete;
  const std::size_t head_size = head_end + 4;
  if (head_size > max_head_bytes) return ReservedRequest::other;
  // The header lines, each ending in CRLF.
  const std::size_t line_end = bytes.find("\r\n");
  std::string_view headers = bytes.substr(line_end + 2, head_end + 2 - (line_end + 2));
  std::optional<std::size_t> length;
  while (!headers.empty()) {
    const std::size_t end = headers.find("\r\n");
    const std::string_view line = headers.substr(0, end);
    headers.remove_prefix(end + 2);
    const std::size_t colon = line.find(':');
    if (colon == std::string_view::npos) continue;  // cpp-httplib judges it
    const std::string_view name = line.substr(0, colon);
    const std::string_view value = trim(line.substr(colon + 1));
    // A chunked body could be of any length: not on this path.
    if (equal_ignoring_case(name, "Transfer-Encoding")) return ReservedRequest::other;
    if (equal_ignoring_case(name, "Content-Length")) {
      const bool number =
          !value.empty() && value.size() <= 5 &&
          std::all_of(value.begin(), value.end(), [](char c) { return c >= '0' && c <= '9'; });
      if (length || !number) return ReservedRequest::other;
      length = static_cast<std::size_t>(std::stoul(std::string(value)));
      if (*length > kReservedStopBodyBytes) return ReservedRequest::other;
    }
  }
  return bytes.size() >= head_size + length.value_or(0) ? ReservedRequest::stop
                                                        : ReservedRequest::incomplete;
}

struct ConsoleServer::Shared {
  ServerLimits limits;
  mutable std::mutex mutex;
  ServerCounts counts;
  /// The connections being served of each address (none: no entry).
  std::unordered_map<std::string, std::size_t> per_peer;
};

/// Threads that each run one task, at most `max` at once.
class ConsoleServer::Threads {
 public:
  explicit Threads(std::size_t max) : max_(max) {}
  ~Threads() { join(); }
  Threads(const Threads&) = delete;
  Threads& operator=(const Threads&) = delete;

  /// Runs `fn` on a thread of its own; false (and `fn` not run) when `max` threads run or no
  /// thread can be had (resource limits).
  bool try_start(std::function<void()> fn) {
    std::lock_guard lock(mutex_);
    reap_finished();
    if (workers_.size() >= max_) return false;
    Worker& w = workers_.emplace_back();
    w.task = std::move(fn);
    try {
      // The worker marks itself done under the lock, which is held until w.thread is set.
      w.thread = std::thread([this, &w] {
        w.task();
        w.task = nullptr;
        std::lock_guard done_lock(mutex_);
        w.done = true;
      });
    } catch (const std::system_error&) {
      workers_.pop_back();
      return false;
    }
    return true;
  }

  /// Waits for every thread to end.
  void join() {
    std::list<Worker> all;
    {
      std::lock_guard lock(mutex_);
      all.swap(workers_);
    }
    for (Worker& w : all)
      if (w.thread.joinable()) w.thread.join();
  }

 private:
  struct Worker {
    std::function<void()> task;
    std::thread thread;
    bool done = false;
  };

  void reap_finished() {
    for (auto it = workers_.begin(); it != workers_.end();) {
      if (it->done) {
        it->thread.join();
        it = workers_.erase(it);
      } else {
        ++it;
      }
    }
  }

  const std::size_t max_;
  std::mutex mutex_;
  std::list<Worker> workers_;
};

/// cpp-httplib's task queue. cpp-httplib's listening thread accepts a connection and enqueues a
/// task that calls process_and_close_socket; it runs at once, on the listening thread, and only
/// hands the connection on (ConsoleServer's threads and reserved path). shutdown(), when the
/// server stops listening, ends the reserved path and waits for every connection's thread.
class ConsoleServer::Listener : public httplib::TaskQueue {
 public:
  explicit Listener(ConsoleServer& server);
  void enqueue(std::function<void()> fn) override { fn(); }
  void shutdown() override;

 private:
  ConsoleServer& server_;
};

/// The reserved path: connections beyond the limits, until their first request shows whether
/// it is an emergency stop. One thread reads all of them without blocking (poll(), recv() with
/// MSG_DONTWAIT) into a buffer each, at most max_header_bytes + kReservedStopBodyBytes; a
/// connection leaves it as a whole stop (served on a thread of its own, at most stop_threads at
/// once), or as anything else, silence for first_byte_timeout, its client's close or the arrival
/// of a newer one when max_waiting wait (answered 503 and closed). Only this thread closes the
/// sockets it holds; the listening thread closes only sockets it has not yet passed on.
class ConsoleServer::Reserved {
 public:
  explicit Reserved(ConsoleServer& server)
      : server_(server), stops_(server.shared_->limits.stop_threads) {}
  ~Reserved() { stop(); }
  Reserved(const Reserved&) = delete;
  Reserved& operator=(const Reserved&) = delete;

  void start() {
    wake_ = ::eventfd(0, EFD_CLOEXEC | EFD_NONBLOCK);
    {
      std::lock_guard lock(mutex_);
      stopping_ = false;
    }
    thread_ = std::thread([this] { run(); });
  }

  /// Ends the reading thread, closes what it held, waits for the stops being served.
  void stop() {
    if (thread_.joinable()) {
      {
        std::lock_guard lock(mutex_);
        stopping_ = true;
      }
      wake();
      thread_.join();
    }
    std::deque<Entry> left;
    {
      std::lock_guard lock(mutex_);
      left.swap(incoming_);
    }
    for (Entry& e : left) drop(e);
    if (wake_ >= 0) ::close(wake_);
    wake_ = -1;
    stops_.join();
  }

  /// On the listening thread: takes `sock` (of `peer`, over its address' share or over
  /// max_connections). Only appends to a queue and wakes the reading thread; when that thread
  /// has not yet taken max_waiting of them, the oldest of these is answered 503 here.
  void hand_over(socket_t sock, std::string peer, bool over_share) {
    const ServerLimits& limits = server_.shared_->limits;
    Entry e;
    e.sock = sock;
    e.peer = std::move(peer);
    e.over_share = over_share;
    e.deadline = SteadyClock::now() + limits.first_byte_timeout;
    {
      std::lock_guard count_lock(server_.shared_->mutex);
      ++server_.shared_->counts.waiting;
    }
    std::optional<Entry> dropped;
    {
      std::lock_guard lock(mutex_);
      if (incoming_.size() >= std::max<std::size_t>(1, limits.max_waiting)) {
        dropped = std::move(incoming_.front());
        incoming_.pop_front();
      }
      incoming_.push_back(std::move(e));
    }
    if (dropped) refuse(*dropped);  // send(MSG_DONTWAIT) and close: no wait
    wake();
  }

 private:
  struct Entry {
    socket_t sock = INVALID_SOCKET;
    std::string peer;
    bool over_share = false;  // else over max_connections
    SteadyClock::time_point deadline;
    std::string bytes;
    bool stop = false;  // a whole emergency stop, waiting for a thread
    bool gone = false;  // closed or handed to a thread
  };

  void wake() const {
    const std::uint64_t one = 1;
    if (wake_ >= 0) (void)!::write(wake_, &one, sizeof one);
  }

  /// Closes `e` without an answer (the server stops).
  void drop(Entry& e) const {
    {
      std::lock_guard lock(server_.shared_->mutex);
      --server_.shared_->counts.waiting;
    }
    close_socket(e.sock);
    e.gone = true;
  }

  /// Answers `e` 503 naming the limit it is over, closes it, counts it.
  void refuse(Entry& e) const {
    Shared& s = *server_.shared_;
    {
      std::lock_guard lock(s.mutex);
      ServerCounts& c = s.counts;
      ++(e.over_share ? c.peer_refused : c.refused);
      if (e.bytes.empty() && SteadyClock::now() >= e.deadline) ++c.silent;
      --c.waiting;
    }
    const std::string limit = e.over_share
                                  ? fmt::format("at most {} connections of one address ({})",
                                                s.limits.max_connections_per_peer, e.peer)
                                  : fmt::format("at most {} connections", s.limits.max_connections);
    const std::string body = fmt::format(
        R"json({{"error": "the console serves {} at once; this one was closed (beyond that it serves only POST /api/estop)"}})json",
        limit);
    const std::string answer = fmt::format(
        "HTTP/1.1 503 Service Unavailable\r\nContent-Type: application/json\r\n"
        "Content-Length: {}\r\nConnection: close\r\n\r\n{}",
        body.size(), body);
    (void)::send(e.sock, answer.data(), answer.size(), MSG_NOSIGNAL | MSG_DONTWAIT);
    close_socket(e.sock);
    e.gone = true;
  }

  /// Serves the whole stop `e` on a thread of its own; false when none is free.
  bool dispatch(Entry& e) {
    ConsoleServer& server = server_;
    // Counted before the thread starts: it may answer the stop before this thread goes on, and
    // whoever reads the counts after the answer must find the stop in them.
    count_dispatch(false);
    // The bytes are copied: `e` keeps them when no thread is free.
    if (!stops_.try_start([&server, sock = e.sock, bytes = e.bytes]() mutable {
          server.serve_stop(sock, std::move(bytes));
        })) {
      count_dispatch(true);
      return false;
    }
    e.gone = true;
    return true;
  }

  /// Moves a stop from waiting to served on the reserved path (`back`: undoes that).
  void count_dispatch(bool back) {
    std::lock_guard lock(server_.shared_->mutex);
    ServerCounts& c = server_.shared_->counts;
    if (back) {
      ++c.waiting;
      --c.reserved_stops;
    } else {
      --c.waiting;
      ++c.reserved_stops;
    }
  }

  /// Makes room for one more: refuses the oldest entry of the address with the most entries
  /// (`newcomer` counted too, so that a flood from one address gives up its own).
  void make_room(std::vector<Entry>& entries, const std::string& newcomer) {
    std::unordered_map<std::string_view, std::size_t> tally;
    ++tally[newcomer];
    for (const Entry& e : entries) ++tally[e.peer];
    std::size_t most = 0;
    for (const auto& [peer, n] : tally) most = std::max(most, n);
    // An entry always has the most: at a most of 1 every entry has it, and the newcomer's
    // address at a most above 1 has entries.
    for (Entry& e : entries)  // oldest first
      if (tally[e.peer] == most) {
        refuse(e);
        break;
      }
    std::erase_if(entries, [](const Entry& e) { return e.gone; });
  }

  /// Reads what has come on `e`, decides when it can.
  void read(Entry& e) {
    const ServerLimits& limits = server_.shared_->limits;
    const std::size_t cap = limits.max_header_bytes + kReservedStopBodyBytes;
    std::array<char, 4096> chunk{};
    bool ended = false;  // by the client (it may still read the answer) or an error
    while (e.bytes.size() < cap) {
      const ssize_t n =
          ::recv(e.sock, chunk.data(), std::min(chunk.size(), cap - e.bytes.size()), MSG_DONTWAIT);
      if (n < 0 && errno == EINTR) continue;
      if (n < 0 && (errno == EAGAIN || errno == EWOULDBLOCK)) break;
      if (n <= 0) {
        ended = true;
        break;
      }
      e.bytes.append(chunk.data(), static_cast<std::size_t>(n));
    }
    switch (classify_reserved_request(e.bytes, limits.max_header_bytes)) {
      case ReservedRequest::incomplete:
        if (ended || e.bytes.size() >= cap) refuse(e);
        break;
      case ReservedRequest::other: refuse(e); break;
      case ReservedRequest::stop:
        e.stop = true;
        (void)dispatch(e);
        break;
    }
  }

  void run() {
    const std::size_t max_waiting = std::max<std::size_t>(1, server_.shared_->limits.max_waiting);
    std::vector<Entry> entries;  // oldest first
    std::vector<pollfd> fds;
    std::vector<Entry*> polled;
    for (;;) {
      std::deque<Entry> fresh;
      {
        std::lock_guard lock(mutex_);
        if (stopping_) break;
        fresh.swap(incoming_);
      }
      for (Entry& e : fresh) {
        if (entries.size() >= max_waiting) make_room(entries, e.peer);
        entries.push_back(std::move(e));
      }
      // Stops waiting for a thread, then deadlines.
      const auto now = SteadyClock::now();
      bool stop_waits = false;
      for (Entry& e : entries) {
        if (e.stop && !dispatch(e)) stop_waits = true;
        if (!e.gone && now >= e.deadline) refuse(e);
      }
      std::erase_if(entries, [](const Entry& e) { return e.gone; });

      fds.assign(1, pollfd{wake_, POLLIN, 0});
      polled.clear();
      auto next = SteadyClock::time_point::max();
      for (Entry& e : entries) {
        next = std::min(next, e.deadline);
        if (e.stop) continue;
        fds.push_back(pollfd{e.sock, POLLIN, 0});
        polled.push_back(&e);
      }
      int timeout = -1;
      if (next != SteadyClock::time_point::max()) timeout = static_cast<int>(until(next).count());
      // A thread may have become free for a waiting stop; without the eventfd (none could be
      // had) nothing wakes this thread for a new connection or the server's stop.
      if (stop_waits || wake_ < 0) timeout = timeout < 0 ? 50 : std::min(timeout, 50);
      int r = 0;
      do {
        r = ::poll(fds.data(), fds.size(), timeout);
      } while (r < 0 && errno == EINTR);
      if (r <= 0) continue;
      if (fds[0].revents != 0) {
        std::uint64_t count = 0;
        (void)!::read(wake_, &count, sizeof count);
      }
      for (std::size_t i = 0; i < polled.size(); ++i)
        if (fds[i + 1].revents != 0) read(*polled[i]);
      std::erase_if(entries, [](const Entry& e) { return e.gone; });
    }
    for (Entry& e : entries) drop(e);
  }

  ConsoleServer& server_;
  Threads stops_;
  int wake_ = -1;  // eventfd: a connection was handed over, or the server stops
  std::thread thread_;
  std::mutex mutex_;
  std::deque<Entry> incoming_;  // handed over, not yet taken by the reading thread
  bool stopping_ = false;
};

ConsoleServer::Listener::Listener(ConsoleServer& server) : server_(server) {
  server_.reserved_->start();
}

void ConsoleServer::Listener::shutdown() {
  server_.reserved_->stop();
  server_.workers_->join();
}

/// One request on a connection: reads through a buffer until the request's deadline or byte
/// budget runs out (then it fails, which ends the connection), each read waiting at most the
/// server's read timeout; writes wait at most its write timeout. Both stop when the server
/// stops. `preread`: bytes of the connection already read (the reserved path's), read first.
class ConsoleServer::RequestStream : public httplib::Stream {
 public:
  RequestStream(const ConsoleServer& server, socket_t sock, std::size_t budget,
                std::string preread = {})
      : server_(server),
        sock_(sock),
        deadline_(SteadyClock::now() + server.shared_->limits.request_deadline),
        budget_(budget),
        preread_(std::move(preread)) {}

  bool is_readable() const override {
    return preread_off_ < preread_.size() || off_ < size_ ||
           server_.wait_readable(sock_, read_until());
  }

  bool is_writable() const override {
    const auto end = SteadyClock::now() + write_timeout();
    for (;;) {
      if (server_.svr_sock_ == INVALID_SOCKET) return false;
      const int r =
          poll_for(sock_, POLLOUT, std::min<std::chrono::milliseconds>(kStopCheck, until(end)));
      if (r != 0) return r > 0;
      if (SteadyClock::now() >= end) return false;
    }
  }

  ssize_t read(char* ptr, size_t size) override {
    if (consumed_ >= budget_) {
      too_large_ = true;
      return -1;
    }
    size = std::min(size, budget_ - consumed_);
    if (preread_off_ < preread_.size()) {
      const std::size_t n = std::min(size, preread_.size() - preread_off_);
      std::copy_n(preread_.data() + preread_off_, n, ptr);
      preread_off_ += n;
      consumed_ += n;
      return static_cast<ssize_t>(n);
    }
    if (off_ >= size_) {
      const auto limit = read_until();
      if (!server_.wait_readable(sock_, limit)) {
        if (SteadyClock::now() >= deadline_) late_ = true;
        return -1;
      }
      ssize_t n = 0;
      do {
        n = ::recv(sock_, buffer_.data(), buffer_.size(), 0);
      } while (n < 0 && errno == EINTR);
      if (n <= 0) return n;
      off_ = 0;
      size_ = static_cast<std::size_t>(n);
    }
    const std::size_t n = std::min(size, size_ - off_);
    std::copy_n(buffer_.data() + off_, n, ptr);
    off_ += n;
    consumed_ += n;
    return static_cast<ssize_t>(n);
  }

  ssize_t write(const char* ptr, size_t size) override {
    if (!is_writable()) return -1;
    ssize_t n = 0;
    do {
      n = ::send(sock_, ptr, size, MSG_NOSIGNAL);
    } while (n < 0 && errno == EINTR);
    return n;
  }

  void get_remote_ip_and_port(std::string& ip, int& port) const override {
    sockaddr_storage addr{};
    socklen_t len = sizeof addr;
    if (::getpeername(sock_, reinterpret_cast<sockaddr*>(&addr), &len) == 0)
      ip_and_port(addr, ip, port);
  }

  void get_local_ip_and_port(std::string& ip, int& port) const override {
    sockaddr_storage addr{};
    socklen_t len = sizeof addr;
    if (::getsockname(sock_, reinterpret_cast<sockaddr*>(&addr), &len) == 0)
      ip_and_port(addr, ip, port);
  }

  socket_t socket() const override { return sock_; }

  [[nodiscard]] bool late() const { return late_; }
  [[nodiscard]] bool too_large() const { return too_large_; }

 private:
  /// The end of the next read's wait: the read timeout, but never beyond the deadline.
  SteadyClock::time_point read_until() const {
    const auto timeout = std::chrono::seconds(server_.read_timeout_sec_) +
                         std::chrono::microseconds(server_.read_timeout_usec_);
    return std::min(
        deadline_, SteadyClock::now() + std::chrono::duration_cast<SteadyClock::duration>(timeout));
  }
  std::chrono::milliseconds write_timeout() const {
    return std::chrono::duration_cast<std::chrono::milliseconds>(
        std::chrono::seconds(server_.write_timeout_sec_) +
        std::chrono::microseconds(server_.write_timeout_usec_));
  }

  const ConsoleServer& server_;
  const socket_t sock_;
  const SteadyClock::time_point deadline_;
  const std::size_t budget_;
  const std::string preread_;
  std::size_t preread_off_ = 0;
  std::size_t consumed_ = 0;
  std::array<char, 4096> buffer_{};
  std::size_t off_ = 0;
  std::size_t size_ = 0;
  bool late_ = false;
  bool too_large_ = false;
};

ConsoleServer::ConsoleServer(ServerLimits limits)
    : shared_(std::make_shared<Shared>()),
      // The connections served are bounded by their count (process_and_close_socket); a thread
      // that has ended its connection may not yet have been reaped.
      workers_(std::make_unique<Threads>(std::numeric_limits<std::size_t>::max())) {
  shared_->limits = limits;
  reserved_ = std::make_unique<Reserved>(*this);
  new_task_queue = [this] { return new Listener(*this); };
}

ConsoleServer::~ConsoleServer() = default;

bool ConsoleServer::bind_to_port(const std::string& host, int port, int socket_flags) {
  // listen() again on a listening socket sets its backlog (Linux).
  return httplib::Server::bind_to_port(host, port, socket_flags) &&
         ::listen(svr_sock_, SOMAXCONN) == 0;
}

int ConsoleServer::bind_to_any_port(const std::string& host, int socket_flags) {
  const int port = httplib::Server::bind_to_any_port(host, socket_flags);
  return port > 0 && ::listen(svr_sock_, SOMAXCONN) == 0 ? port : -1;
}

const ServerLimits& ConsoleServer::limits() const { return shared_->limits; }

ServerCounts ConsoleServer::counts() const {
  std::lock_guard lock(shared_->mutex);
  return shared_->counts;
}

bool ConsoleServer::wait_readable(socket_t sock, SteadyClock::time_point end) const {
  for (;;) {
    if (svr_sock_ == INVALID_SOCKET) return false;  // the server stops
    const int r =
        poll_for(sock, POLLIN, std::min<std::chrono::milliseconds>(kStopCheck, until(end)));
    if (r != 0) return r > 0;
    if (SteadyClock::now() >= end) return false;
  }
}

bool ConsoleServer::process_and_close_socket(socket_t sock) {
  // On the listening thread: nothing here waits on the client.
  Shared& s = *shared_;
  std::string peer = peer_of(sock);
  bool over_share = false;
  bool admitted = false;
  {
    std::lock_guard lock(s.mutex);
    const auto it = s.per_peer.find(peer);
    over_share = it != s.per_peer.end() && it->second >= s.limits.max_connections_per_peer;
    admitted = !over_share && s.counts.open < s.limits.max_connections;
    if (admitted) {
      ++s.per_peer[peer];
      ++s.counts.served;
      s.counts.most_open = std::max(s.counts.most_open, ++s.counts.open);
    }
  }
  if (admitted) {
    if (workers_->try_start([this, sock, peer] { serve(sock, peer); })) return true;
    // No thread to be had (resource limits): as over max_connections.
    std::lock_guard lock(s.mutex);
    if (--s.per_peer[peer] == 0) s.per_peer.erase(peer);
    --s.counts.served;
    --s.counts.open;
  }
  reserved_->hand_over(sock, std::move(peer), over_share);
  return false;
}

void ConsoleServer::serve(socket_t sock, const std::string& peer) {
  Shared& s = *shared_;
  // An answer goes out in several writes (headers, body): with Nagle's algorithm the second
  // waits for the client's delayed ACK of the first, 40 ms on Linux, for every request after the
  // first of a kept-alive connection (the 3D view's 50 polls per second met it every time).
  const int nodelay = 1;
  (void)::setsockopt(sock, IPPROTO_TCP, TCP_NODELAY, &nodelay, sizeof nodelay);
  bool body_refused = false;
  const auto keep_alive = std::chrono::seconds(keep_alive_timeout_sec_);
  for (std::size_t count = keep_alive_max_count_; count > 0; --count) {
    // The first request within first_byte_timeout, each further one within the keep-alive
    // timeout.
    const bool first = count == keep_alive_max_count_;
    const auto end =
        SteadyClock::now() +
        (first ? std::chrono::duration_cast<SteadyClock::duration>(s.limits.first_byte_timeout)
               : keep_alive);
    if (!wait_readable(sock, end)) {  // idle, closed, stopping
      if (first && svr_sock_ != INVALID_SOCKET && SteadyClock::now() >= end) {
        std::lock_guard lock(s.mutex);
        ++s.counts.silent;
      }
      break;
    }
    RequestStream stream(*this, sock, payload_max_length_ + s.limits.max_header_bytes);
    bool connection_closed = false;
    const bool ret =
        process_request(stream, count == 1, connection_closed, [&](httplib::Request& req) {
          // Its body is not read (HttpApi answers 4xx first): what follows on the connection is
          // not the next request.
          body_refused = refuse_declared_body(req, payload_max_length_).has_value();
        });
    if (stream.late() || stream.too_large()) {
      std::lock_guard lock(s.mutex);
      ++(stream.late() ? s.counts.late : s.counts.too_large);
      break;
    }
    if (!ret || connection_closed || body_refused) break;
  }
  if (body_refused) {
    ::shutdown(sock, SHUT_WR);
    std::array<char, 4096> drop{};
    std::size_t dropped = 0;
    const auto end = SteadyClock::now() + kLingerTime;
    while (dropped < kLingerBytes && wait_readable(sock, end)) {
      const ssize_t n = ::recv(sock, drop.data(), drop.size(), 0);
      if (n <= 0) break;
      dropped += static_cast<std::size_t>(n);
    }
  }
  {
    // Counted closed before it is: a client that saw its connection end (and reconnects, or
    // reads the counts) finds its place free.
    std::lock_guard lock(s.mutex);
    --s.counts.open;
    if (--s.per_peer[peer] == 0) s.per_peer.erase(peer);
  }
  close_socket(sock);
}

void ConsoleServer::serve_stop(socket_t sock, std::string bytes) {
  const int nodelay = 1;
  (void)::setsockopt(sock, IPPROTO_TCP, TCP_NODELAY, &nodelay, sizeof nodelay);
  // The whole request is in `bytes` (classify_reserved_request): nothing waits on the client but
  // the answer's write, a few hundred bytes into an empty send buffer. The same checks and
  // handler as on any connection (Host, token, X-Mrroc-Request); then the connection ends.
  RequestStream stream(*this, sock, payload_max_length_ + shared_->limits.max_header_bytes,
                       std::move(bytes));
  bool connection_closed = false;
  (void)process_request(stream, true, connection_closed, [](httplib::Request&) {});
  close_socket(sock);
}

}  // namespace mrroc::ui
