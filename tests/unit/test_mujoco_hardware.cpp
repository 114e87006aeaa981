/// @file
/// The `mujoco` EDP hardware plugin driving the IRb-6 model (robots/irb6).

#include <algorithm>
#include <array>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <memory>
#include <new>
#include <numbers>
#include <span>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <mujoco/mujoco.h>
#include <unistd.h>

#include "mrroc/config/params.hpp"
#include "mrroc/core/error.hpp"
#include "mrroc/edp/hardware.hpp"
#include "plugins/mujoco_hardware.hpp"

#ifndef MRROC_SOURCE_DIR
#error "MRROC_SOURCE_DIR must be defined (absolute path of the source tree)"
#endif

// Heap allocation counter: read() and write() must not allocate.
#include "heap_counter.hpp"

namespace {

using mrroc::ConfigError;
using mrroc::HardwareError;
using mrroc::Params;
using mrroc::SourceLocation;
using mrroc::edp::AxisFeedback;
using mrroc::edp::CycleStatus;
using mrroc::edp::HardwareSetup;
using mrroc::edp::MujocoHardware;

constexpr double kPi = std::numbers::pi;
constexpr std::size_t kAxes = 5;
constexpr double kPeriod = 0.002;  // servo period [s]

std::filesystem::path robot_dir() {
  return std::filesystem::path(MRROC_SOURCE_DIR) / "robots" / "irb6";
}

HardwareSetup irb6_setup() {
  HardwareSetup setup;
  setup.robot = "irb6";
  setup.model_dir = robot_dir();
  setup.servo_period_s = kPeriod;
  setup.synchro_positions = {0.0, -kPi / 2, 0.0, 0.0, 0.0};
  setup.params = Params(SourceLocation{"test.toml", 10});
  return setup;
}

/// Quintic rest-to-rest profile 0 -> 1 over tau in [0, 1].
double quintic(double tau) {
  tau = std::clamp(tau, 0.0, 1.0);
  return tau * tau * tau * (10.0 + tau * (-15.0 + 6.0 * tau));
}

/// Captures MuJoCo warnings (instead of the default print + MUJOCO_LOG.TXT) while alive.
class WarningCapture {
 public:
  WarningCapture() : previous_(mju_user_warning) {
    count_ = 0;
    mju_user_warning = &WarningCapture::handler;
  }
  ~WarningCapture() { mju_user_warning = previous_; }
  WarningCapture(const WarningCapture&) = delete;
  WarningCapture& operator=(const WarningCapture&) = delete;
  [[nodiscard]] int count() const { return count_; }

