// Stock ECP task "engrave": the RNT's demonstration task of the paper. Engraves a text with a
// milling cutter on a horizontal board, stroke by stroke, with the stock Cartesian path
// generator (lift, plunge to the cutting depth, follow the stroke, lift). While cutting it
// records the measured joints of every macro-step, computes the cutter tip from them, and fails
// when the tip strayed from the intended strokes by more than the tolerance.
//
// [robot.ecp.args]: text (letters of the stroke font: C, M, O, R; include/mrroc/ecp/
// stroke_font.hpp, which also lays the text out), origin = [x, y, z] (the text's lower-left
// corner on the board surface [m]), letter_height, letter_width, spacing, depth (below the
// surface), lift (above it), cutter (tool length along the flange z axis), speed [m/s],
// acceleration [m/s^2], tolerance [m], servo_algorithm (1: velocity feed-forward).
#include <fmt/format.h>
#include <fmt/ranges.h>

#include <Eigen/Geometry>
#include <cmath>

#include "mrroc/config/check.hpp"
#include "mrroc/ecp/errors.hpp"
#include "mrroc/ecp/generators/cartesian_path.hpp"
#include "mrroc/ecp/stroke_font.hpp"
#include "mrroc/ecp/task.hpp"

namespace mrroc::ecp {

namespace {

/// Records the measured joints after every exchange of the wrapped generator, and is the wrapped
/// generator in everything else: its resume() too, or a late macro-step (the EDP's ramp to rest,
/// then its refusal of the planned continuation) would end the engraving instead of re-planning
/// it from where the cutter stands.
class Recording : public Generator {
 public:
  Recording(Generator& inner, std::vector<std::vector<double>>& samples)
      : inner_(inner), samples_(samples) {}
  bool first_step(RobotImage& robot, const SensorList& sensors) override {
    return inner_.first_step(robot, sensors);
  }
  bool next_step(RobotImage& robot, const SensorList& sensors) override {
    samples_.push_back(robot.joints);
    return inner_.next_step(robot, sensors);
  }
  bool resume(RobotImage& robot, const SensorList& sensors) override {
    samples_.push_back(robot.joints);
    const bool resumed = inner_.resume(robot, sensors);
    if (resumed) ++resumes_;
    return resumed;
  }
  [[nodiscard]] int resumes() const { return resumes_; }

 private:
  Generator& inner_;
  std::vector<std::vector<double>>& samples_;
  int resumes_ = 0;
};

double distance_to_segment(const Eigen::Vector3d& p, const Eigen::Vector3d& a,
                           const Eigen::Vector3d& b) {
  const Eigen::Vector3d ab = b - a;
  const double t = std::clamp((p - a).dot(ab) / std::max(ab.squaredNorm(), 1e-18), 0.0, 1.0);
  return (a + t * ab - p).norm();
}

}  // namespace

class Engrave : public EcpTask {
 public:
  explicit Engrave(TaskContext& context) : context_(context) {
    const Params& a = context.args;
    // Every argument checked on its own at its own line: a mistake in one does not hide the
    // others.
    ConfigErrorList errors;
    errors.run(a.location_of("text"), [&] {
      text_ = a.get_string("text", "MRROC");
      std::string unknown;
      for (char c : text_)
        if (c != ' ' && engraving::letter_strokes(c) == nullptr &&
            unknown.find(c) == std::string::npos)
          unknown += c;
      if (!unknown.empty())
        throw ConfigError(
            a.location_of("text"),
            fmt::format("letter{} '{}' of \"{}\" {} not in the stroke font ({})",
                        unknown.size() > 1 ? "s" : "", fmt::join(unknown, "', '"), text_,
                        unknown.size() > 1 ? "are" : "is", engraving::kFontLetters));
    });
    errors.run(a.location_of("origin"), [&] {
      const auto origin = a.get_doubles("origin");
      if (origin.size() != 3)
        throw ConfigError(
            a.location_of("origin"),
            fmt::format("'origin' must be [x, y, z] (m), not {} values", origin.size()));
      origin_ = Eigen::Vector3d(origin[0], origin[1], origin[2]);
    });
    // A length, speed or acceleration: finite, above zero (or at zero where `zero` allows).
    const auto number = [&](const char* key, double fallback, const char* unit, bool zero) {
      double value = fallback;
      errors.run(a.location_of(key), [&] {
        value = a.get_double(key, fallback);
        if (!std::isfinite(value) || value < 0.0 || (value == 0.0 && !zero)) {
          const double given = value;
          value = fallback;
          throw ConfigError(a.location_of(key), fmt::format("'{}' = {} {} must be {} 0 {}", key,
                                                            given, unit, zero ? ">=" : ">", unit));
        }
      });
      return value;
    };
    height_ = number("letter_height", 0.04, "m", false);
    width_ = number("letter_width", 0.03, "m", false);
    spacing_ = number("spacing", 0.012, "m", true);
    depth_ = number("depth", 0.002, "m", true);
    lift_ = number("lift", 0.01, "m", false);
    cutter_ = number("cutter", 0.15, "m", true);
    speed_ = number("speed", 0.06, "m/s", false);
    tolerance_ = number("tolerance", 0.001, "m", false);
    acceleration_ = number("acceleration", 1.0, "m/s^2", false);
    errors.run(a.location_of("servo_algorithm"),
               [&] { servo_algorithm_ = a.get_int("servo_algorithm", 1); });
    errors.run(a.location(), [&] { a.reject_unread("robot.ecp.args"); });
    errors.throw_if_any();
  }

