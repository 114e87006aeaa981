#pragma once
/// @file
/// Conversions between LCM message types and the plain C++ values control code uses.
/// `decode` validates everything it reads (enumerations, sizes) and throws `DecodeError`
/// naming the field and value; a malformed message never reaches control code.

#include "mrroc/core/error.hpp"
#include "mrroc/msg/edp_instruction.hpp"
#include "mrroc/msg/mp_command.hpp"
#include "mrroc/msg/sensor_reading.hpp"
#include "mrroc_lcm/ecp_mp_reply_t.hpp"
#include "mrroc_lcm/edp_instruction_t.hpp"
#include "mrroc_lcm/edp_reply_t.hpp"
#include "mrroc_lcm/mp_ecp_command_t.hpp"
#include "mrroc_lcm/raw_sensor_t.hpp"
#include "mrroc_lcm/vsp_command_t.hpp"
#include "mrroc_lcm/vsp_reply_t.hpp"

namespace mrroc::comm {

class DecodeError : public Error {
 public:
  using Error::Error;
};

/// Largest arm/tool/joint vector accepted in a message.
inline constexpr int kMaxVector = 16;

mrroc_lcm::edp_instruction_t encode(const edp::Instruction& in);
edp::Instruction decode(const mrroc_lcm::edp_instruction_t& msg);
mrroc_lcm::edp_reply_t encode(const edp::Reply& in);
edp::Reply decode(const mrroc_lcm::edp_reply_t& msg);

mrroc_lcm::mp_ecp_command_t encode(const ecp::MpCommand& in);
ecp::MpCommand decode(const mrroc_lcm::mp_ecp_command_t& msg);
mrroc_lcm::ecp_mp_reply_t encode(const ecp::EcpReply& in);
ecp::EcpReply decode(const mrroc_lcm::ecp_mp_reply_t& msg);

mrroc_lcm::vsp_command_t encode(const vsp::Request& in);
vsp::Request decode(const mrroc_lcm::vsp_command_t& msg);
mrroc_lcm::vsp_reply_t encode(const vsp::Reply& in);
vsp::Reply decode(const mrroc_lcm::vsp_reply_t& msg);
mrroc_lcm::raw_sensor_t encode(const vsp::RawSample& in);
vsp::RawSample decode(const mrroc_lcm::raw_sensor_t& msg);

/// Largest number of values in a raw sample or a reading.
inline constexpr int kMaxSensorValues = 256;

}  // namespace mrroc::comm
