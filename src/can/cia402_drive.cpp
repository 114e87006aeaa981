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

namespace {
constexpr std::uint32_t key(std::uint16_t index, std::uint8_t sub) {
  return (static_cast<std::uint32_t>(index) << 8U) | sub;
}
bool is_rpdo_communication(std::uint16_t i) { return i >= 0x1400 && i < 0x1600; }
bool is_rpdo_mapping(std::uint16_t i) { return i >= 0x1600 && i < 0x1800; }
bool is_tpdo_communication(std::uint16_t i) { return i >= 0x1800 && i < 0x1A00; }
bool is_tpdo_mapping(std::uint16_t i) { return i >= 0x1A00 && i < 0x1C00; }
std::uint64_t width_mask(int bits) {
  return bits >= 64 ? ~std::uint64_t{0} : (std::uint64_t{1} << static_cast<unsigned>(bits)) - 1U;
}
}  // namespace

Cia402Drive::Cia402Drive(const DriveConfig& config, Output output)
    : config_(config),
      output_(std::move(output)),
      eds_(config.eds ? config.eds : default_drive_eds()),
      supported_modes_(eds_->supported_modes()) {
  reset_store(false);
}

std::uint64_t Cia402Drive::stored(std::uint16_t index, std::uint8_t sub) const {
  const auto it = store_.find(key(index, sub));
  return it == store_.end() ? 0U : it->second;
}

void Cia402Drive::reset_store(bool communication_only) {
  for (auto it = texts_.begin(); it != texts_.end();) {
    const auto index = static_cast<std::uint16_t>(it->first >> 8U);
    it = !communication_only || (index >= 0x1000 && index < 0x2000) ? texts_.erase(it)
                                                                    : std::next(it);
  }
  for (const auto& [index, object] : eds_->objects()) {
    if (communication_only && (index < 0x1000 || index >= 0x2000)) continue;
    for (const auto& [sub, entry] : object.entries)
      if (const auto v = eds_->value(index, sub, config_.node))
        store_[key(index, sub)] = *v & width_mask(eds::bit_size(entry.data_type));
  }
  refresh_pdos();
}

void Cia402Drive::refresh_pdos() {
  rpdos_.clear();
  tpdos_.clear();
  for (const auto& [index, object] : eds_->objects()) {
    const bool receive = is_rpdo_communication(index);
    if (!receive && !is_tpdo_communication(index)) continue;
    const std::uint32_t cob = static_cast<std::uint32_t>(stored(index, 1));
    if ((cob & kPdoInvalid) != 0U || eds_->entry(index, 1) == nullptr) continue;
    ActivePdo p;
    p.number = index - (receive ? 0x1400 : 0x1800) + 1;
    p.id = cob & CAN_SFF_MASK;
    p.transmission = static_cast<std::uint8_t>(stored(index, 2));
    p.inhibit_s = static_cast<double>(stored(index, 3)) * 100e-6;
    p.event_timer_s = static_cast<double>(stored(index, 5)) * 1e-3;
    const auto map = static_cast<std::uint16_t>(index + 0x200);
    const auto count = stored(map, 0);
    for (std::uint64_t k = 1; k <= count && k < 0x41; ++k)
      p.entries.push_back(PdoEntry::from_raw(
          static_cast<std::uint32_t>(stored(map, static_cast<std::uint8_t>(k)))));
    (receive ? rpdos_ : tpdos_).push_back(std::move(p));
  }
}

bool Cia402Drive::mappable(const PdoEntry& m, bool receive) const {
  const eds::Entry* e = eds_->entry(m.index, m.sub);
  if (e == nullptr || !e->pdo_mappable || eds::bit_size(e->data_type) != m.bits) return false;
  return receive ? eds::writable(e->access) : eds::readable(e->access);
}

