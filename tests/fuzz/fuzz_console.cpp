// The web console's request handling (ui/console/http_server.*, http_api.*): raw bytes sent as
// one connection to the console's HTTP server, on loopback, with the console's own routes, Host
// and Origin checks, token check and limits. What the POST routes would do goes to a recorder
// (the bus is not the subject here).
//
// Input: the bytes of the connection (requests, possibly several, possibly broken); the client
// then closes its side and reads the answer to the end.
//
// Properties (docs/fuzzing.md):
// - the server neither crashes nor hangs: the connection ends within the request deadline;
// - whatever it answers starts with "HTTP/1.1 " and a three-digit status;
// - no action (operator command, emergency stop, jog, teach-in) is taken for a connection whose
//   bytes do not carry the token.
#include <arpa/inet.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <sys/time.h>
#include <unistd.h>

#include <atomic>
#include <cctype>
#include <cerrno>
#include <chrono>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <memory>
#include <string>
#include <string_view>
#include <thread>

#include "fuzz_common.hpp"
#include "mrroc/robot/robot_model.hpp"
// Last: <httplib.h> defines `_res` (see http_server.hpp).
#include "console/http_api.hpp"
#include "console/http_server.hpp"
#include "console/state.hpp"

namespace {

using namespace mrroc::ui;

constexpr std::string_view kToken = "fuzz-token-5ac1e2d94b7f";

/// Counts what the routes asked for.
struct Recorder : ConsoleActions {
  std::atomic<int> actions{0};
  MpStatus command(OperatorCommand) override {
    ++actions;
    return {};
  }
  EstopResult emergency_stop(bool, const std::string&, const std::string&) override {
    ++actions;
    return {};
  }
  JogResult jog(const JogRequest&) override {
    ++actions;
    return {};
  }
  JogResult synchronise(const std::string&) override {
    ++actions;
    return {};
  }
  TeachResult teach(const std::string&, const std::string&) override {
    ++actions;
    return {};
  }
};

struct Console {
  ConsoleState state;
  Recorder recorder;
  std::unique_ptr<HttpApi> api;
  std::unique_ptr<ConsoleServer> server;
  std::thread listener;
  int port = 0;

  Console()
      : state("fuzz",
              {ConsoleRobot{"irb6",
                            mrroc::load_robot_model(std::string(MRROC_SOURCE_DIR) + "/robots/irb6"),
                            0.002}}) {
    ApiSettings settings;
    settings.set_name = "fuzz";
    settings.config_file = "/configs/fuzz.toml";
    settings.teach_dir = "/nonexistent";
    settings.token = std::string(kToken);
    settings.token_hint = "the fuzzer's token";
    api = std::make_unique<HttpApi>(state, settings, recorder);
    ServerLimits limits;
    limits.request_deadline = std::chrono::milliseconds(500);
    server = std::make_unique<ConsoleServer>(limits);
    api->install(*server);
    port = server->bind_to_any_port("127.0.0.1");
    fuzz::expect(port > 0, "the console's server cannot listen on loopback");
    listener = std::thread([this] { server->listen_after_bind(); });
    for (int i = 0; i < 1000 && !server->is_running(); ++i)
      std::this_thread::sleep_for(std::chrono::milliseconds(1));
    fuzz::expect(server->is_running(), "the console's server did not start");
  }
};

Console& console() {
  static Console* c = new Console();  // lives as long as the fuzzing process
  return *c;
}

/// Sends `data` as one connection, closes the sending side, reads the answer to its end.
std::string exchange(const std::uint8_t* data, std::size_t size) {
  const int fd = ::socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
  fuzz::expect(fd >= 0, "socket() failed");
  timeval timeout{5, 0};  // well above the request deadline: longer means a hang
  ::setsockopt(fd, SOL_SOCKET, SO_RCVTIMEO, &timeout, sizeof timeout);
  ::setsockopt(fd, SOL_SOCKET, SO_SNDTIMEO, &timeout, sizeof timeout);
  sockaddr_in address{};
  address.sin_family = AF_INET;
  address.sin_port = htons(static_cast<std::uint16_t>(console().port));
  address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  // libFuzzer's timer signal interrupts blocking calls (EINTR): a connect goes on by itself,
  // the others are called again.
  if (::connect(fd, reinterpret_cast<const sockaddr*>(&address), sizeof address) != 0) {
    int error = errno;
    if (error == EINTR) {
      pollfd p{fd, POLLOUT, 0};
      while (::poll(&p, 1, 5000) < 0 && errno == EINTR) {
      }
      socklen_t length = sizeof error;
      ::getsockopt(fd, SOL_SOCKET, SO_ERROR, &error, &length);
    }
    if (error != 0 && error != EINTR)
      fuzz::fail(fmt::format("cannot connect to the console: {}", std::strerror(error)));
  }
  std::size_t sent = 0;
  while (sent < size) {
    const ssize_t n = ::send(fd, data + sent, size - sent, MSG_NOSIGNAL);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) break;  // the server closed early (a refused body): that is allowed
    sent += static_cast<std::size_t>(n);
  }
  ::shutdown(fd, SHUT_WR);
  std::string answer;
  char buffer[4096];
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(5);
  for (;;) {
    fuzz::expect(std::chrono::steady_clock::now() < deadline,
                 "the console did not end the connection within 5 s");
    const ssize_t n = ::recv(fd, buffer, sizeof buffer, 0);
    if (n > 0) {
      answer.append(buffer, static_cast<std::size_t>(n));
      continue;
    }
    if (n < 0 && errno == EINTR) continue;
    fuzz::expect(
        n == 0 || errno == ECONNRESET,
        fmt::format("the console did not end the connection within 5 s (errno {})", errno));
    break;
  }
  ::close(fd);
  return answer;
}

}  // namespace

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  (void)console();
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  Console& c = console();
  const int before = c.recorder.actions.load();
  const std::string answer = exchange(data, size);
  if (!answer.empty()) {
    const bool status_line = answer.size() >= 12 && answer.compare(0, 9, "HTTP/1.1 ") == 0 &&
                             std::isdigit(static_cast<unsigned char>(answer[9])) != 0 &&
                             std::isdigit(static_cast<unsigned char>(answer[10])) != 0 &&
                             std::isdigit(static_cast<unsigned char>(answer[11])) != 0;
    fuzz::expect(status_line, "the console answered without an HTTP/1.1 status line: " +
                                  fuzz::escaped(answer.substr(0, 64)));
  }
  const std::string_view bytes(reinterpret_cast<const char*>(data), size);
  if (bytes.find(kToken) == std::string_view::npos)
    fuzz::expect(c.recorder.actions.load() == before,
                 "a connection without the token made the console act");
  return 0;
}
