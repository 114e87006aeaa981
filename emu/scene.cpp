/// @file
/// Reading cell scene files (see scene.hpp).

#include "scene.hpp"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <map>
#include <memory>
#include <sstream>

#include <fmt/format.h>
#include <tinyxml2.h>
#include <toml++/toml.h>
#include <Eigen/Geometry>

#include "mrroc/core/error.hpp"
#include "mrroc/sim/mujoco_support.hpp"

namespace mrroc::emu {
namespace {

namespace fs = std::filesystem;

constexpr std::array<const char*, 3> kReservedNames = {"world", "floor", "light"};

/// Reads one table of the scene; every error names the file and line of the offending node.
class TableReader {
 public:
  TableReader(const fs::path& file, const toml::table& table, std::string name)
      : file_(file), table_(table), name_(std::move(name)) {}

  [[nodiscard]] SourceLocation at(const toml::node& node) const {
    return SourceLocation{file_.string(), static_cast<int>(node.source().begin.line)};
  }
  [[noreturn]] void fail(const toml::node& node, const std::string& text) const {
    throw ConfigError(at(node), text);
  }
  [[noreturn]] void fail_missing(const char* key, const char* what) const {
    fail(table_, fmt::format("missing key '{}' in [{}] ({})", key, name_, what));
  }

  /// Rejects every key not in `known`.
  void reject_unknown(std::initializer_list<std::string_view> known) const {
    for (const auto& [key, node] : table_) {
      if (std::find(known.begin(), known.end(), key.str()) != known.end()) continue;
      std::string allowed;
      for (const std::string_view k : known)
        allowed += (allowed.empty() ? "" : ", ") + std::string(k);
      fail(node, fmt::format("unknown key '{}' in [{}] (allowed: {})", key.str(), name_, allowed));
    }
  }

  [[nodiscard]] const toml::node* find(const char* key) const { return table_.get(key); }

  [[nodiscard]] std::optional<std::string> text(const char* key) const {
    const toml::node* node = find(key);
    if (node == nullptr) return std::nullopt;
    if (!node->is_string()) fail(*node, fmt::format("'{}' must be a string", key));
    return std::string(**node->as_string());
  }

  /// A name: non-empty, no '/', not reserved.
  [[nodiscard]] std::string name(const char* key) const {
    const std::optional<std::string> value = text(key);
    if (!value) fail_missing(key, "a name");
    const toml::node& node = *find(key);
    if (value->empty() || value->find('/') != std::string::npos ||
        value->find_first_of(" \t\n") != std::string::npos) {
      fail(node, fmt::format("'{}' = \"{}\" must be a non-empty name without '/' or spaces", key,
                             *value));
    }
    for (const char* reserved : kReservedNames) {
      if (*value == reserved) {
        fail(node, fmt::format("'{}' = \"{}\" is reserved (world, floor, light)", key, *value));
      }
    }
    return *value;
  }

  [[nodiscard]] std::optional<bool> flag(const char* key) const {
    const toml::node* node = find(key);
    if (node == nullptr) return std::nullopt;
    if (!node->is_boolean()) fail(*node, fmt::format("'{}' must be true or false", key));
    return **node->as_boolean();
  }

  [[nodiscard]] double number_of(const toml::node& node, const std::string& what) const {
    if (const auto value = node.value<double>(); value && std::isfinite(*value)) return *value;
    fail(node, fmt::format("{} must be a finite number", what));
  }

  /// A number within [min, max] (`unit` names it in messages).
  [[nodiscard]] std::optional<double> number(const char* key, double min, double max,
                                             const char* unit) const {
    const toml::node* node = find(key);
    if (node == nullptr) return std::nullopt;
    const double value = number_of(*node, fmt::format("'{}' [{}]", key, unit));
    if (!(value >= min && value <= max)) {
      fail(*node, fmt::format("'{}' = {} {} is outside the accepted range {} .. {} {}", key, value,
                              unit, min, max, unit));
    }
    return value;
  }

  /// A list of numbers; `count` > 0 demands that many (`shape` describes the list).
  [[nodiscard]] std::optional<std::vector<double>> numbers(const char* key, std::size_t count,
                                                           const std::string& shape) const {
    const toml::node* node = find(key);
    if (node == nullptr) return std::nullopt;
    const toml::array* array = node->as_array();
    if (array == nullptr || (count > 0 && array->size() != count)) {
      const std::string got =
          array == nullptr ? "not a list" : fmt::format("{} values", array->size());
      fail(*node, fmt::format("'{}' must be {} ({})", key, shape, got));
    }
    std::vector<double> values;
    for (const toml::node& element : *array)
      values.push_back(number_of(element, fmt::format("every value of '{}'", key)));
    return values;
  }

  template <std::size_t N>
  [[nodiscard]] std::optional<std::array<double, N>> fixed(const char* key,
                                                           const std::string& shape) const {
    const auto values = numbers(key, N, shape);
    if (!values) return std::nullopt;
    std::array<double, N> out{};
    std::copy(values->begin(), values->end(), out.begin());
    return out;
  }

