// Test task plugin (a shared library loaded through `library = ...`): ECP and MP tasks that
// exercise error handling and PAUSE/RESUME through real process sets.
#include <fmt/format.h>
#include <fmt/ranges.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <thread>

#include "mrroc/ecp/errors.hpp"
#include "mrroc/ecp/generators/joint_poses.hpp"
#include "mrroc/ecp/task.hpp"
#include "mrroc/edp/arm_kinematics.hpp"
#include "mrroc/kinematics/pose.hpp"
#include "mrroc/mp/task.hpp"

namespace {

using namespace mrroc;

/// A generator that moves the column and throws from next_step in its 20th macro-step, while
/// the robot is moving; with class "edp_refusal" it sends a macro-step the EDP refuses instead
/// (its reading after the last servo step + 5: bad_argument, a non-fatal refusal).
class ThrowingGenerator : public ecp::Generator {
 public:
  ThrowingGenerator(std::string error_class, int run) : class_(std::move(error_class)), run_(run) {}
  bool first_step(ecp::RobotImage& robot, const ecp::SensorList& sensors) override {
    start_ = robot.desired_joints;
    return next_step(robot, sensors);
  }
  bool next_step(ecp::RobotImage& robot, const ecp::SensorList&) override {
    if (++step_ == 20 && class_ != "edp_refusal") {
      const std::string text = fmt::format("deliberate {} error, run {}", class_, run_);
      if (class_ == "non_fatal") throw ecp::NonFatalError(text, 201);
      if (class_ == "fatal") throw ecp::FatalError(text, 202);
      throw ecp::SystemError(text, 203);
    }
    auto& c = robot.command;
    c = edp::Instruction{};
    c.type = edp::InstructionType::set;
    c.set = edp::item::arm;
    c.set_arm_type = edp::ArmRepresentation::joint;
    c.motion_steps = 10;
    c.value_in_step_no = 9;
    c.arm = start_;
    // Up to 0.1 rad/s at 1 rad/s^2 (the EDP refuses a jump to 0.1 rad/s from rest), then on.
    const double t = 0.02 * step_;
    c.arm[0] += t < 0.1 ? 0.5 * t * t : 0.005 + 0.1 * (t - 0.1);
    if (step_ == 20) c.value_in_step_no = c.motion_steps + 5;
    return true;
  }

 private:
  std::string class_;
  int run_;
  int step_ = 0;
  std::vector<double> start_;
};

/// ECP task "fail": a Move whose generator throws an error of the class given in `class`, for
/// the first `times` runs in this ECP process; later runs succeed.
class Fail : public ecp::EcpTask {
 public:
  explicit Fail(ecp::TaskContext& context)
      : context_(context),
        class_(context.args.get_string("class")),
        times_(context.args.get_int("times", 1)) {
    context.args.reject_unread("fail arguments");
  }
  void main_task() override {
    static std::atomic<int> runs{0};
    const int run = ++runs;
    if (run > times_) return;
    context_.robot.synchronise();
    // A previous run ended mid-motion: the macro-steps its EDP had queued (up to 8 of 20 ms)
    // and its stopping ramp (about 30 ms) end before this one starts from where the robot stands.
    std::this_thread::sleep_for(std::chrono::milliseconds(400));
    context_.robot.read_state();
    ThrowingGenerator generator(class_, run);
    ecp::Move(context_.robot, {}, generator);
  }

