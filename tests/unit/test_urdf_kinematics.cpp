// The generic Cartesian kinematics from a robot's URDF alone (kinematics::UrdfArm, the EDP's
// "urdf" kinematics) on robots/arm6, a 6-axis arm without any robot-specific code: which robots
// get it, its MJCF against its URDF, forward/inverse round trips at many poses within the joint
// limits, unreachable and out-of-limit targets refused with value, unit and limit; and the EDP
// with the real MuJoCo plugin moving the arm in FRAME representation, refusing an unreachable
// pose without moving.
#include <gtest/gtest.h>
#include <mujoco/mujoco.h>
#include <unistd.h>

#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <functional>
#include <numbers>
#include <random>
#include <regex>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "command_interpreter.hpp"
#include "edp_parts.hpp"
#include "mrroc/core/error.hpp"
#include "mrroc/edp/arm_kinematics.hpp"
#include "mrroc/edp/hardware.hpp"
#include "mrroc/kinematics/pose.hpp"
#include "mrroc/kinematics/urdf_arm.hpp"
#include "mrroc/robot/robot_model.hpp"
#include "servo_loop.hpp"

using namespace mrroc;
using namespace mrroc::edp;
namespace fs = std::filesystem;

namespace {

constexpr double kPeriod = 0.002;
const fs::path kRobots = fs::path(MRROC_SOURCE_DIR) / "robots";

std::string read(const fs::path& file) {
  std::ifstream in(file);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

void write(const fs::path& file, const std::string& text) { std::ofstream(file) << text; }

/// A copy of robots/`name` in a fresh temporary folder, with `edit` applied to its
/// parameters.toml and `urdf_edit` to its URDF.
fs::path robot_copy(const std::string& name, const std::string& tag,
                    const std::function<std::string(std::string)>& edit,
                    const std::function<std::string(std::string)>& urdf_edit = {}) {
  const fs::path dir = fs::temp_directory_path() /
                       ("mrroc-urdf-kin-" + tag + "-" + std::to_string(::getpid())) / name;
  fs::remove_all(dir);
  fs::create_directories(dir);
  for (const auto& entry : fs::directory_iterator(kRobots / name))
    fs::copy(entry.path(), dir / entry.path().filename());
  write(dir / "parameters.toml", edit(read(dir / "parameters.toml")));
  if (urdf_edit) {
    for (const auto& entry : fs::directory_iterator(dir))
      if (entry.path().extension() == ".urdf") write(entry.path(), urdf_edit(read(entry.path())));
  }
  return dir;
}

std::vector<double> random_joints(const RobotModel& model, std::mt19937& rng, double margin) {
  std::vector<double> q(model.axes());
  for (std::size_t i = 0; i < q.size(); ++i)
    q[i] = std::uniform_real_distribution<double>(model.lower_limits[i] + margin,
                                                  model.upper_limits[i] - margin)(rng);
  return q;
}

double rotation_error(const Eigen::Isometry3d& a, const Eigen::Isometry3d& b) {
  return Eigen::AngleAxisd(a.linear().transpose() * b.linear()).angle();
}

bool within(const RobotModel& model, const std::vector<double>& q) {
  for (std::size_t i = 0; i < q.size(); ++i)
    if (q[i] < model.lower_limits[i] || q[i] > model.upper_limits[i]) return false;
  return true;
}

}  // namespace

// --- which robots get which kinematics ---------------------------------------------------------

TEST(UrdfKinematicsSelection, ARobotWithoutASolverGetsTheGenericKinematics) {
  const RobotModel arm6 = test::stock_model("arm6");
  EXPECT_TRUE(arm6.kinematics.empty()) << "robots/arm6 must not name a solver";
  const auto k = make_arm_kinematics(arm6);
  EXPECT_EQ(k->name(), "urdf");
  EXPECT_TRUE(k->cartesian());
  EXPECT_EQ(k->model_count(), 1);
  EXPECT_EQ(k->corrector_count(), 1);
  std::string why;
  const auto chain = kinematics::find_serial_chain(arm6, why);
  ASSERT_TRUE(chain.has_value()) << why;
  EXPECT_EQ(chain->base, "base_link");
  EXPECT_EQ(chain->tip, "flange");
}

TEST(UrdfKinematicsSelection, AnalyticSolversAndTheConveyorKeepTheirs) {
  EXPECT_EQ(make_arm_kinematics(test::stock_model("irb6"))->name(), "irb6");
  EXPECT_EQ(make_arm_kinematics(test::stock_model("rnt"))->name(), "rnt");
  const auto conveyor = make_arm_kinematics(test::stock_model("conveyor"));
  EXPECT_EQ(conveyor->name(), "joint-only");
  EXPECT_FALSE(conveyor->cartesian());
  try {
    (void)conveyor->forward(std::vector<double>{0.0});
    ADD_FAILURE() << "the conveyor answered a Cartesian request";
  } catch (const CommandError& e) {
    EXPECT_EQ(e.code(), error_code::not_supported);
    EXPECT_NE(std::string(e.what()).find("solver = \"joint-only\""), std::string::npos) << e.what();
  }
}

TEST(UrdfKinematicsSelection, TheConveyorWithoutItsKeyWouldGetTheGenericKinematics) {
  const fs::path dir = robot_copy("conveyor", "belt", [](std::string s) {
    return std::regex_replace(s, std::regex("solver = \"joint-only\""), "");
  });
  const RobotModel model = load_robot_model(dir);
  const auto k = make_arm_kinematics(model);
  EXPECT_EQ(k->name(), "urdf");
  // A frame sliding along x at the belt's height: 0.3 m of belt is 0.3 m along x.
  const Eigen::Isometry3d f = k->forward(std::vector<double>{0.3});
  EXPECT_NEAR(f.translation().x(), 0.3, 1e-12);
  EXPECT_NEAR(f.translation().z(), 0.75, 1e-12);
  const std::vector<double> q = k->inverse(f, std::vector<double>{0.0});
  EXPECT_NEAR(q[0], 0.3, 1e-9);
  // Off the belt's line: refused, within the 2.0 m the belt travels from its origin.
  Eigen::Isometry3d off = f;
  off.translation().y() = 0.5;
  try {
    (void)k->inverse(off, std::vector<double>{0.0});
    ADD_FAILURE() << "a frame off the belt's line was accepted";
  } catch (const CommandError& e) {
    EXPECT_EQ(e.code(), error_code::out_of_limits);
    EXPECT_NE(std::string(e.what()).find("its belt_link is 0.5831 m from the first joint, within "
                                         "the arm's reach 2.0000 m, but no configuration "
                                         "reaches it; inverse kinematics did not converge"),
              std::string::npos)
        << e.what();
  }
  fs::remove_all(dir.parent_path());
}

TEST(UrdfKinematicsSelection, JointsInAnotherOrderGiveJointOnlyKinematicsThatSayWhy) {
  const fs::path dir = robot_copy("arm6", "order", [](std::string s) {
    return std::regex_replace(s, std::regex("\"wrist_pitch\", \"wrist_roll\""),
                              "\"wrist_roll\", \"wrist_pitch\"");
  });
  const RobotModel model = load_robot_model(dir);
  const auto k = make_arm_kinematics(model);
  EXPECT_EQ(k->name(), "joint-only");
  try {
    (void)k->forward(std::vector<double>(6, 0.0));
    ADD_FAILURE() << "no refusal";
  } catch (const CommandError& e) {
    const std::string text = e.what();
    EXPECT_EQ(e.code(), error_code::not_supported);
    EXPECT_NE(text.find("wrist_pitch, wrist_roll], parameters.toml's joint_names are"),
              std::string::npos)
        << text;
    std::printf("refused: %s\n", text.c_str());
  }
  // Named explicitly, the generic kinematics refuses to start, naming the file and the joints.
  const fs::path named = robot_copy("arm6", "named", [](std::string s) {
    s = std::regex_replace(s, std::regex("\"wrist_pitch\", \"wrist_roll\""),
                           "\"wrist_roll\", \"wrist_pitch\"");
    return s + "\n[robot.kinematics]\nsolver = \"urdf\"\n";
  });
  try {
    (void)make_arm_kinematics(load_robot_model(named));
    ADD_FAILURE() << "no refusal";
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("arm6.urdf"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("no serial chain"), std::string::npos) << e.what();
  }
  fs::remove_all(dir.parent_path());
  fs::remove_all(named.parent_path());
}

// --- the models ------------------------------------------------------------------------------

TEST(UrdfKinematicsModel, SynchronisationPosePointsTheFlangeDown) {
  const RobotModel model = test::stock_model("arm6");
  const kinematics::UrdfArm arm(model);
  const Eigen::Isometry3d f = arm.forward(model.synchro_joint_positions);
  // Wrist centre at (a1 + d4, 0, d1 + a2 + a3) = (0.455, 0, 0.79); the flange d6 = 0.08 below.
  EXPECT_LT((f.translation() - Eigen::Vector3d(0.455, 0.0, 0.71)).norm(), 1e-12);
  EXPECT_LT((f.linear().col(2) - Eigen::Vector3d(0, 0, -1)).norm(), 1e-12);
  // Reach from the waist's origin: the joint offsets after it, (0.075, 0, 0.40), 0.36,
  // (0.10, 0, 0.03), 0.28 and 0.08 m, in a line.
  EXPECT_NEAR(arm.reach(), std::hypot(0.075, 0.40) + 0.36 + std::hypot(0.10, 0.03) + 0.28 + 0.08,
              1e-12);
}

TEST(UrdfKinematicsModel, MjcfAgreesWithTheUrdfAtRandomPoses) {
  const RobotModel model = test::stock_model("arm6");
  const kinematics::UrdfArm arm(model);
  std::array<char, 1000> error{};
  mjModel* m =
      mj_loadXML(model.mjcf.c_str(), nullptr, error.data(), static_cast<int>(error.size()));
  ASSERT_NE(m, nullptr) << error.data();
  mjData* d = mj_makeData(m);
  const int site = mj_name2id(m, mjOBJ_SITE, "flange");
  ASSERT_GE(site, 0);
  ASSERT_EQ(m->nu, 6);
  for (std::size_t i = 0; i < model.axes(); ++i) {
    const int a = mj_name2id(m, mjOBJ_ACTUATOR, model.joint_names[i].c_str());
    const int j = mj_name2id(m, mjOBJ_JOINT, model.joint_names[i].c_str());
    ASSERT_EQ(a, static_cast<int>(i)) << model.joint_names[i];
    ASSERT_EQ(j, static_cast<int>(i)) << model.joint_names[i];
    EXPECT_DOUBLE_EQ(m->jnt_range[2 * j], model.lower_limits[i]) << model.joint_names[i];
    EXPECT_DOUBLE_EQ(m->jnt_range[2 * j + 1], model.upper_limits[i]) << model.joint_names[i];
    EXPECT_DOUBLE_EQ(m->actuator_ctrlrange[2 * a], model.lower_limits[i]);
    EXPECT_DOUBLE_EQ(m->actuator_ctrlrange[2 * a + 1], model.upper_limits[i]);
  }
  std::mt19937 rng(17);
  double worst_p = 0.0;
  double worst_r = 0.0;
  for (int n = 0; n < 1000; ++n) {
    const std::vector<double> q = random_joints(model, rng, 0.0);
    for (std::size_t i = 0; i < q.size(); ++i) d->qpos[i] = q[i];
    mj_kinematics(m, d);
    Eigen::Isometry3d mj = Eigen::Isometry3d::Identity();
    for (int r = 0; r < 3; ++r) {
      mj.translation()(r) = d->site_xpos[3 * site + r];
      for (int c = 0; c < 3; ++c) mj.linear()(r, c) = d->site_xmat[9 * site + 3 * r + c];
    }
    const Eigen::Isometry3d kdl = arm.forward(q);
    worst_p = std::max(worst_p, (mj.translation() - kdl.translation()).norm());
    worst_r = std::max(worst_r, (mj.linear() - kdl.linear()).cwiseAbs().maxCoeff());
  }
  EXPECT_LT(worst_p, 1e-9);
  EXPECT_LT(worst_r, 1e-9);
  std::printf("MJCF vs URDF over 1000 poses: %.2e m, %.2e\n", worst_p, worst_r);
  mj_deleteData(d);
  mj_deleteModel(m);
}

// --- inverse kinematics ----------------------------------------------------------------------

TEST(UrdfKinematicsInverse, RoundTripsAtManyPosesStayWithinTheLimits) {
  const RobotModel model = test::stock_model("arm6");
  auto k = make_arm_kinematics(model);
  Eigen::Isometry3d pen = Eigen::Isometry3d::Identity();
  pen.translation() = Eigen::Vector3d(0, 0, 0.12);
  k->set_tool(pen);
  std::mt19937 rng(6);
  int near_ok = 0;
  int far_ok = 0;
  double worst_p = 0.0;
  double worst_r = 0.0;
  constexpr int kPoses = 300;
  for (int n = 0; n < kPoses; ++n) {
    const std::vector<double> q = random_joints(model, rng, 0.02);
    const Eigen::Isometry3d target = k->forward(q);
    // Seeded near the answer (as the EDP does, with the current joints of a moving arm) and from
    // the synchronisation pose.
    std::vector<double> seed = q;
    for (double& s : seed) s += std::uniform_real_distribution<double>(-0.1, 0.1)(rng);
    for (const auto& [start, count] :
         {std::pair{seed, &near_ok}, std::pair{model.synchro_joint_positions, &far_ok}}) {
      try {
        const std::vector<double> solved = k->inverse(target, start);
        const Eigen::Isometry3d reached = k->forward(solved);
        worst_p = std::max(worst_p, (reached.translation() - target.translation()).norm());
        worst_r = std::max(worst_r, rotation_error(reached, target));
        EXPECT_TRUE(within(model, solved)) << "solution outside the joint limits, pose " << n;
        ++*count;
      } catch (const CommandError& e) {
        ADD_FAILURE() << "pose " << n << " refused: " << e.what();
      }
    }
  }
  EXPECT_EQ(near_ok, kPoses);
  EXPECT_EQ(far_ok, kPoses);
  EXPECT_LT(worst_p, 1e-6);
  EXPECT_LT(worst_r, 1e-6);
  std::printf("%d poses, seeded nearby and from the synchronisation pose: worst %.2e m, %.2e rad\n",
              kPoses, worst_p, worst_r);
}

TEST(UrdfKinematicsInverse, ANearbySeedGivesTheNearbySolution) {
  // Along a path (as the EDP solves the macro-steps of a Cartesian motion), each solution is the
  // one nearest the previous joints: no jump to another configuration.
  const RobotModel model = test::stock_model("arm6");
  const kinematics::UrdfArm arm(model);
  std::vector<double> q = model.synchro_joint_positions;
  const Eigen::Isometry3d start = arm.forward(q);
  for (int k = 1; k <= 100; ++k) {
    Eigen::Isometry3d target = start;
    target.translation() += Eigen::Vector3d(0.002 * k, -0.003 * k, -0.004 * k);
    const std::vector<double> next = arm.inverse(target, q);
    for (std::size_t i = 0; i < q.size(); ++i)
      EXPECT_LT(std::abs(next[i] - q[i]), 0.05) << "step " << k << " joint " << i;
    q = next;
  }
}

TEST(UrdfKinematicsInverse, ToolAndCorrectorAreApplied) {
  const fs::path dir = robot_copy("arm6", "corrector", [](std::string s) {
    return s + "\n[robot.kinematics]\ncorrectors = [[0.01, -0.02, 0.005, 0.0, 0.0, 0.1]]\n";
  });
  const RobotModel model = load_robot_model(dir);
  auto k = make_arm_kinematics(model);
  EXPECT_EQ(k->name(), "urdf");
  ASSERT_EQ(k->corrector_count(), 2);
  const std::vector<double> q = {0.3, 0.4, 0.2, -0.5, 1.0, 0.7};
  const Eigen::Isometry3d plain = k->forward(q);
  Eigen::Isometry3d tool = Eigen::Isometry3d::Identity();
  tool.translation() = Eigen::Vector3d(0, 0, 0.12);
  k->set_tool(tool);
  k->select_model(0, 1);
  const Eigen::Isometry3d corrector = kinematics::from_values(
      std::array<double, 6>{0.01, -0.02, 0.005, 0.0, 0.0, 0.1}, ArmRepresentation::xyz_angle_axis);
  const Eigen::Isometry3d expected = corrector * plain * tool;
  EXPECT_LT((k->forward(q).matrix() - expected.matrix()).cwiseAbs().maxCoeff(), 1e-12);
  const std::vector<double> solved = k->inverse(expected, model.synchro_joint_positions);
  EXPECT_LT((k->forward(solved).translation() - expected.translation()).norm(), 1e-6);
  for (const auto& [m, c] : {std::pair{1, 0}, std::pair{0, 2}, std::pair{-1, 0}}) {
    try {
      k->select_model(m, c);
      ADD_FAILURE() << "model " << m << " corrector " << c << " accepted";
    } catch (const CommandError& e) {
      EXPECT_EQ(e.code(), error_code::bad_argument) << e.what();
    }
  }
  fs::remove_all(dir.parent_path());
}

TEST(UrdfKinematicsInverse, KinematicModelsAreTheUrdfsOfTheModelsList) {
  // Model 1: a calibrated unit whose upper arm is 2 mm longer (a copy of the URDF).
  const fs::path dir = robot_copy("arm6", "models", [](std::string s) {
    return s + "\n[robot.kinematics]\nmodels = [\"arm6.urdf\", \"arm6_calibrated.urdf\"]\n";
  });
  write(dir / "arm6_calibrated.urdf",
        std::regex_replace(read(dir / "arm6.urdf"),
                           std::regex(R"(<origin xyz="0 0 0.36" rpy="0 0 0"/>)"),
                           R"(<origin xyz="0 0 0.362" rpy="0 0 0"/>)"));
  const RobotModel model = load_robot_model(dir);
  auto k = make_arm_kinematics(model);
  ASSERT_EQ(k->model_count(), 2);
  const std::vector<double> q = model.synchro_joint_positions;  // upper arm vertical
  const Eigen::Isometry3d nominal = k->forward(q);
  k->select_model(1, 0);
  const Eigen::Isometry3d calibrated = k->forward(q);
  EXPECT_LT(
      (calibrated.translation() - nominal.translation() - Eigen::Vector3d(0, 0, 0.002)).norm(),
      1e-12);
  // The same frame needs other joints under model 1; its inverse reaches it under model 1.
  const std::vector<double> solved = k->inverse(nominal, q);
  EXPECT_LT((k->forward(solved).translation() - nominal.translation()).norm(), 1e-6);
  EXPECT_GT(std::abs(solved[1] - q[1]) + std::abs(solved[2] - q[2]), 1e-4);
  // A model whose chain carries other joints is refused when the kinematics is made.
  write(dir / "arm6_calibrated.urdf",
        std::regex_replace(read(dir / "arm6.urdf"), std::regex("forearm_roll"), "forearm_twist"));
  try {
    (void)make_arm_kinematics(load_robot_model(dir));
    ADD_FAILURE() << "a model with other joints was accepted";
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("arm6_calibrated.urdf"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("forearm_twist"), std::string::npos) << e.what();
  }
  fs::remove_all(dir.parent_path());
}

TEST(UrdfKinematicsInverse, UnreachableTargetIsRefusedNamingDistanceAndReach) {
  const RobotModel model = test::stock_model("arm6");
  auto k = make_arm_kinematics(model);
  Eigen::Isometry3d target = k->forward(model.synchro_joint_positions);
  target.translation() = Eigen::Vector3d(1.3, 0.2, 0.5);
  try {
    (void)k->inverse(target, model.synchro_joint_positions);
    ADD_FAILURE() << "unreachable target accepted";
  } catch (const CommandError& e) {
    const std::string text = e.what();
    EXPECT_EQ(e.code(), error_code::out_of_limits) << text;
    EXPECT_TRUE(std::regex_search(
        text, std::regex(R"(target \(1\.3000, 0\.2000, 0\.5000\) m: its flange is [0-9.]+ m from )"
                         R"(the first joint, beyond the arm's reach 1\.2314 m; inverse kinematics )"
                         R"(did not converge: residual [0-9.]+ m)")))
        << text;
    std::printf("refused: %s\n", text.c_str());
  }
}

TEST(UrdfKinematicsInverse, PoseReachableOnlyOutsideAJointLimitIsRefusedNamingIt) {
  // The arm with its waist limited to +-0.5 rad: a pose at azimuth 1.0 rad needs the waist at
  // 1.0 rad (or 1.0 - pi when reaching over the top, also outside).
  const fs::path dir = robot_copy(
      "arm6", "limit", [](std::string s) { return s; },
      [](std::string urdf) {
        return std::regex_replace(
            urdf,
            std::regex(R"(lower="-2.9670597283903604" upper="2.9670597283903604" effort="300")"),
            R"(lower="-0.5" upper="0.5" effort="300")");
      });
  const RobotModel model = load_robot_model(dir);
  ASSERT_DOUBLE_EQ(model.upper_limits[0], 0.5);
  auto k = make_arm_kinematics(model);
  const kinematics::UrdfArm unlimited(test::stock_model("arm6"));
  const Eigen::Isometry3d target = unlimited.forward({1.0, 0.4, 0.3, 0.0, 1.2, 0.0});
  try {
    const std::vector<double> q = k->inverse(target, model.synchro_joint_positions);
    ADD_FAILURE() << "accepted with the waist at " << q[0] << " rad";
  } catch (const CommandError& e) {
    const std::string text = e.what();
    EXPECT_EQ(e.code(), error_code::out_of_limits) << text;
    EXPECT_TRUE(std::regex_search(
        text, std::regex(R"(joint 0 \(waist\) -?[0-9.]+ rad (exceeds upper|is below lower) )"
                         R"(limit -?0\.500000 rad)")))
        << text;
    std::printf("refused: %s\n", text.c_str());
  }
  fs::remove_all(dir.parent_path());
}

// --- the EDP moving the arm in FRAME representation (real MuJoCo plugin) -----------------------

namespace {

class Arm6EdpTest : public ::testing::Test {
 protected:
  void SetUp() override {
    model_ = test::stock_model("arm6");
    hardware_ = test::configured_hardware(model_, "mujoco", kPeriod);
    kinematics_ = make_arm_kinematics(model_);
    servo_ = std::make_unique<ServoLoop>(*hardware_, model_, kPeriod);
    servo_->set_limit_guard(kinematics_.get());
    servo_->start();
    interpreter_ = std::make_unique<CommandInterpreter>(*servo_, model_, *kinematics_, kPeriod);
    Instruction s;
    s.type = InstructionType::synchro;
    ASSERT_EQ(interpreter_->execute(s).type, ReplyType::acknowledge);
    ASSERT_EQ(query().type, ReplyType::data);
  }
  void TearDown() override { servo_->stop(); }

