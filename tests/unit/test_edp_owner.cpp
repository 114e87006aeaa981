// One owner per EDP (docs/edp.md, "One owner at a time"): the command interpreter obeys one
// client; another takes over only while the robot is at rest (explicitly, or after the owner's
// silence), a change of owner forgets the QUERY due to the old one, so a client that died
// between SET and QUERY leaves an EDP the next client can use.
#include <gtest/gtest.h>

#include <chrono>
#include <thread>

#include "command_interpreter.hpp"
#include "edp_parts.hpp"
#include "servo_loop.hpp"

using namespace mrroc;
using namespace mrroc::edp;

namespace {

constexpr double kPeriod = 0.002;

class Owner : public ::testing::Test {
 protected:
  void SetUp() override {
    model_ = test::stock_model("irb6");
    hardware_ = test::configured_hardware(model_, "mock", kPeriod);
    kinematics_ = make_arm_kinematics(model_);
    servo_ = std::make_unique<ServoLoop>(*hardware_, model_, kPeriod);
    servo_->set_limit_guard(kinematics_.get());
    servo_->start();
    interpreter_ = std::make_unique<CommandInterpreter>(*servo_, model_, *kinematics_, kPeriod);
    interpreter_->set_owner_lease(0.3);
    Instruction s;
    s.type = InstructionType::synchro;
    s.with_query = true;
    ASSERT_EQ(interpreter_->execute(s, "ecp#1").type, ReplyType::data);
    wait_at_rest();  // the approach's last step still moved the setpoint
  }
  void TearDown() override { servo_->stop(); }

  Reply get(const std::string& client, bool take_over = false) {
    Instruction g;
    g.type = InstructionType::get;
    g.get = item::arm;
    g.get_arm_type = ArmRepresentation::joint;
    g.with_query = true;
    g.take_over = take_over;
    return interpreter_->execute(g, client);
  }
  /// A slow move of the column (rest to rest, well within its limits), SET without its QUERY.
  Reply set_move(const std::string& client, double to, bool take_over = false) {
    std::vector<double> q = model_.synchro_joint_positions;
    q[0] = to;
    Instruction in = test::set_joints_instruction(q, 1000, 1001);
    in.take_over = take_over;
    return interpreter_->execute(in, client);
  }
  void wait_at_rest() {
    for (int i = 0; i < 400 && !servo_->stopped(); ++i)
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
    ASSERT_TRUE(servo_->stopped());
  }

  RobotModel model_;
  std::unique_ptr<Hardware> hardware_;
  std::unique_ptr<ArmKinematics> kinematics_;
  std::unique_ptr<ServoLoop> servo_;
  std::unique_ptr<CommandInterpreter> interpreter_;
};

}  // namespace

TEST_F(Owner, TheFirstClientOwnsAndOthersAreRefusedWhileItDrives) {
  EXPECT_EQ(interpreter_->owner(), "ecp#1");
  ASSERT_EQ(set_move("ecp#1", 0.1).type, ReplyType::acknowledge);
  // While the robot moves nobody else is obeyed, take-over or not.
  for (const bool take_over : {false, true}) {
    const Reply r = get("ui/jog#2", take_over);
    ASSERT_EQ(r.type, ReplyType::error);
    EXPECT_EQ(r.error_code, error_code::not_owner);
    EXPECT_NE(r.error_text.find("driven by 'ecp#1'"), std::string::npos) << r.error_text;
    EXPECT_NE(r.error_text.find("the robot is moving"), std::string::npos) << r.error_text;
  }
  EXPECT_EQ(interpreter_->owner(), "ecp#1");
  // The owner's QUERY is still due to it, and answered.
  Instruction q;
  q.type = InstructionType::query;
  const Reply reading = interpreter_->execute(q, "ecp#1");
  ASSERT_EQ(reading.type, ReplyType::data) << reading.error_text;
  EXPECT_NEAR(reading.desired_joints[0], 0.1, 1e-12);
}

TEST_F(Owner, AClientKilledBetweenSetAndQueryLeavesAnEdpTheNextClientCanUse) {
  ASSERT_EQ(set_move("ecp#1", 0.1).type, ReplyType::acknowledge);
  // ecp#1 dies here: its QUERY never comes. Before, every other instruction got "query
  // expected" until the EDP restarted.
  wait_at_rest();
  const Reply r = get("ecp#3", /*take_over=*/true);  // the next task's ECP
  ASSERT_EQ(r.type, ReplyType::data) << r.error_text;
  EXPECT_EQ(interpreter_->owner(), "ecp#3");
  EXPECT_TRUE(interpreter_->owner_changed());
  EXPECT_NEAR(r.joints[0], 0.1, 1e-6);
  ASSERT_EQ(set_move("ecp#3", 0.0).type, ReplyType::acknowledge);
  // The old owner, should it come back, is refused.
  const Reply old = get("ecp#1");
  EXPECT_EQ(old.error_code, error_code::not_owner) << old.error_text;
}

TEST_F(Owner, WithoutTakeOverAnotherClientWaitsForTheOwnersSilence) {
  ASSERT_EQ(get("ecp#1").type, ReplyType::data);
  const Reply early = get("ecp#4");
  ASSERT_EQ(early.type, ReplyType::error);
  EXPECT_EQ(early.error_code, error_code::not_owner);
  EXPECT_NE(early.error_text.find("silent for 0.3 s"), std::string::npos) << early.error_text;
  std::this_thread::sleep_for(std::chrono::milliseconds(350));
  const Reply later = get("ecp#4");
  ASSERT_EQ(later.type, ReplyType::data) << later.error_text;
  EXPECT_EQ(interpreter_->owner(), "ecp#4");
}

TEST_F(Owner, TheOwnerItselfRecoversFromATimeoutWithTakeOver) {
  ASSERT_EQ(set_move("ecp#1", 0.05).type, ReplyType::acknowledge);
  wait_at_rest();
  // Without take_over the paper's rule holds: a QUERY is due.
  EXPECT_EQ(get("ecp#1").error_code, error_code::query_expected);
  // edp::Client (under ecp::Robot) sends take_over after a timeout: the due QUERY is forgotten.
  const Reply r = get("ecp#1", /*take_over=*/true);
  ASSERT_EQ(r.type, ReplyType::data) << r.error_text;
  EXPECT_NEAR(r.joints[0], 0.05, 1e-6);
}
