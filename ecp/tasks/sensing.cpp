// Stock sensor-driven ECP tasks (docs/sensors.md), for an arm with a wrist force/torque sensor and
// a probe pointing straight down (the IRb-6 of configs/scenes/sensing.toml):
//
//   touch           a guarded move: the probe goes down until the wrist force says contact, and
//                   the stop must come within `stop_within` of the first contact;
//   follow_surface  touch, then slide along the surface keeping a set contact force (force-
//                   compliant motion: the height follows the force error every macro-step), and
//                   check the force stayed within `force_tolerance` of the set force;
//   pick_when_seen  Wait until the camera sees the part inside the pick region, then move the
//                   probe above it (the start of a pick), and report where the part was.
//   follow_mp_compliant
//                   hybrid control (paper, section 2): the MP generates the tool's path, and
//                   this ECP corrects every NEXT_POSE along the tool axis from its wrist force
//                   (an admittance), so the probe presses with a set force where the MP's path
//                   goes into a surface (a FollowGenerator installed by the task).
//
// The wrist sensor is a VSP (force_torque) whose image Move and Wait refresh every macro-step;
// each INITIATE_READING carries the sensor's orientation for the tool's gravity compensation.
// An invalid reading (a stale or dead VSP) throws SensorError inside the Move: the robot stops
// and the task fails with the VSP's name and reason.
//
// [robot.ecp.args] of touch and follow_surface:
//   sensor = "wrist_force"  VSP name;   tool = 0.15  probe tip centre on the flange z axis [m]
//   start = [x, y, z]       tip centre above the surface, in the base frame [m]
//   speed = 0.01 [m/s], max_distance = 0.1 [m]: the guarded approach downwards
//   contact_force = 5 [N]   force along the probe that ends the approach
//   touch_force = 0.5 [N]   force that counts as first contact
//   stop_within = 0.002 [m] largest travel from first contact to the stop
// follow_surface also: force = 10 [N] set force, force_tolerance = 3 [N], direction = [1, 0, 0],
//   length = 0.1 [m], follow_speed = 0.02 [m/s], gain = 2e-5 [m/N per macro-step],
//   settle = 0.6 [s] (force errors before this are not counted), motion_steps = 20 (per macro-step)
// follow_mp_compliant: sensor = "wrist_force", tool = 0.15 [m], force = 5 [N] largest force the
//   probe presses with along the tool axis, gain = 3e-4 [m/s per N] of force error,
//   max_speed = 0.02 [m/s] and max_acceleration = 0.2 [m/s^2] of the correction, max_offset =
//   0.01 [m] largest correction back along the tool axis, min_offset = 0 [m] largest one forwards
//   (<= 0; 0: it never pushes beyond the MP's pose). force = 0 with min_offset < 0 keeps the
//   force along the tool near zero both ways (each grip of a carried bar, tight-bar-hybrid.toml).
// pick_when_seen: camera = "camera" VSP, region = [xmin, xmax, ymin, ymax] (world, m) where a part
//   may be picked, above = 0.1 [m] above the part, tool = 0.15, timeout = 30 [s],
//   base = [x, y, z] the robot's base position in the world (rotation: none) [m].
#include <fmt/format.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <memory>

#include "mrroc/config/check.hpp"
#include "mrroc/ecp/errors.hpp"
#include "mrroc/ecp/generators/cartesian_path.hpp"
#include "mrroc/ecp/generators/errors.hpp"
#include "mrroc/ecp/generators/guarded_move.hpp"
#include "mrroc/ecp/generators/joint_poses.hpp"
#include "mrroc/ecp/task.hpp"
#include "mrroc/ecp/virtual_sensor.hpp"
#include "mrroc/kinematics/pose.hpp"

