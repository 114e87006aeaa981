// Message round trips: plain values -> LCM type -> bytes -> LCM type -> plain values, and
// malformed messages rejected with the field named.
#include <gtest/gtest.h>

#include "mrroc/comm/codec.hpp"
#include "through_bytes.hpp"

using namespace mrroc;
using test::through_bytes;

TEST(Messages, EdpInstructionRoundTrip) {
  edp::Instruction in;
  in.type = edp::InstructionType::set_get;
  in.set = edp::item::arm | edp::item::tool | edp::item::outputs | edp::item::device;
  in.get = edp::item::arm | edp::item::inputs | edp::item::device;
  in.set_arm_type = edp::ArmRepresentation::xyz_euler_zyz;
  in.get_arm_type = edp::ArmRepresentation::motor;
  in.motion_type = edp::MotionType::relative;
  in.motion_steps = 25;
  in.value_in_step_no = 24;
  in.arm = {0.1, 0.2, 0.3, -1.0, 0.5, 2.0};
  in.tool_type = edp::ArmRepresentation::xyz_angle_axis;
  in.tool = {0, 0, 0.25, 0, 0, 0};
  in.kinematic_model_no = 1;
  in.corrector_no = 2;
  in.servo_algorithm = {1, 2, 1, 1, 0};
  in.servo_parameters_no = {0, 1, 0, 3, 0};
  in.output_values = 0xA5;
  in.device = {0.02, 15.0};
  const edp::Instruction out = comm::decode(through_bytes(comm::encode(in)));
  EXPECT_EQ(out.type, in.type);
  EXPECT_EQ(out.set, in.set);
  EXPECT_EQ(out.get, in.get);
  EXPECT_EQ(out.set_arm_type, in.set_arm_type);
  EXPECT_EQ(out.get_arm_type, in.get_arm_type);
  EXPECT_EQ(out.motion_type, in.motion_type);
  EXPECT_EQ(out.motion_steps, in.motion_steps);
  EXPECT_EQ(out.value_in_step_no, in.value_in_step_no);
  EXPECT_EQ(out.arm, in.arm);
  EXPECT_EQ(out.tool_type, in.tool_type);
  EXPECT_EQ(out.tool, in.tool);
  EXPECT_EQ(out.kinematic_model_no, 1);
  EXPECT_EQ(out.corrector_no, 2);
  EXPECT_EQ(out.servo_algorithm, in.servo_algorithm);
  EXPECT_EQ(out.servo_parameters_no, in.servo_parameters_no);
  EXPECT_EQ(out.output_values, 0xA5U);
  EXPECT_EQ(out.device, in.device);
}

TEST(Messages, EdpReplyRoundTrip) {
  edp::Reply in;
  in.type = edp::ReplyType::data;
  in.synchronised = true;
  in.step_no = 9;
  in.servo_cycle = 123456789;
  in.arm_type = edp::ArmRepresentation::frame;
  in.arm = {1, 0, 0, 0.5, 0, 1, 0, 0.1, 0, 0, 1, 0.9};
  in.joints = {0.1, -1.5, 0.2, 0.3, 0.4};
  in.desired_joints = {0.11, -1.51, 0.21, 0.31, 0.41};
  in.joint_velocities = {0, 0.1, 0, 0, -0.1};
  in.input_values = 7;
  in.device = {0.04, 0.0, 12.5, 1.0};
  in.servo_cycles = 1000;
  in.servo_overruns = 2;
  in.servo_period_us = 2000;
  in.lateness_p50_us = 12.5;
  in.lateness_p99_us = 80.25;
  in.lateness_max_us = 900;
  const edp::Reply out = comm::decode(through_bytes(comm::encode(in)));
  EXPECT_EQ(out.type, in.type);
  EXPECT_TRUE(out.synchronised);
  EXPECT_EQ(out.step_no, 9);
  EXPECT_EQ(out.servo_cycle, 123456789);
  EXPECT_EQ(out.arm_type, in.arm_type);
  EXPECT_EQ(out.arm, in.arm);
  EXPECT_EQ(out.joints, in.joints);
  EXPECT_EQ(out.desired_joints, in.desired_joints);
  EXPECT_EQ(out.joint_velocities, in.joint_velocities);
  EXPECT_EQ(out.input_values, 7U);
  EXPECT_EQ(out.device, in.device);
  EXPECT_EQ(out.servo_cycles, 1000);
  EXPECT_EQ(out.servo_overruns, 2);
  EXPECT_DOUBLE_EQ(out.servo_period_us, 2000);
  EXPECT_DOUBLE_EQ(out.lateness_p50_us, 12.5);
  EXPECT_DOUBLE_EQ(out.lateness_p99_us, 80.25);
  EXPECT_DOUBLE_EQ(out.lateness_max_us, 900);
}

TEST(Messages, EdpErrorReplyRoundTrip) {
  edp::Reply in;
  in.type = edp::ReplyType::error;
  in.error_code = edp::error_code::out_of_limits;
  in.error_class = edp::error_class_of(in.error_code);
  in.error_text = "joint 2 (upper_arm) target 0.81 rad exceeds upper limit 0.70 rad";
  const edp::Reply out = comm::decode(through_bytes(comm::encode(in)));
  EXPECT_EQ(out.type, edp::ReplyType::error);
  EXPECT_EQ(out.error_code, edp::error_code::out_of_limits);
  EXPECT_EQ(out.error_class, ErrorClass::non_fatal);
  EXPECT_EQ(out.error_text, in.error_text);

  // A class the wire does not know does not decode.
  mrroc_lcm::edp_reply_t wire = comm::encode(in);
  wire.error_class = 4;
  EXPECT_THROW(comm::decode(wire), comm::DecodeError);
}