 private:
  const fs::path& file_;
  const toml::table& table_;
  std::string name_;
};

/// The tables of an array of tables ([[scene.robot]]); `full` names it in messages (default
/// "scene.<key>").
std::vector<const toml::table*> table_list(const TableReader& scene, const char* key,
                                           const std::string& full = {}) {
  std::vector<const toml::table*> out;
  const toml::node* node = scene.find(key);
  if (node == nullptr) return out;
  const std::string name = full.empty() ? fmt::format("scene.{}", key) : full;
  const toml::array* array = node->as_array();
  if (array == nullptr) scene.fail(*node, fmt::format("'{}' must be [[{}]] tables", key, name));
  for (const toml::node& element : *array) {
    if (!element.is_table())
      scene.fail(element, fmt::format("'{}' must be [[{}]] tables", key, name));
    out.push_back(element.as_table());
  }
  return out;
}

SceneRobot read_robot(const fs::path& file, const toml::table& table) {
  const TableReader r(file, table, "scene.robot");
  // `drives` (the axes' wiring as CAN drives) is read by the emulator (emu/drives.hpp).
  r.reject_unknown({"name", "model", "base", "mjcf", "initial_joint_positions",
                    "gravity_compensation", "drives"});
  SceneRobot robot;
  robot.where = r.at(table);
  robot.name = r.name("name");
  const std::optional<std::string> model = r.text("model");
  if (!model) r.fail_missing("model", "the robot's model folder, relative to the scene file");
  fs::path dir(*model);
  if (dir.is_relative()) dir = file.parent_path() / dir;
  robot.model_dir = fs::absolute(dir).lexically_normal();
  if (!fs::is_directory(robot.model_dir)) {
    r.fail(*r.find("model"), fmt::format("model folder '{}' of robot '{}' not found",
                                         robot.model_dir.string(), robot.name));
  }
  robot.base = r.fixed<6>("base", "[x, y, z, rx, ry, rz] (m, rotation vector in rad)")
                   .value_or(std::array<double, 6>{});
  robot.mjcf = r.text("mjcf");
  if (robot.mjcf && robot.mjcf->empty()) r.fail(*r.find("mjcf"), "'mjcf' must not be empty");
  robot.initial_joint_positions =
      r.numbers("initial_joint_positions", 0, "a list of joint positions (rad or m)");
  if (robot.initial_joint_positions) robot.initial_where = r.at(*r.find("initial_joint_positions"));
  robot.gravity_compensation = r.flag("gravity_compensation").value_or(true);
  return robot;
}

/// `contact`, `solref` and `friction` of an object (see scene.hpp).
void read_contact(const TableReader& r, SceneObject& object) {
  object.contact = r.flag("contact").value_or(true);
  if (const auto solref = r.fixed<2>("solref",
                                     "[timeconst, dampratio] (s, 1; both positive) or "
                                     "[-stiffness, -damping] (N/m, N s/m; negative)")) {
    const toml::node& node = *r.find("solref");
    const auto [a, b] = *solref;
    if (a > 0.0 && b > 0.0) {
      // MuJoCo's standard form: time constant [s] and damping ratio.
    } else if (a < 0.0 && b <= 0.0) {
      if (-a > 1e9 || -b > 1e7) {
        r.fail(node, fmt::format("'solref' = [{}, {}]: stiffness {} N/m or damping {} N s/m is "
                                 "beyond 1e9 N/m or 1e7 N s/m",
                                 a, b, -a, -b));
      }
    } else {
      r.fail(node,
             fmt::format("'solref' = [{}, {}] mixes MuJoCo's two forms: give [timeconst, "
                         "dampratio] (both > 0, s and 1) or [-stiffness, -damping] (stiffness "
                         "> 0 N/m, damping >= 0 N s/m, both negated)",
                         a, b));
    }
    object.solref = solref;
    object.solref_where = r.at(node);
  }
  if (const auto friction =
          r.numbers("friction", 0, "1 to 3 coefficients [sliding, torsional m, rolling m]")) {
    const toml::node& node = *r.find("friction");
    if (friction->empty() || friction->size() > 3) {
      r.fail(node, fmt::format("'friction' must be 1 to 3 coefficients [sliding, torsional m, "
                               "rolling m] ({} values)",
                               friction->size()));
    }
    for (const double f : *friction) {
      if (!(f >= 0.0 && f <= 10.0))
        r.fail(node, fmt::format("'friction' value {} is outside 0 .. 10", f));
    }
    if (!((*friction)[0] > 0.0)) {
      r.fail(node,
             "'friction' sliding coefficient must be > 0 (MuJoCo's pyramidal friction cone "
             "needs it; frictionless contacts are not supported)");
    }
    object.friction = *friction;
  }
  if (!object.contact) {
    for (const char* key : {"solref", "friction"}) {
      if (const toml::node* node = r.find(key)) {
        r.fail(*node, fmt::format("'{}' has no effect on object '{}' with contact = false", key,
                                  object.name));
      }
    }
  }
}

SceneGrasp read_grasp(const fs::path& file, const toml::table& table, const std::string& object) {
  const TableReader r(file, table, "scene.object.grasp");
  r.reject_unknown({"site", "body", "pos", "rotation", "at", "at_rotation", "engage_distance",
                    "engage_angle", "engage_speed", "stiffness", "damping"});
  SceneGrasp grasp;
  grasp.where = r.at(table);
  grasp.site = r.text("site").value_or("");
  grasp.body = r.text("body").value_or("");
  if (grasp.site.empty() == grasp.body.empty()) {
    r.fail(table, fmt::format("grasp of object '{}': give exactly one of 'site' (a site of a "
                              "robot, e.g. \"left/flange\") or 'body' (a body of a robot)",
                              object));
  }
  if (!grasp.site.empty()) {
    for (const char* key : {"pos", "rotation"}) {
      if (const toml::node* node = r.find(key))
        r.fail(*node, fmt::format("'{}' goes with 'body', not with 'site'", key));
    }
  }
  grasp.position = r.fixed<3>("pos", "[x, y, z] (m, in the body)").value_or(grasp.position);
  grasp.rotation = r.fixed<3>("rotation", "[rx, ry, rz] (rotation vector in rad, in the body)")
                       .value_or(grasp.rotation);
  const auto at = r.fixed<3>("at", "[x, y, z] (m, in the object's frame)");
  if (!at) r.fail_missing("at", "the gripper frame's origin in the object's frame [m]");
  grasp.at = *at;
  grasp.at_rotation = r.fixed<3>("at_rotation", "[rx, ry, rz] (rotation vector in rad)")
                          .value_or(grasp.at_rotation);
  grasp.engage_distance =
      r.number("engage_distance", 1e-5, 0.1, "m").value_or(grasp.engage_distance);
  grasp.engage_angle = r.number("engage_angle", 1e-4, 1.0, "rad").value_or(grasp.engage_angle);
  grasp.engage_speed = r.number("engage_speed", 1e-5, 1.0, "m/s").value_or(grasp.engage_speed);
  grasp.stiffness = r.number("stiffness", 1.0, 1e7, "N/m").value_or(grasp.stiffness);
  grasp.damping = r.number("damping", 0.0, 1e5, "N s/m").value_or(grasp.damping);
  return grasp;
}

SceneCutter read_cutter(const fs::path& file, const toml::table& table) {
  const TableReader r(file, table, "scene.object.cutter");
  r.reject_unknown({"site", "radius", "specific_force"});
  SceneCutter cutter;
  cutter.where = r.at(table);
  const std::optional<std::string> site = r.text("site");
  if (!site || site->empty()) {
    r.fail_missing("site", "the cutter tip: a site of a robot, e.g. \"rnt/tool\"");
  }
  cutter.site = *site;
  const std::optional<double> radius = r.number("radius", 1e-4, 0.05, "m");
  if (!radius) r.fail_missing("radius", "the cutter's radius in m");
  cutter.radius = *radius;
  cutter.specific_force =
      r.number("specific_force", 1.0, 1e9, "N/m^2").value_or(cutter.specific_force);
  return cutter;
}

SceneObject read_object(const fs::path& file, const toml::table& table) {
  const TableReader r(file, table, "scene.object");
  r.reject_unknown({"name", "type", "size", "pos", "rotation", "mass", "rgba", "attach", "contact",
                    "solref", "friction", "grasp", "cutter"});
  SceneObject object;
  object.where = r.at(table);
  object.name = r.name("name");
  const std::optional<std::string> type = r.text("type");
  if (!type) r.fail_missing("type", "box, sphere, cylinder or capsule");
  std::size_t sizes = 0;
  for (const ObjectShape shape :
       {ObjectShape::box, ObjectShape::sphere, ObjectShape::cylinder, ObjectShape::capsule}) {
    if (*type == shape_name(shape)) {
      object.shape = shape;
      sizes = shape == ObjectShape::box ? 3 : shape == ObjectShape::sphere ? 1 : 2;
    }
  }
  if (sizes == 0) {
    r.fail(*r.find("type"),
           fmt::format("'type' = \"{}\" is not box, sphere, cylinder or capsule", *type));
  }
  const std::string size_shape = sizes == 3   ? "[hx, hy, hz] (half-sizes in m)"
                                 : sizes == 1 ? "[radius] (m)"
                                              : "[radius, half-length] (m)";
  const auto size = r.numbers("size", sizes, size_shape);
  if (!size) r.fail_missing("size", size_shape.c_str());
  for (const double s : *size) {
    if (!(s > 0.0)) r.fail(*r.find("size"), fmt::format("'size' value {} m must be positive", s));
  }
  object.size = *size;
  const auto position = r.fixed<3>("pos", "[x, y, z] (m)");
  if (!position) r.fail_missing("pos", "[x, y, z] in m");
  object.position = *position;
  object.rotation = r.fixed<3>("rotation", "[rx, ry, rz] (rotation vector in rad)")
                        .value_or(std::array<double, 3>{});
  const std::optional<double> mass = r.number("mass", 1e-6, 1e4, "kg");
  if (!mass) r.fail_missing("mass", "kg");
  object.mass = *mass;
  if (const auto rgba = r.fixed<4>("rgba", "[r, g, b, a] (each 0 .. 1)")) {
    for (const double c : *rgba) {
      if (!(c >= 0.0 && c <= 1.0)) {
        r.fail(*r.find("rgba"), fmt::format("'rgba' value {} is outside 0 .. 1", c));
      }
    }
    object.rgba = *rgba;
  }
  object.attach = r.text("attach").value_or("");
  if (r.find("attach") != nullptr && object.attach.empty()) {
    r.fail(*r.find("attach"), "'attach' must name a body (or \"world\")");
  }
  read_contact(r, object);
  for (const toml::table* grasp : table_list(r, "grasp", "scene.object.grasp")) {
    object.grasps.push_back(read_grasp(file, *grasp, object.name));
  }
  if (!object.grasps.empty() && !object.attach.empty()) {
    r.fail(*r.find("attach"), fmt::format("object '{}' is attached to '{}': only a free object "
                                          "(without 'attach') can be grasped",
                                          object.name, object.attach));
  }
  for (const toml::table* cutter : table_list(r, "cutter", "scene.object.cutter")) {
    object.cutters.push_back(read_cutter(file, *cutter));
  }
  if (!object.cutters.empty()) {
    if (object.shape != ObjectShape::box) {
      r.fail(*r.find("type"), fmt::format("object '{}' has cutters: only a box (a board, cut on "
                                          "its top face) can be cut, not a {}",
                                          object.name, shape_name(object.shape)));
    }
    if (object.attach.empty()) {
      r.fail(*r.find("cutter"), fmt::format("object '{}' has cutters: a board to cut must be "
                                            "fixed (attach = \"world\" or a body), not free",
                                            object.name));
    }
  }
  return object;
}

// ---- Composition of the scene's MJCF document ----

namespace xml = tinyxml2;

/// Attributes that refer to a named element of the same robot (so they are prefixed too).
constexpr std::array<std::string_view, 29> kReferences = {
    "class",   "childclass", "joint",      "joint1",    "joint2",   "jointinparent",
    "body",    "body1",      "body2",      "geom",      "geom1",    "geom2",
    "site",    "sidesite",   "slidersite", "cranksite", "refsite",  "tendon",
    "tendon1", "tendon2",    "actuator",   "mesh",      "material", "texture",
    "hfield",  "skin",       "target",     "objname",   "refname"};
/// Of those, the ones naming a body (where "world" means the robot's base body).
constexpr std::array<std::string_view, 4> kBodyReferences = {"body", "body1", "body2", "target"};
/// Sections merged from every robot into one (in robot order).
constexpr std::array<std::string_view, 6> kMergedSections = {"contact",  "equality", "tendon",
                                                             "actuator", "sensor",   "custom"};
/// Elements whose default class is the robot's "<robot>/main" when they name none (inside the
/// worldbody the base body's childclass does that).
constexpr std::array<std::string_view, 17> kClassElements = {
    "mesh",     "material", "spatial",  "fixed",  "connect", "weld",
    "joint",    "distance", "tendon",   "pair",   "general", "motor",
    "position", "velocity", "cylinder", "muscle", "adhesion"};
/// Compiler attributes the composition handles itself (the rest must agree between robots).
constexpr std::array<std::string_view, 8> kOwnCompilerAttributes = {
    "angle",      "coordinate", "inertiafromgeom", "meshdir",
    "texturedir", "assetdir",   "strippath",       "fusestatic"};
constexpr std::array<std::string_view, 7> kTextureFiles = {
    "file", "fileright", "fileleft", "fileup", "filedown", "filefront", "fileback"};

template <std::size_t N>
bool among(const std::array<std::string_view, N>& list, std::string_view value) {
  return std::find(list.begin(), list.end(), value) != list.end();
}

std::string text_of(double value) { return fmt::format("{}", value); }

/// "x y z" and "w x y z" of a position and a rotation vector.
std::string position_text(double x, double y, double z) { return fmt::format("{} {} {}", x, y, z); }
std::string quaternion_text(const std::array<double, 3>& rotation_vector) {
  const Eigen::Vector3d v(rotation_vector[0], rotation_vector[1], rotation_vector[2]);
  const double angle = v.norm();
  const Eigen::Quaterniond q = angle > 0.0 ? Eigen::Quaterniond(Eigen::AngleAxisd(angle, v / angle))
                                           : Eigen::Quaterniond::Identity();
  return fmt::format("{} {} {} {}", q.w(), q.x(), q.y(), q.z());
}

std::vector<xml::XMLElement*> children(xml::XMLElement* parent, const char* tag = nullptr) {
  std::vector<xml::XMLElement*> out;
  for (xml::XMLElement* e = parent->FirstChildElement(tag); e != nullptr;
       e = e->NextSiblingElement(tag))
    out.push_back(e);
  return out;
}

/// Every element under (and including) `e`, depth first.
void collect(xml::XMLElement* e, std::vector<xml::XMLElement*>& out) {
  out.push_back(e);
  for (xml::XMLElement* c : children(e)) collect(c, out);
}

/// The names of a robot's model: prefix and the base body that replaces "world".
struct Naming {
  std::string prefix;  ///< "<robot>/"
  std::string base;    ///< "<robot>"