std::uint32_t Cia402Drive::check_pdo_write(std::uint16_t index, std::uint8_t sub,
                                           std::uint64_t raw) const {
  namespace abort = canopen::sdo_abort;
  const bool mapping = is_rpdo_mapping(index) || is_tpdo_mapping(index);
  const bool receive = is_rpdo_mapping(index) || is_rpdo_communication(index);
  const auto communication = static_cast<std::uint16_t>(mapping ? index - 0x200 : index);
  const bool on = (stored(communication, 1) & kPdoInvalid) == 0U;
  if (mapping) {
    if (sub == 0) {
      if (on) return abort::kUnsupportedAccess;  // switch the PDO off first
      int bits = 0;
      for (std::uint64_t k = 1; k <= raw; ++k) {
        if (eds_->entry(index, static_cast<std::uint8_t>(k)) == nullptr) return abort::kValueRange;
        const PdoEntry m = PdoEntry::from_raw(
            static_cast<std::uint32_t>(stored(index, static_cast<std::uint8_t>(k))));
        if (!mappable(m, receive)) return abort::kNotMappable;
        bits += m.bits;
      }
      return bits > 64 ? abort::kPdoTooLong : 0U;
    }
    if (stored(index, 0) != 0U) return abort::kUnsupportedAccess;  // set the count to 0 first
    if (raw != 0U && !mappable(PdoEntry::from_raw(static_cast<std::uint32_t>(raw)), receive))
      return abort::kNotMappable;
    return 0U;
  }
  if (sub == 1) {
    if ((raw & 0x20000000U) != 0U) return abort::kValueRange;  // 29-bit identifiers: none
    if (on && (raw & kPdoInvalid) == 0U &&
        (raw & CAN_SFF_MASK) != (stored(index, 1) & CAN_SFF_MASK))
      return abort::kValueRange;  // a PDO that is on keeps its identifier
  }
  if (sub == 2 && raw > 240 && raw < (receive ? 254U : 252U)) return abort::kValueRange;
  return 0U;
}

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
  if (state_ == DriveState::operation_enabled &&
      (mode_ == canopen::kModeCyclicSyncPosition || mode_ == canopen::kModeCyclicSyncVelocity))
    sw |= canopen::statusword::kFollowingTarget;
  if (state_ == DriveState::operation_enabled && mode_ == canopen::kModeInterpolatedPosition &&
      (controlword_ & canopen::controlword::kEnableIpMode) != 0U)
    sw |= canopen::statusword::kIpModeActive;
  if (following_error_) sw |= canopen::statusword::kFollowingError;
  if (mode_ == canopen::kModeHoming) {
    // Homing: bit 12 attained, bit 13 error, bit 10 at standstill and not homing (CiA 402's
    // table: in progress 0/0/0, interrupted or not started 0/0/1, attained 1/0/1, error x/1/x).
    const bool homing = homing_phase_ != HomingPhase::idle;
    sw &= static_cast<std::uint16_t>(~canopen::statusword::kFollowingError);  // bit 13: homing's
    if (homing_attained_) sw |= canopen::statusword::kHomingAttained;
    if (homing_error_) sw |= canopen::statusword::kHomingError;
    if (!homing && demand_velocity_ == 0.0) sw |= canopen::statusword::kTargetReached;
    if (homing_phase_ == HomingPhase::stopping && demand_velocity_ == 0.0)
      sw |= canopen::statusword::kTargetReached;
    return sw;
  }
  // Target reached: not in cyclic synchronous position, where CiA 402 reserves the bit (it would
  // flicker with every target, and each change of the statusword is a TPDO); in the other modes
  // once the interpolation has ended at the target.
  if (mode_ != canopen::kModeCyclicSyncPosition && mode_ != canopen::kModeCyclicSyncVelocity &&
      demand_velocity_ == 0.0 && std::abs(to_ - sample_.position) * config_.counts_per_unit < 10.0)
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
  outputs_ = output_mask_ = 0;
  uploading_ = false;
  reset_store(false);
  mode_ = eds_->entry(od::kModesOfOperation, 0) != nullptr
              ? static_cast<std::int8_t>(stored(od::kModesOfOperation, 0))
              : canopen::kModeCyclicSyncPosition;
  controlword_ = 0;
  following_error_ = false;
  following_error_since_s_ = over_current_since_s_ = -1.0;
  homing_phase_ = HomingPhase::idle;
  homing_attained_ = homing_error_ = false;
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
  // Homing runs in operation enabled only; a quick stop ramps the axis down from its homing
  // speed (below), and the homing is over.
  if (state != DriveState::operation_enabled && homing_phase_ != HomingPhase::idle)
    homing_phase_ = HomingPhase::idle;
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
    target_velocity_ = 0;
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
  const bool bit4_was = (controlword_ & canopen::controlword::kHomingStart) != 0U;
  controlword_ = cw;
  apply_state_command(cw, reset_edge, now_s);
  // Homing mode, in operation enabled (also when this very controlword enabled it): bit 4 from
  // 0 to 1 starts the homing, from 1 to 0 interrupts it.
  if (mode_ != canopen::kModeHoming || state_ != DriveState::operation_enabled) return;
  const bool bit4 = (cw & canopen::controlword::kHomingStart) != 0U;
  if (bit4 && !bit4_was)
    start_homing(now_s);
  else if (!bit4 && bit4_was && homing_phase_ != HomingPhase::idle)
    homing_phase_ = HomingPhase::stopping;
}

