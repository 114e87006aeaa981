// The servo loop on hardware that keeps its own clock, cycle by cycle: missed periods injected as
// arguments (ServoLoop::step) instead of stalls, so every run is the same. However a stall lands
// in a motion whose queue then runs dry (the client stopped: the group of tight-bar-can stopped
// for 400 ms), no commanded servo step accelerates a joint beyond its limit: not while the motion
// makes up the missed steps, not where it ends and the stopping ramp takes over, not where a
// macro-step is refused, and not in the motion resumed from rest.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <memory>
#include <vector>

#include "edp_parts.hpp"
#include "mrroc/edp/arm_kinematics.hpp"
#include "mrroc/edp/hardware.hpp"
#include "mrroc/robot/robot_model.hpp"
#include "servo_loop.hpp"

using namespace mrroc;
using namespace mrroc::edp;

namespace {

constexpr double kPeriod = 0.002;
constexpr int kLookahead = 8;

/// The mock plugin (every axis follows its setpoint) as drives that keep their own clock
/// (simulated() false): the servo loop makes up the servo steps of the periods it misses.
class ClockedMock final : public Hardware {
 public:
  explicit ClockedMock(std::unique_ptr<Hardware> inner) : inner_(std::move(inner)) {}
  std::string name() const override { return "clocked-mock"; }
  std::size_t axis_count() const override { return inner_->axis_count(); }
  void configure(const HardwareSetup& setup) override { inner_->configure(setup); }
  void activate() override { inner_->activate(); }
  void deactivate() override { inner_->deactivate(); }
  CycleStatus read(std::span<AxisFeedback> out) override { return inner_->read(out); }
  CycleStatus write(std::span<const double> setpoints) override { return inner_->write(setpoints); }
  bool simulated() const override { return false; }

 private:
  std::unique_ptr<Hardware> inner_;
};

/// Where a run stalls and where its client stops.
struct Scenario {
  int stall_cycle = -1;        ///< cycle of the motion (from its first) that wakes late; -1: none
  int missed = 0;              ///< periods that cycle missed
  int client_stops_after = 0;  ///< cruise macro-steps sent before the client stops
  /// The client comes back this many cycles after it stopped, sends the rest of the plan (which
  /// the EDP refuses: the robot came to rest) and then resumes from rest; 0: it never does.
  int comes_back_after = 0;
  /// The macro-step (counted from the first) that jumps to twice the velocity: refused as too
  /// abrupt when it is due, with the robot moving; 0: none.
  int abrupt_at = 0;
};

struct Worst {
  double share = 0.0;  ///< largest |commanded acceleration| / limit over joints and servo steps
  std::size_t joint = 0;
  std::int64_t cycle = 0;
  double acceleration = 0.0;
};

/// One EDP's servo loop on ClockedMock, synchronised, run cycle by cycle.
class Rig {
 public:
  Rig()
      : model_(test::stock_model("irb6")),
        hardware_(
            std::make_unique<ClockedMock>(test::configured_hardware(model_, "mock", kPeriod))),
        kinematics_(make_arm_kinematics(model_)),
        servo_(*hardware_, model_, kPeriod) {
    servo_.set_limit_guard(kinematics_.get());
    servo_.set_lookahead(kLookahead);
    servo_.enable_trace(20000);
    servo_.start_stepped();
    servo_.begin_synchronisation();
    for (int k = 0; k < 20000 && !(servo_.synchronised() && !servo_.moving()); ++k) servo_.step();
  }
  ~Rig() { servo_.stop(); }
  Rig(const Rig&) = delete;
  Rig& operator=(const Rig&) = delete;

  ServoLoop& servo() { return servo_; }
  const RobotModel& model() const { return model_; }

  /// The bar carry in joints: lower arm, upper arm and wrist pitch move together (the upper arm
  /// at `cruise` rad/s) in macro-steps of 10 servo steps read 3 early, after a first one of 240
  /// from rest; the client keeps the lookahead full until it stops.
  Worst run(const Scenario& s, double cruise = 0.3) {
    const std::int64_t first = servo_.latest().cycle;
    std::vector<double> q = servo_.planned_end();
    const std::vector<double> rate = {0.0, -0.5 * cruise, cruise, -0.5 * cruise, 0.0};
    int sent = 0;
    auto send = [&](int steps, int value) {
      const double jump = s.abrupt_at > 0 && sent == s.abrupt_at ? 2.0 : 1.0;
      for (std::size_t j = 0; j < q.size(); ++j) q[j] += jump * rate[j] * steps * kPeriod;
      servo_.submit(q, steps, value);
      ++sent;
    };
    send(240, 237);
    int cycle = 0;
    int stopped_at = -1;
    bool resumed = false;
    for (; cycle < 6000; ++cycle) {
      // A client that sends the next macro-step as soon as a reply lets it (the lookahead full).
      while (sent <= s.client_stops_after && servo_.queued_steps() < 10 * kLookahead) send(10, 7);
      const bool stopped = sent > s.client_stops_after;
      if (stopped && stopped_at < 0) stopped_at = cycle;
      if (stopped && s.comes_back_after > 0 && !resumed &&
          cycle == stopped_at + s.comes_back_after) {
        // The rest of the plan, as the MP had it: refused (the robot is at rest, or on its ramp).
        for (int k = 0; k < 3; ++k) send(10, 7);
        for (int k = 0; k < 400 && servo_.moving(); ++k) servo_.step();
        EXPECT_NE(servo_.refused_upto(), 0U) << "the plan's rest was not refused";
        // Resumed from rest where the robot stands: to the cruise in 240 steps, 5 macro-steps of
        // it, and to rest in 240.
        q = servo_.planned_end();
        send(240, 237);
        for (int k = 0; k < 5; ++k) send(10, 7);
        for (std::size_t j = 0; j < q.size(); ++j) q[j] += 0.5 * rate[j] * 240 * kPeriod;
        servo_.submit(q, 240, 241);
        resumed = true;
      }
      servo_.step(cycle == s.stall_cycle ? s.missed : 0);
      if (stopped && (s.comes_back_after == 0 || resumed) && servo_.stopped()) break;
    }
    EXPECT_LT(cycle, 6000) << "the robot never came to rest";
    return worst_since(first);
  }