  [[nodiscard]] std::string main_class() const { return prefix + "main"; }

  /// Prefixes the names and references of `root`'s subtree.
  void apply(xml::XMLElement* root) const {
    std::vector<xml::XMLElement*> elements;
    collect(root, elements);
    std::vector<std::pair<std::string, std::string>> changes;
    for (xml::XMLElement* e : elements) {
      changes.clear();
      for (const xml::XMLAttribute* a = e->FirstAttribute(); a != nullptr; a = a->Next()) {
        const std::string_view key = a->Name();
        const std::string value = a->Value();
        if (key != "name" && !among(kReferences, key)) continue;
        bool body = among(kBodyReferences, key);
        if (key == "objname" || key == "refname") {
          const char* type = e->Attribute(key == "objname" ? "objtype" : "reftype");
          body = type != nullptr &&
                 (std::string_view(type) == "body" || std::string_view(type) == "xbody");
        }
        changes.emplace_back(std::string(key), body && value == "world" ? base : prefix + value);
      }
      for (const auto& [key, value] : changes) e->SetAttribute(key.c_str(), value.c_str());
    }
  }
};

/// Where a robot's model looks for its asset files.
struct AssetDirs {
  std::filesystem::path model_dir;  ///< folder of the MJCF file
  std::string meshdir, texturedir, assetdir;
  bool strippath = false;