void Cia402Drive::apply_state_command(std::uint16_t cw, bool reset_edge, double now_s) {
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

void Cia402Drive::start_homing(double now_s) {
  (void)now_s;
  const auto method =
      static_cast<std::int8_t>(static_cast<std::uint8_t>(stored(od::kHomingMethod, 0)));
  homing_attained_ = false;
  homing_error_ = false;
  homing_start_ = demand_;
  if (method == 35 || method == 37) {
    // The current position is the home point.
    home_ = sample_.position;
    zero_ = home_ - static_cast<double>(static_cast<std::int32_t>(stored(od::kHomeOffset, 0))) /
                        config_.counts_per_unit;
    homing_attained_ = true;
    homing_phase_ = HomingPhase::idle;
    return;
  }
  if (method < 19 || method > 22) {  // not a method of this drive (0: none written)
    homing_error_ = true;
    homing_phase_ = HomingPhase::stopping;
    return;
  }
  // 19/20: the switch is on above its edge; 21/22: below. 19 and 22 end moving down, 20 and 21
  // moving up; 19 and 21 where the switch goes off, 20 and 22 where it comes on.
  homing_direction_ = method == 20 || method == 21 ? 1.0 : -1.0;
  homing_switch_before_ = method == 19 || method == 21;
  homing_phase_ =
      sample_.home_switch == homing_switch_before_ ? HomingPhase::approach : HomingPhase::search;
}

void Cia402Drive::homing_step(double dt) {
  const double per_count = 1.0 / config_.counts_per_unit;
  const double acceleration =
      static_cast<double>(std::max<std::uint64_t>(1, stored(od::kHomingAcceleration, 0))) *
      per_count;
  const double switch_speed = static_cast<double>(stored(od::kHomingSpeeds, 1)) * per_count;
  const double zero_speed = static_cast<double>(stored(od::kHomingSpeeds, 2)) * per_count;
  double v = demand_velocity_;
  const auto ramp_to = [&](double wanted) {
    const double dv = acceleration * dt;
    v = std::abs(wanted - v) <= dv ? wanted : v + std::copysign(dv, wanted - v);
  };
  const auto beyond_range = [&] {
    return std::abs(demand_ - homing_start_) > config_.homing_search_range;
  };
  switch (homing_phase_) {
    case HomingPhase::search:
      if (sample_.home_switch == homing_switch_before_) {
        homing_phase_ = HomingPhase::reverse;
        ramp_to(0.0);
      } else if (beyond_range()) {
        homing_error_ = true;
        homing_phase_ = HomingPhase::stopping;
        ramp_to(0.0);
      } else {
        ramp_to(-homing_direction_ * switch_speed);
      }
      break;
    case HomingPhase::reverse:
      ramp_to(0.0);
      if (v == 0.0) homing_phase_ = HomingPhase::approach;
      break;
    case HomingPhase::approach:
      if (sample_.home_switch != homing_switch_before_) {
        // The edge: here the position becomes the home offset.
        home_ = sample_.position;
        zero_ = home_ - static_cast<double>(static_cast<std::int32_t>(stored(od::kHomeOffset, 0))) *
                            per_count;
        homing_phase_ = HomingPhase::settle;
      } else if (beyond_range()) {
        homing_error_ = true;
        homing_phase_ = HomingPhase::stopping;
        ramp_to(0.0);
        break;
      } else {
        ramp_to(homing_direction_ * zero_speed);
        break;
      }
      [[fallthrough]];
    case HomingPhase::settle: {
      // Back to the home point at the zero search speed, rest to rest.
      const double d = home_ - demand_;
      const double dv = acceleration * dt;
      if (std::abs(d) <= std::max(per_count, std::abs(v) * dt) && std::abs(v) <= dv) {
        demand_ = home_;
        v = 0.0;
        homing_attained_ = true;
        homing_phase_ = HomingPhase::idle;
        break;
      }
      const bool brake = d * v < 0.0 || std::abs(d) <= v * v / (2.0 * acceleration);
      ramp_to(brake ? 0.0 : std::copysign(std::max(zero_speed, dv), d));
      break;
    }
    case HomingPhase::stopping: ramp_to(0.0); break;
    case HomingPhase::idle: v = 0.0; break;
  }
  demand_velocity_ = v;
  if (homing_phase_ != HomingPhase::idle || v != 0.0) demand_ += v * dt;
  from_ = to_ = demand_;
}

void Cia402Drive::on_sync(double now_s) {
  if (nmt_ != NmtState::operational) return;
  ++syncs_;
  last_sync_s_ = now_s;
  sync_armed_ = cycle_period_us_ != 0;
  for (ActivePdo& p : rpdos_) {
    if (!p.pending) continue;
    p.pending = false;
    apply_rpdo(p, p.frame, now_s);
  }
  const bool interpolating = mode_ == canopen::kModeCyclicSyncPosition ||
                             (mode_ == canopen::kModeInterpolatedPosition &&
                              (controlword_ & canopen::controlword::kEnableIpMode) != 0U);
  if (state_ == DriveState::operation_enabled && mode_ == canopen::kModeCyclicSyncVelocity) {
    // The velocity holds over the period, from where the last one took the axis (the demand
    // sampled between two steps may not have reached it yet).
    from_ = to_;
    demand_velocity_ = static_cast<double>(target_velocity_) / config_.counts_per_unit;
    to_ = from_ + demand_velocity_ * config_.interpolation_period_s;
    segment_start_s_ = now_s;
  }
  if (state_ == DriveState::operation_enabled && interpolating && target_valid_) {
    // Velocity from target to target (the master's stream is uniform even when the SYNCs
    // arrive with jitter).
    const double previous = to_;
    from_ = demand_;
    to_ = position_of(target_);
    segment_start_s_ = now_s;
    demand_velocity_ = (to_ - previous) / config_.interpolation_period_s;
  }
  for (ActivePdo& p : tpdos_) {
    if (p.transmission == transmission::kSyncAcyclic)
      send_tpdo(p, now_s, true);
    else if (p.transmission <= 240 && ++p.syncs % p.transmission == 0)
      send_tpdo(p, now_s, false);
  }
}

void Cia402Drive::apply_rpdo(const ActivePdo& p, const can_frame& frame, double now_s) {
  int bits = 0;
  for (const PdoEntry& m : p.entries) bits += m.bits;
  if (frame.len * 8 < bits) return;  // shorter than the mapping: not processed (CiA 301)
  std::uint64_t data = 0;
  for (int b = 0; b < frame.len && b < 8; ++b)
    data |= static_cast<std::uint64_t>(frame.data[b]) << (8U * static_cast<unsigned>(b));
  int at = 0;
  for (const PdoEntry& m : p.entries) {
    const std::uint64_t raw = (data >> static_cast<unsigned>(at)) & width_mask(m.bits);
    at += m.bits;
    if (m.index >= 0x0001 && m.index <= 0x0007) continue;  // a dummy entry
    (void)write_object(m.index, m.sub, raw, now_s);
  }
}

void Cia402Drive::send_tpdo(ActivePdo& p, double now_s, bool only_if_changed) {
  can_frame f{};
  f.can_id = p.id;
  std::uint64_t data = 0;
  int at = 0;
  for (const PdoEntry& m : p.entries) {
    data |= (read_object(m.index, m.sub) & width_mask(m.bits)) << static_cast<unsigned>(at);
    at += m.bits;
  }
  f.len = static_cast<std::uint8_t>((at + 7) / 8);
  for (int b = 0; b < f.len; ++b)
    f.data[b] = static_cast<std::uint8_t>(data >> (8U * static_cast<unsigned>(b)));
  if (only_if_changed && p.sent && f.len == p.frame.len &&
      std::equal(f.data, f.data + f.len, p.frame.data))
    return;
  p.frame = f;
  p.sent = true;
  p.last_sent_s = now_s;
  send(f);
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
      reset_store(true);
      reset_communication_objects();
      send(canopen::heartbeat_frame(config_.node, NmtState::boot_up));
      break;
  }
}

