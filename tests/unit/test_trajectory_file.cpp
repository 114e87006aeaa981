// Teach-in trajectory files: the format, lossless save/load, errors with file:line naming the
// value and the expectation, a mutation loop that must never crash, the recorder and playback.
#include <gtest/gtest.h>

#include <unistd.h>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <random>
#include <string>

#include "mrroc/core/error.hpp"
#include "mrroc/ecp/generators/teach_in.hpp"
#include "mrroc/ecp/generators/trajectory_file.hpp"
#include "mrroc/edp/arm_kinematics.hpp"
#include "mrroc/kinematics/pose.hpp"

using namespace mrroc;
using edp::ArmRepresentation;

namespace {

const RobotModel& model() {
  static const RobotModel m = load_robot_model(std::string(MRROC_SOURCE_DIR) + "/robots/irb6");
  return m;
}

/// A fresh directory per test under the system's temporary directory.
class TempDir {
 public:
  TempDir() {
    path_ = std::filesystem::temp_directory_path() /
            ("mrroc-trajectory-" + std::to_string(::getpid()) + "-" +
             ::testing::UnitTest::GetInstance()->current_test_info()->name());
    std::filesystem::remove_all(path_);
    std::filesystem::create_directories(path_);
  }
  ~TempDir() {
    std::error_code ec;
    std::filesystem::remove_all(path_, ec);
  }
  TempDir(const TempDir&) = delete;
  TempDir& operator=(const TempDir&) = delete;
  [[nodiscard]] std::filesystem::path file(const std::string& name) const { return path_ / name; }

 private:
  std::filesystem::path path_;
};

const char* const kExample =
    "# mrroc trajectory v1 representation=JOINT axes=5 robot=irb6\n"
    "# column lower_arm upper_arm wrist_pitch wrist_roll [rad]\n"
    "\n"
    "0 -1.5707963267948966 0 0 0\n"
    "  0.2\t-1.4 0.1 0 0.5 duration=2.5   # to the left\n"
    "0.2 -1.4 0.1 0 0.5 duration=1\n"
    "+1e-1 -1.5 -0.05 0.1 0 velocity_scale=0.5\r\n";

bool contains(const std::string& text, const std::string& part) {
  return text.find(part) != std::string::npos;
}

}  // namespace

TEST(TrajectoryFile, ParsesTheDocumentedFormat) {
  const auto t = ecp::TrajectoryFile::parse(kExample, "example.traj");
  EXPECT_EQ(t.representation, ArmRepresentation::joint);
  EXPECT_EQ(t.axes, 5U);
  EXPECT_EQ(t.robot, "irb6");
  ASSERT_EQ(t.points.size(), 4U);
  EXPECT_EQ(t.points[0].values, (std::vector<double>{0, -1.5707963267948966, 0, 0, 0}));
  EXPECT_FALSE(t.points[0].duration_s);
  EXPECT_EQ(t.points[1].duration_s, 2.5);
  EXPECT_EQ(t.points[2].duration_s, 1.0);
  EXPECT_EQ(t.points[3].values[0], 0.1);
  EXPECT_EQ(t.points[3].velocity_scale, 0.5);
}