  [[nodiscard]] std::filesystem::path resolve(const std::string& file, bool texture) const {
    std::filesystem::path path(file);
    if (strippath) path = path.filename();
    if (path.is_absolute()) return path;
    const std::string& own = texture ? texturedir : meshdir;
    const std::filesystem::path dir(own.empty() ? assetdir : own);
    return ((dir.is_absolute() ? dir : model_dir / dir) / path).lexically_normal();
  }
};

/// One robot's sources: its files, the model MuJoCo compiles from its MJCF alone, the XML.
struct RobotSource {
  const SceneRobot* robot = nullptr;
  std::filesystem::path mjcf;
  sim::RobotParameters parameters;
  sim::ModelPtr model;
  std::unique_ptr<xml::XMLDocument> document;
  xml::XMLElement* root = nullptr;
  Naming naming;
  AssetDirs dirs;
  std::string compiler;  ///< the attributes and children that must agree, in one text
};

/// Which field of two physics options differs ("" when none but the timestep).
std::string option_difference(const mjOption& a, const mjOption& b) {
  struct Reals {
    const char* name;
    const mjtNum* x;
    const mjtNum* y;
    int n;
  };
  const std::array<Reals, 13> reals = {{
      {"apirate", &a.apirate, &b.apirate, 1},
      {"impratio", &a.impratio, &b.impratio, 1},
      {"tolerance", &a.tolerance, &b.tolerance, 1},
      {"noslip_tolerance", &a.noslip_tolerance, &b.noslip_tolerance, 1},
      {"mpr_tolerance", &a.mpr_tolerance, &b.mpr_tolerance, 1},
      {"gravity", a.gravity, b.gravity, 3},
      {"wind", a.wind, b.wind, 3},
      {"magnetic", a.magnetic, b.magnetic, 3},
      {"density", &a.density, &b.density, 1},
      {"viscosity", &a.viscosity, &b.viscosity, 1},
      {"o_margin", &a.o_margin, &b.o_margin, 1},
      {"o_solref", a.o_solref, b.o_solref, mjNREF},
      {"o_solimp", a.o_solimp, b.o_solimp, mjNIMP},
  }};
  for (const Reals& r : reals)
    if (!std::equal(r.x, r.x + r.n, r.y)) return r.name;
  const std::array<std::pair<const char*, bool>, 10> integers = {{
      {"integrator", a.integrator == b.integrator},
      {"collision", a.collision == b.collision},
      {"cone", a.cone == b.cone},
      {"jacobian", a.jacobian == b.jacobian},
      {"solver", a.solver == b.solver},
      {"iterations", a.iterations == b.iterations},
      {"noslip_iterations", a.noslip_iterations == b.noslip_iterations},
      {"mpr_iterations", a.mpr_iterations == b.mpr_iterations},
      {"flag (disabled features)", a.disableflags == b.disableflags},
      {"flag (enabled features)", a.enableflags == b.enableflags},
  }};
  for (const auto& [name, same] : integers)
    if (!same) return name;
  return {};
}

class SceneComposer {
 public:
  explicit SceneComposer(const Scene& scene) : scene_(scene) {}