std::uint64_t Cia402Drive::read_object(std::uint16_t index, std::uint8_t sub) const {
  const auto u16 = [](std::int64_t v) { return static_cast<std::uint64_t>(v) & 0xFFFFU; };
  switch (index) {
    case od::kErrorRegister: return state_ == DriveState::fault ? 1U : 0U;
    case od::kErrorCode: return last_emcy_;
    case od::kCommunicationCyclePeriod: return cycle_period_us_;
    case od::kConsumerHeartbeatTime: return sub == 1 ? consumer_heartbeat_ : stored(index, sub);
    case od::kHeartbeatTime: return heartbeat_ms_;
    case od::kErrorBehaviour: return sub == 1 ? error_behaviour_ : stored(index, sub);
    case od::kAbortConnectionOption: return u16(abort_connection_);
    case od::kQuickStopOption: return u16(quick_stop_option_);
    case od::kControlword: return controlword_;
    case od::kStatusword: return statusword();
    case od::kModesOfOperation:
    case od::kModesDisplay: return static_cast<std::uint8_t>(mode_);
    case od::kPositionActual: return static_cast<std::uint32_t>(counts(sample_.position));
    case od::kVelocityActual:
      return static_cast<std::uint32_t>(static_cast<std::int32_t>(std::clamp(
          std::round(sample_.velocity * config_.counts_per_unit), -2147483648.0, 2147483647.0)));
    case od::kFollowingErrorWindow: return config_.following_error_window;
    case od::kFollowingErrorTimeout: return config_.following_error_timeout_ms;
    case od::kTorqueActual:
    case od::kCurrentActual: {
      const double per_mille =
          std::isfinite(config_.current_limit) && config_.current_limit > 0.0
              ? std::clamp(1000.0 * sample_.force / config_.current_limit, -32768.0, 32767.0)
              : 0.0;
      return u16(static_cast<std::int16_t>(per_mille));
    }
    case od::kTargetPosition: return static_cast<std::uint32_t>(target_);
    case od::kTargetVelocity: return static_cast<std::uint32_t>(target_velocity_);
    case od::kInterpolationData:
      return sub == 1 ? static_cast<std::uint32_t>(target_) : stored(index, sub);
    case od::kQuickStopDeceleration:
      return static_cast<std::uint32_t>(
          std::lround(config_.quick_stop_deceleration * config_.counts_per_unit));
    case od::kInterpolationPeriod:
      if (sub == 1)
        return static_cast<std::uint32_t>(std::lround(config_.interpolation_period_s * 1000.0));
      return sub == 2 ? 0xFDU : stored(index, sub);
    case od::kDigitalInputs: return digital_inputs();
    case od::kDigitalOutputs:
      return sub == 1 ? outputs_ : sub == 2 ? output_mask_ : stored(index, sub);
    default: return stored(index, sub);
  }
}

