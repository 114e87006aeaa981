// The EDS/DCF reader (CiA 306) and the drive plan checked against it: the three emulated drives'
// files of configs/drives/, every syntax the format allows, and errors that name file:line.
#include <gtest/gtest.h>

#include <string>

#include "mrroc/can/drive_setup.hpp"
#include "mrroc/can/eds.hpp"
#include "mrroc/config/check.hpp"

namespace {

using namespace mrroc::can;
using mrroc::ConfigError;

std::string drives_dir() { return std::string(MRROC_SOURCE_DIR) + "/configs/drives/"; }

std::shared_ptr<const eds::Dictionary> load(const std::string& name) {
  return std::make_shared<eds::Dictionary>(eds::Dictionary::load(drives_dir() + name));
}

std::string error_of(std::string_view text) {
  try {
    (void)eds::Dictionary::parse(text, "t.eds");
  } catch (const ConfigError& e) {
    return e.what();
  }
  return "no error";
}

TEST(Eds, ReadsTheEmulatedDrivesFiles) {
  const auto csp = load("emu-csp.eds");
  EXPECT_EQ(csp->device().product_name, "EMU-CSP-1");
  EXPECT_EQ(csp->device().vendor_number, 0xA11U);
  EXPECT_EQ(csp->device().rx_pdos, 4);
  EXPECT_EQ(csp->value(0x1000, 0, 3), 0x00020192U);
  // $NODEID formulas: the TPDO1 COB-ID of node 3.
  EXPECT_EQ(csp->value(0x1800, 1, 3), 0x183U);
  EXPECT_EQ(csp->value(0x1A00, 0, 3), 2U);
  EXPECT_EQ(csp->value(0x1A00, 2, 3), 0x60FD0020U);
  EXPECT_EQ(csp->supported_modes(), eds::mode_bit(6) | eds::mode_bit(8));
  const eds::Entry* sw = csp->entry(0x6041, 0);
  ASSERT_NE(sw, nullptr);
  EXPECT_EQ(sw->access, eds::Access::ro);
  EXPECT_TRUE(sw->pdo_mappable);
  EXPECT_EQ(sw->data_type, eds::type::kUnsigned16);
  // Signed values: the interpolation time index -3.
  const eds::Entry* exp = csp->entry(0x60C2, 2);
  ASSERT_NE(exp, nullptr);
  EXPECT_EQ(eds::as_signed(*exp, *csp->value(0x60C2, 2, 1)), -3);

  const auto ip = load("emu-ip.eds");
  EXPECT_EQ(ip->value(0x6060, 0, 1), 7U);  // defaults to interpolated position
  EXPECT_EQ(ip->value(0x1600, 2, 1), 0x60C10120U);
  EXPECT_EQ(ip->value(0x1A00, 0, 1), 3U);
  EXPECT_EQ(ip->entry(0x60FE, 1), nullptr);  // no outputs
  const auto split = load("emu-pp-split.eds");
  EXPECT_EQ(split->value(0x1A01, 1, 1), 0x60640020U);
  EXPECT_EQ(split->value(0x1802, 1, 9), 0x389U);
  EXPECT_EQ(split->value(0x1A02, 1, 1), 0x60FD0020U);
}

TEST(Eds, ReadsEverySyntaxOfTheFormat) {
  const std::string text =
      "; a comment\r\n"
      "[deviceinfo]\r\n"
      "VENDORNUMBER=0x1234\r\n"
      "ProductNumber=010\r\n"  // octal
      "NrOfTXPDO=1\r\n"
      "BaudRate_500=1\r\n"
      "[DeviceComissioning]\r\nNodeID=0x0B\r\n"
      "[MandatoryObjects]\r\nSupportedObjects=2\r\n1=0x1000\r\n2=0x1A00\r\n"
      "[1000]\r\nParameterName=Device type\r\nDataType=0x0007\r\nAccessType=const\r\n"
      "DefaultValue=0x00020192\r\n"
      "[1a00]\r\nObjectType=0x9\r\nParameterName=TPDO1 mapping\r\nCompactSubObj=2\r\n"
      "DataType=0x0007\r\nAccessType=rw\r\nDefaultValue=0\r\n"
      "[1A00Name]\r\nNrOfEntries=1\r\n2=Second entry\r\n"
      "[1A00Value]\r\nNrOfEntries=1\r\n1=0x60410010\r\n"
      "[6007]\r\nDataType=0x0003\r\nAccessType=rw\r\nDefaultValue=-2\r\nLowLimit=-3\r\n"
      "HighLimit=3\r\nParameterValue=-1\r\n"
      "[1800]\r\nSubNumber=2\r\nObjectType=0x9\r\n"
      "[1800sub0]\r\nDataType=5\r\nAccessType=ro\r\nDefaultValue=1\r\n"
      "[1800sub1]\r\nDataType=7\r\nAccessType=rw\r\nDefaultValue=0x180 + $NODEID\r\n";
  const eds::Dictionary d = eds::Dictionary::parse(text, "t.dcf");
  EXPECT_EQ(d.device().vendor_number, 0x1234U);
  EXPECT_EQ(d.device().product_number, 8U);
  ASSERT_EQ(d.device().baud_rates_kbit.size(), 1U);
  EXPECT_EQ(d.node_id(), 11);
  EXPECT_EQ(d.value(0x1A00, 0, 11), 2U);
  EXPECT_EQ(d.value(0x1A00, 1, 11), 0x60410010U);
  EXPECT_EQ(d.value(0x1A00, 2, 11), 0U);
  EXPECT_EQ(d.entry(0x1A00, 2)->name, "Second entry");
  EXPECT_EQ(d.entry(0x1A00, 1)->access, eds::Access::rw);
  // ParameterValue (a DCF's) wins over DefaultValue.
  const eds::Entry* option = d.entry(0x6007, 0);
  EXPECT_EQ(eds::as_signed(*option, *d.value(0x6007, 0, 11)), -1);
  EXPECT_EQ(eds::out_of_range(*option, 0xFFFCU).value_or(""), "-4 below the low limit -3");
  EXPECT_FALSE(eds::out_of_range(*option, 3U));
  EXPECT_EQ(d.value(0x1800, 1, 11), 0x18BU);
}

TEST(Eds, ErrorsNameFileAndLine) {
  EXPECT_EQ(error_of("[1000\n"), "t.eds:1: error: section header without ']'");
  EXPECT_EQ(error_of("x=1\n"), "t.eds:1: error: a key before the first [section]");
  EXPECT_EQ(error_of("[1000]\nDataType=0x0007\nAccessType=ro\nDefaultValue=0x1FFFFFFFF\n"),
            "t.eds:4: error: DefaultValue '0x1FFFFFFFF' does not fit in 32 bits (UNSIGNED32)");
  EXPECT_EQ(error_of("[1000]\nDataType=0x0099\nAccessType=ro\n"),
            "t.eds:2: error: DataType 0x0099 is not a CiA 301 data type mrroc knows "
            "(0x0001..0x001B basic types)");
  EXPECT_EQ(error_of("[1000]\nDataType=7\nAccessType=readonly\n"),
            "t.eds:3: error: AccessType 'readonly' is none of ro, wo, rw, rwr, rww, const");
  EXPECT_EQ(error_of("[1000]\nDataType=7\nAccessType=ro\nDefaultValue=twelve\n"),
            "t.eds:4: error: DefaultValue 'twelve' is not a number (decimal, 0x hex or octal)");
  EXPECT_EQ(error_of("[1A00sub1]\nDataType=7\nAccessType=rw\n"),
            "t.eds:1: error: [1A00sub1] belongs to no object: the file has no [1A00]");
  EXPECT_EQ(error_of("[1A00]\nObjectType=9\nSubNumber=3\n[1A00sub0]\nDataType=5\nAccessType=rw\n"),
            "t.eds:3: error: SubNumber 3 of [1A00], but the file has 1 [1A00subN] sections");
  EXPECT_EQ(error_of("[OptionalObjects]\nSupportedObjects=1\n1=0x6041\n"),
            "t.eds:3: error: [OptionalObjects] lists object 0x6041, which has no [6041] section");
  EXPECT_EQ(error_of("[1000]\nDataType=7\nDataType=5\n"),
            "t.eds:3: error: key 'DataType' appears twice in [1000] (first at line 2)");
  EXPECT_EQ(error_of("[6007]\nDataType=3\nAccessType=rw\nDefaultValue=-40000\n"),
            "t.eds:4: error: DefaultValue '-40000' is out of range (INTEGER16)");
  EXPECT_EQ(error_of("[1000]\nDataType=7\nAccessType=rw\nLowLimit=2\nDefaultValue=1\n"),
            "t.eds:5: error: DefaultValue of 0x1000 sub 0: 1 below the low limit 2");
  EXPECT_NE(error_of("garbage\n").find("t.eds:1: error: 'garbage' is neither"), std::string::npos);
  try {
    (void)eds::Dictionary::load("/nonexistent/drive.eds");
    FAIL() << "no error";
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("/nonexistent/drive.eds: error: cannot read"),
              std::string::npos)
        << e.what();
  }
}

