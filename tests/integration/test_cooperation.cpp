// The three kinds of multi-robot tasks of the paper, each a real process set started by
// mrroc-launch, with checked outcomes read from the robots' own EDP replies and the MP's report.
#include <gtest/gtest.h>

#include <sys/wait.h>
#include <unistd.h>
#include "launch_helpers.hpp"

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <map>
#include <mutex>
#include <regex>
#include <string>
#include <thread>
#include <vector>

#include "mrroc/comm/bus.hpp"
#include "mrroc/comm/codec.hpp"
#include "mrroc/comm/sync_annotations.hpp"
#include "mrroc/config/process_set.hpp"
#include "mrroc/robot/robot_model.hpp"
#include "state_watch.hpp"

namespace fs = std::filesystem;
using namespace mrroc;

namespace {

const fs::path kBin = MRROC_BIN_DIR;
const fs::path kSource = MRROC_SOURCE_DIR;

using RunResult = mrroc::test::LaunchRun;

RunResult launch(const std::string& config) { return mrroc::test::launch_and_kill(config); }

/// Last DATA reply (measured joints) of every robot's EDP, as the EDPs sent them.
class FinalJoints {
 public:
  FinalJoints(comm::Bus& bus, const std::vector<std::string>& robots) {
    for (const auto& robot : robots) {
      auto* slot = &slots_[robot];
      slot->owner = this;
      bus.subscribe<Slot*>(channels::edp_reply(robot), &FinalJoints::on_reply, slot);
    }
  }
  std::vector<double> of(const std::string& robot) {
    std::lock_guard lock(mutex_);
    return slots_[robot].joints;
  }

 private:
  struct Slot {
    FinalJoints* owner = nullptr;
    std::vector<double> joints;
  };
  static void on_reply(const lcm::ReceiveBuffer* buffer, const std::string&, Slot* slot) {
    mrroc_lcm::edp_reply_t msg;
    if (!comm::detail::decode_received(buffer, msg)) return;
    if (msg.header.kind != mrroc_lcm::header_t::REPLY) return;
    const edp::Reply reply = comm::decode(msg);
    if (reply.type != edp::ReplyType::data || !reply.synchronised) return;
    std::lock_guard lock(slot->owner->mutex_);
    slot->joints = reply.joints;
  }
  std::mutex mutex_;
  std::map<std::string, Slot> slots_;
};

void expect_near(const std::vector<double>& actual, const std::vector<double>& expected,
                 double tolerance, const std::string& what) {
  ASSERT_EQ(actual.size(), expected.size()) << what;
  for (std::size_t j = 0; j < expected.size(); ++j)
    EXPECT_NEAR(actual[j], expected[j], tolerance) << what << " joint " << j;
}

}  // namespace

TEST(Cooperation, IndependentRobotsRunTheirOwnTasks) {
  const std::string file = (kSource / "configs/independent.toml").string();
  const ProcessSetConfig config = load_process_set(file);
  comm::Bus bus(config.lcm_url);
  FinalJoints final_joints(bus, {"irb6", "rnt"});
  bus.start();
  const RunResult r = launch(file);
  bus.stop();
  ASSERT_EQ(r.exit_code, 0) << r.output;
  for (const auto& robot : config.robots) {
    EXPECT_NE(r.output.find("ecp/" + robot.name + ": TASK_TERMINATED"), std::string::npos)
        << r.output;
    expect_near(final_joints.of(robot.name), robot.ecp.args.get_double_rows("poses").back(), 2e-3,
                robot.name);
  }
}

TEST(Cooperation, LooseConveyorStartsOnlyAfterThePlacement) {
  const std::string file = (kSource / "configs/loose-conveyor.toml").string();
  const ProcessSetConfig config = load_process_set(file);
  comm::Bus bus(config.lcm_url);
  FinalJoints final_joints(bus, {"irb6", "conveyor"});
  bus.start();
  const RunResult r = launch(file);
  bus.stop();
  ASSERT_EQ(r.exit_code, 0) << r.output;
  // Order of events: released on the belt, then (and only then) the belt moves.
  const auto placed = r.output.find("object placed on the conveyor by irb6");
  std::smatch started;  // the SRP's line of the belt ECP's report
  const auto belt_task =
      std::regex_search(r.output, started,
                        std::regex("ecp/conveyor +info +task 'visit_joint_poses' started"))
          ? static_cast<std::size_t>(started.position(0))
          : std::string::npos;
  const auto delivered = r.output.find("object delivered: conveyor at");
  ASSERT_NE(placed, std::string::npos) << r.output;
  ASSERT_NE(belt_task, std::string::npos) << r.output;
  ASSERT_NE(delivered, std::string::npos) << r.output;
  EXPECT_LT(placed, belt_task);
  EXPECT_LT(belt_task, delivered);
  EXPECT_NE(r.output.find("outputs set to 0x1"), std::string::npos) << "gripper never closed";
  EXPECT_NEAR(final_joints.of("conveyor").at(0), config.mp.args.get_double("belt_target"), 2e-3);
  expect_near(final_joints.of("irb6"), config.mp.args.get_doubles("retreat"), 2e-3, "irb6");
}

