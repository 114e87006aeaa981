// The EDP's device part (SET DEVICE / GET DEVICE): every commanded field is checked against the
// range its plugin declares (refusals name field, value, unit and limit), a plugin without a
// device refuses both as not supported, SET DEVICE is refused during an emergency stop and from
// a client that does not own the EDP, and a GET DEVICE returns what the plugin measured.
#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <limits>
#include <thread>

#include "command_interpreter.hpp"
#include "edp_parts.hpp"
#include "mrroc/edp/arm_kinematics.hpp"
#include "mrroc/edp/hardware.hpp"
#include "mrroc/robot/robot_model.hpp"
#include "servo_loop.hpp"

using namespace mrroc;
using namespace mrroc::edp;

namespace {

constexpr double kPeriod = 0.002;

/// The mock plugin's axes plus a two-field device: the opening follows the commanded opening at
/// most 0.1 m/s; the reply is the opening and the last commanded force.
class MockWithDevice : public Hardware {
 public:
  explicit MockWithDevice(std::unique_ptr<Hardware> axes) : axes_(std::move(axes)) {}
  [[nodiscard]] std::string name() const override { return "mock-with-device"; }
  [[nodiscard]] std::size_t axis_count() const override { return axes_->axis_count(); }
  void configure(const HardwareSetup& setup) override { axes_->configure(setup); }
  void activate() override { axes_->activate(); }
  void deactivate() override { axes_->deactivate(); }
  CycleStatus read(std::span<AxisFeedback> out) override { return axes_->read(out); }
  CycleStatus write(std::span<const double> setpoints) override {
    const double step = 0.1 * kPeriod;
    opening_ += std::clamp(target_ - opening_, -step, step);
    return axes_->write(setpoints);
  }
  [[nodiscard]] DeviceDescription device() const override {
    return {"gripper",
            {{"opening", "m", 0.0, 0.08}, {"force", "N", 0.0, 40.0}},
            {{"opening", "m", 0.0, 0.08}, {"force", "N", 0.0, 40.0}}};
  }
  void write_device(std::span<const double> command) override {
    target_ = command[0];
    force_ = command[1];
  }
  void read_device(std::span<double> reply) const override {
    reply[0] = opening_;
    reply[1] = force_;
  }

 private:
  std::unique_ptr<Hardware> axes_;
  double opening_ = 0.08;
  double target_ = 0.08;
  double force_ = 0.0;
};

class Edp {
 public:
  explicit Edp(bool with_device) {
    model_ = test::stock_model("irb6");
    auto mock = test::configured_hardware(model_, "mock", kPeriod);
    hardware_ = with_device ? std::make_unique<MockWithDevice>(std::move(mock)) : std::move(mock);
    kinematics_ = make_arm_kinematics(model_);
    servo_ = std::make_unique<ServoLoop>(*hardware_, model_, kPeriod);
    servo_->start();
    interpreter_ = std::make_unique<CommandInterpreter>(*servo_, model_, *kinematics_, kPeriod);
  }
  ~Edp() { servo_->stop(); }

  Reply exec(Instruction in, const std::string& client = "ecp/irb6") {
    in.with_query = true;
    return interpreter_->execute(in, client);
  }
  static Instruction set_device(std::vector<double> values) {
    Instruction in;
    in.type = InstructionType::set_get;
    in.set = item::device;
    in.get = item::device;
    in.device = std::move(values);
    return in;
  }
  static Instruction get_device() {
    Instruction in;
    in.type = InstructionType::get;
    in.get = item::device;
    return in;
  }