namespace mrroc::ecp {

namespace {

// The arguments' readers: a value of another type or out of range is added to `errors` at its
// line and the default used, so that a task's other arguments are checked too.

Eigen::Vector3d vector3(const Params& a, const char* key, std::vector<double> fallback,
                        ConfigErrorList& errors) {
  std::vector<double> v = fallback;
  errors.run(a.location_of(key), [&] {
    const std::vector<double> given = a.get_doubles(key, fallback);
    if (given.size() != 3)
      throw ConfigError(a.location_of(key), fmt::format("'{}' must be [x, y, z] (m), not {} values",
                                                        key, given.size()));
    v = given;
  });
  return {v[0], v[1], v[2]};
}

double positive(const Params& a, const char* key, double fallback, const char* unit,
                ConfigErrorList& errors) {
  double v = fallback;
  errors.run(a.location_of(key), [&] {
    const double given = a.get_double(key, fallback);
    if (!(given > 0.0) || !std::isfinite(given))
      throw ConfigError(a.location_of(key),
                        fmt::format("'{}' = {} {} must be a positive number", key, given, unit));
    v = given;
  });
  return v;
}

/// The number `key` (default `fallback`) in [low, high] `unit`, as `positive`.
double in_range(const Params& a, const char* key, double fallback, double low, double high,
                const char* unit, ConfigErrorList& errors) {
  double v = fallback;
  errors.run(a.location_of(key), [&] {
    const double given = a.get_double(key, fallback);
    if (!(given >= low && given <= high))
      throw ConfigError(a.location_of(key), fmt::format("'{}' = {} {} is outside [{}, {}] {}", key,
                                                        given, unit, low, high, unit));
    v = given;
  });
  return v;
}

/// The VSP named by argument `key` (TaskContext::sensor_argument), as `positive`.
std::string sensor_argument(const TaskContext& context, const char* key, const char* fallback,
                            ConfigErrorList& errors) {
  std::string name = fallback;
  errors.run(context.args.location_of(key), [&] { name = context.sensor_argument(key, fallback); });
  return name;
}

/// The wrist sensor as Move and Wait see it: before each INITIATE_READING it tells the VSP the
/// sensor's orientation (the flange frame in the base frame, from the robot image), for the
/// tool's gravity compensation.
class WristSensor : public Sensor {
 public:
  WristSensor(VirtualSensor& vsp, Robot& robot, const edp::ArmKinematics& flange)
      : vsp_(vsp), robot_(robot), flange_(flange) {}
  void initiate_reading() override {
    const Eigen::Matrix3d r = flange_.forward(robot_.image().joints).linear();
    vsp_.set_context(fmt::format("rotation = [{}]", fmt::join(r.transpose().reshaped(), ", ")));
    vsp_.initiate_reading();
  }
  void get_reading() override { vsp_.get_reading(); }
  /// Force pressing the probe back along its axis [N] (the sensor's z axis is the approach
  /// direction; a push from the surface is a force along -z on the tool).
  [[nodiscard]] double pressing() const { return -vsp_.valid_image().value("fz"); }

 private:
  VirtualSensor& vsp_;
  Robot& robot_;
  const edp::ArmKinematics& flange_;
};

/// Shared by touch and follow_surface: arguments, the approach and the guarded move. The
/// errors of the shared arguments are kept in `argument_errors_`, which the derived task's
/// constructor throws with its own.
class Touching : public EcpTask {
 public:
  explicit Touching(TaskContext& context) : context_(context) {
    const Params& a = context.args;
    ConfigErrorList& e = argument_errors_;
    sensor_name_ = sensor_argument(context, "sensor", "wrist_force", e);
    tool_length_ = positive(a, "tool", 0.15, "m", e);
    start_ = vector3(a, "start", {0.9, 0.0, 0.40}, e);
    speed_ = positive(a, "speed", 0.01, "m/s", e);
    max_distance_ = positive(a, "max_distance", 0.1, "m", e);
    contact_force_ = positive(a, "contact_force", 5.0, "N", e);
    touch_force_ = positive(a, "touch_force", 0.5, "N", e);
    stop_within_ = positive(a, "stop_within", 0.002, "m", e);
  }

