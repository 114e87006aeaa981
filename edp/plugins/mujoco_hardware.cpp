/// @file
/// The `mujoco` EDP hardware plugin (see mujoco_hardware.hpp).

#include "mujoco_hardware.hpp"

#include <algorithm>
#include <cmath>
#include <cstdarg>
#include <cstdio>
#include <memory>
#include <optional>
#include <utility>

#include <toml++/toml.h>

#include "mrroc/core/error.hpp"

namespace mrroc::edp {
namespace {

constexpr const char* kParamsTable = "robot.edp.params";

/// A number in a message, with enough digits to tell 0.0025 from 0.002.
std::string num(double value) {
  std::array<char, 32> buffer{};
  std::snprintf(buffer.data(), buffer.size(), "%.9g", value);
  return buffer.data();
}

std::string quoted(const std::filesystem::path& path) { return "'" + path.string() + "'"; }

std::string where(const toml::source_region& region, const std::filesystem::path& file) {
  return file.string() + ":" + std::to_string(region.begin.line);
}

/// What the plugin uses from `<model_dir>/parameters.toml`.
struct RobotFile {
  std::filesystem::path path;
  std::optional<std::string> mjcf;
  std::optional<std::vector<double>> synchro;
  std::optional<std::vector<std::string>> joint_names;
};

RobotFile read_robot_file(const std::filesystem::path& path) {
  RobotFile out;
  out.path = path;
  toml::table table;
  try {
    table = toml::parse_file(path.string());
  } catch (const toml::parse_error& e) {
    throw ConfigError(where(e.source(), path) + ": error: " + std::string(e.description()));
  }
  const toml::node_view robot = table["robot"];
  if (const toml::node* node = robot["mjcf"].node()) {
    const auto value = node->value<std::string>();
    if (!value) {
      throw ConfigError(where(node->source(), path) + ": error: robot.mjcf must be a string");
    }
    out.mjcf = *value;
  }
  if (const toml::node* node = robot["synchro_joint_positions"].node()) {
    const toml::array* array = node->as_array();
    if (array == nullptr) {
      throw ConfigError(where(node->source(), path) +
                        ": error: robot.synchro_joint_positions must be a list of numbers [rad]");
    }
    std::vector<double> values;
    for (const toml::node& element : *array) {
      const auto value = element.value<double>();
      if (!value) {
        throw ConfigError(where(element.source(), path) +
                          ": error: robot.synchro_joint_positions must be a list of numbers [rad]");
      }
      values.push_back(*value);
    }
    out.synchro = std::move(values);
  }
  if (const toml::node* node = robot["joint_names"].node()) {
    const toml::array* array = node->as_array();
    if (array == nullptr) {
      throw ConfigError(where(node->source(), path) +
                        ": error: robot.joint_names must be a list of strings");
    }
    std::vector<std::string> values;
    for (const toml::node& element : *array) {
      const auto value = element.value<std::string>();
      if (!value) {
        throw ConfigError(where(element.source(), path) +
                          ": error: robot.joint_names must be a list of strings");
      }
      values.push_back(*value);
    }
    out.joint_names = std::move(values);
  }
  return out;
}

struct ModelDeleter {
  void operator()(mjModel* m) const noexcept { mj_deleteModel(m); }
};
struct DataDeleter {
  void operator()(mjData* d) const noexcept { mj_deleteData(d); }
};

std::string joint_name(const mjModel* m, int joint) {
  const char* name = mj_id2name(m, mjOBJ_JOINT, joint);
  return name != nullptr ? std::string(name) : "#" + std::to_string(joint);
}

std::size_t index(int i) { return static_cast<std::size_t>(i); }

const char* warning_name(int warning) noexcept {
  switch (warning) {
    case mjWARN_INERTIA:
      return "(near) singular inertia matrix";
    case mjWARN_CONTACTFULL:
      return "contact list full";
    case mjWARN_CNSTRFULL:
      return "constraint buffer full";
    case mjWARN_VGEOMFULL:
      return "visual geom buffer full";
    case mjWARN_BADQPOS:
      return "bad number in qpos (simulation reset)";
    case mjWARN_BADQVEL:
      return "bad number in qvel (simulation reset)";
    case mjWARN_BADQACC:
      return "bad number in qacc (simulation reset)";
    case mjWARN_BADCTRL:
      return "bad number in ctrl";
    default:
      return "unknown";
  }
}

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