 private:
  static void handler(const char*) { ++count_; }
  static inline int count_ = 0;
  void (*previous_)(const char*);
};

TEST(MujocoHardware, IsRegisteredAsMujoco) {
  const auto names = mrroc::edp::hardware_names();
  EXPECT_NE(std::find(names.begin(), names.end(), "mujoco"), names.end());
  auto hw = mrroc::edp::make_hardware("mujoco");
  ASSERT_TRUE(hw);
  EXPECT_EQ(hw->name(), "mujoco");
  EXPECT_NE(dynamic_cast<MujocoHardware*>(hw.get()), nullptr);
}

TEST(MujocoHardware, ConfiguresTheIrb6Model) {
  MujocoHardware hw;
  hw.configure(irb6_setup());
  EXPECT_EQ(hw.axis_count(), kAxes);
  EXPECT_EQ(hw.substeps(), 2);
  ASSERT_NE(hw.model(), nullptr);
  ASSERT_NE(hw.data(), nullptr);
  EXPECT_EQ(hw.mjcf_path(), robot_dir() / "irb6.xml");
  // Default power-on pose: synchronisation pose + 0.05 rad on every axis (inside all limits).
  const std::vector<double> expected = {0.05, -kPi / 2 + 0.05, 0.05, 0.05, 0.05};
  ASSERT_EQ(hw.power_on_positions().size(), kAxes);
  for (std::size_t i = 0; i < kAxes; ++i) {
    EXPECT_DOUBLE_EQ(hw.power_on_positions()[i], expected[i]) << "axis " << i;
  }
  hw.activate();
  const auto q = hw.true_joint_positions();
  for (std::size_t i = 0; i < kAxes; ++i) {
    EXPECT_DOUBLE_EQ(q[i], expected[i]) << "axis " << i;
  }
  std::array<AxisFeedback, kAxes> fb{};
  ASSERT_EQ(hw.read(fb), CycleStatus::ok) << hw.fault_text();
  for (std::size_t i = 0; i < kAxes; ++i) {
    EXPECT_EQ(fb[i].position, 0.0) << "raw position is zero at power-on, axis " << i;
    EXPECT_EQ(fb[i].velocity, 0.0);
    EXPECT_TRUE(fb[i].synchro_switch) << "power-on pose is above the synchro position, axis " << i;
  }
  hw.deactivate();
  hw.deactivate();  // idempotent
}

TEST(MujocoHardware, MjcfNameFromParams) {
  HardwareSetup setup = irb6_setup();
  setup.params.set("mjcf", std::string("irb6.xml"), SourceLocation{"test.toml", 11});
  setup.params.set("gravity_compensation", true, SourceLocation{"test.toml", 12});
  MujocoHardware hw;
  hw.configure(setup);
  EXPECT_EQ(hw.axis_count(), kAxes);
}

TEST(MujocoHardware, TracksASmoothTrajectoryAndSwitchesAtTheSynchroPosition) {
  HardwareSetup setup = irb6_setup();
  MujocoHardware hw;
  hw.configure(setup);
  hw.activate();
  const std::vector<double> power_on = hw.power_on_positions();
  const mjModel* m = hw.model();
  const mjData* d = hw.data();

  // Raw setpoints 0 -> -0.2 rad over 2 s on every axis (true pose sync+0.05 -> sync-0.15), so
  // every synchronisation switch opens once on the way.
  constexpr double kAmplitude = -0.2;
  constexpr double kMoveTime = 2.0;
  constexpr double kSettleTime = 0.5;
  const auto reference = [&](double t) { return kAmplitude * quintic(t / kMoveTime); };
  const int total_cycles = static_cast<int>(std::lround((kMoveTime + kSettleTime) / kPeriod));

  std::array<AxisFeedback, kAxes> fb{};
  std::array<double, kAxes> setpoint{};
  std::array<double, kAxes> max_error{};
  std::array<int, kAxes> toggles{};
  std::array<bool, kAxes> previous_switch{};
  std::array<double, kAxes> previous_true{};
  for (std::size_t i = 0; i < kAxes; ++i) {
    previous_switch[i] = true;
    previous_true[i] = power_on[i];
  }

  // The counter works.
  g_heap.allocations = 0;
  g_heap.counting = true;
  ::operator delete(::operator new(16));
  g_heap.counting = false;
  ASSERT_EQ(g_heap.allocations.load(), 1);

  const auto started = std::chrono::steady_clock::now();
  g_heap.allocations = 0;
  for (int k = 0; k <= total_cycles; ++k) {
    const double t = k * kPeriod;
    g_heap.counting = true;
    const CycleStatus read_status = hw.read(fb);
    g_heap.counting = false;
    ASSERT_EQ(read_status, CycleStatus::ok) << hw.fault_text();
    ASSERT_NEAR(d->time, t, 1e-9) << "one write() = one servo period";

    for (std::size_t i = 0; i < kAxes; ++i) {
      const int j = static_cast<int>(i);
      const double true_q = d->qpos[m->jnt_qposadr[j]];
      ASSERT_EQ(fb[i].position, true_q - power_on[i]);
      ASSERT_EQ(fb[i].velocity, d->qvel[m->jnt_dofadr[j]]);
      // The switch is a cam whose edge is exactly at the synchronisation position.
      ASSERT_EQ(fb[i].synchro_switch, true_q > setup.synchro_positions[i])
          << "axis " << i << " at t = " << t;
      if (fb[i].synchro_switch != previous_switch[i]) {
        ++toggles[i];
        EXPECT_GT(previous_true[i], setup.synchro_positions[i]);
        EXPECT_LE(true_q, setup.synchro_positions[i]);
      }
      previous_switch[i] = fb[i].synchro_switch;
      previous_true[i] = true_q;
      max_error[i] = std::max(max_error[i], std::abs(reference(t) - fb[i].position));
    }

    for (std::size_t i = 0; i < kAxes; ++i) {
      setpoint[i] = reference((k + 1) * kPeriod);
    }
    g_heap.counting = true;
    const CycleStatus write_status = hw.write(setpoint);
    g_heap.counting = false;
    ASSERT_EQ(write_status, CycleStatus::ok) << hw.fault_text();
  }
  const double elapsed =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count();
  EXPECT_EQ(g_heap.allocations.load(), 0) << "read()/write() allocated on the heap";

  ASSERT_EQ(hw.read(fb), CycleStatus::ok) << hw.fault_text();
  const std::array<const char*, kAxes> names = {"column", "lower_arm", "upper_arm", "wrist_pitch",
                                                "wrist_roll"};
  for (std::size_t i = 0; i < kAxes; ++i) {
    const double final_error = std::abs(kAmplitude - fb[i].position);
    std::printf("%-12s max tracking error %.3e rad, final error after %.1f s settling %.3e rad\n",
                names[i], max_error[i], kSettleTime, final_error);
    // Velocity lag of a stiff P servo with viscous damping (~ d/kp * vmax ~ 2e-3 rad at
    // vmax = 0.1875 rad/s).
    EXPECT_LT(max_error[i], 3e-3) << names[i];
    EXPECT_LT(final_error, 1e-3) << names[i];
    EXPECT_LT(std::abs(fb[i].velocity), 1e-3) << names[i];
    EXPECT_EQ(toggles[i], 1) << names[i] << ": the switch must open exactly once";
    EXPECT_FALSE(fb[i].synchro_switch) << names[i];
  }
  std::printf("simulated %.1f s in %.3f s wall time\n", kMoveTime + kSettleTime, elapsed);
  hw.deactivate();
}

TEST(MujocoHardware, InitialJointPositionsSetThePowerOnPose) {
  HardwareSetup setup = irb6_setup();
  const std::vector<double> initial = {0.3, -1.4, 0.2, -0.5, 1.0};
  setup.params.set("initial_joint_positions", initial, SourceLocation{"test.toml", 11});
  MujocoHardware hw;
  hw.configure(setup);
  hw.activate();
  EXPECT_EQ(hw.true_joint_positions(), initial);
  std::array<AxisFeedback, kAxes> fb{};
  std::array<double, kAxes> hold{};
  // Hold the raw zero for 0.5 s: the arm must stay at its power-on pose.
  for (int k = 0; k < 250; ++k) {
    ASSERT_EQ(hw.read(fb), CycleStatus::ok) << hw.fault_text();
    ASSERT_EQ(hw.write(hold), CycleStatus::ok) << hw.fault_text();
  }
  ASSERT_EQ(hw.read(fb), CycleStatus::ok);
  for (std::size_t i = 0; i < kAxes; ++i) {
    EXPECT_NEAR(fb[i].position, 0.0, 1e-6) << "axis " << i;
    EXPECT_NEAR(hw.true_joint_positions()[i], initial[i], 1e-6) << "axis " << i;
  }
  // Switches: axis 0 (0.3 > 0), axis 1 (-1.4 > -pi/2), axis 2 (0.2 > 0), axis 3 (-0.5 < 0),
  // axis 4 (1.0 > 0).
  EXPECT_TRUE(fb[0].synchro_switch);
  EXPECT_TRUE(fb[1].synchro_switch);
  EXPECT_TRUE(fb[2].synchro_switch);
  EXPECT_FALSE(fb[3].synchro_switch);
  EXPECT_TRUE(fb[4].synchro_switch);

  // activate() again returns to the power-on pose.
  std::array<double, kAxes> moved{};
  moved.fill(0.05);
  for (int k = 0; k < 100; ++k) {
    ASSERT_EQ(hw.write(moved), CycleStatus::ok);
  }
  hw.deactivate();
  hw.activate();
  EXPECT_EQ(hw.true_joint_positions(), initial);
  EXPECT_EQ(hw.data()->time, 0.0);
}

TEST(MujocoHardware, WithoutGravityCompensationTheArmSags) {
  HardwareSetup setup = irb6_setup();
  setup.params.set("gravity_compensation", false, SourceLocation{"test.toml", 11});
  MujocoHardware hw;
  hw.configure(setup);
  hw.activate();
  std::array<AxisFeedback, kAxes> fb{};
  std::array<double, kAxes> hold{};
  for (int k = 0; k < 250; ++k) {
    ASSERT_EQ(hw.write(hold), CycleStatus::ok) << hw.fault_text();
  }
  ASSERT_EQ(hw.read(fb), CycleStatus::ok);
  // Gravity torque ~62 N m on the upper arm against kp = 1.9e5 N m/rad: a few 1e-4 rad.
  EXPECT_GT(std::abs(fb[2].position), 1e-4);
  EXPECT_LT(std::abs(fb[2].position), 2e-3);
}

TEST(MujocoHardware, BadMjcfPathNamesThePath) {
  HardwareSetup setup = irb6_setup();
  setup.params.set("mjcf", std::string("no_such_model.xml"), SourceLocation{"test.toml", 11});
  MujocoHardware hw;
  const std::string path = (robot_dir() / "no_such_model.xml").string();
  try {
    hw.configure(setup);
    FAIL() << "configure() accepted a missing MJCF file";
  } catch (const HardwareError& e) {
    std::printf("%s\n", e.what());
    EXPECT_NE(std::string(e.what()).find(path), std::string::npos) << e.what();
  }
  EXPECT_EQ(hw.model(), nullptr);
  EXPECT_EQ(hw.axis_count(), 0U);
}

TEST(MujocoHardware, MissingParameterFileNamesTheFile) {
  HardwareSetup setup = irb6_setup();
  setup.model_dir = std::filesystem::path(MRROC_SOURCE_DIR) / "robots" / "no_such_robot";
  MujocoHardware hw;
  try {
    hw.configure(setup);
    FAIL() << "configure() accepted a missing parameters.toml";
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find((setup.model_dir / "parameters.toml").string()),
              std::string::npos)
        << e.what();
  }
}

