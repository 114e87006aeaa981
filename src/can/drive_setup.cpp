/// @file
/// Planning and checking a drive's configuration against its EDS (see drive_setup.hpp).
#include "mrroc/can/drive_setup.hpp"

#include <cmath>
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
    case 0x607C: return "home offset";
    case 0x6085: return "quick stop deceleration";
    case 0x6098: return "homing method";
    case 0x6099:
      return sub == 1   ? "speed during search for switch"
             : sub == 2 ? "speed during search for zero"
                        : "homing speeds";
    case 0x609A: return "homing acceleration";
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

std::optional<std::int64_t> to_drive_units(double value, double counts_per_unit,
                                           std::int64_t lowest, std::int64_t highest) noexcept {
  const double c = std::round(value * counts_per_unit);
  // Compared as doubles first: a double beyond the int64 range must never reach the cast.
  if (!std::isfinite(c) || c < static_cast<double>(lowest) || c > static_cast<double>(highest))
    return std::nullopt;
  if (c >= 9223372036854775808.0 || c < -9223372036854775808.0) return std::nullopt;  // 2^63
  const auto counts = static_cast<std::int64_t>(c);
  if (counts < lowest || counts > highest) return std::nullopt;  // rounding at the bounds
  return counts;
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
  const auto need_at = [&](const SourceLocation& at, std::uint16_t index, std::uint8_t sub,
                           bool write, bool map, const std::string& why) -> const eds::Entry* {
    const eds::Entry* e = d.entry(index, sub);
    if (e == nullptr) {
      problem(at, d.file() + " has no object " + name(index, sub) + ", which mrroc " + why);
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
  const auto need = [&](std::uint16_t index, std::uint8_t sub, bool write, bool map,
                        const std::string& why) {
    return need_at(request.where, index, sub, write, map, why);
  };
  // An optional object: when present, mrroc writes it, so it must be writable.
  const auto optional_writable = [&](std::uint16_t index, std::uint8_t sub) {
    if (const eds::Entry* e = d.entry(index, sub); e != nullptr && !eds::writable(e->access))
      problem(d.where(*e), name(index, sub) + " is '" + std::string(eds::to_string(e->access)) +
                               "' (AccessType), mrroc configures it at bring-up");
  };

  // Homing: the objects, the mode in 0x6502, each value in drive units within its object.
  const auto plan_homing = [&](const HomingRequest& h) -> std::optional<HomingPlan> {
    const SourceLocation& at = h.where;
    HomingPlan hp;
    hp.timeout_s = h.timeout_s;
    hp.where = at;
    bool ok = true;
    const std::string why =
        "writes at SYNCHRO to home the axis by the drive's homing mode (config 'homing')";
    const eds::Entry* modes = d.entry(0x6502, 0);
    char bits[16];
    std::snprintf(bits, sizeof bits, "0x%08X", d.supported_modes());
    if (modes == nullptr) {
      problem(at, d.file() +
                      " has no object 0x6502 (supported drive modes), so it does not say "
                      "that the drive has homing mode (6), which the config's 'homing' "
                      "asks for");
      ok = false;
    } else if ((d.supported_modes() & eds::mode_bit(eds::mode::kHoming)) == 0U) {
      problem(at, std::string("the drive does not support homing (6): 0x6502 = ") + bits + " at " +
                      d.where(*modes).str() +
                      " does not list it (bit 5), and the config's "
                      "'homing' asks for it");
      ok = false;
    }
    const eds::Entry* method = need_at(at, 0x6098, 0, true, false, why);
    const eds::Entry* switch_speed = need_at(at, 0x6099, 1, true, false, why);
    const eds::Entry* zero_speed = need_at(at, 0x6099, 2, true, false, why);
    const eds::Entry* acceleration = need_at(at, 0x609A, 0, true, false, why);
    const eds::Entry* offset = need_at(at, 0x607C, 0, true, false, why);
    if (const eds::Entry* display =
            need_at(at, 0x6061, 0, false, false, "reads it back after switching to homing mode");
        display != nullptr && !eds::readable(display->access))
      problem(d.where(*display), name(0x6061, 0) + " is '" +
                                     std::string(eds::to_string(display->access)) +
                                     "' (AccessType), mrroc reads it back");
    ok = ok && method && switch_speed && zero_speed && acceleration && offset;
    // A value in drive units, within the object's type and limits; `lowest` bounds the value in
    // the config's units (speeds and acceleration: positive where the method moves).
    const auto in_counts = [&](const eds::Entry* e, const char* what, double value,
                               const char* unit, std::int64_t lowest,
                               std::int64_t highest) -> std::optional<std::int64_t> {
      const auto c = to_drive_units(value, h.counts_per_unit, lowest, highest);
      char text[400];
      if (!c) {
        std::snprintf(text, sizeof text,
                      "homing %s %.6g %s%s is %.6g counts at counts_per_unit %.6g counts/%s, "
                      "outside %s's range %lld..%lld counts",
                      what, value, h.unit.c_str(), unit, value * h.counts_per_unit,
                      h.counts_per_unit, h.unit.c_str(), name(e->index, e->sub).c_str(),
                      static_cast<long long>(lowest), static_cast<long long>(highest));
        problem(at, text);
        return std::nullopt;
      }
      const int width = eds::bit_size(e->data_type);
      const std::uint64_t raw =
          static_cast<std::uint64_t>(*c) &
          (width >= 64 ? ~std::uint64_t{0} : (std::uint64_t{1} << width) - 1U);
      if (const auto bad = eds::out_of_range(*e, raw)) {
        std::snprintf(text, sizeof text, "homing %s %.6g %s%s is %lld counts: %s (%s at %s)", what,
                      value, h.unit.c_str(), unit, static_cast<long long>(*c), bad->c_str(),
                      name(e->index, e->sub).c_str(), d.where(*e).str().c_str());
        problem(at, text);
        return std::nullopt;
      }
      return c;
    };
    if (method != nullptr) {
      const std::uint64_t raw = static_cast<std::uint64_t>(h.method) & 0xFFU;
      if (h.method < -128 || h.method > 127) {
        problem(at, "homing method " + std::to_string(h.method) + " does not fit " +
                        name(0x6098, 0) + " (INTEGER8, -128..127)");
        ok = false;
      } else if (const auto bad = eds::out_of_range(*method, raw)) {
        problem(at, "homing method " + std::to_string(h.method) + ": " + *bad + " of " +
                        name(0x6098, 0) + " (" + d.where(*method).str() + ")");
        ok = false;
      } else {
        hp.method = static_cast<std::int8_t>(h.method);
      }
    }
    // Methods 35 and 37 (the current position is home) move nothing: their speeds are unused.
    const bool moves = h.method != 35 && h.method != 37;
    const std::int64_t least = moves ? 1 : 0;
    if (switch_speed != nullptr) {
      const auto c =
          in_counts(switch_speed, "switch search speed", h.switch_speed, "/s", least, UINT32_MAX);
      ok = ok && c.has_value();
      if (c) hp.switch_speed = static_cast<std::uint32_t>(*c);
    }
    if (zero_speed != nullptr) {
      const auto c =
          in_counts(zero_speed, "zero search speed", h.zero_speed, "/s", least, UINT32_MAX);
      ok = ok && c.has_value();
      if (c) hp.zero_speed = static_cast<std::uint32_t>(*c);
    }
    if (acceleration != nullptr) {
      const auto c =
          in_counts(acceleration, "acceleration", h.acceleration, "/s^2", least, UINT32_MAX);
      ok = ok && c.has_value();
      if (c) hp.acceleration = static_cast<std::uint32_t>(*c);
    }
    if (offset != nullptr) {
      const auto c = in_counts(offset, "offset", h.offset, "", INT32_MIN, INT32_MAX);
      ok = ok && c.has_value();
      if (c) hp.offset = static_cast<std::int32_t>(*c);
    }
    if (!(h.timeout_s > 0.0) || !std::isfinite(h.timeout_s)) {
      char text[160];
      std::snprintf(text, sizeof text, "homing timeout %.6g s must be a positive number of seconds",
                    h.timeout_s);
      problem(at, text);
      ok = false;
    }
    if (!ok) return std::nullopt;
    return hp;
  };

  // Mode.
  const std::uint32_t supported = d.supported_modes();
  const auto supports = [&](std::int8_t m) {
    return supported == 0 || (supported & eds::mode_bit(m)) != 0U;
  };
  if (request.mode) {
    plan.mode = *request.mode;
    if (plan.mode != eds::mode::kCyclicSyncPosition &&
        plan.mode != eds::mode::kInterpolatedPosition &&
        plan.mode != eds::mode::kCyclicSyncVelocity)
      problem(request.where, "mode " + std::to_string(plan.mode) + " (" +
                                 std::string(eds::mode_name(plan.mode)) +
                                 "): mrroc drives in cyclic synchronous position (csp), "
                                 "interpolated position (ip) or cyclic synchronous velocity "
                                 "(csv)");
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
  plan.target = plan.mode == eds::mode::kInterpolatedPosition ? PdoEntry{0x60C1, 1, 32}
                : plan.mode == eds::mode::kCyclicSyncVelocity ? PdoEntry{0x60FF, 0, 32}
                                                              : PdoEntry{0x607A, 0, 32};
  const PdoEntry target = plan.target;

  need(0x1000, 0, false, false, "reads to see a CiA 402 drive");
  need(0x6040, 0, true, true, "sends the controlword every cycle");
  need(0x6041, 0, false, true, "reads the statusword every cycle");
  need(0x6060, 0, true, false, "sets the mode of operation");
  need(0x6064, 0, false, true, "reads the position every cycle");
  need(target.index, target.sub, true, true,
       plan.mode == eds::mode::kCyclicSyncVelocity ? "sends the velocity target every cycle"
                                                   : "sends the position target every cycle");
  need(0x60FD, 0, false, true, "reads the home switch (bit 2) and the input lines from it");
  need(0x1016, 1, true, false, "makes the drive supervise the master's heartbeat");
  need(0x1017, 0, true, false, "sets the drive's heartbeat");
  for (const ObjectId& o : kOptionalObjects) optional_writable(o.index, o.sub);
  const bool outputs = request.outputs && d.entry(0x60FE, 1) != nullptr;
  bool config_rpdos = false;
  bool config_tpdos = false;
  for (const PdoRequest& r : request.pdos) (r.receive ? config_rpdos : config_tpdos) = true;
  if (outputs) {
    if (!config_rpdos) need(0x60FE, 1, true, true, "sends the output lines in RPDO2");
    need(0x60FE, 2, true, false, "sets the mask of the output lines");
  }

  // The PDO's communication and mapping objects, and its entries' widths.
  const auto pdo_objects = [&](const PdoPlan& p, const SourceLocation& at) {
    const std::string why = "configures " + p.name();
    need_at(at, p.communication_index(), 1, true, false, why);
    need_at(at, p.communication_index(), 2, true, false, why);
    if (p.event_timer_ms != 0)
      need_at(at, p.communication_index(), 5, true, false,
              "sets " + p.name() + "'s event timer (" + std::to_string(p.event_timer_ms) + " ms)");
    if (need_at(at, p.mapping_index(), 0, true, false, why) != nullptr)
      for (std::size_t k = 1; k <= p.entries.size(); ++k)
        need_at(at, p.mapping_index(), static_cast<std::uint8_t>(k), true, false,
                "maps " + object_name(&d, p.entries[k - 1].index, p.entries[k - 1].sub) + " into " +
                    p.name() + " (entry " + std::to_string(k) + ")");
  };
  const auto predefined_cob = [&](bool receive, int number) -> std::uint32_t {
    if (number < 1 || number > 4) return 0;
    return static_cast<std::uint32_t>((receive ? 0x200 : 0x180) + 0x100 * (number - 1)) +
           request.node;
  };
  const auto mrroc_pdo = [&](bool receive, int number, std::uint8_t type,
                             std::vector<PdoEntry> entries) {
    PdoPlan p;
    p.receive = receive;
    p.number = number;
    p.cob_id = predefined_cob(receive, number);
    p.transmission = type;
    p.entries = std::move(entries);
    pdo_objects(p, request.where);
    for (const PdoEntry& m : p.entries)
      if (const eds::Entry* e = d.entry(m.index, m.sub);
          e != nullptr && eds::bit_size(e->data_type) != m.bits)
        problem(d.where(*e), name(m.index, m.sub) + " is " +
                                 std::string(eds::type_name(e->data_type)) + ", mrroc maps " +
                                 std::to_string(m.bits) + " bits of it");
    return p;
  };

  // The config's PDOs, each checked against the file at its row.
  for (std::size_t k = 0; k < request.pdos.size(); ++k) {
    const PdoRequest& r = request.pdos[k];
    PdoPlan p;
    p.receive = r.receive;
    p.number = r.number;
    p.transmission = r.transmission;
    p.event_timer_ms = r.event_timer_ms;
    p.where = r.where;
    const auto bad = [&](const std::string& text) { problem(r.where, p.name() + ": " + text); };
    if (r.number < 1 || r.number > 512) {
      problem(r.where, std::string(r.receive ? "RPDO" : "TPDO") + " number " +
                           std::to_string(r.number) + " is outside 1..512");
      continue;
    }
    const PdoRequest* earlier = nullptr;
    for (std::size_t j = 0; j < k && earlier == nullptr; ++j)
      if (request.pdos[j].receive == r.receive && request.pdos[j].number == r.number)
        earlier = &request.pdos[j];
    if (earlier != nullptr) {
      bad("given twice for this node (first at " + earlier->where.str() + ")");
      continue;
    }
    if (d.object(p.communication_index()) == nullptr) {
      bad(d.file() + " has no " + p.name() + " (no object " + name(p.communication_index(), 1) +
          ")");
      continue;
    }
    if (r.cob_id == 0) {
      p.cob_id = predefined_cob(r.receive, r.number);
      if (p.cob_id == 0) bad("has no predefined COB-ID (only PDOs 1..4 do): give one");
    } else if (r.cob_id > CAN_SFF_MASK) {
      char text[96];
      std::snprintf(text, sizeof text, "COB-ID 0x%X is not an 11-bit identifier (0x001..0x7FF)",
                    r.cob_id);
      bad(text);
    } else {
      p.cob_id = r.cob_id;
    }
    if (r.transmission > 240 && r.transmission < transmission::kEventManufacturer)
      bad("transmission type " + std::to_string(r.transmission) +
          " is not one mrroc uses (0..240 synchronous, 254/255 event-driven; 241..251 are "
          "reserved, 252/253 need remote frames)");
    if (r.event_timer_ms != 0) {
      if (r.receive)
        bad("an event timer of " + std::to_string(r.event_timer_ms) +
            " ms: mrroc gives RPDOs none (0)");
      else if (r.transmission < transmission::kEventManufacturer)
        bad("an event timer of " + std::to_string(r.event_timer_ms) +
            " ms with transmission "
            "type " +
            std::to_string(r.transmission) +
            ": only event-driven TPDOs (254, 255) "
            "have one");
    }
    if (r.entries.empty()) bad("maps nothing (leave it out: the PDOs not listed are off)");
    int bits = 0;
    bool entries_ok = true;
    for (PdoEntry m : r.entries) {
      const eds::Entry* e = d.entry(m.index, m.sub);
      const std::string obj = name(m.index, m.sub);
      if (e == nullptr) {
        bad(d.file() + " has no object " + obj + " to map");
        entries_ok = false;
        continue;
      }
      const std::string at = " (" + d.where(*e).str() + ")";
      const int width = eds::bit_size(e->data_type);
      if (!e->pdo_mappable) {
        bad(obj + " cannot be mapped (PDOMapping=0" + at + ")");
        entries_ok = false;
      }
      if (r.receive && !eds::writable(e->access)) {
        bad(obj + " is '" + std::string(eds::to_string(e->access)) + "'" + at +
            ": an RPDO writes the objects it maps");
        entries_ok = false;
      } else if (!r.receive && !eds::readable(e->access)) {
        bad(obj + " is '" + std::string(eds::to_string(e->access)) + "'" + at +
            ": a TPDO reads the objects it maps");
        entries_ok = false;
      }
      if (width <= 0 || width > 64) {
        bad(obj + " is " + std::string(eds::type_name(e->data_type)) + at +
            ": mrroc maps objects of 1..64 bits");
        entries_ok = false;
        continue;
      }
      if (m.bits == 0) {
        m.bits = static_cast<std::uint8_t>(width);
      } else if (m.bits != width) {
        bad(obj + " is " + std::string(eds::type_name(e->data_type)) + ", " +
            std::to_string(width) + " bits" + at + "; the row maps " + std::to_string(m.bits) +
            " bits of it (mrroc maps whole objects)");
        entries_ok = false;
      }
      bits += m.bits;
      if (r.receive) {
        const bool known = (m.index == 0x6040 && m.sub == 0) ||
                           (m.index == target.index && m.sub == target.sub) ||
                           (outputs && m.index == 0x60FE && m.sub == 1);
        if (!known) {
          bad(obj + ": mrroc sends only the controlword (0x6040), the target of mode " +
              std::string(eds::mode_name(plan.mode)) + " (" + name(target.index, target.sub) + ")" +
              (outputs ? " and the digital outputs (0x60FE sub 1)" : std::string()) + " in RPDOs");
          entries_ok = false;
        }
      }
      p.entries.push_back(m);
    }
    if (bits > 64) {
      bad("maps " + std::to_string(bits) + " bits; a PDO carries at most 64 bits (8 bytes)");
      entries_ok = false;
    }
    if (!entries_ok || p.entries.empty()) {
      // Still counted as given, so that what it meant to map is not reported missing too.
      (r.receive ? plan.rpdos : plan.tpdos).push_back(p);
      continue;
    }
    pdo_objects(p, r.where);
    (r.receive ? plan.rpdos : plan.tpdos).push_back(p);
  }

  // mrroc's own PDOs where the config gives none.
  if (!config_rpdos) {
    plan.rpdos.push_back(mrroc_pdo(true, 1, transmission::kSyncEvery, {{0x6040, 0, 16}, target}));
    if (outputs)
      plan.rpdos.push_back(mrroc_pdo(true, 2, transmission::kSyncEvery, {{0x60FE, 1, 32}}));
  }
  if (!config_tpdos) {
    plan.tpdos.push_back(
        mrroc_pdo(false, 1, transmission::kSyncEvery, {{0x6064, 0, 32}, {0x60FD, 0, 32}}));
    PdoPlan status = mrroc_pdo(false, 2, transmission::kEventProfile, {{0x6041, 0, 16}});
    status.event_timer_ms = canopen::kStatuswordEventTimerMs;
    need(status.communication_index(), 5, true, false,
         "sets TPDO2's event timer (the statusword is sent when it changes and at least every " +
             std::to_string(canopen::kStatuswordEventTimerMs) + " ms)");
    plan.tpdos.push_back(status);
  }

  // What the servo loop needs must be mapped somewhere, and each object once in the RPDOs.
  const auto first_row = [&](bool receive) {
    for (const PdoRequest& r : request.pdos)
      if (r.receive == receive) return r.where;
    return request.where;
  };
  const auto mapped_in = [&](const std::vector<PdoPlan>& list, PdoEntry object) {
    const PdoPlan* found = nullptr;
    for (const PdoPlan& p : list)
      for (const PdoEntry& m : p.entries)
        if (m.index == object.index && m.sub == object.sub) {
          if (found != nullptr && found != &p && &list == &plan.rpdos)
            problem(p.where, name(object.index, object.sub) + " is mapped in both " +
                                 found->name() + " and " + p.name());
          if (found == nullptr) found = &p;
        }
    return found;
  };
  const auto required = [&](bool receive, PdoEntry object, const std::string& why) {
    const PdoPlan* p = mapped_in(receive ? plan.rpdos : plan.tpdos, object);
    if (p == nullptr && (receive ? config_rpdos : config_tpdos))
      problem(first_row(receive), std::string("no ") + (receive ? "RPDO" : "TPDO") +
                                      " of the config maps " + name(object.index, object.sub) +
                                      ", which mrroc " + why);
    return p;
  };
  required(true, {0x6040, 0, 16}, "sends every cycle");
  required(true, target,
           "sends every cycle (the target of " + std::string(eds::mode_name(plan.mode)) + ")");
  if (outputs)
    plan.outputs =
        required(true, {0x60FE, 1, 32},
                 "sends the digital output lines in (or set digital_lines = false)") != nullptr;
  required(false, {0x6041, 0, 16}, "reads to follow the drive's state");
  for (const auto& [object, why] :
       {std::pair{PdoEntry{0x6064, 0, 32}, std::string("reads every cycle")},
        std::pair{PdoEntry{0x60FD, 0, 32},
                  std::string("reads the home switch (bit 2) and the input lines from, sampled "
                              "with the position")}}) {
    const PdoPlan* p = required(false, object, why);
    if (p != nullptr && p->transmission != transmission::kSyncEvery)
      problem(p->where.file.empty() ? request.where : p->where,
              p->name() + " carries " + name(object.index, object.sub) +
                  " and has transmission type " + std::to_string(p->transmission) + ": mrroc " +
                  why + ", so it must be sent at every SYNC (type 1)");
  }

  // Every other PDO of the drive: off.
  for (int k = 1; k <= 512; ++k) {
    for (const bool receive : {true, false}) {
      const auto comm = static_cast<std::uint16_t>((receive ? 0x1400 : 0x1800) + k - 1);
      if (d.object(comm) == nullptr) continue;
      bool used = false;
      for (const PdoPlan& p : receive ? plan.rpdos : plan.tpdos) used = used || p.number == k;
      if (used) continue;
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

  // Homing by the drive (mode 6), when the config asks for it.
  if (request.homing) plan.homing = plan_homing(*request.homing);

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
    if (w.text || eds::is_string(e->data_type)) {
      if (!w.text)
        errors.add(ConfigError(w.where, who + ": " + name(w.index, w.sub) + " is " +
                                            std::string(eds::type_name(e->data_type)) + " (" +
                                            d.where(*e).str() + "): write it as text (sdo_text)"));
      else if (!eds::is_string(e->data_type))
        errors.add(ConfigError(w.where, who + ": " + name(w.index, w.sub) + " is " +
                                            std::string(eds::type_name(e->data_type)) + " (" +
                                            d.where(*e).str() +
                                            "), not a string: write it as a number (sdo)"));
      else if (w.text->size() > kMaxSdoTextBytes)
        errors.add(ConfigError(w.where, who + ": the text for " + name(w.index, w.sub) + " is " +
                                            std::to_string(w.text->size()) +
                                            " bytes, longer than mrroc writes (" +
                                            std::to_string(kMaxSdoTextBytes) + " bytes)"));
      else
        plan.writes.push_back(w);
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

void check_pdo_identifiers(const std::vector<DrivePlan>& plans) {
  ConfigErrorList errors;
  struct Use {
    const DrivePlan* plan;
    const PdoPlan* pdo;
  };
  std::vector<Use> seen;
  const auto where = [](const DrivePlan& plan, const PdoPlan& p) {
    return "node " + std::to_string(plan.node) + " (axis '" + plan.axis + "') " + p.name();
  };
  for (const DrivePlan& plan : plans)
    for (const auto* list : {&plan.rpdos, &plan.tpdos})
      for (const PdoPlan& p : *list) {
        const std::uint32_t id = p.cob_id & CAN_SFF_MASK;
        if (id == 0) continue;  // refused by plan_drive already
        const bool reserved = id <= 0x0FF || (id >= 0x101 && id <= 0x180) ||
                              (id >= 0x581 && id <= 0x5FF) || (id >= 0x601 && id <= 0x67F) ||
                              id >= 0x6E0;
        char hex[16];
        std::snprintf(hex, sizeof hex, "0x%03X", id);
        if (reserved) {
          errors.add(ConfigError(p.where, where(plan, p) + ": COB-ID " + hex +
                                              " is reserved by CiA 301 (NMT, SYNC, EMCY, SDO "
                                              "or heartbeat identifiers)"));
          continue;
        }
        for (const Use& u : seen)
          if ((u.pdo->cob_id & CAN_SFF_MASK) == id) {
            errors.add(ConfigError(
                p.where.file.empty() ? u.pdo->where : p.where,
                where(plan, p) + ": COB-ID " + hex + " is also " + where(*u.plan, *u.pdo) + "'s"));
            break;
          }
        seen.push_back({&plan, &p});
      }
  errors.throw_if_any();
}

canopen::BusLoad pdo_bus_load(const std::vector<DrivePlan>& plans, double period_s,
                              double bitrate_bps, double heartbeat_period_s) {
  canopen::BusLoad load;
  double nominal = 0.0;
  double worst = 0.0;
  const auto add = [&](int bytes, double per_cycle) {
    const canopen::FrameBits f = canopen::frame_bits(bytes);
    nominal += per_cycle * f.nominal;
    worst += per_cycle * f.worst;
  };
  add(0, 1.0);  // SYNC
  load.frames_per_cycle = 1;
  for (const DrivePlan& plan : plans) {
    for (const PdoPlan& p : plan.rpdos) {
      const bool cyclic = p.maps(0x6040) || p.maps(plan.target.index, plan.target.sub);
      if (cyclic) ++load.frames_per_cycle;
      add(p.bytes(), cyclic ? 1.0 : 1.0 / static_cast<double>(canopen::kOutputRefreshCycles));
    }
    for (const PdoPlan& p : plan.tpdos) {
      if (p.transmission <= 240) {
        const double every = p.transmission == 0 ? 1.0 : static_cast<double>(p.transmission);
        if (p.transmission <= 1) ++load.frames_per_cycle;
        add(p.bytes(), 1.0 / every);
      } else if (p.event_timer_ms != 0) {
        add(p.bytes(), period_s / (p.event_timer_ms * 1e-3));
      }
    }
    if (heartbeat_period_s > 0.0) add(1, period_s / heartbeat_period_s);
  }
  load.bits_per_cycle_nominal = nominal;
  load.bits_per_cycle_worst = worst;
  const double capacity = bitrate_bps * period_s;
  load.load_nominal = nominal / capacity;
  load.load_worst = worst / capacity;
  return load;
}

}  // namespace mrroc::can
