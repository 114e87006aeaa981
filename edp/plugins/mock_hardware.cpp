// Two test plugins: "mock" mirrors every command (the axes are exactly where they were told to
// be one cycle earlier), and "faulty", a mock that injects a fault after a number of cycles
// (a fault status, or an exception) to test the EDP's fault handling.
//
// Parameters ([robot.edp.params]):
//   mock:   power_on_offset (rad, default 0.05): power-on position relative to the synchronisation
//           position on every axis.
//   faulty: the same, plus fault_after_cycles (default 100) and fault = "status" | "throw" |
//   "stall" (the read of that cycle blocks for stall_ms, default 50: a stalled servo loop).
#include <fmt/format.h>

#include <chrono>
#include <thread>

#include <cstdio>
#include <stdexcept>

#include "mrroc/core/error.hpp"
#include "mrroc/edp/hardware.hpp"

namespace mrroc::edp {

class MockHardware : public Hardware {
 public:
  std::string name() const override { return "mock"; }
  std::size_t axis_count() const override { return axes_; }
  bool simulated() const override { return true; }
  bool drives_real_devices() const override { return false; }

  void configure(const HardwareSetup& setup) override {
    const Params& params = setup.params;  // not a copy: a check's sink of unknown keys is kept
    configure_params(params);
    params.reject_unread("robot.edp.params");
    if (setup.synchro_positions.empty())
      throw HardwareError(
          fmt::format("{}: no synchronisation positions for robot '{}'", name(), setup.robot));
    axes_ = setup.synchro_positions.size();
    synchro_ = setup.synchro_positions;
    power_on_.resize(axes_);
    for (std::size_t i = 0; i < axes_; ++i) power_on_[i] = synchro_[i] + offset_;
    raw_.assign(axes_, 0.0);
    velocity_.assign(axes_, 0.0);
    period_ = setup.servo_period_s;
  }
  void activate() override {
    raw_.assign(axes_, 0.0);
    velocity_.assign(axes_, 0.0);
    active_ = true;
  }
  void deactivate() override { active_ = false; }

  CycleStatus read(std::span<AxisFeedback> out) override {
    for (std::size_t i = 0; i < axes_ && i < out.size(); ++i) {
      out[i].position = raw_[i];
      out[i].velocity = velocity_[i];
      out[i].synchro_switch = power_on_[i] + raw_[i] > synchro_[i];
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

 protected:
  virtual void configure_params(const Params& params) {
    offset_ = params.get_double("power_on_offset", 0.05);
  }

 private:
  std::size_t axes_ = 0;
  double offset_ = 0.05;
  double period_ = kDefaultServoPeriodS;
  bool active_ = false;
  std::vector<double> synchro_, power_on_, raw_, velocity_;
};

class FaultyHardware : public MockHardware {
 public:
  std::string name() const override { return "faulty"; }
  void activate() override {
    MockHardware::activate();
    cycles_ = 0;
    faulted_ = false;
    ++activations_;
  }
  CycleStatus read(std::span<AxisFeedback> out) override {
    // Each activation injects one fault, after fault_after_cycles reads; after a reset the
    // plugin keeps working (the fault was transient).
    if (activations_ == 1 && ++cycles_ > fault_after_ && !faulted_) {
      if (stall_ms_ > 0) {
        // A stall is no fault of the drive: the loop just does not run for a while, once.
        if (!stalled_) std::this_thread::sleep_for(std::chrono::milliseconds(stall_ms_));
        stalled_ = true;
        return MockHardware::read(out);
      }
      faulted_ = true;
      if (throw_) throw std::runtime_error("injected exception in read()");
    }
    if (faulted_ && activations_ == 1) return CycleStatus::fault;
    return MockHardware::read(out);
  }
  std::string fault_text() const override {
    return fmt::format("faulty: injected drive fault after {} cycles", fault_after_);
  }

 protected:
  void configure_params(const Params& params) override {
    MockHardware::configure_params(params);
    fault_after_ = params.get_int("fault_after_cycles", 100);
    const std::string kind = params.get_string("fault", "status");
    if (kind != "status" && kind != "throw" && kind != "stall")
      throw ConfigError(params.location_of("fault"),
                        fmt::format("fault '{}' must be \"status\", \"throw\" or \"stall\"", kind));
    throw_ = kind == "throw";
    const std::int64_t stall = params.get_int("stall_ms", 50);
    if (stall < 1 || stall > 10000)
      throw ConfigError(params.location_of("stall_ms"),
                        fmt::format("stall_ms = {} ms is outside 1..10000 ms", stall));
    if (kind == "stall") stall_ms_ = stall;
  }

 private:
  std::int64_t fault_after_ = 100;
  std::int64_t cycles_ = 0;
  int activations_ = 0;
  bool throw_ = false;
  bool faulted_ = false;
  std::int64_t stall_ms_ = 0;
  bool stalled_ = false;
};

MRROC_REGISTER_HARDWARE("mock", MockHardware);
MRROC_REGISTER_HARDWARE("faulty", FaultyHardware);

}  // namespace mrroc::edp