 private:
  ecp::TaskContext& context_;
  std::string class_;
  std::int64_t times_;
};
MRROC_REGISTER_ECP_TASK("fail", Fail);

/// ECP task "edp_settings": what a GET returns reaches the task. Sets the gripper as the tool
/// (0.25 m along the flange's z axis), kinematic model 1 and outputs 0x5, then reads TOOL, MODEL,
/// SERVO, INPUTS and TIMING back into the robot image, and checks that pose() uses the tool and
/// the model the EDP uses. Any mismatch is a fatal error naming it.
class EdpSettings : public ecp::EcpTask {
 public:
  explicit EdpSettings(ecp::TaskContext& context) : context_(context) {}
  void main_task() override {
    ecp::Robot& robot = context_.robot;
    robot.synchronise();
    const ecp::RobotImage& image = robot.image();
    expect(image.tool.has_value() && image.tool->isApprox(Eigen::Isometry3d::Identity()),
           "the first reading holds the EDP's tool (none)");
    expect(image.kinematic_model_no == 0, "the first reading holds the EDP's model (0)");
    const std::vector<double> flange = robot.pose(edp::ArmRepresentation::frame);

    Eigen::Isometry3d gripper = Eigen::Isometry3d::Identity();
    gripper.translation() = Eigen::Vector3d(0.0, 0.0, 0.25);
    edp::Instruction& c = robot.image().command;
    c = edp::Instruction{};
    c.type = edp::InstructionType::set_get;
    c.set = edp::item::tool | edp::item::model | edp::item::outputs;
    c.get = edp::item::arm | edp::item::servo | edp::item::timing;
    c.tool_type = edp::ArmRepresentation::frame;
    c.tool = kinematics::to_vector(gripper, edp::ArmRepresentation::frame);
    c.kinematic_model_no = 1;
    c.corrector_no = 0;
    c.output_values = 0x5;
    robot.execute();
    expect(image.servo_algorithm && image.servo_algorithm->size() == robot.model().axes(),
           "GET SERVO: one algorithm per axis");
    expect(image.timing && image.timing->cycles > 0 && image.timing->period_us == 2000.0,
           "GET TIMING: servo cycles counted, period 2000 us");
    // The outputs take effect in the next servo cycle: Wait on the inputs (16..19 are wired back
    // to outputs 0..3 in the MuJoCo plugin), reading them with the tool and model before each
    // check, at most 100 times 20 ms (2 s: a slow, instrumented build).
    class InputsShow : public ecp::RobotCondition {
     public:
      [[nodiscard]] std::uint8_t items() const override {
        return edp::item::arm | edp::item::tool | edp::item::model | edp::item::inputs;
      }
      bool holds(const ecp::RobotImage& robot, const ecp::SensorList&) override {
        return (robot.inputs && ((*robot.inputs >> 16U) & 0xFU) == 0x5U) || ++checks_ >= 100;
      }

     private:
      int checks_ = 0;
    } inputs_show_outputs;
    ecp::Wait(robot, {}, inputs_show_outputs, 0.02);
    expect(image.inputs && ((*image.inputs >> 16U) & 0xFU) == 0x5U,
           fmt::format("GET INPUTS: lines 16..19 show the outputs 0x5 (inputs {:#x})",
                       image.inputs.value_or(0)));
    expect(image.tool && image.tool->translation().isApprox(gripper.translation(), 1e-9),
           "GET TOOL: the gripper");
    expect(image.kinematic_model_no == 1 && image.corrector_no == 0, "GET MODEL: model 1");

    // pose(): the same frame as the robot's kinematics with that tool and model.
    auto k = edp::make_arm_kinematics(robot.model());
    k->select_model(1, 0);
    k->set_tool(gripper);
    const std::vector<double> expected =
        kinematics::to_vector(k->forward(image.joints), edp::ArmRepresentation::frame);
    const std::vector<double> got = robot.pose(edp::ArmRepresentation::frame);
    double worst = 0.0;
    for (std::size_t i = 0; i < got.size(); ++i)
      worst = std::max(worst, std::abs(got[i] - expected[i]));
    expect(got.size() == expected.size() && worst < 1e-9,
           fmt::format("pose() uses the tool and model 1 (largest difference {:.2e})", worst));
    const double moved = std::hypot(got[3] - flange[3], got[7] - flange[7], got[11] - flange[11]);
    expect(std::abs(moved - 0.25) < 0.01,
           fmt::format("the tool point is 0.25 m from the flange ({:.4f} m)", moved));
    context_.reporter.info(fmt::format(
        "edp settings read back: tool z {:.4f} m, model {}, inputs {:#x}, {} servo cycles",
        image.tool->translation().z(), *image.kinematic_model_no, *image.inputs,
        image.timing->cycles));
  }

