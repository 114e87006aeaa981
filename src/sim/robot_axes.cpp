#include "mrroc/sim/robot_axes.hpp"

#include <algorithm>
#include <cmath>
#include <utility>

#include <Eigen/Dense>

#include "mrroc/core/error.hpp"
#include "mrroc/sim/mujoco_support.hpp"

namespace mrroc::sim {
namespace {

std::size_t index(int i) { return static_cast<std::size_t>(i); }

std::string name_list(const std::vector<std::string>& names) {
  std::string text;
  for (std::size_t i = 0; i < names.size(); ++i) text += (i == 0 ? "" : ", ") + names[i];
  return text;
}

bool outside(const mjModel* m, int joint, double value, double slack = 0.0) {
  return m->jnt_limited[joint] != 0 &&
         (value < m->jnt_range[2 * joint] - slack || value > m->jnt_range[2 * joint + 1] + slack);
}

std::string range_text(const mjModel* m, int joint) {
  // Appended piece by piece: GCC 12's -O3 warns (-Wstringop-overflow) about `"[" + std::string`,
  // a false positive.
  std::string text(1, '[');
  text += format_number(m->jnt_range[2 * joint]);
  text += ", ";
  text += format_number(m->jnt_range[2 * joint + 1]);
  text += ']';
  return text;
}

/// Errors of the power-on pose: the configuration's when it was given, else the model's.
[[noreturn]] void power_on_failure(const PowerOnRequest& request, const ModelContext& context,
                                   const std::string& text) {
  if (request.given) {
    throw ConfigError(request.given_where, "initial_joint_positions " + text);
  }
  throw HardwareError(context.who + ": " + quoted(context.mjcf) + ": the default power-on pose " +
                      text);
}

}  // namespace

void check_hinge_or_slide(const mjModel* m, std::span<const int> joints,
                          const ModelContext& context) {
  for (const int j : joints) {
    if (m->jnt_type[j] != mjJNT_HINGE && m->jnt_type[j] != mjJNT_SLIDE) {
      throw HardwareError(context.who + ": model " + quoted(context.mjcf) + ": joint '" +
                          joint_name(m, j) +
                          "' is neither a hinge nor a slide joint (only those are supported)");
    }
  }
}

RobotAxes map_axes(const mjModel* m, int first, int count, const std::string& prefix,
                   const ModelContext& context) {
  const std::string model = context.who + ": model " + quoted(context.mjcf);
  if (count <= 0) {
    throw HardwareError(model + " has no actuators (one position actuator per axis is required)");
  }
  RobotAxes axes;
  axes.prefix = prefix;
  const auto strip = [&](std::string name) {
    return name.compare(0, prefix.size(), prefix) == 0 ? name.substr(prefix.size()) : name;
  };
  for (int a = first; a < first + count; ++a) {
    const int joint = m->actuator_trnid[2 * a];
    const char* name = mj_id2name(m, mjOBJ_ACTUATOR, a);
    if (m->actuator_trntype[a] != mjTRN_JOINT || joint < 0 || joint >= m->njnt) {
      throw HardwareError(model + ": actuator '" +
                          (name != nullptr ? name : std::to_string(a - first)) +
                          "' does not drive a joint");
    }
    if (std::find(axes.joint.begin(), axes.joint.end(), joint) != axes.joint.end()) {
      throw HardwareError(model + ": joint '" + joint_name(m, joint) +
                          "' has more than one actuator");
    }
    axes.actuator.push_back(a);
    axes.joint.push_back(joint);
    axes.qpos_adr.push_back(m->jnt_qposadr[joint]);
    axes.dof_adr.push_back(m->jnt_dofadr[joint]);
    axes.names.push_back(strip(name != nullptr ? std::string(name) : joint_name(m, joint)));
  }
  return axes;
}

void check_axis_names(const RobotAxes& axes,
                      const std::optional<std::vector<std::string>>& joint_names,
                      const ModelContext& context) {
  if (joint_names && *joint_names != axes.names) {
    throw HardwareError(context.who + ": actuators of " + quoted(context.mjcf) + " (" +
                        name_list(axes.names) + ") do not match robot.joint_names of " +
                        quoted(context.parameters_file) + " (" + name_list(*joint_names) + ")");
  }
}

void plan_power_on(const mjModel* m, RobotAxes& axes, Coupling coupling,
                   std::vector<double> synchro, const std::string& synchro_source,
                   const PowerOnRequest& request, const ModelContext& context) {
  const std::size_t n = axes.size();
  if (synchro.size() != n) {
    throw HardwareError(context.who + ": " + std::to_string(synchro.size()) +
                        " synchronisation positions from " + synchro_source + " for " +
                        std::to_string(n) + " axes of " + quoted(context.mjcf));
  }
  // The joint whose range is an axis' range: the joint with the axis' name, else the actuator
  // joint of an uncoupled axis (row i of M = unit row), else none.
  std::vector<int> range_joint(n, -1);
  for (std::size_t i = 0; i < n; ++i) {
    const int named = mj_name2id(m, mjOBJ_JOINT, (axes.prefix + axes.names[i]).c_str());
    range_joint[i] = named >= 0 ? named : (coupling.unit_row(i) ? axes.joint[i] : -1);
  }

  std::vector<double> power_on(n);
  if (request.given) {
    const std::vector<double>& given = *request.given;
    const std::string key = "initial_joint_positions";
    if (given.size() != n) {
      throw ConfigError(request.given_where, key + " has " + std::to_string(given.size()) +
                                                 " values for " + std::to_string(n) + " axes");
    }
    for (std::size_t i = 0; i < n; ++i) {
      const double q = given[i];
      const int j = range_joint[i];
      if (!std::isfinite(q)) {
        throw ConfigError(request.given_where,
                          key + "[" + std::to_string(i) + "] is not a finite number");
      }
      if (j >= 0 && outside(m, j, q)) {
        throw ConfigError(request.given_where, key + "[" + std::to_string(i) +
                                                   "] = " + format_number(q) +
                                                   " rad is outside the range " + range_text(m, j) +
                                                   " rad of joint '" + joint_name(m, j) + "'");
      }
      power_on[i] = q;
    }
  } else {
    for (std::size_t i = 0; i < n; ++i) {
      const int j = range_joint[i];
      double q = synchro[i] + kDefaultPowerOnOffset;
      if (j >= 0 && m->jnt_limited[j] != 0) {
        q = std::clamp(q, m->jnt_range[2 * j], m->jnt_range[2 * j + 1]);
      }
      power_on[i] = q;
    }
  }
  std::vector<double> actuators(n);
  coupling.actuators_from_joints(power_on.data(), actuators.data());
  for (std::size_t i = 0; i < n; ++i) {
    const int j = axes.joint[i];
    if (outside(m, j, actuators[i])) {
      power_on_failure(request, context,
                       "puts joint '" + joint_name(m, j) + "' (actuator '" + axes.names[i] +
                           "') at " + format_number(actuators[i]) + " rad, outside its range " +
                           range_text(m, j) + " rad");
    }
  }
  axes.coupling = std::move(coupling);
  axes.range_joint = std::move(range_joint);
  axes.synchro = std::move(synchro);
  axes.power_on = std::move(power_on);
  axes.power_on_actuators = std::move(actuators);
}

double close_loops(const mjModel* m, mjData* d, std::span<const int> actuator_qpos,
                   std::span<const double> targets) {
  // Passive degrees of freedom: those of hinge and slide joints that no actuator holds (one
  // coordinate each, so qpos and qvel addresses correspond through the joint).
  std::vector<int> passive;       // dof addresses
  std::vector<int> passive_qpos;  // their qpos addresses
  for (int j = 0; j < m->njnt; ++j) {
    if (m->jnt_type[j] != mjJNT_HINGE && m->jnt_type[j] != mjJNT_SLIDE) continue;
    const int adr = m->jnt_qposadr[j];
    if (std::find(actuator_qpos.begin(), actuator_qpos.end(), adr) != actuator_qpos.end()) continue;
    passive.push_back(m->jnt_dofadr[j]);
    passive_qpos.push_back(adr);
  }
  const std::size_t nv = index(m->nv);
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
        if (d->efc_type[r] == mjCNSTR_EQUALITY) rows.push_back(r);
      }
      if (rows.empty() || passive.empty()) break;
      Eigen::MatrixXd jacobian = Eigen::MatrixXd::Zero(static_cast<Eigen::Index>(rows.size()),
                                                       static_cast<Eigen::Index>(passive.size()));
      Eigen::VectorXd residual(static_cast<Eigen::Index>(rows.size()));
      double worst = 0.0;
      std::vector<double> dense(nv);
      for (std::size_t r = 0; r < rows.size(); ++r) {
        const int row = rows[r];
        const auto er = static_cast<Eigen::Index>(r);
        residual(er) = d->efc_pos[row];
        worst = std::max(worst, std::abs(d->efc_pos[row]));
        std::fill(dense.begin(), dense.end(), 0.0);
        if (sparse) {
          const int adr = d->efc_J_rowadr[row];
          for (int e = 0; e < d->efc_J_rownnz[row]; ++e) {
            dense[index(d->efc_J_colind[adr + e])] = d->efc_J[adr + e];
          }
        } else {
          for (std::size_t v = 0; v < nv; ++v) dense[v] = d->efc_J[index(row) * nv + v];
        }
        for (std::size_t c = 0; c < passive.size(); ++c) {
          jacobian(er, static_cast<Eigen::Index>(c)) = dense[index(passive[c])];
        }
      }
      if (worst < 1e-13) break;
      // Least-squares step; the rank deficiency of planar loops (a 3-D connect closing a planar
      // loop has a redundant row) is handled by the complete orthogonal decomposition.
      Eigen::CompleteOrthogonalDecomposition<Eigen::MatrixXd> solver(jacobian);
      solver.setThreshold(1e-10);
      const Eigen::VectorXd step = solver.solve(residual);
      for (std::size_t c = 0; c < passive.size(); ++c) {
        d->qpos[passive_qpos[c]] -= step(static_cast<Eigen::Index>(c));
      }
    }
  }
  mj_fwdPosition(m, d);
  return equality_violation(d);
}