DriveRequest request(std::uint8_t node) {
  DriveRequest r;
  r.node = node;
  r.axis = "column";
  r.where = {"cell.toml", 12};
  return r;
}

TEST(DrivePlan, MapsWhatTheServoLoopNeedsOnEachFile) {
  const DrivePlan csp = plan_drive(load("emu-csp.eds"), request(1));
  EXPECT_EQ(csp.mode, eds::mode::kCyclicSyncPosition);
  ASSERT_EQ(csp.rpdos.size(), 2U);
  ASSERT_EQ(csp.tpdos.size(), 2U);
  EXPECT_EQ(csp.rpdos[0].cob_id, 0x201U);
  EXPECT_EQ(csp.target_entry(), (PdoEntry{0x607A, 0, 32}));
  EXPECT_EQ(csp.rpdos[0].entries, (std::vector<PdoEntry>{{0x6040, 0, 16}, {0x607A, 0, 32}}));
  ASSERT_TRUE(csp.outputs);
  EXPECT_EQ(csp.rpdos[1].cob_id, 0x301U);
  EXPECT_EQ(csp.tpdos[0].cob_id, 0x181U);
  EXPECT_EQ(csp.tpdos[0].entries, (std::vector<PdoEntry>{{0x6064, 0, 32}, {0x60FD, 0, 32}}));
  EXPECT_EQ(csp.tpdos[1].cob_id, 0x281U);
  EXPECT_EQ(csp.tpdos[1].transmission, transmission::kEventProfile);
  EXPECT_EQ(csp.tpdos[1].event_timer_ms, 20);
  EXPECT_EQ(csp.switched_off.size(), 4U);  // RPDO3, RPDO4, TPDO3, TPDO4

  // Defaults to interpolated position, supports CSP: CSP chosen; no outputs on this drive.
  const DrivePlan ip = plan_drive(load("emu-ip.eds"), request(2));
  EXPECT_EQ(ip.mode, eds::mode::kCyclicSyncPosition);
  EXPECT_FALSE(ip.outputs);
  EXPECT_EQ(ip.switched_off.size(), 5U);  // RPDO2..4, TPDO3..4
  DriveRequest wants_ip = request(2);
  wants_ip.mode = eds::mode::kInterpolatedPosition;
  EXPECT_EQ(plan_drive(load("emu-ip.eds"), wants_ip).target_entry(), (PdoEntry{0x60C1, 1, 32}));

  const DrivePlan split = plan_drive(load("emu-pp-split.eds"), request(3));
  EXPECT_EQ(split.tpdos.at(1).entries, (std::vector<PdoEntry>{{0x6041, 0, 16}}));
}

