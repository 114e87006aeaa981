// mrroc-launch --check validates what the processes will: every EDP, ECP, VSP and the MP run
// their own start-up checks (--check-config) on the config, and every error of the file is
// reported in one run with its file:line (docs/configs.md, "When each part is checked").
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <array>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include "mrroc/config/process_set.hpp"

namespace {

namespace fs = std::filesystem;
const fs::path kBin = MRROC_BIN_DIR;
const fs::path kSource = MRROC_SOURCE_DIR;

/// Runs `command` (shell words, already quoted), returns its exit code and output (both streams).
std::pair<int, std::string> run(const std::string& command) {
  std::string output;
  FILE* pipe = ::popen((command + " 2>&1 </dev/null").c_str(), "r");
  if (pipe == nullptr) return {-1, "popen failed"};
  std::array<char, 4096> buffer{};
  std::size_t n = 0;
  while ((n = std::fread(buffer.data(), 1, buffer.size(), pipe)) > 0)
    output.append(buffer.data(), n);
  const int status = ::pclose(pipe);
  return {WIFEXITED(status) ? WEXITSTATUS(status) : -1, output};
}

std::string launcher() { return (kBin / "mrroc-launch").string(); }

/// A config with one mistake per marked line; `line_of` finds the line (1-based) of a marker.
struct BrokenConfig {
  std::vector<std::string> lines;
  fs::path file;

  void write() const {
    std::ofstream out(file);
    for (const auto& l : lines) out << l << "\n";
  }