  void main_task() override {
    Robot& robot = context_.robot;
    robot.synchronise();
    // Servo algorithm 1 (velocity feed-forward) where the plugin has it: the cutter follows
    // the strokes without the lag of a plain position servo.
    {
      edp::Instruction& c = robot.image().command;
      c = edp::Instruction{};
      c.type = edp::InstructionType::set;
      c.set = edp::item::servo;
      c.servo_algorithm.assign(robot.model().axes(), static_cast<std::int8_t>(servo_algorithm_));
      c.servo_parameters_no.assign(robot.model().axes(), 0);
      robot.execute();
    }
    auto kinematics = edp::make_arm_kinematics(robot.model());
    Eigen::Isometry3d tool = Eigen::Isometry3d::Identity();
    tool.translation() = Eigen::Vector3d(0, 0, cutter_);
    kinematics->set_tool(tool);
    // Keep the cutter's orientation of the synchronisation pose (pointing down) all the way.
    const Eigen::Matrix3d down = kinematics->forward(robot.image().desired_joints).linear();

    std::vector<std::pair<Eigen::Vector3d, Eigen::Vector3d>> cuts;  // intended, at depth
    std::vector<std::vector<double>> samples;
    const engraving::TextLayout layout{origin_, height_, width_, spacing_};
    int letter = -1;
    for (char c : text_) {
      ++letter;
      const std::vector<engraving::Stroke>* strokes = engraving::letter_strokes(c);
      if (strokes == nullptr) continue;  // a space
      std::vector<CartesianSegment> segments;
      auto at = [&](const Eigen::Vector2d& p, double dz) {
        Eigen::Isometry3d f = Eigen::Isometry3d::Identity();
        f.linear() = down;
        f.translation() = engraving::place(layout, letter, p) + Eigen::Vector3d(0, 0, dz);
        return f;
      };
      for (const engraving::Stroke& stroke : *strokes) {
        segments.push_back(CartesianSegment::line_to(at(stroke.front(), lift_)));
        segments.push_back(CartesianSegment::line_to(at(stroke.front(), -depth_)));
        for (std::size_t i = 1; i < stroke.size(); ++i) {
          segments.push_back(CartesianSegment::line_to(at(stroke[i], -depth_)));
          cuts.emplace_back(at(stroke[i - 1], -depth_).translation(),
                            at(stroke[i], -depth_).translation());
        }
        segments.push_back(CartesianSegment::line_to(at(stroke.back(), lift_)));
      }
      CartesianOptions options;
      options.tool = tool;
      options.max_linear_velocity = speed_;
      options.max_linear_acceleration = acceleration_;
      options.servo_period_s = context_.servo_period_s;
      CartesianPathGenerator generator(robot.model(), segments, options);
      Recording recording(generator, samples);
      Move(robot, {}, recording);
      context_.reporter.info(
          fmt::format("letter '{}' engraved{}", c,
                      recording.resumes() > 0
                          ? fmt::format("; resumed from rest {} time(s) after a late macro-step",
                                        recording.resumes())
                          : ""));
    }

    // Wherever the cutter is in the wood (below half the depth), its tip must lie on an
    // intended stroke, in the board's plane (the groove's path; plunges and lifts are vertical).
    double worst = 0.0;
    int cutting = 0;
    auto flat = [](Eigen::Vector3d v) {
      v.z() = 0.0;
      return v;
    };
    for (const auto& q : samples) {
      const Eigen::Vector3d tip = kinematics->forward(q).translation();
      if (tip.z() > origin_.z() - depth_ / 2) continue;
      ++cutting;
      double nearest = 1e9;
      for (const auto& [a, b] : cuts)
        nearest = std::min(nearest, distance_to_segment(flat(tip), flat(a), flat(b)));
      worst = std::max(worst, nearest);
    }
    context_.reporter.info(fmt::format(
        "engraved '{}': {} strokes, {} cutting samples, cutter tip within {:.3f} mm of the "
        "strokes in the board's plane (tolerance {:.3f} mm)",
        text_, cuts.size(), cutting, worst * 1e3, tolerance_ * 1e3));
    if (cutting == 0) throw FatalError("the cutter never reached the cutting depth");
    if (worst > tolerance_)
      throw FatalError(
          fmt::format("the engraving left its strokes by {:.3f} mm (tolerance {:.3f} "
                      "mm)",
                      worst * 1e3, tolerance_ * 1e3));
  }

 private:
  TaskContext& context_;
  std::string text_;
  Eigen::Vector3d origin_ = Eigen::Vector3d::Zero();
  double height_ = 0.0, width_ = 0.0, spacing_ = 0.0, depth_ = 0.0, lift_ = 0.0, cutter_ = 0.0,
         speed_ = 0.0, tolerance_ = 0.0, acceleration_ = 0.0;
  std::int64_t servo_algorithm_ = 1;
};

MRROC_REGISTER_ECP_TASK("engrave", Engrave);

}  // namespace mrroc::ecp