std::uint32_t Cia402Drive::write_object(std::uint16_t index, std::uint8_t sub, std::uint64_t raw,
                                        double now_s) {
  namespace abort = canopen::sdo_abort;
  const auto v = static_cast<std::uint32_t>(raw);
  const auto i16 = [&] { return static_cast<std::int16_t>(static_cast<std::uint16_t>(v)); };
  switch (index) {
    case od::kCommunicationCyclePeriod:
      cycle_period_us_ = v;
      sync_armed_ = false;  // re-armed by the next SYNC
      return 0U;
    case od::kConsumerHeartbeatTime:
      if (sub != 1) break;
      if ((v >> 16U) > canopen::kMaxNode || (v >> 23U) != 0) return abort::kValueRange;
      consumer_heartbeat_ = v;
      heartbeat_armed_ = false;  // re-armed by the producer's next heartbeat
      return 0U;
    case od::kErrorBehaviour:
      if (sub != 1) break;
      if (v > canopen::error_behaviour::kStopped) return abort::kValueRange;
      error_behaviour_ = static_cast<std::uint8_t>(v);
      return 0U;
    case od::kAbortConnectionOption:
      if (i16() < canopen::abort_connection::kNoAction ||
          i16() > canopen::abort_connection::kQuickStop)
        return abort::kValueRange;
      abort_connection_ = i16();
      return 0U;
    case od::kQuickStopOption:
      if (i16() != canopen::quick_stop_option::kRampThenDisabled &&
          i16() != canopen::quick_stop_option::kRampThenHold)
        return abort::kValueRange;
      quick_stop_option_ = i16();
      return 0U;
    case od::kHeartbeatTime:
      heartbeat_ms_ = static_cast<std::uint16_t>(v);
      next_heartbeat_s_ = now_s;
      return 0U;
    case od::kControlword: apply_controlword(static_cast<std::uint16_t>(v), now_s); return 0U;
    case od::kModesOfOperation: {
      const auto mode = static_cast<std::int8_t>(static_cast<std::uint8_t>(v));
      if (supported_modes_ != 0 ? (supported_modes_ & eds::mode_bit(mode)) == 0U
                                : mode != canopen::kModeCyclicSyncPosition)
        return abort::kValueRange;
      if (state_ == DriveState::operation_enabled && mode != mode_) return abort::kDeviceState;
      if (mode != mode_) {
        homing_phase_ = HomingPhase::idle;
        homing_attained_ = homing_error_ = false;
      }
      mode_ = mode;
      return 0U;
    }
    case od::kHomingMethod: {
      // The axis has a home switch (0x60FD bit 2) and nothing else: no limit switches, no index.
      const auto method = static_cast<std::int8_t>(static_cast<std::uint8_t>(v));
      if (method != 19 && method != 20 && method != 21 && method != 22 && method != 35 &&
          method != 37)
        return abort::kValueRange;
      if (homing_phase_ != HomingPhase::idle) return abort::kDeviceState;
      break;  // stored
    }
    case od::kFollowingErrorWindow: config_.following_error_window = v; return 0U;
    case od::kFollowingErrorTimeout:
      config_.following_error_timeout_ms = static_cast<std::uint16_t>(v);
      return 0U;
    case od::kTargetPosition:
      target_ = static_cast<std::int32_t>(v);
      target_valid_ = true;
      return 0U;
    case od::kInterpolationData:
      if (sub != 1) break;
      target_ = static_cast<std::int32_t>(v);
      target_valid_ = true;
      return 0U;
    case od::kTargetVelocity: target_velocity_ = static_cast<std::int32_t>(v); return 0U;
    case od::kQuickStopDeceleration:
      if (v == 0) return abort::kValueRange;
      config_.quick_stop_deceleration = static_cast<double>(v) / config_.counts_per_unit;
      return 0U;
    case od::kInterpolationPeriod:
      // Kept as milliseconds (sub 1) with exponent -3 (sub 2); other exponents are refused.
      if (sub == 2) return v == 0xFDU ? 0U : abort::kValueRange;
      if (sub != 1) break;
      if (v == 0) return abort::kValueRange;
      if (state_ == DriveState::operation_enabled) return abort::kDeviceState;
      config_.interpolation_period_s = static_cast<double>(v) / 1000.0;
      return 0U;
    case od::kDigitalOutputs:
      if (sub == 1) outputs_ = v;
      if (sub == 2) output_mask_ = v;
      if (sub == 1 || sub == 2) return 0U;
      break;
    default: break;
  }
  if (is_rpdo_communication(index) || is_rpdo_mapping(index) || is_tpdo_communication(index) ||
      is_tpdo_mapping(index)) {
    if (const std::uint32_t code = check_pdo_write(index, sub, raw); code != 0) return code;
    store_[key(index, sub)] = raw;
    refresh_pdos();
    return 0U;
  }
  store_[key(index, sub)] = raw;
  return 0U;
}