void check_power_on_state(const mjModel* m, const mjData* d, const RobotAxes& axes,
                          std::span<const int> robot_joints, double violation,
                          const PowerOnRequest& request, const ModelContext& context) {
  if (!(violation <= kLoopClosureTolerance)) {
    power_on_failure(request, context,
                     "cannot be reached with closed kinematic loops: equality constraint "
                     "violation " +
                         format_number(violation) +
                         " after solving for the passive joints (tolerance " +
                         format_number(kLoopClosureTolerance) + ")");
  }
  for (const int j : robot_joints) {
    if (std::find(axes.joint.begin(), axes.joint.end(), j) != axes.joint.end()) continue;
    const double value = d->qpos[m->jnt_qposadr[j]];
    if (outside(m, j, value, 1e-9)) {
      power_on_failure(request, context,
                       "puts the passive joint '" + joint_name(m, j) + "' at " +
                           format_number(value) + ", outside its range " + range_text(m, j));
    }
  }
  for (std::size_t i = 0; i < axes.size(); ++i) {
    const int j = axes.range_joint[i];
    if (j < 0 || j == axes.joint[i]) continue;
    const double value = d->qpos[m->jnt_qposadr[j]];
    if (std::abs(value - axes.power_on[i]) > kCouplingTolerance) {
      throw HardwareError(context.who + ": robot.transmission.coupling of " +
                          quoted(context.parameters_file) + " does not match " +
                          quoted(context.mjcf) + ": at the power-on pose axis '" + axes.names[i] +
                          "' is at " + format_number(axes.power_on[i]) + " but joint '" +
                          joint_name(m, j) + "' at " + format_number(value));
    }
  }
}

}  // namespace mrroc::sim