TEST(TrajectoryFile, SaveAndLoadAreLossless) {
  TempDir dir;
  std::mt19937_64 random(20240611);
  std::uniform_real_distribution<double> any(-10.0, 10.0);
  for (const auto representation :
       {ArmRepresentation::joint, ArmRepresentation::motor, ArmRepresentation::frame,
        ArmRepresentation::xyz_euler_zyz, ArmRepresentation::xyz_angle_axis}) {
    ecp::TrajectoryFile t;
    t.representation = representation;
    t.axes = 5;
    t.robot = "irb6";
    for (int i = 0; i < 50; ++i) {
      ecp::TrajectoryPoint p;
      if (representation == ArmRepresentation::frame) {
        const Eigen::Vector3d axis(any(random), any(random), any(random));
        Eigen::Isometry3d f = Eigen::Isometry3d::Identity();
        f.linear() = Eigen::AngleAxisd(any(random), axis.normalized()).toRotationMatrix();
        f.translation() = Eigen::Vector3d(any(random), any(random), any(random));
        const auto values = kinematics::frame_to_values(f);
        p.values.assign(values.begin(), values.end());
      } else {
        p.values.resize(t.values_per_point());
        for (double& v : p.values) v = any(random) * std::pow(10.0, any(random));
      }
      if (i % 3 == 1) p.duration_s = std::abs(any(random)) + 1e-3;
      if (i % 3 == 2) p.velocity_scale = std::uniform_real_distribution<double>(1e-6, 1.0)(random);
      t.points.push_back(std::move(p));
    }
    const auto path = dir.file(std::string(edp::to_string(representation)) + ".traj");
    t.save(path);
    const auto loaded = ecp::TrajectoryFile::load(path);
    EXPECT_EQ(loaded, t) << edp::to_string(representation);
    EXPECT_EQ(loaded.to_text(), t.to_text());
    EXPECT_FALSE(std::filesystem::exists(path.string() + ".tmp"));
  }
  // Without a robot name, and empty.
  ecp::TrajectoryFile empty;
  empty.axes = 3;
  empty.save(dir.file("empty.traj"));
  EXPECT_EQ(ecp::TrajectoryFile::load(dir.file("empty.traj")), empty);
  // Inconsistent trajectories are not written.
  ecp::TrajectoryFile bad = empty;
  bad.points.push_back({{1.0, 2.0}});
  EXPECT_THROW(bad.save(dir.file("bad.traj")), Error);
  bad.points = {{{1.0, NAN, 2.0}}};
  EXPECT_THROW((void)bad.to_text(), Error);
  EXPECT_THROW(empty.save(dir.file("no/such/dir/x.traj")), Error);
}

TEST(TrajectoryFile, BadFilesAreRejectedWithFileAndLine) {
  const std::string header = "# mrroc trajectory v1 representation=JOINT axes=3\n";
  struct Case {
    std::string text;
    std::string expected;  // the whole prefix, then a part of the explanation
  };
  const std::vector<Case> cases = {
      {"", "t.traj:1: error: the first line must be the header"},
      {"0 0 0\n", "t.traj:1: error: the first line must be the header"},
      {"# mrroc trajectory v2 representation=JOINT axes=3\n",
       "t.traj:1: error: header: format version 2 is newer than the supported version 1"},
      {"# mrroc trajectory vX\n", "t.traj:1: error: header: format version 'X' is not"},
      {"# mrroc trajectory v1 axes=3\n", "t.traj:1: error: header: representation=... is missing"},
      {"# mrroc trajectory v1 representation=JOINT\n",
       "t.traj:1: error: header: axes=... is missing"},
      {"# mrroc trajectory v1 representation=joint axes=3\n",
       "t.traj:1: error: header: representation 'joint' is not one of JOINT, MOTOR, FRAME"},
      {"# mrroc trajectory v1 representation=JOINT axes=0\n",
       "t.traj:1: error: header: axes '0' is not an integer in 1..64"},
      {"# mrroc trajectory v1 representation=JOINT axes=3 speed=2\n",
       "t.traj:1: error: header: unknown key 'speed'"},
      {"# mrroc trajectory v1 representation=JOINT axes=3 axes=3\n",
       "t.traj:1: error: header: axes is given twice"},
      {header + "0 0\n", "t.traj:2: error: too few values: the pose has 2, expected 3 joint"},
      {header + "# c\n\n0 0 0 0\n",
       "t.traj:4: error: too many values: '0' has 4 values, expected 3"},
      {header + "0 x 0\n",
       "t.traj:2: error: value 2 'x' is not a finite number (expected 3 joint values [rad])"},
      {header + "0 nan 0\n", "t.traj:2: error: value 2 'nan' is not a finite number"},
      {header + "0 1e999 0\n", "t.traj:2: error: value 2 '1e999' is not a finite number"},
      {header + "0 0 0 duration=0\n",
       "t.traj:2: error: duration '0' is not a number of seconds > 0"},
      {header + "0 0 0 duration=-1\n", "t.traj:2: error: duration '-1' is not"},
      {header + "0 0 0 velocity_scale=1.5\n",
       "t.traj:2: error: velocity_scale '1.5' is not a number in (0, 1]"},
      {header + "0 0 0 duration=1 velocity_scale=0.5\n",
       "t.traj:2: error: a pose has either duration= or velocity_scale=, not both"},
      {header + "0 0 0 duration=1 duration=2\n", "t.traj:2: error: duration= is given twice"},
      {header + "0 0 duration=1 0\n", "t.traj:2: error: value '0' after an option"},
      {header + "0 0 0 speed=1\n", "t.traj:2: error: unknown option 'speed'"},
      {header + "0 0 \x01\xff\n", "t.traj:2: error: value 3 '\\x01\\xff' is not a finite"},
      {"# mrroc trajectory v1 representation=FRAME axes=5\n1 0 0 0 0 1 0 0 0 0 2 0\n",
       "t.traj:2: error: the pose is not a frame: "},
  };
  for (const Case& c : cases) {
    try {
      (void)ecp::TrajectoryFile::parse(c.text, "t.traj");
      ADD_FAILURE() << "accepted:\n" << c.text;
    } catch (const ConfigError& e) {
      EXPECT_TRUE(contains(e.what(), c.expected))
          << "expected '" << c.expected << "'\ngot '" << e.what() << "'";
    }
  }
  try {
    (void)ecp::TrajectoryFile::load("/nonexistent/dir/x.traj");
    FAIL();
  } catch (const ConfigError& e) {
    EXPECT_TRUE(contains(e.what(),
                         "/nonexistent/dir/x.traj: error: trajectory file cannot be "
                         "opened"))
        << e.what();
  }
}

