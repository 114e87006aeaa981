/// @file
/// Generic URDF kinematics with orocos KDL (see kdl_solver.hpp).

#include "mrroc/kinematics/kdl_solver.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <optional>
#include <random>
#include <utility>

#include <urdf_parser/urdf_parser.h>
#include <kdl/chain.hpp>
#include <kdl/chainfksolverpos_recursive.hpp>
#include <kdl/chainiksolverpos_lma.hpp>
#include <kdl/chainjnttojacsolver.hpp>
#include <kdl/frames.hpp>
#include <kdl/jntarray.hpp>
#include <kdl/tree.hpp>
#include <kdl_parser/kdl_parser.hpp>

#include "mrroc/core/error.hpp"
#include "mrroc/msg/edp_instruction.hpp"

namespace mrroc::kinematics {

namespace {

namespace fs = std::filesystem;

constexpr double kTwoPi = 2.0 * std::numbers::pi;
constexpr double kInf = std::numeric_limits<double>::infinity();
/// Retries of one attempt from its solution projected into the joint limits.
constexpr int kLimitProjections = 2;

enum class JointKind { revolute, continuous, prismatic };

[[noreturn]] void bad_argument(const std::string& text) {
  throw CommandError(edp::error_code::bad_argument, text);
}
[[noreturn]] void out_of_limits(const std::string& text) {
  throw CommandError(edp::error_code::out_of_limits, text);
}

KDL::Frame to_kdl(const Eigen::Isometry3d& frame) {
  KDL::Frame out;
  const Eigen::Matrix3d r = frame.linear();
  out.M = KDL::Rotation(r(0, 0), r(0, 1), r(0, 2), r(1, 0), r(1, 1), r(1, 2), r(2, 0), r(2, 1),
                        r(2, 2));
  out.p = KDL::Vector(frame.translation().x(), frame.translation().y(), frame.translation().z());
  return out;
}

Eigen::Isometry3d to_eigen(const KDL::Frame& frame) {
  Eigen::Isometry3d out = Eigen::Isometry3d::Identity();
  Eigen::Matrix3d r;
  for (int row = 0; row < 3; ++row) {
    for (int col = 0; col < 3; ++col) {
      r(row, col) = frame.M(row, col);
    }
  }
  out.linear() = r;
  out.translation() = Eigen::Vector3d(frame.p.x(), frame.p.y(), frame.p.z());
  return out;
}

/// Position [m] and orientation angle [rad] between two frames.
std::pair<double, double> residual(const Eigen::Isometry3d& a, const Eigen::Isometry3d& b) {
  const double position = (a.translation() - b.translation()).norm();
  const Eigen::AngleAxisd rotation(a.linear().transpose() * b.linear());
  return {position, std::abs(rotation.angle())};
}

}  // namespace

struct KdlSolver::Impl {
  fs::path urdf;
  std::string base;
  std::string tip;
  KdlSolverOptions options;
  KDL::Chain chain;
  std::vector<std::string> names;
  std::vector<JointKind> kinds;
  std::vector<double> lower;
  std::vector<double> upper;
  /// Seeds of the restarts (fixed sequence).
  std::vector<std::vector<double>> restart_seeds;

  [[nodiscard]] std::size_t size() const { return names.size(); }

  void check_vector(const std::vector<double>& q, const char* what) const {
    if (q.size() != size())
      bad_argument(fmt::format("{} has {} joint values, the chain {} -> {} of {} has {} joints",
                               what, q.size(), base, tip, urdf.string(), size()));
    for (std::size_t i = 0; i < q.size(); ++i) {
      if (!std::isfinite(q[i]))
        bad_argument(fmt::format("{}: joint {} ({}) value {} is not a finite number", what, i,
                                 names[i], q[i]));
    }
  }

  [[nodiscard]] const char* unit(std::size_t i) const {
    return kinds[i] == JointKind::prismatic ? "m" : "rad";
  }