TEST(MujocoHardware, ServoPeriodMustBeAMultipleOfTheTimestep) {
  for (const double period : {0.0025, 0.0005, 0.0}) {
    HardwareSetup setup = irb6_setup();
    setup.servo_period_s = period;
    MujocoHardware hw;
    try {
      hw.configure(setup);
      FAIL() << "servo period " << period << " s accepted";
    } catch (const HardwareError& e) {
      const std::string what = e.what();
      std::printf("%s\n", what.c_str());
      char number[32];
      std::snprintf(number, sizeof number, "%.9g s", period);
      EXPECT_NE(what.find(number), std::string::npos) << what;
      EXPECT_NE(what.find("0.001 s"), std::string::npos) << what;
    }
  }
  HardwareSetup setup = irb6_setup();
  setup.servo_period_s = 0.001;
  MujocoHardware hw;
  hw.configure(setup);
  EXPECT_EQ(hw.substeps(), 1);
}

TEST(MujocoHardware, RejectsBadParameters) {
  {
    HardwareSetup setup = irb6_setup();
    setup.params.set("no_such_key", 1.0, SourceLocation{"test.toml", 13});
    MujocoHardware hw;
    EXPECT_THROW(hw.configure(setup), ConfigError);
  }
  {
    HardwareSetup setup = irb6_setup();
    setup.params.set("initial_joint_positions", std::vector<double>{0.0, 0.0, 0.0, 0.0, 0.0},
                     SourceLocation{"test.toml", 14});
    MujocoHardware hw;
    try {
      hw.configure(setup);
      FAIL() << "lower_arm = 0 rad is outside -130..-50 deg";
    } catch (const ConfigError& e) {
      const std::string what = e.what();
      EXPECT_NE(what.find("test.toml:14"), std::string::npos) << what;
      EXPECT_NE(what.find("lower_arm"), std::string::npos) << what;
    }
  }
  {
    HardwareSetup setup = irb6_setup();
    setup.params.set("initial_joint_positions", std::vector<double>{0.0, -1.5},
                     SourceLocation{"test.toml", 15});
    MujocoHardware hw;
    EXPECT_THROW(hw.configure(setup), ConfigError);
  }
  {
    HardwareSetup setup = irb6_setup();
    setup.synchro_positions = {0.0, 0.0};
    MujocoHardware hw;
    EXPECT_THROW(hw.configure(setup), HardwareError);
  }
}

