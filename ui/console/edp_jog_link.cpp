#include "console/edp_jog_link.hpp"

#include <chrono>

#include "mrroc/edp/client.hpp"

namespace mrroc::ui {

namespace {

class EdpJogLink : public JogLink {
 public:
  EdpJogLink(comm::Bus& bus, const std::string& robot, edp::ClientOptions options)
      : edp_(bus, "ui/jog/" + robot, robot, options) {}

  std::vector<double> move_joints_relative(const std::vector<double>& delta,
                                           int motion_steps) override {
    return move_relative(edp::ArmRepresentation::joint, delta, motion_steps);
  }

  std::vector<double> move_tool_relative(const std::vector<double>& delta,
                                         int motion_steps) override {
    return move_relative(edp::ArmRepresentation::xyz_angle_axis, delta, motion_steps);
  }

  std::vector<double> synchronise() override {
    edp::Instruction c;
    c.type = edp::InstructionType::synchro;
    c.with_query = true;  // the reply carries the joints once the search has ended
    try {
      edp_.take_over_next();
      return edp_.call(c).joints;  // answered IN_PROGRESS while the axes search their switches
    } catch (const edp::Refused& e) {
      throw JogRefused(e.what());
    }
  }

 private:
  /// One SET ARM RELATIVE macro-step from rest to rest; the joints at its end.
  std::vector<double> move_relative(edp::ArmRepresentation representation,
                                    const std::vector<double>& delta, int motion_steps) {
    edp::Instruction c;
    c.type = edp::InstructionType::set;
    c.set = edp::item::arm;
    c.set_arm_type = representation;
    c.motion_type = edp::MotionType::relative;
    c.motion_steps = motion_steps;
    c.value_in_step_no = motion_steps + 1;
    c.arm = delta;
    c.with_query = true;  // the reply carries the joints at the end of the macro-step
    try {
      // The console drives the EDP only after an explicit take-over, which the EDP accepts only
      // while the robot is at rest (the jog checked that the MP is idle).
      edp_.take_over_next();
      return edp_.call(c).joints;
    } catch (const edp::Refused& e) {
      throw JogRefused(e.what());
    }
  }

  edp::Client edp_;
};

}  // namespace

std::unique_ptr<JogLink> make_edp_jog_link(comm::Bus& bus, const std::string& robot) {
  edp::ClientOptions options;
  options.attempt_timeout = std::chrono::milliseconds(250);
  options.max_attempts = 8;
  return std::make_unique<EdpJogLink>(bus, robot, options);
}

}  // namespace mrroc::ui
