// The clients named for the process they call: edp::Client (take-over when due, refusals and
// timeouts) and vsp::Client (replies, refusals, silence), each against a server of its link over
// LCM (in-process memq:// transport unless MRROC_TEST_LCM_URL says otherwise).
#include <gtest/gtest.h>

#include <chrono>
#include <cstdlib>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "mrroc/comm/bus.hpp"
#include "mrroc/comm/links.hpp"
#include "mrroc/config/process_set.hpp"
#include "mrroc/ecp/robot_image.hpp"
#include "mrroc/ecp/virtual_sensor.hpp"
#include "mrroc/edp/client.hpp"
#include "mrroc/vsp/client.hpp"

using namespace mrroc;
using namespace std::chrono_literals;

namespace {

std::string test_url() {
  const char* url = std::getenv("MRROC_TEST_LCM_URL");
  return url != nullptr && *url != '\0' ? url : "memq://";
}

/// An EDP's end of the link: records every instruction, answers DATA, or the error set in
/// `refuse` (code, text) once.
struct FakeEdp {
  std::mutex mutex;
  std::vector<edp::Instruction> received;
  int refuse_code = 0;
  std::string refuse_text;
  std::unique_ptr<comm::EdpServer> server;

  FakeEdp(comm::Bus& bus, const std::string& robot) {
    server = std::make_unique<comm::EdpServer>(bus, "edp/" + robot, channels::edp_command(robot),
                                               channels::edp_reply(robot),
                                               [this](comm::EdpServer::Incoming in) {
                                                 if (!in.request) return;
                                                 edp::Reply reply;
                                                 reply.type = edp::ReplyType::data;
                                                 reply.joints = {0.25};
                                                 {
                                                   std::lock_guard lock(mutex);
                                                   received.push_back(*in.request);
                                                   if (refuse_code != 0) {
                                                     reply.type = edp::ReplyType::error;
                                                     reply.error_code = refuse_code;
                                                     reply.error_text = refuse_text;
                                                     refuse_code = 0;
                                                   }
                                                 }
                                                 in.responder.reply(reply);
                                               });
  }
  edp::Instruction last() {
    std::lock_guard lock(mutex);
    return received.back();
  }
  void refuse_next(int code, const std::string& text) {
    std::lock_guard lock(mutex);
    refuse_code = code;
    refuse_text = text;
  }
};

edp::Instruction instruction(edp::InstructionType type) {
  edp::Instruction i;
  i.type = type;
  if (type == edp::InstructionType::get) {
    i.get = edp::item::arm;
    i.get_arm_type = edp::ArmRepresentation::joint;
  }
  return i;
}

/// A VSP's end of the link: acknowledges, answers GET_READING with `reading`, refuses CONFIGURE
/// with arguments "bad = 1".
struct FakeVsp {
  std::mutex mutex;
  vsp::Reading reading;
  std::unique_ptr<comm::VspServer> server;

  FakeVsp(comm::Bus& bus, const std::string& name) {
    server = std::make_unique<comm::VspServer>(
        bus, "vsp/" + name, channels::vsp_command(name), channels::vsp_reply(name),
        [this](comm::VspServer::Incoming in) {
          if (!in.request) return;
          vsp::Reply reply;
          if (in.request->command == vsp::Command::configure &&
              in.request->arguments == "bad = 1") {
            reply.kind = vsp::ReplyKind::error;
            reply.error_code = vsp::error_code::bad_argument;
            reply.error_text = "unknown argument 'bad'";
          } else if (in.request->command == vsp::Command::get_reading) {
            reply.kind = vsp::ReplyKind::reading;
            std::lock_guard lock(mutex);
            reply.reading = reading;
          }
          in.responder.reply(reply);
        });
  }
};

}  // namespace

TEST(EdpClient, TakesTheEdpOverWithItsFirstInstructionAndWhenAsked) {
  comm::Bus bus(test_url());
  FakeEdp fake(bus, "arm");
  edp::Client client(bus, "test", "arm", edp::ClientOptions{50ms, 4});
  bus.start();
  EXPECT_EQ(client.robot(), "arm");
  EXPECT_TRUE(client.take_over_due());

  const edp::Reply first = client.call(instruction(edp::InstructionType::get));
  EXPECT_EQ(first.joints, std::vector<double>{0.25});
  EXPECT_TRUE(fake.last().take_over);
  EXPECT_FALSE(client.take_over_due());

  (void)client.call(instruction(edp::InstructionType::get));
  EXPECT_FALSE(fake.last().take_over);

  // A QUERY never takes over (a take-over forgets the QUERY that is due).
  client.take_over_next();
  (void)client.call(instruction(edp::InstructionType::query));
  EXPECT_FALSE(fake.last().take_over);
  client.take_over_next();
  (void)client.call(instruction(edp::InstructionType::get));
  EXPECT_TRUE(fake.last().take_over);
}