 private:
  static void expect(bool ok, const std::string& what) {
    if (!ok) throw ecp::FatalError("not as expected: " + what, 210);
  }
  ecp::TaskContext& context_;
};
MRROC_REGISTER_ECP_TASK("edp_settings", EdpSettings);

/// ECP task "single_set": synchronises, then sends one SET ARM JOINT to `target` [rad] in
/// `motion_steps` servo steps (its reading after the motion). When the EDP refuses it, waits
/// 0.3 s, reads the arm back and reports the refusal's code and text and how far the commanded and
/// the measured joints moved since before the SET [rad], then rethrows the refusal (the ECP shell
/// passes its code and class on to the MP). When it is accepted, reports where the robot ended.
class SingleSet : public ecp::EcpTask {
 public:
  explicit SingleSet(ecp::TaskContext& context)
      : context_(context),
        target_(context.args.get_doubles("target")),
        steps_(static_cast<int>(context.args.get_int("motion_steps"))) {
    context.args.reject_unread("robot.ecp.args");
  }
  void main_task() override {
    ecp::Robot& robot = context_.robot;
    robot.synchronise();
    const std::vector<double> before = robot.image().joints;
    const std::vector<double> before_desired = robot.image().desired_joints;
    edp::Instruction& c = robot.image().command;
    c = edp::Instruction{};
    c.type = edp::InstructionType::set;
    c.set = edp::item::arm;
    c.set_arm_type = edp::ArmRepresentation::joint;
    c.motion_steps = steps_;
    c.value_in_step_no = steps_ + 1;
    c.arm = target_;
    try {
      robot.execute();
    } catch (const ecp::EdpRefused& e) {
      // Long enough for anything queued to have started moving (15 of the EDP's states).
      std::this_thread::sleep_for(std::chrono::milliseconds(300));
      robot.read_state();
      double moved = 0.0, commanded = 0.0;
      for (std::size_t i = 0; i < before.size(); ++i) {
        moved = std::max(moved, std::abs(robot.image().joints.at(i) - before[i]));
        commanded =
            std::max(commanded, std::abs(robot.image().desired_joints.at(i) - before_desired[i]));
      }
      context_.reporter.info(
          fmt::format("SET refused with code {}: {}; commanded joints moved by "
                      "at most {:.3e} rad, measured by at most {:.3e} rad",
                      e.code(), e.what(), commanded, moved));
      throw;
    }
    context_.reporter.info(
        fmt::format("SET accepted: joints [{:.4f}] rad", fmt::join(robot.image().joints, ", ")));
  }

 private:
  ecp::TaskContext& context_;
  std::vector<double> target_;
  int steps_;
};
MRROC_REGISTER_ECP_TASK("single_set", SingleSet);

/// MP task "retry": runs the ECP sub-task "fail" until it succeeds; goes on after non-fatal
/// errors, aborts on the others.
class Retry : public mp::MpTask {
 public:
  explicit Retry(mp::TaskContext& context) : context_(context) {
    arguments_ = context.args.get_string("arguments");
    attempts_ = context.args.get_int("attempts", 3);
    context.args.reject_unread("mp.args");
  }
  void main_task() override {
    mp::Robot& robot = *context_.robots.front();
    for (std::int64_t attempt = 1;; ++attempt) {
      try {
        robot.next_state("fail", arguments_);
        context_.reporter.info(fmt::format("succeeded at attempt {}", attempt));
        return;
      } catch (const mp::EcpFailed& e) {
        if (e.error_class() != ecp::ErrorClass::non_fatal || attempt >= attempts_) {
          context_.reporter.error(e.code(), fmt::format("aborting: {}", e.what()));
          throw;
        }
        context_.reporter.warning(
            fmt::format("non-fatal error (code {}), retrying: {}", e.code(), e.what()));
      }
    }
  }

