// Stock MP task "carry_bar": tight cooperation (paper, section 2). Two robots hold one rigid bar
// at its ends; the MP generates both robots' tool frames every macro-step from the bar's path in
// the cell, and the ECPs pass them through to their EDPs (NEXT_POSE). The bar stays rigid only
// if both robots follow in step: the MP measures the distance between the two grips in every
// macro-step (from the robots' own readings and their base poses) and fails when it deviates
// from the bar's length by more than the tolerance.
//
// [mp.args]: robots = ["left", "right"], bar_length [m], path = [[x, y, z], ...] (bar centre in
// the cell [m]; the bar lies along x), speed [m/s], motion_steps, tolerance [m].
#include <fmt/format.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <memory>

#include "mrroc/config/check.hpp"
#include "mrroc/edp/arm_kinematics.hpp"
#include "mrroc/kinematics/pose.hpp"
#include "mrroc/mp/task.hpp"
#include "mrroc/robot/robot_model.hpp"
#include "straight_path.hpp"

namespace mrroc::mp {

namespace {

Eigen::Isometry3d frame_of(const std::array<double, 6>& pose) {
  return kinematics::from_values(pose, edp::ArmRepresentation::xyz_angle_axis);
}

/// Tool orientation gripping the bar from its end: approach along +x (left) or -x (right) of
/// the cell, tool x axis pointing down.
Eigen::Matrix3d grip_orientation(double side) {
  Eigen::Matrix3d r;
  r.col(0) = Eigen::Vector3d(0, 0, -1);
  r.col(2) = Eigen::Vector3d(side, 0, 0);
  r.col(1) = r.col(2).cross(r.col(0));
  return r;
}

/// A carry resumed from rest takes at least this long to the end of the interrupted segment.
constexpr double kMinResumeSegmentS = 0.5;
/// After a resumption the grips' offsets from their nominal poses fade out over this long, or
/// over the rest of the path where that is shorter. Where ECPs correct the grips from their wrist
/// forces (follow_mp_compliant), those offsets are mostly the ECPs' corrections, which restart
/// from 0 at rest and come back only as fast as the force error drives them (gain 3e-4 m/s per
/// N): 2.5 mm faded over a 0.5 s segment needed about 10 mm/s, 33-41 N on the bar.
constexpr double kResumeFadeS = 3.0;

class BarCarryGenerator : public Generator {
 public:
  /// `kinematics`: each robot's, to find where its grip stands after a stop (resume).
  BarCarryGenerator(std::vector<Eigen::Isometry3d> bases,
                    std::vector<std::unique_ptr<edp::ArmKinematics>> kinematics, double bar_length,
                    std::vector<Eigen::Vector3d> path, double speed, int motion_steps,
                    double servo_period_s)
      : bases_(std::move(bases)),
        kinematics_(std::move(kinematics)),
        half_(bar_length / 2.0),
        start_(path.front()),
        path_(path, std::vector<double>(path.size() - 1, speed), motion_steps * servo_period_s),
        steps_(motion_steps),
        macro_step_s_(motion_steps * servo_period_s) {}

  bool first_step(const ImageList& robots, const ecp::SensorList&) override {
    // Approach: both robots go to the grips of the bar's first pose in one long macro-step.
    approaching_ = true;
    dwelled_ = false;
    command(robots, start_, 1000, 1001);
    return true;
  }

  bool next_step(const ImageList& robots, const ecp::SensorList&) override {
    measure(robots);
    if (approaching_ && !dwelled_) {
      // Hold the grips for half a second so that both robots settle before the carry.
      dwelled_ = true;
      command(robots, start_, 250, 251);
      return true;
    }
    if (approaching_) {
      approaching_ = false;
      max_deviation_ = 0.0;  // the carry starts here: the grip distance now is the reference
      start_distance_ = -1.0;
      measure(robots);
    }
    Eigen::Vector3d centre;
    if (!path_.next(centre)) return false;
    // Readings three servo steps early: the next poses must reach both EDPs before the
    // macro-steps queued ahead of them (the EDPs' lookahead) run out, so that neither robot
    // stops between macro-steps.
    command(robots, centre, steps_, path_.at_end() ? steps_ + 1 : std::max(1, steps_ - 3));
    return true;
  }