 protected:
  /// Synchronises, moves above the surface, zeroes the sensor there and goes down until contact.
  /// Returns the tip position at the stop.
  Eigen::Vector3d touch() {
    Robot& robot = context_.robot;
    robot.synchronise();
    flange_ = edp::make_arm_kinematics(robot.model());
    tip_ = edp::make_arm_kinematics(robot.model());
    tool_ = Eigen::Isometry3d::Identity();
    tool_.translation() = Eigen::Vector3d(0, 0, tool_length_);
    tip_->set_tool(tool_);
    // The probe pointing straight down (tool z = -z of the base), tool x along -x of the base.
    down_ << -1, 0, 0, 0, 1, 0, 0, 0, -1;
    vsp_ = context_.sensor(sensor_name_);
    wrist_ = std::make_unique<WristSensor>(*vsp_, robot, *flange_);

    CartesianOptions options;
    options.tool = tool_;
    options.max_linear_velocity = 0.1;
    options.servo_period_s = context_.servo_period_s;
    Eigen::Isometry3d above = Eigen::Isometry3d::Identity();
    above.linear() = down_;
    above.translation() = start_;
    {
      // In joint space: a straight line from the synchronisation pose may cross a motor limit.
      const std::vector<double> q = tip_->inverse(above, robot.image().desired_joints);
      JointPosesOptions joint_options;
      joint_options.servo_period_s = context_.servo_period_s;
      JointPosesGenerator to_start(robot.model(), {q}, joint_options);
      Move(robot, {}, to_start);
    }
    // In free space now: what the sensor feels is the tool's weight and its own offsets.
    wrist_->initiate_reading();
    wrist_->get_reading();
    vsp_->configure("zero = true");
    context_.reporter.info(
        fmt::format("above the surface at [{:.4f}, {:.4f}, {:.4f}] m; wrist "
                    "sensor '{}' zeroed",
                    start_.x(), start_.y(), start_.z(), sensor_name_));

    std::optional<Eigen::Vector3d> first_contact;
    double last_force = 0.0;
    auto contact = [&] {
      last_force = wrist_->pressing();  // throws SensorError for an invalid reading
      if (!first_contact && last_force >= touch_force_)
        first_contact = tip_->forward(robot.image().joints).translation();
      return last_force >= contact_force_;
    };
    GuardedMotion motion;
    motion.speed = speed_;
    motion.acceleration = 0.2;
    motion.max_distance = max_distance_;
    auto guarded = GuardedMoveGenerator::along_line(robot.model(), Eigen::Vector3d(0, 0, -1),
                                                    motion, contact, options);
    Move(robot, {wrist_.get()}, guarded);
    robot.read_state();
    const Eigen::Vector3d stop = tip_->forward(robot.image().joints).translation();
    if (!first_contact) throw FatalError("the guarded move ended without contact");
    const double travel = (*first_contact - stop).norm();
    context_.reporter.info(fmt::format(
        "touched: first contact at z = {:.4f} m, stopped at z = {:.4f} m, {:.2f} mm after first "
        "contact (limit {:.2f} mm), pressing {:.1f} N",
        first_contact->z(), stop.z(), travel * 1e3, stop_within_ * 1e3, last_force));
    if (travel > stop_within_)
      throw FatalError(
          fmt::format("the guarded move stopped {:.2f} mm after first contact (limit "
                      "{:.2f} mm)",
                      travel * 1e3, stop_within_ * 1e3));
    return stop;
  }