  ComposedScene compose() {
    if (scene_.robots.empty()) {
      throw ConfigError(scene_.where, "the scene has no [[scene.robot]]");
    }
    for (const SceneRobot& robot : scene_.robots) sources_.push_back(load(robot));
    start_document();
    merge_compiler();
    merge_option();
    merge_size();
    ComposedScene out;
    out.timestep = timestep_;
    int actuators = 0;
    int equalities = 0;
    for (RobotSource& source : sources_) {
      add_robot(source);
      ComposedRobot robot;
      robot.mjcf = source.mjcf;
      robot.parameters = source.parameters;
      robot.first_actuator = actuators;
      robot.actuator_count = source.model->nu;
      robot.first_equality = equalities;
      robot.equality_count = source.model->neq;
      actuators += source.model->nu;
      equalities += source.model->neq;
      out.robots.push_back(std::move(robot));
    }
    for (const SceneObject& object : scene_.objects) add_object(object);
    out.first_grasp_equality = equalities;
    for (const SceneObject& object : scene_.objects) add_grasps(object);
    for (xml::XMLElement* section : children(root_)) {
      if (section->NoChildren() && section->FirstAttribute() == nullptr)
        root_->DeleteChild(section);
    }
    xml::XMLPrinter printer;
    document_.Print(&printer);
    out.xml = printer.CStr();
    return out;
  }

 private:
  [[noreturn]] static void fail(const RobotSource& source, const std::string& text) {
    throw ConfigError(source.robot->where, fmt::format("robot '{}': {}", source.robot->name, text));
  }

  static RobotSource load(const SceneRobot& robot) {
    RobotSource source;
    source.robot = &robot;
    source.naming = Naming{robot.name + "/", robot.name};
    const std::filesystem::path parameters = robot.model_dir / "parameters.toml";
    if (!std::filesystem::exists(parameters)) {
      fail(source, fmt::format("robot parameter file {} not found (needed for the "
                               "synchronisation pose)",
                               sim::quoted(parameters)));
    }
    source.parameters = sim::read_robot_parameters(parameters);
    const std::optional<std::string> mjcf = robot.mjcf ? robot.mjcf : source.parameters.mjcf;
    if (!mjcf || mjcf->empty()) {
      fail(source, fmt::format("no MJCF file: {} has no robot.mjcf and the scene gives no 'mjcf'",
                               sim::quoted(parameters)));
    }
    source.mjcf = robot.model_dir / *mjcf;
    std::string error;
    source.model = sim::load_mjcf(source.mjcf.string(), nullptr, error);
    if (!source.model) {
      fail(source, fmt::format("cannot load MJCF model {}: {}", sim::quoted(source.mjcf), error));
    }
    source.document = std::make_unique<xml::XMLDocument>();
    if (source.document->LoadFile(source.mjcf.c_str()) != xml::XML_SUCCESS) {
      fail(source, fmt::format("cannot read {}: {}", sim::quoted(source.mjcf),
                               source.document->ErrorStr()));
    }
    source.root = source.document->RootElement();
    if (source.root == nullptr || std::string_view(source.root->Name()) != "mujoco") {
      fail(source,
           fmt::format("{} is not an MJCF file (no <mujoco> root)", sim::quoted(source.mjcf)));
    }
    std::vector<xml::XMLElement*> all;
    collect(source.root, all);
    for (const xml::XMLElement* e : all) {
      const std::string_view tag = e->Name();
      if (tag == "include" || tag == "composite") {
        fail(source, fmt::format("{} line {}: <{}> is not supported in a cell scene",
                                 sim::quoted(source.mjcf), e->GetLineNum(), tag));
      }
    }
    source.dirs.model_dir = source.mjcf.parent_path();
    return source;
  }

  void start_document() {
    document_.InsertEndChild(document_.NewComment(
        fmt::format(" Cell scene '{}' ({}), composed by mrroc's cell world from the robots' "
                    "MJCF files. ",
                    scene_.name, scene_.file.string())
            .c_str()));
    root_ = document_.NewElement("mujoco");
    root_->SetAttribute("model", scene_.name.c_str());
    document_.InsertEndChild(root_);
    for (const char* tag : {"compiler", "option", "size", "default", "custom", "asset", "worldbody",
                            "contact", "equality", "tendon", "actuator", "sensor"}) {
      sections_[tag] = root_->InsertNewChildElement(tag);
    }
    xml::XMLElement* light = sections_["worldbody"]->InsertNewChildElement("light");
    light->SetAttribute("name", "light");
    light->SetAttribute("pos", "0 0 4");
    light->SetAttribute("dir", "0 0 -1");
    light->SetAttribute("directional", "true");
    xml::XMLElement* floor = sections_["worldbody"]->InsertNewChildElement("geom");
    floor->SetAttribute("name", "floor");
    floor->SetAttribute("type", "plane");
    floor->SetAttribute("size", "5 5 0.05");
    floor->SetAttribute("rgba", "0.6 0.6 0.6 1");
  }

