#include "console/jog.hpp"

#include <fmt/format.h>

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
  if (!std::isfinite(step) || step <= 0.0 || step > options_.max_step_rad)
    throw ApiError(
        400, fmt::format("jog step {} rad is outside (0, {}] rad", step, options_.max_step_rad));
  if (const auto mp = state_.mp();
      mp && (mp->state == "RUNNING" || mp->state == "PAUSED" || mp->state == "STOPPING"))
    throw ApiError(409,
                   fmt::format("jogging refused: the MP task is {}; stop it first", mp->state));
  const std::optional<RobotReading> reading = state_.reading(index);
  if (!reading || !reading->fresh())
    throw ApiError(409, fmt::format("jogging refused: no robot_state_t from EDP {} in the "
                                    "last {} s",
                                    robot, kStateFreshS));
  const auto& s = reading->state;
  if (s.estop)
    throw ApiError(409, fmt::format("jogging refused: the emergency stop of {} is engaged; "
                                    "release it first",
                                    robot));
  if (s.fault)
    throw ApiError(409,
                   fmt::format("jogging refused: {} has a hardware fault: {}", robot, s.error));
  if (!s.synchronised)
    throw ApiError(409, fmt::format("jogging refused: {} is not synchronised (run a task "
                                    "first: its ECP synchronises the robot)",
                                    robot));
  if (s.moving) throw ApiError(409, fmt::format("jogging refused: {} is moving", robot));
  return s.q;
}

JogResult Jogger::jog(const JogRequest& request) {
  const std::vector<double> q = check(request);
  const std::string& robot = request.robot;
  const std::size_t index = state_.robot_index(robot);
  const ConsoleRobot& info = state_.robots()[index];
  const auto found = links_.find(robot);
  if (found == links_.end())
    throw ApiError(409, fmt::format("jogging refused: the console has no EDP link to {}", robot));
  Link& link = *found->second;
  std::unique_lock jog_lock(link.busy, std::try_to_lock);
  if (!jog_lock.owns_lock())
    throw ApiError(409, fmt::format("jogging refused: a jog of {} is in progress", robot));
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
            fmt::format("operator jog of {} axis {} ({}) by {:+.4f} rad refused: {}", robot,
                        request.axis, joint, direction * step, e.what()));
    throw ApiError(409, e.what());
  } catch (const TimeoutError& e) {
    throw ApiError(504, e.what());
  }
  // Answer once the EDP's broadcast shows the robot at rest (the next jog is then allowed).
  for (int i = 0; i < 10 && !state_.at_rest_since(index, jog_done); ++i)
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  const std::string text =
      fmt::format("{} axis {} ({}) moved {:+.4f} rad in {} servo steps ({:.3f} s): {:.4f} rad",
                  robot, request.axis, joint, direction * step, steps, steps * period,
                  a < after.size() ? after[a] : std::nan(""));
  report_(Severity::info, "operator jog: " + text);
  return JogResult{text, after, q, steps};
}

}  // namespace mrroc::ui
