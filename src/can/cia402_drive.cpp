/// @file
/// The emulated CiA 402 drive (see cia402_drive.hpp).
#include "mrroc/can/cia402_drive.hpp"

#include <algorithm>
#include <cmath>
#include <span>
#include <utility>

namespace mrroc::can {

using canopen::DriveState;
using canopen::NmtState;
namespace od = canopen::od;

Cia402Drive::Cia402Drive(const DriveConfig& config, Output output)
    : config_(config), output_(std::move(output)) {}

void Cia402Drive::send(const can_frame& frame) {
  if (!silent_ && output_) output_(frame);
}

bool Cia402Drive::powered() const noexcept {
  return state_ == DriveState::operation_enabled || state_ == DriveState::quick_stop_active;
}

std::int32_t Cia402Drive::counts(double position) const noexcept {
  const double c = std::round((position - zero_) * config_.counts_per_unit);
  return static_cast<std::int32_t>(std::clamp(c, -2147483648.0, 2147483647.0));
}

double Cia402Drive::position_of(std::int32_t value) const noexcept {
  return zero_ + static_cast<double>(value) / config_.counts_per_unit;
}

std::uint32_t Cia402Drive::digital_inputs() const noexcept {
  return (sample_.home_switch ? std::uint32_t{canopen::kHomeSwitchBit} : 0U) |
         (static_cast<std::uint32_t>(sample_.input_lines) << canopen::kUserLineShift);
}

std::uint16_t Cia402Drive::statusword() const noexcept {
  std::uint16_t sw = canopen::state_bits(state_);
  if (state_ != DriveState::not_ready_to_switch_on && state_ != DriveState::switch_on_disabled &&
      state_ != DriveState::fault)
    sw |= canopen::statusword::kVoltageEnabled;
  if (state_ != DriveState::quick_stop_active && state_ != DriveState::switch_on_disabled &&
      state_ != DriveState::fault && state_ != DriveState::not_ready_to_switch_on)
    sw |= canopen::statusword::kQuickStop;
  sw |= canopen::statusword::kRemote;
  if (state_ == DriveState::operation_enabled && mode_ == canopen::kModeCyclicSyncPosition)
    sw |= canopen::statusword::kFollowingTarget;
  if (following_error_) sw |= canopen::statusword::kFollowingError;
  if (std::abs(to_ - sample_.position) * config_.counts_per_unit < 10.0)
    sw |= canopen::statusword::kTargetReached;
  return sw;
}

void Cia402Drive::power_on(const AxisSample& sample, double now_s) {
  sample_ = sample;
  zero_ = sample.position;
  demand_ = from_ = to_ = sample.position;
  demand_velocity_ = 0.0;
  target_ = 0;
  target_valid_ = false;
  rpdo_pending_ = false;
  rpdo2_pending_ = false;
  outputs_ = output_mask_ = 0;
  controlword_ = 0;
  following_error_ = false;
  following_error_since_s_ = over_current_since_s_ = -1.0;
  heartbeat_ms_ = 0;
  reset_communication_objects();
  abort_connection_ = canopen::abort_connection::kFault;
  quick_stop_option_ = canopen::quick_stop_option::kRampThenHold;
  comm_error_ = 0;
  last_update_s_ = last_sync_s_ = now_s;
  state_ = DriveState::switch_on_disabled;
  nmt_ = NmtState::pre_operational;
  send(canopen::heartbeat_frame(config_.node, NmtState::boot_up));
}

void Cia402Drive::reset_communication_objects() noexcept {
  consumer_heartbeat_ = 0;
  cycle_period_us_ = 0;
  error_behaviour_ = canopen::error_behaviour::kPreOperational;
  heartbeat_armed_ = false;
  sync_armed_ = false;
}

void Cia402Drive::enter(DriveState state, double now_s) {
  const bool was_powered = powered();
  state_ = state;
  if (state == DriveState::operation_enabled && !was_powered) comm_error_ = 0;
  if (!powered()) {
    // Brake: hold where the axis is.
    demand_ = from_ = to_ = sample_.position;
    demand_velocity_ = 0.0;
  } else if (!was_powered) {
    // Power on at standstill where the axis is; the first target starts from here.
    demand_ = from_ = to_ = sample_.position;
    demand_velocity_ = 0.0;
    segment_start_s_ = now_s;
    last_sync_s_ = now_s;
    target_valid_ = false;
  }
  following_error_since_s_ = -1.0;
  if (state != DriveState::fault) following_error_ = false;
}

void Cia402Drive::fault(std::uint16_t code, double now_s) {
  if (state_ == DriveState::fault) return;
  last_emcy_ = code;
  enter(DriveState::fault, now_s);
  canopen::Emergency e;
  e.code = code;
  e.error_register = code == canopen::emcy::kContinuousOverCurrent ? 0x03 : 0x01;
  send(canopen::encode_emcy(config_.node, e));
}

void Cia402Drive::inject_fault(std::uint16_t code, double now_s) { fault(code, now_s); }

void Cia402Drive::apply_controlword(std::uint16_t cw, double now_s) {
  const bool reset_edge = (cw & 0x80U) != 0U && (controlword_ & 0x80U) == 0U;
  controlword_ = cw;
  const canopen::DriveCommand command = canopen::decode_command(cw);
  if (command == canopen::DriveCommand::fault_reset) {
    if (reset_edge && state_ == DriveState::fault) {
      enter(DriveState::switch_on_disabled, now_s);
      last_emcy_ = canopen::emcy::kErrorReset;
      canopen::Emergency e;  // EMCY with code 0: error reset
      send(canopen::encode_emcy(config_.node, e));
    }
    return;
  }
  if (const auto next = canopen::transition(state_, command); next && *next != state_)
    enter(*next, now_s);
}

void Cia402Drive::on_sync(double now_s) {
  if (nmt_ != NmtState::operational) return;
  ++syncs_;
  last_sync_s_ = now_s;
  sync_armed_ = cycle_period_us_ != 0;
  if (rpdo_pending_) {
    rpdo_pending_ = false;
    apply_controlword(rpdo_.controlword, now_s);
    target_ = rpdo_.target_position;
    target_valid_ = true;
  }
  if (rpdo2_pending_) {
    rpdo2_pending_ = false;
    outputs_ = rpdo2_outputs_;
  }
  if (state_ == DriveState::operation_enabled && mode_ == canopen::kModeCyclicSyncPosition &&
      target_valid_) {
    // Velocity from target to target (the master's stream is uniform even when the SYNCs
    // arrive with jitter).
    const double previous = to_;
    from_ = demand_;
    to_ = position_of(target_);
    segment_start_s_ = now_s;
    demand_velocity_ = (to_ - previous) / config_.interpolation_period_s;
  }
  canopen::Tpdo1 tpdo;
  tpdo.statusword = statusword();
  tpdo.position_actual = counts(sample_.position);
  tpdo.inputs = canopen::compact_inputs(digital_inputs());
  send(canopen::encode(config_.node, tpdo));
}

void Cia402Drive::communication_error(std::uint16_t code, double now_s) {
  comm_error_ = code;
  comm_error_at_s_ = now_s;
  last_emcy_ = code;
  const bool enabled = state_ == DriveState::operation_enabled;
  if (enabled && abort_connection_ == canopen::abort_connection::kFault) {
    fault(code, now_s);  // sends the EMCY
  } else {
    canopen::Emergency e;
    e.code = code;
    e.error_register = 0x11;  // generic + communication
    send(canopen::encode_emcy(config_.node, e));
    if (enabled && abort_connection_ == canopen::abort_connection::kDisableVoltage)
      enter(DriveState::switch_on_disabled, now_s);
    else if (enabled && abort_connection_ == canopen::abort_connection::kQuickStop) {
      // The targets have stopped: the ramp starts from where the axis is and how fast it
      // moves (not from the last target, which may lie behind a moving axis).
      demand_ = from_ = to_ = sample_.position;
      demand_velocity_ = sample_.velocity;
      enter(DriveState::quick_stop_active, now_s);
    }
  }
  if (error_behaviour_ == canopen::error_behaviour::kPreOperational)
    nmt_ = NmtState::pre_operational;
  else if (error_behaviour_ == canopen::error_behaviour::kStopped)
    nmt_ = NmtState::stopped;
}

void Cia402Drive::on_heartbeat(const can_frame& frame, double now_s) {
  const auto producer = static_cast<std::uint8_t>((consumer_heartbeat_ >> 16U) & 0x7FU);
  if (producer == 0 || frame.len != 1 || frame.can_id != canopen::heartbeat_id(producer)) return;
  heartbeat_armed_ = true;
  last_heartbeat_s_ = now_s;
}

void Cia402Drive::on_nmt(const can_frame& frame, double now_s) {
  if (frame.len != 2) return;
  if (frame.data[1] != 0 && frame.data[1] != config_.node) return;
  switch (static_cast<canopen::NmtCommand>(frame.data[0])) {
    case canopen::NmtCommand::start: nmt_ = NmtState::operational; break;
    case canopen::NmtCommand::stop:
      nmt_ = NmtState::stopped;
      if (powered()) enter(DriveState::quick_stop_active, now_s);
      break;
    case canopen::NmtCommand::enter_pre_operational: nmt_ = NmtState::pre_operational; break;
    case canopen::NmtCommand::reset_node: power_on(sample_, now_s); break;
    case canopen::NmtCommand::reset_communication:
      nmt_ = NmtState::pre_operational;
      reset_communication_objects();
      send(canopen::heartbeat_frame(config_.node, NmtState::boot_up));
      break;
  }
}

void Cia402Drive::on_sdo(const can_frame& frame, double now_s) {
  namespace abort = canopen::sdo_abort;
  canopen::SdoResponse r;
  const auto request = canopen::decode_request(frame);
  if (frame.len >= 4) {
    r.index = static_cast<std::uint16_t>(frame.data[1] | (frame.data[2] << 8U));
    r.subindex = frame.data[3];
  }
  const auto fail = [&](std::uint32_t code) {
    r.abort = true;
    r.abort_code = code;
    send(canopen::encode_response(config_.node, r));
  };
  if (!request) return fail(abort::kCommandSpecifier);
  const canopen::SdoRequest& q = *request;
  const auto read = [&](std::uint32_t value, std::uint8_t size) {
    if (q.write) return fail(abort::kReadOnly);
    r.value = value;
    r.size = size;
    send(canopen::encode_response(config_.node, r));
  };
  const auto writable = [&](std::uint8_t size, std::uint32_t current,
                            const std::function<std::uint32_t(std::uint32_t)>& set) {
    if (!q.write) {
      r.value = current;
      r.size = size;
      send(canopen::encode_response(config_.node, r));
      return;
    }
    if (q.size != size) return fail(abort::kLengthMismatch);
    if (const std::uint32_t code = set(q.value); code != 0) return fail(code);
    r.write_confirmed = true;
    send(canopen::encode_response(config_.node, r));
  };
  const auto no_sub = [&](std::uint8_t last) { return q.subindex > last; };
  switch (q.index) {
    case od::kDeviceType:
      return no_sub(0) ? fail(abort::kNoSubindex) : read(od::kServoDeviceType, 4);
    case od::kErrorRegister:
      return no_sub(0) ? fail(abort::kNoSubindex) : read(state_ == DriveState::fault ? 1U : 0U, 1);
    case od::kCommunicationCyclePeriod:
      if (no_sub(0)) return fail(abort::kNoSubindex);
      return writable(4, cycle_period_us_, [&](std::uint32_t v) {
        cycle_period_us_ = v;
        sync_armed_ = false;  // re-armed by the next SYNC
        return 0U;
      });
    case od::kConsumerHeartbeatTime:
      if (no_sub(1)) return fail(abort::kNoSubindex);
      if (q.subindex == 0) return read(1, 1);
      return writable(4, consumer_heartbeat_, [&](std::uint32_t v) {
        if ((v >> 16U) > canopen::kMaxNode || (v >> 23U) != 0) return abort::kValueRange;
        consumer_heartbeat_ = v;
        heartbeat_armed_ = false;  // re-armed by the producer's next heartbeat
        return 0U;
      });
    case od::kErrorBehaviour:
      if (no_sub(1)) return fail(abort::kNoSubindex);
      if (q.subindex == 0) return read(1, 1);
      return writable(1, error_behaviour_, [&](std::uint32_t v) {
        if (v > canopen::error_behaviour::kStopped) return abort::kValueRange;
        error_behaviour_ = static_cast<std::uint8_t>(v);
        return 0U;
      });
    case od::kAbortConnectionOption:
      if (no_sub(0)) return fail(abort::kNoSubindex);
      return writable(2, static_cast<std::uint16_t>(abort_connection_), [&](std::uint32_t v) {
        const auto code = static_cast<std::int16_t>(static_cast<std::uint16_t>(v));
        if (code < canopen::abort_connection::kNoAction ||
            code > canopen::abort_connection::kQuickStop)
          return abort::kValueRange;
        abort_connection_ = code;
        return 0U;
      });
    case od::kQuickStopOption:
      if (no_sub(0)) return fail(abort::kNoSubindex);
      return writable(2, static_cast<std::uint16_t>(quick_stop_option_), [&](std::uint32_t v) {
        const auto code = static_cast<std::int16_t>(static_cast<std::uint16_t>(v));
        if (code != canopen::quick_stop_option::kRampThenDisabled &&
            code != canopen::quick_stop_option::kRampThenHold)
          return abort::kValueRange;
        quick_stop_option_ = code;
        return 0U;
      });
    case od::kHeartbeatTime:
      if (no_sub(0)) return fail(abort::kNoSubindex);
      return writable(2, heartbeat_ms_, [&](std::uint32_t v) {
        heartbeat_ms_ = static_cast<std::uint16_t>(v);
        next_heartbeat_s_ = now_s;
        return 0U;
      });
    case od::kRpdo1Mapping:
    case od::kRpdo2Mapping:
    case od::kTpdo1Mapping: {
      const std::span<const std::uint32_t> entries =
          q.index == od::kRpdo1Mapping   ? std::span<const std::uint32_t>(od::kRpdo1Entries)
          : q.index == od::kRpdo2Mapping ? std::span<const std::uint32_t>(od::kRpdo2Entries)
                                         : std::span<const std::uint32_t>(od::kTpdo1Entries);
      if (q.subindex > entries.size()) return fail(abort::kNoSubindex);
      if (q.subindex == 0) return read(static_cast<std::uint32_t>(entries.size()), 1);
      return read(entries[q.subindex - 1U], 4);
    }
    case od::kDigitalInputsCompact:
      return no_sub(0) ? fail(abort::kNoSubindex)
                       : read(canopen::compact_inputs(digital_inputs()), 2);
    case od::kDigitalOutputs:
      if (no_sub(2)) return fail(abort::kNoSubindex);
      if (q.subindex == 0) return read(2, 1);
      return writable(4, q.subindex == 1 ? outputs_ : output_mask_, [&](std::uint32_t v) {
        (q.subindex == 1 ? outputs_ : output_mask_) = v;
        return 0U;
      });
    case od::kEncoderResolution:
      return read(static_cast<std::uint32_t>(std::lround(config_.counts_per_unit)), 4);
    case od::kControlword:
      return writable(2, controlword_, [&](std::uint32_t v) {
        apply_controlword(static_cast<std::uint16_t>(v), now_s);
        return 0U;
      });
    case od::kStatusword: return read(statusword(), 2);
    case od::kModesOfOperation:
      return writable(1, static_cast<std::uint8_t>(mode_), [&](std::uint32_t v) {
        const auto mode = static_cast<std::int8_t>(v);
        if (mode != canopen::kModeCyclicSyncPosition) return abort::kValueRange;
        if (state_ == DriveState::operation_enabled) return abort::kDeviceState;
        mode_ = mode;
        return 0U;
      });
    case od::kModesDisplay: return read(static_cast<std::uint8_t>(mode_), 1);
    case od::kPositionActual: return read(static_cast<std::uint32_t>(counts(sample_.position)), 4);
    case od::kFollowingErrorWindow:
      return writable(4, config_.following_error_window, [&](std::uint32_t v) {
        config_.following_error_window = v;
        return 0U;
      });
    case od::kFollowingErrorTimeout:
      return writable(2, config_.following_error_timeout_ms, [&](std::uint32_t v) {
        config_.following_error_timeout_ms = static_cast<std::uint16_t>(v);
        return 0U;
      });
    case od::kCurrentActual: {
      const double per_mille =
          std::isfinite(config_.current_limit) && config_.current_limit > 0.0
              ? std::clamp(1000.0 * sample_.force / config_.current_limit, -32768.0, 32767.0)
              : 0.0;
      return read(static_cast<std::uint16_t>(static_cast<std::int16_t>(per_mille)), 2);
    }
    case od::kTargetPosition:
      return writable(4, static_cast<std::uint32_t>(target_), [&](std::uint32_t v) {
        target_ = static_cast<std::int32_t>(v);
        target_valid_ = true;
        return 0U;
      });
    case od::kQuickStopDeceleration:
      return writable(4,
                      static_cast<std::uint32_t>(
                          std::lround(config_.quick_stop_deceleration * config_.counts_per_unit)),
                      [&](std::uint32_t v) {
                        if (v == 0) return abort::kValueRange;
                        config_.quick_stop_deceleration =
                            static_cast<double>(v) / config_.counts_per_unit;
                        return 0U;
                      });
    case od::kDigitalInputs:
      return no_sub(0) ? fail(abort::kNoSubindex) : read(digital_inputs(), 4);
    case od::kInterpolationPeriod: {
      if (q.subindex == 0) return read(2, 1);
      if (q.subindex > 2) return fail(abort::kNoSubindex);
      // Kept as milliseconds (sub 1) with exponent -3 (sub 2); other exponents are refused.
      if (q.subindex == 2)
        return writable(1, 0xFDU,
                        [&](std::uint32_t v) { return v == 0xFDU ? 0U : abort::kValueRange; });
      return writable(
          1, static_cast<std::uint32_t>(std::lround(config_.interpolation_period_s * 1000.0)),
          [&](std::uint32_t v) {
            if (v == 0) return abort::kValueRange;
            if (state_ == DriveState::operation_enabled) return abort::kDeviceState;
            config_.interpolation_period_s = static_cast<double>(v) / 1000.0;
            return 0U;
          });
    }
    default: return fail(abort::kNoObject);
  }
}

void Cia402Drive::on_frame(const can_frame& frame, double now_s) {
  if (silent_ || (frame.can_id & (CAN_ERR_FLAG | CAN_EFF_FLAG | CAN_RTR_FLAG)) != 0U) return;
  const canopen::CobId id = canopen::split_id(frame.can_id);
  if (id.function == canopen::kNmtId) return on_nmt(frame, now_s);
  if (id.function == canopen::kSyncId && id.node == 0) return on_sync(now_s);
  if (id.function == 0x700U && id.node != config_.node) return on_heartbeat(frame, now_s);
  if (nmt_ == NmtState::boot_up || nmt_ == NmtState::stopped) return;
  if (id.node != config_.node) return;
  if (frame.can_id == canopen::sdo_request_id(config_.node)) return on_sdo(frame, now_s);
  if (frame.can_id == canopen::rpdo1_id(config_.node) && nmt_ == NmtState::operational) {
    if (const auto pdo = canopen::decode_rpdo1(frame)) {
      rpdo_ = *pdo;
      rpdo_pending_ = true;
    }
  }
  if (frame.can_id == canopen::rpdo2_id(config_.node) && nmt_ == NmtState::operational) {
    if (const auto pdo = canopen::decode_rpdo2(frame)) {
      rpdo2_outputs_ = pdo->outputs;
      rpdo2_pending_ = true;
    }
  }
}

void Cia402Drive::update(const AxisSample& sample, double now_s) {
  const double dt = std::max(0.0, now_s - last_update_s_);
  last_update_s_ = now_s;
  sample_ = sample;
  if (silent_) return;
  if (heartbeat_ms_ != 0 && now_s >= next_heartbeat_s_) {
    send(canopen::heartbeat_frame(config_.node, nmt_));
    next_heartbeat_s_ = now_s + heartbeat_ms_ / 1000.0;
  }
  if (nmt_ == NmtState::operational) {
    const double heartbeat_s = static_cast<double>(consumer_heartbeat_ & 0xFFFFU) / 1000.0;
    if (heartbeat_armed_ && heartbeat_s > 0.0 && now_s - last_heartbeat_s_ > heartbeat_s) {
      heartbeat_armed_ = false;
      communication_error(canopen::emcy::kHeartbeatError, now_s);
    }
    // Never shorter than the master's heartbeat supervision: a master that stalls (its host) for
    // less than the consumer time it set is not lost by this drive's SYNC watch either.
    const double sync_loss_s = std::max(
        config_.sync_loss_periods * static_cast<double>(cycle_period_us_) * 1e-6, heartbeat_s);
    if (sync_armed_ && cycle_period_us_ != 0 && now_s - last_sync_s_ > sync_loss_s) {
      sync_armed_ = false;
      communication_error(canopen::emcy::kCommunication, now_s);
    }
    if (state_ == DriveState::fault) return;
  }
  if (state_ == DriveState::operation_enabled) {
    const double s =
        std::clamp((now_s - segment_start_s_) / config_.interpolation_period_s, 0.0, 1.0);
    demand_ = from_ + (to_ - from_) * s;
    // The segment's velocity holds until the next SYNC; a late SYNC means standstill.
    if (now_s - segment_start_s_ > 1.5 * config_.interpolation_period_s) demand_velocity_ = 0.0;
  } else if (state_ == DriveState::quick_stop_active) {
    const double dv = config_.quick_stop_deceleration * dt;
    double v = demand_velocity_;
    v = std::abs(v) <= dv ? 0.0 : v - std::copysign(dv, v);
    demand_velocity_ = v;
    demand_ += v * dt;
    from_ = to_ = demand_;
    if (v == 0.0 && quick_stop_option_ == canopen::quick_stop_option::kRampThenDisabled) {
      enter(DriveState::switch_on_disabled, now_s);
      return;
    }
  }
  if (powered()) {
    const double error = std::abs(demand_ - sample.position) * config_.counts_per_unit;
    following_error_ = config_.following_error_window != 0 &&
                       error > static_cast<double>(config_.following_error_window);
    if (following_error_) {
      if (following_error_since_s_ < 0.0) following_error_since_s_ = now_s;
      if (now_s - following_error_since_s_ > config_.following_error_timeout_ms / 1000.0) {
        fault(canopen::emcy::kFollowingError, now_s);
        following_error_ = true;
        return;
      }
    } else {
      following_error_since_s_ = -1.0;
    }
    if (std::abs(sample.force) > config_.current_limit) {
      if (over_current_since_s_ < 0.0) over_current_since_s_ = now_s;
      if (now_s - over_current_since_s_ > config_.over_current_time_s) {
        fault(canopen::emcy::kContinuousOverCurrent, now_s);
        return;
      }
    } else {
      over_current_since_s_ = -1.0;
    }
  }
}

}  // namespace mrroc::can
