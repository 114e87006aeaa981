/// @file
/// The EDP's collision guard (collision_guard.hpp).

#include "collision_guard.hpp"

#include <fmt/format.h>
#include <tinyxml2.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <chrono>
#include <cmath>

#include "mrroc/core/error.hpp"
#include "mrroc/kinematics/pose.hpp"
#include "mrroc/msg/edp_instruction.hpp"
#include "mrroc/sim/mujoco_support.hpp"

namespace mrroc::edp {
namespace {

namespace xml = tinyxml2;

/// Geom names of the fixed objects in the composed model.
std::string object_geom_name(std::size_t k) { return fmt::format("mrroc_collision_object_{}", k); }

Eigen::Isometry3d pose_of(const std::array<double, 6>& v) {
  Eigen::Isometry3d t = Eigen::Isometry3d::Identity();
  t.linear() = kinematics::rotation_from_rotation_vector(Eigen::Vector3d(v[3], v[4], v[5]));
  t.translation() = Eigen::Vector3d(v[0], v[1], v[2]);
  return t;
}

/// True when `body` or a body below it holds a joint named like one of `axes`.
bool holds_axis(const xml::XMLElement* body, const std::vector<std::string>& axes) {
  for (const xml::XMLElement* e = body->FirstChildElement(); e != nullptr;
       e = e->NextSiblingElement()) {
    const std::string_view tag = e->Name();
    if (tag == "joint") {
      const char* name = e->Attribute("name");
      if (name != nullptr && std::find(axes.begin(), axes.end(), name) != axes.end()) return true;
    } else if (tag == "body" && holds_axis(e, axes)) {
      return true;
    }
  }
  return false;
}

/// The robot's MJCF reduced to its own bodies, with the fixed objects in its base frame.
std::string compose(const std::filesystem::path& mjcf, const RobotModel& model,
                    const RobotConfig& robot, const CollisionConfig& config) {
  xml::XMLDocument doc;
  if (doc.LoadFile(mjcf.c_str()) != xml::XML_SUCCESS)
    throw ConfigError(
        SourceLocation::whole_file(mjcf.string()),
        fmt::format("collision guard: cannot read the MJCF model: {}", doc.ErrorStr()));
  xml::XMLElement* root = doc.FirstChildElement("mujoco");
  if (root == nullptr)
    throw ConfigError(SourceLocation::whole_file(mjcf.string()),
                      "collision guard: the MJCF model has no <mujoco> element");
  // What refers to bodies or joints that are left out, or to the state's size.
  for (const char* tag : {"actuator", "sensor", "equality", "tendon", "contact", "keyframe"})
    while (xml::XMLElement* e = root->FirstChildElement(tag)) root->DeleteChild(e);
  // Asset folders relative to the model's folder (the text is compiled from memory).
  const std::filesystem::path folder = mjcf.parent_path();
  xml::XMLElement* compiler = root->FirstChildElement("compiler");
  if (compiler == nullptr) compiler = root->InsertNewChildElement("compiler");
  for (const char* key : {"meshdir", "texturedir"}) {
    const char* value = compiler->Attribute(key);
    const std::filesystem::path dir = value == nullptr ? folder : folder / value;
    compiler->SetAttribute(key, dir.lexically_normal().c_str());
  }
  xml::XMLElement* world = root->FirstChildElement("worldbody");
  if (world == nullptr) world = root->InsertNewChildElement("worldbody");
  for (xml::XMLElement* w = world; w != nullptr; w = w->NextSiblingElement("worldbody")) {
    std::vector<xml::XMLElement*> drop;
    for (xml::XMLElement* e = w->FirstChildElement(); e != nullptr; e = e->NextSiblingElement()) {
      const std::string_view tag = e->Name();
      if (tag == "geom" || (tag == "body" && !holds_axis(e, model.joint_names))) drop.push_back(e);
    }
    for (xml::XMLElement* e : drop) w->DeleteChild(e);
  }
  const Eigen::Isometry3d base_inverse = pose_of(robot.base).inverse();
  for (std::size_t k = 0; k < config.objects.size(); ++k) {
    const CollisionObject& o = config.objects[k];
    const Eigen::Isometry3d in_base = base_inverse * pose_of(o.pose);
    const Eigen::Quaterniond q(in_base.linear());
    const Eigen::Vector3d p = in_base.translation();
    xml::XMLElement* g = world->InsertNewChildElement("geom");
    g->SetAttribute("name", object_geom_name(k).c_str());
    g->SetAttribute("type", "box");
    g->SetAttribute(
        "size", fmt::format("{} {} {}", o.half_size[0], o.half_size[1], o.half_size[2]).c_str());
    g->SetAttribute("pos", fmt::format("{} {} {}", p.x(), p.y(), p.z()).c_str());
    g->SetAttribute("quat", fmt::format("{} {} {} {}", q.w(), q.x(), q.y(), q.z()).c_str());
  }
  xml::XMLPrinter printer;
  doc.Print(&printer);
  return printer.CStr();
}

/// A pair of parts closer than the clearance, at its smallest distance.
struct PairDistance {
  int a = 0;
  int b = 0;
  double distance = 0;
};

}  // namespace

struct CollisionGuard::Impl {
  sim::ModelPtr model;
  sim::DataPtr data;
  std::vector<int> qpos;          ///< per axis: its joint's qpos address
  std::vector<int> part_of_geom;  ///< robot body id, or nbody + object index; -1: not checked
  std::vector<std::string> part_names;
  std::vector<char> allowed;  ///< parts x parts
  std::size_t parts = 0;
  int links = 0;
  std::vector<std::string> default_pairs;  ///< allowed at the synchronisation pose
  int configured_pairs = 0;
  std::vector<PairDistance> start_pairs, step_pairs;
  /// The target of the last path that passed and its pairs: the next macro-step starts there
  /// (the interpreter's planned end), so its start need not be evaluated again.
  std::vector<double> last_target;
  std::vector<PairDistance> last_target_pairs;
  std::vector<double> pose;  ///< the pose being checked