TEST(TrajectoryFile, MutatedFilesNeverCrash) {
  // Random byte edits, insertions, deletions and line duplications of valid files: parsing must
  // either succeed or throw ConfigError with a "name:line: error: " prefix, nothing else.
  const std::vector<std::string> seeds = {
      kExample,
      "# mrroc trajectory v1 representation=FRAME axes=5\n"
      "0 0 1 0.86 0 1 0 0 -1 0 0 1.155 duration=2\n",
      "# mrroc trajectory v1 representation=XYZ_ANGLE_AXIS axes=5\n0.8 0 1.1 0 1.5 0\n"};
  const char* seed_env = std::getenv("MRROC_FUZZ_SEED");
  const std::uint64_t seed = seed_env ? std::strtoull(seed_env, nullptr, 10) : 12345U;
  std::mt19937_64 random(seed);
  const std::string alphabet = "0123456789.-+eE= \t\n\r#xnaifJOINTMOTORFRAMEduration_scale\x01\xff";
  std::size_t accepted = 0;
  constexpr int kIterations = 5000;
  for (int i = 0; i < kIterations; ++i) {
    std::string text = seeds[random() % seeds.size()];
    const int edits = 1 + static_cast<int>(random() % 6);
    for (int e = 0; e < edits; ++e) {
      const std::size_t at = text.empty() ? 0 : random() % (text.size() + 1);
      const char c = alphabet[random() % alphabet.size()];
      switch (random() % 4) {
        case 0:
          if (at < text.size()) text[at] = c;
          break;
        case 1: text.insert(at, 1, c); break;
        case 2:
          if (at < text.size()) text.erase(at, 1 + random() % 8);
          break;
        default: {
          const std::size_t end = text.find('\n', at);
          if (end != std::string::npos) text.insert(end + 1, text.substr(at, end + 1 - at));
          break;
        }
      }
    }
    try {
      const auto t = ecp::TrajectoryFile::parse(text, "fuzz.traj");
      ++accepted;
      // Whatever was accepted writes and reads back the same.
      EXPECT_EQ(ecp::TrajectoryFile::parse(t.to_text(), "again.traj"), t)
          << "seed " << seed << " iteration " << i << "\n"
          << text;
    } catch (const ConfigError& e) {
      ASSERT_TRUE(std::string(e.what()).starts_with("fuzz.traj:"))
          << "seed " << seed << " iteration " << i << ": " << e.what();
      ASSERT_TRUE(contains(e.what(), ": error: ")) << e.what();
    } catch (const std::exception& e) {
      FAIL() << "seed " << seed << " iteration " << i << ": unexpected " << e.what() << "\n"
             << text;
    }
  }
  EXPECT_GT(accepted, 50U) << "the mutations should leave some files valid";
  EXPECT_LT(accepted, static_cast<std::size_t>(kIterations));
}

