// Continuous motion on a busy host: the two-robot bar carry (configs/tight-bar.toml, real time,
// 2 ms servo, MuJoCo) with a CPU-bound busy loop on every core beside it, and with its MP or one
// ECP stopped for 50 ms (SIGSTOP, SIGCONT) in the middle of the carry. Judged by the motion, not
// only its end: no EDP brings a robot to a standstill for want of a macro-step, every commanded
// joint velocity stays within its limit and every commanded acceleration of the carry within
// its limit (read from the states both EDPs broadcast), and the bar stays rigid to 0.2 mm.
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <regex>
#include <string>
#include <thread>
#include <vector>

#include "busy_loops.hpp"
#include "launch_helpers.hpp"
#include "mrroc/robot/robot_model.hpp"
#include "state_watch.hpp"

namespace fs = std::filesystem;
using namespace mrroc;
using mrroc::test::BusyLoops;
using mrroc::test::Clock;
using mrroc::test::LaunchRun;
using mrroc::test::StateWatch;

namespace {

const fs::path kSource = MRROC_SOURCE_DIR;

int count_of(const std::string& text, const std::string& what) {
  int n = 0;
  for (std::size_t at = text.find(what); at != std::string::npos; at = text.find(what, at + 1)) ++n;
  return n;
}

/// Checks the commanded motion one EDP broadcast: velocities within the limits everywhere;
/// accelerations within the limits during the carry (the states after the half-second dwell
/// that follows the approach; the approach itself is one long macro-step from standstill, whose
/// start no EDP check shapes yet). Returns the number of carry states checked.
int check_motion(const std::vector<StateWatch::Sample>& states, const RobotModel& model,
                 double period_s, const std::string& robot) {
  struct Rate {
    std::int64_t step;
    double dt;
    std::vector<double> v;
  };
  std::vector<Rate> rates;
  for (std::size_t k = 1; k < states.size(); ++k) {
    const auto& a = states[k - 1];
    const auto& b = states[k];
    if (!a.synchronised || !b.synchronised || b.servo_step <= a.servo_step) continue;
    const double dt = static_cast<double>(b.servo_step - a.servo_step) * period_s;
    std::vector<double> v(model.axes());
    for (std::size_t j = 0; j < v.size(); ++j) {
      v[j] = (b.q_desired[j] - a.q_desired[j]) / dt;
      EXPECT_LE(std::abs(v[j]), model.max_velocity[j] * 1.0001)
          << robot << " joint " << j << " commanded at " << v[j] << " rad/s, limit "
          << model.max_velocity[j] << " rad/s";
    }
    rates.push_back({b.servo_step, dt, v});
  }
  // The dwell: the last run of still states lasting 0.4 s or more that motion follows (before
  // it come the synchronisation and the approach, after it only the carry).
  std::size_t carry = rates.size();
  std::size_t still_from = rates.size();
  for (std::size_t k = 0; k < rates.size(); ++k) {
    bool still = true;
    for (double x : rates[k].v) still = still && x == 0.0;
    if (still) {
      if (still_from == rates.size()) still_from = k;
      continue;
    }
    if (still_from != rates.size() &&
        static_cast<double>(rates[k].step - rates[still_from].step) * period_s >= 0.4)
      carry = k;
    still_from = rates.size();
  }
  int checked = 0;
  for (std::size_t k = carry + 1; k < rates.size(); ++k) {
    const double dt = 0.5 * (rates[k].dt + rates[k - 1].dt);
    for (std::size_t j = 0; j < model.axes(); ++j) {
      const double a = (rates[k].v[j] - rates[k - 1].v[j]) / dt;
      EXPECT_LE(std::abs(a), model.max_acceleration[j] * 1.0001)
          << robot << " joint " << j << " commanded acceleration " << a << " rad/s^2 at servo step "
          << rates[k].step << ", limit " << model.max_acceleration[j] << " rad/s^2";
    }
    ++checked;
  }
  return checked;
}

struct CarryRun {
  LaunchRun run;
  double deviation_mm = -1.0;
  int standstills = -1;
};

/// Runs tight-bar.toml with `busy` busy loops beside it; when `victim` is given, stops it for
/// 50 ms 3.5 s after the carry began (in its second segment).
CarryRun carry(bool busy, const std::string& victim = {}) {
  const std::string file = (kSource / "configs/tight-bar.toml").string();
  const RobotModel model = load_robot_model(kSource / "robots/irb6");
  comm::Bus bus(comm::kDefaultLcmUrl);
  bus.start();
  StateWatch left(bus, "left");
  StateWatch right(bus, "right");
  CarryRun out;
  {
    std::unique_ptr<BusyLoops> loops;
    if (busy) loops = std::make_unique<BusyLoops>();
    out.run = mrroc::test::launch_and_act(
        file, victim, "carrying the bar", std::chrono::milliseconds(3500), [](pid_t pid) {
          kill(pid, SIGSTOP);
          std::this_thread::sleep_for(std::chrono::milliseconds(50));
          kill(pid, SIGCONT);
        });
  }
  bus.stop();
  out.standstills = count_of(out.run.output, "no next macro-step from the ECP in time");
  std::smatch m;
  const std::regex report("grip distance within ([0-9.]+) mm of its start value");
  if (std::regex_search(out.run.output, m, report)) out.deviation_mm = std::stod(m[1]);
  const int l = check_motion(left.history(), model, 0.002, "left");
  const int r = check_motion(right.history(), model, 0.002, "right");
  EXPECT_GT(l, 200) << "too few states of the carry from the left EDP";
  EXPECT_GT(r, 200) << "too few states of the carry from the right EDP";
  return out;
}

}  // namespace

TEST(Continuity, TheBarCarryBesideABusyLoopOnEveryCoreNeverStops) {
  const CarryRun c = carry(true);
  ASSERT_EQ(c.run.exit_code, 0) << c.run.output;
  EXPECT_EQ(c.standstills, 0) << c.run.output;
  EXPECT_GE(c.deviation_mm, 0.0) << c.run.output;
  EXPECT_LT(c.deviation_mm, 0.2);
  std::printf("busy host: %d standstills, grip distance within %.3f mm\n", c.standstills,
              c.deviation_mm);
}

namespace {
/// The bar carry with `victim` stopped for 50 ms mid-carry: no standstill, the bar rigid.
void expect_no_standstill_across_a_stop_of(const std::string& victim) {
  const CarryRun c = carry(false, victim);
  ASSERT_EQ(c.run.exit_code, 0) << c.run.output;
  ASSERT_NE(c.run.killed_at, Clock::time_point{})
      << victim << " was never stopped: " << c.run.output;
  EXPECT_EQ(c.standstills, 0) << c.run.output;
  EXPECT_LT(c.deviation_mm, 0.2);
}
}  // namespace

TEST(Continuity, AMpStopped50MsMidCarryCausesNoStandstill) {
  expect_no_standstill_across_a_stop_of("mp");
}

TEST(Continuity, AnEcpStopped50MsMidCarryCausesNoStandstill) {
  expect_no_standstill_across_a_stop_of("ecp/right");
}
