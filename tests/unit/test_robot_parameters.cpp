/// @file
/// The robots' parameters.toml: every key is read by some code (an unknown key is refused with its
/// file and line, naming the known keys), the IRb-6's link lengths build its kinematics (a length
/// changed in a copy of the file changes the forward kinematics by what the formula predicts), and
/// bad lengths are refused naming the key, the value, the unit and the limit.

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <numbers>
#include <sstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <unistd.h>

#include "mrroc/core/error.hpp"
#include "mrroc/edp/arm_kinematics.hpp"
#include "mrroc/kinematics/irb6.hpp"
#include "mrroc/msg/edp_instruction.hpp"
#include "mrroc/robot/robot_model.hpp"
#include "mrroc/sim/robot_parameters.hpp"

#ifndef MRROC_SOURCE_DIR
#error "MRROC_SOURCE_DIR must be defined (absolute path of the source tree)"
#endif

namespace {

namespace fs = std::filesystem;
namespace irb6 = mrroc::robots::irb6;
using mrroc::ConfigError;
using mrroc::RobotModel;

constexpr double kPi = std::numbers::pi;

fs::path stock(const std::string& name) { return fs::path(MRROC_SOURCE_DIR) / "robots" / name; }

std::string read(const fs::path& path) {
  std::ifstream in(path);
  std::stringstream text;
  text << in.rdbuf();
  return text.str();
}

/// 1-based line of the first occurrence of `needle` in `text` (0: not found).
int line_of(const std::string& text, const std::string& needle) {
  const std::size_t at = text.find(needle);
  if (at == std::string::npos) return 0;
  int line = 1;
  for (std::size_t i = 0; i < at; ++i) line += text[i] == '\n' ? 1 : 0;
  return line;
}

/// A scratch copy of a stock robot folder whose parameters.toml is `edit`ed.
class ScratchRobot {
 public:
  explicit ScratchRobot(const std::string& name)
      : dir_(fs::temp_directory_path() /
             ("mrroc_params_" + std::to_string(::getpid()) + "_" + std::to_string(counter_++))),
        text_(read(stock(name) / "parameters.toml")) {
    fs::create_directories(dir_);
    for (const auto& entry : fs::directory_iterator(stock(name))) {
      const std::string ext = entry.path().extension().string();
      if (ext == ".urdf" || ext == ".xml")
        fs::copy_file(entry.path(), dir_ / entry.path().filename());
    }
    write();
  }
  ~ScratchRobot() {
    std::error_code ec;
    fs::remove_all(dir_, ec);
  }
  ScratchRobot(const ScratchRobot&) = delete;
  ScratchRobot& operator=(const ScratchRobot&) = delete;

  /// Replaces the one occurrence of `from` in parameters.toml.
  void replace(const std::string& from, const std::string& to) {
    const std::size_t at = text_.find(from);
    ASSERT_NE(at, std::string::npos) << from;
    ASSERT_EQ(text_.find(from, at + 1), std::string::npos) << from << " is not unique";
    text_.replace(at, from.size(), to);
    write();
  }
  void append(const std::string& more) {
    text_ += more;
    write();
  }
  [[nodiscard]] const fs::path& dir() const { return dir_; }
  [[nodiscard]] fs::path file() const { return dir_ / "parameters.toml"; }
  [[nodiscard]] int line(const std::string& needle) const { return line_of(text_, needle); }

 private:
  void write() const { std::ofstream(file()) << text_; }