  bool resume(const ImageList& robots, const ecp::SensorList&) override {
    // The group stopped in the carry (the approach and the dwell end at rest anyway): the bar's
    // centre is where the two grips stand now, and the rest of the path goes on from there.
    if (approaching_) return false;
    Eigen::Vector3d centre = Eigen::Vector3d::Zero();
    std::vector<Eigen::Isometry3d> held;
    for (std::size_t i = 0; i < robots.size(); ++i) {
      // Where each EDP holds its robot (the commanded joints): the next macro-step starts there,
      // and the drives' following error (measured joints) would be a jump from rest.
      const std::vector<double>& q =
          robots[i]->desired_joints.empty() ? robots[i]->joints : robots[i]->desired_joints;
      if (q.empty()) return false;
      held.push_back(bases_[i] * kinematics_[i]->forward(q));
      centre += held.back().translation();
    }
    centre /= static_cast<double>(robots.size());  // the grips sit at the centre -+ half the bar
    // Each grip's pose differs a little from the bar's nominal one at that centre (the ramps to
    // rest ran in joint space, and the grip distance deviates within the tolerance): the
    // difference fades out over the resumed segment, with its time law, so that each robot
    // starts from exactly where it stands (a jump there is refused as too abrupt).
    offsets_.clear();
    for (std::size_t i = 0; i < held.size(); ++i) {
      const Eigen::Isometry3d nominal = grip(i, centre);
      offsets_.push_back({held[i].translation() - nominal.translation(),
                          Eigen::Quaterniond(held[i].linear() * nominal.linear().transpose())});
    }
    path_ = path_.rest_from(centre, kMinResumeSegmentS);
    faded_ = 0;
    fade_macros_ = std::max(
        1, static_cast<int>(std::ceil(std::min(kResumeFadeS, path_.duration_s()) / macro_step_s_)));
    Eigen::Vector3d next;
    if (!path_.next(next)) return false;
    ++resumes_;
    command(robots, next, steps_, path_.at_end() ? steps_ + 1 : std::max(1, steps_ - 3));
    return true;
  }

  [[nodiscard]] double max_deviation() const { return max_deviation_; }
  [[nodiscard]] int resumes() const { return resumes_; }
  [[nodiscard]] int macro_steps() const { return macro_total_; }

 private:
  /// Robot i's grip on the bar whose centre is `centre`, nominally.
  [[nodiscard]] Eigen::Isometry3d grip(std::size_t i, const Eigen::Vector3d& centre) const {
    const double side = i == 0 ? 1.0 : -1.0;  // left grips the bar's -x end, approaching +x
    Eigen::Isometry3d g = Eigen::Isometry3d::Identity();
    g.linear() = grip_orientation(side);
    g.translation() = centre - side * half_ * Eigen::Vector3d::UnitX();
    return g;
  }

  void command(const ImageList& robots, const Eigen::Vector3d& centre, int steps, int value) {
    // After a resumption, the offsets of the grips from their nominal poses fade out over
    // fade_macros_ macro-steps with the quintic time law.
    double keep = 0.0;
    if (!offsets_.empty()) {
      const double tau = std::min(1.0, static_cast<double>(++faded_) / fade_macros_);
      keep = 1.0 - tau * tau * tau * (10.0 + tau * (-15.0 + 6.0 * tau));
    }
    if (keep <= 0.0) offsets_.clear();
    for (std::size_t i = 0; i < robots.size(); ++i) {
      Eigen::Isometry3d grip = this->grip(i, centre);
      if (i < offsets_.size()) {
        grip.translation() += keep * offsets_[i].translation;
        grip.linear() =
            Eigen::Quaterniond::Identity().slerp(keep, offsets_[i].rotation) * grip.linear();
      }
      ecp::MpCommand& c = robots[i]->command;
      c.arm_type = edp::ArmRepresentation::frame;
      c.motion_type = edp::MotionType::absolute;
      c.motion_steps = steps;
      c.value_in_step_no = value;
      c.arm = kinematics::to_vector(bases_[i].inverse() * grip, edp::ArmRepresentation::frame);
      robots[i]->commanded = true;
    }
    ++macro_total_;
  }

  void measure(const ImageList& robots) {
    std::vector<Eigen::Vector3d> grips;
    for (std::size_t i = 0; i < robots.size(); ++i) {
      if (robots[i]->arm_type != edp::ArmRepresentation::frame || robots[i]->arm.size() != 12)
        return;
      grips.push_back(
          bases_[i] *
          kinematics::from_vector(robots[i]->arm, edp::ArmRepresentation::frame).translation());
    }
    const double distance = (grips[1] - grips[0]).norm();
    if (start_distance_ < 0.0) start_distance_ = distance;  // measured when the carry starts
    max_deviation_ = std::max(max_deviation_, std::abs(distance - start_distance_));
  }

