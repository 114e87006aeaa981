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

#include <Eigen/Dense>
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
  /// robot.transmission.coupling, row by row, and where it is.
  std::optional<std::vector<std::vector<double>>> coupling;
  std::string coupling_where;
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
  if (const toml::node* node = robot["transmission"]["coupling"].node()) {
    out.coupling_where = where(node->source(), path);
    const std::string shape_error =
        out.coupling_where +
        ": error: robot.transmission.coupling must be a list of rows, each a list of numbers";
    const toml::array* rows = node->as_array();
    if (rows == nullptr) {
      throw ConfigError(shape_error);
    }
    std::vector<std::vector<double>> matrix;
    for (const toml::node& row_node : *rows) {
      const toml::array* row = row_node.as_array();
      if (row == nullptr) {
        throw ConfigError(where(row_node.source(), path) +
                          ": error: robot.transmission.coupling must be a list of rows, each a "
                          "list of numbers");
      }
      std::vector<double> values;
      for (const toml::node& element : *row) {
        const auto value = element.value<double>();
        if (!value || !std::isfinite(*value)) {
          throw ConfigError(where(element.source(), path) +
                            ": error: robot.transmission.coupling must contain only finite "
                            "numbers");
        }
        values.push_back(*value);
      }
      matrix.push_back(std::move(values));
    }
    out.coupling = std::move(matrix);
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

namespace {

using RowMatrix = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

/// Largest |efc_pos| over the equality-constraint rows of the last constraint computation.
double equality_rows_violation(const mjData* d) noexcept {
  double worst = 0.0;
  for (int r = 0; r < d->nefc; ++r) {
    if (d->efc_type[r] == mjCNSTR_EQUALITY) {
      worst = std::max(worst, std::abs(d->efc_pos[r]));
    }
  }
  return worst;
}

/// Closes the model's kinematic loops: with the actuator joints held at `targets`, moves the
/// passive degrees of freedom (Gauss-Newton on the equality constraints, in `continuation` steps
/// from the current state) until the constraints hold. Every joint is a hinge or a slide, so
/// qpos and qvel addresses correspond. Returns the remaining violation.
double close_loops(const mjModel* m, mjData* d, const std::vector<int>& actuator_qpos,
                   const std::vector<double>& targets) {
  const std::size_t nv = index(m->nv);
  std::vector<bool> actuated(nv, false);
  for (const int adr : actuator_qpos) {
    actuated[index(adr)] = true;
  }
  std::vector<int> passive;
  for (std::size_t v = 0; v < nv; ++v) {
    if (!actuated[v]) {
      passive.push_back(static_cast<int>(v));
    }
  }
  std::vector<double> start(targets.size());
  double largest_move = 0.0;
  for (std::size_t i = 0; i < targets.size(); ++i) {
    start[i] = d->qpos[actuator_qpos[i]];
    largest_move = std::max(largest_move, std::abs(targets[i] - start[i]));
  }
  // Continuation steps of at most 0.05 rad (or m) keep Gauss-Newton on the branch of qpos0.
  const int steps = std::max(1, static_cast<int>(std::ceil(largest_move / 0.05)));
  const bool sparse = mj_isSparse(m) != 0;
  for (int k = 1; k <= steps; ++k) {
    const double s = static_cast<double>(k) / static_cast<double>(steps);
    for (std::size_t i = 0; i < targets.size(); ++i) {
      d->qpos[actuator_qpos[i]] = start[i] + (targets[i] - start[i]) * s;
    }
    for (int iteration = 0; iteration < 100; ++iteration) {
      mj_fwdPosition(m, d);
      std::vector<int> rows;
      for (int r = 0; r < d->nefc; ++r) {
        if (d->efc_type[r] == mjCNSTR_EQUALITY) {
          rows.push_back(r);
        }
      }
      if (rows.empty() || passive.empty()) {
        break;
      }
      Eigen::MatrixXd jacobian = Eigen::MatrixXd::Zero(static_cast<Eigen::Index>(rows.size()),
                                                       static_cast<Eigen::Index>(passive.size()));
      Eigen::VectorXd residual(static_cast<Eigen::Index>(rows.size()));
      double worst = 0.0;
      for (std::size_t r = 0; r < rows.size(); ++r) {
        const int row = rows[r];
        const auto er = static_cast<Eigen::Index>(r);
        residual(er) = d->efc_pos[row];
        worst = std::max(worst, std::abs(d->efc_pos[row]));
        std::vector<double> dense(nv, 0.0);
        if (sparse) {
          const int adr = d->efc_J_rowadr[row];
          for (int n = 0; n < d->efc_J_rownnz[row]; ++n) {
            dense[index(d->efc_J_colind[adr + n])] = d->efc_J[adr + n];
          }
        } else {
          for (std::size_t v = 0; v < nv; ++v) {
            dense[v] = d->efc_J[index(row) * nv + v];
          }
        }
        for (std::size_t c = 0; c < passive.size(); ++c) {
          jacobian(er, static_cast<Eigen::Index>(c)) = dense[index(passive[c])];
        }
      }
      if (worst < 1e-13) {
        break;
      }
      // Least-squares step; the rank deficiency of planar loops (a 3-D connect closing a planar
      // loop has a redundant row) is handled by the complete orthogonal decomposition.
      Eigen::CompleteOrthogonalDecomposition<Eigen::MatrixXd> solver(jacobian);
      solver.setThreshold(1e-10);
      const Eigen::VectorXd step = solver.solve(residual);
      for (std::size_t c = 0; c < passive.size(); ++c) {
        d->qpos[passive[c]] -= step(static_cast<Eigen::Index>(c));
      }
    }
  }
  mj_fwdPosition(m, d);
  return equality_rows_violation(d);
}

}  // namespace

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

  // Every joint is a hinge or a slide (one coordinate each); one axis per actuator, each a
  // position servo on its own joint.
  if (m->njnt <= 0) {
    throw HardwareError("mujoco: model " + quoted(mjcf_path) + " has no joints");
  }
  for (int j = 0; j < m->njnt; ++j) {
    if (m->jnt_type[j] != mjJNT_HINGE && m->jnt_type[j] != mjJNT_SLIDE) {
      throw HardwareError("mujoco: model " + quoted(mjcf_path) + ": joint '" + joint_name(m, j) +
                          "' is neither a hinge nor a slide joint (only those are supported)");
    }
  }
  if (m->nq != m->njnt || m->nv != m->njnt) {
    throw HardwareError("mujoco: model " + quoted(mjcf_path) + ": nq = " + std::to_string(m->nq) +
                        ", nv = " + std::to_string(m->nv) + " differ from the " +
                        std::to_string(m->njnt) + " joints");
  }
  if (m->nu <= 0) {
    throw HardwareError("mujoco: model " + quoted(mjcf_path) +
                        " has no actuators (one position actuator per axis is required)");
  }
  const std::size_t axes = index(m->nu);
  std::vector<int> actuator_joint(axes, -1);
  std::vector<int> driven_by(index(m->njnt), -1);
  std::vector<std::string> axis_names(axes);
  for (int a = 0; a < m->nu; ++a) {
    const int joint = m->actuator_trnid[2 * a];
    const char* aname = mj_id2name(m, mjOBJ_ACTUATOR, a);
    if (m->actuator_trntype[a] != mjTRN_JOINT || joint < 0 || joint >= m->njnt) {
      throw HardwareError("mujoco: model " + quoted(mjcf_path) + ": actuator '" +
                          (aname != nullptr ? aname : std::to_string(a)) +
                          "' does not drive a joint");
    }
    if (driven_by[index(joint)] >= 0) {
      throw HardwareError("mujoco: model " + quoted(mjcf_path) + ": joint '" +
                          joint_name(m, joint) + "' has more than one actuator");
    }
    driven_by[index(joint)] = a;
    actuator_joint[index(a)] = joint;
    axis_names[index(a)] = aname != nullptr ? std::string(aname) : joint_name(m, joint);
  }
  const auto name_list = [](const std::vector<std::string>& names) {
    std::string text;
    for (std::size_t i = 0; i < names.size(); ++i) {
      text += (i == 0 ? "" : ", ") + names[i];
    }
    return text;
  };

  // Axis names must agree with parameters.toml when it lists them.
  if (robot_file && robot_file->joint_names && *robot_file->joint_names != axis_names) {
    throw HardwareError("mujoco: actuators of " + quoted(mjcf_path) + " (" +
                        name_list(axis_names) + ") do not match robot.joint_names of " +
                        quoted(robot_file_path) + " (" + name_list(*robot_file->joint_names) +
                        ")");
  }

  // Coupling a = M q (default identity) and its inverse.
  RowMatrix coupling = RowMatrix::Identity(static_cast<Eigen::Index>(axes),
                                           static_cast<Eigen::Index>(axes));
  if (robot_file && robot_file->coupling) {
    const auto& rows = *robot_file->coupling;
    bool square = rows.size() == axes;
    for (const auto& row : rows) {
      square = square && row.size() == axes;
    }
    if (!square) {
      throw ConfigError(robot_file->coupling_where + ": error: robot.transmission.coupling must be a " +
                        std::to_string(axes) + " x " + std::to_string(axes) +
                        " matrix (one row and one column per actuator of " + quoted(mjcf_path) +
                        ")");
    }
    for (std::size_t r = 0; r < axes; ++r) {
      for (std::size_t c = 0; c < axes; ++c) {
        coupling(static_cast<Eigen::Index>(r), static_cast<Eigen::Index>(c)) = rows[r][c];
      }
    }
  }
  const Eigen::JacobiSVD<Eigen::MatrixXd> svd(coupling);
  const Eigen::VectorXd singular = svd.singularValues();
  const double rcond = singular(singular.size() - 1) / singular(0);
  if (!(rcond > 1e-9)) {
    throw ConfigError(robot_file->coupling_where +
                      ": error: robot.transmission.coupling is singular (smallest / largest "
                      "singular value " +
                      num(rcond) + "): joints cannot be computed from the actuators");
  }
  const RowMatrix inverse = coupling.inverse();
  const bool coupled = !coupling.isIdentity(0.0);

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

  // The joint whose range is an axis' range: the joint with the axis' name, else the actuator
  // joint of an uncoupled axis (row i of M = unit row), else none.
  std::vector<int> range_joint(axes, -1);
  for (std::size_t i = 0; i < axes; ++i) {
    const int named = mj_name2id(m, mjOBJ_JOINT, axis_names[i].c_str());
    bool unit_row = true;
    for (std::size_t c = 0; c < axes; ++c) {
      const double expected = c == i ? 1.0 : 0.0;
      unit_row = unit_row &&
                 coupling(static_cast<Eigen::Index>(i), static_cast<Eigen::Index>(c)) == expected;
    }
    range_joint[i] = named >= 0 ? named : (unit_row ? actuator_joint[i] : -1);
  }

  // Power-on pose (joint coordinates).
  std::vector<double> power_on(axes);
  const std::string initial_where =
      initial ? params.location_of("initial_joint_positions").str() : std::string();
  if (initial) {
    if (initial->size() != axes) {
      throw ConfigError(initial_where + ": error: initial_joint_positions has " +
                        std::to_string(initial->size()) + " values for " + std::to_string(axes) +
                        " axes");
    }
    for (std::size_t i = 0; i < axes; ++i) {
      const double q = (*initial)[i];
      const int j = range_joint[i];
      if (!std::isfinite(q)) {
        throw ConfigError(initial_where + ": error: initial_joint_positions[" +
                          std::to_string(i) + "] is not a finite number");
      }
      if (j >= 0 && m->jnt_limited[j] != 0 &&
          (q < m->jnt_range[2 * j] || q > m->jnt_range[2 * j + 1])) {
        throw ConfigError(initial_where + ": error: initial_joint_positions[" +
                          std::to_string(i) + "] = " + num(q) + " rad is outside the range [" +
                          num(m->jnt_range[2 * j]) + ", " + num(m->jnt_range[2 * j + 1]) +
                          "] rad of joint '" + joint_name(m, j) + "'");
      }
      power_on[i] = q;
    }
  } else {
    for (std::size_t i = 0; i < axes; ++i) {
      const int j = range_joint[i];
      double q = synchro[i] + kDefaultPowerOnOffset;
      if (j >= 0 && m->jnt_limited[j] != 0) {
        q = std::clamp(q, m->jnt_range[2 * j], m->jnt_range[2 * j + 1]);
      }
      power_on[i] = q;
    }
  }
  // Errors of the power-on pose: the configuration's when it was given, else the model's.
  const auto fail = [&](const std::string& text) {
    if (initial) {
      throw ConfigError(initial_where + ": error: initial_joint_positions " + text);
    }
    throw HardwareError("mujoco: " + quoted(mjcf_path) + ": the default power-on pose " + text);
  };
  Eigen::VectorXd q_on(static_cast<Eigen::Index>(axes));
  for (std::size_t i = 0; i < axes; ++i) {
    q_on(static_cast<Eigen::Index>(i)) = power_on[i];
  }
  const Eigen::VectorXd a_on = coupling * q_on;
  std::vector<double> actuator_targets(axes);
  for (std::size_t i = 0; i < axes; ++i) {
    const double a = a_on(static_cast<Eigen::Index>(i));
    const int j = actuator_joint[i];
    actuator_targets[i] = a;
    if (m->jnt_limited[j] != 0 && (a < m->jnt_range[2 * j] || a > m->jnt_range[2 * j + 1])) {
      fail("puts joint '" + joint_name(m, j) + "' (actuator '" + axis_names[i] + "') at " +
           num(a) + " rad, outside its range [" + num(m->jnt_range[2 * j]) + ", " +
           num(m->jnt_range[2 * j + 1]) + "] rad");
    }
  }

  std::unique_ptr<mjData, DataDeleter> data(mj_makeData(m));
  if (!data) {
    throw HardwareError("mujoco: cannot allocate the simulation data of " + quoted(mjcf_path));
  }

  // The whole state at power-on: actuator joints at M q, passive joints closing the loops.
  std::vector<int> qpos_adr(axes);
  std::vector<int> dof_adr(axes);
  for (std::size_t i = 0; i < axes; ++i) {
    qpos_adr[i] = m->jnt_qposadr[actuator_joint[i]];
    dof_adr[i] = m->jnt_dofadr[actuator_joint[i]];
  }
  mjData* d = data.get();
  mj_resetData(m, d);
  const double violation = close_loops(m, d, qpos_adr, actuator_targets);
  if (!(violation <= kLoopClosureTolerance)) {
    fail("cannot be reached with closed kinematic loops: equality constraint violation " +
         num(violation) + " after solving for the passive joints (tolerance " +
         num(kLoopClosureTolerance) + ")");
  }
  for (int j = 0; j < m->njnt; ++j) {
    if (driven_by[index(j)] >= 0 || m->jnt_limited[j] == 0) {
      continue;
    }
    const double value = d->qpos[m->jnt_qposadr[j]];
    if (value < m->jnt_range[2 * j] - 1e-9 || value > m->jnt_range[2 * j + 1] + 1e-9) {
      fail("puts the passive joint '" + joint_name(m, j) + "' at " + num(value) +
           ", outside its range [" + num(m->jnt_range[2 * j]) + ", " +
           num(m->jnt_range[2 * j + 1]) + "]");
    }
  }
  for (std::size_t i = 0; i < axes; ++i) {
    const int j = range_joint[i];
    if (j < 0 || j == actuator_joint[i]) {
      continue;
    }
    const double value = d->qpos[m->jnt_qposadr[j]];
    if (std::abs(value - power_on[i]) > kCouplingTolerance) {
      throw HardwareError("mujoco: robot.transmission.coupling of " + quoted(robot_file_path) +
                          " does not match " + quoted(mjcf_path) + ": at the power-on pose axis '" +
                          axis_names[i] + "' is at " + num(power_on[i]) + " but joint '" +
                          joint_name(m, j) + "' at " + num(value));
    }
  }
  std::vector<double> power_on_qpos(d->qpos, d->qpos + m->nq);

  // Commit.
  actuator_joint_ = std::move(actuator_joint);
  qpos_adr_ = std::move(qpos_adr);
  dof_adr_ = std::move(dof_adr);
  power_on_ = std::move(power_on);
  synchro_ = std::move(synchro);
  power_on_qpos_ = std::move(power_on_qpos);
  coupled_ = coupled;
  coupling_.assign(coupling.data(), coupling.data() + coupling.size());
  inverse_coupling_.assign(inverse.data(), inverse.data() + inverse.size());
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

void MujocoHardware::joints_from_actuators(const double* a, double* q) const noexcept {
  if (!coupled_) {
    for (std::size_t i = 0; i < axes_; ++i) {
      q[i] = a[i];
    }
    return;
  }
  for (std::size_t r = 0; r < axes_; ++r) {
    double sum = 0.0;
    for (std::size_t c = 0; c < axes_; ++c) {
      sum += inverse_coupling_[r * axes_ + c] * a[c];
    }
    q[r] = sum;
  }
}

void MujocoHardware::reset_to_power_on() noexcept {
  have_previous_ctrl_ = false;
  mj_resetData(model_, data_);
  for (int i = 0; i < model_->nq; ++i) {
    data_->qpos[i] = power_on_qpos_[index(i)];
  }
  for (std::size_t i = 0; i < axes_; ++i) {
    data_->ctrl[i] = data_->qpos[qpos_adr_[i]];
  }
  mj_forward(model_, data_);
  for (int v = 0; v < model_->nv; ++v) {
    data_->qfrc_applied[v] = gravity_compensation_ ? data_->qfrc_bias[v] : 0.0;
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

double MujocoHardware::equality_violation() const noexcept {
  if (model_ == nullptr || data_ == nullptr) {
    return 0.0;
  }
  return equality_rows_violation(data_);
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
    a[i] = data_->qpos[qpos_adr_[i]];
  }
  joints_from_actuators(a, q);
  for (std::size_t i = 0; i < axes_; ++i) {
    out[i].position = q[i] - power_on_[i];
    out[i].synchro_switch = q[i] > synchro_[i];
    if (i < switch_state_.size()) switch_state_[i] = out[i].synchro_switch;
  }
  for (std::size_t i = 0; i < axes_; ++i) {
    a[i] = data_->qvel[dof_adr_[i]];
  }
  joints_from_actuators(a, q);
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
  if (coupled_) {
    for (std::size_t r = 0; r < axes_; ++r) {
      double sum = 0.0;
      for (std::size_t c = 0; c < axes_; ++c) {
        sum += coupling_[r * axes_ + c] * (setpoints[c] + power_on_[c]);
      }
      data_->ctrl[r] = sum;
    }
  } else {
    for (std::size_t i = 0; i < axes_; ++i) {
      data_->ctrl[i] = setpoints[i] + power_on_[i];
    }
  }
  // Servo algorithm 1: velocity feed-forward. The joint's viscous friction (damping) is what
  // makes a position servo lag by damping / kp * velocity; feeding the commanded velocity's
  // friction force forward removes that lag.
  for (std::size_t i = 0; i < axes_; ++i) {
    const double velocity = have_previous_ctrl_
                                ? (data_->ctrl[i] - previous_ctrl_[i]) / (substeps_ * model_->opt.timestep)
                                : 0.0;
    previous_ctrl_[i] = data_->ctrl[i];
    feed_forward_[i] = servo_algorithm_[i] == 1
                           ? model_->dof_damping[dof_adr_[i]] * velocity
                           : 0.0;
  }
  have_previous_ctrl_ = true;
  for (int s = 0; s < substeps_; ++s) {
    if (gravity_compensation_) {
      // Gravity and Coriolis feed-forward evaluated at the state of this step: mj_step1 computes
      // qfrc_bias from the current positions and velocities, mj_step2 integrates.
      mj_step1(model_, data_);
      for (int v = 0; v < model_->nv; ++v) {
        data_->qfrc_applied[v] = data_->qfrc_bias[v];
      }
      for (std::size_t i = 0; i < axes_; ++i)
        data_->qfrc_applied[dof_adr_[i]] += feed_forward_[i];
      mj_step2(model_, data_);
    } else {
      for (std::size_t i = 0; i < axes_; ++i) data_->qfrc_applied[dof_adr_[i]] = feed_forward_[i];
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
  joints_from_actuators(a.data(), q.data());
  return q;
}

std::vector<double> MujocoHardware::actuator_joint_positions() const {
  std::vector<double> a(axes_);
  for (std::size_t i = 0; i < axes_; ++i) {
    a[i] = data_->qpos[qpos_adr_[i]];
  }
  return a;
}

MRROC_REGISTER_HARDWARE("mujoco", MujocoHardware);

}  // namespace mrroc::edp