  [[nodiscard]] Eigen::Isometry3d fk(const std::vector<double>& q) const {
    KDL::ChainFkSolverPos_recursive solver(chain);
    KDL::JntArray joints(static_cast<unsigned int>(size()));
    for (std::size_t i = 0; i < size(); ++i) joints(static_cast<unsigned int>(i)) = q[i];
    KDL::Frame frame;
    solver.JntToCart(joints, frame);
    return to_eigen(frame);
  }

  /// Refinement of an LMA result on the exact pose error (Levenberg-Marquardt with adaptive
  /// damping). KDL measures rotations with its global epsilon (1e-6), so LMA alone leaves
  /// orientation errors of up to about 1e-6 rad, and it can stall near singular configurations
  /// (wrist centre on the waist axis, wrist singularity); these steps bring the error to rounding.
  void refine(std::vector<double>& q, const Eigen::Isometry3d& target,
              const Eigen::Matrix<double, 6, 1>& weights) const {
    KDL::ChainJntToJacSolver jacobian_solver(chain);
    const auto n = static_cast<unsigned int>(size());
    KDL::JntArray joints(n);
    KDL::Jacobian jacobian(n);
    const auto weighted_error = [&](const std::vector<double>& joints_now) {
      const Eigen::Isometry3d frame = fk(joints_now);
      Eigen::Matrix<double, 6, 1> error;
      error.head<3>() = target.translation() - frame.translation();
      const Eigen::AngleAxisd rotation(target.linear() * frame.linear().transpose());
      error.tail<3>() = rotation.angle() * rotation.axis();
      return Eigen::Matrix<double, 6, 1>(weights.cwiseProduct(error));
    };
    Eigen::Matrix<double, 6, 1> error = weighted_error(q);
    double damping = 1e-12;
    for (int iteration = 0; iteration < 100 && error.norm() > 1e-15; ++iteration) {
      for (unsigned int i = 0; i < n; ++i) joints(i) = q[i];
      if (jacobian_solver.JntToJac(joints, jacobian) < 0) return;
      // KDL's Jacobian: rows (linear velocity of the tip, angular velocity), base frame.
      const Eigen::MatrixXd weighted = weights.asDiagonal() * jacobian.data;
      const Eigen::MatrixXd normal = weighted.transpose() * weighted;
      const Eigen::VectorXd gradient = weighted.transpose() * error;
      bool improved = false;
      while (!improved && damping < 1e6) {
        const Eigen::MatrixXd damped =
            normal + damping * Eigen::MatrixXd::Identity(normal.rows(), normal.cols());
        const Eigen::VectorXd step = damped.ldlt().solve(gradient);
        std::vector<double> candidate = q;
        for (unsigned int i = 0; i < n; ++i) candidate[i] += step(i);
        const Eigen::Matrix<double, 6, 1> candidate_error = weighted_error(candidate);
        if (candidate_error.norm() < error.norm()) {
          q = std::move(candidate);
          error = candidate_error;
          damping = std::max(1e-12, damping * 0.1);
          improved = true;
        } else {
          damping *= 10.0;
        }
      }
      if (!improved) return;  // no step reduces the error: keep the best joints
    }
  }

  /// Shifts revolute joints by whole turns into their limits (when possible) and continuous
  /// joints to the turn nearest the seed.
  void normalise(std::vector<double>& q, const std::vector<double>& seed) const {
    for (std::size_t i = 0; i < size(); ++i) {
      if (kinds[i] == JointKind::continuous) {
        q[i] -= kTwoPi * std::round((q[i] - seed[i]) / kTwoPi);
      } else if (kinds[i] == JointKind::revolute && (q[i] < lower[i] || q[i] > upper[i])) {
        const double shifted_up = q[i] + kTwoPi * std::ceil((lower[i] - q[i]) / kTwoPi);
        const double shifted_down = q[i] - kTwoPi * std::ceil((q[i] - upper[i]) / kTwoPi);
        if (q[i] < lower[i] && shifted_up <= upper[i]) {
          q[i] = shifted_up;
        } else if (q[i] > upper[i] && shifted_down >= lower[i]) {
          q[i] = shifted_down;
        }
      }
    }
  }