  // The plugin's own parameters; a copy so that unread keys can be checked here.
  const Params params = setup.params;
  const bool gravity_compensation = params.get_bool("gravity_compensation", true);
  const std::string mjcf_param = params.get_string("mjcf", "");
  std::optional<std::vector<double>> initial;
  if (params.has("initial_joint_positions")) {
    initial = params.get_doubles("initial_joint_positions");
  }
  params.reject_unread(kParamsTable);

  // parameters.toml of the robot: needed for the MJCF name and/or the synchronisation pose.
  const std::filesystem::path robot_file_path = setup.model_dir / "parameters.toml";
  std::optional<RobotFile> robot_file;
  const bool need_robot_file = mjcf_param.empty() || setup.synchro_positions.empty();
  if (need_robot_file || std::filesystem::exists(robot_file_path)) {
    if (!std::filesystem::exists(robot_file_path)) {
      throw ConfigError(robot_file_path.string() + ":0: error: robot parameter file not found (" +
                        (mjcf_param.empty() ? "needed for robot.mjcf"
                                            : "needed for robot.synchro_joint_positions") +
                        ")");
    }
    robot_file = read_robot_file(robot_file_path);
  }

  std::string mjcf_name = mjcf_param;
  if (mjcf_name.empty()) {
    if (!robot_file->mjcf || robot_file->mjcf->empty()) {
      throw ConfigError(robot_file_path.string() +
                        ":0: error: missing key robot.mjcf (the MJCF model file name)");
    }
    mjcf_name = *robot_file->mjcf;
  }
  const std::filesystem::path mjcf_path = setup.model_dir / mjcf_name;

  // Load the model.
  std::array<char, 1024> error{};
  std::unique_ptr<mjModel, ModelDeleter> model(
      mj_loadXML(mjcf_path.c_str(), nullptr, error.data(), static_cast<int>(error.size())));
  if (!model) {
    std::string text = error[0] != '\0' ? std::string(error.data()) : "unknown MuJoCo error";
    std::replace(text.begin(), text.end(), '\n', ' ');
    while (!text.empty() && text.back() == ' ') {
      text.pop_back();
    }
    throw HardwareError("mujoco: cannot load MJCF model " + quoted(mjcf_path) + ": " + text);
  }
  const mjModel* m = model.get();

  // One hinge joint and one joint actuator per axis.
  if (m->njnt <= 0) {
    throw HardwareError("mujoco: model " + quoted(mjcf_path) + " has no joints");
  }
  for (int j = 0; j < m->njnt; ++j) {
    if (m->jnt_type[j] != mjJNT_HINGE) {
      throw HardwareError("mujoco: model " + quoted(mjcf_path) + ": joint '" + joint_name(m, j) +
                          "' is not a hinge joint (only hinge joints are supported as axes)");
    }
  }
  if (m->nq != m->njnt || m->nv != m->njnt) {
    throw HardwareError("mujoco: model " + quoted(mjcf_path) + ": nq = " + std::to_string(m->nq) +
                        ", nv = " + std::to_string(m->nv) + " differ from the " +
                        std::to_string(m->njnt) + " hinge joints");
  }
  if (m->nu != m->njnt) {
    throw HardwareError("mujoco: model " + quoted(mjcf_path) + " has " + std::to_string(m->nu) +
                        " actuators for " + std::to_string(m->njnt) +
                        " hinge joints (one position actuator per joint is required)");
  }
  const std::size_t axes = index(m->njnt);
  std::vector<int> actuator(axes, -1);
  for (int a = 0; a < m->nu; ++a) {
    const int joint = m->actuator_trnid[2 * a];
    if (m->actuator_trntype[a] != mjTRN_JOINT || joint < 0 || joint >= m->njnt) {
      const char* aname = mj_id2name(m, mjOBJ_ACTUATOR, a);
      throw HardwareError("mujoco: model " + quoted(mjcf_path) + ": actuator '" +
                          (aname != nullptr ? aname : std::to_string(a)) +
                          "' does not drive a joint");
    }
    if (actuator[index(joint)] >= 0) {
      throw HardwareError("mujoco: model " + quoted(mjcf_path) + ": joint '" +
                          joint_name(m, joint) + "' has more than one actuator");
    }
    actuator[index(joint)] = a;
  }

