#include "mrroc/mp/robot.hpp"

#include <atomic>

#include <fmt/format.h>

#include <chrono>
#include <cmath>
#include <exception>
#include <optional>
#include <thread>

#include "mrroc/comm/edge.hpp"
#include "mrroc/comm/links.hpp"
#include "mrroc/config/process_set.hpp"
#include "mrroc/core/process.hpp"
#include "mrroc/mp/task.hpp"
#include "mrroc/msg/edp_instruction.hpp"
#include "mrroc/msg/robot_state.hpp"

namespace mrroc::mp {

EcpFailed::EcpFailed(const std::string& robot, const ecp::EcpReply& reply)
    : RemoteError(reply.error_code, fmt::format("ecp/{}: {}", robot, reply.error_text),
                  reply.error_class) {}

/// The two request/reply clients of the MP's link to one ECP.
struct Robot::Links {
  Links(comm::Bus& bus, const std::string& robot_name)
      : command(bus, "mp", "ECP " + robot_name, channels::ecp_command(robot_name),
                channels::ecp_reply(robot_name)),
        control(bus, "mp-control", "ECP " + robot_name, channels::ecp_command(robot_name),
                channels::ecp_reply(robot_name),
                comm::ClientOptions{std::chrono::milliseconds(100), 10, {}}),
        states(bus, channels::robot_state(robot_name),
               [this](const RobotState& s, const comm::Received& in) {
                 if (!in.authentic()) return;
                 std::lock_guard lock(mutex);
                 if (!latest || s.servo_step >= latest->servo_step) latest = s;
               }) {}
  comm::EcpClient command;  ///< START_TASK, NEXT_STATE, NEXT_POSE, END_MOTION
  comm::EcpClient control;  ///< STOP, PAUSE, RESUME (never queued behind a running task)
  /// The ECP did not answer a STOP: while the stop lasts, commands to it are not sent (each
  /// would wait its 12 attempts of 250 ms); cleared by the next answered command.
  std::atomic<bool> silent_at_stop{false};
  std::mutex mutex;
  std::optional<RobotState> latest;  ///< the newest state of the EDP's broadcast
  comm::Subscriber<RobotState> states;
};

Robot::Robot(comm::Bus& bus, const std::string& robot_name)
    : links_(std::make_unique<Links>(bus, robot_name)) {
  image_.name = robot_name;
}

Robot::~Robot() = default;

ecp::EcpReply Robot::checked(const ecp::EcpReply& reply) {
  image_.synchronised = reply.synchronised;
  if (!reply.joints.empty()) image_.joints = reply.joints;
  if (!reply.desired_joints.empty()) image_.desired_joints = reply.desired_joints;
  if (reply.type == ecp::EcpReplyType::error) throw EcpFailed(image_.name, reply);
  return reply;
}

namespace {
bool stopping();
}  // namespace

ecp::EcpReply Robot::command(const ecp::MpCommand& c) {
  const auto silent = [this] {
    return ecp::TaskStopped(fmt::format(
        "MP stopped on request; ecp/{} did not answer its STOP, its reply is not awaited",
        image_.name));
  };
  if (links_->silent_at_stop.load() && stopping()) throw silent();
  try {
    ecp::EcpReply reply = links_->command.call(c);
    links_->silent_at_stop.store(false);
    return reply;
  } catch (const CallAbandoned&) {
    throw silent();
  }
}

void Robot::start_task() {
  ecp::MpCommand c;
  c.type = ecp::MpCommandType::start_task;
  checked(command(c));
}

void Robot::next_state(const std::string& state, const std::string& arguments) {
  ecp::MpCommand c;
  c.type = ecp::MpCommandType::next_state;
  c.state_name = state;
  c.arguments = arguments;
  checked(command(c));
}

void Robot::next_pose() {
  ecp::MpCommand c = image_.command;
  c.type = ecp::MpCommandType::next_pose;
  const ecp::EcpReply r = checked(command(c));
  image_.arm_type = r.arm_type;
  image_.arm = r.arm;
}

void Robot::end_motion() {
  ecp::MpCommand c;
  c.type = ecp::MpCommandType::end_motion;
  checked(command(c));
}

ecp::EcpReply Robot::control(ecp::MpCommandType type) {
  // Operator commands come from other threads than the task's: they do not touch the image.
  ecp::MpCommand c;
  c.type = type;
  const ecp::EcpReply reply = links_->control.call(c);
  if (reply.type == ecp::EcpReplyType::error) throw EcpFailed(image_.name, reply);
  return reply;
}

RobotImage Robot::state_image() const {
  RobotImage image;
  image.name = image_.name;  // set once, in the constructor
  std::lock_guard lock(links_->mutex);
  if (!links_->latest) return image;
  const RobotState& s = *links_->latest;
  image.synchronised = s.synchronised;
  image.moving = s.moving;
  image.joints = s.q;
  image.desired_joints = s.q_desired;
  image.joint_velocities = s.dq;
  image.state_servo_step = s.servo_step;
  return image;
}

void Robot::stop() {
  try {
    control(ecp::MpCommandType::stop);
  } catch (const TimeoutError&) {
    // An ECP that does not answer its STOP will not answer the task's command either: end that
    // wait now, and send it nothing more while the stop lasts.
    links_->silent_at_stop.store(true);
    links_->command.abandon();
    throw;
  }
}
void Robot::pause() { control(ecp::MpCommandType::pause); }
void Robot::resume() { control(ecp::MpCommandType::resume); }

void parallel(const RobotList& robots, const std::function<void(Robot&)>& action) {
  std::vector<std::exception_ptr> errors(robots.size());
  std::vector<std::thread> threads;
  threads.reserve(robots.size());
  for (std::size_t i = 0; i < robots.size(); ++i)
    threads.emplace_back([&, i] {
      try {
        action(*robots[i]);
      } catch (...) {
        errors[i] = std::current_exception();
      }
    });
  for (auto& t : threads) t.join();
  for (auto& e : errors)
    if (e) std::rethrow_exception(e);
}

namespace {
std::atomic<bool> g_task_stop{false};

bool stopping() { return mrroc::stop_requested() || g_task_stop.load(); }

void refresh(const ecp::SensorList& sensors) {
  for (ecp::Sensor* s : sensors) s->initiate_reading();
  for (ecp::Sensor* s : sensors) s->get_reading();
}
}  // namespace

void request_task_stop() { g_task_stop.store(true); }
void clear_task_stop() { g_task_stop.store(false); }
bool task_stop_requested() { return g_task_stop.load(); }

namespace {
/// A refusal the generator may answer by re-planning from where the robots stand.
bool replannable(const EcpFailed& e) {
  return e.code() == edp::error_code::too_fast || e.code() == edp::error_code::too_abrupt;
}

/// The group stops together: every robot's motion ends (its EDP finishes what it queued and comes
/// to rest), then Move waits until every EDP reports its robot still, and reads where each stands:
/// the joints its EDP holds it at, from the EDP's own state broadcast at rest (an ECP's reply to
/// the end of a motion may carry the joints of its last reading, from before the robot's ramp to
/// rest, and a resume planned from those started with a jump: refused as too abrupt, again and
/// again).
void stop_group(const RobotList& robots) {
  parallel(robots, [](Robot& r) { r.end_motion(); });
  constexpr auto kPoll = std::chrono::milliseconds(10);
  constexpr auto kLimit = std::chrono::seconds(5);
  const auto give_up = std::chrono::steady_clock::now() + kLimit;
  // A state broadcast after this moment (they come every 20 ms) that says still, for every robot.
  std::vector<std::int64_t> from;
  for (Robot* r : robots) from.push_back(r->state_image().state_servo_step);
  for (;;) {
    bool still = true;
    for (std::size_t i = 0; i < robots.size(); ++i) {
      const RobotImage s = robots[i]->state_image();
      still = still && s.state_servo_step > from[i] && !s.moving;
    }
    if (still) break;
    if (std::chrono::steady_clock::now() >= give_up)
      throw Error(fmt::format("the robots did not come to rest within {} s after a refusal",
                              kLimit.count()));
    std::this_thread::sleep_for(kPoll);
  }
  parallel(robots, [](Robot& r) { r.end_motion(); });
  for (Robot* r : robots) {
    const RobotImage s = r->state_image();
    if (!s.desired_joints.empty()) r->image().desired_joints = s.desired_joints;
    if (!s.joints.empty()) r->image().joints = s.joints;
  }
}
}  // namespace

void Move(const RobotList& robots, const ecp::SensorList& sensors, Generator& generator) {
  // Stops and resumptions a motion may take in a row; the count starts again only after the
  // resumed motion went on for kSettledSteps macro-steps (a resumption that is refused again a
  // step or two later is the same trouble, not a new one: counted, it cannot loop for ever).
  constexpr int kMaxRefusals = 3;
  constexpr int kSettledSteps = 25;
  int accepted = 0;
  ImageList images;
  for (Robot* r : robots) images.push_back(&r->image());
  refresh(sensors);
  for (RobotImage* image : images) image->commanded = false;
  if (!generator.first_step(images, sensors)) return;
  int refusals = 0;
  try {
    for (;;) {
      if (stopping()) throw ecp::TaskStopped("MP stopped on request");
      RobotList step;
      for (Robot* r : robots)
        if (r->image().commanded) step.push_back(r);
      try {
        parallel(step, [](Robot& r) { r.next_pose(); });
        if (!step.empty() && ++accepted >= kSettledSteps) refusals = 0;
      } catch (const EcpFailed& e) {
        // A robot had to stop for want of macro-steps and the planned continuation is too fast
        // or too abrupt from where it stands: the whole group stops and resumes from rest.
        if (!replannable(e) || ++refusals > kMaxRefusals) throw;
        accepted = 0;
        const std::exception_ptr refusal = std::current_exception();
        try {
          stop_group(robots);
        } catch (...) {
          std::rethrow_exception(refusal);  // the refusal says what happened first
        }
        for (RobotImage* image : images) image->commanded = false;
        refresh(sensors);
        if (!generator.resume(images, sensors)) std::rethrow_exception(refusal);
        continue;
      }
      refresh(sensors);
      for (RobotImage* image : images) image->commanded = false;
      if (!generator.next_step(images, sensors)) break;
    }
  } catch (...) {
    // Leave no robot half-way in a continuous motion: end it on every robot that still answers.
    for (Robot* r : robots) {
      try {
        r->end_motion();
      } catch (...) {
      }
    }
    throw;
  }
  parallel(robots, [](Robot& r) { r.end_motion(); });
}

void Wait(const RobotList& robots, const ecp::SensorList& sensors, Condition& condition,
          double period_s, double timeout_s) {
  std::vector<RobotImage> states(robots.size());
  ImageList images;
  for (RobotImage& s : states) images.push_back(&s);
  const auto start = std::chrono::steady_clock::now();
  for (;;) {
    if (stopping()) throw ecp::TaskStopped("MP stopped on request");
    refresh(sensors);
    for (std::size_t i = 0; i < robots.size(); ++i) states[i] = robots[i]->state_image();
    if (condition.check(images, sensors)) return;
    const double waited =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    if (waited >= timeout_s)
      throw TimeoutError(fmt::format("MP Wait: the condition did not hold within {} s", timeout_s));
    std::this_thread::sleep_for(std::chrono::duration<double>(period_s));
  }
}

Running::Running(const RobotList& robots, std::function<void(Robot&)> action) {
  slots_.resize(robots.size());
  for (std::size_t i = 0; i < robots.size(); ++i) slots_[i].robot = robots[i];
  threads_.reserve(robots.size());
  for (std::size_t i = 0; i < robots.size(); ++i)
    threads_.emplace_back([this, i, action] {
      std::exception_ptr error;
      try {
        action(*slots_[i].robot);
      } catch (...) {
        error = std::current_exception();
      }
      std::lock_guard lock(mutex_);
      slots_[i].done = true;
      slots_[i].error = error;
      order_.push_back(i);
      ended_.notify_all();
    });
}

Running::~Running() {
  for (auto& t : threads_)
    if (t.joinable()) t.join();
}

Robot& Running::wait_any(double timeout_s) {
  std::unique_lock lock(mutex_);
  const auto next = [&]() -> Slot* {
    for (std::size_t i : order_)
      if (!slots_[i].returned) return &slots_[i];
    return nullptr;
  };
  bool all_returned = true;
  for (const Slot& s : slots_) all_returned = all_returned && s.returned;
  if (all_returned) throw Error("mp::Running::wait_any: every robot's function already ended");
  const auto ready = [&] { return next() != nullptr; };
  if (std::isinf(timeout_s)) {
    ended_.wait(lock, ready);
  } else if (!ended_.wait_for(lock, std::chrono::duration<double>(timeout_s), ready)) {
    throw TimeoutError(
        fmt::format("mp::Running: no robot's function ended within {} s", timeout_s));
  }
  Slot* slot = next();
  slot->returned = true;
  if (slot->error) std::rethrow_exception(slot->error);
  return *slot->robot;
}

void Running::wait_all() {
  for (auto& t : threads_)
    if (t.joinable()) t.join();
  std::lock_guard lock(mutex_);
  std::exception_ptr first;
  for (std::size_t i : order_) {
    Slot& s = slots_[i];
    if (s.returned) continue;
    s.returned = true;
    if (s.error && !first) first = s.error;
  }
  if (first) std::rethrow_exception(first);
}

void Wait(const ecp::SensorList& sensors, ecp::Condition& condition, double period_s) {
  for (;;) {
    if (stopping()) throw ecp::TaskStopped("MP stopped on request");
    refresh(sensors);
    if (condition.check(sensors)) return;
    std::this_thread::sleep_for(std::chrono::duration<double>(period_s));
  }
}

}  // namespace mrroc::mp