  TaskContext& context_;
  ConfigErrorList argument_errors_;
  std::string sensor_name_;
  double tool_length_, speed_, max_distance_, contact_force_, touch_force_, stop_within_;
  Eigen::Vector3d start_;
  Eigen::Isometry3d tool_;
  Eigen::Matrix3d down_;
  std::unique_ptr<edp::ArmKinematics> flange_, tip_;
  std::unique_ptr<VirtualSensor> vsp_;
  std::unique_ptr<WristSensor> wrist_;
};

class Touch : public Touching {
 public:
  explicit Touch(TaskContext& context) : Touching(context) {
    argument_errors_.run(context.args.location(),
                         [&] { context.args.reject_unread("robot.ecp.args"); });
    argument_errors_.throw_if_any();
  }
  void main_task() override { (void)touch(); }
};

/// Macro-steps of travel that ForceFollowing's ramp-up over 25 macro-steps costs.
constexpr int kRampTravelMacroSteps = 12;

/// Force-compliant motion: each macro-step the tip advances along the surface and its height
/// follows the force error (an admittance: dz = gain * (pressing - set force)).
class ForceFollowing : public Generator {
 public:
  /// `tip`: the arm's kinematics with `tool` set (where the tip stands after a stop, resume).
  ForceFollowing(const WristSensor& wrist, const edp::ArmKinematics& tip,
                 const Eigen::Isometry3d& start, Eigen::Vector3d step, int macro_steps,
                 double set_force, double gain, int motion_steps, const Eigen::Isometry3d& tool)
      : wrist_(wrist),
        tip_(tip),
        pose_(start),
        step_(std::move(step)),
        left_(macro_steps),
        set_force_(set_force),
        gain_(gain),
        motion_steps_(motion_steps),
        tool_(tool) {}

  bool first_step(RobotImage& robot, const SensorList&) override {
    command(robot, 0.0);
    edp::Instruction& c = robot.command;
    c.set |= edp::item::tool;
    c.tool_type = edp::ArmRepresentation::frame;
    const auto t = kinematics::frame_to_values(tool_);
    c.tool.assign(t.begin(), t.end());
    return true;
  }
  bool next_step(RobotImage& robot, const SensorList&) override {
    const double f = wrist_.pressing();
    forces_.push_back(f);
    if (--left_ <= 0) return false;
    // Too little force: further down; too much: up. At most 0.2 mm per macro-step.
    command(robot, std::clamp(gain_ * (set_force_ - f), -2e-4, 2e-4));
    return true;
  }
  /// The EDP brought the robot to rest (a macro-step came late) and refused the next one as too
  /// abrupt from there: go on along the surface from where the tip is held, ramping the speed
  /// up again from rest, as at the start.
  bool resume(RobotImage& robot, const SensorList&) override {
    if (robot.desired_joints.empty()) return false;
    const Eigen::Isometry3d held = tip_.forward(robot.desired_joints);
    pose_.translation() = held.translation();
    done_ = 0;
    left_ += kRampTravelMacroSteps;  // the new ramp costs its travel again
    ++resumes_;
    command(robot, 0.0);
    return true;
  }
  [[nodiscard]] const std::vector<double>& forces() const { return forces_; }
  [[nodiscard]] int resumes() const { return resumes_; }

 private:
  void command(RobotImage& robot, double down) {
    // The speed along the surface ramps up over the first 25 macro-steps (no jerk at the start).
    const double ramp = std::min(1.0, static_cast<double>(++done_) / 25.0);
    pose_.translation() += ramp * step_ - Eigen::Vector3d(0, 0, down);
    edp::Instruction& c = robot.command;
    c = edp::Instruction{};
    c.type = edp::InstructionType::set;
    c.set = edp::item::arm;
    c.set_arm_type = edp::ArmRepresentation::frame;
    c.motion_type = edp::MotionType::absolute;
    c.motion_steps = motion_steps_;
    // Read a quarter of the macro-step early: the next macro-step needs two VSP exchanges and
    // the EDP's, which one servo period (the paper's minimum) does not always leave time for.
    c.value_in_step_no = motion_steps_ - motion_steps_ / 4;
    const auto v = kinematics::frame_to_values(pose_);
    c.arm.assign(v.begin(), v.end());
  }

