// The `mujoco` plugin's gripper device (robots/irb6/irb6_gripper.xml) through the EDP (servo loop
// and command interpreter, lock-step): the plugin declares the fingers as a device, not as arm
// axes; SET DEVICE closes them on the part, GET DEVICE measures the opening, grip force and
// holding from the physics, and the part rises with the arm when lifted. Closing on nothing is
// not holding; a force above the actuators' limit is refused naming value, unit and limit. The
// servo thread does not allocate while it drives the gripper.
#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <thread>

#include <mujoco/mujoco.h>

#include "command_interpreter.hpp"
#include "edp_parts.hpp"
#include "mrroc/edp/arm_kinematics.hpp"
#include "mrroc/edp/hardware.hpp"
#include "plugins/mujoco_hardware.hpp"
#include "servo_loop.hpp"

// The servo cycle, device calls included, must not allocate.
#include "heap_counter.hpp"

using namespace mrroc;
using namespace mrroc::edp;

namespace {

constexpr double kPeriod = 0.002;
constexpr double kPartWidth = 0.04;  // across the fingers [m]
// Joint poses with the flange pointing down at x = 0.80 m: z = 0.79 m (above the part), 0.69 m
// (the part between the pads), 0.84 m (lifted 0.15 m), as in configs/gripper-irb6.toml.
const std::vector<double> kAbove = {0.0, -1.241505, -0.102649, 1.344154, 0.0};
const std::vector<double> kGrasp = {0.0, -1.177113, -0.027025, 1.204138, 0.0};
const std::vector<double> kLift = {0.0, -1.262529, -0.153090, 1.415620, 0.0};

class GripperEdp {
 public:
  GripperEdp() {
    model_ = test::stock_model("irb6");
    Params params;
    params.set("mjcf", std::string("irb6_gripper.xml"), {});
    hardware_ = test::configured_hardware(model_, "mujoco", kPeriod, std::move(params));
    kinematics_ = make_arm_kinematics(model_);
    servo_ = std::make_unique<ServoLoop>(*hardware_, model_, kPeriod);
    servo_->set_limit_guard(kinematics_.get());
    servo_->set_lock_step(true);
    servo_->start();
    interpreter_ = std::make_unique<CommandInterpreter>(*servo_, model_, *kinematics_, kPeriod);
  }
  ~GripperEdp() { servo_->stop(); }

  Reply exec(Instruction in) {
    in.with_query = true;
    return interpreter_->execute(in);
  }
  void synchronise() {
    Instruction s;
    s.type = InstructionType::synchro;
    ASSERT_EQ(exec(s).type, ReplyType::data);
  }
  void move_to(const std::vector<double>& q) {
    const int steps = test::rest_to_rest_steps(model_, servo_->planned_end(), q, kPeriod, 0.5);
    const Reply r = exec(test::set_joints_instruction(q, steps, steps + 1));
    ASSERT_EQ(r.type, ReplyType::data) << r.error_text;
  }
  Reply grip(double opening, double force) {
    Instruction in;
    in.type = InstructionType::set_get;
    in.set = item::device;
    in.get = item::device;
    in.device = {opening, force};
    return exec(in);
  }
  /// GET DEVICE until the fingers have stopped (5 readings 10 ms apart below 2 mm/s).
  Reply settled() {
    Instruction get;
    get.type = InstructionType::get;
    get.get = item::device;
    Reply r;
    int still = 0;
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(5);
    for (int k = 0; still < 5 && std::chrono::steady_clock::now() < deadline; ++k) {
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
      r = exec(get);
      if (r.type != ReplyType::data) return r;
      still = k > 3 && std::abs(r.device[1]) < MujocoHardware::kStoppedSpeed ? still + 1 : 0;
    }
    return r;
  }
  /// Height of the part [m] (read with the servo loop stopped).
  double part_z() {
    servo_->stop();
    const auto& sim = dynamic_cast<const MujocoHardware&>(*hardware_);
    const int joint = mj_name2id(sim.model(), mjOBJ_JOINT, "part_z");
    const int body = mj_name2id(sim.model(), mjOBJ_BODY, "part");
    return sim.model()->body_pos[3 * body + 2] + sim.data()->qpos[sim.model()->jnt_qposadr[joint]];
  }