  RobotModel model_;
  std::unique_ptr<Hardware> hardware_;
  std::unique_ptr<ServoLoop> servo_;
  std::unique_ptr<ArmKinematics> kinematics_;
  std::unique_ptr<CommandInterpreter> interpreter_;
};

TEST(EdpDevice, CommandsReachThePluginAndGetReturnsItsReply) {
  Edp edp(true);
  // No SYNCHRO needed: the device is not the arm.
  Reply r = edp.exec(Edp::set_device({0.02, 15.0}));
  ASSERT_EQ(r.type, ReplyType::data) << r.error_text;
  ASSERT_EQ(r.device.size(), 2U);
  // The opening moves at 0.1 m/s from 0.08 m to 0.02 m: 0.6 s.
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(3);
  do {
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
    r = edp.exec(Edp::get_device());
    ASSERT_EQ(r.type, ReplyType::data) << r.error_text;
  } while (r.device[0] > 0.02 + 1e-9 && std::chrono::steady_clock::now() < deadline);
  EXPECT_NEAR(r.device[0], 0.02, 1e-9);
  EXPECT_DOUBLE_EQ(r.device[1], 15.0);
  // A GET without DEVICE carries no device part.
  Instruction arm;
  arm.type = InstructionType::get;
  arm.get = item::arm;
  EXPECT_TRUE(edp.exec(arm).device.empty());
}

TEST(EdpDevice, OutOfRangeNanAndWrongLengthAreRefusedNamingValueUnitAndLimit) {
  Edp edp(true);
  Reply r = edp.exec(Edp::set_device({0.02, 55.0}));
  EXPECT_EQ(r.error_code, error_code::out_of_limits);
  EXPECT_EQ(r.error_text,
            "SET DEVICE gripper field 1 (force) 55 N exceeds its upper limit of 40 N");
  r = edp.exec(Edp::set_device({-0.01, 10.0}));
  EXPECT_EQ(r.error_code, error_code::out_of_limits);
  EXPECT_EQ(r.error_text,
            "SET DEVICE gripper field 0 (opening) -0.01 m is below its lower limit of 0 m");
  r = edp.exec(Edp::set_device({std::numeric_limits<double>::quiet_NaN(), 10.0}));
  EXPECT_EQ(r.error_code, error_code::bad_argument);
  EXPECT_EQ(r.error_text,
            "SET DEVICE gripper field 0 (opening) value nan m is not a finite number");
  r = edp.exec(Edp::set_device({0.02}));
  EXPECT_EQ(r.error_code, error_code::bad_argument);
  EXPECT_EQ(r.error_text,
            "SET DEVICE has 1 values, device 'gripper' of plugin 'mock-with-device' takes 2: "
            "opening [m], force [N]");
  // Nothing of a refused SET reached the plugin: still open, no force.
  r = edp.exec(Edp::get_device());
  ASSERT_EQ(r.type, ReplyType::data) << r.error_text;
  EXPECT_DOUBLE_EQ(r.device[0], 0.08);
  EXPECT_DOUBLE_EQ(r.device[1], 0.0);
}

TEST(EdpDevice, RefusedDuringEmergencyStopAndFromAnotherClient) {
  Edp edp(true);
  ASSERT_EQ(edp.exec(Edp::get_device()).type, ReplyType::data);  // ecp/irb6 owns the EDP
  Reply r = edp.exec(Edp::set_device({0.0, 10.0}), "ui/console");
  EXPECT_EQ(r.error_code, error_code::not_owner) << r.error_text;
  edp.servo_->emergency_stop();
  r = edp.exec(Edp::set_device({0.0, 10.0}));
  EXPECT_EQ(r.error_code, error_code::emergency_stop);
  EXPECT_EQ(r.error_text,
            "SET_GET DEVICE refused: emergency stop engaged (release it first, e.g. mrroc-ui "
            "release)");
  // Reading the device is still possible; releasing makes the command acceptable again.
  EXPECT_EQ(edp.exec(Edp::get_device()).type, ReplyType::data);
  edp.servo_->release_emergency_stop();
  r = edp.exec(Edp::set_device({0.0, 10.0}));
  EXPECT_EQ(r.type, ReplyType::data) << r.error_text;
}

TEST(EdpDevice, PluginWithoutDeviceRefusesAsNotSupported) {
  Edp edp(false);
  Reply r = edp.exec(Edp::set_device({0.02, 15.0}));
  EXPECT_EQ(r.error_code, error_code::not_supported);
  EXPECT_EQ(r.error_text, "SET DEVICE refused: plugin 'mock' drives no device");
  r = edp.exec(Edp::get_device());
  EXPECT_EQ(r.error_code, error_code::not_supported);
  EXPECT_EQ(r.error_text, "GET DEVICE refused: plugin 'mock' drives no device");
}

}  // namespace