  const WristSensor& wrist_;
  const edp::ArmKinematics& tip_;
  Eigen::Isometry3d pose_;
  Eigen::Vector3d step_;
  int left_;
  double set_force_, gain_;
  int motion_steps_;
  Eigen::Isometry3d tool_;
  std::vector<double> forces_;
  int done_ = 0;
  int resumes_ = 0;
};

class FollowSurface : public Touching {
 public:
  explicit FollowSurface(TaskContext& context) : Touching(context) {
    const Params& a = context.args;
    ConfigErrorList& e = argument_errors_;
    force_ = positive(a, "force", 10.0, "N", e);
    tolerance_ = positive(a, "force_tolerance", 3.0, "N", e);
    direction_ = vector3(a, "direction", {1.0, 0.0, 0.0}, e);
    length_ = positive(a, "length", 0.1, "m", e);
    follow_speed_ = positive(a, "follow_speed", 0.02, "m/s", e);
    gain_ = positive(a, "gain", 2e-5, "m/N", e);
    e.run(a.location_of("settle"), [&] { settle_ = a.get_double("settle", 0.6); });
    e.run(a.location_of("motion_steps"), [&] {
      const std::int64_t steps = a.get_int("motion_steps", 20);
      if (steps < 4 || steps > 1000)
        throw ConfigError(a.location_of("motion_steps"),
                          fmt::format("'motion_steps' = {} must be in 4..1000 servo steps", steps));
      motion_steps_ = static_cast<int>(steps);
    });
    e.run(a.location(), [&] { a.reject_unread("robot.ecp.args"); });
    direction_.z() = 0.0;
    if (direction_.norm() < 1e-9)
      e.add(ConfigError(a.location_of("direction"), "'direction' must have a horizontal part"));
    else
      direction_.normalize();
    e.throw_if_any();
  }

  void main_task() override {
    const Eigen::Vector3d stop = touch();
    Robot& robot = context_.robot;
    const int motion_steps = motion_steps_;
    const double dt = motion_steps * context_.servo_period_s;
    // Ramping up costs 12 macro-steps of travel (see ForceFollowing::command).
    const int macro_steps =
        static_cast<int>(std::ceil(length_ / (follow_speed_ * dt))) + kRampTravelMacroSteps;
    Eigen::Isometry3d start = Eigen::Isometry3d::Identity();
    start.linear() = down_;
    start.translation() = stop;
    ForceFollowing follow(*wrist_, *tip_, start, direction_ * follow_speed_ * dt, macro_steps,
                          force_, gain_, motion_steps, tool_);
    Move(robot, {wrist_.get()}, follow);
    robot.read_state();
    const std::vector<double>& f = follow.forces();
    const auto skip = static_cast<std::size_t>(std::ceil(settle_ / dt));
    double worst = 0.0, sum = 0.0, sum2 = 0.0;
    std::size_t n = 0;
    for (std::size_t i = skip; i < f.size(); ++i) {
      worst = std::max(worst, std::abs(f[i] - force_));
      sum += f[i];
      sum2 += (f[i] - force_) * (f[i] - force_);
      ++n;
    }
    if (n == 0) throw FatalError("the surface was too short to measure the contact force");
    const Eigen::Vector3d end = tip_->forward(robot.image().joints).translation();
    context_.reporter.info(fmt::format(
        "followed the surface for {:.3f} m: contact force mean {:.2f} N, rms error {:.2f} N, "
        "largest error {:.2f} N (set {:.1f} N, tolerance {:.1f} N, {} macro-steps after {:.1f} s "
        "settling){}",
        (end - stop).norm(), sum / static_cast<double>(n), std::sqrt(sum2 / static_cast<double>(n)),
        worst, force_, tolerance_, n, settle_,
        follow.resumes() > 0 ? fmt::format("; resumed from rest {} time(s) after a late macro-step",
                                           follow.resumes())
                             : std::string()));
    if (worst > tolerance_)
      throw FatalError(fmt::format("the contact force left {:.1f} +- {:.1f} N by {:.2f} N", force_,
                                   tolerance_, worst - tolerance_));
  }

