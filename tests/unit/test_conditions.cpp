// The stock conditions: delay on an injected clock, sensor thresholds with hysteresis, the
// operator trigger across threads, the robot-stopped condition on fresh readings only, and the
// binary-input condition with its timeout.
#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <cmath>
#include <thread>

#include "mrroc/core/error.hpp"
#include "mrroc/ecp/conditions.hpp"
#include "mrroc/ecp/generators/errors.hpp"

using namespace mrroc;
using namespace std::chrono_literals;

namespace {
/// A steady clock that only moves when told to.
struct FakeClock {
  std::chrono::steady_clock::time_point now{std::chrono::seconds(1000)};
  ecp::SteadyClock function() {
    return [this] { return now; };
  }
};
}  // namespace

TEST(DelayCondition, TrueAfterTheDelayFromTheFirstCheck) {
  FakeClock clock;
  ecp::DelayCondition delay(1.5, clock.function());
  clock.now += 10s;  // time before the first check does not count
  EXPECT_FALSE(delay.check({}));
  EXPECT_EQ(delay.elapsed_s(), 0.0);
  clock.now += 1499ms;
  EXPECT_FALSE(delay.check({}));
  EXPECT_NEAR(delay.elapsed_s(), 1.499, 1e-9);
  clock.now += 1ms;
  EXPECT_TRUE(delay.check({}));
  clock.now += 1h;
  EXPECT_TRUE(delay.check({}));
  delay.restart();
  EXPECT_FALSE(delay.check({}));
  clock.now += 1500ms;
  EXPECT_TRUE(delay.check({}));

  ecp::DelayCondition zero(0.0, clock.function());
  EXPECT_TRUE(zero.check({}));
  EXPECT_THROW(ecp::DelayCondition(-1.0), Error);
  EXPECT_THROW(ecp::DelayCondition(NAN), Error);
}

TEST(DelayCondition, DefaultsToTheSteadyClock) {
  ecp::DelayCondition delay(0.02);
  const auto start = std::chrono::steady_clock::now();
  int checks = 0;
  while (!delay.check({})) {
    ++checks;
    std::this_thread::sleep_for(1ms);
    ASSERT_LT(std::chrono::steady_clock::now() - start, 2s) << "never became true";
  }
  EXPECT_GE(std::chrono::steady_clock::now() - start, 20ms);
  EXPECT_GT(checks, 0);
}

TEST(SensorThresholdCondition, AboveWithHysteresis) {
  double reading = 0.0;
  ecp::SensorThresholdCondition c([&] { return reading; }, 10.0,
                                  ecp::SensorThresholdCondition::Direction::above, 2.0);
  const std::vector<std::pair<double, bool>> sequence = {
      {0.0, false}, {9.99, false}, {10.0, true}, {9.0, true},  {8.01, true},
      {8.0, false}, {9.5, false},  {12.0, true}, {7.0, false}, {-5.0, false}};
  for (const auto& [x, expected] : sequence) {
    reading = x;
    EXPECT_EQ(c.check({}), expected) << "reading " << x;
    EXPECT_EQ(c.last_reading(), x);
  }
}

TEST(SensorThresholdCondition, BelowAndPlainComparison) {
  double reading = 5.0;
  ecp::SensorThresholdCondition below([&] { return reading; }, 1.0,
                                      ecp::SensorThresholdCondition::Direction::below, 0.5);
  const std::vector<std::pair<double, bool>> sequence = {
      {5.0, false}, {1.0, true}, {1.4, true}, {1.5, false}, {0.2, true}};
  for (const auto& [x, expected] : sequence) {
    reading = x;
    EXPECT_EQ(below.check({}), expected) << "reading " << x;
  }
  ecp::SensorThresholdCondition plain([&] { return reading; }, 1.0);
  for (const auto& [x, expected] :
       std::vector<std::pair<double, bool>>{{0.5, false}, {1.0, true}, {0.999, false}}) {
    reading = x;
    EXPECT_EQ(plain.check({}), expected) << "reading " << x;
  }
  reading = NAN;
  EXPECT_THROW((void)plain.check({}), ecp::GeneratorError);
  EXPECT_THROW(ecp::SensorThresholdCondition({}, 1.0), Error);
  EXPECT_THROW(ecp::SensorThresholdCondition([] { return 0.0; }, INFINITY), Error);
  EXPECT_THROW(ecp::SensorThresholdCondition([] { return 0.0; }, 1.0,
                                             ecp::SensorThresholdCondition::Direction::above, -1.0),
               Error);
}