TEST(MujocoHardware, SynchroPositionsDefaultToTheParameterFile) {
  HardwareSetup setup = irb6_setup();
  setup.synchro_positions.clear();
  MujocoHardware hw;
  hw.configure(setup);
  const std::vector<double> expected = {0.0, -kPi / 2, 0.0, 0.0, 0.0};
  EXPECT_EQ(hw.synchro_positions(), expected);
}

TEST(MujocoHardware, CycleCallsReportMisuseWithoutThrowing) {
  MujocoHardware hw;
  std::array<AxisFeedback, kAxes> fb{};
  std::array<double, kAxes> sp{};
  EXPECT_EQ(hw.read(fb), CycleStatus::fault);
  EXPECT_FALSE(hw.fault_text().empty());
  EXPECT_THROW(hw.activate(), HardwareError);
  hw.configure(irb6_setup());
  EXPECT_EQ(hw.write(sp), CycleStatus::fault) << "write() before activate()";
  hw.activate();
  std::array<AxisFeedback, 3> short_fb{};
  EXPECT_EQ(hw.read(short_fb), CycleStatus::fault);
  std::array<double, 3> short_sp{};
  EXPECT_EQ(hw.write(short_sp), CycleStatus::fault);
  sp[1] = std::nan("");
  EXPECT_EQ(hw.write(sp), CycleStatus::fault);
  EXPECT_NE(hw.fault_text().find("axis 1"), std::string::npos) << hw.fault_text();
  hw.deactivate();
  EXPECT_EQ(hw.write(sp), CycleStatus::fault);
}