  RobotModel model_;
  std::unique_ptr<Hardware> hardware_;
  std::unique_ptr<ArmKinematics> kinematics_;
  std::unique_ptr<ServoLoop> servo_;
  std::unique_ptr<CommandInterpreter> interpreter_;
};

TEST(MujocoGripper, TheFingersAreADeviceNotArmAxes) {
  GripperEdp edp;
  EXPECT_EQ(edp.hardware_->axis_count(), 5U);
  const DeviceDescription d = edp.hardware_->device();
  EXPECT_EQ(d.name, "gripper");
  ASSERT_EQ(d.command.size(), 2U);
  EXPECT_EQ(d.command[0].name, "opening");
  EXPECT_DOUBLE_EQ(d.command[0].max, 0.08);
  EXPECT_EQ(d.command[1].unit, "N");
  EXPECT_DOUBLE_EQ(d.command[1].max, 60.0);
  ASSERT_EQ(d.reply.size(), 4U);
  EXPECT_EQ(d.reply[3].name, "holding");
  // The stock irb6.xml has no gripper.
  const RobotModel model = test::stock_model("irb6");
  EXPECT_TRUE(test::configured_hardware(model, "mujoco", kPeriod)->device().name.empty());
}

TEST(MujocoGripper, ClosesOnThePartAndLiftsIt) {
  GripperEdp edp;
  // Open at power-on, before SYNCHRO.
  Reply r = edp.settled();
  ASSERT_EQ(r.type, ReplyType::data) << r.error_text;
  EXPECT_NEAR(r.device[0], 0.08, 1e-4);
  EXPECT_EQ(r.device[3], 0.0);
  edp.synchronise();
  edp.move_to(kAbove);
  edp.move_to(kGrasp);
  g_heap.allocations = 0;
  g_heap.watched = edp.servo_->servo_thread_id();
  r = edp.grip(0.0, 20.0);
  ASSERT_EQ(r.type, ReplyType::data) << r.error_text;
  r = edp.settled();
  EXPECT_NEAR(r.device[0], kPartWidth, 1e-3);  // stopped on the part, not closed
  EXPECT_NEAR(r.device[2], 20.0, 2.0);         // each finger pushes with its force limit
  EXPECT_EQ(r.device[3], 1.0);
  const double z_on_table = 0.61;
  edp.move_to(kLift);
  r = edp.settled();
  EXPECT_EQ(r.device[3], 1.0) << "the part slipped out";
  EXPECT_NEAR(r.device[0], kPartWidth, 1e-3);
  g_heap.watched = std::thread::id{};
  EXPECT_EQ(g_heap.allocations.load(), 0) << "the servo thread allocated";
  // The lift raises the flange by 0.15 m; the part follows within the pads' slip.
  const double z = edp.part_z();
  EXPECT_NEAR(z - z_on_table, 0.15, 0.005);
  std::printf("holding at %.5f m with %.2f N; the part rose %.4f m\n", r.device[0], r.device[2],
              z - z_on_table);
}

TEST(MujocoGripper, ClosingOnNothingIsNotHoldingAndTooMuchForceIsRefused) {
  GripperEdp edp;
  Reply r = edp.grip(0.0, 75.0);
  EXPECT_EQ(r.error_code, error_code::out_of_limits);
  EXPECT_EQ(r.error_text,
            "SET DEVICE gripper field 1 (force) 75 N exceeds its upper limit of 60 N");
  r = edp.grip(0.09, 10.0);
  EXPECT_EQ(r.error_text,
            "SET DEVICE gripper field 0 (opening) 0.09 m exceeds its upper limit of 0.08 m");
  r = edp.grip(0.0, 10.0);
  ASSERT_EQ(r.type, ReplyType::data) << r.error_text;
  r = edp.settled();
  EXPECT_NEAR(r.device[0], 0.0, 1e-3);
  EXPECT_EQ(r.device[2], 0.0);  // no contact outside the robot
  EXPECT_EQ(r.device[3], 0.0);
}

}  // namespace
