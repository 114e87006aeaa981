/// @file
/// The cell's physics (see cell_world.hpp).

#include "cell_world.hpp"

#include <algorithm>
#include <cmath>
#include <cstdarg>
#include <cstdio>
#include <cstring>
#include <memory>
#include <utility>

#include <fmt/format.h>
#include <tinyxml2.h>

#include "mrroc/core/error.hpp"

namespace mrroc::emu {
namespace {

std::size_t index(int i) { return static_cast<std::size_t>(i); }

Range range_if(bool limited, const mjtNum* pair) {
  return limited ? Range{pair[0], pair[1]} : Range{};
}

/// The name (without NUL) as a NUL-terminated string in `buffer`; false when it does not fit.
bool terminated(std::string_view name, std::array<char, 256>& buffer) noexcept {
  if (name.size() >= buffer.size()) return false;
  std::memcpy(buffer.data(), name.data(), name.size());
  buffer[name.size()] = '\0';
  return true;
}

}  // namespace

CellWorld::CellWorld(const Scene& scene) { build(scene); }

CellWorld::CellWorld(const std::filesystem::path& scene_file) { build(load_scene(scene_file)); }

void CellWorld::build(const Scene& scene) {
  name_ = scene.name;
  ComposedScene composed = compose_scene(scene);
  xml_ = std::move(composed.xml);
  std::string error;
  model_ = sim::load_mjcf_text(xml_, error);
  if (!model_) {
    throw ConfigError(scene.where, fmt::format("MuJoCo cannot load the composed scene: {}", error));
  }
  convert_spring_contacts(scene);
  const mjModel* m = model_.get();
  const ComposedRobot& last = composed.robots.back();
  std::size_t grasp_total = 0;
  for (const SceneObject& object : scene.objects) grasp_total += object.grasps.size();
  if (last.first_actuator + last.actuator_count != m->nu ||
      last.first_equality + last.equality_count != composed.first_grasp_equality ||
      composed.first_grasp_equality + static_cast<int>(grasp_total) != m->neq) {
    throw HardwareError(
        fmt::format("cell '{}': the composed model has {} actuators and {} "
                    "equality constraints, its robots {} and {}, its grasps {}",
                    name_, m->nu, m->neq, last.first_actuator + last.actuator_count,
                    last.first_equality + last.equality_count, grasp_total));
  }
  setup_grasps(scene, composed.first_grasp_equality);
  setup_cuts(scene);

  joint_robot_.assign(index(m->njnt), -1);
  joint_axis_.assign(index(m->njnt), -1);
  std::vector<sim::ModelContext> contexts;
  std::vector<sim::PowerOnRequest> requests;
  std::vector<std::vector<int>> robot_joints;
  for (std::size_t k = 0; k < scene.robots.size(); ++k) {
    const SceneRobot& source = scene.robots[k];
    const ComposedRobot& composed_robot = composed.robots[k];
    const sim::ModelContext context{fmt::format("cell '{}', robot '{}'", name_, source.name),
                                    composed_robot.mjcf, composed_robot.parameters.path};
    // The robot's joints: those in the subtree of its base body.
    const int base = mj_name2id(m, mjOBJ_BODY, source.name.c_str());
    std::vector<int> joints;
    for (int j = 0; j < m->njnt; ++j) {
      int body = m->jnt_bodyid[j];
      while (body > 0 && body != base) body = m->body_parentid[body];
      if (body == base) joints.push_back(j);
    }
    sim::check_hinge_or_slide(m, joints, context);

    RobotState robot;
    robot.axes = sim::map_axes(m, composed_robot.first_actuator, composed_robot.actuator_count,
                               source.name + "/", context);
    sim::check_axis_names(robot.axes, composed_robot.parameters.joint_names, context);
    const std::size_t axes = robot.axes.size();
    sim::Coupling coupling =
        sim::Coupling::from_parameters(composed_robot.parameters, axes, composed_robot.mjcf);
    if (!composed_robot.parameters.synchro) {
      throw ConfigError(SourceLocation{composed_robot.parameters.path.string(), 0},
                        "missing key robot.synchro_joint_positions [rad]");
    }
    sim::PowerOnRequest request{source.initial_joint_positions, source.initial_where};
    sim::plan_power_on(m, robot.axes, std::move(coupling), *composed_robot.parameters.synchro,
                       sim::quoted(composed_robot.parameters.path), request, context);
    robot.first_equality = composed_robot.first_equality;
    robot.equality_count = composed_robot.equality_count;
    for (const int j : joints) {
      joint_robot_[index(j)] = static_cast<int>(k);
      robot.dofs.push_back(m->jnt_dofadr[j]);
      (source.gravity_compensation ? compensated_dofs_ : plain_dofs_).push_back(m->jnt_dofadr[j]);
    }
    for (std::size_t i = 0; i < axes; ++i) {
      const int j = robot.axes.joint[i];
      if (joint_robot_[index(j)] != static_cast<int>(k)) {
        throw HardwareError(
            fmt::format("{}: actuator '{}' drives joint '{}', which is not the "
                        "robot's",
                        context.who, robot.axes.names[i], sim::joint_name(m, j)));
      }
      joint_axis_[index(j)] = static_cast<int>(i);
    }
    robot.feed_forward.assign(axes, 0.0);
    robot.scratch.assign(axes, 0.0);

    CellRobot& info = robot.info;
    info.name = source.name;
    info.model_dir = source.model_dir;
    info.mjcf = composed_robot.mjcf;
    info.base = source.base;
    info.gravity_compensation = source.gravity_compensation;
    info.axis_names = robot.axes.names;
    info.coupling = robot.axes.coupling.matrix();
    info.coupled = robot.axes.coupling.coupled();
    info.synchro_joint_positions = robot.axes.synchro;
    info.power_on_joint_positions = robot.axes.power_on;
    info.power_on_actuator_positions = robot.axes.power_on_actuators;
    for (std::size_t i = 0; i < axes; ++i) {
      const int a = robot.axes.actuator[i];
      const int j = robot.axes.joint[i];
      const int r = robot.axes.range_joint[i];
      info.linear.push_back(m->jnt_type[j] == mjJNT_SLIDE);
      info.actuator_ranges.push_back(range_if(m->jnt_limited[j] != 0, m->jnt_range + 2 * j));
      info.joint_ranges.push_back(r >= 0 ? range_if(m->jnt_limited[r] != 0, m->jnt_range + 2 * r)
                                         : Range{});
      info.target_ranges.push_back(
          range_if(m->actuator_ctrllimited[a] != 0, m->actuator_ctrlrange + 2 * a));
      info.force_limits.push_back(
          range_if(m->actuator_forcelimited[a] != 0, m->actuator_forcerange + 2 * a));
      info.position_gains.push_back(
          m->actuator_gainprm[index(a) * static_cast<std::size_t>(mjNGAIN)]);
      info.damping.push_back(m->dof_damping[robot.axes.dof_adr[i]]);
    }
    robots_.push_back(std::move(robot));
    contexts.push_back(context);
    requests.push_back(std::move(request));
    robot_joints.push_back(std::move(joints));
  }

  // The power-on state: every robot's actuator joints at M q, passive joints closing the loops.
  data_.reset(mj_makeData(m));
  if (!data_) throw HardwareError(fmt::format("cell '{}': cannot allocate MuJoCo data", name_));
  mjData* d = data_.get();
  mj_resetData(m, d);
  std::vector<int> qpos_adr;
  std::vector<double> targets;
  for (const RobotState& robot : robots_) {
    qpos_adr.insert(qpos_adr.end(), robot.axes.qpos_adr.begin(), robot.axes.qpos_adr.end());
    targets.insert(targets.end(), robot.axes.power_on_actuators.begin(),
                   robot.axes.power_on_actuators.end());
  }
  sim::close_loops(m, d, qpos_adr, targets);
  for (std::size_t k = 0; k < robots_.size(); ++k) {
    const RobotState& robot = robots_[k];
    const double violation =
        robot.equality_count > 0
            ? sim::equality_violation(d, robot.first_equality, robot.equality_count)
            : 0.0;
    sim::check_power_on_state(m, d, robot.axes, robot_joints[k], violation, requests[k],
                              contexts[k]);
  }
  power_on_qpos_.assign(d->qpos, d->qpos + m->nq);
  reset();
}

void CellWorld::convert_spring_contacts(const Scene& scene) {
  mjModel* m = model_.get();
  tinyxml2::XMLDocument document;
  bool changed = false;
  for (const SceneObject& object : scene.objects) {
    if (!object.spring_contact()) continue;
    const int geom = mj_name2id(m, mjOBJ_GEOM, object.name.c_str());
    if (geom < 0) continue;  // cannot happen: compose_scene names the geom after the object
    const int body = m->geom_bodyid[geom];
    // The solver's approximation of the contact's inverse mass (mj_diagApprox): the two bodies'
    // mean translational inverse weights at qpos0; the other body is taken as fixed (0).
    const double w = m->body_invweight0[2 * index(body)];
    if (!(w > 0.0)) {
      throw ConfigError(
          object.solref_where,
          fmt::format(
              "object '{}' does not move (fixed to the world): a stiffness solref [N/m] needs a "
              "moving object; give it to the object or robot tool that touches this one",
              object.name));
    }
    // MuJoCo's soft contact (mj_makeImpedance, constant impedance d = solimp[0] = solimp[1],
    // k = -solref[0] / d^2, b = -solref[1] / d): each constraint row gets R = (1 - d) / d * w
    // (elliptic cone, condim 1). A pyramidal cone of dimension n has 2 (n - 1) edge rows, all with
    // R = 2 mu^2 / impratio * (1 - d) / d * w (1 + mu^2). In a static contact each row pushes with
    // k d p / R (p the penetration), its damping is b / R, so the normal force is
    //   f = -solref[0] / ((1 - d) w g) * p - solref[1] / ((1 - d) w g) * v,
    // g = 1 (elliptic, condim 1) or g = mu^2 (1 + mu^2) / ((n - 1) impratio) (pyramidal).
    // Along the normal the contact also adds an inertia 1 / R_normal = d / ((1 - d) w g) (the
    // row's regularisation): d is chosen so that it equals kSpringContactAddedMass / w.
    const int condim = m->geom_condim[geom];
    const double mu = m->geom_friction[3 * index(geom)];
    double g = 1.0;
    if (condim > 1 && m->opt.cone == mjCONE_PYRAMIDAL)
      g = mu * mu * (1.0 + mu * mu) / (static_cast<double>(condim - 1) * m->opt.impratio);
    const double ratio = kSpringContactAddedMass * g;  // d / (1 - d)
    const double d = std::clamp(ratio / (1.0 + ratio), mjMINIMP, mjMAXIMP);
    mjtNum* solref = m->geom_solref + mjNREF * index(geom);
    mjtNum* solimp = m->geom_solimp + mjNIMP * index(geom);
    solref[0] = (*object.solref)[0] * (1.0 - d) * w * g;
    solref[1] = (*object.solref)[1] * (1.0 - d) * w * g;
    solimp[0] = solimp[1] = d;
    // The composed document shows what MuJoCo runs.
    if (!changed && document.Parse(xml_.c_str()) != tinyxml2::XML_SUCCESS) continue;
    changed = true;
    std::vector<tinyxml2::XMLElement*> stack{document.RootElement()};
    while (!stack.empty()) {
      tinyxml2::XMLElement* e = stack.back();
      stack.pop_back();
      const char* name = e->Attribute("name");
      if (std::string_view(e->Name()) == "geom" && name != nullptr && object.name == name) {
        e->SetAttribute("solref", fmt::format("{} {}", solref[0], solref[1]).c_str());
        e->SetAttribute("solimp", fmt::format("{} {} {} {} {}", solimp[0], solimp[1], solimp[2],
                                              solimp[3], solimp[4])
                                      .c_str());
        e->InsertNewComment(fmt::format(" solref: {} N/m, {} N s/m (scene {}), in MuJoCo's "
                                        "per-unit-mass form ",
                                        -(*object.solref)[0], -(*object.solref)[1],
                                        object.solref_where.str())
                                .c_str());
        break;
      }
      for (tinyxml2::XMLElement* c = e->FirstChildElement(); c != nullptr;
           c = c->NextSiblingElement())
        stack.push_back(c);
    }
  }
  if (changed) {
    tinyxml2::XMLPrinter printer;
    document.Print(&printer);
    xml_ = printer.CStr();
  }
}

void CellWorld::setup_grasps(const Scene& scene, int first_equality) {
  mjModel* m = model_.get();
  int equality = first_equality;
  tinyxml2::XMLDocument document;
  const bool editable = document.Parse(xml_.c_str()) == tinyxml2::XML_SUCCESS;
  std::vector<tinyxml2::XMLElement*> welds;
  if (editable) {
    if (tinyxml2::XMLElement* section = document.RootElement()->FirstChildElement("equality")) {
      for (tinyxml2::XMLElement* e = section->FirstChildElement("weld"); e != nullptr;
           e = e->NextSiblingElement("weld"))
        welds.push_back(e);
    }
  }
  for (const SceneObject& object : scene.objects) {
    if (object.grasps.empty()) continue;
    HeldObject held;
    held.name = object.name;
    for (std::size_t i = 0; i < object.grasps.size(); ++i, ++equality) {
      const SceneGrasp& source = object.grasps[i];
      GraspState g;
      g.info.object = object.name;
      g.info.gripper = source.gripper();
      g.info.held = held_.size();
      g.info.equality = equality;
      g.info.engage_distance = source.engage_distance;
      g.info.engage_angle = source.engage_angle;
      g.info.engage_speed = source.engage_speed;
      g.info.stiffness = source.stiffness;
      g.info.damping = source.damping;
      g.gripper_body = m->eq_obj1id[equality];
      g.object_body = m->eq_obj2id[equality];
      const int joint = m->body_jntadr[g.object_body];
      if (m->body_jntnum[g.object_body] != 1 || m->jnt_type[joint] != mjJNT_FREE) {
        throw ConfigError(source.where, fmt::format("grasp of object '{}': the object is not a "
                                                    "free body",
                                                    object.name));
      }
      g.object_dof = m->jnt_dofadr[joint];
      if (!source.site.empty()) {
        const int site = mj_name2id(m, mjOBJ_SITE, source.site.c_str());
        std::copy(m->site_pos + 3 * index(site), m->site_pos + 3 * index(site) + 3,
                  g.frame_pos.begin());
        std::copy(m->site_quat + 4 * index(site), m->site_quat + 4 * index(site) + 4,
                  g.frame_quat.begin());
      } else {
        g.frame_pos = source.position;
        const double angle = mju_norm3(source.rotation.data());
        if (angle > 0.0) {
          std::array<double, 3> axis = source.rotation;
          mju_scl3(axis.data(), axis.data(), 1.0 / angle);
          mju_axisAngle2Quat(g.frame_quat.data(), axis.data(), angle);
        }
      }
      g.at_pos = source.at;
      const double at_angle = mju_norm3(source.at_rotation.data());
      if (at_angle > 0.0) {
        std::array<double, 3> axis = source.at_rotation;
        mju_scl3(axis.data(), axis.data(), 1.0 / at_angle);
        mju_axisAngle2Quat(g.at_quat.data(), axis.data(), at_angle);
      }
      // The weld (MuJoCo 2.2): data[0..2] its point in body2 (the object), data[3..5] in body1
      // (the gripper's body), data[6..9] the relative orientation q1^-1 q2 that it holds,
      // data[10] the torque scale. Held: q_body q_frame = q_object q_at.
      mjtNum* data = m->eq_data + mjNEQDATA * index(equality);
      std::copy(g.at_pos.begin(), g.at_pos.end(), data);
      std::copy(g.frame_pos.begin(), g.frame_pos.end(), data + 3);
      std::array<double, 4> at_inverse{};
      mju_negQuat(at_inverse.data(), g.at_quat.data());
      mju_mulQuat(data + 6, g.frame_quat.data(), at_inverse.data());
      data[10] = 1.0;
      // Stiffness and damping as for contact springs (convert_spring_contacts): each row's static
      // force is -solref[0] / ((1 - d) w) * r, its damping -solref[1] / ((1 - d) w), w being the
      // solver's approximation of the row's inverse mass (the two bodies' translational mean
      // inverse weights for the translational rows); the regularisation adds the inertia
      // d / ((1 - d) w) = kSpringContactAddedMass / w.
      const double w = m->body_invweight0[2 * index(g.gripper_body)] +
                       m->body_invweight0[2 * index(g.object_body)];
      const double d =
          std::clamp(kSpringContactAddedMass / (1.0 + kSpringContactAddedMass), mjMINIMP, mjMAXIMP);
      mjtNum* solref = m->eq_solref + mjNREF * index(equality);
      mjtNum* solimp = m->eq_solimp + mjNIMP * index(equality);
      solref[0] = -source.stiffness * (1.0 - d) * w;
      solref[1] = -source.damping * (1.0 - d) * w;
      solimp[0] = solimp[1] = d;
      solimp[2] = 0.001;
      solimp[3] = 0.5;
      solimp[4] = 2.0;
      m->eq_active[equality] = 0;
      // The composed document shows what MuJoCo runs (the welds are the last ones).
      const std::size_t from_end = index(m->neq - equality);
      if (from_end <= welds.size()) {
        tinyxml2::XMLElement* weld = welds[welds.size() - from_end];
        weld->SetAttribute("solref", fmt::format("{} {}", solref[0], solref[1]).c_str());
        weld->SetAttribute("solimp", fmt::format("{} {} {} {} {}", solimp[0], solimp[1], solimp[2],
                                                 solimp[3], solimp[4])
                                         .c_str());
        weld->InsertNewComment(
            fmt::format(" grasp of '{}' by '{}' ({}): eq_data [{}] set by the cell world; "
                        "stiffness {} N/m, damping {} N s/m in MuJoCo's per-unit-mass form; "
                        "closes within {} m, {} rad, {} m/s ",
                        object.name, source.gripper(), source.where.str(),
                        fmt::join(data, data + mjNEQDATA, " "), source.stiffness, source.damping,
                        source.engage_distance, source.engage_angle, source.engage_speed)
                .c_str());
      }
      held.grasps.push_back(grasps_.size());
      grasps_.push_back(g);
    }
    held_.push_back(std::move(held));
  }
  if (editable && !grasps_.empty()) {
    tinyxml2::XMLPrinter printer;
    document.Print(&printer);
    xml_ = printer.CStr();
  }
}

void CellWorld::setup_cuts(const Scene& scene) {
  const mjModel* m = model_.get();
  for (const SceneObject& object : scene.objects) {
    for (const SceneCutter& source : object.cutters) {
      CutState c;
      c.info.object = object.name;
      c.info.cutter = source.site;
      c.info.radius = source.radius;
      c.info.specific_force = source.specific_force;
      std::copy(object.size.begin(), object.size.end(), c.info.half_size.begin());
      c.info.board_body = mj_name2id(m, mjOBJ_BODY, object.name.c_str());
      c.site = mj_name2id(m, mjOBJ_SITE, source.site.c_str());
      if (c.site < 0) {
        throw ConfigError(source.where,
                          fmt::format("cutter of object '{}': site '{}' is not in the scene (a "
                                      "robot's sites are named '<robot>/<site>', e.g. 'rnt/tool')",
                                      object.name, source.site));
      }
      c.info.cutter_body = m->site_bodyid[c.site];
      // The cutter is a robot's: the root of its body's tree is a robot's base body.
      const char* root = mj_id2name(m, mjOBJ_BODY, m->body_rootid[c.info.cutter_body]);
      bool robot = false;
      for (const SceneRobot& r : scene.robots) robot = robot || (root != nullptr && r.name == root);
      if (!robot) {
        throw ConfigError(source.where,
                          fmt::format("cutter of object '{}': site '{}' is not on a robot (a "
                                      "cutter is a robot's tool)",
                                      object.name, source.site));
      }
      c.groove.reserve(kGrooveCapacity);
      for (const int body : {c.info.cutter_body, c.info.board_body}) {
        if (body > 0 &&
            std::find(cut_bodies_.begin(), cut_bodies_.end(), body) == cut_bodies_.end())
          cut_bodies_.push_back(body);
      }
      cuts_.push_back(std::move(c));
    }
  }
}

void CellWorld::measure_cuts() noexcept {
  if (cuts_.empty()) return;
  const mjModel* m = model_.get();
  const mjData* d = data_.get();
  for (CutState& c : cuts_) {
    const std::size_t b = index(c.info.board_body);
    const mjtNum* rotation = d->xmat + 9 * b;
    const mjtNum* origin = d->xpos + 3 * b;
    const mjtNum* point = d->site_xpos + 3 * index(c.site);
    std::array<double, 3> arm{};
    std::array<double, 3> tip{};
    mju_sub3(arm.data(), point, origin);
    mju_mulMatTVec(tip.data(), rotation, arm.data(), 3, 3);
    CutReading& r = c.now;
    const std::array<double, 3>& half = c.info.half_size;
    r.tip = tip;
    std::copy(point, point + 3, r.point.begin());
    r.depth = half[2] - tip[2];
    r.cutting = r.depth > 0.0 && std::abs(tip[0]) <= half[0] && std::abs(tip[1]) <= half[1];
    r.force = {};
    r.force_norm = 0.0;
    if (r.cutting) {
      // The tip's velocity relative to the board's material point under it, in the board frame.
      std::array<double, 6> tip_velocity{};
      std::array<double, 6> board_velocity{};
      mj_objectVelocity(m, d, mjOBJ_SITE, c.site, tip_velocity.data(), 0);
      mj_objectVelocity(m, d, mjOBJ_XBODY, c.info.board_body, board_velocity.data(), 0);
      std::array<double, 3> turn{};
      mju_cross(turn.data(), board_velocity.data(), arm.data());
      std::array<double, 3> relative{};
      for (std::size_t k = 0; k < 3; ++k)
        relative[k] = tip_velocity[3 + k] - board_velocity[3 + k] - turn[k];
      std::array<double, 3> v{};
      mju_mulMatTVec(v.data(), rotation, relative.data(), 3, 3);
      const double s = std::max(mju_norm3(v.data()), kCutCreepSpeed);
      const double depth = std::min(r.depth, 2.0 * half[2]);
      const double side = c.info.specific_force * depth * 2.0 * c.info.radius;
      const double end = c.info.specific_force * M_PI * c.info.radius * c.info.radius;
      r.force = {-side * v[0] / s, -side * v[1] / s, end * std::max(0.0, -v[2]) / s};
      r.force_norm = mju_norm3(r.force.data());
    }
    // The groove.
    CutSummary& sum = c.summary;
    const bool record_end = !r.cutting && c.was_cutting;
    if (r.cutting) {
      sum.cutting_time += m->opt.timestep;
      sum.max_depth = std::max(sum.max_depth, r.depth);
      sum.peak_force = std::max(sum.peak_force, r.force_norm);
      bool record = false;
      if (!c.was_cutting) {
        ++sum.strokes;
        record = true;
      } else {
        sum.length += std::hypot(tip[0] - c.last_tip[0], tip[1] - c.last_tip[1]);
        const GroovePoint* last = c.groove.empty() ? nullptr : &c.groove.back();
        record = last == nullptr || last->stroke != sum.strokes - 1 ||
                 std::hypot(tip[0] - last->x, tip[1] - last->y) >= kGrooveSpacing;
      }
      if (record) {
        if (c.groove.size() < kGrooveCapacity) {
          c.groove.push_back({tip[0], tip[1], r.depth, sum.strokes - 1});
        } else {
          c.groove_full = true;
        }
      }
      c.last_tip = {tip[0], tip[1]};
      c.last_depth = r.depth;
    } else if (record_end && !c.groove.empty()) {
      // The stroke's end, where the tip left the board.
      const GroovePoint& last = c.groove.back();
      if (last.x != c.last_tip[0] || last.y != c.last_tip[1]) {
        if (c.groove.size() < kGrooveCapacity) {
          c.groove.push_back({c.last_tip[0], c.last_tip[1], c.last_depth, sum.strokes - 1});
        } else {
          c.groove_full = true;
        }
      }
    }
    c.was_cutting = r.cutting;
    // The resistance in the world, for apply_cuts().
    mju_mulMatVec(r.world_force.data(), rotation, r.force.data(), 3, 3);
  }
}

void CellWorld::apply_cuts() noexcept {
  if (cuts_.empty()) return;
  mjData* d = data_.get();
  for (const int body : cut_bodies_) mju_zero(d->xfrc_applied + 6 * index(body), 6);
  // xfrc_applied acts at the body's centre of mass: the force at the tip adds a torque.
  const auto add = [d](int body, const std::array<double, 3>& force, const double* point) {
    if (body <= 0) return;  // the world
    mjtNum* applied = d->xfrc_applied + 6 * index(body);
    std::array<double, 3> arm{};
    std::array<double, 3> torque{};
    mju_sub3(arm.data(), point, d->xipos + 3 * index(body));
    mju_cross(torque.data(), arm.data(), force.data());
    mju_addTo3(applied, force.data());
    mju_addTo3(applied + 3, torque.data());
  };
  for (const CutState& c : cuts_) {
    if (!c.now.cutting) continue;
    add(c.info.cutter_body, c.now.world_force, c.now.point.data());
    const std::array<double, 3> opposite = {-c.now.world_force[0], -c.now.world_force[1],
                                            -c.now.world_force[2]};
    add(c.info.board_body, opposite, c.now.point.data());
  }
}

std::size_t CellWorld::cut_index(std::string_view object, std::string_view cutter) const {
  std::string known;
  std::size_t found = cuts_.size();
  int matches = 0;
  for (std::size_t i = 0; i < cuts_.size(); ++i) {
    const CellCut& c = cuts_[i].info;
    known += fmt::format("{}'{}' by '{}'", i == 0 ? "" : ", ", c.object, c.cutter);
    if (c.object == object && (cutter.empty() || c.cutter == cutter)) {
      found = i;
      ++matches;
    }
  }
  if (matches == 1) return found;
  if (matches > 1) {
    throw Error(fmt::format("cell '{}': object '{}' has {} cutters: name one (cuts: {})", name_,
                            object, matches, known));
  }
  throw Error(fmt::format("cell '{}': no cut of object '{}'{} (cuts: {})", name_, object,
                          cutter.empty() ? std::string() : fmt::format(" by '{}'", cutter),
                          known.empty() ? "none" : known));
}

const CutReading& CellWorld::cut_reading(std::size_t c) const noexcept {
  static const CutReading none;
  return c < cuts_.size() ? cuts_[c].now : none;
}

const CutSummary& CellWorld::cut_summary(std::size_t c) const noexcept {
  static const CutSummary none;
  return c < cuts_.size() ? cuts_[c].summary : none;
}

std::span<const GroovePoint> CellWorld::groove(std::size_t c) const noexcept {
  if (c >= cuts_.size()) return {};
  return cuts_[c].groove;
}

bool CellWorld::groove_full(std::size_t c) const noexcept {
  return c < cuts_.size() && cuts_[c].groove_full;
}

void CellWorld::grasp_frames(const GraspState& g, double gripper[3], double target[3],
                             double& angle) const noexcept {
  const mjData* d = data_.get();
  const std::size_t b = index(g.gripper_body);
  const std::size_t o = index(g.object_body);
  std::array<double, 3> offset{};
  mju_rotVecMat(offset.data(), g.frame_pos.data(), d->xmat + 9 * b);
  mju_add3(gripper, d->xpos + 3 * b, offset.data());
  mju_rotVecMat(offset.data(), g.at_pos.data(), d->xmat + 9 * o);
  mju_add3(target, d->xpos + 3 * o, offset.data());
  std::array<double, 4> gripper_quat{};
  std::array<double, 4> target_quat{};
  std::array<double, 4> inverse{};
  std::array<double, 4> difference{};
  mju_mulQuat(gripper_quat.data(), d->xquat + 4 * b, g.frame_quat.data());
  mju_mulQuat(target_quat.data(), d->xquat + 4 * o, g.at_quat.data());
  mju_negQuat(inverse.data(), gripper_quat.data());
  mju_mulQuat(difference.data(), inverse.data(), target_quat.data());
  angle = 2.0 * std::atan2(mju_norm3(difference.data() + 1), std::abs(difference[0]));
}

void CellWorld::engage_grasps() noexcept {
  mjModel* m = model_.get();
  const mjData* d = data_.get();
  for (GraspState& g : grasps_) {
    if (g.engaged) continue;
    std::array<double, 3> gripper{};
    std::array<double, 3> target{};
    double angle = 0.0;
    grasp_frames(g, gripper.data(), target.data(), angle);
    std::array<double, 3> gap{};
    mju_sub3(gap.data(), gripper.data(), target.data());
    if (mju_norm3(gap.data()) > g.info.engage_distance || angle > g.info.engage_angle) continue;
    // Velocities of the gripper point on either body (world frame): v + w x (p - x).
    std::array<double, 3> speed{};
    for (const int body : {g.gripper_body, g.object_body}) {
      std::array<double, 6> v{};
      mj_objectVelocity(m, d, mjOBJ_BODY, body, v.data(), 0);
      std::array<double, 3> arm{};
      std::array<double, 3> turn{};
      mju_sub3(arm.data(), gripper.data(), d->xpos + 3 * index(body));
      mju_cross(turn.data(), v.data(), arm.data());
      const double sign = body == g.gripper_body ? 1.0 : -1.0;
      for (std::size_t k = 0; k < 3; ++k) speed[k] += sign * (v[3 + k] + turn[k]);
    }
    if (mju_norm3(speed.data()) > g.info.engage_speed) continue;
    g.engaged = true;
    g.engaged_at = d->time;
    m->eq_active[g.info.equality] = 1;
  }
}

void CellWorld::measure_grasps() noexcept {
  if (grasps_.empty()) return;
  const mjModel* m = model_.get();
  const mjData* d = data_.get();
  const bool sparse = mj_isSparse(m) != 0;
  const std::size_t nv = index(m->nv);
  for (GraspState& g : grasps_) {
    g.force = {};
    if (!g.engaged) continue;
    // The weld's rows, through their Jacobian onto the object's translational dofs (world).
    for (int r = 0; r < d->nefc; ++r) {
      if (d->efc_type[r] != mjCNSTR_EQUALITY || d->efc_id[r] != g.info.equality) continue;
      const double f = d->efc_force[r];
      if (sparse) {
        const int adr = d->efc_J_rowadr[r];
        for (int e = 0; e < d->efc_J_rownnz[r]; ++e) {
          const int column = d->efc_J_colind[adr + e] - g.object_dof;
          if (column >= 0 && column < 3) g.force[index(column)] += d->efc_J[adr + e] * f;
        }
      } else {
        for (std::size_t k = 0; k < 3; ++k)
          g.force[k] += d->efc_J[index(r) * nv + index(g.object_dof) + k] * f;
      }
    }
  }
  for (HeldObject& held : held_) {
    held.internal = 0.0;
    std::array<double, 3> mean{};
    std::size_t n = 0;
    for (const std::size_t k : held.grasps) {
      if (!grasps_[k].engaged) continue;
      ++n;
      mju_addTo3(mean.data(), grasps_[k].force.data());
    }
    if (n < 2) continue;
    mju_scl3(mean.data(), mean.data(), 1.0 / static_cast<double>(n));
    for (const std::size_t k : held.grasps) {
      if (!grasps_[k].engaged) continue;
      std::array<double, 3> difference{};
      mju_sub3(difference.data(), grasps_[k].force.data(), mean.data());
      held.internal = std::max(held.internal, mju_norm3(difference.data()));
    }
    if (held.internal > held.peak) {
      held.peak = held.internal;
      held.peak_at = d->time;
    }
  }
}

bool CellWorld::grasp_engaged(std::size_t g) const noexcept {
  return g < grasps_.size() && grasps_[g].engaged;
}

double CellWorld::grasp_engaged_at(std::size_t g) const noexcept {
  return g < grasps_.size() ? grasps_[g].engaged_at : -1.0;
}

std::array<double, 3> CellWorld::grasp_force(std::size_t g) const noexcept {
  return g < grasps_.size() ? grasps_[g].force : std::array<double, 3>{};
}

int CellWorld::grasp_gripper_body(std::size_t g) const noexcept {
  return g < grasps_.size() ? grasps_[g].gripper_body : -1;
}

std::array<double, 3> CellWorld::grasp_point(std::size_t g) const noexcept {
  if (g >= grasps_.size()) return {};
  std::array<double, 3> gripper{};
  std::array<double, 3> target{};
  double angle = 0.0;
  grasp_frames(grasps_[g], gripper.data(), target.data(), angle);
  return gripper;
}

double CellWorld::grasp_offset(std::size_t g) const noexcept {
  if (g >= grasps_.size()) return 0.0;
  std::array<double, 3> gripper{};
  std::array<double, 3> target{};
  double angle = 0.0;
  grasp_frames(grasps_[g], gripper.data(), target.data(), angle);
  mju_subFrom3(gripper.data(), target.data());
  return mju_norm3(gripper.data());
}

const std::string& CellWorld::held_object(std::size_t i) const noexcept {
  static const std::string none;
  return i < held_.size() ? held_[i].name : none;
}

std::size_t CellWorld::held_object_index(std::string_view object) const {
  std::string known;
  for (std::size_t i = 0; i < held_.size(); ++i) {
    if (held_[i].name == object) return i;
    known += (i == 0 ? "" : ", ") + held_[i].name;
  }
  throw Error(fmt::format("cell '{}': no grasped object named '{}' (objects with grasps: {})",
                          name_, object, known.empty() ? "none" : known));
}

double CellWorld::internal_force(std::size_t i) const noexcept {
  return i < held_.size() ? held_[i].internal : 0.0;
}

double CellWorld::peak_internal_force(std::size_t i) const noexcept {
  return i < held_.size() ? held_[i].peak : 0.0;
}

double CellWorld::peak_internal_force_time(std::size_t i) const noexcept {
  return i < held_.size() ? held_[i].peak_at : -1.0;
}

std::size_t CellWorld::robot_index(std::string_view robot_name) const {
  std::string known;
  for (std::size_t k = 0; k < robots_.size(); ++k) {
    if (robots_[k].info.name == robot_name) return k;
    known += (k == 0 ? "" : ", ") + robots_[k].info.name;
  }
  throw Error(fmt::format("cell '{}': no robot named '{}' (robots: {})", name_, robot_name, known));
}

void CellWorld::reset() noexcept {
  const mjModel* m = model_.get();
  mjData* d = data_.get();
  mj_resetData(m, d);
  std::copy(power_on_qpos_.begin(), power_on_qpos_.end(), d->qpos);
  for (RobotState& robot : robots_) {
    for (std::size_t i = 0; i < robot.axes.size(); ++i)
      d->ctrl[robot.axes.actuator[i]] = d->qpos[robot.axes.qpos_adr[i]];
    std::fill(robot.feed_forward.begin(), robot.feed_forward.end(), 0.0);
  }
  for (GraspState& g : grasps_) {
    model_->eq_active[g.info.equality] = 0;
    g.engaged = false;
    g.engaged_at = -1.0;
    g.force = {};
  }
  for (HeldObject& held : held_) {
    held.internal = held.peak = 0.0;
    held.peak_at = -1.0;
  }
  for (CutState& c : cuts_) {
    c.summary = {};
    c.groove.clear();
    c.groove_full = false;
    c.was_cutting = false;
  }
  mj_forward(m, d);
  measure_cuts();
  for (const int v : compensated_dofs_) d->qfrc_applied[v] = d->qfrc_bias[v];
  warnings_at_reset_ = sim::warning_total(d);
  faulted_ = false;
  fault_[0] = '\0';
}

bool CellWorld::set_targets(std::size_t k, std::span<const double> positions) noexcept {
  if (!valid(k, positions.size())) return false;
  for (const double p : positions)
    if (!std::isfinite(p)) return false;
  const sim::RobotAxes& axes = robots_[k].axes;
  for (std::size_t i = 0; i < positions.size(); ++i) data_->ctrl[axes.actuator[i]] = positions[i];
  return true;
}

bool CellWorld::set_velocity_feed_forward(std::size_t k,
                                          std::span<const double> velocities) noexcept {
  if (!valid(k, velocities.size())) return false;
  for (const double v : velocities)
    if (!std::isfinite(v)) return false;
  RobotState& robot = robots_[k];
  for (std::size_t i = 0; i < velocities.size(); ++i)
    robot.feed_forward[i] = model_->dof_damping[robot.axes.dof_adr[i]] * velocities[i];
  return true;
}

void CellWorld::apply_feed_forward() noexcept {
  mjData* d = data_.get();
  // qfrc_bias is that of the current state: computed by mj_forward (reset) or by the mj_step1
  // that ends every step.
  for (const int v : compensated_dofs_) d->qfrc_applied[v] = d->qfrc_bias[v];
  for (const int v : plain_dofs_) d->qfrc_applied[v] = 0.0;
  for (const RobotState& robot : robots_) {
    for (std::size_t i = 0; i < robot.axes.size(); ++i)
      d->qfrc_applied[robot.axes.dof_adr[i]] += robot.feed_forward[i];
  }
}

bool CellWorld::step() noexcept {
  if (faulted_) return false;
  const mjModel* m = model_.get();
  mjData* d = data_.get();
  // Splitting the step this way keeps body poses and constraint violations current for the
  // readings between steps.
  apply_feed_forward();
  apply_cuts();
  mj_step2(m, d);
  measure_grasps();  // efc_force and efc_J belong to the same state until mj_step1
  mj_step1(m, d);
  engage_grasps();
  measure_cuts();
  return check_stable();
}

void CellWorld::solve_constraint_forces() noexcept {
  if (faulted_) return;
  const mjModel* m = model_.get();
  mjData* d = data_.get();
  // The first half of mj_step2 without the integration: the next step() recomputes the same
  // from the same inputs (only the solver's warm start changes, to round-off).
  apply_feed_forward();
  mj_fwdActuation(m, d);
  mj_fwdAcceleration(m, d);
  mj_fwdConstraint(m, d);
}

void CellWorld::set_fault(const char* format, ...) noexcept {
  va_list args;
  va_start(args, format);
  std::vsnprintf(fault_.data(), fault_.size(), format, args);
  va_end(args);
  faulted_ = true;
}

void CellWorld::describe_joint(int joint, std::array<char, 256>& out) const noexcept {
  const char* name = mj_id2name(model_.get(), mjOBJ_JOINT, joint);
  name = name != nullptr ? name : "(unnamed)";
  const int k = joint >= 0 && joint < model_->njnt ? joint_robot_[index(joint)] : -1;
  if (k < 0) {
    std::snprintf(out.data(), out.size(), "object joint '%s'", name);
    return;
  }
  const RobotState& robot = robots_[index(k)];
  const int axis = joint_axis_[index(joint)];
  if (axis < 0) {
    std::snprintf(out.data(), out.size(), "robot '%s', passive joint '%s'", robot.info.name.c_str(),
                  name);
  } else {
    std::snprintf(out.data(), out.size(), "robot '%s', joint '%s' (axis %d '%s')",
                  robot.info.name.c_str(), name, axis, robot.info.axis_names[index(axis)].c_str());
  }
}

bool CellWorld::check_stable() noexcept {
  const mjModel* m = model_.get();
  const mjData* d = data_.get();
  std::array<char, 256> where{};
  if (const int joint = sim::non_finite_joint(m, d); joint >= 0) {
    describe_joint(joint, where);
    set_fault("cell '%s' unstable at t = %.6f s: non-finite state of %s", name_.c_str(), d->time,
              where.data());
    return false;
  }
  if (sim::warning_total(d) != warnings_at_reset_) {
    for (int w = 0; w < mjNWARNING; ++w) {
      const mjWarningStat& stat = d->warning[w];
      if (stat.number == 0) continue;
      // The bad-number warnings name a qpos address or a degree of freedom.
      int joint = -1;
      if (w == mjWARN_BADQPOS) {
        for (int j = 0; j < m->njnt; ++j)
          if (m->jnt_qposadr[j] <= stat.lastinfo) joint = j;
      } else if ((w == mjWARN_BADQVEL || w == mjWARN_BADQACC) && stat.lastinfo >= 0 &&
                 stat.lastinfo < m->nv) {
        joint = m->dof_jntid[stat.lastinfo];
      }
      if (joint >= 0) {
        describe_joint(joint, where);
      } else {
        std::snprintf(where.data(), where.size(), "index %d", stat.lastinfo);
      }
      set_fault(
          "cell '%s' unstable at t = %.6f s: MuJoCo warning '%s' raised %d time(s), last "
          "at %s",
          name_.c_str(), d->time, sim::warning_text(w), stat.number, where.data());
      return false;
    }
  }
  for (const RobotState& robot : robots_) {
    if (robot.equality_count == 0) continue;
    const double violation = sim::equality_violation(d, robot.first_equality, robot.equality_count);
    if (violation > kLoopOpenFault) {
      set_fault(
          "cell '%s' unstable at t = %.6f s: robot '%s': a closed kinematic loop opened by "
          "%.3g (limit %.3g)",
          name_.c_str(), d->time, robot.info.name.c_str(), violation, kLoopOpenFault);
      return false;
    }
  }
  return true;
}

bool CellWorld::actuator_positions(std::size_t k, std::span<double> out) const noexcept {
  if (!valid(k, out.size())) return false;
  const sim::RobotAxes& axes = robots_[k].axes;
  for (std::size_t i = 0; i < out.size(); ++i) out[i] = data_->qpos[axes.qpos_adr[i]];
  return true;
}

bool CellWorld::actuator_velocities(std::size_t k, std::span<double> out) const noexcept {
  if (!valid(k, out.size())) return false;
  const sim::RobotAxes& axes = robots_[k].axes;
  for (std::size_t i = 0; i < out.size(); ++i) out[i] = data_->qvel[axes.dof_adr[i]];
  return true;
}

bool CellWorld::actuator_forces(std::size_t k, std::span<double> out) const noexcept {
  if (!valid(k, out.size())) return false;
  const sim::RobotAxes& axes = robots_[k].axes;
  for (std::size_t i = 0; i < out.size(); ++i)
    out[i] = data_->actuator_force[axes.actuator[i]] + data_->qfrc_applied[axes.dof_adr[i]];
  return true;
}

bool CellWorld::joint_positions(std::size_t k, std::span<double> out) const noexcept {
  if (!valid(k, out.size())) return false;
  const RobotState& robot = robots_[k];
  (void)actuator_positions(k, robot.scratch);
  robot.axes.coupling.joints_from_actuators(robot.scratch.data(), out.data());
  return true;
}

bool CellWorld::joint_velocities(std::size_t k, std::span<double> out) const noexcept {
  if (!valid(k, out.size())) return false;
  const RobotState& robot = robots_[k];
  (void)actuator_velocities(k, robot.scratch);
  robot.axes.coupling.joints_from_actuators(robot.scratch.data(), out.data());
  return true;
}

bool CellWorld::synchro_switch(std::size_t k, std::size_t axis) const noexcept {
  if (k >= robots_.size() || axis >= robots_[k].axes.size()) return false;
  const RobotState& robot = robots_[k];
  (void)actuator_positions(k, robot.scratch);
  return robot.axes.coupling.joint_from_actuators(robot.scratch.data(), axis) >
         robot.axes.synchro[axis];
}

int CellWorld::body_id(std::string_view body_name) const noexcept {
  std::array<char, 256> buffer{};
  return terminated(body_name, buffer) ? mj_name2id(model_.get(), mjOBJ_BODY, buffer.data()) : -1;
}

int CellWorld::site_id(std::string_view site_name) const noexcept {
  std::array<char, 256> buffer{};
  return terminated(site_name, buffer) ? mj_name2id(model_.get(), mjOBJ_SITE, buffer.data()) : -1;
}

FramePose CellWorld::body_pose(int id) const noexcept {
  FramePose pose;
  if (id < 0 || id >= model_->nbody) return pose;
  const std::size_t i = index(id);
  std::copy(data_->xpos + 3 * i, data_->xpos + 3 * i + 3, pose.position.begin());
  std::copy(data_->xquat + 4 * i, data_->xquat + 4 * i + 4, pose.quaternion.begin());
  return pose;
}

FramePose CellWorld::site_pose(int id) const noexcept {
  FramePose pose;
  if (id < 0 || id >= model_->nsite) return pose;
  const std::size_t i = index(id);
  std::copy(data_->site_xpos + 3 * i, data_->site_xpos + 3 * i + 3, pose.position.begin());
  mju_mat2Quat(pose.quaternion.data(), data_->site_xmat + 9 * i);
  return pose;
}

FramePose CellWorld::body_pose(std::string_view body_name) const {
  const int id = body_id(body_name);
  if (id < 0) throw Error(fmt::format("cell '{}': no body named '{}'", name_, body_name));
  return body_pose(id);
}

FramePose CellWorld::site_pose(std::string_view site_name) const {
  const int id = site_id(site_name);
  if (id < 0) throw Error(fmt::format("cell '{}': no site named '{}'", name_, site_name));
  return site_pose(id);
}

}  // namespace mrroc::emu