  [[nodiscard]] int line_of(const std::string& marker) const {
    for (std::size_t i = 0; i < lines.size(); ++i)
      if (lines[i].find(marker) != std::string::npos) return static_cast<int>(i + 1);
    ADD_FAILURE() << "no line with " << marker;
    return 0;
  }
};

BrokenConfig write_broken_config() {
  BrokenConfig c;
  const fs::path dir = fs::temp_directory_path() / ("mrroc-check-" + std::to_string(getpid()));
  fs::create_directories(dir);
  c.file = dir / "broken.toml";
  const std::string irb6 = (kSource / "robots/irb6").string();
  c.lines = {
      "[system]",
      "name = \"broken\"",
      "",
      "[mp]",
      "task = \"start_and_wait\"",
      "[mp.args]",
      "extra = 1",  // unknown key in the MP task's arguments
      "",
      "[[vsp]]",
      "name = \"wrist\"",
      "plugin = \"force_torgue\"",  // unknown sensor plugin
      "sources = [\"wrist_ft\"]",
      "",
      "[[robot]]",
      "name = \"irb6\"",
      "model = \"" + irb6 + "\"",
      "[robot.edp]",
      "plugin = \"mujoko\"",  // unknown hardware plugin
      "[robot.ecp]",
      "task = \"visit_joint_poses\"",
      "[robot.ecp.args]",
      // 4 values for a 5-axis arm; 9 rad beyond the column's limit
      "poses = [[0.6, -1.35, 0.15, 0.5], [9.0, -1.8, -0.2, -0.6, -1.2]]",
      "motion_stepz = 10",  // misspelt task argument
      "",
      "[[robot]]",
      "name = \"second\"",
      "model = \"" + irb6 + "\"",
      "[robot.edp]",
      "plugin = \"mujoco\"",
      "servo_period_sm = 2.0",  // unknown key of the schema
      "[robot.edp.params]",
      "gravity_compensaton = true",  // unknown key of the plugin
      "[robot.ecp]  # second's",
      "task = \"visit_joint_posez\"",  // unknown ECP task, checked as visit_joint_poses
      "",
      "[[robot]]",
      "name = \"third\"",
      "model = \"" + (kSource / "robots/no_such_robot").string() + "\"",  // missing model folder
      "[robot.edp]",
      "plugin = \"mujoco\"",
      "[robot.ecp]",
      "task = \"follow_mp\"",
  };
  c.write();
  return c;
}

TEST(ConfigCheck, ReportsEveryMistakeOfTheFileWithItsLineAndExits2) {
  const BrokenConfig c = write_broken_config();
  const auto [code, out] = run(launcher() + " --check '" + c.file.string() + "'");
  std::printf("%s", out.c_str());
  EXPECT_EQ(code, 2) << out;
  const std::string f = c.file.string();
  const std::string irb6 = (kSource / "robots").string();
  const std::vector<std::pair<std::string, std::string>> expected = {
      {"extra = 1", "unknown key 'extra' in [mp.args]"},
      {"force_torgue", "unknown sensor plugin 'force_torgue' (known: "},
      {"mujoko", "unknown hardware plugin 'mujoko' (known: "},
      {"poses = ", "pose 1 has 4 joint values, robot 'irb6' has 5 axes"},
      {"poses = ", "joint 0 (column) pose 2 9.000000 rad exceeds upper limit"},
      {"motion_stepz", "unknown key 'motion_stepz' in [robot.ecp.args]"},
      {"servo_period_sm", "unknown key 'servo_period_sm' in [robot.edp] (allowed: "},
      {"gravity_compensaton", "unknown key 'gravity_compensaton' in [robot.edp.params]"},
      {"visit_joint_posez", "unknown ECP task 'visit_joint_posez' (known: "},
      // Checked as the task its name suggests, which needs its poses.
      {"second's", "missing required key 'poses' (checked as ECP task 'visit_joint_poses')"},
      {"no_such_robot", "robot model folder '" + irb6 + "/no_such_robot' not found"},
  };
  for (const auto& [marker, message] : expected) {
    const std::string line = f + ":" + std::to_string(c.line_of(marker)) + ": error: " + message;
    EXPECT_NE(out.find(line), std::string::npos) << "expected: " << line << "\n" << out;
  }
  // Each unknown name a letter away from a known one: the known one suggested.
  for (const char* suggestion : {"; did you mean 'force_torque'?", "; did you mean 'mujoco'?",
                                 "; did you mean 'visit_joint_poses'?"})
    EXPECT_NE(out.find(suggestion), std::string::npos) << suggestion << "\n" << out;
  EXPECT_NE(out.find(std::to_string(expected.size()) + " errors; nothing started"),
            std::string::npos)
      << "each error once, nothing else\n"
      << out;
  EXPECT_EQ(out.find("config is valid"), std::string::npos) << out;
  EXPECT_EQ(out.find("mrroc-launch: started"), std::string::npos) << out;

  // A process' own check is the one --check ran: the ECP of irb6 alone names its three errors.
  const auto [ecp_code, ecp_out] =
      run((kBin / "mrroc-ecp").string() + " --check-config -c '" + f + "' -r irb6");
  EXPECT_EQ(ecp_code, 2) << ecp_out;
  EXPECT_NE(ecp_out.find(f + ":" + std::to_string(c.line_of("motion_stepz")) + ": error: "),
            std::string::npos)
      << ecp_out;
  EXPECT_NE(ecp_out.find("pose 1 has 4 joint values"), std::string::npos) << ecp_out;
  fs::remove_all(c.file.parent_path());
}

TEST(ConfigCheck, EveryArgumentMistakeOfATaskAndTheArgumentsOfAMistypedTaskName) {
  // Type errors mixed with unknown, missing and out-of-range arguments in one task's arguments:
  // a type error does not end the check of the others. A task or plugin name a letter or two
  // away from a known one gets that name suggested and its arguments checked against it.
  BrokenConfig c;
  const fs::path dir = fs::temp_directory_path() / ("mrroc-check-args-" + std::to_string(getpid()));
  fs::create_directories(dir);
  c.file = dir / "arguments.toml";
  const std::string irb6 = (kSource / "robots/irb6").string();
  c.lines = {
      "[system]",
      "name = \"arguments\"",
      "[mp]",
      "task = \"tool_pth\"",  // unknown MP task, near tool_path
      "[mp.args]",
      "robot = \"irb6\"",
      "path = [[0.8, 0.0, 0.3], [0.8, 0.1]]",  // point 2 without z
      "speed = \"slow\"",                      // not a number
      "motion_step = 10",                      // misspelt
      "[[robot]]",
      "name = \"irb6\"",
      "model = \"" + irb6 + "\"",
      "[robot.edp]",
      "plugin = \"mujoco\"",
      "[robot.ecp]",
      "task = \"visit_joint_poses\"",
      "[robot.ecp.args]",
      "poses = [[0.0, -1.5708, 0.0, 0.0, 0.0], [9.0, -1.5708, 0.0, 0.0, 0.0]]",  // 9 rad
      "velocity_scale = \"fast\"",                                               // not a number
      "acceleration_scale = 1.5",                                                // beyond 1
      "motion_steps = 2.5",                                                      // not an integer
      "wait_input = 40",           // no such input line
      "wait_timeout = \"never\"",  // not a number
      "outputs_at_end = \"0x1\"",  // a string, not an integer
      "speeed = 0.1",              // misspelt
      "[[robot]]",
      "name = \"arm2\"",
      "model = \"" + irb6 + "\"",
      "[robot.edp]",
      "plugin = \"mujoco\"",
      "[robot.ecp]",
      "task = \"engarve\"",                    // unknown ECP task, near engrave
      "[robot.ecp.args]  # without 'origin'",  // engrave's required argument
      "text = \"MRROC\"",
      "letter_height = \"4 cm\"",  // not a number
      "speed = -0.06",             // below zero
      "[[robot]]",
      "name = \"arm3\"",
      "model = \"" + irb6 + "\"",
      "[robot.edp]",
      "plugin = \"mujocoo\"",  // unknown hardware plugin, near mujoco
      "[robot.edp.params]",
      "gravity_compensaton = true",  // misspelt, found checked as mujoco
      "[robot.ecp]",
      "task = \"follow_mp\"",
      "[[vsp]]",
      "name = \"wrist\"",
      "plugin = \"force_torqe\"",  // unknown sensor plugin, near force_torque
      "sources = [\"wrist_ft\"]",
      "[vsp.params]",
      "filter_hx = 5",  // misspelt filter_hz
  };
  c.write();
  const auto [code, out] = run(launcher() + " --check '" + c.file.string() + "'");
  std::printf("%s", out.c_str());
  EXPECT_EQ(code, 2) << out;
  const std::string as_tool_path = " (checked as MP task 'tool_path')";
  const std::string as_engrave = " (checked as ECP task 'engrave')";
  const std::vector<std::pair<std::string, std::string>> expected = {
      {"tool_pth", "unknown MP task 'tool_pth' (known: "},
      {"tool_pth", "; did you mean 'tool_path'?"},
      {"path = ", "every 'path' point is [x, y, z] (m); point 2 has 2 values" + as_tool_path},
      {"speed = \"slow\"", "'speed' must be a number, not \"slow\"" + as_tool_path},
      {"motion_step = ", "unknown key 'motion_step' in [mp.args]" + as_tool_path},
      {"poses = ", "joint 0 (column) pose 2 9.000000 rad exceeds upper limit"},
      {"velocity_scale", "'velocity_scale' must be a number, not \"fast\""},
      {"acceleration_scale", "acceleration_scale 1.5 is outside (0, 1]"},
      {"motion_steps", "'motion_steps' must be an integer, not 2.5"},
      {"wait_input = ", "'wait_input' = 40 is not a binary input line (0..31)"},
      {"wait_timeout", "'wait_timeout' must be a number, not \"never\""},
      {"outputs_at_end", "'outputs_at_end' must be an integer, not \"0x1\""},
      {"speeed", "unknown key 'speeed' in [robot.ecp.args]"},
      {"engarve", "unknown ECP task 'engarve' (known: "},
      {"engarve", "; did you mean 'engrave'?"},
      {"without 'origin'", "missing required key 'origin'" + as_engrave},
      {"letter_height", "'letter_height' must be a number, not \"4 cm\"" + as_engrave},
      {"speed = -0.06", "'speed' = -0.06 m/s must be > 0 m/s" + as_engrave},
      {"mujocoo", "unknown hardware plugin 'mujocoo' (known: "},
      {"mujocoo", "; did you mean 'mujoco'?"},
      {"gravity_compensaton",
       "unknown key 'gravity_compensaton' in [robot.edp.params] (checked "
       "as hardware plugin 'mujoco')"},
      {"force_torqe", "unknown sensor plugin 'force_torqe' (known: "},
      {"force_torqe", "; did you mean 'force_torque'?"},
      {"filter_hx",
       "unknown key 'filter_hx' in [vsp.params] (checked as sensor plugin "
       "'force_torque')"},
  };
  for (const auto& [marker, message] : expected) {
    const std::string at = c.file.string() + ":" + std::to_string(c.line_of(marker)) + ": error: ";
    // The message on the line of its mistake (a suggestion ends the unknown name's line).
    bool found = false;
    for (std::size_t from = out.find(at); from != std::string::npos && !found;
         from = out.find(at, from + 1)) {
      const std::string line = out.substr(from, out.find('\n', from) - from);
      found = line.find(message) != std::string::npos;
    }
    EXPECT_TRUE(found) << "expected at " << at << ": " << message << "\n" << out;
  }
  // Four of the expectations are the suggestions, on the lines of the unknown names.
  EXPECT_NE(out.find(std::to_string(expected.size() - 4) + " errors; nothing started"),
            std::string::npos)
      << "each error once, nothing else\n"
      << out;
  fs::remove_all(dir);
}

TEST(ConfigCheck, ReachesRealDevicePluginParametersTheSetsVspNamesAndTheMpTasksPoses) {
  // What a process finds only when it starts, before: the `can` plugin's parameters (checked
  // without opening the bus), a task argument naming a VSP the set lacks, and the MP task's joint
  // poses against the joint count and limits of the robots they are for.
  BrokenConfig c;
  const fs::path dir = fs::temp_directory_path() / ("mrroc-check-dev-" + std::to_string(getpid()));
  fs::create_directories(dir);
  c.file = dir / "devices.toml";
  c.lines = {
      "[system]",
      "name = \"broken-devices\"",
      "[mp]",
      "task = \"place_on_conveyor\"",
      "[mp.args]",
      "approach = [-0.9, -1.40, 0.10]",          // 3 values for a 5-axis arm
      "place = [-0.9, -9.35, 0.15, 0.60, 0.0]",  // beyond the lower arm's limit
      "retreat = [0.0, -1.5708, 0.0, 0.0, 0.0]",
      "belt_target = 9.0",  // m, beyond the conveyor's travel
      "gripper_outpt = 1",  // misspelt
      "[[vsp]]",
      "name = \"wrist_force\"",
      "plugin = \"force_torque\"",
      "sources = [\"irb6_wrist\"]",
      "[[robot]]",
      "name = \"irb6\"",
      "model = \"" + (kSource / "robots/irb6").string() + "\"",
      "[robot.edp]",
      "plugin = \"can\"",
      "[robot.edp.params]",
      "bus = \"virtual:irb 6\"",  // a space in the bus name
      "bitrat = 5",               // misspelt
      "[robot.ecp]",
      "task = \"follow_mp_compliant\"",
      "[robot.ecp.args]",
      "sensor = \"wrist_forse\"",  // no such VSP
      "[[robot]]",
      "name = \"conveyor\"",
      "model = \"" + (kSource / "robots/conveyor").string() + "\"",
      "[robot.edp]",
      "plugin = \"can\"",
      "params = { bus = \"virtual:cell\", silent_cycles = 1 }",  // below 2
      "[robot.ecp]",
      "task = \"follow_mp\"",
  };
  c.write();
  const auto [code, out] = run(launcher() + " --check '" + c.file.string() + "'");
  std::printf("%s", out.c_str());
  EXPECT_EQ(code, 2) << out;
  const std::vector<std::pair<std::string, std::string>> expected = {
      {"approach = ", "approach has 3 joint values, robot 'irb6' has 5 axes"},
      {"place = ", "joint 1 (lower_arm) place -9.350000 rad is below lower limit -2.268928 rad"},
      {"belt_target = ", "joint 0 (belt) belt_target 9.000000 m exceeds upper limit 2.000000 m"},
      {"gripper_outpt", "unknown key 'gripper_outpt' in [mp.args]"},
      {"virtual:irb 6", "CAN bus URL 'virtual:irb 6': bus name has the character ' '"},
      {"bitrat", "unknown key 'bitrat' in [robot.edp.params]"},
      {"wrist_forse",
       "'sensor' = \"wrist_forse\": VSP 'wrist_forse' is not in the process set (its [[vsp]] "
       "are: wrist_force)"},
      {"silent_cycles", "'silent_cycles' = 1 must be in 2..1000"},
  };
  for (const auto& [marker, message] : expected) {
    const std::string line =
        c.file.string() + ":" + std::to_string(c.line_of(marker)) + ": error: " + message;
    EXPECT_NE(out.find(line), std::string::npos) << "expected: " << line << "\n" << out;
  }
  EXPECT_NE(out.find(std::to_string(expected.size()) + " errors; nothing started"),
            std::string::npos)
      << "each error once, nothing else\n"
      << out;
  fs::remove_all(dir);
}

TEST(ConfigCheck, ChecksEveryDriveAgainstItsEdsNamingFileLineNodeAndObject) {
  // The `can` plugin's drives described by their EDS files: a file without digital inputs and
  // with a read-only controlword, a mode the drive lacks, an SDO write to an object the file does
  // not have, and a file that does not parse. Every problem of every drive, in one run.
  BrokenConfig c;
  const fs::path dir = fs::temp_directory_path() / ("mrroc-check-eds-" + std::to_string(getpid()));
  fs::create_directories(dir);
  std::ofstream(dir / "lacking.eds") << "[1000]\nDataType=7\nAccessType=const\nDefaultValue="
                                        "0x20192\n[6040]\nDataType=6\nAccessType=ro\n"
                                        "PDOMapping=1\n";
  std::ofstream(dir / "broken.eds") << "[DeviceInfo]\nVendorNumber=0x12\n[6041\n";
  c.file = dir / "drives.toml";
  const std::string drives = (kSource / "configs/drives/").string();
  c.lines = {
      "[system]",
      "name = \"eds-drives\"",
      "[mp]",
      "task = \"start_and_wait\"",
      "[[robot]]",
      "name = \"irb6\"",
      "model = \"" + (kSource / "robots/irb6").string() + "\"",
      "[robot.edp]",
      "plugin = \"can\"",
      "[robot.edp.params]",
      "bus = \"virtual:irb6\"",
      "eds = [\"" + drives + "emu-csp.eds\", \"lacking.eds\", \"" + drives + "emu-csp.eds\", \"" +
          drives + "emu-ip.eds\", \"broken.eds\"]",
      "mode = \"ip\"",
      "sdo = [[3, 0x2345, 0, 7]]",
      "[robot.ecp]",
      "task = \"visit_joint_poses\"",
      "[robot.ecp.args]",
      "poses = [[0.0, -1.5708, 0.0, 0.0, 0.0]]",
  };
  c.write();
  const auto [code, out] = run(launcher() + " --check '" + c.file.string() + "'");
  std::printf("%s", out.c_str());
  EXPECT_EQ(code, 2) << out;
  const std::string at_eds = c.file.string() + ":" + std::to_string(c.line_of("eds = ")) + ": ";
  for (const std::string& line : {
           at_eds +
               "error: node 1 (axis 'column'): the drive does not support interpolated "
               "position (0x6502 = 0x000000A0 at " +
               drives + "emu-csp.eds:",
           (dir / "lacking.eds").string() +
               ":5: error: node 2 (axis 'lower_arm'): 0x6040 (controlword) is 'ro' "
               "(AccessType), mrroc writes it",
           at_eds + "error: node 2 (axis 'lower_arm'): " + (dir / "lacking.eds").string() +
               " has no object 0x60FD (digital inputs), which mrroc reads the home switch",
           c.file.string() + ":" + std::to_string(c.line_of("sdo = ")) +
               ": error: node 3 (axis 'upper_arm'): " + drives +
               "emu-csp.eds has no object 0x2345 to write",
           (dir / "broken.eds").string() + ":3: error: section header without ']'",
       })
    EXPECT_NE(out.find(line), std::string::npos) << "expected: " << line << "\n" << out;
  // The interpolated position drive (emu-ip.eds) has what mrroc needs: nothing about node 4.
  EXPECT_EQ(out.find("node 4 ("), std::string::npos) << out;
  fs::remove_all(dir);
}

TEST(ConfigCheck, ChecksTheConfigsPdoMappingsAgainstTheFilesAtTheirRows) {
  // PDO mappings chosen in the config: a read-only object in an RPDO, an object that cannot be
  // mapped, more than 64 bits, and no TPDO that carries the statusword. Each error names its own
  // row of the list, the node and the object; all of them in one run. A second robot's encoder
  // resolution puts its joints' ranges beyond the drives' INTEGER32 positions.
  BrokenConfig c;
  const fs::path dir = fs::temp_directory_path() / ("mrroc-check-pdo-" + std::to_string(getpid()));
  fs::create_directories(dir);
  c.file = dir / "pdos.toml";
  const std::string drives = (kSource / "configs/drives/").string();
  c.lines = {
      "[system]",
      "name = \"pdo-check\"",
      "[mp]",
      "task = \"start_and_wait\"",
      "[[robot]]",
      "name = \"irb6\"",
      "model = \"" + (kSource / "robots/irb6").string() + "\"",
      "[robot.edp]",
      "plugin = \"can\"",
      "[robot.edp.params]",
      "bus = \"virtual:irb6\"",
      "eds = \"" + drives + "emu-csp.eds\"",
      "digital_lines = false",
      "sdo_text = [\"2 0x1008 0 lower arm\", \"3 0x2100 0 upper arm\", \"4 0x2100\"]",
      "rpdo = [[2, 1, 0, 1, 0, 0x60400010, 0x607A0020, 0x60410010]]  # read only",
      "tpdo = [",
      "  [3, 1, 0, 1, 0, 0x60640020, 0x60FD0020],",
      "  [3, 2, 0, 255, 20, 0x60410010, 0x60650020],  # not mappable",
      "  [4, 1, 0, 1, 0, 0x60640020, 0x60FD0020],",
      "  [4, 2, 0, 255, 20, 0x60410010, 0x606C0020, 0x60770010, 0x60780010],  # 80 bits",
      "  [5, 1, 0, 1, 0, 0x60640020, 0x60FD0020],  # node 5",
      "  [5, 2, 0, 255, 20, 0x6077],",
      "]",
      "[robot.ecp]",
      "task = \"visit_joint_poses\"",
      "[robot.ecp.args]",
      "poses = [[0.0, -1.5708, 0.0, 0.0, 0.0]]",
      "[[robot]]",  // counts beyond the drives' INTEGER32 positions
      "name = \"fine\"",
      "model = \"" + (kSource / "robots/irb6").string() + "\"",
      "[robot.edp]",
      "plugin = \"can\"",
      "[robot.edp.params]",
      "bus = \"virtual:fine\"",
      "counts_per_unit = 1e9",
      "[robot.ecp]",
      "task = \"follow_mp\"",
  };
  c.write();
  const auto [code, out] = run(launcher() + " --check '" + c.file.string() + "'");
  std::printf("%s", out.c_str());
  EXPECT_EQ(code, 2) << out;
  const auto at = [&](const std::string& marker) {
    return c.file.string() + ":" + std::to_string(c.line_of(marker)) + ": error: ";
  };
  for (const std::string& line : {
           at("# read only") + "node 2 (axis 'lower_arm'): RPDO1: 0x6041 (Statusword) is 'ro' (" +
               drives + "emu-csp.eds:",
           at("# read only") +
               "node 2 (axis 'lower_arm'): RPDO1: 0x6041 (Statusword): mrroc sends only the "
               "controlword (0x6040), the target of mode cyclic synchronous position",
           at("# not mappable") +
               "node 3 (axis 'upper_arm'): TPDO2: 0x6065 (Following error window) cannot be "
               "mapped (PDOMapping=0 (" +
               drives + "emu-csp.eds:",
           at("# 80 bits") +
               "node 4 (axis 'wrist_pitch'): TPDO2: maps 80 bits; a PDO carries at most 64 bits",
           at("# node 5") +
               "node 5 (axis 'wrist_roll'): no TPDO of the config maps 0x6041 (Statusword), "
               "which mrroc reads to follow the drive's state",
           at("sdo_text = ") +
               "node 2 (axis 'lower_arm'): 0x1008 (Manufacturer device name) is "
               "'const' (AccessType at " +
               drives + "emu-csp.eds:",
           at("sdo_text = ") + "node 3 (axis 'upper_arm'): " + drives +
               "emu-csp.eds has no object 0x2100 to write",
           at("sdo_text = ") +
               "'sdo_text' entry \"4 0x2100\" is not \"node index sub text\" (node 0..127, 0: "
               "every drive; index 0..0xFFFF; sub 0..255)",
           at("counts_per_unit = 1e9") +
               "'counts_per_unit' = 1e+09 counts/rad: axis 0 (column) spans 5.93412 rad of its "
               "range, 5.93412e+09 counts, beyond the drives' position range of 2147483647 "
               "counts (INTEGER32) either side of their zero",
       })
    EXPECT_NE(out.find(line), std::string::npos) << "expected: " << line << "\n" << out;
  fs::remove_all(dir);
}

TEST(ConfigCheck, ChecksTheEmulatorsSceneAndTheSetsRobotsAgainstIt) {
  // The cell emulator checks its scene (the file, its drives, sensors) and the [emulator] faults,
  // and the set's robots on emulated buses against the scene: the robot exists, bus, node ids,
  // encoder resolution and model are the scene's.
  const fs::path dir = fs::temp_directory_path() / ("mrroc-check-emu-" + std::to_string(getpid()));
  fs::create_directories(dir);
  const std::string irb6 = (kSource / "robots/irb6").string();
  {
    std::ofstream scene(dir / "cell.toml");
    scene << "[scene]\nname = \"cell\"\n[[scene.robot]]\nname = \"irb6\"\nmodel = \"" << irb6
          << "\"\n[scene.robot.drives]\nbus = \"virtual:cell\"\n[[scene.sensor]]\nname = "
             "\"wrist\"\ntype = \"strain_gauges\"\nbody = \"irb6/roll_link\"\n";
    std::ofstream broken(dir / "broken-scene.toml");
    broken << "[scene]\nname = \"broken\"\n[[scene.robot]]\nname = \"irb6\"\nmodel = \"" << irb6
           << "\"\n[[scene.object]]\nname = \"part\"\ntype = \"box\"\nsize = [0.05, 0.05, "
              "0.05]\npos = [1.0, 0.0, 0.1]\nmass = 0.5\ncolour = [1, 0, 0, 1]\n";
  }
  BrokenConfig c;
  c.file = dir / "emulated.toml";
  c.lines = {
      "[system]",
      "name = \"emulated\"",
      "[emulator]",
      "scene = \"cell.toml\"",
      "faults = [\"drive:irb6/wrist_twist@1.0\", \"sensor:wirst@2.0\"]",  // no such axis, device
      "[mp]",
      "task = \"start_and_wait\"",
      "[[robot]]",
      "name = \"irb6\"",
      "model = \"" + irb6 + "\"",
      "[robot.edp]",
      "plugin = \"can\"",
      "[robot.edp.params]",
      "bus = \"virtual:irb6\"",   // the scene wires it to virtual:cell
      "nodes = [1, 2, 3, 4, 6]",  // the scene's are 1..5
      "counts_per_unit = 4096",   // the scene's drives count 100000 per rad
      "[robot.ecp]",
      "task = \"follow_mp\"",
      "[[robot]]",
      "name = \"rnt\"",  // not in the scene
      "model = \"" + (kSource / "robots/rnt").string() + "\"",
      "[robot.edp]",
      "plugin = \"can\"",
      "params = { bus = \"virtual:rnt\" }",
      "[robot.ecp]",
      "task = \"follow_mp\"",
  };
  c.write();
  const auto [code, out] = run(launcher() + " --check '" + c.file.string() + "'");
  std::printf("%s", out.c_str());
  EXPECT_EQ(code, 2) << out;
  const std::string f = c.file.string();
  const auto at = [&](const std::string& marker) {
    return f + ":" + std::to_string(c.line_of(marker)) + ": error: ";
  };
  const std::vector<std::string> expected = {
      at("[emulator]") +
          "fault 'drive:irb6/wrist_twist@1.0': robot 'irb6' has no axis "
          "'wrist_twist' (axes: column, lower_arm, upper_arm, wrist_pitch, "
          "wrist_roll)",
      at("[emulator]") +
          "fault 'sensor:wirst@2.0': the scene has no raw sensor device 'wirst' "
          "(devices: wrist)",
      at("bus = ") + "robot 'irb6': bus 'virtual:irb6' is not where the scene",
      at("nodes = ") + "robot 'irb6': node ids [1, 2, 3, 4, 6] are not the scene's [1, 2, 3, 4, 5]",
      at("counts_per_unit") +
          "robot 'irb6': counts_per_unit = 4096 counts/unit is not the emulated drives' 100000",
      // At its [[robot]] table, the line before its name.
      f + ":" + std::to_string(c.line_of("name = \"rnt\"") - 1) + ": error: " +
          "robot 'rnt' drives the emulated bus 'virtual:rnt', but the "
          "emulator's scene",
  };
  for (const auto& message : expected)
    EXPECT_NE(out.find(message), std::string::npos) << "expected: " << message << "\n" << out;
  EXPECT_NE(out.find(std::to_string(expected.size()) + " errors; nothing started"),
            std::string::npos)
      << out;

  // A scene with a mistake of its own: reported at the scene file's line.
  std::string text;
  {
    std::ifstream in(c.file);
    text.assign(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
  }
  text.replace(text.find("cell.toml"), 9, "broken-scene.toml");
  {
    std::ofstream file(dir / "broken-scene-set.toml");
    file << text;
  }
  const auto [scene_code, scene_out] =
      run(launcher() + " --check '" + (dir / "broken-scene-set.toml").string() + "'");
  std::printf("%s", scene_out.c_str());
  EXPECT_EQ(scene_code, 2) << scene_out;
  EXPECT_NE(scene_out.find((dir / "broken-scene.toml").string() + ":12: error: "),
            std::string::npos)
      << scene_out;
  EXPECT_NE(scene_out.find("colour"), std::string::npos) << scene_out;
  fs::remove_all(dir);
}

TEST(ConfigCheck, TheReaderReportsEveryErrorOfEveryTableAndWhichProcessesTheyConcern) {
  const std::string model = (kSource / "robots/irb6").string();
  const std::string text =
      "[system]\n"                   // 1
      "name = \"x\"\n"               // 2
      "ready_timeout_s = \"10\"\n"   // 3: not a number
      "[mp]\n"                       // 4
      "task = \"start_and_wait\"\n"  // 5
      "[[robot]]\n"                  // 6
      "name = \"irb6\"\n"            // 7
      "model = \"" +
      model +
      "\"\n"                     // 8
      "[robot.edp]\n"            // 9
      "plugin = \"mujoco\"\n"    // 10
      "servo_period_sm = 2\n"    // 11: unknown key
      "lookahead = 0\n"          // 12: out of range
      "extra = true\n"           // 13: unknown key
      "[robot.ecp]\n"            // 14
      "task = \"follow_mp\"\n";  // 15
  const mrroc::ProcessSetCheck check = mrroc::check_process_set_text(text, "/tmp/set.toml");
  std::string all;
  for (const auto& e : check.errors) all += std::string(e.what()) + "\n";
  ASSERT_EQ(check.errors.size(), 4U) << all;
  std::set<int> lines;
  for (const auto& e : check.errors) lines.insert(e.where().line);
  EXPECT_EQ(lines, (std::set<int>{3, 11, 12, 13})) << all;
  EXPECT_NE(all.find("'lookahead' = 0 macro-steps is outside 1..64"), std::string::npos) << all;
  // [robot.edp] had an error of its own: the EDP's own check is left out, the ECP's is not.
  EXPECT_TRUE(check.broken_process("edp/irb6"));
  EXPECT_FALSE(check.broken_process("ecp/irb6"));
  EXPECT_FALSE(check.broken_process("mp"));
  EXPECT_EQ(check.config.robots.size(), 1U);
  EXPECT_EQ(check.config.robots[0].ecp.name, "follow_mp");
  // load_process_set reads the same tables and stops at the first error.
  EXPECT_THROW((void)mrroc::parse_process_set(text, "/tmp/set.toml"), mrroc::ConfigError);
}

TEST(ConfigCheck, EveryMistakeOfAStateMachineFileAtItsLine) {
  // The MP task state_machine reads and checks its file when it is built: --check reports every
  // mistake of it, each at the file's own line, besides the config's.
  const fs::path dir = fs::temp_directory_path() / ("mrroc-check-fsm-" + std::to_string(getpid()));
  fs::create_directories(dir / "tasks");
  BrokenConfig m;
  m.file = dir / "tasks/broken.fsm.toml";
  m.lines = {
      "initial = \"synchronise\"",
      "[state.synchronise]",
      "start_tasks = [\"irb6\", \"convayor\"]",  // unknown robot, near conveyor
      "next = \"grip\"",
      "[state.grip]",
      "robot = \"irb6\"",
      "subtask = \"set_output\"",  // unknown ECP task, near set_outputs
      "args = { outputs = 1 }",
      "next = \"place\"",
      "[state.place]",
      "robot = \"irb6\"",
      "subtask = \"visit_joint_poses\"",
      "args.poses = [[-0.9, -1.40, 0.10, 0.40, 0.0],",
      "  [9.0, -1.35, 0.15, 0.60, 0.0]]",  // joint 0 beyond its limit
      "args.velocity_scale = \"fast\"",    // not a number
      "next = \"relase\"",                 // unknown state, near release
      "[state.release]",
      "robot = \"irb6\"",
      "subtask = \"set_outputs\"",
      "args = { outputs = 0 }",
      "next = \"check\"",
      "on_fatl = \"failed\"",  // unknown key, near on_fatal
      "[state.check]",
      "wait = { robot = \"conveyor\", joint = 3, above = 1.19 }",  // the conveyor has one joint
      "timeout = 1.0",
      "next = \"done\"",
      "on_timeout = \"faild\"",  // unknown state, near failed
      "[state.spare]",           // never reached
      "delay = 1.0",
      "next = \"done\"",
  };
  m.write();
  BrokenConfig c;
  c.file = dir / "fsm.toml";
  c.lines = {
      "[system]",
      "name = \"fsm\"",
      "[mp]",
      "task = \"state_machine\"",
      "[mp.args]",
      "file = \"tasks/broken.fsm.toml\"",
      "[[robot]]",
      "name = \"irb6\"",
      "model = \"" + (kSource / "robots/irb6").string() + "\"",
      "[robot.edp]",
      "plugin = \"mujoco\"",
      "[robot.ecp]",
      "task = \"follow_mp\"",
      "[[robot]]",
      "name = \"conveyor\"",
      "model = \"" + (kSource / "robots/conveyor").string() + "\"",
      "[robot.edp]",
      "plugin = \"mujoco\"",
      "[robot.ecp]",
      "task = \"follow_mp\"",
  };
  c.write();
  const auto [code, out] = run(launcher() + " --check '" + c.file.string() + "'");
  std::printf("%s", out.c_str());
  EXPECT_EQ(code, 2) << out;
  const std::string f = m.file.string();
  const std::vector<std::pair<std::string, std::string>> expected = {
      {"convayor",
       "unknown robot 'convayor' (the process set has: irb6, conveyor); did you mean "
       "'conveyor'?"},
      {"set_output\"", "unknown ECP task 'set_output' (known: "},
      {"[9.0,", "joint 0 (column) pose 2 9.000000 rad exceeds upper limit"},
      {"velocity_scale", "'velocity_scale'"},
      {"relase",
       "'next' of state 'place': 'relase' is no state of the machine; did you mean "
       "'release'?"},
      {"on_fatl", "unknown key 'on_fatl' in state 'release'; did you mean 'on_fatal'?"},
      {"joint = 3", "robot 'conveyor' has no joint 3 (it has 1: 0..0)"},
      {"faild",
       "'on_timeout' of state 'check': 'faild' is no state of the machine; did you mean "
       "'failed'?"},
      {"[state.spare]", "state 'spare' is never reached from the initial state 'synchronise'"},
  };
  for (const auto& [marker, message] : expected) {
    const std::string line = f + ":" + std::to_string(m.line_of(marker)) + ": error: " + message;
    EXPECT_NE(out.find(line), std::string::npos) << "expected: " << line << "\n" << out;
  }
  EXPECT_NE(out.find("; did you mean 'set_outputs'?"), std::string::npos) << out;
  EXPECT_NE(out.find(std::to_string(expected.size()) + " errors; nothing started"),
            std::string::npos)
      << "each error once, nothing else\n"
      << out;

  // No initial state, and a file that is missing: each named.
  m.lines = {"[state.only]", "delay = 0.1", "next = \"done\""};
  m.write();
  const auto [code2, out2] = run(launcher() + " --check '" + c.file.string() + "'");
  EXPECT_EQ(code2, 2) << out2;
  EXPECT_NE(out2.find(f + ":1: error: missing key 'initial'"), std::string::npos) << out2;
  fs::remove(m.file);
  const auto [code3, out3] = run(launcher() + " --check '" + c.file.string() + "'");
  EXPECT_EQ(code3, 2) << out3;
  EXPECT_NE(out3.find(c.file.string() + ":" + std::to_string(c.line_of("file = ")) +
                      ": error: state machine file '" + f + "' not found"),
            std::string::npos)
      << out3;
  fs::remove_all(dir);
}

TEST(ConfigCheck, EveryStockConfigPasses) {
  int checked = 0;
  for (const auto& entry : fs::directory_iterator(kSource / "configs")) {
    if (entry.path().extension() != ".toml") continue;
    const auto [code, out] = run(launcher() + " --check '" + entry.path().string() + "'");
    EXPECT_EQ(code, 0) << entry.path() << "\n" << out;
    EXPECT_NE(out.find("mrroc-launch: config is valid (--check: nothing started)"),
              std::string::npos)
        << entry.path() << "\n"
        << out;
    ++checked;
  }
  EXPECT_GE(checked, 10);
}

TEST(ConfigCheck, AProcessChecksOnlyWhatItsOwnTablesAllow) {
  // A robot whose model folder is missing: its EDP and ECP do not add follow-on errors.
  const BrokenConfig c = write_broken_config();
  const auto [code, out] =
      run((kBin / "mrroc-edp").string() + " --check-config -c '" + c.file.string() + "' -r third");
  EXPECT_EQ(code, 2) << out;
  EXPECT_EQ(out.find("parameters.toml"), std::string::npos) << out;
  EXPECT_NE(out.find("no_such_robot' not found"), std::string::npos) << out;
  fs::remove_all(c.file.parent_path());
}

}  // namespace