 private:
  double force_, tolerance_, length_, follow_speed_, gain_, settle_;
  int motion_steps_ = 20;
  Eigen::Vector3d direction_;
};

/// The ECP half of hybrid control: every NEXT_POSE of the MP (an ABSOLUTE Cartesian tool frame)
/// moves back along the tool's z axis by `offset`, which follows the force error:
///   v = gain * (pressing - force), limited to max_speed and max_acceleration,
///   offset += v * dt, within [min_offset, max_offset] (braking before either end),
/// dt being the macro-step. With min_offset 0, in free space (pressing 0) the offset returns to
/// 0: the MP's path.
class ForceCompliance : public FollowGenerator {
 public:
  struct Settings {
    double force, gain, max_speed, max_acceleration, min_offset, max_offset, servo_period_s;
  };
  ForceCompliance(Robot& robot, Reporter& reporter, std::unique_ptr<VirtualSensor> vsp,
                  std::unique_ptr<edp::ArmKinematics> flange, const Settings& settings)
      : reporter_(reporter),
        vsp_(std::move(vsp)),
        flange_(std::move(flange)),
        wrist_(*vsp_, robot, *flange_),
        s_(settings) {}

  SensorList sensors() override { return {&wrist_}; }

  void correct(MpCommand& command, const RobotImage&, const SensorList&) override {
    if (command.arm_type == edp::ArmRepresentation::joint ||
        command.arm_type == edp::ArmRepresentation::motor ||
        command.motion_type != edp::MotionType::absolute)
      throw GeneratorError(fmt::format(
          "follow_mp_compliant corrects ABSOLUTE Cartesian poses; the MP sent a {} {} pose",
          command.motion_type == edp::MotionType::absolute ? "ABSOLUTE" : "RELATIVE",
          to_string(command.arm_type)));
    const double dt = command.motion_steps * s_.servo_period_s;
    const double pressing = wrist_.pressing();
    double v = std::clamp(s_.gain * (pressing - s_.force), -s_.max_speed, s_.max_speed);
    v = std::clamp(v, speed_ - s_.max_acceleration * dt, speed_ + s_.max_acceleration * dt);
    // Brake before either end of [0, max_offset].
    const double up = std::sqrt(2.0 * s_.max_acceleration * std::max(0.0, s_.max_offset - offset_));
    const double down =
        std::sqrt(2.0 * s_.max_acceleration * std::max(0.0, offset_ - s_.min_offset));
    v = std::clamp(v, -down, up);
    offset_ = std::clamp(offset_ + v * dt, s_.min_offset, s_.max_offset);
    speed_ = v;
    Eigen::Isometry3d pose = kinematics::from_vector(command.arm, command.arm_type);
    pose = pose * Eigen::Translation3d(0.0, 0.0, -offset_);
    command.arm = kinematics::to_vector(pose, command.arm_type);
    ++steps_;
    if (std::abs(pressing) > std::abs(largest_force_)) largest_force_ = pressing;
    if (std::abs(offset_) > std::abs(largest_offset_)) largest_offset_ = offset_;
    if (offset_ != 0.0) {
      pressed_sum_ += pressing;
      ++pressed_;
    }
  }

  void end_motion(const RobotImage&) override {
    reporter_.info(fmt::format(
        "corrected {} poses of the MP: largest force {:.2f} N (set {:.1f} N), mean force while "
        "corrected {:.2f} N in {} macro-steps, largest correction {:.3f} mm",
        steps_, largest_force_, s_.force, pressed_ > 0 ? pressed_sum_ / pressed_ : 0.0, pressed_,
        largest_offset_ * 1e3));
    steps_ = pressed_ = 0;
    largest_force_ = largest_offset_ = pressed_sum_ = 0.0;
    // The robot stands where the MP's images now show it, this correction included; the MP's next
    // motion (a new Move, or the resumption of a group stopped for want of macro-steps) starts
    // there. Kept, the correction would count twice: a jump of its size from rest, refused as too
    // abrupt. It starts again from 0 at rest and follows the force from there.
    offset_ = speed_ = 0.0;
  }

