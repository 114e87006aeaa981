/// @file
/// The client of a VSP (see mrroc/vsp/client.hpp) over the typed request/reply link.
#include "mrroc/vsp/client.hpp"

#include <fmt/format.h>

#include "mrroc/comm/links.hpp"
#include "mrroc/config/process_set.hpp"

namespace mrroc::vsp {

struct Client::Impl {
  Impl(comm::Bus& bus, const std::string& vsp, const std::string& owner,
       const comm::ClientOptions& options)
      : name(vsp),
        link(bus, owner + "->vsp/" + vsp, "vsp/" + vsp, channels::vsp_command(vsp),
             channels::vsp_reply(vsp), options) {}

  std::string name;
  comm::VspClient link;
};

Client::Client(comm::Bus& bus, const std::string& vsp, const std::string& owner,
               ClientOptions options) {
  comm::ClientOptions o;
  o.attempt_timeout = options.attempt_timeout;
  o.max_attempts = options.max_attempts;
  impl_ = std::make_unique<Impl>(bus, vsp, owner, o);
}

Client::~Client() = default;

const std::string& Client::name() const { return impl_->name; }

Reply Client::call(Command command, const std::string& arguments) {
  try {
    return impl_->link.call(Request{command, arguments});
  } catch (const Error& e) {
    throw NoAnswer(
        fmt::format("VSP '{}' did not answer {}: {}", impl_->name, to_string(command), e.what()));
  }
}

namespace {
/// `reply`, unless it is an error: then Refused naming the VSP and the command.
Reply accepted(const std::string& vsp, Command command, Reply reply) {
  if (reply.kind == ReplyKind::error)
    throw Refused(
        reply.error_code, reply.error_text,
        fmt::format("VSP '{}' refused {}: {}", vsp, to_string(command), reply.error_text));
  return reply;
}
}  // namespace

void Client::configure(const std::string& arguments) {
  (void)accepted(impl_->name, Command::configure, call(Command::configure, arguments));
}

void Client::terminate() {
  (void)accepted(impl_->name, Command::terminate, call(Command::terminate));
}

void Client::initiate_reading(const std::string& context) {
  (void)accepted(impl_->name, Command::initiate_reading, call(Command::initiate_reading, context));
}

Reading Client::get_reading() {
  Reading reading = accepted(impl_->name, Command::get_reading, call(Command::get_reading)).reading;
  if (!reading.valid)
    reading.invalid_reason = fmt::format("VSP '{}': {}", impl_->name, reading.invalid_reason);
  return reading;
}

}  // namespace mrroc::vsp