TEST(MujocoHardware, UnstableSimulationIsAFault) {
  // A stiff servo on a tiny inertia, explicitly integrated: diverges within a few steps.
  const auto dir =
      std::filesystem::temp_directory_path() / ("mrroc_unstable_" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  {
    std::ofstream out(dir / "unstable.xml");
    out << R"(<mujoco model="unstable">
  <option timestep="0.001"/>
  <worldbody>
    <body name="link">
      <inertial pos="0.1 0 0" mass="0.001" diaginertia="1e-6 1e-6 1e-6"/>
      <joint name="j" type="hinge" axis="0 0 1" limited="false"/>
    </body>
  </worldbody>
  <actuator><position name="j" joint="j" kp="1e6" ctrllimited="true" ctrlrange="-3 3"/></actuator>
</mujoco>
)";
  }
  HardwareSetup setup;
  setup.robot = "unstable";
  setup.model_dir = dir;
  setup.servo_period_s = 0.002;
  setup.synchro_positions = {0.0};
  setup.params.set("mjcf", std::string("unstable.xml"), SourceLocation{"test.toml", 11});
  setup.params.set("gravity_compensation", false, SourceLocation{"test.toml", 12});
  MujocoHardware hw;
  hw.configure(setup);
  hw.activate();

  const WarningCapture capture;
  std::array<AxisFeedback, 1> fb{};
  const std::array<double, 1> sp = {1.0};
  bool faulted = false;
  for (int k = 0; k < 1000 && !faulted; ++k) {
    faulted = hw.write(sp) == CycleStatus::fault || hw.read(fb) == CycleStatus::fault;
  }
  EXPECT_TRUE(faulted);
  EXPECT_NE(hw.fault_text().find("unstable"), std::string::npos) << hw.fault_text();
  EXPECT_GT(capture.count(), 0);
  std::printf("fault text: %s\n", hw.fault_text().c_str());
  EXPECT_EQ(hw.read(fb), CycleStatus::fault) << "the fault is latched until activate()";
  hw.activate();
  EXPECT_EQ(hw.read(fb), CycleStatus::ok) << hw.fault_text();
  std::filesystem::remove_all(dir);
}

// ---- The RNT: a closed parallelogram, coupled axes (robots/rnt). ----

constexpr std::size_t kRntAxes = 6;
// The elbow actuator drives the absolute forearm pitch: a2 = q1 + q2 (parameters.toml).
constexpr std::size_t kShoulder = 1;
constexpr std::size_t kElbow = 2;

std::filesystem::path rnt_dir() {
  return std::filesystem::path(MRROC_SOURCE_DIR) / "robots" / "rnt";
}

HardwareSetup rnt_setup() {
  HardwareSetup setup;
  setup.robot = "rnt";
  setup.model_dir = rnt_dir();
  setup.servo_period_s = kPeriod;
  setup.synchro_positions = {0.0, 0.0, 0.0, kPi / 2, 0.0, 0.0};
  setup.params = Params(SourceLocation{"test.toml", 20});
  return setup;
}

int joint_id(const mjModel* m, const char* name) { return mj_name2id(m, mjOBJ_JOINT, name); }

double joint_qpos(const mjModel* m, const mjData* d, const char* name) {
  return d->qpos[m->jnt_qposadr[joint_id(m, name)]];
}

/// Exact violation of every `connect` constraint of the model at the state `d->qpos` [m]:
/// distance between the anchor on body1 and the anchor on body2 (computed on a scratch copy).
class LoopProbe {
 public:
  explicit LoopProbe(const mjModel* m) : m_(m), d_(mj_makeData(m)) {}
  ~LoopProbe() { mj_deleteData(d_); }
  LoopProbe(const LoopProbe&) = delete;
  LoopProbe& operator=(const LoopProbe&) = delete;

  double violation(const mjData* state) {
    for (int i = 0; i < m_->nq; ++i) {
      d_->qpos[i] = state->qpos[i];
    }
    mj_kinematics(m_, d_);
    double worst = 0.0;
    for (int e = 0; e < m_->neq; ++e) {
      if (m_->eq_type[e] != mjEQ_CONNECT) {
        continue;
      }
      const mjtNum* data = m_->eq_data + mjNEQDATA * e;
      std::array<mjtNum, 3> p1{};
      std::array<mjtNum, 3> p2{};
      const int b1 = m_->eq_obj1id[e];
      const int b2 = m_->eq_obj2id[e];
      mju_mulMatVec(p1.data(), d_->xmat + 9 * b1, data, 3, 3);
      mju_addTo3(p1.data(), d_->xpos + 3 * b1);
      mju_mulMatVec(p2.data(), d_->xmat + 9 * b2, data + 3, 3, 3);
      mju_addTo3(p2.data(), d_->xpos + 3 * b2);
      worst = std::max(worst, mju_dist3(p1.data(), p2.data()));
    }
    return worst;
  }

 private:
  const mjModel* m_;
  mjData* d_;
};