 private:
  Reporter& reporter_;
  std::unique_ptr<VirtualSensor> vsp_;
  std::unique_ptr<edp::ArmKinematics> flange_;
  WristSensor wrist_;
  Settings s_;
  double offset_ = 0.0, speed_ = 0.0;
  int steps_ = 0, pressed_ = 0;
  double largest_force_ = 0.0, largest_offset_ = 0.0, pressed_sum_ = 0.0;
};

/// follow_mp_compliant: synchronises, sets the tool, zeroes the wrist sensor and leaves a
/// ForceCompliance to correct the MP's poses.
class FollowMpCompliant : public EcpTask {
 public:
  explicit FollowMpCompliant(TaskContext& context) : context_(context) {
    const Params& a = context.args;
    // Every argument checked on its own at its own line: a mistake in one does not hide the
    // others.
    ConfigErrorList e;
    sensor_name_ = sensor_argument(context, "sensor", "wrist_force", e);
    tool_length_ = in_range(a, "tool", 0.15, 0.0, 1.0, "m", e);
    settings_.force = in_range(a, "force", 5.0, 0.0, 1000.0, "N", e);
    settings_.gain = positive(a, "gain", 3e-4, "m/s per N", e);
    settings_.max_speed = positive(a, "max_speed", 0.02, "m/s", e);
    settings_.max_acceleration = positive(a, "max_acceleration", 0.2, "m/s^2", e);
    settings_.max_offset = positive(a, "max_offset", 0.01, "m", e);
    settings_.min_offset = in_range(a, "min_offset", 0.0, -1.0, 0.0, "m", e);
    settings_.servo_period_s = context.servo_period_s;
    e.run(a.location(), [&] { a.reject_unread("robot.ecp.args"); });
    e.throw_if_any();
  }

  void main_task() override {
    Robot& robot = context_.robot;
    robot.synchronise();
    Eigen::Isometry3d tool = Eigen::Isometry3d::Identity();
    tool.translation() = Eigen::Vector3d(0, 0, tool_length_);
    edp::Instruction& c = robot.image().command;
    c = edp::Instruction{};
    c.type = edp::InstructionType::set;
    c.set = edp::item::tool;
    c.tool_type = edp::ArmRepresentation::frame;
    const auto t = kinematics::frame_to_values(tool);
    c.tool.assign(t.begin(), t.end());
    robot.execute();
    auto vsp = context_.sensor(sensor_name_);
    auto flange = edp::make_arm_kinematics(robot.model());
    {
      // In free space: what the sensor feels is the tool's weight and its own offsets.
      WristSensor wrist(*vsp, robot, *flange);
      wrist.initiate_reading();
      wrist.get_reading();
      vsp->configure("zero = true");
    }
    context_.follow_mp_with(std::make_unique<ForceCompliance>(
        robot, context_.reporter, std::move(vsp), std::move(flange), settings_));
    context_.reporter.info(fmt::format(
        "wrist sensor '{}' zeroed; following the MP, pressing at most {:.1f} N along the tool",
        sensor_name_, settings_.force));
  }

 private:
  TaskContext& context_;
  std::string sensor_name_;
  double tool_length_;
  ForceCompliance::Settings settings_{};
};

/// True when the camera sees the part inside the pick region.
class PartInRegion : public Condition {
 public:
  PartInRegion(const VirtualSensor& camera, std::vector<double> region)
      : camera_(camera), region_(std::move(region)) {}
  bool check(const SensorList&) override {
    const vsp::Reading& r = camera_.valid_image();
    if (r.value("visible") < 0.5) return false;
    const double x = r.value("x"), y = r.value("y");
    return x >= region_[0] && x <= region_[1] && y >= region_[2] && y <= region_[3];
  }