  /// Reads the robot's <compiler>: checks what the scene needs, keeps the rest for agreement.
  void read_compiler(RobotSource& source) const {
    std::map<std::string, std::string> attributes;
    std::string child_text;
    for (xml::XMLElement* compiler : children(source.root, "compiler")) {
      for (const xml::XMLAttribute* a = compiler->FirstAttribute(); a != nullptr; a = a->Next())
        attributes[a->Name()] = a->Value();
      for (xml::XMLElement* child : children(compiler)) {
        xml::XMLPrinter printer(nullptr, true);
        child->Accept(&printer);
        child_text += printer.CStr();
      }
    }
    const std::string file = sim::quoted(source.mjcf);
    if (attributes["angle"] != "radian") {
      fail(source, fmt::format("{}: <compiler angle> is '{}' (MuJoCo's default is degree); a cell "
                               "scene needs angle=\"radian\"",
                               file, attributes["angle"]));
    }
    if (!attributes["coordinate"].empty() && attributes["coordinate"] != "local") {
      fail(source, fmt::format("{}: <compiler coordinate=\"{}\"> is not supported (only local)",
                               file, attributes["coordinate"]));
    }
    if (attributes.count("settotalmass") != 0) {
      fail(source, fmt::format("{}: <compiler settotalmass> would scale the whole cell", file));
    }
    const std::string inertia = attributes["inertiafromgeom"];
    if (inertia == "false" || inertia == "true") {
      std::vector<xml::XMLElement*> all;
      collect(source.root, all);
      for (xml::XMLElement* body : all) {
        if (std::string_view(body->Name()) != "body") continue;
        const bool has_inertial = body->FirstChildElement("inertial") != nullptr;
        if (has_inertial != (inertia == "false")) {
          const char* name = body->Attribute("name");
          fail(source,
               fmt::format("{} line {}: with <compiler inertiafromgeom=\"{}\"> body '{}' "
                           "{} an <inertial>; the cell scene uses \"auto\", which would "
                           "treat it differently",
                           file, body->GetLineNum(), inertia, name != nullptr ? name : "(unnamed)",
                           inertia == "false" ? "needs" : "must not have"));
        }
      }
    }
    source.dirs.meshdir = attributes["meshdir"];
    source.dirs.texturedir = attributes["texturedir"];
    source.dirs.assetdir = attributes["assetdir"];
    source.dirs.strippath = attributes["strippath"] == "true";
    for (const auto& [key, value] : attributes) {
      if (!among(kOwnCompilerAttributes, key) && !value.empty())
        source.compiler += fmt::format("{}=\"{}\" ", key, value);
    }
    source.compiler += child_text;
  }

  void merge_compiler() {
    for (RobotSource& source : sources_) {
      read_compiler(source);
      const RobotSource& first = sources_.front();
      if (source.compiler != first.compiler) {
        fail(source, fmt::format("<compiler> settings of {} ({}) differ from those of robot '{}' "
                                 "in {} ({})",
                                 sim::quoted(source.mjcf), source.compiler, first.robot->name,
                                 sim::quoted(first.mjcf), first.compiler));
      }
    }
    xml::XMLElement* compiler = sections_["compiler"];
    compiler->SetAttribute("angle", "radian");
    compiler->SetAttribute("inertiafromgeom", "auto");
    for (xml::XMLElement* own : children(sources_.front().root, "compiler")) {
      for (const xml::XMLAttribute* a = own->FirstAttribute(); a != nullptr; a = a->Next())
        if (!among(kOwnCompilerAttributes, a->Name()))
          compiler->SetAttribute(a->Name(), a->Value());
      for (xml::XMLElement* child : children(own))
        compiler->InsertEndChild(child->DeepClone(&document_));
    }
  }

  void merge_option() {
    const RobotSource& first = sources_.front();
    timestep_ = scene_.timestep.value_or(first.model->opt.timestep);
    for (const RobotSource& source : sources_) {
      const std::string field = option_difference(source.model->opt, first.model->opt);
      if (!field.empty()) {
        fail(source,
             fmt::format("<option> {} of {} differs from that of robot '{}' in {}", field,
                         sim::quoted(source.mjcf), first.robot->name, sim::quoted(first.mjcf)));
      }
      if (!scene_.timestep && source.model->opt.timestep != first.model->opt.timestep) {
        throw ConfigError(scene_.where,
                          fmt::format("the robots' MuJoCo timesteps differ ({} s in {}, {} s in "
                                      "{}): set [scene] timestep",
                                      first.model->opt.timestep, sim::quoted(first.mjcf),
                                      source.model->opt.timestep, sim::quoted(source.mjcf)));
      }
    }
    xml::XMLElement* option = sections_["option"];
    for (const RobotSource& source : sources_) {
      if (xml::XMLElement* own = source.root->FirstChildElement("option")) {
        xml::XMLElement* copy = own->DeepClone(&document_)->ToElement();
        root_->InsertAfterChild(option, copy);
        root_->DeleteChild(option);
        sections_["option"] = option = copy;
        break;
      }
    }
    option->SetAttribute("timestep", text_of(timestep_).c_str());
  }

  void merge_size() {
    std::map<std::string, int> largest;
    std::map<std::string, bool> summed;
    for (const RobotSource& source : sources_) {
      for (xml::XMLElement* size : children(source.root, "size")) {
        for (const xml::XMLAttribute* a = size->FirstAttribute(); a != nullptr; a = a->Next()) {
          const std::string key = a->Name();
          if (key == "njmax" || key == "nconmax" || key == "nstack") {
            summed[key] = true;
          } else if (key.rfind("nuser", 0) == 0) {
            largest[key] = std::max(largest[key], a->IntValue());
          } else if (key != "nkey") {
            fail(source, fmt::format("{}: <size {}> is not supported in a cell scene",
                                     sim::quoted(source.mjcf), key));
          }
        }
      }
    }
    xml::XMLElement* size = sections_["size"];
    for (const auto& [key, value] : largest) size->SetAttribute(key.c_str(), value);
    // Each robot needs its own share: sum what MuJoCo allotted to each model alone.
    for (const auto& [key, unused] : summed) {
      long total = 0;
      for (const RobotSource& source : sources_) {
        const mjModel* m = source.model.get();
        total += key == "njmax" ? m->njmax : key == "nconmax" ? m->nconmax : m->nstack;
      }
      size->SetAttribute(key.c_str(), static_cast<int64_t>(total));
    }
  }