 private:
  mp::TaskContext& context_;
  std::string arguments_;
  std::int64_t attempts_ = 3;
};
MRROC_REGISTER_MP_TASK("retry", Retry);

/// MP task "pause_resume": one long joint move (NEXT_STATE visit_joint_poses) paused for
/// `pause_s` seconds half-way through.
class PauseResume : public mp::MpTask {
 public:
  explicit PauseResume(mp::TaskContext& context) : context_(context) {
    pause_s_ = context.args.get_double("pause_s", 1.0);
    context.args.reject_unread("mp.args");
  }
  void main_task() override {
    mp::Robot& robot = *context_.robots.front();
    robot.start_task();  // follow_mp: synchronise
    const auto t0 = std::chrono::steady_clock::now();
    std::thread move([&] {
      robot.next_state("visit_joint_poses",
                       "poses = [[1.0, -1.5708, 0.0, 0.0, 0.0], "
                       "[0.0, -1.5708, 0.0, 0.0, 0.0]]\n");
    });
    std::this_thread::sleep_for(std::chrono::milliseconds(800));
    robot.pause();
    context_.reporter.info("PAUSE sent");
    std::this_thread::sleep_for(std::chrono::duration<double>(pause_s_));
    robot.resume();
    context_.reporter.info("RESUME sent");
    move.join();
    const double total =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    context_.reporter.info(fmt::format("move with pause took {:.3f} s", total));
  }

 private:
  mp::TaskContext& context_;
  double pause_s_ = 1.0;
};
MRROC_REGISTER_MP_TASK("pause_resume", PauseResume);

/// MP-level Wait over robots: every robot synchronised and at rest, from the images the EDPs'
/// state broadcasts keep current.
class AllAtRest : public mp::Condition {
 public:
  bool check(const mp::ImageList& robots, const ecp::SensorList&) override {
    ++checks;
    for (const mp::RobotImage* r : robots) {
      if (r->state_servo_step < 0 || !r->synchronised || r->moving) return false;
      for (double v : r->joint_velocities)
        if (std::abs(v) > 1e-3) return false;
    }
    return true;
  }
  int checks = 0;
};

/// MP task "first_then_rest": starts every robot's ECP task at once, reports the robot whose
/// task ended first, then Waits on the MP level until every robot stands still (the others'
/// motions end while the MP polls their images), and collects the rest.
class FirstThenRest : public mp::MpTask {
 public:
  explicit FirstThenRest(mp::TaskContext& context) : context_(context) {}
  void main_task() override {
    mp::Running tasks(context_.robots, [](mp::Robot& r) { r.start_task(); });
    const mp::Robot& first = tasks.wait_any(60.0);
    context_.reporter.info("first to finish: " + first.name());
    std::vector<std::int64_t> steps_before;
    for (const mp::Robot* r : context_.robots)
      steps_before.push_back(r->state_image().state_servo_step);
    AllAtRest rest;
    mp::Wait(context_.robots, {}, rest, 0.02, 30.0);
    for (std::size_t i = 0; i < context_.robots.size(); ++i)
      if (context_.robots[i]->state_image().state_servo_step <= steps_before[i])
        throw Error(fmt::format("{}: the MP's image was not refreshed from the EDP's states",
                                context_.robots[i]->name()));
    context_.reporter.info(fmt::format("every robot at rest after {} checks", rest.checks));
    tasks.wait_all();
    context_.reporter.info("every robot's task ended");
  }

 private:
  mp::TaskContext& context_;
};
MRROC_REGISTER_MP_TASK("first_then_rest", FirstThenRest);

}  // namespace