void Cia402Drive::upload_segment(const can_frame& frame) {
  namespace abort = canopen::sdo_abort;
  can_frame f{};
  f.can_id = canopen::sdo_response_id(config_.node);
  f.len = 8;
  const bool toggle = (frame.data[0] & 0x10U) != 0U;
  if (!uploading_ || toggle != upload_toggle_) {
    uploading_ = false;
    f.data[0] = 0x80;
    const std::uint32_t code = uploading_ ? abort::kToggleBit : abort::kCommandSpecifier;
    for (int b = 0; b < 4; ++b)
      f.data[4 + b] = static_cast<std::uint8_t>(code >> (8U * static_cast<unsigned>(b)));
    send(f);
    return;
  }
  const std::size_t n = std::min<std::size_t>(7, upload_.size() - upload_at_);
  std::copy_n(upload_.begin() + static_cast<std::ptrdiff_t>(upload_at_), n, f.data + 1);
  upload_at_ += n;
  const bool last = upload_at_ >= upload_.size();
  f.data[0] =
      static_cast<std::uint8_t>((toggle ? 0x10U : 0U) | ((7U - n) << 1U) | (last ? 1U : 0U));
  upload_toggle_ = !upload_toggle_;
  if (last) uploading_ = false;
  send(f);
}

std::string Cia402Drive::text_of(std::uint16_t index, std::uint8_t sub) const {
  if (const auto it = texts_.find(key(index, sub)); it != texts_.end()) return it->second;
  const eds::Entry* e = eds_->entry(index, sub);
  return e != nullptr && e->value ? e->value->text : std::string();
}

namespace {
/// An SDO response frame of `node` with byte 0 `command` and the request's index and sub.
can_frame sdo_answer(std::uint8_t node, std::uint8_t command, std::uint16_t index,
                     std::uint8_t sub) {
  can_frame f{};
  f.can_id = canopen::sdo_response_id(node);
  f.len = 8;
  f.data[0] = command;
  f.data[1] = static_cast<std::uint8_t>(index);
  f.data[2] = static_cast<std::uint8_t>(index >> 8U);
  f.data[3] = sub;
  return f;
}
void put_code(can_frame& f, std::uint32_t code) {
  for (unsigned b = 0; b < 4; ++b) f.data[4 + b] = static_cast<std::uint8_t>(code >> (8U * b));
}
}  // namespace

std::uint32_t Cia402Drive::store_download(std::uint16_t index, std::uint8_t sub,
                                          const std::string& data, double now_s) {
  namespace abort = canopen::sdo_abort;
  const eds::Entry* e = eds_->entry(index, sub);
  if (e == nullptr) return eds_->object(index) != nullptr ? abort::kNoSubindex : abort::kNoObject;
  if (!eds::writable(e->access)) return abort::kReadOnly;
  if (eds::is_string(e->data_type)) {
    texts_[key(index, sub)] = data;
    return 0U;
  }
  const int bits = eds::bit_size(e->data_type);
  if (bits <= 0 || bits > 32) return abort::kUnsupportedAccess;
  const auto bytes = static_cast<std::size_t>(bits <= 8 ? 1 : bits / 8);
  if (data.size() != bytes)
    return data.size() > bytes ? abort::kLengthTooHigh : abort::kLengthTooLow;
  std::uint64_t raw = 0;
  for (std::size_t b = 0; b < bytes; ++b)
    raw |= static_cast<std::uint64_t>(static_cast<std::uint8_t>(data[b])) << (8U * b);
  if (eds::out_of_range(*e, raw)) {
    const std::int64_t value = eds::as_signed(*e, raw);
    return e->high_limit && value > *e->high_limit ? abort::kValueTooHigh
           : e->low_limit && value < *e->low_limit ? abort::kValueTooLow
                                                   : abort::kValueRange;
  }
  return write_object(index, sub, raw, now_s);
}

