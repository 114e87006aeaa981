/// @file
/// Generic Cartesian kinematics of a serial arm from its URDF (see urdf_arm.hpp).

#include "mrroc/kinematics/urdf_arm.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <exception>
#include <string>
#include <system_error>
#include <utility>

#include <urdf_parser/urdf_parser.h>

#include "mrroc/core/error.hpp"
#include "mrroc/kinematics/pose.hpp"
#include "mrroc/msg/edp_instruction.hpp"

namespace mrroc::kinematics {

namespace {

namespace fs = std::filesystem;

/// Link whose frame is the arm's tip when the URDF has it.
constexpr const char* kFlangeLink = "flange";

std::string joined(const std::vector<std::string>& names) {
  std::string out;
  for (const auto& n : names) out += (out.empty() ? "" : ", ") + n;
  return out;
}

Eigen::Isometry3d to_eigen(const urdf::Pose& pose) {
  Eigen::Isometry3d out = Eigen::Isometry3d::Identity();
  out.linear() =
      Eigen::Quaterniond(pose.rotation.w, pose.rotation.x, pose.rotation.y, pose.rotation.z)
          .normalized()
          .toRotationMatrix();
  out.translation() = Eigen::Vector3d(pose.position.x, pose.position.y, pose.position.z);
  return out;
}

/// The joints from the root link down to `tip`, in chain order (fixed ones included).
std::vector<urdf::JointConstSharedPtr> joints_to(const urdf::ModelInterface& urdf,
                                                 const std::string& tip) {
  std::vector<urdf::JointConstSharedPtr> joints;
  urdf::LinkConstSharedPtr link = urdf.getLink(tip);
  while (link && link->parent_joint) {
    joints.push_back(link->parent_joint);
    link = urdf.getLink(link->parent_joint->parent_link_name);
  }
  std::reverse(joints.begin(), joints.end());
  return joints;
}

bool movable(const urdf::Joint& joint) { return joint.type != urdf::Joint::FIXED; }

/// The first movable joint's origin at q = 0 in the base frame (a point of its axis, fixed for a
/// revolute joint) and a bound of the distance of `tip` from it over all joint values: the sum of
/// the joint origins' offsets after that joint and of every prismatic joint's largest travel [m].
std::pair<Eigen::Vector3d, double> chain_extent(const urdf::ModelInterface& urdf,
                                                const std::string& tip) {
  Eigen::Isometry3d to_first = Eigen::Isometry3d::Identity();
  double reach = 0.0;
  bool after_first = false;
  for (const auto& joint : joints_to(urdf, tip)) {
    const Eigen::Isometry3d origin = to_eigen(joint->parent_to_joint_origin_transform);
    if (after_first) {
      reach += origin.translation().norm();
    } else {
      to_first = to_first * origin;
      after_first = movable(*joint);
    }
    if (joint->type == urdf::Joint::PRISMATIC && joint->limits)
      reach += std::max(std::abs(joint->limits->lower), std::abs(joint->limits->upper));
  }
  return {to_first.translation(), reach};
}

}  // namespace

std::optional<SerialChain> find_serial_chain(const RobotModel& model, std::string& why_not) {
  why_not.clear();
  std::error_code ec;
  if (model.urdf.empty() || !fs::exists(model.urdf, ec)) {
    why_not = fmt::format("URDF file '{}' not found", model.urdf.string());
    return std::nullopt;
  }
  urdf::ModelInterfaceSharedPtr urdf;
  try {
    urdf = urdf::parseURDFFile(model.urdf.string());
  } catch (const std::exception& e) {
    why_not = fmt::format("{} does not parse: {}", model.urdf.string(), e.what());
    return std::nullopt;
  }
  if (!urdf || !urdf->getRoot()) {
    why_not = fmt::format("{} does not parse", model.urdf.string());
    return std::nullopt;
  }
  if (model.joint_names.empty()) {
    why_not = "the robot has no joints";
    return std::nullopt;
  }
  SerialChain chain;
  chain.base = urdf->getRoot()->name;
  if (urdf->getLink(kFlangeLink)) {
    chain.tip = kFlangeLink;
  } else {
    const urdf::JointConstSharedPtr last = urdf->getJoint(model.joint_names.back());
    if (!last) {
      why_not =
          fmt::format("joint '{}' is not in {}", model.joint_names.back(), model.urdf.string());
      return std::nullopt;
    }
    chain.tip = last->child_link_name;
  }
  std::vector<std::string> found;
  for (const auto& joint : joints_to(*urdf, chain.tip)) {
    if (!movable(*joint)) continue;
    if (joint->type == urdf::Joint::FLOATING || joint->type == urdf::Joint::PLANAR) {
      why_not = fmt::format(
          "joint '{}' of {} is floating or planar (KDL chains have only "
          "revolute, continuous and prismatic joints)",
          joint->name, model.urdf.string());
      return std::nullopt;
    }
    found.push_back(joint->name);
  }
  if (found != model.joint_names) {
    why_not = fmt::format(
        "the chain from link '{}' to link '{}' of {} has the movable joints [{}], "
        "parameters.toml's joint_names are [{}]",
        chain.base, chain.tip, model.urdf.string(), joined(found), joined(model.joint_names));
    return std::nullopt;
  }
  return chain;
}

UrdfArm::UrdfArm(const RobotModel& model, KdlSolverOptions options) : model_(model) {
  std::string why_not;
  const std::optional<SerialChain> chain = find_serial_chain(model, why_not);
  if (!chain)
    throw ConfigError(
        SourceLocation::whole_file(model.urdf.string()),
        "no serial chain of the robot's joints for the generic URDF kinematics: " + why_not);
  chain_ = *chain;
  std::vector<fs::path> files = model.kinematic_models;
  if (files.empty()) files.push_back(model.urdf);
  for (const auto& file : files) {
    KdlSolver solver(file, chain_.base, chain_.tip, options);
    if (solver.joint_names() != model.joint_names)
      throw ConfigError(SourceLocation::whole_file(file.string()),
                        fmt::format("kinematic model: the chain from link '{}' to link '{}' has "
                                    "the movable joints [{}], parameters.toml's joint_names are "
                                    "[{}]",
                                    chain_.base, chain_.tip, joined(solver.joint_names()),
                                    joined(model.joint_names)));
    const urdf::ModelInterfaceSharedPtr urdf = urdf::parseURDFFile(file.string());
    const auto [origin, reach] = chain_extent(*urdf, chain_.tip);
    first_axis_origin_.push_back(origin);
    reach_.push_back(reach);
    solvers_.push_back(std::move(solver));
  }
}

double UrdfArm::reach() const { return reach_[static_cast<std::size_t>(model_no_)]; }

void UrdfArm::select(int model_no, int corrector_no) {
  if (model_no < 0 || model_no >= model_count())
    throw CommandError(
        edp::error_code::bad_argument,
        fmt::format("kinematic model {} is outside 0..{} of robot '{}' "
                    "([robot.kinematics] models in {})",
                    model_no, model_count() - 1, model_.name, model_.parameters_file().string()));
  if (corrector_no < 0 || corrector_no >= corrector_count())
    throw CommandError(edp::error_code::bad_argument,
                       fmt::format("corrector {} is outside 0..{} of robot '{}' (0 = none; "
                                   "[robot.kinematics] correctors in {})",
                                   corrector_no, corrector_count() - 1, model_.name,
                                   model_.parameters_file().string()));
  corrector_ = Eigen::Isometry3d::Identity();
  if (corrector_no > 0)
    corrector_ = from_values(model_.correctors[static_cast<std::size_t>(corrector_no - 1)],
                             edp::ArmRepresentation::xyz_angle_axis);
  model_no_ = model_no;
}

Eigen::Isometry3d UrdfArm::forward(const std::vector<double>& q) const {
  return corrector_ * solver().forward(q) * tool_;
}

std::vector<double> UrdfArm::inverse(const Eigen::Isometry3d& target,
                                     const std::vector<double>& seed) const {
  if (!target.matrix().allFinite())
    throw CommandError(edp::error_code::bad_argument,
                       "inverse kinematics target frame has a value that is not a finite number");
  const Eigen::Isometry3d tip = corrector_.inverse() * target * tool_.inverse();
  std::vector<double> q;
  try {
    q = solver().inverse(tip, seed);
  } catch (const CommandError& e) {
    if (e.code() != edp::error_code::out_of_limits) throw;
    const Eigen::Vector3d p = target.translation();
    std::string where;
    if (std::string(e.what()).find("did not converge") != std::string::npos) {
      // How far the target is, against the longest the chain can stretch.
      const std::size_t model = static_cast<std::size_t>(model_no_);
      const double distance = (tip.translation() - first_axis_origin_[model]).norm();
      where = distance > reach_[model]
                  ? fmt::format(
                        "its {} is {:.4f} m from the first joint, beyond the arm's "
                        "reach {:.4f} m; ",
                        chain_.tip, distance, reach_[model])
                  : fmt::format(
                        "its {} is {:.4f} m from the first joint, within the arm's "
                        "reach {:.4f} m, but no configuration reaches it; ",
                        chain_.tip, distance, reach_[model]);
    }
    throw CommandError(edp::error_code::out_of_limits,
                       fmt::format("robot '{}': target ({:.4f}, {:.4f}, {:.4f}) m: {}{}",
                                   model_.name, p.x(), p.y(), p.z(), where, e.what()));
  }
  model_.check_joint_limits(q, "inverse kinematics solution");
  return q;
}

}  // namespace mrroc::kinematics
