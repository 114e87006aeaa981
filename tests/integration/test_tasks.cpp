// Test task plugin (a shared library loaded through `library = ...`): ECP and MP tasks that
// exercise error handling and PAUSE/RESUME through real process sets.
#include <fmt/format.h>

#include <atomic>
#include <chrono>
#include <thread>

#include "mrroc/ecp/errors.hpp"
#include "mrroc/ecp/generators/joint_poses.hpp"
#include "mrroc/ecp/task.hpp"
#include "mrroc/mp/task.hpp"

namespace {

using namespace mrroc;

/// A generator that moves the column and throws from next_step in its 20th macro-step, while
/// the robot is moving.
class ThrowingGenerator : public ecp::Generator {
 public:
  ThrowingGenerator(std::string error_class, int run) : class_(std::move(error_class)), run_(run) {}
  bool first_step(ecp::RobotImage& robot, const ecp::SensorList& sensors) override {
    start_ = robot.desired_joints;
    return next_step(robot, sensors);
  }
  bool next_step(ecp::RobotImage& robot, const ecp::SensorList&) override {
    if (++step_ == 20) {
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

}  // namespace