  // Joint names must agree with parameters.toml when it lists them.
  if (robot_file && robot_file->joint_names) {
    const auto& names = *robot_file->joint_names;
    bool same = names.size() == axes;
    for (std::size_t i = 0; same && i < axes; ++i) {
      same = names[i] == joint_name(m, static_cast<int>(i));
    }
    if (!same) {
      std::string model_names;
      for (std::size_t i = 0; i < axes; ++i) {
        model_names += (i == 0 ? "" : ", ") + joint_name(m, static_cast<int>(i));
      }
      throw HardwareError("mujoco: joints of " + quoted(mjcf_path) + " (" + model_names +
                          ") do not match robot.joint_names of " + quoted(robot_file_path));
    }
  }

  // Servo period = an integer number of MuJoCo steps.
  const double timestep = m->opt.timestep;
  const double ratio = setup.servo_period_s / timestep;
  const double steps = std::round(ratio);
  if (!(setup.servo_period_s > 0.0) || !(timestep > 0.0) || steps < 1.0 ||
      std::abs(ratio - steps) > 1e-6 * steps) {
    throw HardwareError("mujoco: servo period " + num(setup.servo_period_s) +
                        " s is not an integer multiple (>= 1) of the MuJoCo timestep " +
                        num(timestep) + " s of " + quoted(mjcf_path) + " (ratio " + num(ratio) +
                        ")");
  }

  // Synchronisation switch positions.
  std::vector<double> synchro = setup.synchro_positions;
  std::string synchro_source = "the EDP setup";
  if (synchro.empty()) {
    if (!robot_file->synchro) {
      throw ConfigError(robot_file_path.string() +
                        ":0: error: missing key robot.synchro_joint_positions [rad]");
    }
    synchro = *robot_file->synchro;
    synchro_source = quoted(robot_file_path);
  }
  if (synchro.size() != axes) {
    throw HardwareError("mujoco: " + std::to_string(synchro.size()) +
                        " synchronisation positions from " + synchro_source + " for " +
                        std::to_string(axes) + " axes of " + quoted(mjcf_path));
  }

  // Power-on pose.
  std::vector<double> power_on(axes);
  if (initial) {
    const std::string loc = params.location_of("initial_joint_positions").str();
    if (initial->size() != axes) {
      throw ConfigError(loc + ": error: initial_joint_positions has " +
                        std::to_string(initial->size()) + " values for " + std::to_string(axes) +
                        " axes");
    }
    for (std::size_t i = 0; i < axes; ++i) {
      const double q = (*initial)[i];
      const int j = static_cast<int>(i);
      const double lo = m->jnt_range[2 * j];
      const double hi = m->jnt_range[2 * j + 1];
      if (!std::isfinite(q) || (m->jnt_limited[j] != 0 && (q < lo || q > hi))) {
        throw ConfigError(loc + ": error: initial_joint_positions[" + std::to_string(i) +
                          "] = " + num(q) + " rad is outside the range [" + num(lo) + ", " +
                          num(hi) + "] rad of joint '" + joint_name(m, j) + "'");
      }
      power_on[i] = q;
    }
  } else {
    for (std::size_t i = 0; i < axes; ++i) {
      const int j = static_cast<int>(i);
      double q = synchro[i] + kDefaultPowerOnOffset;
      if (m->jnt_limited[j] != 0) {
        q = std::clamp(q, m->jnt_range[2 * j], m->jnt_range[2 * j + 1]);
      }
      power_on[i] = q;
    }
  }

  std::unique_ptr<mjData, DataDeleter> data(mj_makeData(m));
  if (!data) {
    throw HardwareError("mujoco: cannot allocate the simulation data of " + quoted(mjcf_path));
  }

