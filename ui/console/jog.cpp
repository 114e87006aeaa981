#include "console/jog.hpp"

#include <fmt/format.h>
#include <fmt/ranges.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <optional>
#include <thread>

#include "mrroc/ecp/robot_image.hpp"
#include "mrroc/msg/operator.hpp"

namespace mrroc::ui {

Jogger::Jogger(const ConsoleState& state, JogOptions options,
               std::map<std::string, std::unique_ptr<JogLink>> links, ReportFn report)
    : state_(state), options_(options), report_(std::move(report)) {
  for (auto& [name, link] : links) {
    auto l = std::make_unique<Link>();
    l->link = std::move(link);
    l->kinematics = edp::make_arm_kinematics(state_.robots()[state_.robot_index(name)].model);
    links_.emplace(name, std::move(l));
  }
}

bool Jogger::cartesian(const std::string& robot) const {
  const auto found = links_.find(robot);
  return found != links_.end() && found->second->kinematics->cartesian();
}

namespace {

constexpr const char* kToolAxes[] = {"x", "y", "z", "rx", "ry", "rz"};

}  // namespace

std::vector<double> Jogger::check(const JogRequest& request) const {
  const std::string& robot = request.robot;
  const std::size_t index = state_.robot_index(robot);
  const ConsoleRobot& info = state_.robots()[index];
  const bool tool = request.space == JogSpace::tool;
  const std::size_t axes = tool ? 6 : info.model.axes();
  if (request.axis < 0 || static_cast<std::size_t>(request.axis) >= axes)
    throw ApiError(
        400, tool ? fmt::format("tool axis {} is out of range 0..5 (x y z rx ry rz)", request.axis)
                  : fmt::format("axis {} is out of range: robot {} has axes 0..{}", request.axis,
                                robot, axes - 1));
  const double step = request.step;
  const auto a = static_cast<std::size_t>(request.axis);
  const char* unit = tool ? (a < 3 ? "m" : "rad") : info.model.unit(a);
  const double max_step = tool && a < 3 ? options_.max_step_m : options_.max_step_rad;
  if (!std::isfinite(step) || step <= 0.0 || step > max_step)
    throw ApiError(400,
                   fmt::format("jog step {} {} is outside (0, {}] {}", step, unit, max_step, unit));
  if (tool && !cartesian(robot))
    throw ApiError(409, fmt::format("tool jog refused: {} has no Cartesian kinematics (jog its "
                                    "joints)",
                                    robot));
  const RobotReading reading = check_ready(index, "jogging");
  if (!reading.state.synchronised && tool)
    throw ApiError(409, fmt::format("tool jog refused: {} is not synchronised (its position is "
                                    "unknown: press Synchronise; joint jogs work before it, at "
                                    "reduced limits)",
                                    robot));
  // Before SYNCHRO the EDP refuses a larger move ([robot.edp] unsynchronised_max_move).
  if (!reading.state.synchronised && step > info.unsynchronised_max_move)
    throw ApiError(400, fmt::format("jog step {} {} is outside (0, {}] {} while {} is not "
                                    "synchronised ([robot.edp] unsynchronised_max_move)",
                                    step, unit, info.unsynchronised_max_move, unit, robot));
  return reading.state.q;
}

RobotReading Jogger::check_ready(std::size_t index, const std::string& what) const {
  const std::string& robot = state_.robots()[index].name;
  // Only when the MP is known to rest (an allow-list): a robot at rest in the middle of a task
  // (between two motions, or paused) must not be taken over, and an MP that does not answer may
  // be running one.
  const std::optional<MpReading> answer = state_.mp_reading();
  if (!answer) {
    const std::string error = state_.mp_error();
    throw ApiError(409, fmt::format("{} refused: the MP's state is unknown (no answer from the "
                                    "MP{}): a task may be running; {} needs the MP answering "
                                    "and its task IDLE, FINISHED or FAILED",
                                    what, error.empty() ? " yet" : ": " + error, what));
  }
  if (!answer->fresh())
    throw ApiError(409, fmt::format("{} refused: the MP's state is unknown (no answer from the "
                                    "MP for {:.1f} s, limit {} s; the last said {}): a task may "
                                    "be running; {} needs the MP answering and its task IDLE, "
                                    "FINISHED or FAILED",
                                    what, answer->age_s(), kMpFreshS, answer->status.state, what));
  const std::string& task = answer->status.state;
  if (task == mp::to_string(mp::TaskState::running) ||
      task == mp::to_string(mp::TaskState::paused) ||
      task == mp::to_string(mp::TaskState::stopping))
    throw ApiError(409, fmt::format("{} refused: the MP task is {}; stop it first", what, task));
  if (task != mp::to_string(mp::TaskState::idle) &&
      task != mp::to_string(mp::TaskState::finished) &&
      task != mp::to_string(mp::TaskState::failed))
    throw ApiError(409, fmt::format("{} refused: the MP task is {}; {} needs it IDLE, FINISHED "
                                    "or FAILED",
                                    what, task, what));
  const std::optional<RobotReading> reading = state_.reading(index);
  if (!reading || !reading->fresh())
    throw ApiError(409, fmt::format("{} refused: no robot_state_t from EDP {} in the last {} s",
                                    what, robot, kStateFreshS));
  const auto& s = reading->state;
  if (s.estop)
    throw ApiError(409, fmt::format("{} refused: the emergency stop of {} is engaged; release "
                                    "it first",
                                    what, robot));
  if (s.fault)
    throw ApiError(409,
                   fmt::format("{} refused: {} has a hardware fault: {}", what, robot, s.error));
  if (s.moving) throw ApiError(409, fmt::format("{} refused: {} is moving", what, robot));
  return *reading;
}

Jogger::Link& Jogger::link_of(const std::string& robot, const std::string& what) const {
  const auto found = links_.find(robot);
  if (found == links_.end())
    throw ApiError(409, fmt::format("{} refused: the console has no EDP link to {}", what, robot));
  return *found->second;
}

JogResult Jogger::synchronise(const std::string& robot) {
  const std::size_t index = state_.robot_index(robot);
  const RobotReading reading = check_ready(index, "synchronisation");
  if (reading.state.synchronised)
    return JogResult{fmt::format("{} is already synchronised", robot), reading.state.q,
                     reading.state.q, 0};
  Link& link = link_of(robot, "synchronisation");
  std::unique_lock lock(link.busy, std::try_to_lock);
  if (!lock.owns_lock())
    throw ApiError(409, fmt::format("synchronisation refused: a jog or synchronisation of {} is "
                                    "in progress",
                                    robot));
  report_(Severity::info, fmt::format("operator synchronises {}", robot));
  std::vector<double> after;
  SteadyClock::time_point done{};
  try {
    after = link.link->synchronise();
    done = SteadyClock::now();
  } catch (const JogRefused& e) {
    report_(Severity::warning,
            fmt::format("operator synchronisation of {} refused: {}", robot, e.what()));
    throw ApiError(409, e.what());
  } catch (const TimeoutError& e) {
    throw ApiError(504, e.what());
  }
  for (int i = 0; i < 10 && !state_.at_rest_since(index, done); ++i)
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  const std::string text =
      fmt::format("{} synchronised at [{:.4f}]", robot, fmt::join(after, ", "));
  report_(Severity::info, "operator synchronisation: " + text);
  return JogResult{text, after, reading.state.q, 0};
}

JogResult Jogger::jog(const JogRequest& request) {
  const std::vector<double> q = check(request);
  const std::string& robot = request.robot;
  const std::size_t index = state_.robot_index(robot);
  const ConsoleRobot& info = state_.robots()[index];
  // check() passed a robot that is not synchronised for a joint jog only.
  const std::optional<RobotReading> before = state_.reading(index);
  const bool synchronised = before && before->state.synchronised;
  Link& link = link_of(robot, "jogging");
  std::unique_lock jog_lock(link.busy, std::try_to_lock);
  if (!jog_lock.owns_lock())
    throw ApiError(409, fmt::format("jogging refused: a jog or synchronisation of {} is in "
                                    "progress",
                                    robot));
  if (request.space == JogSpace::tool) return jog_tool(request, q);
  const auto a = static_cast<std::size_t>(request.axis);
  const double step = request.step;
  const int direction = request.direction;
  // One macro-step from rest to rest; the EDP accelerates uniformly over its first half and
  // decelerates over its second (docs/edp.md, "Acceleration"), so the velocity peaks at 2 d / T
  // and the acceleration is 4 d / T^2: T keeps both within velocity_fraction of the axis'
  // limits (and lasts at least min_duration_s).
  const double period = info.servo_period_s;
  std::vector<double> delta(info.model.axes(), 0.0);
  delta[a] = step;
  const double fraction = synchronised
                              ? options_.velocity_fraction
                              : std::min(options_.velocity_fraction, info.unsynchronised_fraction);
  const int steps =
      ecp::rest_to_rest_steps(info.model, delta, fraction, period, options_.min_duration_s);
  delta[a] = direction * step;
  const std::string joint = info.model.joint_names[a];
  std::vector<double> after;
  SteadyClock::time_point jog_done{};
  try {
    after = link.link->move_joints_relative(delta, steps);
    jog_done = SteadyClock::now();
  } catch (const JogRefused& e) {
    report_(Severity::warning,
            fmt::format("operator {}jog of {} axis {} ({}) by {:+.4f} {} refused: {}",
                        synchronised ? "" : "UNSYNCHRONISED ", robot, request.axis, joint,
                        direction * step, info.model.unit(a), e.what()));
    throw ApiError(409, e.what());
  } catch (const TimeoutError& e) {
    throw ApiError(504, e.what());
  }
  // Answer once the EDP's broadcast shows the robot at rest (the next jog is then allowed).
  for (int i = 0; i < 10 && !state_.at_rest_since(index, jog_done); ++i)
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  std::string text =
      fmt::format("{} axis {} ({}) moved {:+.4f} {} in {} servo steps ({:.3f} s): {:.4f} {}", robot,
                  request.axis, joint, direction * step, info.model.unit(a), steps, steps * period,
                  a < after.size() ? after[a] : std::nan(""), info.model.unit(a));
  if (!synchronised)
    text = fmt::format(
        "UNSYNCHRONISED: {} (raw axis position; at most {:.2f} of the axis' "
        "limits until SYNCHRO)",
        text, fraction);
  report_(Severity::info, "operator jog: " + text);
  return JogResult{text, after, q, steps, synchronised};
}

// Called with the robot's link locked (jog()).
JogResult Jogger::jog_tool(const JogRequest& request, const std::vector<double>& q) {
  const std::string& robot = request.robot;
  const std::size_t index = state_.robot_index(robot);
  const ConsoleRobot& info = state_.robots()[index];
  Link& link = *links_.at(robot);
  const auto a = static_cast<std::size_t>(request.axis);
  const double signed_step = request.direction * request.step;
  const char* unit = a < 3 ? "m" : "rad";
  // The move as the EDP makes it: goal = FK(end) * delta, delta in the tool frame; the joints'
  // change sets the duration (the same rest-to-rest bound as a joint jog).
  std::vector<double> delta(6, 0.0);
  delta[a] = signed_step;
  Eigen::Isometry3d move = Eigen::Isometry3d::Identity();
  if (a < 3)
    move.translation()[static_cast<Eigen::Index>(a)] = signed_step;
  else
    move.linear() =
        Eigen::AngleAxisd(signed_step, Eigen::Vector3d::Unit(static_cast<Eigen::Index>(a - 3)))
            .toRotationMatrix();
  std::vector<double> goal;
  try {
    goal = link.kinematics->inverse(link.kinematics->forward(q) * move, q);
  } catch (const Error& e) {
    throw ApiError(409, fmt::format("tool jog refused: {} {} by {:+.4f} {}: {}", robot,
                                    kToolAxes[a], signed_step, unit, e.what()));
  }
  std::vector<double> joint_delta(q.size());
  for (std::size_t j = 0; j < q.size(); ++j) joint_delta[j] = goal[j] - q[j];
  const double period = info.servo_period_s;
  const int steps = ecp::rest_to_rest_steps(info.model, joint_delta, options_.velocity_fraction,
                                            period, options_.min_duration_s);
  std::vector<double> after;
  SteadyClock::time_point done{};
  try {
    after = link.link->move_tool_relative(delta, steps);
    done = SteadyClock::now();
  } catch (const JogRefused& e) {
    report_(Severity::warning, fmt::format("operator tool jog of {} {} by {:+.4f} {} refused: {}",
                                           robot, kToolAxes[a], signed_step, unit, e.what()));
    throw ApiError(409, e.what());
  } catch (const TimeoutError& e) {
    throw ApiError(504, e.what());
  }
  for (int i = 0; i < 10 && !state_.at_rest_since(index, done); ++i)
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  const std::string text = fmt::format(
      "{} tool {} moved {:+.4f} {} in {} servo steps ({:.3f} s): joints [{:.4f}]", robot,
      kToolAxes[a], signed_step, unit, steps, steps * period, fmt::join(after, ", "));
  report_(Severity::info, "operator jog: " + text);
  return JogResult{text, after, q, steps};
}

}  // namespace mrroc::ui