void Cia402Drive::initiate_download(const can_frame& frame, double now_s) {
  namespace abort = canopen::sdo_abort;
  (void)now_s;
  const auto index = static_cast<std::uint16_t>(frame.data[1] | (frame.data[2] << 8U));
  const std::uint8_t sub = frame.data[3];
  const auto refuse = [&](std::uint32_t code) {
    can_frame f = sdo_answer(config_.node, 0x80, index, sub);
    put_code(f, code);
    send(f);
  };
  const eds::Entry* e = eds_->entry(index, sub);
  if (e == nullptr)
    return refuse(eds_->object(index) != nullptr ? abort::kNoSubindex : abort::kNoObject);
  if (!eds::writable(e->access)) return refuse(abort::kReadOnly);
  std::size_t size = 0;
  if ((frame.data[0] & 0x01U) != 0U) {  // size indicated
    size = static_cast<std::size_t>(frame.data[4]) |
           (static_cast<std::size_t>(frame.data[5]) << 8U) |
           (static_cast<std::size_t>(frame.data[6]) << 16U) |
           (static_cast<std::size_t>(frame.data[7]) << 24U);
    if (size > kMaxSegmentedBytes) return refuse(abort::kOutOfMemory);
  }
  download_index_ = index;
  download_sub_ = sub;
  download_.clear();
  download_size_ = size;
  download_toggle_ = false;
  downloading_ = true;
  send(sdo_answer(config_.node, 0x60, index, sub));
}

void Cia402Drive::download_segment(const can_frame& frame, double now_s) {
  namespace abort = canopen::sdo_abort;
  const bool toggle = (frame.data[0] & 0x10U) != 0U;
  const auto refuse = [&](std::uint32_t code) {
    downloading_ = false;
    can_frame f = sdo_answer(config_.node, 0x80, download_index_, download_sub_);
    put_code(f, code);
    send(f);
  };
  if (!downloading_) return refuse(abort::kCommandSpecifier);
  if (toggle != download_toggle_) return refuse(abort::kToggleBit);
  const std::size_t n = 7U - ((frame.data[0] >> 1U) & 0x7U);
  download_.append(reinterpret_cast<const char*>(frame.data + 1), n);
  if (download_.size() > kMaxSegmentedBytes) return refuse(abort::kOutOfMemory);
  if (download_size_ != 0 && download_.size() > download_size_)
    return refuse(abort::kLengthTooHigh);
  const bool last = (frame.data[0] & 0x01U) != 0U;
  if (last) {
    if (download_size_ != 0 && download_.size() < download_size_)
      return refuse(abort::kLengthTooLow);
    if (const std::uint32_t code = store_download(download_index_, download_sub_, download_, now_s);
        code != 0U)
      return refuse(code);
    downloading_ = false;
  }
  download_toggle_ = !download_toggle_;
  can_frame f{};
  f.can_id = canopen::sdo_response_id(config_.node);
  f.len = 8;
  f.data[0] = static_cast<std::uint8_t>(0x20U | (toggle ? 0x10U : 0U));
  send(f);
}

