#pragma once
/// @file
/// The image of one virtual sensor in an ECP or the MP, kept current through the VSP's client
/// (vsp::Client, mrroc/vsp/client.hpp: CONFIGURE, INITIATE_READING, GET_READING, TERMINATE).
/// Move and Wait call `initiate_reading` and `get_reading` in step with the motion (paper,
/// section 4), so generators and conditions find the current reading in `image()`. No LCM here.
///
/// A VSP that does not answer, or answers an error, leaves an invalid image whose
/// `invalid_reason` names the VSP and why; a VSP whose sources went stale answers an invalid
/// reading. Generators use `valid_image()`, which throws `SensorError` (a system error of the
/// task) for an invalid image: the Move ends, the robot holds, the SRP gets the reason.
#include <string>

#include "mrroc/ecp/errors.hpp"
#include "mrroc/ecp/generator.hpp"
#include "mrroc/msg/sensor_reading.hpp"
#include "mrroc/vsp/client.hpp"

namespace mrroc::ecp {

/// A sensor gave no valid reading. `what()` names the VSP and the reason.
class SensorError : public SystemError {
 public:
  explicit SensorError(const std::string& text) : SystemError(text, error_code::sensor_invalid) {}
};

/// Timeouts of the VSP's client (40 ms per attempt, 3 attempts unless set).
using VirtualSensorOptions = vsp::ClientOptions;

class VirtualSensor : public Sensor {
 public:
  /// @param owner  the calling process' name, for the link's endpoint name.
  VirtualSensor(comm::Bus& bus, const std::string& vsp, const std::string& owner,
                VirtualSensorOptions options = {});
  ~VirtualSensor() override = default;
  VirtualSensor(const VirtualSensor&) = delete;
  VirtualSensor& operator=(const VirtualSensor&) = delete;

  /// CONFIGURE with TOML `key = value` arguments (e.g. "zero = true").
  /// @throws SensorError naming the VSP and its answer.
  void configure(const std::string& arguments = {});
  /// TERMINATE. @throws SensorError.
  void terminate();
  /// Arguments sent with every INITIATE_READING (e.g. the sensor's orientation).
  void set_context(const std::string& arguments) { context_ = arguments; }

  void initiate_reading() override;
  void get_reading() override;

  [[nodiscard]] const std::string& name() const { return client_.name(); }
  /// The VSP's client the image is kept current through.
  [[nodiscard]] vsp::Client& client() { return client_; }
  /// The last reading (possibly invalid).
  [[nodiscard]] const vsp::Reading& image() const { return image_; }
  /// The last reading. @throws SensorError when it is not valid.
  [[nodiscard]] const vsp::Reading& valid_image() const;
  /// A value of the last valid reading by name. @throws SensorError, or Error for a bad name.
  [[nodiscard]] double value(const std::string& value_name) const {
    return valid_image().value(value_name);
  }

 private:
  void invalid(const std::string& reason);

  vsp::Client client_;
  std::string context_;
  vsp::Reading image_;
};

}  // namespace mrroc::ecp