TEST(MujocoHardwareRnt, AxesAreTheActuatorsAndThePowerOnPoseClosesTheParallelogram) {
  MujocoHardware hw;
  hw.configure(rnt_setup());
  ASSERT_EQ(hw.axis_count(), kRntAxes);
  EXPECT_TRUE(hw.coupled());
  const mjModel* m = hw.model();
  ASSERT_EQ(m->nu, 6);
  ASSERT_EQ(m->njnt, 8) << "6 axes + the passive elbow_drive crank and coupler";
  ASSERT_EQ(m->neq, 1);
  // Axis 2's actuator joint is the parallelogram crank, not the serial elbow.
  EXPECT_EQ(hw.actuator_joints()[kElbow], joint_id(m, "elbow_drive"));
  EXPECT_EQ(hw.actuator_joints()[kShoulder], joint_id(m, "shoulder"));
  // The coupling of parameters.toml: identity except a2 = q1 + q2.
  const std::vector<double>& c = hw.coupling();
  ASSERT_EQ(c.size(), kRntAxes * kRntAxes);
  for (std::size_t r = 0; r < kRntAxes; ++r) {
    for (std::size_t col = 0; col < kRntAxes; ++col) {
      const double expected = (r == col || (r == kElbow && col == kShoulder)) ? 1.0 : 0.0;
      EXPECT_EQ(c[r * kRntAxes + col], expected) << "M(" << r << ", " << col << ")";
    }
  }

  // Default power-on pose: synchro + 0.05 rad in joint coordinates.
  const std::vector<double> expected = {0.05, 0.05, 0.05, kPi / 2 + 0.05, 0.05, 0.05};
  hw.activate();
  const mjData* d = hw.data();
  const auto q = hw.true_joint_positions();
  for (std::size_t i = 0; i < kRntAxes; ++i) {
    EXPECT_NEAR(hw.power_on_positions()[i], expected[i], 1e-15) << "axis " << i;
    EXPECT_NEAR(q[i], expected[i], 1e-12) << "axis " << i;
  }
  // The plugin solved the loop for the passive joints: elbow = q2, coupler = -q2, crank = q1 + q2.
  EXPECT_NEAR(joint_qpos(m, d, "elbow_drive"), 0.10, 1e-15);
  EXPECT_NEAR(joint_qpos(m, d, "elbow"), 0.05, 1e-12);
  EXPECT_NEAR(joint_qpos(m, d, "coupler"), -0.05, 1e-12);
  LoopProbe probe(m);
  EXPECT_LT(probe.violation(d), 1e-12);
  EXPECT_LT(hw.equality_violation(), 1e-12);

  std::array<AxisFeedback, kRntAxes> fb{};
  ASSERT_EQ(hw.read(fb), CycleStatus::ok) << hw.fault_text();
  for (std::size_t i = 0; i < kRntAxes; ++i) {
    EXPECT_NEAR(fb[i].position, 0.0, 1e-12) << "axis " << i;
    EXPECT_TRUE(fb[i].synchro_switch) << "axis " << i;
  }
}

TEST(MujocoHardwareRnt, InitialPoseAwayFromQpos0IsClosedBySolving) {
  HardwareSetup setup = rnt_setup();
  // Upper arm leaning 0.9 rad forward, forearm 0.6 rad below it (absolute pitch 1.5 rad).
  const std::vector<double> initial = {0.4, 0.9, 0.6, 0.3, -0.5, 1.2};
  setup.params.set("initial_joint_positions", initial, SourceLocation{"test.toml", 21});
  MujocoHardware hw;
  hw.configure(setup);
  hw.activate();
  const mjModel* m = hw.model();
  const mjData* d = hw.data();
  EXPECT_NEAR(joint_qpos(m, d, "shoulder"), 0.9, 1e-15);
  EXPECT_NEAR(joint_qpos(m, d, "elbow_drive"), 1.5, 1e-15);
  EXPECT_NEAR(joint_qpos(m, d, "elbow"), 0.6, 1e-10);
  EXPECT_NEAR(joint_qpos(m, d, "coupler"), -0.6, 1e-10);
  LoopProbe probe(m);
  EXPECT_LT(probe.violation(d), 1e-10);
  const auto q = hw.true_joint_positions();
  for (std::size_t i = 0; i < kRntAxes; ++i) {
    EXPECT_NEAR(q[i], initial[i], 1e-12) << "axis " << i;
  }
}