  /// A deep copy of a robot's element, its names prefixed.
  xml::XMLElement* copy(const RobotSource& source, const xml::XMLElement* element) {
    xml::XMLElement* out = element->DeepClone(&document_)->ToElement();
    source.naming.apply(out);
    return out;
  }

  void give_class(const RobotSource& source, xml::XMLElement* element) const {
    const std::string_view tag = element->Name();
    if (element->Attribute("class") == nullptr && among(kClassElements, tag)) {
      element->SetAttribute("class", source.naming.main_class().c_str());
    }
  }

  void add_robot(const RobotSource& source) {
    const Naming& naming = source.naming;
    // Defaults: the robot's top-level class becomes "<robot>/main".
    const std::vector<xml::XMLElement*> defaults = children(source.root, "default");
    if (defaults.size() > 1) {
      fail(source, fmt::format("{} has {} top-level <default> elements (one is supported)",
                               sim::quoted(source.mjcf), defaults.size()));
    }
    xml::XMLElement* main =
        defaults.empty() ? document_.NewElement("default") : copy(source, defaults.front());
    main->SetAttribute("class", naming.main_class().c_str());
    sections_["default"]->InsertEndChild(main);

    for (xml::XMLElement* asset : children(source.root, "asset")) {
      for (xml::XMLElement* element : children(asset)) add_asset(source, element);
    }

    // The robot's world goes into its base body.
    xml::XMLElement* base = sections_["worldbody"]->InsertNewChildElement("body");
    const std::array<double, 6>& pose = source.robot->base;
    base->SetAttribute("name", naming.base.c_str());
    base->SetAttribute("pos", position_text(pose[0], pose[1], pose[2]).c_str());
    base->SetAttribute("quat", quaternion_text({pose[3], pose[4], pose[5]}).c_str());
    base->SetAttribute("childclass", naming.main_class().c_str());
    for (xml::XMLElement* world : children(source.root, "worldbody")) {
      for (xml::XMLElement* element : children(world)) {
        const std::string_view tag = element->Name();
        const char* type = element->Attribute("type");
        const bool plane = tag == "geom" && type != nullptr && std::string_view(type) == "plane";
        if (tag == "light" || plane) continue;  // the scene has its own floor and light
        base->InsertEndChild(copy(source, element));
      }
    }

    for (const std::string_view tag : kMergedSections) {
      const std::string name(tag);
      for (xml::XMLElement* section : children(source.root, name.c_str())) {
        for (xml::XMLElement* element : children(section)) {
          xml::XMLElement* merged = copy(source, element);
          give_class(source, merged);
          sections_[name]->InsertEndChild(merged);
        }
      }
    }
  }

  void add_asset(const RobotSource& source, const xml::XMLElement* element) {
    xml::XMLElement* asset = copy(source, element);
    const std::string_view tag = asset->Name();
    const bool texture = tag == "texture";
    if (texture || tag == "mesh" || tag == "hfield" || tag == "skin") {
      for (const std::string_view key : kTextureFiles) {
        const std::string attribute(key);
        const char* file = asset->Attribute(attribute.c_str());
        if (file == nullptr || (!texture && key != "file")) continue;
        const std::filesystem::path path = source.dirs.resolve(file, texture);
        // MuJoCo names an unnamed file asset after its file; the name gets the prefix too.
        if (key == "file" && asset->Attribute("name") == nullptr) {
          asset->SetAttribute("name", (source.naming.prefix + path.stem().string()).c_str());
        }
        asset->SetAttribute(attribute.c_str(), path.c_str());
      }
    }
    give_class(source, asset);
    sections_["asset"]->InsertEndChild(asset);
  }

  static xml::XMLElement* find_body(xml::XMLElement* root, const std::string& name) {
    std::vector<xml::XMLElement*> all;
    collect(root, all);
    for (xml::XMLElement* e : all) {
      const char* own = e->Attribute("name");
      if (std::string_view(e->Name()) == "body" && own != nullptr && name == own) return e;
    }
    return nullptr;
  }

  void add_object(const SceneObject& object) {
    xml::XMLElement* parent = sections_["worldbody"];
    if (!object.attach.empty() && object.attach != "world") {
      parent = find_body(sections_["worldbody"], object.attach);
      if (parent == nullptr) {
        throw ConfigError(
            object.where,
            fmt::format(
                "object '{}': attach = \"{}\" names no body of the scene (a robot's bodies are "
                "named '<robot>/<body>', e.g. 'conveyor/belt_link'; objects by their name)",
                object.name, object.attach));
      }
    }
    xml::XMLElement* body = parent->InsertNewChildElement("body");
    body->SetAttribute("name", object.name.c_str());
    body->SetAttribute(
        "pos", position_text(object.position[0], object.position[1], object.position[2]).c_str());
    body->SetAttribute("quat", quaternion_text(object.rotation).c_str());
    body->SetAttribute("childclass", "main");
    if (object.attach.empty())
      body->InsertNewChildElement("freejoint")->SetAttribute("name", object.name.c_str());
    xml::XMLElement* geom = body->InsertNewChildElement("geom");
    geom->SetAttribute("name", object.name.c_str());
    geom->SetAttribute("type", shape_name(object.shape));
    std::string size;
    for (const double s : object.size) size += (size.empty() ? "" : " ") + text_of(s);
    geom->SetAttribute("size", size.c_str());
    geom->SetAttribute("mass", text_of(object.mass).c_str());
    if (!object.contact) {
      geom->SetAttribute("contype", 0);
      geom->SetAttribute("conaffinity", 0);
    }
    if (object.solref || !object.friction.empty()) geom->SetAttribute("priority", 1);
    if (object.solref) {
      // A stiffness solref is converted to MuJoCo's form by CellWorld (it needs the model).
      geom->SetAttribute("solref",
                         fmt::format("{} {}", (*object.solref)[0], (*object.solref)[1]).c_str());
    }
    if (!object.friction.empty()) {
      std::string friction;
      for (const double f : object.friction) friction += (friction.empty() ? "" : " ") + text_of(f);
      geom->SetAttribute("friction", friction.c_str());
    }
    geom->SetAttribute("rgba", fmt::format("{} {} {} {}", object.rgba[0], object.rgba[1],
                                           object.rgba[2], object.rgba[3])
                                   .c_str());
  }