  [[nodiscard]] bool is_allowed(int a, int b) const {
    return allowed[static_cast<std::size_t>(a) * parts + static_cast<std::size_t>(b)] != 0;
  }
  void allow(int a, int b) {
    allowed[static_cast<std::size_t>(a) * parts + static_cast<std::size_t>(b)] = 1;
    allowed[static_cast<std::size_t>(b) * parts + static_cast<std::size_t>(a)] = 1;
  }

  /// Every pair that is not allowed and closer than `clearance` at `q`, each once, in `out`.
  void evaluate(std::span<const double> q, double clearance, std::vector<PairDistance>& out) {
    const mjModel* m = model.get();
    mjData* d = data.get();
    for (std::size_t i = 0; i < qpos.size(); ++i) d->qpos[qpos[i]] = q[i];
    mj_kinematics(m, d);
    mj_collision(m, d);
    out.clear();
    for (int c = 0; c < d->ncon; ++c) {
      const mjContact& contact = d->contact[c];
      int a = part_of_geom[static_cast<std::size_t>(contact.geom1)];
      int b = part_of_geom[static_cast<std::size_t>(contact.geom2)];
      if (a < 0 || b < 0 || a == b || is_allowed(a, b) || !(contact.dist < clearance)) continue;
      if (a > b) std::swap(a, b);
      auto same = [&](const PairDistance& p) { return p.a == a && p.b == b; };
      if (auto it = std::find_if(out.begin(), out.end(), same); it != out.end())
        it->distance = std::min(it->distance, static_cast<double>(contact.dist));
      else
        out.push_back({a, b, contact.dist});
    }
  }
};

std::unique_ptr<CollisionGuard> CollisionGuard::make(const RobotModel& model,
                                                     const RobotConfig& robot,
                                                     const CollisionConfig& config,
                                                     const std::filesystem::path& mjcf,
                                                     std::string& why_not) {
  why_not.clear();
  if (!config.enabled) {
    why_not = config.enabled_where.line > 0
                  ? fmt::format("off ({}:{}: [collision] enabled = false)",
                                config.enabled_where.file, config.enabled_where.line)
                  : fmt::format("off ({} has no [collision] section)", config.enabled_where.file);
    return nullptr;
  }
  if (mjcf.empty()) {
    why_not = fmt::format("off for robot '{}': it has no MJCF model (robot.mjcf of {})", robot.name,
                          model.parameters_file().string());
    return nullptr;
  }
  if (!model.coupling.empty()) {
    why_not = fmt::format(
        "off for robot '{}': its axes are coupled ([robot.transmission] coupling of {}), and "
        "the guard cannot place the links of closed kinematic loops yet",
        robot.name, model.parameters_file().string());
    return nullptr;
  }
  return std::make_unique<CollisionGuard>(model, robot, config, mjcf);
}

CollisionGuard::CollisionGuard(const RobotModel& robot_model, const RobotConfig& robot,
                               const CollisionConfig& config, const std::filesystem::path& mjcf)
    : impl_(std::make_unique<Impl>()), clearance_(config.clearance_m) {
  const SourceLocation model_file = SourceLocation::whole_file(mjcf.string());
  std::string error;
  impl_->model = sim::load_mjcf_text(compose(mjcf, robot_model, robot, config), error);
  if (!impl_->model)
    throw ConfigError(model_file,
                      "collision guard: MuJoCo cannot load the robot's model with the cell's "
                      "objects: " +
                          error);
  mjModel* m = impl_->model.get();
  impl_->data.reset(mj_makeData(m));
  if (!impl_->data) throw HardwareError("collision guard: cannot allocate MuJoCo data");
  mj_resetData(m, impl_->data.get());
  // Every geom collides with every other (but those joined by a joint: the parent filter) and
  // reports any pair closer than the clearance.
  m->opt.disableflags &= ~(mjDSBL_CONTACT | mjDSBL_CONSTRAINT | mjDSBL_FILTERPARENT);
  for (int g = 0; g < m->ngeom; ++g) {
    m->geom_contype[g] = 1;
    m->geom_conaffinity[g] = 1;
    m->geom_margin[g] = clearance_;
    m->geom_gap[g] = 0;
  }

  const auto nbody = static_cast<std::size_t>(m->nbody);
  impl_->parts = nbody + config.objects.size();
  impl_->part_names.resize(impl_->parts);
  impl_->allowed.assign(impl_->parts * impl_->parts, 0);
  for (std::size_t b = 1; b < nbody; ++b)
    impl_->part_names[b] = fmt::format("link '{}'", mj_id2name(m, mjOBJ_BODY, static_cast<int>(b)));
  impl_->part_of_geom.assign(static_cast<std::size_t>(m->ngeom), -1);
  std::vector<char> has_geom(nbody, 0);
  for (int g = 0; g < m->ngeom; ++g) {
    const int body = m->geom_bodyid[g];
    if (body != 0) {
      impl_->part_of_geom[static_cast<std::size_t>(g)] = body;
      has_geom[static_cast<std::size_t>(body)] = 1;
    }
  }
  impl_->links = static_cast<int>(std::count(has_geom.begin(), has_geom.end(), 1));
  for (std::size_t k = 0; k < config.objects.size(); ++k) {
    const int g = mj_name2id(m, mjOBJ_GEOM, object_geom_name(k).c_str());
    impl_->part_of_geom[static_cast<std::size_t>(g)] = static_cast<int>(nbody + k);
    impl_->part_names[nbody + k] = fmt::format("'{}'", config.objects[k].name);
  }

  // The axes' joints, and how far a point moves per unit of each.
  const std::size_t axes = robot_model.axes();
  for (std::size_t i = 0; i < axes; ++i) {
    const std::string& name = robot_model.joint_names[i];
    const int j = mj_name2id(m, mjOBJ_JOINT, name.c_str());
    if (j < 0 || (m->jnt_type[j] != mjJNT_HINGE && m->jnt_type[j] != mjJNT_SLIDE))
      throw ConfigError(model_file,
                        fmt::format("collision guard: the model has no hinge or slide joint named "
                                    "'{}' (axis {} of robot '{}')",
                                    name, i, robot.name));
    impl_->qpos.push_back(m->jnt_qposadr[j]);
    if (m->jnt_type[j] == mjJNT_SLIDE) {
      reach_.push_back(1.0);
      continue;
    }
    const int joint_body = m->jnt_bodyid[j];
    double reach = 0;
    for (int g = 0; g < m->ngeom; ++g) {
      int body = m->geom_bodyid[g];
      if (body == 0) continue;
      double chain = 0;
      while (body != joint_body && body != 0) {
        chain += mju_norm3(m->body_pos + 3 * body);
        body = m->body_parentid[body];
      }
      if (body != joint_body) continue;
      reach = std::max(reach, mju_norm3(m->jnt_pos + 3 * j) + chain +
                                  mju_norm3(m->geom_pos + 3 * g) + m->geom_rbound[g]);
    }
    reach_.push_back(reach);
  }

  // Configured pairs that name this robot's links or the objects.
  const std::size_t objects = config.objects.size();
  auto part_of = [&](const AllowedContact& a, const std::string& side) -> int {
    const auto slash = side.find('/');
    if (slash == std::string::npos) {
      for (std::size_t k = 0; k < objects; ++k)
        if (config.objects[k].name == side) return static_cast<int>(nbody + k);
      throw ConfigError(a.where, fmt::format("allowed contact names '{}', which is no "
                                             "[[collision.object]]",
                                             side));
    }
    if (side.substr(0, slash) != robot.name) return -1;  // another robot's (its EDP checks it)
    const std::string link = side.substr(slash + 1);
    const int body = mj_name2id(m, mjOBJ_BODY, link.c_str());
    if (body <= 0 || has_geom[static_cast<std::size_t>(body)] == 0) {
      std::string list;
      for (std::size_t b = 1; b < nbody; ++b)
        if (has_geom[b] != 0)
          list += (list.empty() ? "" : ", ") +
                  std::string(mj_id2name(m, mjOBJ_BODY, static_cast<int>(b)));
      throw ConfigError(a.where,
                        fmt::format("allowed contact '{}': robot '{}' has no link '{}' with "
                                    "geometry in {} (its links: {})",
                                    side, robot.name, link, mjcf.string(), list));
    }
    return body;
  };
  for (const AllowedContact& a : config.allowed) {
    const int first = part_of(a, a.first);
    const int second = part_of(a, a.second);
    if (first >= 0 && second >= 0) {
      impl_->allow(first, second);
      ++impl_->configured_pairs;
    }
  }

  // Pairs of the robot's own links closer than the clearance at the synchronisation pose touch
  // by design. A fixed object that close is a mistake of the configuration (the robot could
  // never be synchronised there without touching it): the first one is an error at the object,
  // naming the allowed pair that would accept it.
  if (robot_model.synchro_joint_positions.size() == axes) {
    impl_->evaluate(robot_model.synchro_joint_positions, clearance_, impl_->start_pairs);
    for (const PairDistance& p : impl_->start_pairs) {
      if (static_cast<std::size_t>(p.b) >= nbody) {
        const CollisionObject& o = config.objects[static_cast<std::size_t>(p.b) - nbody];
        const std::string link(mj_id2name(m, mjOBJ_BODY, p.a));
        throw ConfigError(
            o.where,
            fmt::format("object '{}' is {} link '{}' of robot '{}' at its synchronisation pose "
                        "(distance {:.4f} m, clearance {:g} m): move or resize the object, or "
                        "allow the pair in [collision]: allow = [[\"{}/{}\", \"{}\"]]",
                        o.name, p.distance < 0 ? "inside" : "within the clearance of", link,
                        robot.name, p.distance, clearance_, robot.name, link, o.name));
      }
      impl_->allow(p.a, p.b);
      impl_->default_pairs.push_back(
          fmt::format("{} - {} ({:.3f} m)", impl_->part_names[static_cast<std::size_t>(p.a)],
                      impl_->part_names[static_cast<std::size_t>(p.b)], p.distance));
    }
  }
  impl_->start_pairs.reserve(16);
  impl_->step_pairs.reserve(16);
  impl_->last_target_pairs.reserve(16);
  impl_->last_target.reserve(axes);
  impl_->pose.resize(axes);
}

CollisionGuard::~CollisionGuard() = default;

std::optional<Proximity> CollisionGuard::closest(std::span<const double> q) {
  poses_checked_.fetch_add(1, std::memory_order_relaxed);
  impl_->evaluate(q, clearance_, impl_->step_pairs);
  if (impl_->step_pairs.empty()) return std::nullopt;
  const auto it = std::min_element(
      impl_->step_pairs.begin(), impl_->step_pairs.end(),
      [](const PairDistance& x, const PairDistance& y) { return x.distance < y.distance; });
  return Proximity{impl_->part_names[static_cast<std::size_t>(it->a)],
                   impl_->part_names[static_cast<std::size_t>(it->b)], it->distance};
}

int CollisionGuard::sample_stride(std::span<const double> start, std::span<const double> target,
                                  int steps) const {
  double sweep = 0;  // bound of how far any point moves over the macro-step [m]
  for (std::size_t i = 0; i < reach_.size(); ++i)
    sweep += reach_[i] * std::abs(target[i] - start[i]);
  const double per_step = sweep / steps;
  if (!(per_step > 0)) return steps;
  return std::clamp(static_cast<int>(std::floor(0.5 * clearance_ / per_step)), 1, steps);
}

void CollisionGuard::check_path(std::span<const double> start, std::span<const double> target,
                                int steps) {
  // Timed with its refusal: the time and count go into statistics() however the check ends.
  struct Timer {
    CollisionGuard& guard;
    std::chrono::steady_clock::time_point began = std::chrono::steady_clock::now();
    bool refused = true;  // until the check ends normally
    ~Timer() {
      const long long ns = std::chrono::duration_cast<std::chrono::nanoseconds>(
                               std::chrono::steady_clock::now() - began)
                               .count();
      guard.paths_.fetch_add(1, std::memory_order_relaxed);
      if (refused) guard.refused_.fetch_add(1, std::memory_order_relaxed);
      guard.path_ns_.fetch_add(ns, std::memory_order_relaxed);
      if (ns > guard.max_path_ns_.load(std::memory_order_relaxed))
        guard.max_path_ns_.store(ns, std::memory_order_relaxed);  // one writer: this thread
    }
  } timer{*this};
  Impl& p = *impl_;
  if (std::equal(start.begin(), start.end(), p.last_target.begin(), p.last_target.end())) {
    p.start_pairs = p.last_target_pairs;  // where the last path that passed ended
  } else {
    poses_checked_.fetch_add(1, std::memory_order_relaxed);
    p.evaluate(start, clearance_, p.start_pairs);
  }
  const int stride = sample_stride(start, target, steps);
  std::vector<double>& q = p.pose;
  for (int k = stride;; k += stride) {
    k = std::min(k, steps);
    const double s = static_cast<double>(k) / steps;
    for (std::size_t i = 0; i < q.size(); ++i) q[i] = start[i] + (target[i] - start[i]) * s;
    poses_checked_.fetch_add(1, std::memory_order_relaxed);
    p.evaluate(q, clearance_, p.step_pairs);
    for (const PairDistance& pair : p.step_pairs) {
      const auto at_start =
          std::find_if(p.start_pairs.begin(), p.start_pairs.end(),
                       [&](const PairDistance& x) { return x.a == pair.a && x.b == pair.b; });
      // Already closer than the clearance where the macro-step starts: it may not come closer.
      constexpr double kTolerance = 1e-6;  // m
      if (at_start != p.start_pairs.end() && pair.distance >= at_start->distance - kTolerance)
        continue;
      const std::string& first = p.part_names[static_cast<std::size_t>(pair.a)];
      const std::string& second = p.part_names[static_cast<std::size_t>(pair.b)];
      const std::string how =
          pair.distance < 0
              ? fmt::format("{} would penetrate {} by {:.4f} m", first, second, -pair.distance)
              : fmt::format("{} would come within {:.4f} m of {}", first, pair.distance, second);
      const std::string closer =
          at_start == p.start_pairs.end()
              ? std::string()
              : fmt::format(", closer than the {:.4f} m where the macro-step starts",
                            at_start->distance);
      throw CommandError(error_code::collision,
                         fmt::format("SET refused: {} (clearance {:g} m{}) at servo step {} of {}",
                                     how, clearance_, closer, k, steps));
    }
    if (k == steps) break;
  }
  p.last_target.assign(target.begin(), target.end());
  p.last_target_pairs = p.step_pairs;  // evaluated at k == steps: the target
  timer.refused = false;
}

CollisionGuard::Statistics CollisionGuard::statistics() const {
  Statistics s;
  s.paths = paths_.load(std::memory_order_relaxed);
  s.refused = refused_.load(std::memory_order_relaxed);
  s.poses = poses_checked_.load(std::memory_order_relaxed);
  if (s.paths > 0)
    s.mean_us = static_cast<double>(path_ns_.load(std::memory_order_relaxed)) * 1e-3 /
                static_cast<double>(s.paths);
  s.max_us = static_cast<double>(max_path_ns_.load(std::memory_order_relaxed)) * 1e-3;
  return s;
}

std::string CollisionGuard::statistics_text() const {
  const Statistics s = statistics();
  return fmt::format(
      "collision guard: {} path{} checked, {} refusal{}, {} poses, mean {:.1f} us, max {:.1f} us "
      "per path",
      s.paths, s.paths == 1 ? "" : "s", s.refused, s.refused == 1 ? "" : "s", s.poses, s.mean_us,
      s.max_us);
}

std::string CollisionGuard::describe() const {
  const std::size_t objects = impl_->parts - static_cast<std::size_t>(impl_->model->nbody);
  std::string names;
  for (std::size_t k = 0; k < objects; ++k)
    names += (k == 0 ? " (" : ", ") +
             impl_->part_names[static_cast<std::size_t>(impl_->model->nbody) + k] +
             (k + 1 == objects ? ")" : "");
  std::string defaults;
  for (const std::string& d : impl_->default_pairs) defaults += (defaults.empty() ? "" : "; ") + d;
  return fmt::format(
      "collision guard on: {} links, {} fixed object{}{}, clearance {:g} m; allowed: links "
      "joined by a joint, {} pair{} closer at the synchronisation pose{}{}, {} configured",
      impl_->links, objects, objects == 1 ? "" : "s", names, clearance_,
      impl_->default_pairs.size(), impl_->default_pairs.size() == 1 ? "" : "s",
      defaults.empty() ? "" : ": ", defaults, impl_->configured_pairs);
}

}  // namespace mrroc::edp