TEST(MujocoHardwareRnt, TracksAJointTrajectoryThroughTheParallelogram) {
  MujocoHardware hw;
  hw.configure(rnt_setup());
  hw.activate();
  const mjModel* m = hw.model();
  const mjData* d = hw.data();
  const std::vector<double> power_on = hw.power_on_positions();
  LoopProbe probe(m);

  // Raw (joint-space) moves over 2 s: the shoulder leans 0.6 rad forward while the elbow turns
  // -0.4 rad relative to it (the elbow drive turns +0.2 rad), the wrist axes move too.
  const std::array<double, kRntAxes> amplitude = {0.5, 0.6, -0.4, -0.5, 0.4, 0.8};
  constexpr double kMoveTime = 2.0;
  constexpr double kSettleTime = 0.5;
  const int total_cycles = static_cast<int>(std::lround((kMoveTime + kSettleTime) / kPeriod));
  const auto reference = [&](std::size_t i, double t) {
    return amplitude[i] * quintic(t / kMoveTime);
  };

  std::array<AxisFeedback, kRntAxes> fb{};
  std::array<double, kRntAxes> setpoint{};
  std::array<double, kRntAxes> max_error{};
  double max_violation = 0.0;
  double max_elbow_mismatch = 0.0;
  g_heap.allocations = 0;
  for (int k = 0; k <= total_cycles; ++k) {
    const double t = k * kPeriod;
    g_heap.counting = true;
    const CycleStatus read_status = hw.read(fb);
    g_heap.counting = false;
    ASSERT_EQ(read_status, CycleStatus::ok) << hw.fault_text();
    // The reading is in joint coordinates: q2 = elbow_drive - shoulder.
    const double a1 = joint_qpos(m, d, "shoulder");
    const double a2 = joint_qpos(m, d, "elbow_drive");
    ASSERT_NEAR(fb[kShoulder].position, a1 - power_on[kShoulder], 1e-12);
    ASSERT_NEAR(fb[kElbow].position, (a2 - a1) - power_on[kElbow], 1e-12);
    // ... and agrees with the passive serial elbow joint while the loop stays closed.
    max_elbow_mismatch =
        std::max(max_elbow_mismatch,
                 std::abs(fb[kElbow].position + power_on[kElbow] - joint_qpos(m, d, "elbow")));
    max_violation = std::max(max_violation, probe.violation(d));
    for (std::size_t i = 0; i < kRntAxes; ++i) {
      max_error[i] = std::max(max_error[i], std::abs(reference(i, t) - fb[i].position));
    }
    for (std::size_t i = 0; i < kRntAxes; ++i) {
      setpoint[i] = reference(i, (k + 1) * kPeriod);
    }
    g_heap.counting = true;
    const CycleStatus write_status = hw.write(setpoint);
    g_heap.counting = false;
    ASSERT_EQ(write_status, CycleStatus::ok) << hw.fault_text();
    // The elbow drive is commanded with the absolute forearm pitch q1 + q2.
    ASSERT_NEAR(d->ctrl[kElbow],
                setpoint[kShoulder] + power_on[kShoulder] + setpoint[kElbow] + power_on[kElbow],
                1e-12);
  }
  EXPECT_EQ(g_heap.allocations.load(), 0) << "read()/write() allocated on the heap";

  ASSERT_EQ(hw.read(fb), CycleStatus::ok) << hw.fault_text();
  const std::array<const char*, kRntAxes> names = {"waist",       "shoulder",  "elbow",
                                                   "wrist_pitch", "wrist_yaw", "wrist_roll"};
  for (std::size_t i = 0; i < kRntAxes; ++i) {
    const double final_error = std::abs(amplitude[i] - fb[i].position);
    std::printf(
        "rnt %-12s max tracking error %.3e rad, final error after %.1f s settling %.3e rad\n",
        names[i], max_error[i], kSettleTime, final_error);
    // Velocity lag of the servo, d/kp ~ 0.0107 s times at most 0.75 rad/s (peak of the quintic
    // at 0.8 rad over 2 s).
    EXPECT_LT(max_error[i], 1e-2) << names[i];
    EXPECT_LT(final_error, 1e-3) << names[i];
  }
  std::printf(
      "rnt parallelogram: max loop violation %.3e m, max |elbow reading - serial elbow "
      "joint| %.3e rad\n",
      max_violation, max_elbow_mismatch);
  EXPECT_LT(max_violation, 1e-4);
  EXPECT_LT(max_elbow_mismatch, 1e-3);
  EXPECT_LT(hw.equality_violation(), 1e-4);
}

TEST(MujocoHardwareRnt, ShoulderAloneKeepsTheForearmAngleRelativeToTheUpperArm) {
  // Moving only joint q1 (raw setpoint on axis 1) moves both the shoulder and the elbow drive, so
  // that the elbow joint q2 stays put: the EDP's joint coordinates are the serial chain's.
  MujocoHardware hw;
  hw.configure(rnt_setup());
  hw.activate();
  const mjModel* m = hw.model();
  const mjData* d = hw.data();
  std::array<AxisFeedback, kRntAxes> fb{};
  std::array<double, kRntAxes> setpoint{};
  const double elbow_before = joint_qpos(m, d, "elbow");
  const double drive_before = joint_qpos(m, d, "elbow_drive");
  for (int k = 0; k < 1000; ++k) {
    setpoint[kShoulder] = 0.3 * quintic(k * kPeriod / 1.5);
    ASSERT_EQ(hw.write(setpoint), CycleStatus::ok) << hw.fault_text();
  }
  ASSERT_EQ(hw.read(fb), CycleStatus::ok);
  EXPECT_NEAR(fb[kShoulder].position, 0.3, 1e-3);
  EXPECT_NEAR(fb[kElbow].position, 0.0, 1e-3);
  EXPECT_NEAR(joint_qpos(m, d, "elbow"), elbow_before, 1e-3);
  EXPECT_NEAR(joint_qpos(m, d, "elbow_drive"), drive_before + 0.3, 1e-3);
}

