/// @file
/// Planning and checking a drive's configuration against its EDS (see drive_setup.hpp).
#include "mrroc/can/drive_setup.hpp"

#include <cstdio>

#include "mrroc/can/canopen.hpp"
#include "mrroc/config/check.hpp"

namespace mrroc::can {

extern const char* const kDefaultDriveEdsText;  // default_eds.cpp, generated from the file
extern const char* const kDefaultDriveEdsName;

std::string PdoPlan::name() const { return (receive ? "RPDO" : "TPDO") + std::to_string(number); }

namespace {

const char* known_name(std::uint16_t index, std::uint8_t sub) {
  switch (index) {
    case 0x1000: return "device type";
    case 0x1006: return "communication cycle period";
    case 0x1008: return "manufacturer device name";
    case 0x1016: return "consumer heartbeat time";
    case 0x1017: return "producer heartbeat time";
    case 0x1018:
      return sub == 1   ? "vendor-ID"
             : sub == 2 ? "product code"
             : sub == 3 ? "revision number"
                        : "identity object";
    case 0x1029: return "error behaviour";
    case 0x6007: return "abort connection option code";
    case 0x6040: return "controlword";
    case 0x6041: return "statusword";
    case 0x605A: return "quick stop option code";
    case 0x6060: return "modes of operation";
    case 0x6061: return "modes of operation display";
    case 0x6064: return "position actual value";
    case 0x6065: return "following error window";
    case 0x6066: return "following error time out";
    case 0x606C: return "velocity actual value";
    case 0x6077: return "torque actual value";
    case 0x607A: return "target position";
    case 0x6085: return "quick stop deceleration";
    case 0x60C1: return "interpolation data record";
    case 0x60C2: return "interpolation time period";
    case 0x60FD: return "digital inputs";
    case 0x60FE: return "digital outputs";
    case 0x60FF: return "target velocity";
    case 0x6502: return "supported drive modes";
    default: break;
  }
  if (index >= 0x1400 && index < 0x1600) return "RPDO communication parameter";
  if (index >= 0x1600 && index < 0x1800) return "RPDO mapping parameter";
  if (index >= 0x1800 && index < 0x1A00) return "TPDO communication parameter";
  if (index >= 0x1A00 && index < 0x1C00) return "TPDO mapping parameter";
  return nullptr;
}

}  // namespace

std::string object_name(const eds::Dictionary* eds, std::uint16_t index, std::uint8_t sub) {
  char id[24];
  const eds::Object* o = eds != nullptr ? eds->object(index) : nullptr;
  if (o != nullptr && o->object_type != eds::kVar)
    std::snprintf(id, sizeof id, "0x%04X sub %u", index, sub);
  else if (o == nullptr && sub != 0)
    std::snprintf(id, sizeof id, "0x%04X sub %u", index, sub);
  else
    std::snprintf(id, sizeof id, "0x%04X", index);
  std::string name;
  if (const eds::Entry* e = eds != nullptr ? eds->entry(index, sub) : nullptr;
      e && !e->name.empty())
    name = e->name;
  else if (const char* k = known_name(index, sub))
    name = k;
  return name.empty() ? std::string(id) : std::string(id) + " (" + name + ")";
}

std::shared_ptr<const eds::Dictionary> default_drive_eds() {
  static const std::shared_ptr<const eds::Dictionary> d = std::make_shared<eds::Dictionary>(
      eds::Dictionary::parse(kDefaultDriveEdsText, kDefaultDriveEdsName));
  return d;
}

DrivePlan plan_drive(std::shared_ptr<const eds::Dictionary> eds, const DriveRequest& request) {
  ConfigErrorList errors;
  DrivePlan plan;
  plan.eds = eds;
  plan.node = request.node;
  plan.axis = request.axis;
  plan.identity = request.identity;
  const eds::Dictionary& d = *eds;
  const std::string who = "node " + std::to_string(request.node) + " (axis '" + request.axis + "')";
  const auto problem = [&](const SourceLocation& where, const std::string& text) {
    errors.add(ConfigError(where, who + ": " + text));
  };
  const auto name = [&](std::uint16_t index, std::uint8_t sub) {
    return object_name(&d, index, sub);
  };
  // A required object: its absence is the config's problem (the file has no line for it).
  const auto need = [&](std::uint16_t index, std::uint8_t sub, bool write, bool map,
                        const std::string& why) -> const eds::Entry* {
    const eds::Entry* e = d.entry(index, sub);
    if (e == nullptr) {
      problem(request.where,
              d.file() + " has no object " + name(index, sub) + ", which mrroc " + why);
      return nullptr;
    }
    if (write && !eds::writable(e->access))
      problem(d.where(*e), name(index, sub) + " is '" + std::string(eds::to_string(e->access)) +
                               "' (AccessType), mrroc writes it: " + why);
    if (map && !e->pdo_mappable)
      problem(d.where(*e),
              name(index, sub) + " cannot be mapped (PDOMapping=0); mrroc maps it: " + why);
    return e;
  };
  // An optional object: when present, mrroc writes it, so it must be writable.
  const auto optional_writable = [&](std::uint16_t index, std::uint8_t sub) {
    if (const eds::Entry* e = d.entry(index, sub); e != nullptr && !eds::writable(e->access))
      problem(d.where(*e), name(index, sub) + " is '" + std::string(eds::to_string(e->access)) +
                               "' (AccessType), mrroc configures it at bring-up");
  };

  // Mode.
  const std::uint32_t supported = d.supported_modes();
  const auto supports = [&](std::int8_t m) {
    return supported == 0 || (supported & eds::mode_bit(m)) != 0U;
  };
  if (request.mode) {
    plan.mode = *request.mode;
    if (plan.mode != eds::mode::kCyclicSyncPosition &&
        plan.mode != eds::mode::kInterpolatedPosition)
      problem(request.where, "mode " + std::to_string(plan.mode) + " (" +
                                 std::string(eds::mode_name(plan.mode)) +
                                 "): mrroc drives in cyclic synchronous position (csp) or "
                                 "interpolated position (ip)");
    else if (!supports(plan.mode)) {
      const eds::Entry* e = d.entry(0x6502, 0);
      char bits[16];
      std::snprintf(bits, sizeof bits, "0x%08X", supported);
      problem(request.where, "the drive does not support " +
                                 std::string(eds::mode_name(plan.mode)) + " (0x6502 = " + bits +
                                 " at " + d.where(*e).str() + ")");
    }
  } else if (supports(eds::mode::kCyclicSyncPosition)) {
    plan.mode = eds::mode::kCyclicSyncPosition;
  } else if (supports(eds::mode::kInterpolatedPosition)) {
    plan.mode = eds::mode::kInterpolatedPosition;
  } else {
    char bits[16];
    std::snprintf(bits, sizeof bits, "0x%08X", supported);
    problem(request.where, std::string("the drive supports neither cyclic synchronous position ") +
                               "nor interpolated position (0x6502 = " + bits + " in " + d.file() +
                               ")");
  }
  const bool ip = plan.mode == eds::mode::kInterpolatedPosition;
  const PdoEntry target = ip ? PdoEntry{0x60C1, 1, 32} : PdoEntry{0x607A, 0, 32};

  if (const eds::Entry* e = need(0x1000, 0, false, false, "reads to see a CiA 402 drive")) (void)e;
  need(0x6040, 0, true, true, "sends the controlword every cycle");
  need(0x6041, 0, false, true, "reads the statusword every cycle");
  need(0x6060, 0, true, false, "sets the mode of operation");
  need(0x6064, 0, false, true, "reads the position every cycle");
  need(target.index, target.sub, true, true, "sends the position target every cycle");
  need(0x60FD, 0, false, true, "reads the home switch (bit 2) and the input lines from it");
  need(0x1016, 1, true, false, "makes the drive supervise the master's heartbeat");
  need(0x1017, 0, true, false, "sets the drive's heartbeat");
  for (const ObjectId& o : kOptionalObjects) optional_writable(o.index, o.sub);
  const bool outputs = request.outputs && d.entry(0x60FE, 1) != nullptr;
  if (outputs) {
    need(0x60FE, 1, true, true, "sends the output lines in RPDO2");
    need(0x60FE, 2, true, false, "sets the mask of the output lines");
  }

  const auto pdo = [&](bool receive, int number, std::uint32_t base, std::uint8_t type,
                       std::vector<PdoEntry> entries) {
    PdoPlan p;
    p.receive = receive;
    p.number = number;
    p.cob_id = base + request.node;
    p.transmission = type;
    p.entries = std::move(entries);
    const std::string why = "configures " + p.name();
    need(p.communication_index(), 1, true, false, why);
    need(p.communication_index(), 2, true, false, why);
    if (need(p.mapping_index(), 0, true, false, why) != nullptr)
      for (std::size_t k = 1; k <= p.entries.size(); ++k)
        need(p.mapping_index(), static_cast<std::uint8_t>(k), true, false,
             "maps " + object_name(&d, p.entries[k - 1].index, p.entries[k - 1].sub) + " into " +
                 p.name());
    for (const PdoEntry& m : p.entries)
      if (const eds::Entry* e = d.entry(m.index, m.sub);
          e != nullptr && eds::bit_size(e->data_type) != m.bits)
        problem(d.where(*e), name(m.index, m.sub) + " is " +
                                 std::string(eds::type_name(e->data_type)) + ", mrroc maps " +
                                 std::to_string(m.bits) + " bits of it");
    return p;
  };
  plan.target = pdo(true, 1, 0x200, transmission::kSyncEvery, {{0x6040, 0, 16}, target});
  if (outputs) plan.outputs = pdo(true, 2, 0x300, transmission::kSyncEvery, {{0x60FE, 1, 32}});
  plan.feedback =
      pdo(false, 1, 0x180, transmission::kSyncEvery, {{0x6064, 0, 32}, {0x60FD, 0, 32}});
  plan.statusword = pdo(false, 2, 0x280, transmission::kEventProfile, {{0x6041, 0, 16}});
  plan.statusword.event_timer_ms = canopen::kStatuswordEventTimerMs;
  need(plan.statusword.communication_index(), 5, true, false,
       "sets TPDO2's event timer (the statusword is sent when it changes and at least every " +
           std::to_string(canopen::kStatuswordEventTimerMs) + " ms)");
  for (int k = 1; k <= 512; ++k) {
    for (const bool receive : {true, false}) {
      const auto comm = static_cast<std::uint16_t>((receive ? 0x1400 : 0x1800) + k - 1);
      if (d.object(comm) == nullptr) continue;
      if (k == 1 || (k == 2 && (!receive || outputs))) continue;
      PdoPlan off;
      off.receive = receive;
      off.number = k;
      const auto cob = d.value(comm, 1, request.node);
      off.cob_id = static_cast<std::uint32_t>(cob.value_or(0)) | kPdoInvalid;
      const eds::Entry* e = d.entry(comm, 1);
      if (e != nullptr && !eds::writable(e->access) && cob && (*cob & kPdoInvalid) == 0U)
        problem(d.where(*e), off.name() + " is on by default and its COB-ID is '" +
                                 std::string(eds::to_string(e->access)) +
                                 "': mrroc cannot switch it off");
      plan.switched_off.push_back(off);
    }
  }

  // The config's own SDO writes.
  for (SdoWrite w : request.writes) {
    const eds::Entry* e = d.entry(w.index, w.sub);
    if (e == nullptr) {
      errors.add(ConfigError(
          w.where, who + ": " + d.file() + " has no object " + name(w.index, w.sub) + " to write"));
      continue;
    }
    if (!eds::writable(e->access)) {
      errors.add(ConfigError(w.where, who + ": " + name(w.index, w.sub) + " is '" +
                                          std::string(eds::to_string(e->access)) +
                                          "' (AccessType at " + d.where(*e).str() + ")"));
      continue;
    }
    const int bits = eds::bit_size(e->data_type);
    if (bits <= 0 || bits > 32 || bits % 8 != 0) {
      errors.add(ConfigError(w.where, who + ": " + name(w.index, w.sub) + " is " +
                                          std::string(eds::type_name(e->data_type)) +
                                          "; mrroc writes numbers of 8, 16 or 32 bits"));
      continue;
    }
    const auto v = static_cast<std::int64_t>(w.value);
    const std::int64_t lo = eds::is_signed(e->data_type) ? -(std::int64_t{1} << (bits - 1)) : 0;
    const std::int64_t hi = eds::is_signed(e->data_type) ? (std::int64_t{1} << (bits - 1)) - 1
                                                         : (std::int64_t{1} << bits) - 1;
    if (v < lo || v > hi) {
      errors.add(ConfigError(w.where, who + ": " + std::to_string(v) + " does not fit " +
                                          name(w.index, w.sub) + " (" +
                                          std::string(eds::type_name(e->data_type)) + ", " +
                                          std::to_string(lo) + ".." + std::to_string(hi) + ")"));
      continue;
    }
    w.value = static_cast<std::uint64_t>(v) & ((std::uint64_t{1} << bits) - 1U);
    if (const auto why = eds::out_of_range(*e, w.value)) {
      errors.add(ConfigError(w.where, who + ": " + name(w.index, w.sub) + " = " +
                                          std::to_string(v) + ": " + *why + " (" +
                                          d.where(*e).str() + ")"));
      continue;
    }
    w.size = static_cast<std::uint8_t>(bits / 8);
    plan.writes.push_back(w);
  }
  errors.throw_if_any();
  return plan;
}

}  // namespace mrroc::can
