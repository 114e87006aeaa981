#include "console/jog.hpp"

#include <fmt/format.h>
#include <fmt/ranges.h>

#include <chrono>
#include <cmath>
#include <thread>

#include "mrroc/ecp/robot_image.hpp"

namespace mrroc::ui {

Jogger::Jogger(const ConsoleState& state, JogOptions options,
               std::map<std::string, std::unique_ptr<JogLink>> links, ReportFn report)
    : state_(state), options_(options), report_(std::move(report)) {
  for (auto& [name, link] : links) {
    auto l = std::make_unique<Link>();
    l->link = std::move(link);
    links_.emplace(name, std::move(l));
  }
}

std::vector<double> Jogger::check(const JogRequest& request) const {
  const std::string& robot = request.robot;
  const std::size_t index = state_.robot_index(robot);
  const ConsoleRobot& info = state_.robots()[index];
  const std::size_t axes = info.model.axes();
  if (request.axis < 0 || static_cast<std::size_t>(request.axis) >= axes)
    throw ApiError(400, fmt::format("axis {} is out of range: robot {} has axes 0..{}",
                                    request.axis, robot, axes - 1));
  const double step = request.step_rad;
  const char* unit = info.model.unit(static_cast<std::size_t>(request.axis));
  if (!std::isfinite(step) || step <= 0.0 || step > options_.max_step_rad)
    throw ApiError(400, fmt::format("jog step {} {} is outside (0, {}] {}", step, unit,
                                    options_.max_step_rad, unit));
  const RobotReading reading = check_ready(index, "jogging");
  if (!reading.state.synchronised)
    throw ApiError(409, fmt::format("jogging refused: {} is not synchronised (press "
                                    "Synchronise, or run a task: its ECP synchronises the robot)",
                                    robot));
  return reading.state.q;
}

RobotReading Jogger::check_ready(std::size_t index, const std::string& what) const {
  const std::string& robot = state_.robots()[index].name;
  if (const auto mp = state_.mp();
      mp && (mp->state == "RUNNING" || mp->state == "PAUSED" || mp->state == "STOPPING"))
    throw ApiError(409,
                   fmt::format("{} refused: the MP task is {}; stop it first", what, mp->state));
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
  Link& link = link_of(robot, "jogging");
  std::unique_lock jog_lock(link.busy, std::try_to_lock);
  if (!jog_lock.owns_lock())
    throw ApiError(409, fmt::format("jogging refused: a jog or synchronisation of {} is in "
                                    "progress",
                                    robot));
  const auto a = static_cast<std::size_t>(request.axis);
  const double step = request.step_rad;
  const int direction = request.direction;
  // One macro-step from rest to rest; the EDP accelerates uniformly over its first half and
  // decelerates over its second (docs/edp.md, "Acceleration"), so the velocity peaks at 2 d / T
  // and the acceleration is 4 d / T^2: T keeps both within velocity_fraction of the axis'
  // limits (and lasts at least min_duration_s).
  const double period = info.servo_period_s;
  std::vector<double> delta(info.model.axes(), 0.0);
  delta[a] = step;
  const int steps = ecp::rest_to_rest_steps(info.model, delta, options_.velocity_fraction, period,
                                            options_.min_duration_s);
  delta[a] = direction * step;
  const std::string joint = info.model.joint_names[a];
  std::vector<double> after;
  SteadyClock::time_point jog_done{};
  try {
    after = link.link->move_joints_relative(delta, steps);
    jog_done = SteadyClock::now();
  } catch (const JogRefused& e) {
    report_(Severity::warning,
            fmt::format("operator jog of {} axis {} ({}) by {:+.4f} {} refused: {}", robot,
                        request.axis, joint, direction * step, info.model.unit(a), e.what()));
    throw ApiError(409, e.what());
  } catch (const TimeoutError& e) {
    throw ApiError(504, e.what());
  }
  // Answer once the EDP's broadcast shows the robot at rest (the next jog is then allowed).
  for (int i = 0; i < 10 && !state_.at_rest_since(index, jog_done); ++i)
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  const std::string text =
      fmt::format("{} axis {} ({}) moved {:+.4f} {} in {} servo steps ({:.3f} s): {:.4f} {}", robot,
                  request.axis, joint, direction * step, info.model.unit(a), steps, steps * period,
                  a < after.size() ? after[a] : std::nan(""), info.model.unit(a));
  report_(Severity::info, "operator jog: " + text);
  return JogResult{text, after, q, steps};
}

}  // namespace mrroc::ui