  /// The column alone along a plan with corners: to 0.3 rad/s in 240 servo steps from rest,
  /// macro-steps of 10 servo steps (read 3 early) at that cruise, then speeding up at
  /// 0.25 rad/s^2 and at 0.44 rad/s^2 (the queued mean velocities change by less than the catch-up
  /// tolerates, kWarpQueuedAccelerationShare of the limit of 3 rad/s^2), a cruise again, and
  /// slowing down at 0.44 rad/s^2 to rest. The blend turns each change of the speed-up into a jump
  /// of the planned acceleration half way through a macro-step (-0.13 to 0.38, 0.16 to
  /// 0.54 rad/s^2). The cycle `stall_cycle` (from the motion's first) wakes `missed` periods late.
  Worst run_corners(int stall_cycle, int missed) {
    const std::int64_t first = servo_.latest().cycle;
    std::vector<double> q = servo_.planned_end();
    constexpr double kMacroStepS = 10 * kPeriod;
    std::vector<double> means;  // of the column, per macro-step after the first [rad/s]
    for (int k = 0; k < 20; ++k) means.push_back(0.3);
    for (int k = 1; k <= 12; ++k) means.push_back(0.3 + 0.25 * kMacroStepS * k);
    const double top = means.back();
    for (int k = 1; k <= 12; ++k) means.push_back(top + 0.44 * kMacroStepS * k);
    for (int k = 0; k < 10; ++k) means.push_back(means.back());
    while (means.back() > 0.005) means.push_back(means.back() - 0.44 * kMacroStepS);
    means.back() = 0.5 * means[means.size() - 2];  // the last one ends at rest
    const std::size_t plan = means.size() + 1;
    std::size_t sent = 0;
    auto send = [&]() {
      if (sent == 0) {
        q[0] += 0.3 * 240 * kPeriod;
        servo_.submit(q, 240, 237);
      } else {
        q[0] += means[sent - 1] * kMacroStepS;
        servo_.submit(q, 10, sent + 1 == plan ? 11 : 7);
      }
      ++sent;
    };
    int cycle = 0;
    for (; cycle < 3000; ++cycle) {
      while (sent < plan && servo_.queued_steps() < 10 * kLookahead) send();
      servo_.step(cycle == stall_cycle ? missed : 0);
      if (sent == plan && servo_.stopped()) break;
    }
    EXPECT_LT(cycle, 3000) << "the robot never came to rest";
    EXPECT_EQ(servo_.refused_upto(), 0U) << "a macro-step of the plan was refused";
    EXPECT_EQ(servo_.lost_successors(), 0) << "the plan did not end at rest as planned";
    return worst_since(first);
  }

  /// The hardest commanded acceleration of any joint between consecutive servo steps of the trace
  /// after cycle `first`.
  Worst worst_since(std::int64_t first) const {
    const auto trace = servo_.trace();
    Worst w;
    for (std::size_t k = 2; k < trace.size(); ++k) {
      if (trace[k - 2].cycle < first || !trace[k - 2].synchronised) continue;
      for (std::size_t j = 0; j < model_.axes(); ++j) {
        const double a =
            (trace[k].desired[j] - 2.0 * trace[k - 1].desired[j] + trace[k - 2].desired[j]) /
            (kPeriod * kPeriod);
        const double share = std::abs(a) / model_.max_acceleration[j];
        if (share > w.share) w = {share, j, trace[k].cycle, a};
      }
    }
    return w;
  }

