#include "cell_view.hpp"

#include <fmt/format.h>
#include <tinyxml2.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <memory>

#include "cell_world.hpp"
#include "mrroc/core/error.hpp"
#include "mrroc/sim/robot_axes.hpp"
#include "scene.hpp"

namespace mrroc::render {

namespace {

namespace xml = tinyxml2;

/// The scene to draw: the emulator's cell scene, or the set's robots at their bases.
emu::Scene scene_of(const ProcessSetConfig& set) {
  emu::Scene scene;
  if (set.emulator) {
    scene = emu::load_scene(set.emulator->scene);
  } else {
    scene.file = set.file;
    scene.name = set.name;
    scene.where = SourceLocation::whole_file(set.file.string());
  }
  for (const RobotConfig& robot : set.robots) {
    const bool present =
        std::any_of(scene.robots.begin(), scene.robots.end(),
                    [&](const emu::SceneRobot& r) { return r.name == robot.name; });
    if (present) continue;
    emu::SceneRobot added;
    added.name = robot.name;
    added.model_dir = robot.model_dir;
    added.base = robot.base;
    added.where = robot.where;
    // The `mujoco` plugin may name another MJCF file of the model folder.
    if (robot.edp.plugin == "mujoco" && robot.edp.params.has("mjcf")) {
      added.mjcf = robot.edp.params.get_string("mjcf");
    }
    scene.robots.push_back(std::move(added));
  }
  if (scene.robots.empty()) {
    throw ConfigError(SourceLocation::whole_file(set.file.string()),
                      "the set has no robot to draw");
  }
  return scene;
}

xml::XMLElement* child(xml::XMLElement* parent, const char* tag) {
  xml::XMLElement* e = parent->FirstChildElement(tag);
  return e != nullptr ? e : parent->InsertNewChildElement(tag);
}

/// The composed cell dressed for pictures: a tiled floor, a sky gradient, a soft headlight and
/// shadows. Adds assets and visual settings only, so the model's joints and bodies (and so the
/// layout of qpos) stay those of the cell world.
std::string dressed(const std::string& composed) {
  xml::XMLDocument doc;
  if (doc.Parse(composed.c_str()) != xml::XML_SUCCESS || doc.RootElement() == nullptr) {
    throw Error(fmt::format("the composed cell is not XML: {}", doc.ErrorStr()));
  }
  xml::XMLElement* root = doc.RootElement();
  xml::XMLElement* visual = root->FirstChildElement("visual");
  if (visual == nullptr) {
    visual = doc.NewElement("visual");
    root->InsertFirstChild(visual);
  }
  xml::XMLElement* headlight = child(visual, "headlight");
  headlight->SetAttribute("ambient", "0.25 0.25 0.25");
  headlight->SetAttribute("diffuse", "0.4 0.4 0.4");
  headlight->SetAttribute("specular", "0.1 0.1 0.1");
  xml::XMLElement* quality = child(visual, "quality");
  quality->SetAttribute("shadowsize", "2048");
  quality->SetAttribute("offsamples", "4");
  xml::XMLElement* map = child(visual, "map");
  map->SetAttribute("znear", "0.01");
  map->SetAttribute("shadowscale", "0.8");
  xml::XMLElement* rgba = child(visual, "rgba");
  rgba->SetAttribute("haze", "0.85 0.88 0.92 1");

  xml::XMLElement* asset = root->FirstChildElement("asset");
  if (asset == nullptr) {
    asset = doc.NewElement("asset");
    root->InsertAfterChild(visual, asset);
  }
  xml::XMLElement* sky = asset->InsertNewChildElement("texture");
  sky->SetAttribute("name", "render/sky");
  sky->SetAttribute("type", "skybox");
  sky->SetAttribute("builtin", "gradient");
  sky->SetAttribute("rgb1", "0.86 0.9 0.95");
  sky->SetAttribute("rgb2", "0.42 0.5 0.6");
  sky->SetAttribute("width", "512");
  sky->SetAttribute("height", "3072");
  xml::XMLElement* grid = asset->InsertNewChildElement("texture");
  grid->SetAttribute("name", "render/tiles");
  grid->SetAttribute("type", "2d");
  grid->SetAttribute("builtin", "checker");
  grid->SetAttribute("rgb1", "0.7 0.71 0.74");
  grid->SetAttribute("rgb2", "0.6 0.61 0.65");
  grid->SetAttribute("mark", "edge");
  grid->SetAttribute("markrgb", "0.62 0.63 0.66");
  grid->SetAttribute("width", "512");
  grid->SetAttribute("height", "512");
  xml::XMLElement* material = asset->InsertNewChildElement("material");
  material->SetAttribute("name", "render/floor");
  material->SetAttribute("texture", "render/tiles");
  material->SetAttribute("texrepeat", "10 10");
  material->SetAttribute("reflectance", "0.0");

  // The scene's floor (a plane named "floor" in the world body) gets the tiles.
  xml::XMLElement* world = root->FirstChildElement("worldbody");
  for (xml::XMLElement* geom = world != nullptr ? world->FirstChildElement("geom") : nullptr;
       geom != nullptr; geom = geom->NextSiblingElement("geom")) {
    const char* geom_name = geom->Attribute("name");
    if (geom_name != nullptr && std::strcmp(geom_name, "floor") == 0) {
      geom->DeleteAttribute("rgba");
      geom->SetAttribute("material", "render/floor");
    }
  }
  xml::XMLPrinter printer;
  doc.Print(&printer);
  return printer.CStr();
}

}  // namespace

CellView::CellView(const ProcessSetConfig& set) {
  const emu::Scene scene = scene_of(set);
  // The cell world checks every robot model and closes the loops at the power-on poses.
  const emu::CellWorld world(scene);
  name_ = scene.name;
  std::string error;
  model_ = sim::load_mjcf_text(dressed(world.composed_xml()), error);
  if (!model_) {
    throw Error(
        fmt::format("MuJoCo cannot load the cell '{}' dressed for drawing: {}", name_, error));
  }
  mjModel* m = model_.get();
  if (m->nq != world.model()->nq || m->nbody != world.model()->nbody) {
    throw Error(
        fmt::format("the cell '{}' dressed for drawing has {} positions and {} bodies, "
                    "the cell world {} and {}",
                    name_, m->nq, m->nbody, world.model()->nq, world.model()->nbody));
  }
  data_.reset(mj_makeData(m));
  std::copy_n(world.data()->qpos, m->nq, data_->qpos);

  for (std::size_t k = 0; k < world.robot_count(); ++k) {
    const emu::CellRobot& info = world.robot(k);
    Robot robot;
    robot.name = info.name;
    robot.coupling = info.coupling;
    for (const std::string& axis : info.axis_names) {
      const std::string actuator = info.name + "/" + axis;
      const int id = mj_name2id(m, mjOBJ_ACTUATOR, actuator.c_str());
      if (id < 0) {
        throw Error(fmt::format("robot '{}': no actuator '{}' in the cell '{}'", info.name,
                                actuator, name_));
      }
      robot.qpos_adr.push_back(m->jnt_qposadr[m->actuator_trnid[2 * id]]);
    }
    robot.q.assign(info.axis_count(), 0.0);
    world.joint_positions(k, robot.q);
    const int base = mj_name2id(m, mjOBJ_BODY, info.name.c_str());
    for (int b = 1; b < m->nbody; ++b) {
      int up = b;
      while (up > 0 && up != base) up = m->body_parentid[up];
      if (up == base && base > 0) robot.bodies.push_back(b);
    }
    robots_.push_back(std::move(robot));
  }
  mj_fwdPosition(m, data_.get());
}

std::optional<std::size_t> CellView::robot_index(const std::string& robot) const {
  for (std::size_t k = 0; k < robots_.size(); ++k) {
    if (robots_[k].name == robot) return k;
  }
  return std::nullopt;
}

std::string CellView::robot_names() const {
  std::string out;
  for (const Robot& r : robots_) out += (out.empty() ? "" : ", ") + r.name;
  return out;
}

void CellView::set_joints(std::size_t k, std::span<const double> q) {
  Robot& robot = robots_.at(k);
  if (q.size() != robot.q.size()) {
    throw Error(fmt::format("robot '{}' has {} joints in its model, the log gives {}", robot.name,
                            robot.q.size(), q.size()));
  }
  std::copy(q.begin(), q.end(), robot.q.begin());
}

bool CellView::set_object(const std::string& name, const std::array<double, 3>& position,
                          const std::array<double, 4>& quaternion) {
  const mjModel* m = model_.get();
  const int joint = mj_name2id(m, mjOBJ_JOINT, name.c_str());
  if (joint < 0 || m->jnt_type[joint] != mjJNT_FREE) return false;
  const double norm = std::sqrt(quaternion[0] * quaternion[0] + quaternion[1] * quaternion[1] +
                                quaternion[2] * quaternion[2] + quaternion[3] * quaternion[3]);
  if (!std::isfinite(norm) || norm < 1e-9) return false;
  mjtNum* q = data_->qpos + m->jnt_qposadr[joint];
  for (std::size_t i = 0; i < 3; ++i) q[i] = position[i];
  for (std::size_t i = 0; i < 4; ++i) q[3 + i] = quaternion[i] / norm;
  return true;
}

double CellView::pose() {
  std::vector<int> adr;
  std::vector<double> targets;
  for (const Robot& robot : robots_) {
    const std::size_t n = robot.q.size();
    for (std::size_t i = 0; i < n; ++i) {
      double a = 0.0;
      for (std::size_t j = 0; j < n; ++j) a += robot.coupling[i * n + j] * robot.q[j];
      adr.push_back(robot.qpos_adr[i]);
      targets.push_back(a);
    }
  }
  mjModel* m = model_.get();
  double violation = 0.0;
  if (m->neq > 0) {
    violation = sim::close_loops(m, data_.get(), adr, targets);
  } else {
    for (std::size_t i = 0; i < adr.size(); ++i) data_->qpos[adr[i]] = targets[i];
  }
  mj_fwdPosition(m, data_.get());
  return violation;
}

void CellView::robot_bounds(double low[3], double high[3]) const {
  const mjModel* m = model_.get();
  const mjData* d = data_.get();
  for (int c = 0; c < 3; ++c) {
    low[c] = std::numeric_limits<double>::infinity();
    high[c] = -std::numeric_limits<double>::infinity();
  }
  for (const Robot& robot : robots_) {
    for (const int b : robot.bodies) {
      for (int c = 0; c < 3; ++c) {
        low[c] = std::min(low[c], d->xpos[3 * b + c]);
        high[c] = std::max(high[c], d->xpos[3 * b + c]);
      }
    }
  }
  for (int g = 0; g < m->ngeom; ++g) {
    const int body = m->geom_bodyid[g];
    const bool robot_geom = std::any_of(robots_.begin(), robots_.end(), [&](const Robot& r) {
      return std::find(r.bodies.begin(), r.bodies.end(), body) != r.bodies.end();
    });
    if (!robot_geom) continue;
    const double r = m->geom_rbound[g];
    for (int c = 0; c < 3; ++c) {
      low[c] = std::min(low[c], d->geom_xpos[3 * g + c] - r);
      high[c] = std::max(high[c], d->geom_xpos[3 * g + c] + r);
    }
  }
}

}  // namespace mrroc::render
