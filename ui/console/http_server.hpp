#pragma once
// The console's HTTP server: cpp-httplib's Server with connection handling of its own, so that
// hostile clients can neither starve the emergency stop nor fill the console's memory
// (docs/operating.md, "Limits"):
// - every connection is served on a thread of its own, at most ServerLimits::max_connections at
//   once and at most max_connections_per_peer of one address (cpp-httplib's pool of a fixed
//   number of threads lets that many slow clients make every other request wait);
// - a new connection must send its first byte within first_byte_timeout (an idle kept-alive one
//   its next request within the keep-alive timeout), or it is closed;
// - a connection beyond either limit goes to the reserved path: one thread reads the first
//   request of every such connection at once, without blocking (poll(), at most max_waiting
//   connections, each for at most first_byte_timeout); an emergency stop (POST /api/estop, not
//   the release) is then served on a thread of its own (at most stop_threads at once) through
//   the same checks and handler as any request, everything else is answered 503 and closed.
//   When max_waiting connections wait there, a new one takes the place of the oldest of the
//   address that has the most of them. A stop's connection, which sends its request at once, is
//   thus given up only when max_waiting newer connections of its own address arrive before its
//   request does (a fraction of a millisecond on a network), or newer ones from about as many
//   addresses as max_waiting; connections from fewer addresses never take its place;
// - the listening thread never waits on a client: it only looks up the peer's address, counts
//   and hands the socket on;
// - a request's line, headers and body must arrive within ServerLimits::request_deadline of its
//   first byte and hold at most payload_max_length + ServerLimits::max_header_bytes bytes, or the
//   connection is closed (cpp-httplib alone bounds only the time of each single read, and reads a
//   request line or a chunked body of any length into memory);
// - a request whose body is refused unread (refuse_declared_body) ends its connection after the
//   answer;
// - stop() ends every connection within about 50 ms, however slowly its client sends;
// - the listen backlog is SOMAXCONN, not 5 (bind_to_port).
//
// Include it after every other header: <httplib.h> includes <resolv.h>, which defines `_res`, a
// name Eigen's headers use.

#include <atomic>
#include <chrono>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <string_view>

#include <httplib.h>

