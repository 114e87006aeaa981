/// @file
/// mrroc-can: commissioning CANopen drives on a bus (SocketCAN or mrroc's virtual bus) before
/// anything moves, and checking their EDS/DCF files. docs/hil.md, "Connecting real drives".
#include <linux/can.h>

#include <chrono>
#include <csignal>
#include <cstdio>
#include <cstring>
#include <ctime>
#include <fstream>
#include <iostream>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <fmt/format.h>

#include "mrroc/can/bus.hpp"
#include "mrroc/can/canopen.hpp"
#include "mrroc/can/cia402_master.hpp"
#include "mrroc/can/drive_setup.hpp"
#include "mrroc/can/eds.hpp"
#include "mrroc/config/check.hpp"
#include "mrroc/core/command_line.hpp"
#include "mrroc/core/error.hpp"

namespace {

using namespace mrroc;
using namespace mrroc::can;
namespace co = mrroc::can::canopen;

volatile std::sig_atomic_t g_stop = 0;
void on_signal(int /*signal*/) { g_stop = 1; }

std::uint64_t number(const std::string& text, const char* what) {
  try {
    std::size_t used = 0;
    const long long v = std::stoll(text, &used, 0);
    if (used != text.size()) throw std::invalid_argument(text);
    return static_cast<std::uint64_t>(v);
  } catch (const std::exception&) {
    throw ConfigError(fmt::format("{} '{}' is not a number (decimal or 0x hex)", what, text));
  }
}

/// "index:sub" (hex index, decimal or 0x sub): 0x6041, 0x1018:1, 1A00:2.
std::pair<std::uint16_t, std::uint8_t> object_of(const std::string& text) {
  const auto colon = text.find(':');
  std::string index = text.substr(0, colon);
  if (index.rfind("0x", 0) != 0 && index.rfind("0X", 0) != 0) index = "0x" + index;
  const std::uint64_t i = number(index, "object index");
  const std::uint64_t s = colon == std::string::npos ? 0 : number(text.substr(colon + 1), "sub");
  if (i > 0xFFFF || s > 0xFF)
    throw ConfigError(
        fmt::format("object '{}' is not index[:sub] (index 0..0xFFFF, sub 0..255)", text));
  return {static_cast<std::uint16_t>(i), static_cast<std::uint8_t>(s)};
}

/// An SDO client on the bus for one node (the master's code, without bringing anything up).
std::unique_ptr<Cia402Master> client(Bus& bus, int node, int timeout_ms) {
  MasterAxis axis;
  axis.name = "node" + std::to_string(node);
  axis.node = static_cast<std::uint8_t>(node);
  MasterOptions options;
  options.sdo_timeout = std::chrono::milliseconds(timeout_ms);
  options.sdo_attempts = 1;
  options.master_node = static_cast<std::uint8_t>(node == 127 ? 126 : 127);
  return std::make_unique<Cia402Master>(bus, std::vector<MasterAxis>{axis}, options);
}

std::string hex(std::uint64_t v, int digits) { return fmt::format("0x{:0{}X}", v, digits); }

std::string mapping_text(const eds::Dictionary& d, std::uint16_t map, std::uint8_t node) {
  const auto count = d.value(map, 0, node).value_or(0);
  std::string out;
  for (std::uint64_t k = 1; k <= count; ++k) {
    const PdoEntry e = PdoEntry::from_raw(
        static_cast<std::uint32_t>(d.value(map, static_cast<std::uint8_t>(k), node).value_or(0)));
    out += (k > 1 ? " + " : "") + object_name(&d, e.index, e.sub);
  }
  return count == 0 ? "(nothing mapped)" : out;
}

int eds_check(const std::string& file, int node, const std::string& mode) {
  const auto d = std::make_shared<eds::Dictionary>(eds::Dictionary::load(file));
  const eds::DeviceInfo& info = d->device();
  std::cout << fmt::format("{}: {} {} (vendor {}, product {}, revision {}), {} objects\n", file,
                           info.vendor_name, info.product_name, hex(info.vendor_number, 8),
                           hex(info.product_number, 8), hex(info.revision_number, 8),
                           d->objects().size());
  const std::uint32_t modes = d->supported_modes();
  std::string listed;
  for (std::int8_t m = 1; m <= 10; ++m)
    if ((modes & eds::mode_bit(m)) != 0U)
      listed += (listed.empty() ? "" : ", ") + std::string(eds::mode_name(m));
  std::cout << "modes (0x6502): " << (modes == 0 ? "not in the file" : listed) << "\n";
  if (const auto m = d->value(0x6060, 0, 1))
    std::cout << "default mode (0x6060): "
              << eds::mode_name(static_cast<std::int8_t>(static_cast<std::uint8_t>(*m))) << "\n";
  const auto n = static_cast<std::uint8_t>(node);
  std::cout << "default PDOs (node " << node << "):\n";
  for (const bool receive : {true, false})
    for (int k = 0; k < 512; ++k) {
      const auto comm = static_cast<std::uint16_t>((receive ? 0x1400 : 0x1800) + k);
      if (d->object(comm) == nullptr) continue;
      const std::uint64_t cob = d->value(comm, 1, n).value_or(kPdoInvalid);
      std::cout << fmt::format("  {}PDO{} {}: {}\n", receive ? "R" : "T", k + 1,
                               (cob & kPdoInvalid) != 0U
                                   ? "off"
                                   : hex(cob & CAN_SFF_MASK, 3) +
                                         fmt::format(", type {}", d->value(comm, 2, n).value_or(0)),
                               mapping_text(*d, static_cast<std::uint16_t>(comm + 0x200), n));
    }
  DriveRequest request;
  request.node = n;
  request.axis = "axis";
  request.where = SourceLocation{"mrroc-can", 0};
  if (mode == "csp") request.mode = eds::mode::kCyclicSyncPosition;
  if (mode == "ip") request.mode = eds::mode::kInterpolatedPosition;
  const DrivePlan plan = plan_drive(d, request);
  std::cout << fmt::format("mrroc will drive it in {} and map:\n", eds::mode_name(plan.mode));
  for (const auto* list : {&plan.rpdos, &plan.tpdos})
    for (const PdoPlan& p : *list) {
      std::string entries;
      for (const PdoEntry& e : p.entries)
        entries += (entries.empty() ? "" : " + ") + object_name(d.get(), e.index, e.sub);
      std::cout << fmt::format("  {} {}, type {}: {}\n", p.name(), hex(p.cob_id, 3), p.transmission,
                               entries);
    }
  if (!plan.outputs) std::cout << "  no digital outputs (the file has no 0x60FE)\n";
  std::string off;
  for (const PdoPlan& p : plan.switched_off) off += (off.empty() ? "" : ", ") + p.name();
  if (!off.empty()) std::cout << "  switched off: " << off << "\n";
  std::string missing;
  for (const ObjectId& o : kOptionalObjects)
    if (d->entry(o.index, o.sub) == nullptr)
      missing += (missing.empty() ? "" : ", ") + object_name(nullptr, o.index, o.sub);
  if (!missing.empty()) std::cout << "  not in the file, so not configured: " << missing << "\n";
  std::cout << "ok: mrroc can drive it\n";
  return 0;
}

int scan(Bus& bus, int first, int last, int timeout_ms) {
  int found = 0;
  for (int node = first; node <= last; ++node) {
    auto c = client(bus, node, timeout_ms);
    std::uint32_t type = 0;
    try {
      type = c->sdo_read(static_cast<std::uint8_t>(node), co::od::kDeviceType, 0);
    } catch (const HardwareError&) {
      continue;  // nobody there
    }
    ++found;
    std::string identity;
    try {
      identity =
          fmt::format("vendor {}, product {}, revision {}",
                      hex(c->sdo_read(static_cast<std::uint8_t>(node), co::od::kIdentity, 1), 8),
                      hex(c->sdo_read(static_cast<std::uint8_t>(node), co::od::kIdentity, 2), 8),
                      hex(c->sdo_read(static_cast<std::uint8_t>(node), co::od::kIdentity, 3), 8));
    } catch (const HardwareError& e) {
      identity = std::string("identity: ") + e.what();
    }
    std::string name;
    try {
      name = c->sdo_read_bytes(static_cast<std::uint8_t>(node), 0x1008, 0);
    } catch (const HardwareError&) {
      name = "(no 0x1008)";
    }
    std::cout << fmt::format("node {}: device type {}{}, {}, name '{}'\n", node, hex(type, 8),
                             (type & 0xFFFFU) == 0x0192U ? " (CiA 402 drive)" : "", identity, name);
  }
  std::cout << fmt::format("{} node(s) answered on {} (nodes {}..{})\n", found, bus.url(), first,
                           last);
  return found > 0 ? 0 : 1;
}

/// One frame in candump -L format: "(1700000000.123456) can0 183#0102".
std::string candump_line(const Received& r, const std::string& interface) {
  const std::int64_t ns = r.timestamp_ns;
  std::string id;
  const canid_t cid = r.frame.can_id;
  if ((cid & CAN_ERR_FLAG) != 0U || (cid & CAN_EFF_FLAG) != 0U)
    id = fmt::format("{:08X}", cid & (CAN_EFF_MASK | CAN_ERR_FLAG));
  else
    id = fmt::format("{:03X}", cid & CAN_SFF_MASK);
  std::string data;
  if ((cid & CAN_RTR_FLAG) != 0U) {
    data = "R";
  } else {
    for (int b = 0; b < r.frame.len && b < 8; ++b) data += fmt::format("{:02X}", r.frame.data[b]);
  }
  return fmt::format("({}.{:06}) {} {}#{}", ns / 1000000000, (ns % 1000000000) / 1000, interface,
                     id, data);
}

/// A frame decoded with CiA 301/402 names (PDOs through `eds` when given).
std::string describe(const can_frame& f, const eds::Dictionary* eds) {
  if ((f.can_id & CAN_ERR_FLAG) != 0U) return "error frame";
  const co::CobId id = co::split_id(f.can_id);
  const auto u32 = [&](int at) {
    return static_cast<std::uint32_t>(f.data[at]) |
           (static_cast<std::uint32_t>(f.data[at + 1]) << 8U) |
           (static_cast<std::uint32_t>(f.data[at + 2]) << 16U) |
           (static_cast<std::uint32_t>(f.data[at + 3]) << 24U);
  };
  if (f.can_id == co::kNmtId && f.len == 2) {
    static const std::map<int, const char*> commands{{1, "start"},
                                                     {2, "stop"},
                                                     {0x80, "enter pre-operational"},
                                                     {0x81, "reset node"},
                                                     {0x82, "reset communication"}};
    const auto it = commands.find(f.data[0]);
    return fmt::format(
        "NMT {} {}", it == commands.end() ? "?" : it->second,
        f.data[1] == 0 ? std::string("all nodes") : fmt::format("node {}", f.data[1]));
  }
  if (f.can_id == co::kSyncId) return "SYNC";
  if (id.function == 0x080 && f.len == 8) {
    const std::uint16_t code = static_cast<std::uint16_t>(f.data[0] | (f.data[1] << 8U));
    return fmt::format("EMCY node {}: {} {}, error register {}", id.node, hex(code, 4),
                       co::describe_emcy(code), hex(f.data[2], 2));
  }
  if (id.function == 0x700 && f.len == 1)
    return fmt::format("heartbeat node {}: {}", id.node,
                       co::to_string(static_cast<co::NmtState>(f.data[0])));
  if ((id.function == 0x580 || id.function == 0x600) && f.len == 8) {
    const std::uint16_t index = static_cast<std::uint16_t>(f.data[1] | (f.data[2] << 8U));
    const std::string object = object_name(eds, index, f.data[3]);
    const char* dir = id.function == 0x600 ? "SDO request to" : "SDO response from";
    if (f.data[0] == 0x80)
      return fmt::format("{} node {}: abort {}: {} {}", dir, id.node, object, hex(u32(4), 8),
                         co::describe_sdo_abort(u32(4)));
    return fmt::format("{} node {}: {} (command {})", dir, id.node, object, hex(f.data[0], 2));
  }
  const bool tpdo =
      id.function == 0x180 || id.function == 0x280 || id.function == 0x380 || id.function == 0x480;
  const bool rpdo =
      id.function == 0x200 || id.function == 0x300 || id.function == 0x400 || id.function == 0x500;
  if (tpdo || rpdo) {
    const int number = (id.function - (tpdo ? 0x180 : 0x200)) / 0x100 + 1;
    std::string out = fmt::format("{}PDO{} node {}", tpdo ? "T" : "R", number, id.node);
    if (eds != nullptr) {
      const auto map = static_cast<std::uint16_t>((tpdo ? 0x1A00 : 0x1600) + number - 1);
      std::uint64_t data = 0;
      for (int b = 0; b < f.len && b < 8; ++b)
        data |= static_cast<std::uint64_t>(f.data[b]) << (8U * static_cast<unsigned>(b));
      int at = 0;
      const auto count = eds->value(map, 0, id.node).value_or(0);
      for (std::uint64_t k = 1; k <= count; ++k) {
        const PdoEntry e = PdoEntry::from_raw(static_cast<std::uint32_t>(
            eds->value(map, static_cast<std::uint8_t>(k), id.node).value_or(0)));
        const std::uint64_t mask = e.bits >= 64 ? ~0ULL : (1ULL << e.bits) - 1U;
        const std::uint64_t raw = (data >> static_cast<unsigned>(at)) & mask;
        at += e.bits;
        const eds::Entry* entry = eds->entry(e.index, e.sub);
        const std::int64_t v =
            entry != nullptr ? eds::as_signed(*entry, raw) : static_cast<std::int64_t>(raw);
        out += fmt::format("{} {} = {}", k == 1 ? ":" : ",", object_name(eds, e.index, e.sub), v);
      }
    }
    return out;
  }
  return "";
}

int run_dump(Bus& bus, const std::string& interface, const std::string& eds_file, double seconds,
             bool record, const std::string& out_file) {
  std::unique_ptr<eds::Dictionary> eds;
  if (!eds_file.empty()) eds = std::make_unique<eds::Dictionary>(eds::Dictionary::load(eds_file));
  std::ofstream file;
  std::ostream* out = &std::cout;
  if (!out_file.empty()) {
    file.open(out_file);
    if (!file)
      throw ConfigError(fmt::format("cannot write '{}': {}", out_file, std::strerror(errno)));
    out = &file;
  }
  std::signal(SIGINT, on_signal);
  std::signal(SIGTERM, on_signal);
  bus.receive_error_frames(true);
  const auto until = std::chrono::steady_clock::now() + std::chrono::duration<double>(seconds);
  std::uint64_t frames = 0;
  Received r;
  while (g_stop == 0 && (seconds <= 0.0 || std::chrono::steady_clock::now() < until)) {
    if (!bus.receive(r, std::chrono::milliseconds(50))) continue;
    ++frames;
    const std::string line = candump_line(r, interface);
    if (record) {
      *out << line << "\n";
    } else {
      *out << fmt::format("{:<40} {}\n", line, describe(r.frame, eds.get()));
    }
  }
  out->flush();
  std::cerr << fmt::format("mrroc-can: {} frames from {}\n", frames, bus.url());
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  CommandLine cli("mrroc-can",
                  "Commissioning CANopen (CiA 301/402) drives: check an EDS/DCF file, scan a bus, "
                  "read and write objects by SDO, show PDO mappings, send NMT commands, and watch "
                  "or record the bus in candump's -L log format (read by can-utils, python-can "
                  "and Wireshark). Buses: socketcan:<interface>, virtual:<name> (docs/hil.md).");
  cli.require_subcommand();
  std::string bus_url;
  int timeout_ms = 100;
  cli.option("-b,--bus", bus_url, "bus URL (socketcan:can0, virtual:irb6)");
  cli.option("--sdo-timeout-ms", timeout_ms, "SDO answer time limit [ms]")
      .range(1, 10000)
      .show_default();

  CommandLine& eds_cmd = cli.subcommand("eds", "EDS/DCF files");
  eds_cmd.require_subcommand();
  CommandLine& check = eds_cmd.subcommand(
      "check",
      "reads FILE and prints what mrroc will use from it: identity, modes, default PDOs, "
      "the mapping mrroc writes, the objects it configures; exit 2 when mrroc cannot "
      "drive it (every problem named with file:line)");
  std::string eds_file;
  int node = 1;
  std::string mode;
  check.option("file", eds_file, "EDS or DCF file").required();
  check.option("--node", node, "node id for $NODEID values").range(1, 127).show_default();
  check.option("--mode", mode, "csp or ip (default: csp where supported)").one_of({"csp", "ip"});

  CommandLine& scan_cmd =
      cli.subcommand("scan",
                     "asks every node id for its device type, identity and name (SDO); exit 1 when "
                     "nobody answers");
  int first = 1;
  int last = 127;
  scan_cmd.option("--from", first, "first node id").range(1, 127).show_default();
  scan_cmd.option("--to", last, "last node id").range(1, 127).show_default();

  CommandLine& sdo_cmd = cli.subcommand("sdo", "read or write an object by SDO");
  sdo_cmd.require_subcommand();
  std::string object;
  std::string value;
  int size = 4;
  CommandLine& read_cmd = sdo_cmd.subcommand("read", "reads NODE's INDEX[:SUB] (hex index)");
  read_cmd.option("node", node, "node id").required().range(1, 127);
  read_cmd.option("object", object, "INDEX[:SUB], e.g. 6041 or 1018:1").required();
  bool as_text = false;
  read_cmd.flag("--text", as_text, "print the value as text (strings; segmented transfers)");
  CommandLine& write_cmd = sdo_cmd.subcommand("write", "writes VALUE to NODE's INDEX[:SUB]");
  write_cmd.option("node", node, "node id").required().range(1, 127);
  write_cmd.option("object", object, "INDEX[:SUB], e.g. 6060 or 1017").required();
  write_cmd.option("value", value, "decimal or 0x hex, or text with --text").required();
  write_cmd.option("--size", size, "bytes (1, 2 or 4)").range(1, 4).show_default();
  bool write_text = false;
  write_cmd.flag("--text", write_text,
                 "write VALUE as text (strings; segmented when longer than 4 bytes)");

  CommandLine& pdo_cmd = cli.subcommand(
      "pdo", "shows NODE's PDOs as the drive has them now (communication and mapping objects)");
  pdo_cmd.option("node", node, "node id").required().range(1, 127);
  std::string pdo_eds;
  pdo_cmd.option("--eds", pdo_eds, "the node's EDS (object names)");

  CommandLine& nmt_cmd = cli.subcommand("nmt", "sends an NMT command");
  std::string command;
  int nmt_node = 0;
  nmt_cmd
      .option("command", command, "start, stop, pre-operational, reset-node, reset-communication")
      .required()
      .one_of({"start", "stop", "pre-operational", "reset-node", "reset-communication"});
  nmt_cmd.option("node", nmt_node, "node id, 0 = all").range(0, 127).show_default();

  double seconds = 0.0;
  std::string dump_eds;
  std::string out_file;
  std::string interface;
  CommandLine& dump_cmd = cli.subcommand(
      "dump", "prints every frame (candump -L format) with its CiA 301/402 meaning until Ctrl-C");
  dump_cmd.option("--seconds", seconds, "stop after this long [s] (0: until Ctrl-C)")
      .show_default();
  dump_cmd.option("--eds", dump_eds, "decode PDOs with this EDS's default mappings");
  dump_cmd.option("--interface", interface, "interface name in the log (default: the bus')");
  CommandLine& record_cmd = cli.subcommand(
      "record",
      "writes every frame in candump's -L log format (can-utils' canplayer and log2asc, "
      "python-can's CanutilsLogReader and Wireshark read it) until Ctrl-C");
  record_cmd.option("-o,--output", out_file, "log file (default: standard output)");
  record_cmd.option("--seconds", seconds, "stop after this long [s] (0: until Ctrl-C)")
      .show_default();
  record_cmd.option("--interface", interface, "interface name in the log (default: the bus')");

  if (const auto exit_code = cli.parse(argc, argv)) return *exit_code;
  try {
    if (cli.got("eds")) return eds_check(eds_file, node, mode);
    if (bus_url.empty()) {
      std::cerr << "mrroc-can: --bus is required for this command\n";
      return 2;
    }
    check_bus_url(bus_url);
    auto bus = open_bus(bus_url);
    if (interface.empty()) interface = bus_url.substr(bus_url.find(':') + 1);
    if (cli.got("scan")) return scan(*bus, first, std::max(first, last), timeout_ms);
    if (cli.got("dump")) return run_dump(*bus, interface, dump_eds, seconds, false, "");
    if (cli.got("record")) return run_dump(*bus, interface, "", seconds, true, out_file);
    if (cli.got("nmt")) {
      const std::map<std::string, co::NmtCommand> commands{
          {"start", co::NmtCommand::start},
          {"stop", co::NmtCommand::stop},
          {"pre-operational", co::NmtCommand::enter_pre_operational},
          {"reset-node", co::NmtCommand::reset_node},
          {"reset-communication", co::NmtCommand::reset_communication}};
      (void)bus->send(co::nmt_frame(commands.at(command), static_cast<std::uint8_t>(nmt_node)));
      std::cout << describe(
                       co::nmt_frame(commands.at(command), static_cast<std::uint8_t>(nmt_node)),
                       nullptr)
                << "\n";
      return 0;
    }
    auto c = client(*bus, node, timeout_ms);
    const auto n = static_cast<std::uint8_t>(node);
    if (sdo_cmd.got("read")) {
      const auto [index, sub] = object_of(object);
      if (as_text) {
        std::cout << c->sdo_read_bytes(n, index, sub) << "\n";
      } else {
        const std::uint32_t v = c->sdo_read(n, index, sub);
        std::cout << fmt::format("{} = {} ({})\n", object_name(nullptr, index, sub), v, hex(v, 8));
      }
      return 0;
    }
    if (sdo_cmd.got("write")) {
      const auto [index, sub] = object_of(object);
      if (write_text) {
        c->sdo_write_bytes(n, index, sub, value);
        std::cout << fmt::format("{} written: '{}' ({} bytes{})\n",
                                 object_name(nullptr, index, sub), value, value.size(),
                                 value.size() > 4 ? ", segmented" : "");
        return 0;
      }
      if (size == 3) throw ConfigError("--size 3: an SDO write here is 1, 2 or 4 bytes");
      const std::uint64_t v = number(value, "value");
      c->sdo_write(n, index, sub, static_cast<std::uint32_t>(v), static_cast<std::uint8_t>(size));
      std::cout << fmt::format("{} written: {}\n", object_name(nullptr, index, sub), value);
      return 0;
    }
    if (cli.got("pdo")) {
      std::unique_ptr<eds::Dictionary> names;
      if (!pdo_eds.empty())
        names = std::make_unique<eds::Dictionary>(eds::Dictionary::load(pdo_eds));
      for (const bool receive : {true, false})
        for (int k = 0; k < 4; ++k) {
          const auto comm = static_cast<std::uint16_t>((receive ? 0x1400 : 0x1800) + k);
          std::uint32_t cob = 0;
          try {
            cob = c->sdo_read(n, comm, 1);
          } catch (const HardwareError&) {
            continue;  // the drive has no such PDO
          }
          const auto map = static_cast<std::uint16_t>(comm + 0x200);
          const std::uint32_t count = c->sdo_read(n, map, 0);
          std::string entries;
          for (std::uint32_t e = 1; e <= count; ++e) {
            const PdoEntry m =
                PdoEntry::from_raw(c->sdo_read(n, map, static_cast<std::uint8_t>(e)));
            entries += (entries.empty() ? "" : " + ") + object_name(names.get(), m.index, m.sub);
          }
          std::cout << fmt::format(
              "{}PDO{} {}: {}\n", receive ? "R" : "T", k + 1,
              (cob & kPdoInvalid) != 0U
                  ? std::string("off")
                  : fmt::format("{}, type {}", hex(cob & CAN_SFF_MASK, 3), c->sdo_read(n, comm, 2)),
              count == 0 ? std::string("(nothing mapped)") : entries);
        }
      return 0;
    }
  } catch (const ConfigErrors& e) {
    std::cerr << e.what() << "\n";
    return 2;
  } catch (const ConfigError& e) {
    std::cerr << "mrroc-can: " << e.what() << "\n";
    return 2;
  } catch (const Error& e) {
    std::cerr << "mrroc-can: " << e.what() << "\n";
    return 1;
  }
  return 0;
}
