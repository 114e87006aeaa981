// A robot class derived from ecp::Robot with a device (the example ecp::Gripper,
// ecp/tasks/gripper.hpp) against an EDP's end of the link over LCM (in-process memq:// unless
// MRROC_TEST_LCM_URL says otherwise): its command fields go out in the device part of every SET
// DEVICE, the reply's device part comes back into its own fields and the robot image, a reply
// that does not fit is an error naming the robot; the ECP shell makes a task's robot the class
// the task was registered with, and robot_as names both classes when it is not.
#include <gtest/gtest.h>

#include <cstdlib>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "mrroc/comm/bus.hpp"
#include "mrroc/comm/links.hpp"
#include "mrroc/comm/reporter.hpp"
#include "mrroc/config/process_set.hpp"
#include "mrroc/ecp/task.hpp"
#include "mrroc/robot/robot_model.hpp"
#include "tasks/gripper.hpp"

using namespace mrroc;

namespace {

std::string test_url() {
  const char* url = std::getenv("MRROC_TEST_LCM_URL");
  return url != nullptr && *url != '\0' ? url : "memq://";
}

RobotModel irb6() {
  return load_robot_model(std::filesystem::path(MRROC_SOURCE_DIR) / "robots/irb6");
}

/// An EDP's end of the link: records every instruction and answers DATA with `device` as the
/// device part of a GET DEVICE.
struct DeviceEdp {
  std::mutex mutex;
  std::vector<edp::Instruction> received;
  std::vector<double> device;
  std::unique_ptr<comm::EdpServer> server;

  DeviceEdp(comm::Bus& bus, const std::string& robot) {
    server = std::make_unique<comm::EdpServer>(bus, "edp/" + robot, channels::edp_command(robot),
                                               channels::edp_reply(robot),
                                               [this](comm::EdpServer::Incoming in) {
                                                 if (!in.request) return;
                                                 edp::Reply reply;
                                                 reply.type = edp::ReplyType::data;
                                                 reply.joints = {0, -1.5708, 0, 0, 0};
                                                 {
                                                   std::lock_guard lock(mutex);
                                                   received.push_back(*in.request);
                                                   if ((in.request->get & edp::item::device) != 0)
                                                     reply.device = device;
                                                 }
                                                 in.responder.reply(reply);
                                               });
  }
};

TEST(DeviceRobot, CommandFieldsGoOutAndReplyFieldsComeBack) {
  comm::Bus bus(test_url());
  bus.start();
  DeviceEdp edp(bus, "irb6");
  edp.device = {0.0398, 0.0, 19.9, 1.0};  // opening, speed, force, holding: stopped on a part
  ecp::Gripper gripper(bus, "ecp/irb6", "irb6", irb6());
  gripper.close(20.0);
  {
    std::lock_guard lock(edp.mutex);
    ASSERT_FALSE(edp.received.empty());
    const edp::Instruction& set = edp.received.front();
    EXPECT_EQ(set.type, edp::InstructionType::set_get);
    EXPECT_EQ(set.set, edp::item::device);
    EXPECT_EQ(set.device, (std::vector<double>{0.0, 20.0}));
    // Then GET DEVICE until the fingers stood still.
    EXPECT_GT(edp.received.size(), 5U);
    EXPECT_TRUE(edp.received.back().device.empty());
  }
  EXPECT_DOUBLE_EQ(gripper.width(), 0.0398);
  EXPECT_DOUBLE_EQ(gripper.force(), 19.9);
  EXPECT_TRUE(gripper.holding());
  ASSERT_TRUE(gripper.image().device.has_value());
  EXPECT_EQ(*gripper.image().device, edp.device);

  // A reply of another device is an error naming the robot.
  edp.device = {0.1, 0.2};
  try {
    gripper.read_device();
    ADD_FAILURE() << "a two-field reply was accepted";
  } catch (const Error& e) {
    EXPECT_STREQ(e.what(),
                 "robot 'irb6': the EDP's device replied 2 fields, a gripper has 4 (opening, "
                 "speed, force, holding): is its plugin's device a gripper?");
  }
  bus.stop();
}

TEST(DeviceRobot, TheShellMakesTheRobotClassItsTaskNames) {
  comm::Bus bus(test_url());
  bus.start();
  const std::unique_ptr<ecp::Robot> gripper =
      ecp::make_task_robot("grasp_part", bus, "ecp/irb6", "irb6", irb6());
  EXPECT_NE(dynamic_cast<ecp::Gripper*>(gripper.get()), nullptr);
  const std::unique_ptr<ecp::Robot> plain =
      ecp::make_task_robot("visit_joint_poses", bus, "ecp/irb6", "irb6", irb6());
  EXPECT_EQ(dynamic_cast<ecp::Gripper*>(plain.get()), nullptr);

  Reporter reporter(bus, "ecp/irb6", "irb6");
  const Params args;
  ecp::TaskContext context{*plain, reporter, args, 0.002, &bus, "ecp/irb6", nullptr};
  try {
    (void)context.robot_as<ecp::Gripper>();
    ADD_FAILURE() << "a plain robot passed for a gripper";
  } catch (const Error& e) {
    EXPECT_STREQ(e.what(),
                 "this task needs robot 'irb6' to be a mrroc::ecp::Gripper, the ECP's configured "
                 "task ([robot.ecp] task) drives a mrroc::ecp::Robot (a task names its robot "
                 "class with MRROC_REGISTER_ECP_TASK_WITH_ROBOT)");
  }
  bus.stop();
}

}  // namespace