 private:
  const VirtualSensor& camera_;
  std::vector<double> region_;
};

class PickWhenSeen : public EcpTask {
 public:
  explicit PickWhenSeen(TaskContext& context) : context_(context) {
    const Params& a = context.args;
    // Every argument checked on its own at its own line: a mistake in one does not hide the
    // others.
    ConfigErrorList e;
    camera_name_ = sensor_argument(context, "camera", "camera", e);
    e.run(a.location_of("region"), [&] {
      region_ = a.get_doubles("region");
      if (region_.size() != 4 || region_[0] >= region_[1] || region_[2] >= region_[3])
        throw ConfigError(a.location_of("region"),
                          "'region' must be [xmin, xmax, ymin, ymax] (m) with min < max");
    });
    above_ = positive(a, "above", 0.1, "m", e);
    tool_length_ = positive(a, "tool", 0.15, "m", e);
    timeout_ = positive(a, "timeout", 30.0, "s", e);
    base_ = vector3(a, "base", {0.0, 0.0, 0.0}, e);
    e.run(a.location(), [&] { a.reject_unread("robot.ecp.args"); });
    e.throw_if_any();
  }

  void main_task() override {
    Robot& robot = context_.robot;
    robot.synchronise();
    auto camera = context_.sensor(camera_name_);
    PartInRegion seen(*camera, region_);
    const auto t0 = std::chrono::steady_clock::now();
    context_.reporter.info(
        fmt::format("waiting for the part in x {:.3f}..{:.3f}, y {:.3f}..{:.3f} m", region_[0],
                    region_[1], region_[2], region_[3]));
    WaitWithTimeout timed(seen, t0, timeout_);
    Wait(robot, {camera.get()}, timed, 0.02);
    const vsp::Reading& r = camera->valid_image();
    const Eigen::Vector3d part(r.value("x"), r.value("y"), r.value("z"));
    const double waited =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    context_.reporter.info(
        fmt::format("part seen at [{:.4f}, {:.4f}, {:.4f}] m (reading {} ms "
                    "old) after {:.2f} s: starting the pick",
                    part.x(), part.y(), part.z(), r.age_us / 1000, waited));
    auto kinematics = edp::make_arm_kinematics(robot.model());
    Eigen::Isometry3d tool = Eigen::Isometry3d::Identity();
    tool.translation() = Eigen::Vector3d(0, 0, tool_length_);
    Eigen::Isometry3d target = Eigen::Isometry3d::Identity();
    target.linear() << -1, 0, 0, 0, 1, 0, 0, 0, -1;  // the probe pointing straight down
    target.translation() = part - base_ + Eigen::Vector3d(0, 0, above_);
    kinematics->set_tool(tool);
    const std::vector<double> q = kinematics->inverse(target, robot.image().desired_joints);
    JointPosesOptions joint_options;
    joint_options.servo_period_s = context_.servo_period_s;
    joint_options.velocity_scale = 0.8;
    JointPosesGenerator approach(robot.model(), {q}, joint_options);
    Move(robot, {}, approach);
    robot.read_state();
    const Eigen::Vector3d tip = kinematics->forward(robot.image().joints).translation() + base_;
    context_.reporter.info(fmt::format("above the part: tip at [{:.4f}, {:.4f}, {:.4f}] m", tip.x(),
                                       tip.y(), tip.z()));
  }

 private:
  /// The wrapped condition, or an error after `timeout` seconds.
  class WaitWithTimeout : public Condition {
   public:
    WaitWithTimeout(Condition& inner, std::chrono::steady_clock::time_point start, double timeout)
        : inner_(inner), start_(start), timeout_(timeout) {}
    bool check(const SensorList& sensors) override {
      if (inner_.check(sensors)) return true;
      if (std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count() >
          timeout_)
        throw NonFatalError(
            fmt::format("no part seen in the pick region within {:.0f} s", timeout_));
      return false;
    }

   private:
    Condition& inner_;
    std::chrono::steady_clock::time_point start_;
    double timeout_;
  };

  TaskContext& context_;
  std::string camera_name_;
  std::vector<double> region_;
  double above_, tool_length_, timeout_;
  Eigen::Vector3d base_;
};

}  // namespace

MRROC_REGISTER_ECP_TASK("touch", Touch);
MRROC_REGISTER_ECP_TASK("follow_surface", FollowSurface);
MRROC_REGISTER_ECP_TASK("pick_when_seen", PickWhenSeen);
MRROC_REGISTER_ECP_TASK("follow_mp_compliant", FollowMpCompliant);

}  // namespace mrroc::ecp
