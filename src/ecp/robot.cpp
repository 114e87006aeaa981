#include "mrroc/ecp/robot.hpp"

#include <algorithm>
#include <cmath>

#include "mrroc/kinematics/pose.hpp"
#include "mrroc/robot/rest_to_rest.hpp"

namespace mrroc::ecp {

int rest_to_rest_steps(const RobotModel& model, const std::vector<double>& delta, double fraction,
                       double period_s, double min_s) {
  double duration = min_s;
  for (std::size_t j = 0; j < delta.size() && j < model.axes(); ++j)
    duration = std::max(duration, rest_to_rest_duration(delta[j], fraction * model.max_velocity[j],
                                                        fraction * model.max_acceleration[j]));
  return std::max(1, static_cast<int>(std::ceil(duration / period_s - 1e-9)));
}

Robot::Robot(comm::Bus& bus, const std::string& process_name, const std::string& robot_name,
             RobotModel model, edp::ClientOptions options)
    : name_(robot_name),
      model_(std::move(model)),
      kinematics_(edp::make_arm_kinematics(model_)),
      client_(bus, process_name, robot_name, options) {}

Robot::Robot(comm::Bus& bus, const std::string& process_name, const std::string& robot_name,
             RobotModel model, const comm::ClientOptions& options)
    : name_(robot_name),
      model_(std::move(model)),
      kinematics_(edp::make_arm_kinematics(model_)),
      client_(bus, process_name, robot_name, options) {}

edp::Reply Robot::exchange(const edp::Instruction& instruction) {
  try {
    return client_.call(instruction);
  } catch (const CallAbandoned& e) {
    // request_stop() ended the wait: a STOP does not wait for a silent EDP's last attempts.
    throw TaskStopped(std::string("task stopped on request (") + e.what() + ")");
  }
}

void Robot::update_image(const edp::Reply& reply, std::uint8_t asked) {
  image_.synchronised = reply.synchronised;
  image_.joints = reply.joints;
  image_.desired_joints = reply.desired_joints;
  image_.joint_velocities = reply.joint_velocities;
  image_.step_no = reply.step_no;
  image_.macro_steps_ahead = reply.macro_steps_ahead;
  image_.servo_cycle = reply.servo_cycle;
  image_.arm_type = reply.arm_type;
  image_.arm = reply.arm;
  if ((asked & edp::item::tool) != 0 && !reply.tool.empty()) {
    image_.tool = kinematics::from_vector(reply.tool, reply.tool_type);
    kinematics_->set_tool(*image_.tool);
  }
  if ((asked & edp::item::model) != 0) {
    image_.kinematic_model_no = reply.kinematic_model_no;
    image_.corrector_no = reply.corrector_no;
    kinematics_->select_model(reply.kinematic_model_no, reply.corrector_no);
  }
  if ((asked & edp::item::servo) != 0) {
    image_.servo_algorithm = reply.servo_algorithm;
    image_.servo_parameters_no = reply.servo_parameters_no;
  }
  if ((asked & edp::item::inputs) != 0) image_.inputs = reply.input_values;
  if ((asked & edp::item::device) != 0) {
    image_.device = reply.device;
    read_device_reply(reply.device);
  }
  if ((asked & edp::item::timing) != 0)
    image_.timing =
        ServoTiming{reply.servo_cycles,    reply.servo_overruns,  reply.servo_period_us,
                    reply.lateness_p50_us, reply.lateness_p99_us, reply.lateness_max_us};
}

void Robot::follow_settings(const edp::Instruction& sent) {
  const bool sets =
      sent.type == edp::InstructionType::set || sent.type == edp::InstructionType::set_get;
  if (!sets) return;
  if ((sent.set & edp::item::tool) != 0) {
    image_.tool = kinematics::from_vector(sent.tool, sent.tool_type);
    kinematics_->set_tool(*image_.tool);
  }
  if ((sent.set & edp::item::model) != 0) {
    kinematics_->select_model(sent.kinematic_model_no, sent.corrector_no);
    image_.kinematic_model_no = sent.kinematic_model_no;
    image_.corrector_no = sent.corrector_no;
  }
}

void Robot::request_stop() {
  stop_.store(true);
  client_.abandon();
  std::lock_guard lock(pause_mutex_);
  pause_cv_.notify_all();
}

void Robot::pause() {
  std::lock_guard lock(pause_mutex_);
  paused_ = true;
}

void Robot::resume() {
  std::lock_guard lock(pause_mutex_);
  paused_ = false;
  pause_cv_.notify_all();
}

bool Robot::paused() const {
  std::lock_guard lock(pause_mutex_);
  return paused_;
}

bool Robot::wait_while_paused() {
  std::unique_lock lock(pause_mutex_);
  const bool waited = paused_ && !stop_.load();
  pause_cv_.wait(lock, [&] { return !paused_ || stop_.load(); });
  if (stop_.load()) throw TaskStopped("task stopped on request");
  return waited;
}

std::vector<double> Robot::pose(edp::ArmRepresentation representation, bool desired) const {
  const std::vector<double>& q = desired ? image_.desired_joints : image_.joints;
  switch (representation) {
    case edp::ArmRepresentation::joint: return q;
    case edp::ArmRepresentation::motor: return kinematics_->motors_from_joints(q);
    default: return kinematics::to_vector(kinematics_->forward(q), representation);
  }
}

void Robot::execute() {
  const edp::Instruction& command = image_.command;
  const bool gets =
      command.type == edp::InstructionType::get || command.type == edp::InstructionType::set_get;
  const std::uint8_t asked = gets ? command.get : 0;
  const bool sets_device = (command.type == edp::InstructionType::set ||
                            command.type == edp::InstructionType::set_get) &&
                           (command.set & edp::item::device) != 0;
  if (!separate_query_ && command.type != edp::InstructionType::query) {
    edp::Instruction with_query = command;
    if (sets_device) write_device_command(with_query.device);
    with_query.with_query = true;
    const edp::Reply reply = exchange(with_query);
    follow_settings(with_query);  // accepted: the EDP uses them from now on
    update_image(reply, asked);
    return;
  }
  edp::Instruction sent = command;
  if (sets_device) write_device_command(sent.device);
  exchange(sent);
  follow_settings(sent);
  edp::Instruction query;
  query.type = edp::InstructionType::query;
  update_image(exchange(query), asked);
}

namespace {
/// GET ARM in JOINT coordinates, with the EDP's tool and model (so that pose() uses them).
edp::Instruction get_joints() {
  edp::Instruction get;
  get.type = edp::InstructionType::get;
  get.get = edp::item::arm | edp::item::tool | edp::item::model;
  get.get_arm_type = edp::ArmRepresentation::joint;
  return get;
}
}  // namespace

void Robot::read_state() {
  const edp::Instruction saved = image_.command;
  image_.command = get_joints();
  execute();
  image_.command = saved;
}

void Robot::announce_no_successor() noexcept {
  try {
    edp::Instruction get = get_joints();
    get.no_successor = true;
    get.with_query = true;
    (void)exchange(get);  // the image keeps the reading of the last macro-step
  } catch (...) {
  }
}

void Robot::synchronise() {
  read_state();
  if (image_.synchronised) return;
  const edp::Instruction saved = image_.command;
  image_.command = edp::Instruction{};
  image_.command.type = edp::InstructionType::synchro;
  execute();
  image_.command = saved;
}

}  // namespace mrroc::ecp