  /// A site's body: the <body> element holding the <site> named `site`; empty when none.
  std::string site_body(const std::string& site) const {
    std::vector<xml::XMLElement*> all;
    collect(root_, all);
    for (xml::XMLElement* e : all) {
      const char* own = e->Attribute("name");
      if (std::string_view(e->Name()) != "site" || own == nullptr || site != own) continue;
      const xml::XMLElement* parent = e->Parent()->ToElement();
      const char* body = parent != nullptr ? parent->Attribute("name") : nullptr;
      if (parent != nullptr && std::string_view(parent->Name()) == "worldbody") return "world";
      return body != nullptr ? body : "";
    }
    return {};
  }

  /// The grasps' welds: inactive, between the gripper's body and the object (CellWorld sets
  /// their data).
  void add_grasps(const SceneObject& object) {
    for (std::size_t i = 0; i < object.grasps.size(); ++i) {
      const SceneGrasp& grasp = object.grasps[i];
      std::string body = grasp.body;
      if (!grasp.site.empty()) {
        body = site_body(grasp.site);
        if (body.empty()) {
          throw ConfigError(grasp.where,
                            fmt::format("grasp of object '{}': site '{}' is not in the scene (a "
                                        "robot's sites are named '<robot>/<site>', e.g. "
                                        "'left/flange')",
                                        object.name, grasp.site));
        }
      } else if (find_body(sections_["worldbody"], body) == nullptr) {
        throw ConfigError(grasp.where,
                          fmt::format("grasp of object '{}': body '{}' is not in the scene (a "
                                      "robot's bodies are named '<robot>/<body>', e.g. "
                                      "'left/roll_link')",
                                      object.name, body));
      }
      bool robot = false;
      for (const SceneRobot& r : scene_.robots) robot = robot || body.rfind(r.name + "/", 0) == 0;
      if (!robot) {
        throw ConfigError(grasp.where,
                          fmt::format("grasp of object '{}': '{}' is on body '{}', which is not "
                                      "a robot's (a gripper is a robot's body)",
                                      object.name, grasp.gripper(), body));
      }
      xml::XMLElement* weld = sections_["equality"]->InsertNewChildElement("weld");
      weld->SetAttribute("name", fmt::format("{}/grasp{}", object.name, i).c_str());
      weld->SetAttribute("body1", body.c_str());
      weld->SetAttribute("body2", object.name.c_str());
      weld->SetAttribute("active", "false");
    }
  }

  const Scene& scene_;
  std::vector<RobotSource> sources_;
  xml::XMLDocument document_;
  xml::XMLElement* root_ = nullptr;
  std::map<std::string, xml::XMLElement*> sections_;
  double timestep_ = 0.0;
};

}  // namespace

const char* shape_name(ObjectShape shape) noexcept {
  switch (shape) {
    case ObjectShape::box: return "box";
    case ObjectShape::sphere: return "sphere";
    case ObjectShape::cylinder: return "cylinder";
    case ObjectShape::capsule: return "capsule";
  }
  return "?";
}

Scene parse_scene(const std::string& text, const fs::path& origin) {
  toml::table root;
  try {
    root = toml::parse(text, origin.string());
  } catch (const toml::parse_error& e) {
    throw ConfigError(SourceLocation{origin.string(), static_cast<int>(e.source().begin.line)},
                      std::string(e.description()));
  }
  const TableReader top(origin, root, "");
  top.reject_unknown({"scene"});
  const toml::node* scene_node = root.get("scene");
  if (scene_node == nullptr || !scene_node->is_table()) {
    throw ConfigError(SourceLocation{origin.string(), 1}, "missing table [scene]");
  }
  const toml::table& table = *scene_node->as_table();
  const TableReader r(origin, table, "scene");
  // `sensor` (raw sensor devices) is read by the emulator (emu/sensors.hpp).
  r.reject_unknown({"name", "timestep", "robot", "object", "sensor"});

  Scene scene;
  scene.file = origin;
  scene.where = r.at(table);
  scene.name = r.text("name").value_or(origin.stem().string());
  scene.timestep = r.number("timestep", kMinTimestep, kMaxTimestep, "s");

  // Names are unique across robots and objects: they are the bodies' names in the scene.
  std::vector<std::pair<std::string, SourceLocation>> names;
  const auto claim = [&](const std::string& name, const SourceLocation& where, const char* kind) {
    for (const auto& [other, other_where] : names) {
      if (other == name) {
        throw ConfigError(where, fmt::format("duplicate {} name '{}' (first used at {})", kind,
                                             name, other_where.str()));
      }
    }
    names.emplace_back(name, where);
  };
  for (const toml::table* robot : table_list(r, "robot")) {
    scene.robots.push_back(read_robot(origin, *robot));
    claim(scene.robots.back().name, scene.robots.back().where, "robot");
  }
  if (scene.robots.empty()) {
    throw ConfigError(scene.where, "the scene has no [[scene.robot]]");
  }
  for (const toml::table* object : table_list(r, "object")) {
    scene.objects.push_back(read_object(origin, *object));
    claim(scene.objects.back().name, scene.objects.back().where, "object");
  }
  return scene;
}

ComposedScene compose_scene(const Scene& scene) { return SceneComposer(scene).compose(); }

Scene load_scene(const fs::path& file) {
  std::ifstream in(file);
  if (!in) throw ConfigError(SourceLocation{file.string(), 0}, "cannot read the scene file");
  std::stringstream text;
  text << in.rdbuf();
  return parse_scene(text.str(), file);
}

}  // namespace mrroc::emu
