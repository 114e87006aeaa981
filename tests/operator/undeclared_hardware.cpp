// A hardware plugin library as a user writes one: it mirrors every command (as the EDP's `mock`
// plugin) and does not say whether it drives real devices, so it counts as driving them
// (edp::Hardware::drives_real_devices). test_launch_restart loads it through [robot.edp] library
// and checks that the launcher holds its EDP's restart for an operator.
#include <fmt/format.h>

#include <vector>

#include "mrroc/core/error.hpp"
#include "mrroc/core/time.hpp"
#include "mrroc/edp/hardware.hpp"

namespace {

using namespace mrroc;
using namespace mrroc::edp;

class UndeclaredHardware final : public Hardware {
 public:
  std::string name() const override { return "undeclared"; }
  std::size_t axis_count() const override { return axes_; }

  void configure(const HardwareSetup& setup) override {
    setup.params.reject_unread("robot.edp.params");
    if (setup.synchro_positions.empty())
      throw HardwareError(
          fmt::format("{}: no synchronisation positions for robot '{}'", name(), setup.robot));
    axes_ = setup.synchro_positions.size();
    synchro_ = setup.synchro_positions;
    raw_.assign(axes_, 0.0);
    velocity_.assign(axes_, 0.0);
    period_ = setup.servo_period_s;
  }
  void activate() override { active_ = true; }
  void deactivate() override { active_ = false; }

  CycleStatus read(std::span<AxisFeedback> out) override {
    for (std::size_t i = 0; i < axes_ && i < out.size(); ++i) {
      out[i].position = raw_[i];
      out[i].velocity = velocity_[i];
      out[i].synchro_switch = synchro_[i] + 0.05 + raw_[i] > synchro_[i];
    }
    return CycleStatus::ok;
  }
  CycleStatus write(std::span<const double> setpoints) override {
    if (!active_) return CycleStatus::fault;
    for (std::size_t i = 0; i < axes_ && i < setpoints.size(); ++i) {
      velocity_[i] = (setpoints[i] - raw_[i]) / period_;
      raw_[i] = setpoints[i];
    }
    return CycleStatus::ok;
  }

 private:
  std::size_t axes_ = 0;
  double period_ = kDefaultServoPeriodS;
  bool active_ = false;
  std::vector<double> synchro_, raw_, velocity_;
};

MRROC_REGISTER_HARDWARE("undeclared", UndeclaredHardware);

}  // namespace