  // Commit.
  qpos_adr_.assign(axes, 0);
  dof_adr_.assign(axes, 0);
  for (std::size_t i = 0; i < axes; ++i) {
    qpos_adr_[i] = m->jnt_qposadr[i];
    dof_adr_[i] = m->jnt_dofadr[i];
  }
  actuator_ = std::move(actuator);
  power_on_ = std::move(power_on);
  synchro_ = std::move(synchro);
  mjcf_path_ = mjcf_path;
  gravity_compensation_ = gravity_compensation;
  substeps_ = static_cast<int>(steps);
  axes_ = axes;
  model_ = model.release();
  data_ = data.release();
  reset_to_power_on();
}

void MujocoHardware::reset_to_power_on() noexcept {
  mj_resetData(model_, data_);
  for (std::size_t i = 0; i < axes_; ++i) {
    data_->qpos[qpos_adr_[i]] = power_on_[i];
    data_->ctrl[actuator_[i]] = power_on_[i];
  }
  mj_forward(model_, data_);
  for (std::size_t i = 0; i < axes_; ++i) {
    data_->qfrc_applied[dof_adr_[i]] = gravity_compensation_ ? data_->qfrc_bias[dof_adr_[i]] : 0.0;
  }
}

void MujocoHardware::activate() {
  if (model_ == nullptr || data_ == nullptr) {
    throw HardwareError("mujoco: activate() called before configure()");
  }
  reset_to_power_on();
  warnings_at_activate_ = warning_total();
  fault_[0] = '\0';
  active_ = true;
}

void MujocoHardware::deactivate() { active_ = false; }

int MujocoHardware::warning_total() const noexcept {
  int total = 0;
  for (const mjWarningStat& w : data_->warning) {
    total += w.number;
  }
  return total;
}

bool MujocoHardware::state_is_finite() const noexcept {
  for (int i = 0; i < model_->nq; ++i) {
    if (!std::isfinite(data_->qpos[i])) {
      return false;
    }
  }
  for (int i = 0; i < model_->nv; ++i) {
    if (!std::isfinite(data_->qvel[i]) || !std::isfinite(data_->qacc[i])) {
      return false;
    }
  }
  return true;
}

void MujocoHardware::set_fault(const char* format, ...) noexcept {
  va_list args;
  va_start(args, format);
  std::vsnprintf(fault_.data(), fault_.size(), format, args);
  va_end(args);
}

bool MujocoHardware::check_stable() noexcept {
  if (!state_is_finite()) {
    set_fault("mujoco: simulation of '%s' unstable: non-finite joint state at t = %.6f s",
              mjcf_path_.c_str(), data_->time);
    return false;
  }
  if (warning_total() != warnings_at_activate_) {
    for (int w = 0; w < mjNWARNING; ++w) {
      if (data_->warning[w].number > 0) {
        set_fault(
            "mujoco: simulation of '%s' unstable: MuJoCo warning '%s' raised %d time(s), "
            "last at index %d",
            mjcf_path_.c_str(), warning_name(w), data_->warning[w].number,
            data_->warning[w].lastinfo);
        return false;
      }
    }
    set_fault("mujoco: simulation of '%s' unstable (MuJoCo warning)", mjcf_path_.c_str());
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
  for (std::size_t i = 0; i < axes_; ++i) {
    const double q = data_->qpos[qpos_adr_[i]];
    out[i].position = q - power_on_[i];
    out[i].velocity = data_->qvel[dof_adr_[i]];
    out[i].synchro_switch = q > synchro_[i];
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
    // The actuator's ctrlrange (= joint range) clamps the target.
    data_->ctrl[actuator_[i]] = setpoints[i] + power_on_[i];
  }
  for (int s = 0; s < substeps_; ++s) {
    if (gravity_compensation_) {
      // Gravity and Coriolis feed-forward evaluated at the state of this step: mj_step1 computes
      // qfrc_bias from the current positions and velocities, mj_step2 integrates.
      mj_step1(model_, data_);
      for (std::size_t i = 0; i < axes_; ++i) {
        data_->qfrc_applied[dof_adr_[i]] = data_->qfrc_bias[dof_adr_[i]];
      }
      mj_step2(model_, data_);
    } else {
      mj_step(model_, data_);
    }
  }
  if (!check_stable()) {
    return CycleStatus::fault;
  }
  return CycleStatus::ok;
}

std::vector<double> MujocoHardware::true_joint_positions() const {
  std::vector<double> q(axes_);
  for (std::size_t i = 0; i < axes_; ++i) {
    q[i] = data_->qpos[qpos_adr_[i]];
  }
  return q;
}

MRROC_REGISTER_HARDWARE("mujoco", MujocoHardware);

}  // namespace mrroc::edp
