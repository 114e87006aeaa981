/// @file
/// The image of a VSP (see mrroc/ecp/virtual_sensor.hpp), kept through its vsp::Client.
#include "mrroc/ecp/virtual_sensor.hpp"

#include <fmt/format.h>

namespace mrroc::ecp {

VirtualSensor::VirtualSensor(comm::Bus& bus, const std::string& vsp, const std::string& owner,
                             VirtualSensorOptions options)
    : client_(bus, vsp, owner, options) {
  image_.invalid_reason = fmt::format("VSP '{}': no reading yet", vsp);
}

void VirtualSensor::invalid(const std::string& reason) {
  image_ = vsp::Reading{};
  image_.valid = false;
  image_.invalid_reason = fmt::format("VSP '{}': {}", name(), reason);
}

void VirtualSensor::configure(const std::string& arguments) {
  try {
    client_.configure(arguments);
  } catch (const Error& e) {
    throw SensorError(e.what());
  }
}

void VirtualSensor::terminate() {
  try {
    client_.terminate();
  } catch (const Error& e) {
    throw SensorError(e.what());
  }
}

void VirtualSensor::initiate_reading() {
  try {
    client_.initiate_reading(context_);
  } catch (const vsp::Refused& e) {
    invalid("INITIATE_READING refused: " + e.reason());
  } catch (const vsp::NoAnswer& e) {
    image_ = vsp::Reading{};
    image_.invalid_reason = e.what();  // names the VSP already
  }
}

void VirtualSensor::get_reading() {
  try {
    image_ = client_.get_reading();
  } catch (const vsp::Refused& e) {
    invalid("GET_READING refused: " + e.reason());
  } catch (const vsp::NoAnswer& e) {
    image_ = vsp::Reading{};
    image_.invalid_reason = e.what();
  }
}

const vsp::Reading& VirtualSensor::valid_image() const {
  if (!image_.valid) throw SensorError(image_.invalid_reason);
  return image_;
}

}  // namespace mrroc::ecp
