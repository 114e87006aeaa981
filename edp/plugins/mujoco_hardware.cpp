/// @file
/// The `mujoco` EDP hardware plugin (see mujoco_hardware.hpp).

#include "mujoco_hardware.hpp"

#include <algorithm>
#include <cmath>
#include <cstdarg>
#include <cstdio>
#include <optional>
#include <utility>

#include "mrroc/core/error.hpp"
#include "mrroc/sim/mujoco_support.hpp"
#include "mrroc/sim/robot_parameters.hpp"

namespace mrroc::edp {
namespace {

constexpr const char* kParamsTable = "robot.edp.params";

std::size_t index(int i) { return static_cast<std::size_t>(i); }

}  // namespace

MujocoHardware::~MujocoHardware() { release(); }

void MujocoHardware::release() noexcept {
  active_ = false;
  if (data_ != nullptr) {
    mj_deleteData(data_);
    data_ = nullptr;
  }
  if (model_ != nullptr) {
    mj_deleteModel(model_);
    model_ = nullptr;
  }
  axes_ = 0;
  substeps_ = 0;
}

void MujocoHardware::configure(const HardwareSetup& setup) {
  release();
  fault_[0] = '\0';

  // The plugin's own parameters (not a copy: a check collecting every unknown key sees them).
  const Params& params = setup.params;
  const bool gravity_compensation = params.get_bool("gravity_compensation", true);
  const std::string mjcf_param = params.get_string("mjcf", "");
  sim::PowerOnRequest power_on_request;
  if (params.has("initial_joint_positions")) {
    power_on_request.given = params.get_doubles("initial_joint_positions");
    power_on_request.given_where = params.location_of("initial_joint_positions");
  }
  params.reject_unread(kParamsTable);

  // parameters.toml of the robot: needed for the MJCF name and/or the synchronisation pose.
  const std::filesystem::path robot_file_path = setup.model_dir / "parameters.toml";
  std::optional<sim::RobotParameters> robot_file;
  const bool need_robot_file = mjcf_param.empty() || setup.synchro_positions.empty();
  if (need_robot_file || std::filesystem::exists(robot_file_path)) {
    if (!std::filesystem::exists(robot_file_path)) {
      throw ConfigError(SourceLocation{robot_file_path.string(), 0},
                        std::string("robot parameter file not found (") +
                            (mjcf_param.empty() ? "needed for robot.mjcf"
                                                : "needed for robot.synchro_joint_positions") +
                            ")");
    }
    robot_file = sim::read_robot_parameters(robot_file_path);
  }

  std::string mjcf_name = mjcf_param;
  if (mjcf_name.empty()) {
    if (!robot_file->mjcf || robot_file->mjcf->empty()) {
      throw ConfigError(SourceLocation{robot_file_path.string(), 0},
                        "missing key robot.mjcf (the MJCF model file name)");
    }
    mjcf_name = *robot_file->mjcf;
  }
  const std::filesystem::path mjcf_path = setup.model_dir / mjcf_name;
  const sim::ModelContext context{"mujoco", mjcf_path, robot_file_path};

  // Load the model.
  std::string error;
  sim::ModelPtr model = sim::load_mjcf(mjcf_path.string(), nullptr, error);
  if (!model) {
    throw HardwareError("mujoco: cannot load MJCF model " + sim::quoted(mjcf_path) + ": " + error);
  }
  const mjModel* m = model.get();

  // Every joint is a hinge or a slide (one coordinate each); one axis per actuator, each a
  // position servo on its own joint.
  if (m->njnt <= 0) {
    throw HardwareError("mujoco: model " + sim::quoted(mjcf_path) + " has no joints");
  }
  std::vector<int> joints(index(m->njnt));
  for (int j = 0; j < m->njnt; ++j) joints[index(j)] = j;
  sim::check_hinge_or_slide(m, joints, context);
  if (m->nq != m->njnt || m->nv != m->njnt) {
    throw HardwareError("mujoco: model " + sim::quoted(mjcf_path) +
                        ": nq = " + std::to_string(m->nq) + ", nv = " + std::to_string(m->nv) +
                        " differ from the " + std::to_string(m->njnt) + " joints");
  }
  // The arm's axes are the first actuators, one per joint of robot.joint_names (all of them when
  // parameters.toml lists none); the actuators after them are the gripper device.
  int arm_actuators = m->nu;
  if (robot_file && robot_file->joint_names && !robot_file->joint_names->empty() &&
      static_cast<int>(robot_file->joint_names->size()) < m->nu)
    arm_actuators = static_cast<int>(robot_file->joint_names->size());
  sim::RobotAxes robot = sim::map_axes(m, 0, arm_actuators, "", context);
  GripperDevice gripper = find_gripper(m, arm_actuators, robot, mjcf_path);
  const std::size_t axes = robot.size();
  // Axis names must agree with parameters.toml when it lists them.
  if (robot_file) sim::check_axis_names(robot, robot_file->joint_names, context);

  // Coupling a = M q (default identity).
  sim::Coupling coupling = robot_file ? sim::Coupling::from_parameters(*robot_file, axes, mjcf_path)
                                      : sim::Coupling(axes);

  // Servo period = an integer number of MuJoCo steps.
  const double timestep = m->opt.timestep;
  const double ratio = setup.servo_period_s / timestep;
  const double steps = std::round(ratio);
  if (!(setup.servo_period_s > 0.0) || !(timestep > 0.0) || steps < 1.0 ||
      std::abs(ratio - steps) > 1e-6 * steps) {
    throw HardwareError("mujoco: servo period " + sim::format_number(setup.servo_period_s) +
                        " s is not an integer multiple (>= 1) of the MuJoCo timestep " +
                        sim::format_number(timestep) + " s of " + sim::quoted(mjcf_path) +
                        " (ratio " + sim::format_number(ratio) + ")");
  }

  // Synchronisation switch positions, and the power-on pose.
  std::vector<double> synchro = setup.synchro_positions;
  std::string synchro_source = "the EDP setup";
  if (synchro.empty()) {
    if (!robot_file->synchro) {
      throw ConfigError(SourceLocation{robot_file_path.string(), 0},
                        "missing key robot.synchro_joint_positions [rad]");
    }
    synchro = *robot_file->synchro;
    synchro_source = sim::quoted(robot_file_path);
  }
  sim::plan_power_on(m, robot, std::move(coupling), std::move(synchro), synchro_source,
                     power_on_request, context);

  sim::DataPtr data(mj_makeData(m));
  if (!data) {
    throw HardwareError("mujoco: cannot allocate the simulation data of " + sim::quoted(mjcf_path));
  }
  // The whole state at power-on: actuator joints at M q, passive joints closing the loops.
  mjData* d = data.get();
  mj_resetData(m, d);
  const double violation = sim::close_loops(m, d, robot.qpos_adr, robot.power_on_actuators);
  sim::check_power_on_state(m, d, robot, joints, violation, power_on_request, context);
  std::vector<double> power_on_qpos(d->qpos, d->qpos + m->nq);

  // Commit.
  robot_ = std::move(robot);
  gripper_ = gripper;
  // Gravity feed-forward acts on the robot's own degrees of freedom (arm and gripper), not on
  // the objects of its world (the part falls as it would).
  const int robot_root = m->body_rootid[m->jnt_bodyid[robot_.joint[0]]];
  compensated_.assign(index(m->nv), false);
  for (int v = 0; v < m->nv; ++v)
    compensated_[index(v)] = m->body_rootid[m->dof_bodyid[v]] == robot_root;
  robot_root_ = robot_root;
  power_on_qpos_ = std::move(power_on_qpos);
  scratch_a_.assign(axes, 0.0);
  scratch_q_.assign(axes, 0.0);
  mjcf_path_ = mjcf_path;
  gravity_compensation_ = gravity_compensation;
  substeps_ = static_cast<int>(steps);
  axes_ = axes;
  model_ = model.release();
  data_ = data.release();
  previous_ctrl_.assign(axes_, 0.0);
  feed_forward_.assign(axes_, 0.0);
  servo_algorithm_.assign(axes_, 0);
  have_previous_ctrl_ = false;
  nominal_kp_.assign(axes_, 0.0);
  for (std::size_t i = 0; i < axes_; ++i)
    nominal_kp_[i] = model_->actuator_gainprm[static_cast<std::size_t>(mjNGAIN) * i];
  outputs_ = 0;
  reset_to_power_on();
}

int MujocoHardware::servo_parameter_set_count(int algorithm) const {
  return algorithm == 0 || algorithm == 1 ? static_cast<int>(kServoGainScale.size()) : 0;
}

void MujocoHardware::set_servo(std::size_t axis, int algorithm, int parameter_set) {
  if (model_ == nullptr || axis >= axes_ || algorithm < 0 || algorithm > 1 || parameter_set < 0 ||
      parameter_set >= static_cast<int>(kServoGainScale.size()))
    return;
  // A position servo: force = kp (target - q) (+ the joint's damping). Changing kp changes the
  // stiffness of the servo; the bias term must follow the gain.
  const double kp = nominal_kp_[axis] * kServoGainScale[static_cast<std::size_t>(parameter_set)];
  model_->actuator_gainprm[static_cast<std::size_t>(mjNGAIN) * axis] = kp;
  model_->actuator_biasprm[static_cast<std::size_t>(mjNBIAS) * axis + 1] = -kp;
  servo_algorithm_[axis] = algorithm;
}

std::uint32_t MujocoHardware::read_inputs() const {
  // Emulated controller I/O: input i (0..15) is axis i's synchronisation switch; inputs 16..31
  // are wired to outputs 0..15 (a loop-back plug, so that tasks can test their I/O).
  std::uint32_t inputs = (outputs_ & 0xFFFFU) << 16U;
  if (model_ == nullptr || data_ == nullptr) return inputs;
  for (std::size_t i = 0; i < axes_ && i < 16; ++i)
    if (switch_state_[i]) inputs |= 1U << i;
  return inputs;
}

void MujocoHardware::reset_to_power_on() noexcept {
  have_previous_ctrl_ = false;
  mj_resetData(model_, data_);
  for (int i = 0; i < model_->nq; ++i) {
    data_->qpos[i] = power_on_qpos_[index(i)];
  }
  for (std::size_t i = 0; i < axes_; ++i) {
    data_->ctrl[i] = data_->qpos[robot_.qpos_adr[i]];
  }
  if (gripper_.present) {
    // Power-on: the fingers open, pushing with the opening force.
    for (std::size_t k = 0; k < 2; ++k) {
      data_->qpos[gripper_.qpos_adr[k]] = gripper_.max_opening / 2.0;
      data_->ctrl[gripper_.actuator[k]] = gripper_.max_opening / 2.0;
    }
    set_finger_force(kGripperPowerOnForce);
    gripper_.command_opening = gripper_.max_opening;
  }
  mj_forward(model_, data_);
  for (int v = 0; v < model_->nv; ++v) {
    data_->qfrc_applied[v] =
        gravity_compensation_ && compensated_[index(v)] ? data_->qfrc_bias[v] : 0.0;
  }
}

void MujocoHardware::activate() {
  if (model_ == nullptr || data_ == nullptr) {
    throw HardwareError("mujoco: activate() called before configure()");
  }
  reset_to_power_on();
  warnings_at_activate_ = sim::warning_total(data_);
  fault_[0] = '\0';
  active_ = true;
}

void MujocoHardware::deactivate() { active_ = false; }

double MujocoHardware::equality_violation() const noexcept {
  if (model_ == nullptr || data_ == nullptr) {
    return 0.0;
  }
  return sim::equality_violation(data_);
}

void MujocoHardware::set_fault(const char* format, ...) noexcept {
  va_list args;
  va_start(args, format);
  std::vsnprintf(fault_.data(), fault_.size(), format, args);
  va_end(args);
}

bool MujocoHardware::check_stable() noexcept {
  if (sim::non_finite_joint(model_, data_) >= 0) {
    set_fault("mujoco: simulation of '%s' unstable: non-finite joint state at t = %.6f s",
              mjcf_path_.c_str(), data_->time);
    return false;
  }
  if (sim::warning_total(data_) != warnings_at_activate_) {
    for (int w = 0; w < mjNWARNING; ++w) {
      if (data_->warning[w].number > 0) {
        set_fault(
            "mujoco: simulation of '%s' unstable: MuJoCo warning '%s' raised %d time(s), "
            "last at index %d",
            mjcf_path_.c_str(), sim::warning_text(w), data_->warning[w].number,
            data_->warning[w].lastinfo);
        return false;
      }
    }
    set_fault("mujoco: simulation of '%s' unstable (MuJoCo warning)", mjcf_path_.c_str());
    return false;
  }
  if (const double violation = equality_violation(); violation > kLoopOpenFault) {
    set_fault(
        "mujoco: simulation of '%s' unstable: a closed kinematic loop opened by %.3g (limit "
        "%.3g) at t = %.6f s",
        mjcf_path_.c_str(), violation, kLoopOpenFault, data_->time);
    return false;
  }
  return true;
}

std::string MujocoHardware::fault_text() const { return fault_.data(); }

CycleStatus MujocoHardware::read(std::span<AxisFeedback> out) {
  if (model_ == nullptr || data_ == nullptr) {
    set_fault("mujoco: read() before configure()");
    return CycleStatus::fault;
  }
  if (out.size() != axes_) {
    set_fault("mujoco: read() with %zu axes, the model has %zu", out.size(), axes_);
    return CycleStatus::fault;
  }
  if (!check_stable()) {
    return CycleStatus::fault;
  }
  double* a = scratch_a_.data();
  double* q = scratch_q_.data();
  for (std::size_t i = 0; i < axes_; ++i) {
    a[i] = data_->qpos[robot_.qpos_adr[i]];
  }
  robot_.coupling.joints_from_actuators(a, q);
  for (std::size_t i = 0; i < axes_; ++i) {
    out[i].position = q[i] - robot_.power_on[i];
    out[i].synchro_switch = q[i] > robot_.synchro[i];
    if (i < switch_state_.size()) switch_state_[i] = out[i].synchro_switch;
  }
  for (std::size_t i = 0; i < axes_; ++i) {
    a[i] = data_->qvel[robot_.dof_adr[i]];
  }
  robot_.coupling.joints_from_actuators(a, q);
  for (std::size_t i = 0; i < axes_; ++i) {
    out[i].velocity = q[i];
  }
  return CycleStatus::ok;
}

CycleStatus MujocoHardware::write(std::span<const double> setpoints) {
  if (!active_) {
    set_fault("mujoco: write() while the drives are not active");
    return CycleStatus::fault;
  }
  if (setpoints.size() != axes_) {
    set_fault("mujoco: write() with %zu setpoints, the model has %zu axes", setpoints.size(),
              axes_);
    return CycleStatus::fault;
  }
  for (std::size_t i = 0; i < axes_; ++i) {
    if (!std::isfinite(setpoints[i])) {
      set_fault("mujoco: write(): setpoint of axis %zu is not a finite number", i);
      return CycleStatus::fault;
    }
  }
  // Actuator targets a = M q; the actuators' ctrlrange clamps them.
  double* q = scratch_q_.data();
  for (std::size_t i = 0; i < axes_; ++i) q[i] = setpoints[i] + robot_.power_on[i];
  robot_.coupling.actuators_from_joints(q, data_->ctrl);
  // Servo algorithm 1: velocity feed-forward. The joint's viscous friction (damping) is what
  // makes a position servo lag by damping / kp * velocity; feeding the commanded velocity's
  // friction force forward removes that lag.
  for (std::size_t i = 0; i < axes_; ++i) {
    const double velocity = have_previous_ctrl_ ? (data_->ctrl[i] - previous_ctrl_[i]) /
                                                      (substeps_ * model_->opt.timestep)
                                                : 0.0;
    previous_ctrl_[i] = data_->ctrl[i];
    feed_forward_[i] =
        servo_algorithm_[i] == 1 ? model_->dof_damping[robot_.dof_adr[i]] * velocity : 0.0;
  }
  have_previous_ctrl_ = true;
  for (int s = 0; s < substeps_; ++s) {
    if (gravity_compensation_) {
      // Gravity and Coriolis feed-forward evaluated at the state of this step: mj_step1 computes
      // qfrc_bias from the current positions and velocities, mj_step2 integrates.
      mj_step1(model_, data_);
      for (int v = 0; v < model_->nv; ++v) {
        data_->qfrc_applied[v] = compensated_[index(v)] ? data_->qfrc_bias[v] : 0.0;
      }
      for (std::size_t i = 0; i < axes_; ++i)
        data_->qfrc_applied[robot_.dof_adr[i]] += feed_forward_[i];
      mj_step2(model_, data_);
    } else {
      for (std::size_t i = 0; i < axes_; ++i)
        data_->qfrc_applied[robot_.dof_adr[i]] = feed_forward_[i];
      mj_step(model_, data_);
    }
  }
  if (!check_stable()) {
    return CycleStatus::fault;
  }
  return CycleStatus::ok;
}

std::vector<double> MujocoHardware::true_joint_positions() const {
  std::vector<double> a = actuator_joint_positions();
  std::vector<double> q(axes_);
  robot_.coupling.joints_from_actuators(a.data(), q.data());
  return q;
}

std::vector<double> MujocoHardware::actuator_joint_positions() const {
  std::vector<double> a(axes_);
  for (std::size_t i = 0; i < axes_; ++i) {
    a[i] = data_->qpos[robot_.qpos_adr[i]];
  }
  return a;
}

MujocoHardware::GripperDevice MujocoHardware::find_gripper(const mjModel* m, int first,
                                                           const sim::RobotAxes& arm,
                                                           const std::filesystem::path& mjcf) {
  GripperDevice g;
  const int count = m->nu - first;
  if (count == 0) return g;
  const std::string where = "mujoco: model " + sim::quoted(mjcf) + ": ";
  if (count != 2)
    throw HardwareError(where + std::to_string(count) +
                        " actuators follow the arm's (robot.joint_names of parameters.toml); a "
                        "gripper device has two, one slide joint per finger");
  for (int k = 0; k < 2; ++k) {
    const int a = first + k;
    const int joint = m->actuator_trnid[2 * a];
    const char* name = mj_id2name(m, mjOBJ_ACTUATOR, a);
    const std::string label = name != nullptr ? name : std::to_string(a);
    if (m->actuator_trntype[a] != mjTRN_JOINT || joint < 0 || m->jnt_type[joint] != mjJNT_SLIDE)
      throw HardwareError(where + "gripper actuator '" + label + "' does not drive a slide joint");
    if (std::find(arm.joint.begin(), arm.joint.end(), joint) != arm.joint.end())
      throw HardwareError(where + "gripper actuator '" + label + "' drives an arm joint");
    if (m->actuator_forcelimited[a] == 0 || m->jnt_limited[joint] == 0)
      throw HardwareError(where + "gripper actuator '" + label +
                          "' needs forcelimited=\"true\" and its joint a range");
    const auto uk = static_cast<std::size_t>(k);
    g.actuator[uk] = a;
    g.qpos_adr[uk] = m->jnt_qposadr[joint];
    g.dof_adr[uk] = m->jnt_dofadr[joint];
    g.body[uk] = m->jnt_bodyid[joint];
    // A finger's joint is half the opening: its range's upper end, twice, is the widest.
    g.max_opening += m->jnt_range[2 * joint + 1];
    g.max_force = k == 0 ? m->actuator_forcerange[2 * a + 1]
                         : std::min(g.max_force, m->actuator_forcerange[2 * a + 1]);
  }
  g.present = true;
  return g;
}

DeviceDescription MujocoHardware::device() const {
  if (!gripper_.present) return {};
  return {"gripper",
          {{"opening", "m", 0.0, gripper_.max_opening}, {"force", "N", 0.0, gripper_.max_force}},
          {{"opening", "m"}, {"speed", "m/s"}, {"force", "N"}, {"holding", "-"}}};
}

void MujocoHardware::set_finger_force(double force_n) noexcept {
  for (std::size_t k = 0; k < 2; ++k) {
    const auto a = static_cast<std::size_t>(gripper_.actuator[k]);
    model_->actuator_forcerange[2 * a] = -force_n;
    model_->actuator_forcerange[2 * a + 1] = force_n;
  }
}

void MujocoHardware::write_device(std::span<const double> command) {
  if (!gripper_.present || model_ == nullptr || data_ == nullptr || command.size() != 2) return;
  // Each finger is servoed to half the opening; the force limit is what it may push with.
  for (std::size_t k = 0; k < 2; ++k) data_->ctrl[gripper_.actuator[k]] = command[0] / 2.0;
  set_finger_force(command[1]);
  gripper_.command_opening = command[0];
}

void MujocoHardware::read_device(std::span<double> reply) const {
  if (!gripper_.present || model_ == nullptr || data_ == nullptr || reply.size() != 4) return;
  const double opening = data_->qpos[gripper_.qpos_adr[0]] + data_->qpos[gripper_.qpos_adr[1]];
  const double speed = data_->qvel[gripper_.dof_adr[0]] + data_->qvel[gripper_.dof_adr[1]];
  // The grip force: the normal forces of each finger's contacts with bodies outside the robot
  // (the objects of its world), and the body each finger presses on most.
  std::array<double, 2> pressing{};
  std::array<int, 2> object{-1, -1};
  std::array<double, 2> strongest{};
  for (int c = 0; c < data_->ncon; ++c) {
    const mjContact& contact = data_->contact[c];
    const int b1 = model_->geom_bodyid[contact.geom1];
    const int b2 = model_->geom_bodyid[contact.geom2];
    for (std::size_t k = 0; k < 2; ++k) {
      const int other = b1 == gripper_.body[k] ? b2 : b2 == gripper_.body[k] ? b1 : -1;
      if (other < 0 || model_->body_rootid[other] == robot_root_) continue;
      mjtNum force[6];
      mj_contactForce(model_, data_, c, force);
      pressing[k] += force[0];
      if (force[0] > strongest[k]) {
        strongest[k] = force[0];
        object[k] = other;
      }
    }
  }
  // Holding: both fingers press on one object, they have stopped, and short of the commanded
  // opening (they did not close fully).
  const bool holding = object[0] >= 0 && object[0] == object[1] &&
                       std::min(pressing[0], pressing[1]) >= kHoldingForce &&
                       std::abs(speed) < kStoppedSpeed &&
                       opening > gripper_.command_opening + kHoldingMargin;
  reply[0] = opening;
  reply[1] = speed;
  reply[2] = (pressing[0] + pressing[1]) / 2.0;
  reply[3] = holding ? 1.0 : 0.0;
}

MRROC_REGISTER_HARDWARE("mujoco", MujocoHardware);

}  // namespace mrroc::edp
