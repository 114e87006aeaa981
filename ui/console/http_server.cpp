#include <arpa/inet.h>
#include <fmt/format.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cerrno>
#include <condition_variable>
#include <functional>
#include <list>
#include <mutex>
#include <system_error>
#include <thread>
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

/// Set on the listening thread while it runs a connection it refuses (over max_connections).
thread_local bool refusing_connection = false;

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

struct ConsoleServer::Shared {
  ServerLimits limits;
  mutable std::mutex mutex;
  ServerCounts counts;
};

namespace {

/// cpp-httplib's task queue: a thread of its own for every connection, at most
/// `max_connections`; a connection beyond them runs at once on the listening thread, which
/// answers it 503 and closes it (refusing_connection).
class ConnectionThreads : public httplib::TaskQueue {
 public:
  explicit ConnectionThreads(std::size_t max_threads) : max_threads_(max_threads) {}
  ~ConnectionThreads() override { shutdown(); }
  ConnectionThreads(const ConnectionThreads&) = delete;
  ConnectionThreads& operator=(const ConnectionThreads&) = delete;

  void enqueue(std::function<void()> fn) override {
    {
      std::lock_guard lock(mutex_);
      reap_finished();
      if (workers_.size() < max_threads_) {
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
          return;
        } catch (const std::system_error&) {
          // No thread to be had (resource limits): refused like a connection above the limit.
          fn = std::move(w.task);
          workers_.pop_back();
        }
      }
    }
    refusing_connection = true;
    fn();
    refusing_connection = false;
  }

  void shutdown() override {
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
    std::function<void()> task;  // serves the connection and closes its socket
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

  const std::size_t max_threads_;
  std::mutex mutex_;
  std::list<Worker> workers_;
};

}  // namespace

/// One request on a connection: reads through a buffer until the request's deadline or byte
/// budget runs out (then it fails, which ends the connection), each read waiting at most the
/// server's read timeout; writes wait at most its write timeout. Both stop when the server
/// stops.
class ConsoleServer::RequestStream : public httplib::Stream {
 public:
  RequestStream(const ConsoleServer& server, socket_t sock, std::size_t budget)
      : server_(server),
        sock_(sock),
        deadline_(SteadyClock::now() + server.shared_->limits.request_deadline),
        budget_(budget) {}

  bool is_readable() const override {
    return off_ < size_ || server_.wait_readable(sock_, read_until());
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
  std::size_t consumed_ = 0;
  std::array<char, 4096> buffer_{};
  std::size_t off_ = 0;
  std::size_t size_ = 0;
  bool late_ = false;
  bool too_large_ = false;
};

ConsoleServer::ConsoleServer(ServerLimits limits) : shared_(std::make_shared<Shared>()) {
  shared_->limits = limits;
  new_task_queue = [max = limits.max_connections] { return new ConnectionThreads(max); };
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
  Shared& s = *shared_;
  if (refusing_connection) {
    {
      std::lock_guard lock(s.mutex);
      ++s.counts.refused;
    }
    const std::string body = fmt::format(
        R"({{"error": "the console serves at most {} connections at once; this one was closed"}})",
        s.limits.max_connections);
    const std::string answer = fmt::format(
        "HTTP/1.1 503 Service Unavailable\r\nContent-Type: application/json\r\n"
        "Content-Length: {}\r\nConnection: close\r\n\r\n{}",
        body.size(), body);
    (void)::send(sock, answer.data(), answer.size(), MSG_NOSIGNAL | MSG_DONTWAIT);
    close_socket(sock);
    return false;
  }
  {
    std::lock_guard lock(s.mutex);
    ++s.counts.served;
    s.counts.most_open = std::max(s.counts.most_open, ++s.counts.open);
  }
  // An answer goes out in several writes (headers, body): with Nagle's algorithm the second
  // waits for the client's delayed ACK of the first, 40 ms on Linux, for every request after the
  // first of a kept-alive connection (the 3D view's 50 polls per second met it every time).
  const int nodelay = 1;
  (void)::setsockopt(sock, IPPROTO_TCP, TCP_NODELAY, &nodelay, sizeof nodelay);
  bool ret = false;
  bool body_refused = false;
  const auto keep_alive = std::chrono::seconds(keep_alive_timeout_sec_);
  for (std::size_t count = keep_alive_max_count_; count > 0; --count) {
    if (!wait_readable(sock, SteadyClock::now() + keep_alive)) break;  // idle, closed, stopping
    RequestStream stream(*this, sock, payload_max_length_ + s.limits.max_header_bytes);
    bool connection_closed = false;
    ret = process_request(stream, count == 1, connection_closed, [&](httplib::Request& req) {
      // Its body is not read (HttpApi answers 4xx first): what follows on the connection is not
      // the next request.
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
  close_socket(sock);
  {
    std::lock_guard lock(s.mutex);
    --s.counts.open;
  }
  return ret;
}

}  // namespace mrroc::ui