  Reply query() {
    Instruction q;
    q.type = InstructionType::query;
    return interpreter_->execute(q);
  }
  Reply move(std::vector<double> arm, int steps) {
    Instruction in;
    in.type = InstructionType::set;
    in.set = item::arm;
    in.set_arm_type = ArmRepresentation::frame;
    in.motion_steps = steps;
    in.value_in_step_no = steps + 1;
    in.arm = std::move(arm);
    const Reply accepted = interpreter_->execute(in);
    if (accepted.type == ReplyType::error) return accepted;
    return query();
  }
  Reply read(ArmRepresentation type) {
    Instruction get;
    get.type = InstructionType::get;
    get.get = item::arm;
    get.get_arm_type = type;
    EXPECT_EQ(interpreter_->execute(get).type, ReplyType::acknowledge);
    return query();
  }

  RobotModel model_;
  std::unique_ptr<Hardware> hardware_;
  std::unique_ptr<ServoLoop> servo_;
  std::unique_ptr<ArmKinematics> kinematics_;
  std::unique_ptr<CommandInterpreter> interpreter_;
};

}  // namespace

TEST_F(Arm6EdpTest, FrameMovesReachTheirPosesAndAnUnreachableOneMovesNothing) {
  EXPECT_EQ(kinematics_->name(), "urdf");
  const Reply start = read(ArmRepresentation::frame);
  ASSERT_EQ(start.type, ReplyType::data) << start.error_text;
  const Eigen::Isometry3d synchro = kinematics::from_vector(start.arm, ArmRepresentation::frame);
  EXPECT_LT((synchro.translation() - Eigen::Vector3d(0.455, 0, 0.71)).norm(), 2e-3);
  // Corners of a 0.2 m square 0.3 m below, flange pointing down, each turned a little about z.
  int k = 0;
  for (const auto& [x, y] : std::vector<std::pair<double, double>>{
           {0.40, -0.10}, {0.60, -0.10}, {0.60, 0.10}, {0.40, 0.10}}) {
    Eigen::Isometry3d goal = synchro;
    goal.translation() = Eigen::Vector3d(x, y, 0.40);
    goal.linear() = Eigen::AngleAxisd(0.2 * ++k, Eigen::Vector3d::UnitZ()) * synchro.linear();
    const std::vector<double> from = servo_->planned_end();
    const int steps =
        test::rest_to_rest_steps(model_, from, kinematics_->inverse(goal, from), kPeriod) + 5;
    const Reply r = move(kinematics::to_vector(goal, ArmRepresentation::frame), steps);
    ASSERT_EQ(r.type, ReplyType::data) << "(" << x << ", " << y << "): " << r.error_text;
    std::this_thread::sleep_for(std::chrono::milliseconds(200));
    const Reply now = read(ArmRepresentation::frame);
    ASSERT_EQ(now.type, ReplyType::data) << now.error_text;
    const Eigen::Isometry3d reached = kinematics::from_vector(now.arm, ArmRepresentation::frame);
    EXPECT_LT((reached.translation() - goal.translation()).norm(), 1e-3) << x << ", " << y;
    EXPECT_LT(rotation_error(reached, goal), 5e-3) << x << ", " << y;
  }
  // Out of reach: refused before anything moves; the arm stays where it was.
  const Reply before = read(ArmRepresentation::joint);
  Eigen::Isometry3d far = synchro;
  far.translation() = Eigen::Vector3d(1.5, 0.0, 0.4);
  const Reply refused = move(kinematics::to_vector(far, ArmRepresentation::frame), 500);
  EXPECT_EQ(refused.type, ReplyType::error);
  EXPECT_EQ(refused.error_code, error_code::out_of_limits) << refused.error_text;
  EXPECT_NE(refused.error_text.find("beyond the arm's reach"), std::string::npos)
      << refused.error_text;
  std::printf("EDP refused: %s\n", refused.error_text.c_str());
  std::this_thread::sleep_for(std::chrono::milliseconds(100));
  const Reply after = read(ArmRepresentation::joint);
  ASSERT_EQ(after.arm.size(), before.arm.size());
  for (std::size_t j = 0; j < after.arm.size(); ++j)
    EXPECT_NEAR(after.arm[j], before.arm[j], 1e-4) << "joint " << j << " moved";
}