TEST(OperatorTriggerCondition, TriggeredFromAnotherThread) {
  ecp::OperatorTriggerCondition c;
  EXPECT_FALSE(c.check({}));
  std::atomic<bool> checking{false};
  std::thread shell([&] {
    while (!checking.load()) std::this_thread::yield();
    std::this_thread::sleep_for(5ms);
    c.trigger();
  });
  const auto start = std::chrono::steady_clock::now();
  bool triggered = false;
  while (!triggered && std::chrono::steady_clock::now() - start < 5s) {
    checking.store(true);
    triggered = c.check({});
  }
  shell.join();
  EXPECT_TRUE(triggered);
  EXPECT_TRUE(c.check({})) << "latched";
  c.reset();
  EXPECT_FALSE(c.check({}));
}

TEST(RobotStoppedCondition, CountsConsecutiveFreshReadings) {
  ecp::RobotImage image;
  ecp::RobotStoppedCondition c(image, 0.01, 3);
  EXPECT_FALSE(c.check({})) << "no velocities yet";
  const auto reading = [&](std::vector<double> v) {
    image.joint_velocities = std::move(v);
    image.servo_cycle += 10;
  };
  reading({0.5, 0.0, 0.0});
  EXPECT_FALSE(c.check({}));
  reading({0.005, -0.009, 0.0});
  EXPECT_FALSE(c.check({}));
  EXPECT_EQ(c.count(), 1);
  // The same reading checked again does not count.
  EXPECT_FALSE(c.check({}));
  EXPECT_FALSE(c.check({}));
  EXPECT_EQ(c.count(), 1);
  reading({0.0, 0.0, 0.0});
  EXPECT_FALSE(c.check({}));
  reading({0.0, 0.02, 0.0});  // moving again: start over
  EXPECT_FALSE(c.check({}));
  EXPECT_EQ(c.count(), 0);
  for (int i = 0; i < 2; ++i) {
    reading({0.001, 0.001, -0.001});
    EXPECT_FALSE(c.check({}));
  }
  reading({0.001, 0.001, -0.001});
  EXPECT_TRUE(c.check({}));
  EXPECT_TRUE(c.check({})) << "stays true on the same reading";
  reading({0.001, NAN, 0.0});
  EXPECT_FALSE(c.check({})) << "a NaN velocity is not a stop";

  // With a refresh function (e.g. robot.read_state()), every check reads anew.
  int refreshes = 0;
  ecp::RobotStoppedCondition refreshed(image, 0.01, 2, [&] {
    ++refreshes;
    reading({0.0, 0.0, 0.0});
  });
  EXPECT_FALSE(refreshed.check({}));
  EXPECT_TRUE(refreshed.check({}));
  EXPECT_EQ(refreshes, 2);

  EXPECT_THROW(ecp::RobotStoppedCondition(image, 0.0), Error);
  EXPECT_THROW(ecp::RobotStoppedCondition(image, 0.1, 0), Error);
}

TEST(InputCondition, WaitsForTheLineAndTimesOutNamingIt) {
  FakeClock clock;
  ecp::InputCondition on(17, true, 2.0, clock.function());
  EXPECT_EQ(on.items() & edp::item::inputs, edp::item::inputs);
  ecp::RobotImage robot;
  // An image without inputs (not read): an error naming the line, not a wait for ever.
  try {
    (void)on.holds(robot, {});
    FAIL() << "no error without inputs";
  } catch (const ecp::GeneratorError& e) {
    EXPECT_NE(std::string(e.what()).find("input condition on line 17: the robot image has no "
                                         "inputs"),
              std::string::npos)
        << e.what();
  }
  robot.inputs = 0x10000U;  // line 16 on, 17 off
  clock.now += 1s;
  EXPECT_FALSE(on.holds(robot, {}));
  EXPECT_NEAR(on.waited_s(), 1.0, 1e-9);
  robot.inputs = 0x20000U;
  EXPECT_TRUE(on.holds(robot, {}));
  // Waiting for a line to turn off.
  ecp::InputCondition off(17, false, 0.0, clock.function());
  EXPECT_FALSE(off.holds(robot, {}));
  robot.inputs = 0U;
  EXPECT_TRUE(off.holds(robot, {}));
  // The timeout names the line, the state and the time.
  ecp::InputCondition timed(3, true, 2.0, clock.function());
  EXPECT_FALSE(timed.holds(robot, {}));
  clock.now += 2s;
  try {
    (void)timed.holds(robot, {});
    FAIL() << "no timeout";
  } catch (const ecp::GeneratorError& e) {
    EXPECT_STREQ(e.what(), "input 3 did not turn on within 2.0 s");
  }
  // As a plain Condition it refuses: it needs the robot image.
  EXPECT_THROW((void)on.check({}), Error);
  EXPECT_THROW(ecp::InputCondition(32), Error);
  EXPECT_THROW(ecp::InputCondition(-1), Error);
  EXPECT_THROW(ecp::InputCondition(0, true, -1.0), Error);
}
