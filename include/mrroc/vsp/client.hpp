#pragma once
/// @file
/// The client of one VSP: CONFIGURE, INITIATE_READING, GET_READING and TERMINATE over the
/// request/reply link of the virtual sensor (channels `vsp/<name>/cmd` and `vsp/<name>/reply`;
/// docs/sensors.md). The sensor image of ECP and MP tasks (ecp::VirtualSensor,
/// mrroc/ecp/virtual_sensor.hpp) is built on it.
///
/// No LCM here: the link lives behind a pointer, in src/vsp/client.cpp.

#include <chrono>
#include <memory>
#include <string>

#include "mrroc/core/error.hpp"
#include "mrroc/msg/sensor_reading.hpp"

namespace mrroc::comm {
class Bus;
}  // namespace mrroc::comm

namespace mrroc::vsp {

/// The VSP did not answer a command (no reply within the attempts, or one that does not decode).
/// `what()` names the VSP, the command and the cause.
class NoAnswer : public Error {
 public:
  using Error::Error;
};

/// The VSP answered a command with an error. `code()` and `reason()` are the VSP's; `what()`
/// names the VSP and the command as well.
class Refused : public RemoteError {
 public:
  Refused(int code, std::string reason, const std::string& what)
      : RemoteError(code, what), reason_(std::move(reason)) {}
  [[nodiscard]] const std::string& reason() const { return reason_; }

 private:
  std::string reason_;
};

struct ClientOptions {
  /// Per attempt; a reading is needed every macro-step, so a dead VSP must show quickly.
  std::chrono::milliseconds attempt_timeout{40};
  int max_attempts = 3;
};

class Client {
 public:
  /// @param vsp    the VSP's name ([[vsp]] name).
  /// @param owner  the calling process' name ("ecp/irb6", "mp"), for the link's endpoint name.
  Client(comm::Bus& bus, const std::string& vsp, const std::string& owner,
         ClientOptions options = {});
  ~Client();
  Client(const Client&) = delete;
  Client& operator=(const Client&) = delete;

  /// The VSP's name.
  [[nodiscard]] const std::string& name() const;

  /// One command with TOML `key = value` arguments; the VSP's reply as it is.
  /// @throws NoAnswer.
  Reply call(Command command, const std::string& arguments = {});

  /// CONFIGURE (e.g. "zero = true"). @throws NoAnswer, Refused.
  void configure(const std::string& arguments = {});
  /// TERMINATE. @throws NoAnswer, Refused.
  void terminate();
  /// INITIATE_READING with the arguments of this reading (e.g. the sensor's orientation).
  /// @throws NoAnswer, Refused.
  void initiate_reading(const std::string& context = {});
  /// GET_READING: the VSP's last reading; an invalid one's `invalid_reason` names the VSP.
  /// @throws NoAnswer, Refused.
  Reading get_reading();

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace mrroc::vsp