  static inline int counter_ = 0;
  fs::path dir_;
  std::string text_;
};

/// Loads `robot` and expects a ConfigError at `line` of its parameters.toml whose text holds every
/// one of `parts`.
void expect_refused(const ScratchRobot& robot, int line, const std::vector<std::string>& parts) {
  ASSERT_GT(line, 0);
  try {
    (void)mrroc::load_robot_model(robot.dir());
    ADD_FAILURE() << "load_robot_model accepted " << robot.file();
  } catch (const ConfigError& e) {
    EXPECT_EQ(e.where().file, robot.file().string()) << e.what();
    EXPECT_EQ(e.where().line, line) << e.what();
    const std::string what = e.what();
    EXPECT_EQ(what.rfind(robot.file().string() + ":" + std::to_string(line) + ": error: ", 0), 0U)
        << what;
    for (const std::string& part : parts) EXPECT_NE(what.find(part), std::string::npos) << what;
  }
}

TEST(RobotParameters, EveryStockRobotLoadsWithOnlyKnownKeys) {
  for (const char* name : {"irb6", "rnt", "conveyor", "arm6"}) {
    SCOPED_TRACE(name);
    EXPECT_NO_THROW((void)mrroc::load_robot_model(stock(name)));
    EXPECT_NO_THROW(mrroc::check_robot_parameter_keys(stock(name) / "parameters.toml"));
    EXPECT_NO_THROW((void)mrroc::sim::read_robot_parameters(stock(name) / "parameters.toml"));
  }
  // The IRb-6's models are the file's lengths; the other solvers take none from the file.
  const RobotModel model = mrroc::load_robot_model(stock("irb6"));
  const std::vector<irb6::Irb6Geometry> models = irb6::kinematic_models(model);
  ASSERT_EQ(models.size(), 2U);
  EXPECT_EQ(models[0].d1, 0.70);
  EXPECT_EQ(models[0].a2, 0.455);
  EXPECT_EQ(models[0].a3, 0.67);
  EXPECT_EQ(models[0].d5, 0.19);
  EXPECT_EQ(models[1].d1, 0.70);  // not in [robot.kinematics.calibrated]: the nominal value
  EXPECT_EQ(models[1].a2, 0.4596);
  EXPECT_EQ(models[1].a3, 0.6729);
  EXPECT_EQ(models[1].d5, 0.1903);
  EXPECT_TRUE(mrroc::load_robot_model(stock("rnt")).link_lengths.empty());
  EXPECT_THROW((void)irb6::kinematic_models(mrroc::load_robot_model(stock("rnt"))), ConfigError);
}

TEST(RobotParameters, ALengthChangedInTheFileChangesTheForwardKinematics) {
  const RobotModel original = mrroc::load_robot_model(stock("irb6"));
  ScratchRobot robot("irb6");
  robot.replace("a3 = 0.67 ", "a3 = 0.70 ");  // upper arm 3 cm longer
  robot.replace("d1 = 0.70 ", "d1 = 0.75 ");  // column 5 cm higher
  const RobotModel changed = mrroc::load_robot_model(robot.dir());
  const auto before = mrroc::edp::make_arm_kinematics(original);
  const auto after = mrroc::edp::make_arm_kinematics(changed);
  const Eigen::Isometry3d gripper = Eigen::Isometry3d(Eigen::Translation3d(0.0, 0.0, 0.25));
  before->set_tool(gripper);
  after->set_tool(gripper);
  // The upper arm at absolute pitch t2 = q1 + q2 + pi/2 points along (c0 cos t2, s0 cos t2,
  // -sin t2): 3 cm more of it, and 5 cm more column, move the tool by exactly that.
  double worst = 0.0;
  for (double q0 : {-2.0, 0.0, 1.3}) {
    for (double q1 : {-2.0, -kPi / 2, -1.0}) {
      for (double q2 : {-0.3, 0.0, 0.6}) {
        const std::vector<double> q = {q0, q1, q2, 0.4, -0.7};
        const double t2 = q1 + q2 + kPi / 2;
        const Eigen::Vector3d expected(0.03 * std::cos(q0) * std::cos(t2),
                                       0.03 * std::sin(q0) * std::cos(t2),
                                       0.05 - 0.03 * std::sin(t2));
        const Eigen::Vector3d moved =
            after->forward(q).translation() - before->forward(q).translation();
        worst = std::max(worst, (moved - expected).norm());
        EXPECT_LT((moved - expected).norm(), 1e-12) << q0 << " " << q1 << " " << q2;
        EXPECT_LT((after->forward(q).linear() - before->forward(q).linear()).norm(), 1e-15);
      }
    }
  }
  RecordProperty("worst_length_change_error_m", std::to_string(worst));
  // The calibrated model kept its own a3 (0.6729 m) and took the new d1 (not in its table).
  const std::vector<irb6::Irb6Geometry> models = irb6::kinematic_models(changed);
  ASSERT_EQ(models.size(), 2U);
  EXPECT_EQ(models[1].a3, 0.6729);
  EXPECT_EQ(models[1].d1, 0.75);
  // Without [robot.kinematics.calibrated] there is model 0 only, and SET MODEL 1 is refused.
  ScratchRobot single("irb6");
  single.replace("[robot.kinematics.calibrated]\na2 = 0.4596\na3 = 0.6729\nd5 = 0.1903\n", "");
  const RobotModel one = mrroc::load_robot_model(single.dir());
  const auto kinematics = mrroc::edp::make_arm_kinematics(one);
  EXPECT_EQ(kinematics->model_count(), 1);
  try {
    kinematics->select_model(1, 0);
    ADD_FAILURE() << "SET MODEL 1 accepted without a calibrated model";
  } catch (const mrroc::CommandError& e) {
    EXPECT_EQ(e.code(), mrroc::edp::error_code::bad_argument);
    EXPECT_NE(std::string(e.what()).find("has no [robot.kinematics.calibrated]"), std::string::npos)
        << e.what();
  }
}

TEST(RobotParameters, UnknownKeysAreRefusedWithFileLineAndTheKnownKeys) {
  {
    ScratchRobot robot("irb6");
    robot.append("\n[robot.tool]\ngripper_length = 0.25\n");
    expect_refused(robot, robot.line("[robot.tool]"),
                   {"unknown key 'tool' in [robot]",
                    "(known: name, axes, joint_names, urdf, mjcf, synchro_joint_positions, "
                    "max_joint_velocity, max_joint_acceleration, kinematics, transmission)"});
    // Every reader of the file refuses it.
    try {
      (void)mrroc::sim::read_robot_parameters(robot.file());
      ADD_FAILURE() << "read_robot_parameters accepted an unknown key";
    } catch (const ConfigError& e) {
      EXPECT_EQ(e.where().line, robot.line("[robot.tool]")) << e.what();
    }
  }
  {
    ScratchRobot robot("irb6");
    robot.replace("d5 = 0.19 ", "d6 = 0.19 ");
    expect_refused(robot, robot.line("d6 = 0.19"),
                   {"unknown key 'd6' in [robot.kinematics]",
                    "(known: solver, models, correctors, d1, a2, a3, d5, calibrated)"});
  }
  {
    ScratchRobot robot("irb6");
    robot.replace("a3 = 0.6729", "a4 = 0.6729");
    expect_refused(
        robot, robot.line("a4 = 0.6729"),
        {"unknown key 'a4' in [robot.kinematics.calibrated]", "(known: d1, a2, a3, d5)"});
  }
  {
    ScratchRobot robot("irb6");
    robot.replace("solver = \"irb6\"", "solver = \"irb6\"\nmodels = [\"irb6.urdf\"]");
    expect_refused(robot, robot.line("models = "), {"'models' is not read by solver \"irb6\""});
  }
  {
    // The RNT's geometry is its URDF's: lengths in its file are refused.
    ScratchRobot robot("rnt");
    robot.replace("solver = \"rnt\"", "solver = \"rnt\"\nd1 = 0.60");
    expect_refused(robot, robot.line("d1 = 0.60"),
                   {"unknown key 'd1' in [robot.kinematics]",
                    "link lengths are read only by solver \"irb6\", solver \"rnt\" takes none "
                    "from this file"});
  }
  {
    ScratchRobot robot("rnt");
    robot.replace("[robot.transmission]\n",
                  "[robot.transmission]\ngear_ratio = [1, 1, 1, 1, 1, 1]\n");
    expect_refused(robot, robot.line("gear_ratio"),
                   {"unknown key 'gear_ratio' in [robot.transmission] (known: coupling)"});
  }
  {
    ScratchRobot robot("conveyor");
    robot.append("\n[scene]\nname = \"x\"\n");
    expect_refused(robot, robot.line("[scene]"),
                   {"unknown key 'scene' at the top level (known: robot)"});
  }
  {
    ScratchRobot robot("conveyor");
    robot.append("correctors = [[0.0, 0.0, 0.0, 0.0, 0.0, 0.0]]\n");
    expect_refused(robot, robot.line("correctors"),
                   {"'correctors' is not read by solver \"joint-only\""});
  }
}

TEST(RobotParameters, BadLengthsAreRefusedNamingKeyValueUnitAndLimit) {
  struct Case {
    const char* from;
    const char* to;
    std::vector<std::string> parts;
  };
  const std::vector<Case> cases = {
      {"a2 = 0.455 ", "a2 = -0.455 ", {"robot.kinematics.a2 = -0.455 m must be more than 0 m"}},
      {"a2 = 0.455 ", "a2 = 0 ", {"robot.kinematics.a2 = 0 m must be more than 0 m"}},
      {"a3 = 0.67 ",
       "a3 = 12.5 ",
       {"robot.kinematics.a3 = 12.5 m exceeds the plausible limit 10 m"}},
      {"d5 = 0.19 ", "d5 = nan ", {"robot.kinematics.d5 = nan m is not a finite number"}},
      {"d1 = 0.70 ", "d1 = \"0.70\" ", {"robot.kinematics.d1 must be a number [m], not a string"}},
      {"a3 = 0.6729",
       "a3 = 0.80",
       {"robot.kinematics.calibrated.a3 = 0.8 m differs from the nominal 0.67 m (line ",
        "by 0.13 m, more than the plausible 0.067 m (10 % of the nominal"}},
      {"axes = 5", "axes = 6", {"robot.axes = 6 but joint_names lists 5 axes"}},
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(c.to);
    ScratchRobot robot("irb6");
    robot.replace(c.from, c.to);
    expect_refused(robot, robot.line(c.to), c.parts);
  }
  // A length missing from [robot.kinematics] is refused at the table, naming it.
  ScratchRobot robot("irb6");
  robot.replace("d5 = 0.19   # wrist-pitch axis to the flange\n", "");
  expect_refused(robot, robot.line("[robot.kinematics]\n"),
                 {"missing key 'd5' in [robot.kinematics]: solver \"irb6\" takes its link lengths "
                  "d1, a2, a3, d5 [m] from there"});
}

}  // namespace