TEST(Messages, EveryEdpErrorCodeHasItsClass) {
  // A refusal before anything moved is non-fatal (the caller may retry or try another), what
  // leaves the robot unable to go on is fatal, a failed message is the system's.
  using namespace edp::error_code;
  for (int code : {query_expected, query_unexpected, not_synchronised, already_synchronised,
                   out_of_limits, bad_argument, not_supported, too_fast, too_abrupt})
    EXPECT_EQ(edp::error_class_of(code), ErrorClass::non_fatal) << "code " << code;
  for (int code : {hardware_fault, emergency_stop, servo_overrun, not_owner})
    EXPECT_EQ(edp::error_class_of(code), ErrorClass::fatal) << "code " << code;
  for (int code : {malformed, unauthenticated})
    EXPECT_EQ(edp::error_class_of(code), ErrorClass::system) << "code " << code;
  EXPECT_EQ(edp::error_class_of(none), ErrorClass::none);
  EXPECT_STREQ(to_string(ErrorClass::non_fatal), "non-fatal");
}

TEST(Messages, MpCommandAndEcpReplyRoundTrip) {
  ecp::MpCommand c;
  c.type = ecp::MpCommandType::next_pose;
  c.state_name = "place";
  c.arguments = "slot=3";
  c.arm_type = edp::ArmRepresentation::joint;
  c.motion_type = edp::MotionType::absolute;
  c.motion_steps = 10;
  c.value_in_step_no = 9;
  c.arm = {0, -1.57, 0, 0, 0};
  const ecp::MpCommand c2 = comm::decode(through_bytes(comm::encode(c)));
  EXPECT_EQ(c2.type, c.type);
  EXPECT_EQ(c2.state_name, "place");
  EXPECT_EQ(c2.arguments, "slot=3");
  EXPECT_EQ(c2.motion_steps, 10);
  EXPECT_EQ(c2.value_in_step_no, 9);
  EXPECT_EQ(c2.arm, c.arm);

  ecp::EcpReply r;
  r.type = ecp::EcpReplyType::error;
  r.error_class = ecp::ErrorClass::fatal;
  r.error_code = 6;
  r.error_text = "boom";
  r.synchronised = true;
  r.joints = {1, 2, 3};
  r.desired_joints = {1.5, 2.5, 3.5};
  r.arm_type = edp::ArmRepresentation::xyz_euler_zyz;
  r.arm = {0.1, 0.2, 0.3, 0.4, 0.5, 0.6};
  const ecp::EcpReply r2 = comm::decode(through_bytes(comm::encode(r)));
  EXPECT_EQ(r2.type, r.type);
  EXPECT_EQ(r2.error_class, ecp::ErrorClass::fatal);
  EXPECT_EQ(r2.error_code, 6);
  EXPECT_EQ(r2.error_text, "boom");
  EXPECT_TRUE(r2.synchronised);
  EXPECT_EQ(r2.joints, r.joints);
  EXPECT_EQ(r2.desired_joints, r.desired_joints);
  EXPECT_EQ(r2.arm_type, r.arm_type);
  EXPECT_EQ(r2.arm, r.arm);
}

TEST(Messages, MalformedInstructionNamesTheField) {
  auto expect_rejected = [](mrroc_lcm::edp_instruction_t m, const std::string& field) {
    try {
      comm::decode(m);
      FAIL() << "accepted a malformed '" << field << "'";
    } catch (const comm::DecodeError& e) {
      EXPECT_NE(std::string(e.what()).find(field), std::string::npos) << e.what();
    }
  };
  const mrroc_lcm::edp_instruction_t good = comm::encode(edp::Instruction{});
  auto m = good;
  m.instruction = 42;
  expect_rejected(m, "instruction");
  m = good;
  m.set_arm_type = 0;
  expect_rejected(m, "set_arm_type");
  m = good;
  m.motion_type = 3;
  expect_rejected(m, "motion_type");
  m = good;
  m.n_arm = 2;  // length field disagrees with the data
  expect_rejected(m, "arm");
  m = good;
  m.set_mask = 0x100;  // above DEVICE_BIT
  expect_rejected(m, "set_mask");
  m = good;
  m.n_device = 1;  // length field disagrees with the data
  expect_rejected(m, "device");
}

TEST(Messages, TruncatedBytesDoNotDecode) {
  const auto m = comm::encode(edp::Instruction{});
  std::vector<std::uint8_t> buf(static_cast<std::size_t>(m.getEncodedSize()));
  m.encode(buf.data(), 0, static_cast<int>(buf.size()));
  mrroc_lcm::edp_instruction_t out;
  EXPECT_LT(out.decode(buf.data(), 0, static_cast<int>(buf.size()) - 5), 0);
  buf[0] ^= 0xFF;  // wrong fingerprint
  EXPECT_LT(out.decode(buf.data(), 0, static_cast<int>(buf.size())), 0);
}

TEST(Messages, OversizedVectorIsRefusedBeforeSending) {
  edp::Instruction in;
  in.arm.assign(comm::kMaxVector + 1, 0.0);
  EXPECT_THROW(comm::encode(in), Error);
}