TEST(TeachIn, RecordSaveLoadAndPlayBackJointPoses) {
  const RobotModel& m = model();
  TempDir dir;
  ecp::TeachInRecorder recorder(m);
  ecp::RobotImage image;
  const std::vector<std::vector<double>> taught = {
      {0.2, -1.45, 0.1, 0.2, 0.4}, {-0.1, -1.65, -0.1, -0.2, 0.0}, {0.0, -1.5, 0.05, 0.0, -0.3}};
  image.joints = taught[0];
  recorder.record(image);
  image.joints = taught[1];
  recorder.record(image, 3.0);
  image.joints = taught[2];
  recorder.record(image, std::nullopt, 0.5);
  image.joints = {9, 9, 9, 9, 9};
  recorder.record(image);
  recorder.remove_last();
  EXPECT_THROW(recorder.record(ecp::RobotImage{}), Error);
  EXPECT_THROW(recorder.record(image, 1.0, 0.5), Error);
  ASSERT_EQ(recorder.trajectory().points.size(), 3U);

  const auto path = dir.file("taught.traj");
  recorder.save(path);
  const auto loaded = ecp::TrajectoryFile::load(path);
  EXPECT_EQ(loaded, recorder.trajectory());

  ecp::TeachInPlaybackGenerator g(m, loaded);
  const ecp::MotionPlan plan = g.plan_from(m.synchro_joint_positions);
  ASSERT_EQ(plan.segments.size(), 3U);
  for (std::size_t i = 0; i < taught.size(); ++i) {
    const auto& s = plan.segments[i];
    EXPECT_EQ(plan.targets[s.first_macro_step + s.macro_steps - 1], taught[i]);
  }
  EXPECT_NEAR(static_cast<double>(plan.segments[1].macro_steps) * plan.macro_step_s(), 3.0, 1e-9);
  // Run it as Move does: every command a JOINT SET ARM, the last one read after the stop.
  ecp::RobotImage robot;
  robot.desired_joints = m.synchro_joint_positions;
  std::size_t commands = 0;
  ASSERT_TRUE(g.first_step(robot, {}));
  do {
    ++commands;
    EXPECT_EQ(robot.command.set_arm_type, ArmRepresentation::joint);
    robot.desired_joints = robot.command.arm;
  } while (g.next_step(robot, {}));
  EXPECT_EQ(commands, plan.size());
  EXPECT_EQ(robot.desired_joints, taught.back());
  EXPECT_EQ(robot.command.value_in_step_no, robot.command.motion_steps + 1);
}

TEST(TeachIn, MotorAndCartesianRecordingsPlayBack) {
  const RobotModel& m = model();
  const auto kin = edp::make_arm_kinematics(m);
  ecp::RobotImage image;
  const std::vector<double> q = {0.0, -1.5, 0.1, 0.2, 0.3};
  image.joints = q;
  image.desired_joints = q;

  ecp::TeachInRecorder motors(m, ArmRepresentation::motor, ecp::TeachInRecorder::Source::desired);
  motors.record(image);
  EXPECT_EQ(motors.trajectory().points[0].values, kin->motors_from_joints(q));
  ecp::TeachInPlaybackGenerator motor_playback(
      m, ecp::TrajectoryFile::parse(motors.trajectory().to_text()));
  const auto motor_plan = motor_playback.plan_from(m.synchro_joint_positions);
  EXPECT_EQ(motor_plan.representation, ArmRepresentation::motor);
  for (std::size_t j = 0; j < q.size(); ++j) EXPECT_NEAR(motor_plan.joints.back()[j], q[j], 1e-9);

  ecp::TeachInRecorder frames(m, ArmRepresentation::frame);
  image.joints = m.synchro_joint_positions;
  image.joints[1] += 0.1;
  frames.record(image);
  image.joints[3] -= 0.2;
  frames.record(image, 2.0);
  ecp::TeachInPlaybackGenerator cartesian(m, frames.trajectory());
  const auto plan = cartesian.plan_from(m.synchro_joint_positions);
  ASSERT_EQ(plan.segments.size(), 2U);
  EXPECT_EQ(plan.representation, ArmRepresentation::frame);
  EXPECT_NEAR(static_cast<double>(plan.segments[1].macro_steps) * plan.macro_step_s(), 2.0, 1e-9);
  for (std::size_t j = 0; j < q.size(); ++j)
    EXPECT_NEAR(plan.joints.back()[j], image.joints[j], 1e-9);

  // A trajectory for another robot is refused.
  ecp::TrajectoryFile other = frames.trajectory();
  other.robot = "rnt";
  EXPECT_THROW(ecp::TeachInPlaybackGenerator(m, other), CommandError);
  other = frames.trajectory();
  other.axes = 6;
  EXPECT_THROW(ecp::TeachInPlaybackGenerator(m, other), CommandError);
}
