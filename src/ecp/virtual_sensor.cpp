/// @file
/// The client of a VSP (see mrroc/ecp/virtual_sensor.hpp).
#include "mrroc/ecp/virtual_sensor.hpp"

#include <fmt/format.h>

#include "mrroc/comm/links.hpp"
#include "mrroc/config/process_set.hpp"

namespace mrroc::ecp {

struct VirtualSensor::Link {
  Link(comm::Bus& bus, const std::string& owner, const std::string& vsp, comm::ClientOptions o)
      : client(bus, owner + "->vsp/" + vsp, "vsp/" + vsp, channels::vsp_command(vsp),
               channels::vsp_reply(vsp), o) {}
  comm::VspClient client;
};

VirtualSensor::VirtualSensor(comm::Bus& bus, const std::string& vsp, const std::string& owner,
                             VirtualSensorOptions options)
    : name_(vsp) {
  comm::ClientOptions o;
  o.attempt_timeout = options.attempt_timeout;
  o.max_attempts = options.max_attempts;
  link_ = std::make_unique<Link>(bus, owner, vsp, o);
  image_.invalid_reason = fmt::format("VSP '{}': no reading yet", vsp);
}

VirtualSensor::~VirtualSensor() = default;

void VirtualSensor::invalid(const std::string& reason) {
  image_ = vsp::Reading{};
  image_.valid = false;
  image_.invalid_reason = fmt::format("VSP '{}': {}", name_, reason);
}

namespace {
vsp::Reply call(comm::VspClient& client, const std::string& vsp, vsp::Command command,
                const std::string& arguments) {
  try {
    return client.call(vsp::Request{command, arguments});
  } catch (const Error& e) {
    throw SensorError(
        fmt::format("VSP '{}' did not answer {}: {}", vsp, vsp::to_string(command), e.what()));
  }
}
}  // namespace

void VirtualSensor::configure(const std::string& arguments) {
  const vsp::Reply r = call(link_->client, name_, vsp::Command::configure, arguments);
  if (r.kind == vsp::ReplyKind::error)
    throw SensorError(fmt::format("VSP '{}' refused CONFIGURE: {}", name_, r.error_text));
}

void VirtualSensor::terminate() {
  const vsp::Reply r = call(link_->client, name_, vsp::Command::terminate, {});
  if (r.kind == vsp::ReplyKind::error)
    throw SensorError(fmt::format("VSP '{}' refused TERMINATE: {}", name_, r.error_text));
}

void VirtualSensor::initiate_reading() {
  try {
    const vsp::Reply r = call(link_->client, name_, vsp::Command::initiate_reading, context_);
    if (r.kind == vsp::ReplyKind::error) invalid("INITIATE_READING refused: " + r.error_text);
  } catch (const SensorError& e) {
    invalid(e.what());
  }
}

void VirtualSensor::get_reading() {
  try {
    const vsp::Reply r = call(link_->client, name_, vsp::Command::get_reading, {});
    if (r.kind == vsp::ReplyKind::error) {
      invalid("GET_READING refused: " + r.error_text);
    } else {
      image_ = r.reading;
      if (!image_.valid)
        image_.invalid_reason = fmt::format("VSP '{}': {}", name_, image_.invalid_reason);
    }
  } catch (const SensorError& e) {
    image_ = vsp::Reading{};
    image_.invalid_reason = e.what();
  }
}

const vsp::Reading& VirtualSensor::valid_image() const {
  if (!image_.valid) throw SensorError(image_.invalid_reason);
  return image_;
}

}  // namespace mrroc::ecp

#include "mrroc/ecp/task.hpp"

namespace mrroc::ecp {

std::unique_ptr<VirtualSensor> TaskContext::sensor(const std::string& vsp) const {
  if (bus == nullptr) throw Error("this task context has no LCM bus for virtual sensors");
  return std::make_unique<VirtualSensor>(*bus, vsp, process.empty() ? "ecp" : process);
}

}  // namespace mrroc::ecp