  /// A grip's pose at a resumption against its nominal one: world translation, world rotation.
  struct Offset {
    Eigen::Vector3d translation;
    Eigen::Quaterniond rotation;
  };
  std::vector<Eigen::Isometry3d> bases_;
  std::vector<std::unique_ptr<edp::ArmKinematics>> kinematics_;
  std::vector<Offset> offsets_;  ///< since the last resumption, until they faded out
  int faded_ = 0;                ///< macro-steps of the fade done
  int fade_macros_ = 1;          ///< macro-steps the fade takes
  double half_;
  Eigen::Vector3d start_;
  StraightPath path_;
  int steps_;
  double macro_step_s_;  ///< [s]
  int macro_total_ = 0;
  int resumes_ = 0;
  bool approaching_ = true;
  bool dwelled_ = false;
  double max_deviation_ = 0.0;
  double start_distance_ = -1.0;
};

}  // namespace

class CarryBar : public MpTask {
 public:
  explicit CarryBar(TaskContext& context) : context_(context) {
    const Params& args = context.args;
    // Every argument checked on its own at its own line: a mistake in one does not hide the
    // others.
    ConfigErrorList errors;
    errors.run(args.location_of("robots"), [&] {
      const auto names = args.get_strings("robots");
      if (names.size() != 2)
        throw ConfigError(
            args.location_of("robots"),
            fmt::format("'robots' must name exactly two robots, not {}", names.size()));
      for (const auto& n : names) robots_.push_back(&context.robot(n));
    });
    errors.run(args.location_of("bar_length"), [&] {
      bar_length_ = args.get_double("bar_length");
      if (!(bar_length_ > 0.0 && std::isfinite(bar_length_)))
        throw ConfigError(args.location_of("bar_length"),
                          fmt::format("'bar_length' = {} m must be > 0 m", bar_length_));
    });
    errors.run(args.location_of("path"), [&] { path_ = read_path_points(args); });
    errors.run(args.location_of("speed"), [&] {
      speed_ = args.get_double("speed", 0.05);
      if (!(speed_ > 0.0 && speed_ <= 0.5))
        throw ConfigError(args.location_of("speed"),
                          fmt::format("speed {} m/s is outside (0, 0.5] m/s", speed_));
    });
    errors.run(args.location_of("motion_steps"),
               [&] { motion_steps_ = static_cast<int>(args.get_int("motion_steps", 10)); });
    errors.run(args.location_of("tolerance"), [&] {
      tolerance_ = args.get_double("tolerance", 0.003);
      if (!(tolerance_ > 0.0))
        throw ConfigError(args.location_of("tolerance"),
                          fmt::format("'tolerance' = {} m must be > 0 m", tolerance_));
    });
    errors.run(args.location(), [&] { args.reject_unread("mp.args"); });
    errors.throw_if_any();
  }

  void main_task() override {
    parallel(robots_, [](Robot& r) { r.start_task(); });  // follow_mp: synchronise
    context_.reporter.info("both robots synchronised; carrying the bar");
    std::vector<Eigen::Isometry3d> bases;
    std::vector<std::unique_ptr<RobotModel>> models;  // the kinematics refer to them
    std::vector<std::unique_ptr<edp::ArmKinematics>> kinematics;
    for (Robot* r : robots_) {
      const RobotConfig& robot = context_.config.robot(r->name());
      bases.push_back(frame_of(robot.base));
      models.push_back(std::make_unique<RobotModel>(load_robot_model(robot.model_dir)));
      kinematics.push_back(edp::make_arm_kinematics(*models.back()));
    }
    BarCarryGenerator generator(bases, std::move(kinematics), bar_length_, path_, speed_,
                                motion_steps_,
                                context_.config.robot(robots_[0]->name()).edp.servo_period_s);
    Move(robots_, {}, generator);
    const double deviation = generator.max_deviation();
    context_.reporter.info(fmt::format(
        "bar carried along {} points in {} macro-steps; grip distance within {:.3f} mm of its "
        "start value (bar length {:.3f} m){}",
        path_.size(), generator.macro_steps(), deviation * 1e3, bar_length_,
        generator.resumes() > 0
            ? fmt::format("; the robots stopped together and resumed from rest {} time(s)",
                          generator.resumes())
            : std::string()));
    if (deviation > tolerance_)
      throw Error(
          fmt::format("the robots did not keep the bar rigid: grip distance deviated "
                      "{:.3f} mm, tolerance {:.3f} mm",
                      deviation * 1e3, tolerance_ * 1e3));
  }

 private:
  TaskContext& context_;
  RobotList robots_;
  double bar_length_ = 0;
  std::vector<Eigen::Vector3d> path_;
  double speed_ = 0.05;
  int motion_steps_ = 10;
  double tolerance_ = 0.003;
};

MRROC_REGISTER_MP_TASK("carry_bar", CarryBar);

}  // namespace mrroc::mp