namespace mrroc::ui {

struct ServerLimits {
  /// Connections served at once; a connection beyond them goes to the reserved path (only an
  /// emergency stop is served there, anything else is answered 503 and closed).
  std::size_t max_connections = 128;
  /// Connections served at once from one address (the peer's IP); beyond them as beyond
  /// max_connections, so that one client cannot take every place. Every client of a console
  /// bound to a loopback address (the default), through an SSH tunnel or a reverse proxy too,
  /// comes from 127.0.0.1: then this is the limit for all of them together (a browser opens at
  /// most 6 connections to one server).
  std::size_t max_connections_per_peer = 32;
  /// A new connection that sends no byte within this time is closed (counted as silent); the
  /// time between the requests of a kept-alive connection is the keep-alive timeout. On the
  /// reserved path the whole first request must arrive within this time.
  std::chrono::milliseconds first_byte_timeout{2000};
  /// Connections on the reserved path at once; for a further one, the oldest of the address
  /// that has the most of them there is answered 503 and closed.
  std::size_t max_waiting = 64;
  /// Emergency stops served at once on the reserved path, each on a thread of its own; a stop
  /// beyond them waits on the reserved path.
  std::size_t stop_threads = 4;
  /// A request must arrive whole (line, headers, body) within this time of its first byte [ms].
  std::chrono::milliseconds request_deadline{3000};
  /// Bytes a request's line and headers may take besides the body (payload_max_length).
  std::size_t max_header_bytes = 32 * 1024;
};

/// What the server has done so far (for tests and measurements).
struct ServerCounts {
  std::size_t open = 0;       ///< connections being served now (not those on the reserved path)
  std::size_t most_open = 0;  ///< the most served at once
  std::size_t waiting = 0;    ///< connections on the reserved path now
  std::uint64_t served = 0;   ///< connections accepted and served (ended or not)
  std::uint64_t refused = 0;  ///< connections over max_connections not served (answered 503)
  std::uint64_t peer_refused = 0;  ///< connections over max_connections_per_peer not served (503)
  /// Connections closed because no byte came within first_byte_timeout (served ones and ones
  /// on the reserved path, which are also counted as refused or peer_refused).
  std::uint64_t silent = 0;
  std::uint64_t reserved_stops = 0;  ///< emergency stops served on the reserved path
  std::uint64_t late = 0;            ///< connections closed because a request missed its deadline
  std::uint64_t too_large = 0;       ///< connections closed because a request exceeded its bytes
};

/// The largest body of an emergency stop served on the reserved path [bytes] (the page sends
/// {"reason": ...}, a few dozen bytes).
inline constexpr std::size_t kReservedStopBodyBytes = 4 * 1024;

/// What the reserved path makes of the first bytes of a connection: a whole emergency stop
/// (`POST /api/estop` or `POST /api/estop?...`, its headers at most `max_head_bytes` with the
/// request line, without Transfer-Encoding, a Content-Length of at most kReservedStopBodyBytes
/// and all of its body), not yet, or something else (as soon as the bytes tell).
enum class ReservedRequest { incomplete, stop, other };
[[nodiscard]] ReservedRequest classify_reserved_request(std::string_view bytes,
                                                        std::size_t max_head_bytes);

/// Why a request's body is refused before any of it is read: {HTTP status, text naming the value
/// and the limit}; none when its body may be read. A chunked body (no Content-Length) is refused
/// with 411, a Content-Length above `max_bytes` with 413, one that is not a number with 400.
struct BodyRefusal {
  int status = 0;
  std::string text;
};
[[nodiscard]] std::optional<BodyRefusal> refuse_declared_body(const httplib::Request& req,
                                                              std::size_t max_bytes);

class ConsoleServer : public httplib::Server {
 public:
  explicit ConsoleServer(ServerLimits limits = {});
  ~ConsoleServer() override;
  ConsoleServer(const ConsoleServer&) = delete;
  ConsoleServer& operator=(const ConsoleServer&) = delete;

  /// As httplib::Server's, with a listen backlog of SOMAXCONN instead of cpp-httplib's 5: with 5,
  /// a burst of connections (a browser's, or a client's opening many) fills the queue before the
  /// listening thread takes them, and a further connection, the emergency stop's too, waits for
  /// its SYN to be sent again (1 s, then 3 s). They hide the base class' functions.
  bool bind_to_port(const std::string& host, int port, int socket_flags = 0);
  int bind_to_any_port(const std::string& host, int socket_flags = 0);

  [[nodiscard]] const ServerLimits& limits() const;
  [[nodiscard]] ServerCounts counts() const;

  struct Shared;  // the limits and counters, shared with the connection threads

 private:
  /// Runs on the listening thread for every accepted connection: serves it on a thread of its
  /// own within the limits, else hands it to the reserved path. Never waits on the client.
  bool process_and_close_socket(socket_t sock) override;
  /// A connection within the limits, on its own thread, until it ends; then closes it.
  void serve(socket_t sock, const std::string& peer);
  /// An emergency stop read on the reserved path (`bytes`, the whole request): one request,
  /// then the connection is closed.
  void serve_stop(socket_t sock, std::string bytes);
  /// Waits until `sock` has data (true), or until `until`, an error or the server's stop (false).
  bool wait_readable(socket_t sock, std::chrono::steady_clock::time_point until) const;
  class RequestStream;
  class Listener;  // cpp-httplib's task queue: runs each accepted connection's task at once
  class Threads;
  class Reserved;

  std::shared_ptr<Shared> shared_;
  std::unique_ptr<Threads> workers_;
  std::unique_ptr<Reserved> reserved_;
};

}  // namespace mrroc::ui