  /// The first joint outside its limits, as text; empty when all are inside.
  [[nodiscard]] std::string limit_violation(const std::vector<double>& q) const {
    for (std::size_t i = 0; i < size(); ++i) {
      if (q[i] > upper[i])
        return fmt::format("joint {} ({}) {:.6f} {} exceeds upper limit {:.6f} {}", i, names[i],
                           q[i], unit(i), upper[i], unit(i));
      if (q[i] < lower[i])
        return fmt::format("joint {} ({}) {:.6f} {} is below lower limit {:.6f} {}", i, names[i],
                           q[i], unit(i), lower[i], unit(i));
    }
    return {};
  }
};

KdlSolver::KdlSolver(const fs::path& urdf, const std::string& base, const std::string& tip,
                     KdlSolverOptions options)
    : impl_(std::make_unique<Impl>()) {
  Impl& s = *impl_;
  s.urdf = urdf;
  s.base = base;
  s.tip = tip;
  s.options = options;
  if (!fs::exists(urdf))
    throw ConfigError(SourceLocation::whole_file(urdf.string()), "URDF file not found");
  const urdf::ModelInterfaceSharedPtr model = urdf::parseURDFFile(urdf.string());
  if (!model)
    throw ConfigError(SourceLocation::whole_file(urdf.string()), "the URDF does not parse");
  KDL::Tree tree;
  if (!kdl_parser::treeFromUrdfModel(*model, tree))
    throw ConfigError(SourceLocation::whole_file(urdf.string()),
                      "kdl_parser cannot build a KDL tree from the URDF");
  if (!tree.getChain(base, tip, s.chain) || s.chain.getNrOfSegments() == 0) {
    std::string links;
    for (const auto& [name, link] : model->links_) links += (links.empty() ? "" : ", ") + name;
    throw ConfigError(SourceLocation::whole_file(urdf.string()),
                      fmt::format("no kinematic chain from link '{}' to link '{}' (links: {})",
                                  base, tip, links));
  }
  for (const KDL::Segment& segment : s.chain.segments) {
    const KDL::Joint& joint = segment.getJoint();
    if (joint.getType() == KDL::Joint::None) continue;
    const urdf::JointConstSharedPtr uj = model->getJoint(joint.getName());
    if (!uj)
      throw ConfigError(
          SourceLocation::whole_file(urdf.string()),
          fmt::format("joint '{}' of the KDL chain is not in the URDF", joint.getName()));
    s.names.push_back(joint.getName());
    if (uj->type == urdf::Joint::CONTINUOUS) {
      s.kinds.push_back(JointKind::continuous);
      s.lower.push_back(-kInf);
      s.upper.push_back(kInf);
      continue;
    }
    s.kinds.push_back(uj->type == urdf::Joint::PRISMATIC ? JointKind::prismatic
                                                         : JointKind::revolute);
    if (!uj->limits)
      throw ConfigError(SourceLocation::whole_file(urdf.string()),
                        fmt::format("joint '{}' has no <limit>", joint.getName()));
    s.lower.push_back(uj->limits->lower);
    s.upper.push_back(uj->limits->upper);
  }
  if (s.names.empty())
    throw ConfigError(
        SourceLocation::whole_file(urdf.string()),
        fmt::format("the chain from link '{}' to link '{}' has no movable joint", base, tip));

  // Restart seeds: uniformly spread over the joint ranges (unlimited: -pi .. pi), fixed sequence.
  std::mt19937 rng(20240607U);
  for (int k = 0; k < std::max(0, options.restarts); ++k) {
    std::vector<double> seed(s.size());
    for (std::size_t i = 0; i < s.size(); ++i) {
      const double lo = std::isfinite(s.lower[i]) ? s.lower[i] : -std::numbers::pi;
      const double hi = std::isfinite(s.upper[i]) ? s.upper[i] : std::numbers::pi;
      seed[i] = std::uniform_real_distribution<double>(lo, hi)(rng);
    }
    s.restart_seeds.push_back(std::move(seed));
  }
}

KdlSolver::~KdlSolver() = default;
KdlSolver::KdlSolver(KdlSolver&&) noexcept = default;
KdlSolver& KdlSolver::operator=(KdlSolver&&) noexcept = default;

std::size_t KdlSolver::joint_count() const { return impl_->size(); }
const std::vector<std::string>& KdlSolver::joint_names() const { return impl_->names; }
const std::vector<double>& KdlSolver::lower_limits() const { return impl_->lower; }
const std::vector<double>& KdlSolver::upper_limits() const { return impl_->upper; }
const KdlSolverOptions& KdlSolver::options() const { return impl_->options; }

Eigen::Isometry3d KdlSolver::forward(const std::vector<double>& q) const {
  impl_->check_vector(q, "forward kinematics joints");
  return impl_->fk(q);
}

std::vector<double> KdlSolver::inverse(const Eigen::Isometry3d& target,
                                       const std::vector<double>& seed) const {
  const Impl& s = *impl_;
  s.check_vector(seed, "inverse kinematics seed");
  if (!target.matrix().allFinite())
    bad_argument("inverse kinematics target frame has a value that is not a finite number");

  const KdlSolverOptions& o = s.options;
  Eigen::Matrix<double, 6, 1> weights;
  weights << 1.0, 1.0, 1.0, o.orientation_weight, o.orientation_weight, o.orientation_weight;
  // LMA's own tolerance applies to the weighted error; the result is checked below anyway.
  const double eps =
      1e-3 * std::min(o.position_tolerance, o.orientation_weight * o.orientation_tolerance);
  KDL::ChainIkSolverPos_LMA solver(s.chain, weights, eps, o.max_iterations);
  const KDL::Frame goal = to_kdl(target);
  const auto n = static_cast<unsigned int>(s.size());

  double best_position = kInf;
  double best_orientation = kInf;
  std::optional<std::string> first_limit_text;
  const std::size_t attempts = 1 + s.restart_seeds.size();
  for (std::size_t attempt = 0; attempt < attempts; ++attempt) {
    std::vector<double> start = attempt == 0 ? seed : s.restart_seeds[attempt - 1];
    // A solution outside the limits is retried from its projection into the limits, which
    // usually leads to the configuration inside them when there is one nearby.
    for (int projection = 0; projection <= kLimitProjections; ++projection) {
      KDL::JntArray q_init(n);
      KDL::JntArray q_out(n);
      for (unsigned int i = 0; i < n; ++i) q_init(i) = start[i];
      solver.CartToJnt(q_init, goal, q_out);
      std::vector<double> q(s.size());
      bool finite = true;
      for (unsigned int i = 0; i < n; ++i) {
        q[i] = q_out(i);
        finite = finite && std::isfinite(q[i]);
      }
      if (!finite) break;
      s.refine(q, target, weights);
      s.normalise(q, seed);
      const auto [position, orientation] = residual(s.fk(q), target);
      if (position > o.position_tolerance || orientation > o.orientation_tolerance) {
        if (position + o.orientation_weight * orientation <
            best_position + o.orientation_weight * best_orientation) {
          best_position = position;
          best_orientation = orientation;
        }
        break;
      }
      std::string violation = s.limit_violation(q);
      if (violation.empty()) return q;
      if (!first_limit_text) first_limit_text = std::move(violation);
      for (std::size_t i = 0; i < s.size(); ++i)
        start[i] = std::clamp(q[i], s.lower[i], s.upper[i]);
    }
  }
  if (first_limit_text)
    out_of_limits("inverse kinematics: solution outside the joint limits: " + *first_limit_text);
  out_of_limits(fmt::format(
      "inverse kinematics did not converge: residual {:.6f} m, {:.6f} rad "
      "(tolerance {:g} m, {:g} rad; {} attempts)",
      best_position, best_orientation, o.position_tolerance, o.orientation_tolerance, attempts));
}

}  // namespace mrroc::kinematics
