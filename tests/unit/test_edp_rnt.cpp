// The EDP on the RNT (6 axes, parallelogram transmission, KDL kinematics) with the real MuJoCo
// plugin: synchronisation, Cartesian moves over the engraving board, the coupled q1 + q2 limit,
// kinematic models.
#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <thread>

#include "command_interpreter.hpp"
#include "edp_parts.hpp"
#include "mrroc/edp/arm_kinematics.hpp"
#include "mrroc/edp/hardware.hpp"
#include "mrroc/kinematics/pose.hpp"
#include "mrroc/robot/robot_model.hpp"
#include "servo_loop.hpp"

using namespace mrroc;
using namespace mrroc::edp;

namespace {

constexpr double kPeriod = 0.002;

class RntEdpTest : public ::testing::Test {
 protected:
  void SetUp() override {
    model_ = test::stock_model("rnt");
    hardware_ = test::configured_hardware(model_, "mujoco", kPeriod);
    kinematics_ = make_arm_kinematics(model_);
    servo_ = std::make_unique<ServoLoop>(*hardware_, model_, kPeriod);
    servo_->set_limit_guard(kinematics_.get());
    servo_->start();
    interpreter_ = std::make_unique<CommandInterpreter>(*servo_, model_, *kinematics_, kPeriod);
    Instruction s;
    s.type = InstructionType::synchro;
    ASSERT_EQ(interpreter_->execute(s).type, ReplyType::acknowledge);
    ASSERT_EQ(query().type, ReplyType::data);
  }
  void TearDown() override { servo_->stop(); }

  Reply query() {
    Instruction q;
    q.type = InstructionType::query;
    return interpreter_->execute(q);
  }
  Reply move(ArmRepresentation type, std::vector<double> arm, int steps = 200) {
    Instruction in;
    in.type = InstructionType::set;
    in.set = item::arm;
    in.set_arm_type = type;
    in.motion_steps = steps;
    in.value_in_step_no = steps + 1;
    in.arm = std::move(arm);
    const Reply accepted = interpreter_->execute(in);
    if (accepted.type == ReplyType::error) return accepted;
    return query();
  }
  Eigen::Isometry3d tool_frame() {
    Instruction get;
    get.type = InstructionType::get;
    get.get = item::arm;
    get.get_arm_type = ArmRepresentation::frame;
    EXPECT_EQ(interpreter_->execute(get).type, ReplyType::acknowledge);
    const Reply r = query();
    EXPECT_EQ(r.type, ReplyType::data) << r.error_text;
    return kinematics::from_vector(r.arm, ArmRepresentation::frame);
  }

  RobotModel model_;
  std::unique_ptr<Hardware> hardware_;
  std::unique_ptr<ServoLoop> servo_;
  std::unique_ptr<ArmKinematics> kinematics_;
  std::unique_ptr<CommandInterpreter> interpreter_;
};

}  // namespace

TEST_F(RntEdpTest, CartesianMovesOverTheBoard) {
  EXPECT_EQ(kinematics_->name(), "rnt");
  // Cutter 0.15 m along the flange z axis, pointing down; visit the board's corners
  // (board centred at (0.60, 0, 0.20), 0.30 x 0.40 m) 2 cm above its surface.
  Instruction tool;
  tool.type = InstructionType::set;
  tool.set = item::tool;
  tool.tool_type = ArmRepresentation::xyz_angle_axis;
  tool.tool = {0, 0, 0.15, 0, 0, 0};
  ASSERT_EQ(interpreter_->execute(tool).type, ReplyType::acknowledge);
  ASSERT_EQ(query().type, ReplyType::data);
  const Eigen::Matrix3d down = tool_frame().linear();
  for (const auto& [x, y] : std::vector<std::pair<double, double>>{
           {0.45, -0.2}, {0.75, -0.2}, {0.75, 0.2}, {0.45, 0.2}}) {
    Eigen::Isometry3d goal = Eigen::Isometry3d::Identity();
    goal.linear() = down;
    goal.translation() = Eigen::Vector3d(x, y, 0.22);
    // In the fewest steps the joints' velocity and acceleration limits allow from rest to rest
    // to the joints the EDP will solve for, with a margin for their rounding.
    const std::vector<double> from = servo_->planned_end();
    const int steps =
        test::rest_to_rest_steps(model_, from, kinematics_->inverse(goal, from), kPeriod) + 5;
    const Reply r = move(ArmRepresentation::frame,
                         kinematics::to_vector(goal, ArmRepresentation::frame), steps);
    ASSERT_EQ(r.type, ReplyType::data)
        << "corner (" << x << ", " << y << ") in " << steps << " steps: " << r.error_text;
    std::this_thread::sleep_for(std::chrono::milliseconds(200));
    const Eigen::Isometry3d reached = tool_frame();
    EXPECT_LT((reached.translation() - goal.translation()).norm(), 1e-3)
        << "corner (" << x << ", " << y << ")";
  }
}

TEST_F(RntEdpTest, ParallelogramLimitIsRefused) {
  // Each joint inside its own range, but q1 + q2 = 1.35 + 0.6 rad leaves the parallelogram's
  // range (elbow motor limit).
  const Reply r = move(ArmRepresentation::joint, {0.0, 1.35, 0.6, 1.5707963, 0.0, 0.0});
  EXPECT_EQ(r.type, ReplyType::error);
  EXPECT_EQ(r.error_code, error_code::out_of_limits) << r.error_text;
  std::printf("refused: %s\n", r.error_text.c_str());
}

TEST_F(RntEdpTest, TwoKinematicModels) {
  EXPECT_EQ(kinematics_->model_count(), 2);
  const std::vector<double> q = {0.1, 0.3, -0.2, 1.4, 0.1, 0.2};
  const Eigen::Vector3d nominal = kinematics_->forward(q).translation();
  kinematics_->select_model(1, 0);
  const Eigen::Vector3d calibrated = kinematics_->forward(q).translation();
  const double difference = (nominal - calibrated).norm();
  EXPECT_GT(difference, 5e-4);
  EXPECT_LT(difference, 1e-2);
  std::printf("calibrated model moves the flange by %.2f mm at this pose\n", difference * 1e3);
  // Motor <-> joint through the parallelogram: the elbow motor follows q1 + q2.
  const auto m = kinematics_->motors_from_joints(q);
  const auto back = kinematics_->joints_from_motors(m);
  for (std::size_t j = 0; j < q.size(); ++j) EXPECT_NEAR(back[j], q[j], 1e-12);
}
