/// @file
/// The CiA 402 master (see cia402_master.hpp).
#include "mrroc/can/cia402_master.hpp"

#include <linux/can/error.h>

#include <algorithm>
#include <climits>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <thread>

#include "mrroc/core/error.hpp"

namespace mrroc::can {

using canopen::DriveState;
namespace od = canopen::od;

namespace {
/// Cycles after a quick stop is released during which a drive may still report quick stop
/// active (its TPDOs sent before it processed the re-enabling RPDO).
constexpr std::uint64_t kQuickStopReleaseCycles = 5;

std::string hex(std::uint32_t value, int digits) {
  char buffer[16];
  std::snprintf(buffer, sizeof buffer, "0x%0*X", digits, value);
  return buffer;
}
}  // namespace

Cia402Master::Cia402Master(Bus& bus, std::vector<MasterAxis> axes, const MasterOptions& options)
    : bus_(bus),
      axes_(std::move(axes)),
      options_(options),
      status_(axes_.size()),
      targets_(axes_.size(), 0),
      velocities_(axes_.size(), 0),
      last_target_(axes_.size(), 0.0),
      target_before_(axes_.size(), 0.0),
      held_(axes_.size(), 0),
      outputs_(axes_.size(), 0),
      sent_outputs_(axes_.size(), -1) {
  if (axes_.empty()) throw HardwareError(bus_.url() + ": a CiA 402 master needs at least one axis");
  for (std::size_t i = 0; i < axes_.size(); ++i) {
    const MasterAxis& a = axes_[i];
    if (a.node < 1 || a.node > canopen::kMaxNode)
      throw HardwareError(bus_.url() + ": axis '" + a.name + "': node id " +
                          std::to_string(a.node) + " outside 1..127");
    for (std::size_t j = 0; j < i; ++j)
      if (axes_[j].node == a.node)
        throw HardwareError(bus_.url() + ": axes '" + axes_[j].name + "' and '" + a.name +
                            "' have the same node id " + std::to_string(a.node));
    if (a.node == options_.master_node)
      throw HardwareError(bus_.url() + ": axis '" + a.name + "': node id " +
                          std::to_string(a.node) +
                          " is the master's own node id (its heartbeat); choose another");
    if (!(a.counts_per_unit > 0.0) || !std::isfinite(a.counts_per_unit))
      throw HardwareError(bus_.url() + ": axis '" + a.name + "': counts_per_unit " +
                          std::to_string(a.counts_per_unit) + " must be a positive number");
  }
  if (options_.master_node < 1 || options_.master_node > canopen::kMaxNode)
    throw HardwareError(bus_.url() + ": master node id " + std::to_string(options_.master_node) +
                        " outside 1..127");
  if (options_.master_heartbeat_ms < 1 || options_.master_heartbeat_ms > 1000)
    throw HardwareError(bus_.url() + ": master heartbeat " +
                        std::to_string(options_.master_heartbeat_ms) + " ms outside 1..1000 ms");
  if (options_.heartbeat_consumer_ms <= options_.master_heartbeat_ms)
    throw HardwareError(bus_.url() + ": drives' heartbeat consumer time " +
                        std::to_string(options_.heartbeat_consumer_ms) +
                        " ms must exceed the master's heartbeat period " +
                        std::to_string(options_.master_heartbeat_ms) + " ms");
  enable_command_.assign(axes_.size(), canopen::controlword::kEnableOperation);
  controlword_override_.assign(axes_.size(), -1);
  homing_axis_.assign(axes_.size(), 0);
  reports_.assign(axes_.size(), std::string());
  for (std::size_t i = 0; i < axes_.size(); ++i) {
    MasterAxis& a = axes_[i];
    if (!a.plan.eds) {
      DriveRequest request;
      request.node = a.node;
      request.axis = a.name;
      request.outputs = options_.digital_lines;
      a.plan = plan_drive(default_drive_eds(), request);
    }
    if (a.plan.node != a.node)
      throw HardwareError(bus_.url() + ": axis '" + a.name + "': its drive plan is for node " +
                          std::to_string(a.plan.node) + ", the axis has node " +
                          std::to_string(a.node));
    if (a.plan.mode == canopen::kModeInterpolatedPosition)
      enable_command_[i] |= canopen::controlword::kEnableIpMode;
    // Configured quantities in drive units, refused here rather than at bring-up.
    (void)unsigned_counts(i, "following error window", a.following_error_window, "",
                          od::kFollowingErrorWindow);
    (void)unsigned_counts(i, "quick stop deceleration", a.quick_stop_deceleration, "/s^2",
                          od::kQuickStopDeceleration);
    rpdo_layouts_.push_back(layouts(a.plan, true));
    tpdo_layouts_.push_back(layouts(a.plan, false));
  }
  std::vector<DrivePlan> plans;
  for (const MasterAxis& a : axes_) plans.push_back(a.plan);
  try {
    check_pdo_identifiers(plans);
  } catch (const ConfigError& e) {
    throw HardwareError(bus_.url() + ": " + e.what());
  }
  const double ms = options_.period_s * 1000.0;
  if (!(ms >= 1.0) || std::abs(ms - std::round(ms)) > 1e-9 || ms > 255.0)
    throw HardwareError(bus_.url() + ": cycle " + std::to_string(options_.period_s) +
                        " s must be a whole number of milliseconds in 1..255 ms (0x60C2)");
}

std::vector<Cia402Master::Layout> Cia402Master::layouts(const DrivePlan& plan, bool receive) {
  std::vector<Layout> out;
  for (const PdoPlan& p : receive ? plan.rpdos : plan.tpdos) {
    Layout l;
    l.id = p.cob_id & CAN_SFF_MASK;
    l.bytes = static_cast<std::uint8_t>(p.bytes());
    unsigned shift = 0;
    for (const PdoEntry& m : p.entries) {
      Field f;
      f.shift = static_cast<std::uint8_t>(shift);
      f.bits = m.bits;
      shift += m.bits;
      const eds::Entry* e = plan.eds ? plan.eds->entry(m.index, m.sub) : nullptr;
      f.is_signed = e != nullptr && eds::is_signed(e->data_type);
      if (m.index == od::kControlword && m.sub == 0)
        f.role = Role::controlword;
      else if (m.index == plan.target.index && m.sub == plan.target.sub)
        f.role = Role::target;
      else if (m.index == od::kDigitalOutputs && m.sub == 1)
        f.role = Role::outputs;
      else if (m.index == od::kStatusword && m.sub == 0)
        f.role = Role::statusword;
      else if (m.index == od::kPositionActual && m.sub == 0)
        f.role = Role::position;
      else if (m.index == od::kDigitalInputs && m.sub == 0)
        f.role = Role::inputs;
      else if (m.index == od::kVelocityActual && m.sub == 0)
        f.role = Role::velocity;
      else if (m.index == od::kTorqueActual && m.sub == 0)
        f.role = Role::torque;
      if (receive && (f.role == Role::controlword || f.role == Role::target)) l.cyclic = true;
      if (receive && f.role == Role::outputs) l.outputs = true;
      l.fields.push_back(f);
    }
    out.push_back(std::move(l));
  }
  return out;
}

std::string Cia402Master::who(std::size_t axis) const {
  return bus_.url() + " node " + std::to_string(axes_[axis].node) + " (axis '" + axes_[axis].name +
         "')";
}

std::optional<std::int32_t> Cia402Master::counts(std::size_t axis, double position) const noexcept {
  const auto c = to_drive_units(position, axes_[axis].counts_per_unit, INT32_MIN, INT32_MAX);
  if (!c) return std::nullopt;
  return static_cast<std::int32_t>(*c);
}

std::uint32_t Cia402Master::unsigned_counts(std::size_t axis, const char* what, double value,
                                            const char* unit, std::uint16_t index) const {
  const MasterAxis& a = axes_[axis];
  const auto c = to_drive_units(value, a.counts_per_unit, 0, UINT32_MAX);
  if (!c) {
    char text[320];
    std::snprintf(text, sizeof text,
                  "%s %.6g %s%s is %.6g counts at counts_per_unit %.6g counts/%s, outside "
                  "0x%04X's range 0..4294967295 counts (UNSIGNED32)",
                  what, value, a.unit.c_str(), unit, value * a.counts_per_unit, a.counts_per_unit,
                  a.unit.c_str(), index);
    throw HardwareError(who(axis) + ": " + text);
  }
  return static_cast<std::uint32_t>(*c);
}

void Cia402Master::set_fault(std::size_t axis, const char* what) noexcept {
  if (faulted_) return;
  faulted_ = true;
  std::snprintf(fault_, sizeof fault_, "drive node %u (axis '%s') on %s: %s",
                static_cast<unsigned>(axes_[axis].node), axes_[axis].name.c_str(),
                bus_.url().c_str(), what);
}

void Cia402Master::handle(const Received& r) noexcept {
  if (r.is_error()) {
    if ((r.frame.can_id & CAN_ERR_BUSOFF) != 0U && !faulted_) {
      faulted_ = true;
      std::snprintf(fault_, sizeof fault_, "CAN bus %s: bus-off", bus_.url().c_str());
    }
    return;
  }
  // A TPDO, by its identifier (a config may give any COB-ID).
  for (std::size_t i = 0; i < axes_.size(); ++i)
    for (std::size_t k = 0; k < tpdo_layouts_[i].size(); ++k)
      if (tpdo_layouts_[i][k].id == r.frame.can_id) {
        decode_tpdo(i, k, r.frame);
        return;
      }
  const canopen::CobId id = canopen::split_id(r.frame.can_id);
  for (std::size_t i = 0; i < axes_.size(); ++i) {
    if (axes_[i].node != id.node) continue;
    DriveStatus& s = status_[i];
    if (r.frame.can_id == canopen::heartbeat_id(id.node) && r.frame.len == 1 &&
        r.frame.data[0] == static_cast<std::uint8_t>(canopen::NmtState::boot_up)) {
      // A drive that boots while it is driven has lost its configuration (a power cut, a reset
      // of its own): the axis is lost until a bring-up configures it again.
      if (enabled_) set_fault(i, "rebooted (boot-up message): its configuration is lost");
      return;
    }
    if (r.frame.can_id == canopen::emcy_id(id.node)) {
      const auto e = canopen::decode_emcy(r.frame);
      if (!e) return;
      s.last_emcy = e->code;
      if (e->code != canopen::emcy::kErrorReset && enabled_) {
        char text[160];
        const std::string_view what = canopen::describe_emcy(e->code);
        std::snprintf(text, sizeof text, "EMCY 0x%04X (%.*s), error register 0x%02X", e->code,
                      static_cast<int>(what.size()), what.data(), e->error_register);
        set_fault(i, text);
      }
    }
    return;
  }
}

void Cia402Master::decode_tpdo(std::size_t i, std::size_t k, const can_frame& frame) noexcept {
  const Layout& l = tpdo_layouts_[i][k];
  if (frame.len < l.bytes) return;  // shorter than its mapping: not processed (CiA 301)
  std::uint64_t data = 0;
  for (unsigned b = 0; b < frame.len && b < 8; ++b)
    data |= static_cast<std::uint64_t>(frame.data[b]) << (8U * b);
  DriveStatus& s = status_[i];
  const double position_before = s.position;
  bool position = false;
  bool statusword = false;
  std::uint16_t sw = 0;
  for (const Field& f : l.fields) {
    const std::uint64_t mask = f.bits >= 64 ? ~std::uint64_t{0} : (std::uint64_t{1} << f.bits) - 1U;
    const std::uint64_t raw = (data >> f.shift) & mask;
    std::int64_t value = static_cast<std::int64_t>(raw);
    if (f.is_signed && f.bits < 64 && (raw >> (f.bits - 1U)) != 0U)
      value = static_cast<std::int64_t>(raw | ~mask);  // sign-extended
    switch (f.role) {
      case Role::position:
        s.position = static_cast<double>(value) / axes_[i].counts_per_unit;
        position = true;
        break;
      case Role::inputs: {
        const auto inputs = static_cast<std::uint32_t>(raw);
        s.home_switch = (inputs & canopen::kHomeSwitchBit) != 0U;
        s.input_lines =
            static_cast<std::uint8_t>((inputs & canopen::kUserLineMask) >> canopen::kUserLineShift);
        break;
      }
      case Role::statusword:
        sw = static_cast<std::uint16_t>(raw);
        statusword = true;
        break;
      case Role::velocity:
        s.velocity_actual = static_cast<double>(value) / axes_[i].counts_per_unit;
        break;
      case Role::torque: s.torque_actual = static_cast<std::int16_t>(value); break;
      default: break;  // mapped by the config, not used by the servo loop
    }
  }
  if (position && s.last_tpdo_cycle != cycle_) {
    // The one before, for a velocity from the last two whoever reads them (a second position in
    // the same cycle replaces the first and keeps the pair's older end).
    s.previous_position = position_before;
    s.previous_tpdo_cycle = s.last_tpdo_cycle;
  }
  if (position) s.last_tpdo_cycle = cycle_;
  if (statusword) on_statusword(i, sw);
}

void Cia402Master::on_statusword(std::size_t i, std::uint16_t statusword) noexcept {
  DriveStatus& s = status_[i];
  s.statusword = statusword;
  s.state = canopen::decode_state(statusword);
  s.last_statusword_cycle = cycle_;
  if (!enabled_ || faulted_) return;
  char text[160];
  if (s.state == DriveState::fault || s.state == DriveState::fault_reaction_active) {
    const std::string_view what = canopen::describe_emcy(s.last_emcy);
    std::snprintf(text, sizeof text, "in fault (statusword 0x%04X, last EMCY 0x%04X %.*s)",
                  s.statusword, s.last_emcy, static_cast<int>(what.size()), what.data());
    set_fault(i, text);
  } else if (s.state != DriveState::operation_enabled && homing_axis_[i] == 0U &&
             !((quick_stopping_ || cycle_ < quick_stop_grace_until_) &&
               s.state == DriveState::quick_stop_active)) {
    const std::string_view state = canopen::to_string(s.state);
    std::snprintf(text, sizeof text, "left operation enabled by itself: %.*s",
                  static_cast<int>(state.size()), state.data());
    set_fault(i, text);
  }
}

void Cia402Master::receive() noexcept {
  Received r;
  while (bus_.receive(r, std::chrono::nanoseconds(0))) handle(r);
  if (!enabled_ || faulted_) return;
  for (std::size_t i = 0; i < axes_.size(); ++i) {
    const std::uint64_t silent = cycle_ - status_[i].last_tpdo_cycle;
    if (silent >= static_cast<std::uint64_t>(options_.silent_cycles)) {
      char text[128];
      std::snprintf(text, sizeof text, "silent: no TPDO for %llu cycles (%.0f ms)",
                    static_cast<unsigned long long>(silent),
                    static_cast<double>(silent) * options_.period_s * 1000.0);
      set_fault(i, text);
    }
  }
}

void Cia402Master::heartbeat_if_due() noexcept {
  const auto now = std::chrono::steady_clock::now();
  if (now < next_heartbeat_) return;
  (void)bus_.send(canopen::heartbeat_frame(options_.master_node, canopen::NmtState::operational));
  // On a fixed grid: scheduled from the time it was due, not the cycle that sent it (that made
  // the period one cycle longer on average, 12 instead of 10 ms at a 2 ms cycle). After a stall
  // the grid restarts from now, without a burst of heartbeats.
  const auto period = std::chrono::milliseconds(options_.master_heartbeat_ms);
  next_heartbeat_ += period;
  if (next_heartbeat_ <= now) next_heartbeat_ = now + period;
}

void Cia402Master::cycle_once(std::uint16_t controlword, std::span<const std::int32_t> targets) {
  for (std::size_t i = 0; i < axes_.size(); ++i) {
    targets_[i] = targets[i];
    const bool refresh =
        cycle_ % canopen::kOutputRefreshCycles == i % canopen::kOutputRefreshCycles;
    const bool outputs_due = has_outputs(i) && (refresh || sent_outputs_[i] != outputs_[i]);
    for (const Layout& l : rpdo_layouts_[i]) {
      if (!l.cyclic && !(l.outputs && outputs_due)) continue;
      std::uint64_t data = 0;
      for (const Field& f : l.fields) {
        std::uint64_t value = 0;
        switch (f.role) {
          case Role::controlword:
            value = controlword_override_[i] >= 0
                        ? static_cast<std::uint32_t>(controlword_override_[i])
                    : controlword == canopen::controlword::kEnableOperation ? enable_command_[i]
                                                                            : controlword;
            break;
          case Role::target:
            value = static_cast<std::uint32_t>(
                axes_[i].plan.mode == canopen::kModeCyclicSyncVelocity ? velocities_[i]
                                                                       : targets[i]);
            break;
          case Role::outputs:
            value = static_cast<std::uint32_t>(outputs_[i]) << canopen::kUserLineShift;
            break;
          default: break;
        }
        const std::uint64_t mask =
            f.bits >= 64 ? ~std::uint64_t{0} : (std::uint64_t{1} << f.bits) - 1U;
        data |= (value & mask) << f.shift;
      }
      can_frame frame{};
      frame.can_id = l.id;
      frame.len = l.bytes;
      for (unsigned b = 0; b < l.bytes; ++b)
        frame.data[b] = static_cast<std::uint8_t>(data >> (8U * b));
      const SendResult result = bus_.send(frame);
      if (result == SendResult::bus_off && !faulted_) {
        faulted_ = true;
        std::snprintf(fault_, sizeof fault_, "CAN bus %s: bus-off (send failed)",
                      bus_.url().c_str());
      }
      if (l.outputs && result == SendResult::sent && has_outputs(i)) sent_outputs_[i] = outputs_[i];
    }
  }
  (void)bus_.send(canopen::sync_frame());
  heartbeat_if_due();
  ++cycle_;
}

void Cia402Master::send(std::span<const double> targets, bool quick_stop) noexcept {
  const bool stop = quick_stop || faulted_;
  if (quick_stopping_ && !stop) {
    // Leaving quick stop: re-enable at the actual positions. TPDOs already on their way (one
    // cycle old, more on a slow bus or emulator) still say quick stop active for a few cycles.
    quick_stopping_ = false;
    quick_stop_grace_until_ = cycle_ + kQuickStopReleaseCycles;
    for (std::size_t i = 0; i < axes_.size(); ++i) {
      held_[i] = counts(i, status_[i].position).value_or(targets_[i]);
      velocities_[i] = 0;
      last_target_[i] = target_before_[i] = status_[i].position;
    }
    cycle_once(canopen::controlword::kEnableOperation, held_);
    return;
  }
  for (std::size_t i = 0; i < axes_.size(); ++i) {
    const std::optional<std::int32_t> c = counts(i, targets[i]);
    held_[i] = c.value_or(targets_[i]);  // beyond the range: the last target, and a fault
    if (!c) {
      char text[200];
      std::snprintf(text, sizeof text,
                    "target %.6g %s is %.6g counts at counts_per_unit %.6g counts/%s, outside "
                    "the drive's position range -2147483648..2147483647 counts (INTEGER32)",
                    targets[i], axes_[i].unit.c_str(), targets[i] * axes_[i].counts_per_unit,
                    axes_[i].counts_per_unit, axes_[i].unit.c_str());
      set_fault(i, text);
    }
    if (axes_[i].plan.mode == canopen::kModeCyclicSyncVelocity) {
      // The targets' difference over the period, plus a correction towards where the drive
      // should have been at the last SYNC (the target before the last: the velocity sent with
      // it was to bring the axis there by that SYNC), from a TPDO of that SYNC only.
      double velocity = (targets[i] - last_target_[i]) / options_.period_s;
      // Within a count the axis is where it should be (the target lies between two counts).
      const double error = target_before_[i] - status_[i].position;
      if (status_[i].last_tpdo_cycle == cycle_ && std::abs(error) * axes_[i].counts_per_unit > 1.0)
        velocity += error / (kCsvCorrectionCycles * options_.period_s);
      const auto v = to_drive_units(velocity, axes_[i].counts_per_unit, INT32_MIN, INT32_MAX);
      if (!v || !c) {
        if (c) {
          char text[200];
          std::snprintf(text, sizeof text,
                        "velocity %.6g %s/s is %.6g counts/s at counts_per_unit %.6g counts/%s, "
                        "outside the drive's velocity range -2147483648..2147483647 counts/s "
                        "(0x60FF, INTEGER32)",
                        velocity, axes_[i].unit.c_str(), velocity * axes_[i].counts_per_unit,
                        axes_[i].counts_per_unit, axes_[i].unit.c_str());
          set_fault(i, text);
        }
        velocities_[i] = 0;
      } else {
        velocities_[i] = static_cast<std::int32_t>(*v);
        target_before_[i] = last_target_[i];
        last_target_[i] = targets[i];
      }
    }
  }
  quick_stopping_ = stop || faulted_;
  if (quick_stopping_) std::fill(velocities_.begin(), velocities_.end(), 0);
  cycle_once(
      quick_stopping_ ? canopen::controlword::kQuickStop : canopen::controlword::kEnableOperation,
      held_);
}

canopen::SdoResponse Cia402Master::sdo_transfer(std::uint8_t node, const canopen::SdoRequest& q) {
  const auto what = [&] {
    return std::string(q.write ? "an SDO write of " + std::to_string(q.value) + " to "
                               : "an SDO read of ") +
           hex(q.index, 4) + ":" + std::to_string(q.subindex);
  };
  for (int attempt = 0; attempt < options_.sdo_attempts; ++attempt) {
    heartbeat_if_due();
    (void)bus_.send(canopen::encode_request(node, q));
    const auto deadline = std::chrono::steady_clock::now() + options_.sdo_timeout;
    Received r;
    for (;;) {
      // Keep the heartbeat going while waiting (the drives supervise it).
      heartbeat_if_due();
      const auto now = std::chrono::steady_clock::now();
      if (now >= deadline) break;
      if (!bus_.receive(r, std::min(deadline, next_heartbeat_) - now)) {
        if (std::chrono::steady_clock::now() >= deadline) break;
        continue;
      }
      if (r.frame.can_id != canopen::sdo_response_id(node)) {
        handle(r);
        continue;
      }
      const auto response = canopen::decode_response(r.frame);
      if (!response || response->index != q.index || response->subindex != q.subindex) continue;
      if (response->abort)
        throw HardwareError(bus_.url() + " node " + std::to_string(node) + ": " + what() +
                            " aborted: " + hex(response->abort_code, 8) + " " +
                            std::string(canopen::describe_sdo_abort(response->abort_code)));
      if (!q.write || response->write_confirmed) return *response;
    }
  }
  throw HardwareError(bus_.url() + " node " + std::to_string(node) + ": no answer to " + what() +
                      " (" + std::to_string(options_.sdo_attempts) + " attempts of " +
                      std::to_string(options_.sdo_timeout.count()) +
                      " ms; is the drive powered and on this bus?)");
}

std::uint32_t Cia402Master::sdo_read(std::uint8_t node, std::uint16_t index,
                                     std::uint8_t subindex) {
  canopen::SdoRequest q;
  q.index = index;
  q.subindex = subindex;
  return sdo_transfer(node, q).value;
}

void Cia402Master::sdo_write(std::uint8_t node, std::uint16_t index, std::uint8_t subindex,
                             std::uint32_t value, std::uint8_t size) {
  canopen::SdoRequest q;
  q.write = true;
  q.index = index;
  q.subindex = subindex;
  q.value = value;
  q.size = size;
  (void)sdo_transfer(node, q);
}

bool Cia402Master::sdo_frame(std::uint8_t node, can_frame& out) {
  const auto deadline = std::chrono::steady_clock::now() + options_.sdo_timeout;
  Received r;
  for (;;) {
    heartbeat_if_due();
    const auto now = std::chrono::steady_clock::now();
    if (now >= deadline) return false;
    if (!bus_.receive(r, std::min(deadline, next_heartbeat_) - now)) continue;
    if (r.frame.can_id != canopen::sdo_response_id(node)) {
      handle(r);
      continue;
    }
    out = r.frame;
    return true;
  }
}

std::string Cia402Master::sdo_read_bytes(std::uint8_t node, std::uint16_t index,
                                         std::uint8_t subindex) {
  const std::string what = "an SDO read of " + hex(index, 4) + ":" + std::to_string(subindex);
  const auto fail = [&](const std::string& why) {
    return HardwareError(bus_.url() + " node " + std::to_string(node) + ": " + what + " " + why);
  };
  can_frame q{};
  q.can_id = canopen::sdo_request_id(node);
  q.len = 8;
  q.data[0] = 0x40;
  q.data[1] = static_cast<std::uint8_t>(index);
  q.data[2] = static_cast<std::uint8_t>(index >> 8U);
  q.data[3] = subindex;
  (void)bus_.send(q);
  can_frame f{};
  for (;;) {
    if (!sdo_frame(node, f)) throw fail("got no answer");
    if (f.len == 8 && f.data[1] == q.data[1] && f.data[2] == q.data[2] && f.data[3] == subindex)
      break;
  }
  const auto u32 = [](const std::uint8_t* d) {
    return static_cast<std::uint32_t>(d[0]) | (static_cast<std::uint32_t>(d[1]) << 8U) |
           (static_cast<std::uint32_t>(d[2]) << 16U) | (static_cast<std::uint32_t>(d[3]) << 24U);
  };
  if (f.data[0] == 0x80U) {
    const std::uint32_t code = u32(f.data + 4);
    throw fail("aborted: " + hex(code, 8) + " " + std::string(canopen::describe_sdo_abort(code)));
  }
  if ((f.data[0] & 0xE2U) == 0x42U) {  // expedited
    const std::size_t n = (f.data[0] & 0x01U) != 0U ? 4U - ((f.data[0] >> 2U) & 0x3U) : 4U;
    return std::string(reinterpret_cast<const char*>(f.data + 4), n);
  }
  if ((f.data[0] & 0xE2U) != 0x40U) throw fail("got command specifier " + hex(f.data[0], 2));
  const std::size_t size = (f.data[0] & 0x01U) != 0U ? u32(f.data + 4) : 0U;
  std::string out;
  bool toggle = false;
  for (;;) {
    can_frame seg{};
    seg.can_id = canopen::sdo_request_id(node);
    seg.len = 8;
    seg.data[0] = static_cast<std::uint8_t>(0x60U | (toggle ? 0x10U : 0U));
    (void)bus_.send(seg);
    if (!sdo_frame(node, f))
      throw fail("got no answer to upload segment " + std::to_string(out.size() / 7));
    if (f.data[0] == 0x80U) {
      const std::uint32_t code = u32(f.data + 4);
      throw fail("aborted: " + hex(code, 8) + " " + std::string(canopen::describe_sdo_abort(code)));
    }
    if ((f.data[0] & 0xE0U) != 0x00U || ((f.data[0] & 0x10U) != 0U) != toggle)
      throw fail("got a segment out of order (" + hex(f.data[0], 2) + ")");
    const std::size_t n = 7U - ((f.data[0] >> 1U) & 0x7U);
    out.append(reinterpret_cast<const char*>(f.data + 1), n);
    if ((f.data[0] & 0x01U) != 0U) break;
    if (out.size() > 4096) throw fail("is longer than 4096 bytes");
    toggle = !toggle;
  }
  if (size != 0 && out.size() != size)
    throw fail("announced " + std::to_string(size) + " bytes and sent " +
               std::to_string(out.size()));
  return out;
}

void Cia402Master::sdo_write_bytes(std::uint8_t node, std::uint16_t index, std::uint8_t subindex,
                                   std::string_view data) {
  namespace abort = canopen::sdo_abort;
  const std::string what = "an SDO write of " + std::to_string(data.size()) + " bytes to " +
                           hex(index, 4) + ":" + std::to_string(subindex);
  const auto fail = [&](const std::string& why) {
    return HardwareError(bus_.url() + " node " + std::to_string(node) + ": " + what + " " + why);
  };
  const auto code_of = [](const can_frame& f) {
    return static_cast<std::uint32_t>(f.data[4]) | (static_cast<std::uint32_t>(f.data[5]) << 8U) |
           (static_cast<std::uint32_t>(f.data[6]) << 16U) |
           (static_cast<std::uint32_t>(f.data[7]) << 24U);
  };
  const auto aborted = [&](const can_frame& f, const std::string& when) {
    const std::uint32_t code = code_of(f);
    return fail("aborted" + when + ": " + hex(code, 8) + " " +
                std::string(canopen::describe_sdo_abort(code)));
  };
  // The client's own abort, so that the server forgets the transfer.
  const auto abort_transfer = [&](std::uint32_t code) {
    can_frame f{};
    f.can_id = canopen::sdo_request_id(node);
    f.len = 8;
    f.data[0] = 0x80;
    f.data[1] = static_cast<std::uint8_t>(index);
    f.data[2] = static_cast<std::uint8_t>(index >> 8U);
    f.data[3] = subindex;
    for (unsigned b = 0; b < 4; ++b) f.data[4 + b] = static_cast<std::uint8_t>(code >> (8U * b));
    (void)bus_.send(f);
  };
  if (data.size() > 0xFFFFFFFFU) throw fail("is longer than an SDO can carry");
  can_frame q{};
  q.can_id = canopen::sdo_request_id(node);
  q.len = 8;
  q.data[1] = static_cast<std::uint8_t>(index);
  q.data[2] = static_cast<std::uint8_t>(index >> 8U);
  q.data[3] = subindex;
  const bool expedited = !data.empty() && data.size() <= 4;
  if (expedited) {
    q.data[0] = static_cast<std::uint8_t>(0x23U | ((4U - data.size()) << 2U));
    std::copy(data.begin(), data.end(), q.data + 4);
  } else {
    q.data[0] = 0x21;  // initiate a segmented download, size indicated
    const auto size = static_cast<std::uint32_t>(data.size());
    for (unsigned b = 0; b < 4; ++b) q.data[4 + b] = static_cast<std::uint8_t>(size >> (8U * b));
  }
  (void)bus_.send(q);
  can_frame f{};
  for (;;) {
    if (!sdo_frame(node, f)) {
      abort_transfer(abort::kTimeout);
      throw fail("got no answer (" + std::to_string(options_.sdo_timeout.count()) + " ms)");
    }
    if (f.len == 8 && f.data[1] == q.data[1] && f.data[2] == q.data[2] && f.data[3] == subindex)
      break;
  }
  if (f.data[0] == 0x80U) throw aborted(f, "");
  if (f.data[0] != 0x60U) {
    abort_transfer(abort::kCommandSpecifier);
    throw fail("got command specifier " + hex(f.data[0], 2) + " (expected 0x60)");
  }
  if (expedited) return;
  bool toggle = false;
  std::size_t at = 0;
  std::size_t segment = 0;
  do {
    const std::size_t n = std::min<std::size_t>(7, data.size() - at);
    const bool last = at + n >= data.size();
    can_frame seg{};
    seg.can_id = canopen::sdo_request_id(node);
    seg.len = 8;
    seg.data[0] =
        static_cast<std::uint8_t>((toggle ? 0x10U : 0U) | ((7U - n) << 1U) | (last ? 1U : 0U));
    std::copy_n(data.begin() + static_cast<std::ptrdiff_t>(at), n, seg.data + 1);
    (void)bus_.send(seg);
    if (!sdo_frame(node, f)) {
      abort_transfer(abort::kTimeout);
      throw fail("got no answer to download segment " + std::to_string(segment));
    }
    if (f.data[0] == 0x80U) throw aborted(f, " at segment " + std::to_string(segment));
    if ((f.data[0] & 0xE0U) != 0x20U) {
      abort_transfer(abort::kCommandSpecifier);
      throw fail("got command specifier " + hex(f.data[0], 2) + " to download segment " +
                 std::to_string(segment));
    }
    if (((f.data[0] & 0x10U) != 0U) != toggle) {
      abort_transfer(abort::kToggleBit);
      throw fail("got an answer to download segment " + std::to_string(segment) +
                 " whose toggle bit did not alternate (" + hex(f.data[0], 2) + ")");
    }
    at += n;
    ++segment;
    toggle = !toggle;
  } while (at < data.size());
}

void Cia402Master::nmt_own_nodes(canopen::NmtCommand command) noexcept {
  for (const MasterAxis& a : axes_) (void)bus_.send(canopen::nmt_frame(command, a.node));
}

void Cia402Master::wait_boot_up(std::size_t i) {
  const std::uint8_t n = axes_[i].node;
  (void)bus_.send(canopen::nmt_frame(canopen::NmtCommand::reset_communication, n));
  const auto deadline = std::chrono::steady_clock::now() + options_.boot_up_timeout;
  Received r;
  for (;;) {
    heartbeat_if_due();
    const auto now = std::chrono::steady_clock::now();
    if (now >= deadline)
      throw HardwareError(who(i) + ": no boot-up message (" + hex(canopen::heartbeat_id(n), 3) +
                          " with 0x00) within " + std::to_string(options_.boot_up_timeout.count()) +
                          " ms of NMT reset communication; is the drive powered, on this bus, "
                          "at this node id and bit rate?");
    if (!bus_.receive(r, std::min(deadline, next_heartbeat_) - now)) continue;
    if (!r.is_error() && r.frame.can_id == canopen::heartbeat_id(n) && r.frame.len == 1 &&
        r.frame.data[0] == static_cast<std::uint8_t>(canopen::NmtState::boot_up))
      return;
    handle(r);
  }
}

void Cia402Master::write_checked(std::size_t i, std::uint16_t index, std::uint8_t sub,
                                 std::uint32_t value, std::uint8_t size) {
  const std::uint8_t n = axes_[i].node;
  sdo_write(n, index, sub, value, size);
  if (const std::uint32_t back = sdo_read(n, index, sub); back != value)
    throw HardwareError(who(i) + ": " + object_name(axes_[i].plan.eds.get(), index, sub) +
                        " reads back " + hex(back, 8) + " after writing " + hex(value, 8) +
                        " (see docs/hil.md)");
}

void Cia402Master::configure_pdo(std::size_t i, const PdoPlan& p) {
  const std::uint8_t n = axes_[i].node;
  const std::uint16_t comm = p.communication_index();
  const std::uint16_t map = p.mapping_index();
  // Read what the drive has; write only what differs (a DCF's drive is already right).
  const std::uint32_t cob = sdo_read(n, comm, 1);
  if (p.entries.empty()) {  // a PDO mrroc does not use: off
    if ((cob & kPdoInvalid) == 0U) {
      write_checked(i, comm, 1, cob | kPdoInvalid, 4);
      switched_off_.push_back(p.name());
    }
    return;
  }
  bool same = (cob & (kPdoInvalid | CAN_SFF_MASK)) == p.cob_id &&
              sdo_read(n, comm, 2) == p.transmission && sdo_read(n, map, 0) == p.entries.size() &&
              (p.event_timer_ms == 0 || sdo_read(n, comm, 5) == p.event_timer_ms);
  for (std::size_t k = 0; same && k < p.entries.size(); ++k)
    same = sdo_read(n, map, static_cast<std::uint8_t>(k + 1)) == p.entries[k].raw();
  if (same) return;
  written_.push_back(p.name());
  // CiA 301's order: the PDO off, its mapping emptied, the entries, their count, the
  // transmission type, the PDO on.
  write_checked(i, comm, 1, (cob & ~CAN_SFF_MASK) | kPdoInvalid | (p.cob_id & CAN_SFF_MASK), 4);
  write_checked(i, map, 0, 0, 1);
  for (std::size_t k = 0; k < p.entries.size(); ++k)
    write_checked(i, map, static_cast<std::uint8_t>(k + 1), p.entries[k].raw(), 4);
  write_checked(i, map, 0, static_cast<std::uint32_t>(p.entries.size()), 1);
  write_checked(i, comm, 2, p.transmission, 1);
  if (p.event_timer_ms != 0) write_checked(i, comm, 5, p.event_timer_ms, 2);
  write_checked(i, comm, 1, p.cob_id, 4);
}

void Cia402Master::configure_drive(std::size_t i) {
  const MasterAxis& a = axes_[i];
  const DrivePlan& plan = a.plan;
  const std::uint8_t n = a.node;
  written_.clear();
  switched_off_.clear();
  wait_boot_up(i);
  std::uint32_t type = 0;
  try {
    type = sdo_read(n, od::kDeviceType, 0);
  } catch (const HardwareError& e) {
    throw HardwareError("axis '" + a.name + "': " + e.what());
  }
  if ((type & 0xFFFFU) != 0x0192U)
    throw HardwareError(who(i) + ": device type " + hex(type, 8) +
                        " is not a CiA 402 drive (expected 0x....0192)");
  if (plan.identity) {
    const std::uint32_t vendor = sdo_read(n, od::kIdentity, 1);
    const std::uint32_t product = sdo_read(n, od::kIdentity, 2);
    const std::uint32_t revision = plan.identity->revision ? sdo_read(n, od::kIdentity, 3) : 0U;
    if (vendor != plan.identity->vendor || product != plan.identity->product ||
        (plan.identity->revision && revision != *plan.identity->revision)) {
      const auto text = [&](std::uint32_t v, std::uint32_t p, std::optional<std::uint32_t> r) {
        return "vendor " + hex(v, 8) + ", product " + hex(p, 8) +
               (r ? ", revision " + hex(*r, 8) : std::string());
      };
      throw HardwareError(
          who(i) + ": the drive is " +
          text(vendor, product,
               plan.identity->revision ? std::optional<std::uint32_t>(revision) : std::nullopt) +
          " (0x1018), the config expects " +
          text(plan.identity->vendor, plan.identity->product, plan.identity->revision) +
          " (its EDS: " + plan.eds->file() + ")");
    }
  }
  const std::uint16_t sw = static_cast<std::uint16_t>(sdo_read(n, od::kStatusword, 0));
  status_[i].statusword = sw;
  status_[i].state = canopen::decode_state(sw);
  if (canopen::decode_state(sw) == DriveState::fault) {
    sdo_write(n, od::kControlword, 0, canopen::controlword::kDisableVoltage, 2);
    sdo_write(n, od::kControlword, 0, canopen::controlword::kFaultReset, 2);
  }
  sdo_write(n, od::kControlword, 0, canopen::controlword::kDisableVoltage, 2);
  // PDOs: the drive's own first switched off (a default TPDO on the COB-ID mrroc maps must not
  // answer the SYNC while the mapping changes), then mrroc's.
  for (const PdoPlan& off : plan.switched_off) configure_pdo(i, off);
  for (const PdoPlan& p : plan.rpdos) {
    // Without digital lines an RPDO of the outputs alone is left as it is (never sent).
    const bool outputs_only = p.entries.size() == 1 && p.maps(od::kDigitalOutputs, 1);
    if (outputs_only && !options_.digital_lines) continue;
    configure_pdo(i, p);
  }
  for (const PdoPlan& p : plan.tpdos) configure_pdo(i, p);
  write_checked(i, od::kModesOfOperation, 0, static_cast<std::uint8_t>(plan.mode), 1);
  if (plan.has(od::kInterpolationPeriod, 1)) {
    sdo_write(n, od::kInterpolationPeriod, 1,
              static_cast<std::uint32_t>(std::lround(options_.period_s * 1000.0)), 1);
    if (plan.has(od::kInterpolationPeriod, 2))
      sdo_write(n, od::kInterpolationPeriod, 2, 0xFDU, 1);  // 10^-3 s
  }
  if (plan.has(od::kFollowingErrorWindow))
    sdo_write(n, od::kFollowingErrorWindow, 0,
              unsigned_counts(i, "following error window", a.following_error_window, "",
                              od::kFollowingErrorWindow),
              4);
  if (plan.has(od::kFollowingErrorTimeout))
    sdo_write(n, od::kFollowingErrorTimeout, 0, a.following_error_timeout_ms, 2);
  if (plan.has(od::kQuickStopDeceleration))
    sdo_write(n, od::kQuickStopDeceleration, 0,
              std::max(1U, unsigned_counts(i, "quick stop deceleration", a.quick_stop_deceleration,
                                           "/s^2", od::kQuickStopDeceleration)),
              4);
  sdo_write(n, od::kHeartbeatTime, 0, options_.heartbeat_ms, 2);
  // Supervision of the master: heartbeat consumer, SYNC period, reaction (see the header).
  const auto period_us = static_cast<std::uint32_t>(std::lround(options_.period_s * 1e6));
  const std::uint32_t consumer =
      (static_cast<std::uint32_t>(options_.master_node) << 16U) | options_.heartbeat_consumer_ms;
  const auto qs = [](std::int16_t v) {
    return static_cast<std::uint32_t>(static_cast<std::uint16_t>(v));
  };
  const struct {
    std::uint16_t index;
    std::uint8_t sub;
    std::uint32_t value;
    std::uint8_t size;
  } supervision[] = {
      {od::kCommunicationCyclePeriod, 0, period_us, 4},
      {od::kConsumerHeartbeatTime, 1, consumer, 4},
      {od::kErrorBehaviour, 1, canopen::error_behaviour::kNoChange, 1},
      {od::kAbortConnectionOption, 0, qs(canopen::abort_connection::kQuickStop), 2},
      {od::kQuickStopOption, 0, qs(canopen::quick_stop_option::kRampThenHold), 2},
      // Its digital outputs: the mask that lets them out, then the lines set so far.
      {od::kDigitalOutputs, 2, canopen::kUserLineMask, 4},
      {od::kDigitalOutputs, 1, static_cast<std::uint32_t>(outputs_[i]) << canopen::kUserLineShift,
       4},
  };
  for (const auto& o : supervision) {
    if (o.index == od::kDigitalOutputs && !has_outputs(i)) continue;
    if (!plan.has(o.index, o.sub)) continue;  // plan_drive required the ones that must be
    write_checked(i, o.index, o.sub, o.value, o.size);
  }
  for (const SdoWrite& w : plan.writes) {
    if (!w.text) {
      write_checked(i, w.index, w.sub, static_cast<std::uint32_t>(w.value), w.size);
      continue;
    }
    sdo_write_bytes(n, w.index, w.sub, *w.text);
    if (const std::string back = sdo_read_bytes(n, w.index, w.sub); back != *w.text)
      throw HardwareError(who(i) + ": " + object_name(plan.eds.get(), w.index, w.sub) +
                          " reads back '" + back + "' after writing '" + *w.text + "'");
  }
  const auto actual = static_cast<std::int32_t>(sdo_read(n, od::kPositionActual, 0));
  held_[i] = actual;
  status_[i].position = static_cast<double>(actual) / a.counts_per_unit;
  const std::uint32_t inputs = sdo_read(n, od::kDigitalInputs, 0);
  status_[i].home_switch = (inputs & canopen::kHomeSwitchBit) != 0U;
  status_[i].input_lines =
      static_cast<std::uint8_t>((inputs & canopen::kUserLineMask) >> canopen::kUserLineShift);
  status_[i].last_emcy = 0;
  sent_outputs_[i] = outputs_[i];
  const auto list = [](const std::vector<std::string>& names) {
    std::string out;
    for (const std::string& name : names) out += (out.empty() ? "" : ", ") + name;
    return out.empty() ? std::string("none") : out;
  };
  const std::string file = std::filesystem::path(plan.eds->file()).filename().string();
  reports_[i] = "node " + std::to_string(n) + " (axis '" + a.name + "'): " +
                (plan.eds->device().product_name.empty() ? std::string("drive")
                                                         : plan.eds->device().product_name) +
                " (" + file + "), " + std::string(eds::mode_name(plan.mode)) +
                "; PDOs written: " + list(written_) + "; switched off: " + list(switched_off_);
}

void Cia402Master::bring_up(std::chrono::milliseconds timeout) {
  enabled_ = false;
  homing_ = false;
  std::fill(controlword_override_.begin(), controlword_override_.end(), -1);
  std::fill(homing_axis_.begin(), homing_axis_.end(), 0);
  faulted_ = false;
  quick_stopping_ = false;
  fault_[0] = '\0';
  std::fill(velocities_.begin(), velocities_.end(), 0);
  // Configure every drive over SDO (pre-operational: no PDOs yet). Only this master's own nodes
  // are addressed: other drives on the bus (another robot's) keep their NMT state.
  nmt_own_nodes(canopen::NmtCommand::enter_pre_operational);
  for (std::size_t i = 0; i < axes_.size(); ++i) configure_drive(i);
  nmt_own_nodes(canopen::NmtCommand::start);
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  // Step the drives to operation enabled, holding them where they are.
  const auto period = std::chrono::duration<double>(options_.period_s);
  const std::uint16_t steps[] = {canopen::controlword::kShutdown, canopen::controlword::kSwitchOn,
                                 canopen::controlword::kEnableOperation};
  const DriveState expected[] = {DriveState::ready_to_switch_on, DriveState::switched_on,
                                 DriveState::operation_enabled};
  for (std::size_t step = 0; step < 3; ++step) {
    for (;;) {
      cycle_once(steps[step], held_);
      std::this_thread::sleep_for(period);
      Received r;
      while (bus_.receive(r, std::chrono::nanoseconds(0))) handle(r);
      bool all = true;
      for (std::size_t i = 0; i < axes_.size(); ++i)
        all = all && status_[i].state == expected[step] && status_[i].last_tpdo_cycle == cycle_;
      if (all) break;
      if (std::chrono::steady_clock::now() > deadline) {
        for (std::size_t i = 0; i < axes_.size(); ++i) {
          if (status_[i].last_tpdo_cycle != cycle_)
            throw HardwareError(who(i) +
                                ": no TPDO after SYNC while enabling (NMT start sent; "
                                "is the node operational?)");
          if (status_[i].state != expected[step])
            throw HardwareError(who(i) + ": did not reach '" +
                                std::string(canopen::to_string(expected[step])) + "' within " +
                                std::to_string(timeout.count()) + " ms; it is in '" +
                                std::string(canopen::to_string(status_[i].state)) +
                                "' (statusword " + hex(status_[i].statusword, 4) + ")");
        }
      }
    }
  }
  for (std::size_t i = 0; i < axes_.size(); ++i) {
    held_[i] = counts(i, status_[i].position).value_or(held_[i]);
    targets_[i] = held_[i];
    last_target_[i] = target_before_[i] = status_[i].position;
  }
  enabled_ = true;
}

bool Cia402Master::homes_by_drive() const noexcept {
  return std::any_of(axes_.begin(), axes_.end(),
                     [](const MasterAxis& a) { return a.plan.homing.has_value(); });
}

void Cia402Master::homing_cycle(bool quick_stop) {
  if (quick_stop) std::fill(controlword_override_.begin(), controlword_override_.end(), -1);
  cycle_once(quick_stop ? canopen::controlword::kQuickStop : canopen::controlword::kEnableOperation,
             held_);
  std::this_thread::sleep_for(std::chrono::duration<double>(options_.period_s));
  receive();
}

void Cia402Master::home(const std::atomic<bool>& stop) {
  namespace cw = canopen::controlword;
  namespace sw = canopen::statusword;
  using Clock = std::chrono::steady_clock;
  if (!enabled_ || faulted_)
    throw HardwareError(bus_.url() + ": homing needs every drive brought up and free of faults" +
                        (faulted_ ? std::string(" (") + fault_ + ")" : std::string()));
  std::vector<std::size_t> homing;
  for (std::size_t i = 0; i < axes_.size(); ++i)
    if (axes_[i].plan.homing) homing.push_back(i);
  if (homing.empty()) return;
  const Clock::time_point began = Clock::now();
  std::vector<std::optional<Clock::time_point>> started(axes_.size());
  const auto seconds = [&](std::size_t i) {
    return std::chrono::duration<double>(Clock::now() - started[i].value_or(began)).count();
  };
  const auto method = [&](std::size_t i) { return static_cast<int>(axes_[i].plan.homing->method); };
  const auto end_homing = [&] {
    homing_ = false;
    std::fill(controlword_override_.begin(), controlword_override_.end(), -1);
    std::fill(homing_axis_.begin(), homing_axis_.end(), 0);
  };
  // Ends the homing as a fault (unless one is already there: its text stands): every drive is
  // quick-stopped, the homing ones from their homing motion.
  const auto fail = [&](std::size_t i, const std::string& why) {
    char text[224];
    std::snprintf(text, sizeof text, "homing by method %d failed after %.2f s: %s", method(i),
                  seconds(i), why.c_str());
    const bool earlier = faulted_;
    set_fault(i, text);
    quick_stopping_ = true;
    for (int k = 0; k < 5; ++k) homing_cycle(true);
    end_homing();
    return HardwareError(earlier ? std::string(fault_) + "; " + who(i) + ": " + text
                                 : std::string(fault_));
  };
  const auto hex_text = [](std::uint32_t v, int digits) { return hex(v, digits); };
  // The drives whose homing has not ended yet (every homing drive before the start and after
  // the last has attained its home).
  std::vector<std::uint8_t> done(axes_.size(), 0);
  const auto still_homing = [&] {
    std::vector<std::size_t> out;
    for (const std::size_t i : homing)
      if (done[i] == 0U) out.push_back(i);
    return out.empty() ? homing : out;
  };
  // Ends the homing, naming the first drive still homing and the others after it.
  const auto fail_still_homing = [&](const std::string& why) {
    const std::vector<std::size_t> still = still_homing();
    std::string text = why;
    for (std::size_t k = 1; k < still.size(); ++k)
      text += (k == 1 ? "; still homing too: node " : ", node ") +
              std::to_string(axes_[still[k]].node) + " (axis '" + axes_[still[k]].name + "')";
    return fail(still.front(), text);
  };
  // One cycle, then: the stop, or a fault the cycle found, ends the homing.
  const auto cycle_checked = [&] {
    homing_cycle(false);
    if (stop.load(std::memory_order_relaxed))
      throw fail_still_homing("stopped by the emergency stop (quick stop)");
    if (faulted_) throw fail_still_homing("a fault while homing");
  };
  // An SDO write, read back, with a cycle after each transfer.
  const auto sdo_checked = [&](std::size_t i, std::uint16_t index, std::uint8_t sub,
                               std::uint32_t value, std::uint8_t size) {
    const std::uint8_t n = axes_[i].node;
    try {
      sdo_write(n, index, sub, value, size);
    } catch (const HardwareError& e) {
      throw fail(i, e.what());
    }
    cycle_checked();
    std::uint32_t back = 0;
    try {
      back = sdo_read(n, index, sub);
    } catch (const HardwareError& e) {
      throw fail(i, e.what());
    }
    if (back != value)
      throw fail(i, object_name(axes_[i].plan.eds.get(), index, sub) + " reads back " +
                        hex_text(back, 8) + " after writing " + hex_text(value, 8));
    cycle_checked();
  };
  // Waits for every homing drive to report `state`, stepping it there with `controlword` (-1:
  // the cycle's own enable operation, with the plan's mode's bits).
  const auto step_to = [&](std::int32_t controlword, DriveState state) {
    const std::uint64_t from = cycle_;
    for (const std::size_t i : homing) controlword_override_[i] = controlword;
    const auto deadline = Clock::now() + std::chrono::seconds(2);
    for (;;) {
      cycle_checked();
      bool all = true;
      for (const std::size_t i : homing)
        all = all && status_[i].state == state && status_[i].last_statusword_cycle > from;
      if (all) return;
      if (Clock::now() > deadline)
        for (const std::size_t i : homing)
          if (status_[i].state != state)
            throw fail(i, "did not reach '" + std::string(canopen::to_string(state)) +
                              "' within 2 s; it is in '" +
                              std::string(canopen::to_string(status_[i].state)) + "' (statusword " +
                              hex_text(status_[i].statusword, 4) + ")");
    }
  };
  const auto set_mode = [&](std::size_t i, std::int8_t mode) {
    const std::uint8_t n = axes_[i].node;
    try {
      sdo_write(n, od::kModesOfOperation, 0, static_cast<std::uint8_t>(mode), 1);
    } catch (const HardwareError& e) {
      throw fail(i, e.what());
    }
    cycle_checked();
    std::uint32_t shown = 0;
    try {
      shown = sdo_read(n, od::kModesDisplay, 0);
    } catch (const HardwareError& e) {
      throw fail(i, e.what());
    }
    if (static_cast<std::int8_t>(shown) != mode)
      throw fail(i, "0x6061 (modes of operation display) reads " +
                        std::to_string(static_cast<std::int8_t>(shown)) + " after 0x6060 = " +
                        std::to_string(mode) + " (" + std::string(eds::mode_name(mode)) + ")");
    cycle_checked();
  };

  homing_ = true;
  std::fill(velocities_.begin(), velocities_.end(), 0);
  // 1. The homing objects, each read back (a method the drive lacks is refused here, before
  // anything moves).
  for (const std::size_t i : homing) {
    const HomingPlan& h = *axes_[i].plan.homing;
    sdo_checked(i, od::kHomingMethod, 0, static_cast<std::uint8_t>(h.method), 1);
    sdo_checked(i, od::kHomingSpeeds, 1, h.switch_speed, 4);
    sdo_checked(i, od::kHomingSpeeds, 2, h.zero_speed, 4);
    sdo_checked(i, od::kHomingAcceleration, 0, h.acceleration, 4);
    sdo_checked(i, od::kHomeOffset, 0, static_cast<std::uint32_t>(h.offset), 4);
  }
  // 2. Homing mode, changed out of operation enabled (the brake holds meanwhile).
  for (const std::size_t i : homing) homing_axis_[i] = 1;
  step_to(cw::kSwitchOn, DriveState::switched_on);
  for (const std::size_t i : homing) set_mode(i, canopen::kModeHoming);
  step_to(cw::kEnableOperation, DriveState::operation_enabled);
  // 3. Homing operation start: bit 4 from 0 to 1. Only a statusword the drive sent after it saw
  // the start counts, and homing attained only once it was clear since (a drive may keep bit 12
  // from an earlier homing until it starts again).
  const std::uint64_t start_cycle = cycle_;
  std::vector<std::uint8_t> attained_before(axes_.size(), 0);
  for (const std::size_t i : homing) {
    attained_before[i] = (status_[i].statusword & sw::kHomingAttained) != 0U ? 1 : 0;
    controlword_override_[i] = cw::kEnableOperation | cw::kHomingStart;
    started[i] = Clock::now();
  }
  for (std::size_t remaining = homing.size(); remaining > 0;) {
    cycle_checked();
    for (const std::size_t i : homing) {
      if (done[i] != 0U) continue;
      const std::uint16_t word = status_[i].statusword;
      const bool fresh = status_[i].last_statusword_cycle >= start_cycle + 2;
      if (fresh && (word & sw::kHomingAttained) == 0U) attained_before[i] = 0;
      if (fresh && (word & sw::kHomingError) != 0U)
        throw fail(i, "the drive reports a homing error (statusword " + hex_text(word, 4) +
                          ": bit 13 set" +
                          ((word & sw::kTargetReached) != 0U ? ", at standstill)" : ", moving)"));
      if (fresh && attained_before[i] == 0U && (word & sw::kHomingAttained) != 0U &&
          (word & sw::kTargetReached) != 0U) {
        done[i] = 1;
        --remaining;
        continue;
      }
      if (seconds(i) > axes_[i].plan.homing->timeout_s) {
        char text[160];
        std::snprintf(text, sizeof text,
                      "no homing attained (statusword bit 12 with bit 10) within its timeout "
                      "of %.3g s (statusword 0x%04X)",
                      axes_[i].plan.homing->timeout_s, word);
        throw fail(i, text);
      }
    }
  }
  // 4. Back to the plan's mode, the target where the drive now is.
  for (const std::size_t i : homing) controlword_override_[i] = cw::kEnableOperation;
  cycle_checked();
  step_to(cw::kSwitchOn, DriveState::switched_on);
  for (const std::size_t i : homing) set_mode(i, axes_[i].plan.mode);
  const std::uint64_t settled = cycle_;
  for (bool fresh = false; !fresh;) {
    cycle_checked();
    fresh = true;
    for (const std::size_t i : homing) fresh = fresh && status_[i].last_tpdo_cycle > settled;
  }
  for (const std::size_t i : homing) {
    held_[i] = counts(i, status_[i].position).value_or(held_[i]);
    targets_[i] = held_[i];
    velocities_[i] = 0;
    last_target_[i] = target_before_[i] = status_[i].position;
  }
  step_to(-1, DriveState::operation_enabled);
  end_homing();
}

void Cia402Master::switch_outputs_off() noexcept {
  for (std::size_t i = 0; i < axes_.size(); ++i) {
    if (!has_outputs(i)) continue;
    if (outputs_[i] == 0 && sent_outputs_[i] <= 0) continue;  // never switched on
    try {
      sdo_write(axes_[i].node, od::kDigitalOutputs, 1, 0, 4);
      sent_outputs_[i] = 0;
    } catch (...) {
      // A drive that does not answer keeps what it had; nothing more can be done here.
    }
  }
}

void Cia402Master::shut_down() noexcept {
  enabled_ = false;
  quick_stopping_ = false;
  std::fill(velocities_.begin(), velocities_.end(), 0);
  for (std::size_t i = 0; i < axes_.size(); ++i)
    held_[i] = counts(i, status_[i].position).value_or(targets_[i]);
  try {
    cycle_once(canopen::controlword::kDisableVoltage, held_);
  } catch (...) {
  }
  nmt_own_nodes(canopen::NmtCommand::enter_pre_operational);
}

}  // namespace mrroc::can