 private:
  RobotModel model_;
  std::unique_ptr<Hardware> hardware_;
  std::unique_ptr<ArmKinematics> kinematics_;
  ServoLoop servo_;
};

TEST(CatchUp, WithoutAStallTheRampFromADryQueueStaysWithinTheLimits) {
  Rig rig;
  ASSERT_TRUE(rig.servo().synchronised());
  const Worst w = rig.run({-1, 0, 30, 0});
  EXPECT_EQ(rig.servo().lost_successors(), 1);
  EXPECT_LE(w.share, 1.0 + 1e-6) << "joint " << w.joint << " at " << w.acceleration
                                 << " rad/s^2, cycle " << w.cycle;
}

// One stall mid-cruise, made up before the client stops; the queue then runs dry and the robot
// is ramped to rest.
TEST(CatchUp, AStallMadeUpBeforeTheQueueRunsDryLeavesNoStepBeyondTheLimits) {
  Rig rig;
  ASSERT_TRUE(rig.servo().synchronised());
  const Worst w = rig.run({300, 1, 40, 0});
  EXPECT_EQ(rig.servo().caught_up_steps(), 1);
  EXPECT_EQ(rig.servo().lost_successors(), 1);
  EXPECT_LE(w.share, 1.0 + 1e-6) << "joint " << w.joint << " at " << w.acceleration
                                 << " rad/s^2, cycle " << w.cycle;
}

// A stall whose lead carries the macro-steps' ends into the middle of cycles, then a macro-step
// refused while the robot moves: the ramp to rest starts in the cycle after the one that ended
// the motion, not on top of it.
TEST(CatchUp, AMacroStepRefusedMidCycleStartsTheRampInTheNextCycle) {
  Worst worst;
  int refused = 0;
  for (const int missed : {1, 2, 3, 7})
    for (int stall = 250; stall < 450; stall += 17) {
      Rig rig;
      ASSERT_TRUE(rig.servo().synchronised());
      const Worst w = rig.run({stall, missed, 40, 0, 35});
      if (rig.servo().refused_upto() != 0) ++refused;
      if (w.share > worst.share) worst = w;
    }
  EXPECT_EQ(refused, 48) << "the jump was not refused in every run";
  EXPECT_LE(worst.share, 1.0 + 1e-6) << "joint " << worst.joint << " at " << worst.acceleration
                                     << " rad/s^2, cycle " << worst.cycle;
}

// Stalls of 1..20 periods at every cycle of a stretch, the client stopping early or late after
// them, then coming back: the rest of its plan refused, the motion resumed from rest.
TEST(CatchUp, NoStallLeavesAStepBeyondTheLimitsWhereverItLands) {
  Worst worst;
  Scenario at;
  int runs = 0;
  for (const int missed : {1, 2, 3, 7, 20})
    for (int stall = 250; stall < 550; stall += 13)
      for (const int stops : {20, 30, 45}) {
        const Scenario s{stall, missed, stops, 150};
        Rig rig;
        ASSERT_TRUE(rig.servo().synchronised());
        const Worst w = rig.run(s);
        ++runs;
        if (w.share > worst.share) {
          worst = w;
          at = s;
        }
        if (HasFatalFailure()) return;
      }
  std::printf(
      "%d runs: hardest commanded acceleration %.4f of the limit (joint %zu, %.4f rad/s^2, cycle "
      "%lld; %d periods missed in cycle %d, client stopped after %d macro-steps)\n",
      runs, worst.share, worst.joint, worst.acceleration, static_cast<long long>(worst.cycle),
      at.missed, at.stall_cycle, at.client_stops_after);
  EXPECT_LE(worst.share, 1.0 + 1e-6);
}

// A stall of one period just before a corner of the plan: the rate that makes up the missed step
// rises while the planned acceleration jumps, and the commanded acceleration is the sum of both.
// Every cycle of a stretch that covers both corners stalls once, in a run of its own.
TEST(CatchUp, AStallBeforeACornerOfThePlanLeavesNoStepBeyondTheLimits) {
  double planned = 0.0;  // the plan's own hardest acceleration, without a stall
  {
    Rig rig;
    ASSERT_TRUE(rig.servo().synchronised());
    planned = rig.run_corners(-1, 0).share;
  }
  Worst worst;
  int at = -1;
  int runs = 0;
  int caught_up = 0;
  for (int stall = 420; stall < 600; stall += 2) {
    Rig rig;
    ASSERT_TRUE(rig.servo().synchronised());
    const Worst w = rig.run_corners(stall, 1);
    ++runs;
    caught_up += static_cast<int>(rig.servo().caught_up_steps());
    if (w.share > worst.share) {
      worst = w;
      at = stall;
    }
    if (HasFailure()) return;
  }
  std::printf(
      "%d runs: hardest commanded acceleration %.4f of the limit (joint %zu, %.4f rad/s^2, cycle "
      "%lld; one period missed in cycle %d; without a stall %.4f)\n",
      runs, worst.share, worst.joint, worst.acceleration, static_cast<long long>(worst.cycle), at,
      planned);
  EXPECT_EQ(caught_up, runs) << "not every stall was made up";
  EXPECT_LE(worst.share, 1.0 + 1e-6);
}

}  // namespace