TEST(EdpClient, ARefusalNamesTheRobotAndTheInstructionAndKeepsTheEdpsCode) {
  comm::Bus bus(test_url());
  FakeEdp fake(bus, "arm");
  edp::Client client(bus, "test", "arm", edp::ClientOptions{50ms, 4});
  bus.start();
  (void)client.call(instruction(edp::InstructionType::get));

  fake.refuse_next(edp::error_code::not_owner, "owned by ui/jog/arm#7");
  client.take_over_next();
  try {
    (void)client.call(instruction(edp::InstructionType::get));
    FAIL() << "a refusal did not throw";
  } catch (const ecp::EdpRefused& e) {  // the task API's name for the same error
    EXPECT_EQ(e.code(), edp::error_code::not_owner);
    EXPECT_NE(std::string(e.what()).find("EDP arm refused GET"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("owned by ui/jog/arm#7"), std::string::npos) << e.what();
  }
  // Refused for not being the owner: the take-over is still due.
  EXPECT_TRUE(client.take_over_due());

  fake.refuse_next(3, "beyond the joint limit");
  EXPECT_THROW((void)client.call(instruction(edp::InstructionType::get)), edp::Refused);
  EXPECT_FALSE(client.take_over_due());
}

TEST(EdpClient, ATimeoutMakesTheNextInstructionTakeTheEdpOver) {
  comm::Bus bus(test_url());
  auto fake = std::make_unique<FakeEdp>(bus, "arm");
  edp::Client client(bus, "test", "arm", edp::ClientOptions{20ms, 3});
  bus.start();
  (void)client.call(instruction(edp::InstructionType::get));
  ASSERT_FALSE(client.take_over_due());

  fake.reset();  // the EDP is gone
  EXPECT_THROW((void)client.call(instruction(edp::InstructionType::get)), TimeoutError);
  EXPECT_TRUE(client.take_over_due());

  FakeEdp back(bus, "arm");
  (void)client.call(instruction(edp::InstructionType::get));
  EXPECT_TRUE(back.last().take_over);
}

TEST(VspClient, ReadsConfiguresAndNamesTheVspInEveryFailure) {
  comm::Bus bus(test_url());
  FakeVsp wrist(bus, "wrist");
  {
    std::lock_guard lock(wrist.mutex);
    wrist.reading.valid = false;
    wrist.reading.invalid_reason = "source gauges stale for 120 ms";
  }
  vsp::Client client(bus, "wrist", "test");
  bus.start();
  EXPECT_EQ(client.name(), "wrist");

  client.configure("zero = true");
  client.initiate_reading("roll = 0.5");
  const vsp::Reading stale = client.get_reading();
  EXPECT_FALSE(stale.valid);
  EXPECT_EQ(stale.invalid_reason, "VSP 'wrist': source gauges stale for 120 ms");

  {
    std::lock_guard lock(wrist.mutex);
    wrist.reading.valid = true;
    wrist.reading.invalid_reason.clear();
    wrist.reading.values = {1.5};
    wrist.reading.names = {"fz"};
  }
  const vsp::Reading fresh = client.get_reading();
  ASSERT_TRUE(fresh.valid);
  EXPECT_DOUBLE_EQ(fresh.value("fz"), 1.5);

  try {
    client.configure("bad = 1");
    FAIL() << "a refused CONFIGURE did not throw";
  } catch (const vsp::Refused& e) {
    EXPECT_EQ(e.code(), vsp::error_code::bad_argument);
    EXPECT_EQ(e.reason(), "unknown argument 'bad'");
    EXPECT_EQ(std::string(e.what()), "VSP 'wrist' refused CONFIGURE: unknown argument 'bad'");
  }

  vsp::Client absent(bus, "elbow", "test", vsp::ClientOptions{10ms, 2});
  try {
    (void)absent.get_reading();
    FAIL() << "a VSP that does not answer did not throw";
  } catch (const vsp::NoAnswer& e) {
    EXPECT_NE(std::string(e.what()).find("VSP 'elbow' did not answer GET_READING"),
              std::string::npos)
        << e.what();
  }

  // The task's sensor image names the VSP once in the reason it is invalid.
  ecp::VirtualSensor elbow(bus, "elbow", "test", vsp::ClientOptions{10ms, 2});
  elbow.initiate_reading();
  const std::string reason = elbow.image().invalid_reason;
  EXPECT_EQ(reason.rfind("VSP 'elbow' did not answer INITIATE_READING", 0), 0u) << reason;
  EXPECT_EQ(reason.find("VSP 'elbow'", 1), std::string::npos) << reason;
  elbow.get_reading();
  EXPECT_EQ(elbow.image().invalid_reason.rfind("VSP 'elbow' did not answer GET_READING", 0), 0u)
      << elbow.image().invalid_reason;
}
