/// @file
/// The client of an EDP (see mrroc/edp/client.hpp) over the typed request/reply link.
#include "mrroc/edp/client.hpp"

#include <fmt/format.h>

#include "mrroc/comm/links.hpp"
#include "mrroc/config/process_set.hpp"

namespace mrroc::edp {

struct Client::Impl {
  Impl(comm::Bus& bus, const std::string& process_name, const std::string& robot_name,
       const comm::ClientOptions& options)
      : robot(robot_name),
        link(bus, process_name, "EDP " + robot_name, channels::edp_command(robot_name),
             channels::edp_reply(robot_name), options) {}

  std::string robot;
  comm::EdpClient link;
  bool take_over_next = true;
};

namespace {
comm::ClientOptions link_options(const ClientOptions& options) {
  comm::ClientOptions o;
  o.attempt_timeout = options.attempt_timeout;
  o.max_attempts = options.max_attempts;
  return o;
}
}  // namespace

Client::Client(comm::Bus& bus, const std::string& process_name, const std::string& robot_name,
               ClientOptions options)
    : Client(bus, process_name, robot_name, link_options(options)) {}

Client::Client(comm::Bus& bus, const std::string& process_name, const std::string& robot_name,
               const comm::ClientOptions& options)
    : impl_(std::make_unique<Impl>(bus, process_name, robot_name, options)) {}

Client::~Client() = default;

const std::string& Client::robot() const { return impl_->robot; }

void Client::take_over_next() { impl_->take_over_next = true; }

bool Client::take_over_due() const { return impl_->take_over_next; }

void Client::abandon() { impl_->link.abandon(); }

Reply Client::call(const Instruction& instruction) {
  Reply reply;
  try {
    if (impl_->take_over_next && instruction.type != InstructionType::query) {
      Instruction claiming = instruction;
      claiming.take_over = true;
      reply = impl_->link.call(claiming);
    } else {
      reply = impl_->link.call(instruction);
    }
  } catch (const TimeoutError&) {
    // Whatever the EDP did with it, the next instruction starts afresh.
    impl_->take_over_next = true;
    throw;
  } catch (const CallAbandoned&) {
    impl_->take_over_next = true;
    throw;
  }
  if (!(reply.type == ReplyType::error && reply.error_code == error_code::not_owner))
    impl_->take_over_next = false;
  if (reply.type == ReplyType::error)
    throw Refused(reply.error_code,
                  fmt::format("EDP {} refused {}: {}", impl_->robot, to_string(instruction.type),
                              reply.error_text),
                  reply.error_class == ErrorClass::none ? ErrorClass::fatal : reply.error_class);
  return reply;
}

}  // namespace mrroc::edp
