// A user's generator, ECP task, MP task, hardware plugin and sensor plugin, and the EDP and VSP
// clients, compiled with LCM's, the TOML parser's and mrroc's own LCM-bound headers (bus,
// request/reply, links, codecs) replaced by ones that stop the compiler
// (tests/package/CMakeLists.txt): the extension points include none of them.
#include <cstddef>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "mrroc/comm/reporter.hpp"
#include "mrroc/ecp/conditions.hpp"
#include "mrroc/ecp/generator.hpp"
#include "mrroc/ecp/generators/cartesian_path.hpp"
#include "mrroc/ecp/generators/errors.hpp"
#include "mrroc/ecp/generators/guarded_move.hpp"
#include "mrroc/ecp/generators/interpolation.hpp"
#include "mrroc/ecp/generators/joint_poses.hpp"
#include "mrroc/ecp/generators/motion_profile.hpp"
#include "mrroc/ecp/generators/pass_through.hpp"
#include "mrroc/ecp/generators/planned_motion.hpp"
#include "mrroc/ecp/generators/teach_in.hpp"
#include "mrroc/ecp/generators/trajectory_file.hpp"
#include "mrroc/ecp/robot.hpp"
#include "mrroc/ecp/task.hpp"
#include "mrroc/ecp/virtual_sensor.hpp"
#include "mrroc/edp/arm_kinematics.hpp"
#include "mrroc/edp/client.hpp"
#include "mrroc/edp/hardware.hpp"
#include "mrroc/mp/robot.hpp"
#include "mrroc/mp/task.hpp"
#include "mrroc/vsp/client.hpp"
#include "mrroc/vsp/sensor.hpp"

namespace {

/// Holds the first joint where it is for `steps` macro-steps.
class HoldGenerator : public mrroc::ecp::Generator {
 public:
  explicit HoldGenerator(int steps) : steps_(steps) {}
  bool first_step(mrroc::ecp::RobotImage& robot, const mrroc::ecp::SensorList&) override {
    robot.command.type = mrroc::edp::InstructionType::set;
    robot.command.arm = robot.desired_joints;
    return steps_ > 0;
  }
  bool next_step(mrroc::ecp::RobotImage&, const mrroc::ecp::SensorList&) override {
    return --steps_ > 0;
  }

 private:
  int steps_;
};

/// An ECP task: reads a sensor, holds the robot, reports.
class HoldTask : public mrroc::ecp::EcpTask {
 public:
  explicit HoldTask(mrroc::ecp::TaskContext& context) : context_(context) {}
  void main_task() override {
    context_.robot.synchronise();
    std::unique_ptr<mrroc::ecp::VirtualSensor> sensor = context_.sensor("wrist");
    sensor->configure("zero = true");
    HoldGenerator hold(static_cast<int>(context_.args.get_int("steps", 3)));
    mrroc::ecp::Move(context_.robot, {sensor.get()}, hold);
    context_.reporter.info("held at " + std::to_string(context_.robot.image().joints.at(0)));
  }

 private:
  mrroc::ecp::TaskContext& context_;
};
MRROC_REGISTER_ECP_TASK("hold", HoldTask);

/// An MP task: runs every robot's ECP task at once.
class StartAllTask : public mrroc::mp::MpTask {
 public:
  explicit StartAllTask(mrroc::mp::TaskContext& context) : context_(context) {}
  void main_task() override {
    mrroc::mp::parallel(context_.robots, [](mrroc::mp::Robot& r) { r.start_task(); });
    context_.reporter.info(std::to_string(context_.config.robots.size()) + " robots ran");
  }

 private:
  mrroc::mp::TaskContext& context_;
};
MRROC_REGISTER_MP_TASK("start_all", StartAllTask);

/// A hardware plugin whose axes follow their setpoints at once.
class IdealHardware : public mrroc::edp::Hardware {
 public:
  [[nodiscard]] std::string name() const override { return "ideal"; }
  [[nodiscard]] std::size_t axis_count() const override { return positions_.size(); }
  void configure(const mrroc::edp::HardwareSetup& setup) override {
    positions_.assign(setup.synchro_positions.size(), 0.0);
  }
  void activate() override {}
  void deactivate() override {}
  mrroc::edp::CycleStatus read(std::span<mrroc::edp::AxisFeedback> out) override {
    for (std::size_t i = 0; i < out.size() && i < positions_.size(); ++i)
      out[i].position = positions_[i];
    return mrroc::edp::CycleStatus::ok;
  }
  mrroc::edp::CycleStatus write(std::span<const double> setpoints) override {
    positions_.assign(setpoints.begin(), setpoints.end());
    return mrroc::edp::CycleStatus::ok;
  }

 private:
  std::vector<double> positions_;
};

MRROC_REGISTER_HARDWARE("ideal", IdealHardware);

/// A sensor plugin that reads the first value of its first source.
class FirstValueSensor : public mrroc::vsp::SensorPlugin {
 public:
  [[nodiscard]] std::string plugin_name() const override { return "first_value"; }
  void configure(const mrroc::vsp::SensorSetup& setup) override {
    setup.params.reject_unread("vsp.params");
  }
  void on_sample(std::size_t source, const mrroc::vsp::RawSample& sample) override {
    if (source == 0 && !sample.values.empty()) last_ = sample.values.front();
  }
  mrroc::vsp::Reading make_reading(const mrroc::Params&) override {
    mrroc::vsp::Reading r;
    r.valid = true;
    r.values = {last_};
    r.names = {"value"};
    r.units = {"1"};
    return r;
  }

 private:
  double last_ = 0.0;
};
MRROC_REGISTER_SENSOR("first_value", FirstValueSensor);

/// The clients, as the console or a tool would use them.
[[maybe_unused]] mrroc::edp::Reply query(mrroc::edp::Client& edp) {
  mrroc::edp::Instruction q;
  q.type = mrroc::edp::InstructionType::query;
  return edp.call(q);
}
[[maybe_unused]] mrroc::vsp::Reading read(mrroc::vsp::Client& vsp) {
  vsp.initiate_reading();
  return vsp.get_reading();
}

}  // namespace

int extension_points_compile() {
  HoldGenerator g(3);
  mrroc::ecp::RobotImage image;
  return g.first_step(image, {}) ? 1 : 0;
}
