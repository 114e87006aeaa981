#pragma once
// The console's HTTP server: cpp-httplib's Server with connection handling of its own, so that
// hostile clients can neither starve the emergency stop nor fill the console's memory
// (docs/operating.md, "Limits"):
// - every connection is served on a thread of its own, at most ServerLimits::max_connections at
//   once (cpp-httplib's pool of a fixed number of threads lets that many slow clients make every
//   other request wait); a connection beyond them is answered 503 and closed at once, so nothing
//   waits for a thread and no socket is held in a queue;
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

#include <httplib.h>

namespace mrroc::ui {

struct ServerLimits {
  /// Connections served at once; more are answered 503 and closed.
  std::size_t max_connections = 128;
  /// A request must arrive whole (line, headers, body) within this time of its first byte [ms].
  std::chrono::milliseconds request_deadline{3000};
  /// Bytes a request's line and headers may take besides the body (payload_max_length).
  std::size_t max_header_bytes = 32 * 1024;
};

/// What the server has done so far (for tests and measurements).
struct ServerCounts {
  std::size_t open = 0;         ///< connections being served now
  std::size_t most_open = 0;    ///< the most served at once
  std::uint64_t served = 0;     ///< connections accepted and served (ended or not)
  std::uint64_t refused = 0;    ///< connections answered 503 (over max_connections)
  std::uint64_t late = 0;       ///< connections closed because a request missed its deadline
  std::uint64_t too_large = 0;  ///< connections closed because a request exceeded its bytes
};

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
  bool process_and_close_socket(socket_t sock) override;
  /// Waits until `sock` has data (true), or until `until`, an error or the server's stop (false).
  bool wait_readable(socket_t sock, std::chrono::steady_clock::time_point until) const;
  class RequestStream;

  std::shared_ptr<Shared> shared_;
};

}  // namespace mrroc::ui
