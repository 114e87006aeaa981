#include "mrroc/ecp/generators/pass_through.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>

#include "mrroc/core/error.hpp"
#include "mrroc/kinematics/pose.hpp"

namespace mrroc::ecp {

void InstructionQueue::push(edp::Instruction instruction) {
  {
    std::lock_guard lock(mutex_);
    if (closed_) throw Error("instruction queue: push after close");
    queue_.push_back(std::move(instruction));
  }
  ready_.notify_one();
}

void InstructionQueue::close() {
  {
    std::lock_guard lock(mutex_);
    closed_ = true;
  }
  ready_.notify_all();
}

std::optional<edp::Instruction> InstructionQueue::pop(std::chrono::milliseconds timeout) {
  std::unique_lock lock(mutex_);
  if (!ready_.wait_for(lock, timeout, [&] { return closed_ || !queue_.empty(); }))
    throw TimeoutError(fmt::format("pass-through: no pose arrived within {} ms", timeout.count()));
  if (queue_.empty()) return std::nullopt;  // closed
  edp::Instruction next = std::move(queue_.front());
  queue_.pop_front();
  return next;
}

std::size_t InstructionQueue::size() const {
  std::lock_guard lock(mutex_);
  return queue_.size();
}

bool InstructionQueue::closed() const {
  std::lock_guard lock(mutex_);
  return closed_;
}

PassThroughGenerator::PassThroughGenerator(const RobotModel& model, InstructionSource source,
                                           PassThroughOptions options)
    : model_(model),
      kinematics_(edp::make_arm_kinematics(model)),
      source_(std::move(source)),
      options_(std::move(options)) {
  if (!source_) throw Error("pass-through: no instruction source");
  for (const auto r : options_.representations) {
    const bool cartesian = r == edp::ArmRepresentation::frame ||
                           r == edp::ArmRepresentation::xyz_euler_zyz ||
                           r == edp::ArmRepresentation::xyz_angle_axis;
    if (cartesian && !kinematics_->cartesian())
      throw Error(
          fmt::format("pass-through: representation {} needs Cartesian kinematics, robot "
                      "'{}' has none",
                      edp::to_string(r), model.name));
  }
}

PassThroughGenerator::PassThroughGenerator(const RobotModel& model, InstructionQueue& queue,
                                           std::chrono::milliseconds timeout,
                                           PassThroughOptions options)
    : PassThroughGenerator(
          model, [&queue, timeout] { return queue.pop(timeout); }, std::move(options)) {}

void PassThroughGenerator::validate(const edp::Instruction& in, std::size_t number,
                                    const std::vector<double>& desired_joints) {
  const auto fail = [&](int code, const std::string& text) {
    throw CommandError(code, fmt::format("pass-through pose {}: {}", number, text));
  };
  const auto bad = [&](const std::string& text) { fail(edp::error_code::bad_argument, text); };

  if (in.type != edp::InstructionType::set && in.type != edp::InstructionType::set_get)
    bad(fmt::format("instruction type {} is not SET or SET_GET", edp::to_string(in.type)));
  if ((in.set & edp::item::arm) == 0) bad("the instruction does not set the arm (item::arm)");
  const auto rep = in.set_arm_type;
  const bool joint_like =
      rep == edp::ArmRepresentation::joint || rep == edp::ArmRepresentation::motor;
  const bool cartesian = rep == edp::ArmRepresentation::frame ||
                         rep == edp::ArmRepresentation::xyz_euler_zyz ||
                         rep == edp::ArmRepresentation::xyz_angle_axis;
  if (!joint_like && !cartesian)
    bad(fmt::format("arm representation {} is unknown", static_cast<int>(rep)));
  const auto& accepted = options_.representations;
  if (!accepted.empty() && std::find(accepted.begin(), accepted.end(), rep) == accepted.end())
    bad(fmt::format("arm representation {} is not accepted here", edp::to_string(rep)));
  if (cartesian && !kinematics_->cartesian())
    bad(fmt::format("arm representation {} needs Cartesian kinematics, robot '{}' has none",
                    edp::to_string(rep), model_.name));
  if (in.motion_type != edp::MotionType::absolute && in.motion_type != edp::MotionType::relative)
    bad(fmt::format("motion type {} is unknown", static_cast<int>(in.motion_type)));
  const std::size_t expected = joint_like ? model_.axes() : kinematics::representation_size(rep);
  if (in.arm.size() != expected)
    bad(fmt::format("{} arm has {} values, {} expected", edp::to_string(rep), in.arm.size(),
                    expected));
  for (std::size_t i = 0; i < in.arm.size(); ++i)
    if (!std::isfinite(in.arm[i]))
      bad(fmt::format("{} arm value {} is not a finite number", edp::to_string(rep), i));
  if (in.motion_steps < 1 || in.motion_steps > 100000)
    bad(fmt::format("motion_steps {} is outside 1..100000", in.motion_steps));
  if (in.value_in_step_no < 1 || in.value_in_step_no > in.motion_steps + 1)
    bad(fmt::format("value_in_step_no {} is outside 1..{} (motion_steps + 1)", in.value_in_step_no,
                    in.motion_steps + 1));

  // Tool and model first, as the EDP applies them before the arm; undone if the arm is refused.
  const Eigen::Isometry3d old_tool = kinematics_->tool();
  const int old_model = kinematics_->model_no();
  const int old_corrector = kinematics_->corrector_no();
  try {
    if ((in.set & edp::item::model) != 0)
      kinematics_->select_model(in.kinematic_model_no, in.corrector_no);
    if ((in.set & edp::item::tool) != 0)
      kinematics_->set_tool(kinematics::from_vector(in.tool, in.tool_type));
    if (cartesian) (void)kinematics::from_vector(in.arm, rep);  // a FRAME must be a rotation
    if (options_.check_limits && in.motion_type == edp::MotionType::absolute) {
      std::vector<double> joints;
      if (rep == edp::ArmRepresentation::joint) {
        joints = in.arm;
      } else if (rep == edp::ArmRepresentation::motor) {
        kinematics_->check_motor_limits(in.arm, "target");
        joints = kinematics_->joints_from_motors(in.arm);
      } else {
        if (desired_joints.size() != model_.axes())
          bad("the robot image has no desired joint position to seed the inverse kinematics");
        joints = kinematics_->inverse(kinematics::from_vector(in.arm, rep), desired_joints);
      }
      kinematics_->check_joint_limits(joints, "target");
      kinematics_->check_motor_limits(kinematics_->motors_from_joints(joints), "target");
    }
  } catch (const CommandError& e) {
    kinematics_->select_model(old_model, old_corrector);
    kinematics_->set_tool(old_tool);
    if (std::string(e.what()).starts_with("pass-through pose")) throw;
    fail(e.code(), e.what());
  }
}

bool PassThroughGenerator::forward(RobotImage& robot) {
  std::optional<edp::Instruction> next = source_();
  if (!next) return false;
  validate(*next, forwarded_ + 1, robot.desired_joints);
  robot.command = std::move(*next);
  ++forwarded_;
  return true;
}

bool PassThroughGenerator::first_step(RobotImage& robot, const SensorList&) {
  forwarded_ = 0;
  return forward(robot);
}

bool PassThroughGenerator::next_step(RobotImage& robot, const SensorList&) {
  return forward(robot);
}

}  // namespace mrroc::ecp