TEST(DrivePlan, RefusesWhatTheFileDoesNotHaveNamingNodeObjectAndLine) {
  // Interpolated position on a drive that cannot, and a write the file does not allow.
  DriveRequest r = request(4);
  r.mode = eds::mode::kInterpolatedPosition;
  r.writes.push_back({0x6041, 0, 5, 0, {"cell.toml", 20}, std::nullopt});
  r.writes.push_back({0x6065, 0, 0x1FFFFFFFF, 0, {"cell.toml", 21}, std::nullopt});
  r.writes.push_back({0x2345, 0, 1, 0, {"cell.toml", 22}, std::nullopt});
  try {
    (void)plan_drive(load("emu-csp.eds"), r);
    FAIL() << "no error";
  } catch (const mrroc::ConfigErrors& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("cell.toml:12: error: node 4 (axis 'column'): the drive does not support "
                        "interpolated position (0x6502 = 0x000000A0 at "),
              std::string::npos)
        << what;
    EXPECT_NE(what.find("emu-csp.eds has no object 0x60C1 sub 1 (interpolation data record), "
                        "which mrroc sends the position target every cycle"),
              std::string::npos)
        << what;
    EXPECT_NE(what.find("cell.toml:20: error: node 4 (axis 'column'): 0x6041 (Statusword) is 'ro'"),
              std::string::npos)
        << what;
    EXPECT_NE(what.find("cell.toml:21: error: node 4 (axis 'column'): 8589934591 does not fit "
                        "0x6065 (Following error window) (UNSIGNED32, 0..4294967295)"),
              std::string::npos)
        << what;
    EXPECT_NE(what.find("cell.toml:22: error: node 4 (axis 'column'): "), std::string::npos);
    EXPECT_EQ(e.errors().size(), 5U) << what;
  }
  // A read-only controlword is the file's problem: its line is named.
  std::string text(eds::Dictionary::load(drives_dir() + "emu-csp.eds").file());
  const auto broken = std::make_shared<eds::Dictionary>(
      eds::Dictionary::parse("[1000]\nDataType=7\nAccessType=const\nDefaultValue=0x20192\n"
                             "[6040]\nDataType=6\nAccessType=ro\nPDOMapping=1\n",
                             "broken.eds"));
  try {
    (void)plan_drive(broken, request(5));
    FAIL() << "no error";
  } catch (const mrroc::ConfigErrors& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("broken.eds:5: error: node 5 (axis 'column'): 0x6040 (controlword) is "
                        "'ro' (AccessType), mrroc writes it: sends the controlword every cycle"),
              std::string::npos)
        << what;
    EXPECT_NE(what.find("cell.toml:12: error: node 5 (axis 'column'): broken.eds has no object "
                        "0x60FD (digital inputs)"),
              std::string::npos)
        << what;
  }
}

TEST(DrivePlan, TheBuiltInFileIsTheEmulatedDrives) {
  const auto d = default_drive_eds();
  EXPECT_EQ(d->device().product_name, "EMU-CSP-1");
  EXPECT_NE(d->file().find("(built in)"), std::string::npos);
  EXPECT_NO_THROW((void)plan_drive(d, request(1)));
}

}  // namespace