TEST(Cooperation, LooseConveyorAsAStateMachineEndsAsTheCppTask) {
  // The routine of place_on_conveyor written as data (MP task state_machine): the same order of
  // events and the same final poses as the C++ task's arguments in loose-conveyor.toml.
  const ProcessSetConfig cpp = load_process_set(kSource / "configs/loose-conveyor.toml");
  const std::string file = (kSource / "configs/loose-conveyor-fsm.toml").string();
  const ProcessSetConfig config = load_process_set(file);
  comm::Bus bus(config.lcm_url);
  FinalJoints final_joints(bus, {"irb6", "conveyor"});
  bus.start();
  const RunResult r = launch(file);
  bus.stop();
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const auto placed = r.output.find("object placed on the conveyor by irb6");
  std::smatch started;
  const auto belt_task =
      std::regex_search(r.output, started,
                        std::regex("ecp/conveyor +info +task 'visit_joint_poses' started"))
          ? static_cast<std::size_t>(started.position(0))
          : std::string::npos;
  const auto delivered = r.output.find("object delivered by conveyor");
  ASSERT_NE(placed, std::string::npos) << r.output;
  ASSERT_NE(belt_task, std::string::npos) << r.output;
  ASSERT_NE(delivered, std::string::npos) << r.output;
  EXPECT_LT(placed, belt_task);
  EXPECT_LT(belt_task, delivered);
  EXPECT_NE(r.output.find("state 'check_delivery' -> 'done'"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("outputs set to 0x1"), std::string::npos) << "gripper never closed";
  const std::vector<double> belt = final_joints.of("conveyor");
  const std::vector<double> arm = final_joints.of("irb6");
  ASSERT_EQ(belt.size(), 1U);
  EXPECT_NEAR(belt.at(0), cpp.mp.args.get_double("belt_target"), 2e-3);
  expect_near(arm, cpp.mp.args.get_doubles("retreat"), 2e-3, "irb6");
  std::printf(
      "state machine: conveyor at %.4f m (C++ task's target %.4f m), irb6 joint 1 at "
      "%.4f rad\n",
      belt.at(0), cpp.mp.args.get_double("belt_target"), arm.size() > 1 ? arm[1] : 0.0);
}

TEST(Cooperation, AStateMachineGoesToFailedWithItsMessageWhenTheConditionTimesOut) {
  // The same machine with a belt target the conveyor does not reach by the check: the state
  // check_delivery times out and the task fails with the state's message, the belt where the
  // sub-task left it (0.6 m).
  const fs::path dir = fs::temp_directory_path() / ("mrroc-fsm-" + std::to_string(::getpid()));
  fs::create_directories(dir / "tasks");
  std::ifstream in(kSource / "configs/tasks/loose-conveyor.fsm.toml");
  std::string machine((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const std::string target = "poses = [[1.2]]";
  ASSERT_NE(machine.find(target), std::string::npos);
  machine.replace(machine.find(target), target.size(), "poses = [[0.6]]");
  std::ofstream(dir / "tasks/loose-conveyor.fsm.toml") << machine;
  std::ifstream config_in(kSource / "configs/loose-conveyor-fsm.toml");
  std::string text((std::istreambuf_iterator<char>(config_in)), std::istreambuf_iterator<char>());
  for (const char* model : {"../robots/irb6", "../robots/conveyor"}) {
    const std::string absolute = (kSource / "robots" / fs::path(model).filename()).string();
    text.replace(text.find(model), std::string(model).size(), absolute);
  }
  const fs::path file = dir / "short-belt.toml";
  std::ofstream(file) << text;
  comm::Bus bus(load_process_set(file).lcm_url);
  FinalJoints final_joints(bus, {"conveyor"});
  bus.start();
  const RunResult r = launch(file.string());
  bus.stop();
  EXPECT_NE(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("object not delivered: the conveyor's belt is not within 2 mm of 1.2 m"),
            std::string::npos)
      << r.output;
  EXPECT_NE(r.output.find("state 'check_delivery' -> 'failed'"), std::string::npos) << r.output;
  EXPECT_EQ(r.output.find("object delivered by conveyor"), std::string::npos) << r.output;
  EXPECT_NEAR(final_joints.of("conveyor").at(0), 0.6, 2e-3);
  fs::remove_all(dir);
}

TEST(Cooperation, TightTwoRobotsKeepTheBarRigid) {
  const std::string file = (kSource / "configs/tight-bar.toml").string();
  const RunResult r = launch(file);
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const std::regex report("grip distance within ([0-9.]+) mm of its start value");
  std::smatch m;
  ASSERT_TRUE(std::regex_search(r.output, m, report)) << r.output;
  const double deviation_mm = std::stod(m[1]);
  EXPECT_LT(deviation_mm, 1.0);
  EXPECT_GE(deviation_mm, 0.0);
  std::printf("bar: grip distance deviation %.3f mm\n", deviation_mm);
  const std::regex steps("in ([0-9]+) macro-steps");
  ASSERT_TRUE(std::regex_search(r.output, m, steps));
  EXPECT_GT(std::stoi(m[1]), 100) << "the MP must generate the trajectory macro-step by macro-step";
}

/// The engrave task's last report: strokes, cutting samples, cutter tip's distance [mm].
const std::regex& engraving_report() {
  static const std::regex report(
      "engraved 'MRROC': ([0-9]+) strokes, ([0-9]+) cutting samples, cutter tip within ([0-9.]+) "
      "mm of the strokes");
  return report;
}

TEST(Cooperation, RntEngravesMrrocOnTheStrokes) {
  const std::string file = (kSource / "configs/engrave-rnt.toml").string();
  const RunResult r = launch(file);
  ASSERT_EQ(r.exit_code, 0) << r.output;
  std::smatch m;
  ASSERT_TRUE(std::regex_search(r.output, m, engraving_report())) << r.output;
  EXPECT_GT(std::stoi(m[1]), 30);
  EXPECT_GT(std::stoi(m[2]), 200) << "too few samples in the wood to judge the engraving";
  EXPECT_LT(std::stod(m[3]), 0.5);
  std::printf("engraving: %s strokes, %s samples, within %s mm\n", m[1].str().c_str(),
              m[2].str().c_str(), m[3].str().c_str());
}

TEST(Cooperation, AnEngravingWhoseEcpIsHeld400MsResumesOnItsStrokes) {
  // The ECP stopped (SIGSTOP) for 400 ms while it engraves the R: longer than the EDP's
  // lookahead of 8 macro-steps (160 ms), so the EDP brings the cutter to rest within the limits
  // and then refuses the planned continuation as too fast from there. The task's generator
  // re-plans from where the cutter stands (Move's resume): the engraving goes on, stays on its
  // strokes, and the motion stays within the limits throughout.
  const std::string file = (kSource / "configs/engrave-rnt.toml").string();
  const ProcessSetConfig config = load_process_set(file);
  const RobotModel model = load_robot_model(config.robots.at(0).model_dir);
  comm::Bus bus(config.lcm_url);
  mrroc::test::StateWatch states(bus, "rnt");
  bus.start();
  const RunResult r = mrroc::test::launch_and_act(
      file, "ecp/rnt", "letter 'M' engraved", std::chrono::milliseconds(300), [](pid_t pid) {
        kill(pid, SIGSTOP);
        std::this_thread::sleep_for(std::chrono::milliseconds(400));
        kill(pid, SIGCONT);
      });
  bus.stop();
  ASSERT_NE(r.killed_at, mrroc::test::Clock::time_point{}) << "the ECP was never stopped\n"
                                                           << r.output;
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_TRUE(mrroc::test::has(r.output, "no next macro-step from the ECP in time")) << r.output;
  EXPECT_TRUE(std::regex_search(
      r.output, std::regex("letter '[MRROC]' engraved; resumed from rest [0-9]+ time")))
      << r.output;
  std::smatch m;
  ASSERT_TRUE(std::regex_search(r.output, m, engraving_report())) << r.output;
  EXPECT_LT(std::stod(m[3]), 0.5);
  const mrroc::test::MotionCheck motion = mrroc::test::check_commanded_motion(
      states.history(), model, config.robots.at(0).edp.servo_period_s);
  EXPECT_GT(motion.states, 200);
  std::printf(
      "engraving with its ECP held 400 ms: within %s mm of the strokes; velocity up to %.0f %%, "
      "acceleration up to %.0f %% of the limits over %d states\n",
      m[3].str().c_str(), motion.worst_velocity_share * 100, motion.worst_acceleration_share * 100,
      motion.states);
}