void Cia402Drive::on_sdo(const can_frame& frame, double now_s) {
  namespace abort = canopen::sdo_abort;
  canopen::SdoResponse r;
  if (frame.len >= 4) {
    r.index = static_cast<std::uint16_t>(frame.data[1] | (frame.data[2] << 8U));
    r.subindex = frame.data[3];
  }
  const auto fail = [&](std::uint32_t code) {
    r.abort = true;
    r.abort_code = code;
    send(canopen::encode_response(config_.node, r));
  };
  if (frame.len == 8 && (frame.data[0] & 0xEFU) == 0x60U) return upload_segment(frame);
  if (frame.len == 8 && frame.data[0] == 0x80U) {  // the client aborts
    uploading_ = false;
    downloading_ = false;
    return;
  }
  if (frame.len == 8 && (frame.data[0] & 0xE0U) == 0x00U) return download_segment(frame, now_s);
  uploading_ = false;
  downloading_ = false;
  if (frame.len == 8 && (frame.data[0] & 0xE2U) == 0x20U) return initiate_download(frame, now_s);
  if (frame.len == 8 && (frame.data[0] & 0xE3U) == 0x23U) {
    // Expedited of 1..4 bytes into a string object.
    const auto index = static_cast<std::uint16_t>(frame.data[1] | (frame.data[2] << 8U));
    const eds::Entry* e = eds_->entry(index, frame.data[3]);
    if (e != nullptr && eds::is_string(e->data_type)) {
      const std::size_t n = 4U - ((frame.data[0] >> 2U) & 0x3U);
      const std::uint32_t code =
          store_download(index, frame.data[3],
                         std::string(reinterpret_cast<const char*>(frame.data + 4), n), now_s);
      if (code != 0U) return fail(code);
      r.write_confirmed = true;
      return send(canopen::encode_response(config_.node, r));
    }
  }
  const auto request = canopen::decode_request(frame);
  if (!request) return fail(abort::kCommandSpecifier);
  const canopen::SdoRequest& q = *request;
  const eds::Entry* e = eds_->entry(q.index, q.subindex);
  if (e == nullptr)
    return fail(eds_->object(q.index) != nullptr ? abort::kNoSubindex : abort::kNoObject);
  const int bits = eds::bit_size(e->data_type);
  const auto bytes = static_cast<std::uint8_t>(bits <= 8 ? 1 : bits / 8);
  if (!q.write) {
    if (e->access == eds::Access::wo) return fail(abort::kWriteOnly);
    if (eds::is_string(e->data_type)) {
      upload_ = text_of(q.index, q.subindex);
      if (upload_.size() <= 4) {
        can_frame f{};
        f.can_id = canopen::sdo_response_id(config_.node);
        f.len = 8;
        f.data[0] = static_cast<std::uint8_t>(0x43U | ((4U - upload_.size()) << 2U));
        f.data[1] = frame.data[1];
        f.data[2] = frame.data[2];
        f.data[3] = frame.data[3];
        // Byte by byte within the frame's 4 data bytes (GCC 12 at -O3 cannot see the size check
        // above through std::copy and warns of an overflow, -Wstringop-overflow).
        for (std::size_t k = 0; k < upload_.size() && k < 4; ++k)
          f.data[4 + k] = static_cast<std::uint8_t>(upload_[k]);
        return send(f);
      }
      can_frame f{};  // initiate a segmented upload, size indicated
      f.can_id = canopen::sdo_response_id(config_.node);
      f.len = 8;
      f.data[0] = 0x41;
      f.data[1] = frame.data[1];
      f.data[2] = frame.data[2];
      f.data[3] = frame.data[3];
      const auto size = static_cast<std::uint32_t>(upload_.size());
      for (int b = 0; b < 4; ++b)
        f.data[4 + b] = static_cast<std::uint8_t>(size >> (8U * static_cast<unsigned>(b)));
      upload_at_ = 0;
      upload_toggle_ = false;
      uploading_ = true;
      return send(f);
    }
    if (bits <= 0 || bits > 32) return fail(abort::kUnsupportedAccess);
    r.value = static_cast<std::uint32_t>(read_object(q.index, q.subindex) & width_mask(bits));
    r.size = bytes;
    return send(canopen::encode_response(config_.node, r));
  }
  if (!eds::writable(e->access)) return fail(abort::kReadOnly);
  if (bits <= 0 || bits > 32) return fail(abort::kUnsupportedAccess);
  if (q.size != bytes) return fail(abort::kLengthMismatch);
  const std::uint64_t raw = q.value & width_mask(bits);
  if (eds::out_of_range(*e, raw)) {
    const std::int64_t value = eds::as_signed(*e, raw);
    return fail(e->high_limit && value > *e->high_limit ? abort::kValueTooHigh
                : e->low_limit && value < *e->low_limit ? abort::kValueTooLow
                                                        : abort::kValueRange);
  }
  if (const std::uint32_t code = write_object(q.index, q.subindex, raw, now_s); code != 0)
    return fail(code);
  r.write_confirmed = true;
  send(canopen::encode_response(config_.node, r));
}

void Cia402Drive::on_frame(const can_frame& frame, double now_s) {
  if (silent_ || (frame.can_id & (CAN_ERR_FLAG | CAN_EFF_FLAG | CAN_RTR_FLAG)) != 0U) return;
  const canopen::CobId id = canopen::split_id(frame.can_id);
  if (id.function == canopen::kNmtId) return on_nmt(frame, now_s);
  if (id.function == canopen::kSyncId && id.node == 0) return on_sync(now_s);
  if (id.function == 0x700U && id.node != config_.node) return on_heartbeat(frame, now_s);
  if (nmt_ == NmtState::boot_up || nmt_ == NmtState::stopped) return;
  if (frame.can_id == canopen::sdo_request_id(config_.node)) return on_sdo(frame, now_s);
  if (nmt_ != NmtState::operational) return;
  for (ActivePdo& p : rpdos_) {
    if (p.id != frame.can_id) continue;
    if (p.transmission <= 240) {
      p.pending = true;
      p.frame = frame;
    } else {
      apply_rpdo(p, frame, now_s);
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
    for (ActivePdo& p : tpdos_) {
      if (p.transmission < transmission::kEventManufacturer) continue;
      if (p.sent && now_s - p.last_sent_s < p.inhibit_s) continue;
      const bool timer = p.event_timer_s > 0.0 && now_s - p.last_sent_s >= p.event_timer_s;
      send_tpdo(p, now_s, !timer);
    }
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
  if (state_ == DriveState::operation_enabled && mode_ == canopen::kModeHoming) {
    homing_step(dt);
  } else if (state_ == DriveState::operation_enabled) {
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