/// A scratch copy of robots/rnt with another parameters.toml.
class RntScratch {
 public:
  explicit RntScratch(const std::string& coupling_toml)
      : dir_(std::filesystem::temp_directory_path() /
             ("mrroc_rnt_" + std::to_string(::getpid()) + "_" + std::to_string(counter_++))) {
    std::filesystem::create_directories(dir_);
    std::filesystem::copy_file(rnt_dir() / "rnt.xml", dir_ / "rnt.xml");
    std::ofstream out(dir_ / "parameters.toml");
    out << "[robot]\nname = \"rnt\"\nmjcf = \"rnt.xml\"\n"
        << "joint_names = [\"waist\", \"shoulder\", \"elbow\", \"wrist_pitch\", \"wrist_yaw\", "
           "\"wrist_roll\"]\n"
        << "synchro_joint_positions = [0.0, 0.0, 0.0, 1.5707963267948966, 0.0, 0.0]\n\n"
        << "[robot.transmission]\n"
        << coupling_toml;
  }
  ~RntScratch() { std::filesystem::remove_all(dir_); }
  RntScratch(const RntScratch&) = delete;
  RntScratch& operator=(const RntScratch&) = delete;
  [[nodiscard]] HardwareSetup setup() const {
    HardwareSetup s = rnt_setup();
    s.model_dir = dir_;
    return s;
  }
  [[nodiscard]] std::filesystem::path file() const { return dir_ / "parameters.toml"; }

 private:
  static inline int counter_ = 0;
  std::filesystem::path dir_;
};

TEST(MujocoHardwareRnt, CouplingErrorsNameTheFileAndTheProblem) {
  {
    // Identity (no coupling declared): the serial elbow joint would not follow axis 2.
    RntScratch scratch("# no coupling\n");
    MujocoHardware hw;
    try {
      hw.configure(scratch.setup());
      FAIL() << "an identity coupling was accepted for the parallelogram";
    } catch (const HardwareError& e) {
      const std::string what = e.what();
      std::printf("%s\n", what.c_str());
      EXPECT_NE(what.find("does not match"), std::string::npos) << what;
      EXPECT_NE(what.find("'elbow'"), std::string::npos) << what;
    }
  }
  {
    RntScratch scratch("coupling = [[1.0, 0.0], [0.0, 1.0]]\n");
    MujocoHardware hw;
    try {
      hw.configure(scratch.setup());
      FAIL() << "a 2 x 2 coupling was accepted for 6 actuators";
    } catch (const ConfigError& e) {
      const std::string what = e.what();
      std::printf("%s\n", what.c_str());
      EXPECT_NE(what.find(scratch.file().string() + ":"), std::string::npos) << what;
      EXPECT_NE(what.find("6 x 6"), std::string::npos) << what;
    }
  }
  {
    // Rows 1 and 2 equal: singular.
    RntScratch scratch(
        "coupling = [\n"
        "  [1.0, 0.0, 0.0, 0.0, 0.0, 0.0],\n  [0.0, 1.0, 1.0, 0.0, 0.0, 0.0],\n"
        "  [0.0, 1.0, 1.0, 0.0, 0.0, 0.0],\n  [0.0, 0.0, 0.0, 1.0, 0.0, 0.0],\n"
        "  [0.0, 0.0, 0.0, 0.0, 1.0, 0.0],\n  [0.0, 0.0, 0.0, 0.0, 0.0, 1.0],\n]\n");
    MujocoHardware hw;
    try {
      hw.configure(scratch.setup());
      FAIL() << "a singular coupling was accepted";
    } catch (const ConfigError& e) {
      const std::string what = e.what();
      std::printf("%s\n", what.c_str());
      EXPECT_NE(what.find(scratch.file().string() + ":8"), std::string::npos) << what;
      EXPECT_NE(what.find("singular"), std::string::npos) << what;
    }
  }
}

TEST(MujocoHardwareRnt, InitialPoseOutsideTheForearmRangeIsRefused) {
  HardwareSetup setup = rnt_setup();
  // q1 + q2 = 1.3 + 0.7 = 2.0 rad: inside both joint limits, beyond the elbow drive's 1.90625 rad.
  setup.params.set("initial_joint_positions", std::vector<double>{0.0, 1.3, 0.7, 0.0, 0.0, 0.0},
                   SourceLocation{"test.toml", 22});
  MujocoHardware hw;
  try {
    hw.configure(setup);
    FAIL() << "an initial pose beyond the elbow drive range was accepted";
  } catch (const ConfigError& e) {
    const std::string what = e.what();
    std::printf("%s\n", what.c_str());
    EXPECT_NE(what.find("test.toml:22"), std::string::npos) << what;
    EXPECT_NE(what.find("elbow_drive"), std::string::npos) << what;
  }
}

}  // namespace
