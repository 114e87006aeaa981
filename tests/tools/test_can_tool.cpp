// mrroc-can, the commissioning tool: its EDS check on the drives' files and on broken ones, and on
// the emulated IRb-6's bus (mrroc-axis-emu, real time) a scan, SDO reads and a recording in
// candump's -L format that Debian's python3-can reads back frame for frame as this test saw the
// frames on the bus itself.
#include <gtest/gtest.h>

#include <chrono>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include <fmt/format.h>

#include "mrroc/can/bus.hpp"
#include "operator_helpers.hpp"

namespace {

using namespace mrroc::test;

std::string tool() { return (kBin / "mrroc-can").string(); }
std::string drives() { return (kSource / "configs/drives/").string(); }

fs::path temp_file(const std::string& name, const std::string& text) {
  const fs::path dir = fs::temp_directory_path() / fmt::format("mrroc-can-{}", ::getpid());
  fs::create_directories(dir);
  std::ofstream(dir / name) << text;
  return dir / name;
}

TEST(CanTool, HelpVersionAndUsage) {
  const auto [help_code, help] = run({tool(), "--help"});
  EXPECT_EQ(help_code, 0) << help;
  for (const char* command : {"eds", "scan", "sdo", "pdo", "nmt", "dump", "record"})
    EXPECT_TRUE(has(help, command)) << command << "\n" << help;
  const auto [version_code, version] = run({tool(), "--version"});
  EXPECT_EQ(version_code, 0) << version;
  EXPECT_TRUE(has(version, "mrroc-can")) << version;
  EXPECT_EQ(run({tool()}).first, 2);
  EXPECT_EQ(run({tool(), "eds", "check"}).first, 2);
  const auto [no_bus, text] = run({tool(), "scan"});
  EXPECT_EQ(no_bus, 2) << text;
  EXPECT_TRUE(has(text, "--bus is required")) << text;
}

TEST(CanTool, EdsCheckPrintsWhatMrrocUsesFromEachFile) {
  const auto [code, out] = run({tool(), "eds", "check", drives() + "emu-ip.eds", "--node", "3"});
  EXPECT_EQ(code, 0) << out;
  for (const char* line :
       {"EMU-IP-2 (vendor 0x00000A11, product 0x00000002, revision 0x00020003)",
        "modes (0x6502): profile position, homing, interpolated position, cyclic synchronous "
        "position",
        "default mode (0x6060): interpolated position",
        "RPDO1 0x203, type 1: 0x6040 (Controlword) + 0x60C1 sub 1 (Interpolation data record 1)",
        "TPDO1 0x183, type 1: 0x6041 (Statusword) + 0x6077 (Torque actual value) + 0x6064 "
        "(Position actual value)",
        "mrroc will drive it in cyclic synchronous position and map:",
        "RPDO1 0x203, type 1: 0x6040 (Controlword) + 0x607A (Target position)",
        "TPDO1 0x183, type 1: 0x6064 (Position actual value) + 0x60FD (Digital inputs)",
        "TPDO2 0x283, type 255: 0x6041 (Statusword)", "no digital outputs (the file has no 0x60FE)",
        "ok: mrroc can drive it"})
    EXPECT_TRUE(has(out, line)) << line << "\n" << out;
  for (const char* file : {"emu-csp.eds", "emu-pp-split.eds"})
    EXPECT_EQ(run({tool(), "eds", "check", drives() + file}).first, 0) << file;
  // Interpolated position where the drive has none: refused, naming the mode.
  const auto [csp_ip, csp_ip_text] =
      run({tool(), "eds", "check", drives() + "emu-csp.eds", "--mode", "ip"});
  EXPECT_EQ(csp_ip, 2) << csp_ip_text;
  EXPECT_TRUE(has(csp_ip_text, "the drive does not support interpolated position")) << csp_ip_text;
}

TEST(CanTool, EdsCheckNamesFileLineNodeAndObject) {
  const fs::path bad = temp_file("bad.eds", "[1000]\nDataType=0x0007\nAccessType=rw\nLowLimit=x\n");
  const auto [bad_code, bad_text] = run({tool(), "eds", "check", bad.string()});
  EXPECT_EQ(bad_code, 2) << bad_text;
  EXPECT_TRUE(has(bad_text, bad.string() + ":4: error: LowLimit 'x' is not a number")) << bad_text;
  // A drive without digital inputs (no home switch) and with a read-only controlword.
  const fs::path lacking =
      temp_file("lacking.eds",
                "[1000]\nDataType=7\nAccessType=const\nDefaultValue=0x20192\n"
                "[6040]\nParameterName=Controlword\nDataType=6\nAccessType=ro\nPDOMapping=1\n");
  const auto [code, text] = run({tool(), "eds", "check", lacking.string(), "--node", "4"});
  EXPECT_EQ(code, 2) << text;
  EXPECT_TRUE(has(text, lacking.string() + ":5: error: node 4 (axis 'axis'): 0x6040 (Controlword) "
                                           "is 'ro' (AccessType)"))
      << text;
  EXPECT_TRUE(has(
      text, "node 4 (axis 'axis'): " + lacking.string() + " has no object 0x60FD (digital inputs)"))
      << text;
}

TEST(CanTool, ScansRecordsAndPythonCanReadsTheRecordingFrameForFrame) {
  Background emu({(kBin / "mrroc-axis-emu").string(), "--scene",
                  (kSource / "configs/scenes/irb6.toml").string()});
  ASSERT_TRUE(emu.wait_for("; real time", 60s)) << emu.output();
  // This test's own view of the bus, to compare the recording with.
  auto bus = mrroc::can::open_bus("virtual:irb6");
  const fs::path log = fs::temp_directory_path() / fmt::format("mrroc-can-{}.log", ::getpid());
  Background record(
      {tool(), "--bus", "virtual:irb6", "record", "--seconds", "6", "-o", log.string()});
  std::this_thread::sleep_for(300ms);
  const auto [scan_code, scan] = run({tool(), "--bus", "virtual:irb6", "scan", "--to", "7"});
  EXPECT_EQ(scan_code, 0) << scan;
  EXPECT_TRUE(has(scan,
                  "node 1: device type 0x00020192 (CiA 402 drive), vendor 0x00000A11, "
                  "product 0x00000001, revision 0x00010000, name 'EMU-CSP-1'"))
      << scan;
  EXPECT_TRUE(has(scan,
                  "node 3: device type 0x00020192 (CiA 402 drive), vendor 0x00000A11, "
                  "product 0x00000002, revision 0x00020003, name 'EMU-IP-2'"))
      << scan;
  EXPECT_TRUE(has(scan, "5 node(s) answered on virtual:irb6 (nodes 1..7)")) << scan;
  const auto [read_code, read] =
      run({tool(), "--bus", "virtual:irb6", "sdo", "read", "2", "1018:2"});
  EXPECT_EQ(read_code, 0) << read;
  EXPECT_TRUE(has(read, "= 3 (0x00000003)")) << read;
  const auto [abort_code, abort] =
      run({tool(), "--bus", "virtual:irb6", "sdo", "write", "2", "6041", "1", "--size", "2"});
  EXPECT_EQ(abort_code, 1) << abort;
  EXPECT_TRUE(has(abort, "aborted: 0x06010002 attempt to write a read only object")) << abort;
  // A string, segmented (the axis label of emu-pp-split.eds), and read back.
  const auto [text_code, text] = run(
      {tool(), "--bus", "virtual:irb6", "sdo", "write", "2", "2100", "lower arm drive", "--text"});
  EXPECT_EQ(text_code, 0) << text;
  EXPECT_TRUE(has(text, "written: 'lower arm drive' (15 bytes, segmented)")) << text;
  const auto [back_code, back] =
      run({tool(), "--bus", "virtual:irb6", "sdo", "read", "2", "2100", "--text"});
  EXPECT_EQ(back_code, 0) << back;
  EXPECT_TRUE(has(back, "lower arm drive")) << back;
  const auto [const_code, refused] =
      run({tool(), "--bus", "virtual:irb6", "sdo", "write", "2", "1008", "another name", "--text"});
  EXPECT_EQ(const_code, 1) << refused;
  EXPECT_TRUE(has(refused,
                  "an SDO write of 12 bytes to 0x1008:0 aborted: 0x06010002 attempt to "
                  "write a read only object"))
      << refused;
  const auto [pdo_code, pdo] = run({tool(), "--bus", "virtual:irb6", "pdo", "3"});
  EXPECT_EQ(pdo_code, 0) << pdo;
  EXPECT_TRUE(has(pdo,
                  "TPDO1 0x183, type 1: 0x6041 (statusword) + 0x6077 (torque actual value) + "
                  "0x6064 (position actual value)"))
      << pdo;
  std::vector<std::string> seen;  // "ID#DATA" as candump writes them
  mrroc::can::Received r;
  while (bus->receive(r, 0ms))
    if ((r.frame.can_id & CAN_ERR_FLAG) == 0U) {
      std::string data;
      for (int b = 0; b < r.frame.len; ++b) data += fmt::format("{:02X}", r.frame.data[b]);
      seen.push_back(fmt::format("{:03X}#{}", r.frame.can_id, data));
    }
  ASSERT_EQ(record.wait(20s), 0) << record.output();
  ASSERT_GT(seen.size(), 50U);
  // Debian's python-can reads the file as can-utils wrote it.
  const fs::path script = temp_file(
      "read.py",
      "import sys, can\n"
      "for m in can.CanutilsLogReader(sys.argv[1]):\n"
      "    print('%03X#%s %.6f %s' % (m.arbitration_id, m.data.hex().upper(), m.timestamp, "
      "m.channel))\n");
  const auto [py_code, py] = run({"/usr/bin/python3", script.string(), log.string()});
  ASSERT_EQ(py_code, 0) << py;
  std::istringstream lines(py);
  std::vector<std::string> read_back;
  std::string line;
  double last_stamp = 0.0;
  while (std::getline(lines, line)) {
    std::istringstream fields(line);
    std::string frame;
    double stamp = 0.0;
    std::string channel;
    fields >> frame >> stamp >> channel;
    EXPECT_EQ(channel, "irb6") << line;
    EXPECT_GE(stamp, last_stamp) << line;
    last_stamp = stamp;
    read_back.push_back(frame);
  }
  // The recording began before this test's own reading and ended after it: the frames this test
  // saw appear in it, in the same order, one after the other.
  ASSERT_GE(read_back.size(), seen.size());
  const auto start = std::search(read_back.begin(), read_back.end(), seen.begin(), seen.end());
  EXPECT_NE(start, read_back.end())
      << "python-can read " << read_back.size() << " frames; the test saw " << seen.size();
  std::printf("recorded %zu frames; python-can read them back; the test's %zu among them\n",
              read_back.size(), seen.size());
  fs::remove(log);
}

}  // namespace
