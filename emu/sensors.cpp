/// @file
/// The scene's raw sensor devices (see sensors.hpp).
#include "sensors.hpp"

#include <fmt/format.h>

#include <toml++/toml.h>
#include <Eigen/Dense>
#include <algorithm>
#include <cmath>

#include "mrroc/comm/auth.hpp"
#include "mrroc/comm/codec.hpp"
#include "mrroc/config/process_set.hpp"
#include "mrroc/core/error.hpp"

namespace mrroc::emu {
namespace {

namespace fs = std::filesystem;
using Matrix3 = Eigen::Matrix3d;
using Vector3 = Eigen::Vector3d;
using RowMajor3 = Eigen::Matrix<double, 3, 3, Eigen::RowMajor>;

constexpr std::array<const char*, 6> kTypeNames = {"strain_gauges", "range", "encoder",
                                                   "camera",        "grasp", "engraving"};
constexpr std::array<double, 6> kDefaultRates = {500.0, 50.0, 500.0, 30.0, 500.0, 500.0};
constexpr const char* kTypeList = "strain_gauges, range, encoder, camera, grasp or engraving";

std::size_t at(int i) { return static_cast<std::size_t>(i); }

Matrix3 rotation_matrix(const std::array<double, 3>& rotation_vector) {
  const Vector3 v(rotation_vector[0], rotation_vector[1], rotation_vector[2]);
  const double angle = v.norm();
  return angle > 0.0 ? Eigen::AngleAxisd(angle, v / angle).toRotationMatrix() : Matrix3::Identity();
}

/// FNV-1a: a stable default noise seed from the device name.
std::uint64_t name_seed(const std::string& name) {
  std::uint64_t h = 14695981039346656037ULL;
  for (const char c : name) {
    h ^= static_cast<unsigned char>(c);
    h *= 1099511628211ULL;
  }
  return h;
}

/// Reads one [[scene.sensor]] table; every error names the file, line and device.
class SensorReader {
 public:
  SensorReader(const fs::path& file, const toml::table& table) : file_(file), table_(table) {}

  [[nodiscard]] SourceLocation at(const toml::node& node) const {
    return SourceLocation{file_.string(), static_cast<int>(node.source().begin.line)};
  }
  [[noreturn]] void fail(const toml::node& node, const std::string& text) const {
    const std::string who = device_.empty() ? "sensor" : fmt::format("sensor '{}'", device_);
    throw ConfigError(at(node), fmt::format("{}: {}", who, text));
  }
  [[noreturn]] void fail_missing(const char* key, const std::string& what) const {
    fail(table_, fmt::format("missing key '{}' ({})", key, what));
  }
  void set_device(std::string name) { device_ = std::move(name); }

  void reject_unknown(const std::vector<std::string>& known, const std::string& type) const {
    for (const auto& [key, node] : table_) {
      if (std::find(known.begin(), known.end(), key.str()) != known.end()) continue;
      fail(node, fmt::format("unknown key '{}' in [[scene.sensor]] of type {} (allowed: {})",
                             key.str(), type, fmt::join(known, ", ")));
    }
  }

  [[nodiscard]] const toml::node* find(const char* key) const { return table_.get(key); }

  [[nodiscard]] std::optional<std::string> text(const char* key) const {
    const toml::node* node = find(key);
    if (node == nullptr) return std::nullopt;
    if (!node->is_string()) fail(*node, fmt::format("'{}' must be a string", key));
    return std::string(**node->as_string());
  }

  [[nodiscard]] double number_of(const toml::node& node, const std::string& what) const {
    if (node.is_number()) {
      if (const auto value = node.value<double>(); value && std::isfinite(*value)) return *value;
    }
    fail(node, fmt::format("{} must be a finite number", what));
  }

  /// A number within [min, max].
  [[nodiscard]] std::optional<double> number(const char* key, double min, double max,
                                             const char* unit) const {
    const toml::node* node = find(key);
    if (node == nullptr) return std::nullopt;
    const double value = number_of(*node, fmt::format("'{}' [{}]", key, unit));
    if (!(value >= min && value <= max)) {
      fail(*node,
           fmt::format("'{}' = {} {} is outside {} .. {} {}", key, value, unit, min, max, unit));
    }
    return value;
  }

  [[nodiscard]] std::vector<double> numbers_of(const toml::node& node, std::size_t count,
                                               const char* key, const std::string& shape) const {
    const toml::array* array = node.as_array();
    if (array == nullptr || array->size() != count) {
      const std::string got =
          array == nullptr ? "not a list" : fmt::format("{} values", array->size());
      fail(node, fmt::format("'{}' must be {} ({})", key, shape, got));
    }
    std::vector<double> values;
    for (const toml::node& element : *array)
      values.push_back(number_of(element, fmt::format("every value of '{}'", key)));
    return values;
  }

  template <std::size_t N>
  [[nodiscard]] std::optional<std::array<double, N>> fixed(const char* key,
                                                           const std::string& shape) const {
    const toml::node* node = find(key);
    if (node == nullptr) return std::nullopt;
    const std::vector<double> values = numbers_of(*node, N, key, shape);
    std::array<double, N> out{};
    std::copy(values.begin(), values.end(), out.begin());
    return out;
  }

 private:
  const fs::path& file_;
  const toml::table& table_;
  std::string device_;
};

const std::vector<std::string>& known_keys(SensorType type) {
  static const std::vector<std::string> gauges = {"name",         "type",  "rate_hz", "noise",
                                                  "seed",         "body",  "pos",     "rotation",
                                                  "gauge_matrix", "offset"};
  static const std::vector<std::string> range = {"name", "type", "rate_hz",  "noise",    "seed",
                                                 "body", "pos",  "rotation", "max_range"};
  static const std::vector<std::string> encoder = {"name", "type",  "rate_hz", "noise",
                                                   "seed", "robot", "axis"};
  static const std::vector<std::string> camera = {"name", "type",    "rate_hz", "noise",
                                                  "seed", "objects", "region",  "latency_ms"};
  static const std::vector<std::string> grasp = {"name",  "type", "rate_hz",
                                                 "noise", "seed", "object"};
  static const std::vector<std::string> engraving = {"name", "type",   "rate_hz", "noise",
                                                     "seed", "object", "cutter"};
  switch (type) {
    case SensorType::strain_gauges: return gauges;
    case SensorType::range: return range;
    case SensorType::encoder: return encoder;
    case SensorType::camera: return camera;
    case SensorType::grasp: return grasp;
    case SensorType::engraving: return engraving;
  }
  return gauges;
}

const char* kBodyHint =
    "a robot's bodies are named '<robot>/<body>', e.g. 'irb6/roll_link'; objects by their "
    "name; \"world\" is the world";

void read_mount(const SensorReader& r, const CellWorld& world, SensorConfig& c) {
  const std::optional<std::string> body = r.text("body");
  if (!body) r.fail_missing("body", std::string("the body it is mounted on: ") + kBodyHint);
  if (*body != "world" && world.body_id(*body) < 0)
    r.fail(*r.find("body"), fmt::format("body '{}' is not in the scene ({})", *body, kBodyHint));
  c.body = *body;
  c.position = r.fixed<3>("pos", "[x, y, z] (m, in the body)").value_or(std::array<double, 3>{});
  c.rotation = r.fixed<3>("rotation", "[rx, ry, rz] (rotation vector in rad, in the body)")
                   .value_or(std::array<double, 3>{});
}

void read_gauges(const SensorReader& r, SensorConfig& c) {
  if (const toml::node* node = r.find("gauge_matrix")) {
    const char* shape = "6 rows of 6 numbers (V per N or per N m)";
    const toml::array* rows = node->as_array();
    if (rows == nullptr || rows->size() != 6) {
      r.fail(*node,
             fmt::format("'gauge_matrix' must be {} ({})", shape,
                         rows == nullptr ? "not a list" : fmt::format("{} rows", rows->size())));
    }
    for (std::size_t i = 0; i < 6; ++i) {
      const std::vector<double> row =
          r.numbers_of((*rows)[i], 6, "gauge_matrix", fmt::format("{}: row {}", shape, i));
      std::copy(row.begin(), row.end(), c.gauge_matrix.begin() + static_cast<long>(6 * i));
    }
    const Eigen::Map<const Eigen::Matrix<double, 6, 6, Eigen::RowMajor>> g(c.gauge_matrix.data());
    const Eigen::JacobiSVD<Eigen::Matrix<double, 6, 6>> svd(g);
    const auto& s = svd.singularValues();
    if (!(s(5) > 1e-9 * s(0))) {
      r.fail(*node, fmt::format("'gauge_matrix' is singular (singular values {:.3g} .. {:.3g}): "
                                "the wrench could not be calibrated back from the volts",
                                s(0), s(5)));
    }
  }
  c.offset = r.fixed<6>("offset", "6 numbers (V)").value_or(std::array<double, 6>{});
}

void read_encoder(const SensorReader& r, const CellWorld& world, SensorConfig& c) {
  const std::optional<std::string> robot = r.text("robot");
  if (!robot) r.fail_missing("robot", "the robot whose axis it reads");
  std::size_t k = 0;
  try {
    k = world.robot_index(*robot);
  } catch (const Error& e) {
    r.fail(*r.find("robot"), e.what());
  }
  c.robot = *robot;
  const CellRobot& info = world.robot(k);
  const toml::node* axis = r.find("axis");
  if (axis == nullptr) r.fail_missing("axis", "an axis name or 0-based index");
  bool found = false;
  if (const auto number = axis->value<std::int64_t>(); axis->is_integer() && number) {
    found = *number >= 0 && static_cast<std::size_t>(*number) < info.axis_count();
    if (found) c.axis = static_cast<std::size_t>(*number);
  } else if (axis->is_string()) {
    for (std::size_t i = 0; i < info.axis_count(); ++i) {
      if (info.axis_names[i] == **axis->as_string()) {
        c.axis = i;
        found = true;
      }
    }
  }
  if (!found) {
    r.fail(*axis,
           fmt::format("robot '{}' has no axis {} (axes: {})", info.name,
                       axis->is_string() ? fmt::format("'{}'", **axis->as_string())
                                         : fmt::format("{}", axis->value<double>().value_or(-1)),
                       fmt::join(info.axis_names, ", ")));
  }
}

void read_camera(const SensorReader& r, const CellWorld& world, SensorConfig& c) {
  const toml::node* objects = r.find("objects");
  if (objects == nullptr) r.fail_missing("objects", "the bodies it looks for, e.g. [\"part\"]");
  const toml::array* list = objects->as_array();
  if (list == nullptr || list->empty())
    r.fail(*objects, "'objects' must be a non-empty list of body names");
  for (const toml::node& element : *list) {
    if (!element.is_string()) r.fail(element, "'objects' must be a list of body names");
    const std::string name(**element.as_string());
    if (world.body_id(name) <= 0)
      r.fail(element, fmt::format("object '{}' is not a body of the scene ({})", name, kBodyHint));
    c.objects.push_back(name);
  }
  const auto region = r.fixed<6>("region", "[xmin, xmax, ymin, ymax, zmin, zmax] (m, world)");
  if (!region) r.fail_missing("region", "[xmin, xmax, ymin, ymax, zmin, zmax] in m (world)");
  for (std::size_t i = 0; i < 3; ++i) {
    if (!((*region)[2 * i] < (*region)[2 * i + 1])) {
      r.fail(*r.find("region"), fmt::format("'region' {} range {} .. {} m is empty", "xyz"[i],
                                            (*region)[2 * i], (*region)[2 * i + 1]));
    }
  }
  c.region = *region;
  c.latency_s = r.number("latency_ms", 0.0, 10000.0, "ms").value_or(50.0) * 1e-3;
}

void read_grasp(const SensorReader& r, const CellWorld& world, SensorConfig& c) {
  const std::optional<std::string> object = r.text("object");
  if (!object) r.fail_missing("object", "an object with [[scene.object.grasp]] entries");
  try {
    (void)world.held_object_index(*object);
  } catch (const Error& e) {
    r.fail(*r.find("object"), e.what());
  }
  c.object = *object;
}

void read_engraving(const SensorReader& r, const CellWorld& world, SensorConfig& c) {
  const std::optional<std::string> object = r.text("object");
  if (!object) r.fail_missing("object", "a board with [[scene.object.cutter]] entries");
  c.cutter = r.text("cutter").value_or("");
  try {
    (void)world.cut_index(*object, c.cutter);
  } catch (const Error& e) {
    r.fail(*r.find(c.cutter.empty() ? "object" : "cutter"), e.what());
  }
  c.object = *object;
}

SensorConfig read_sensor(const fs::path& file, const toml::table& table, const CellWorld& world) {
  SensorReader r(file, table);
  SensorConfig c;
  c.where = r.at(table);
  const std::optional<std::string> name = r.text("name");
  if (!name) r.fail_missing("name", "the device name; its channel is mrroc/raw/<name>");
  if (name->empty() || name->find('/') != std::string::npos ||
      name->find_first_of(" \t\n") != std::string::npos) {
    r.fail(*r.find("name"),
           fmt::format("'name' = \"{}\" must be a non-empty name without '/' or spaces", *name));
  }
  c.name = *name;
  r.set_device(c.name);
  const std::optional<std::string> type = r.text("type");
  if (!type) r.fail_missing("type", kTypeList);
  bool known = false;
  for (std::size_t t = 0; t < kTypeNames.size(); ++t) {
    if (*type == kTypeNames[t]) {
      c.type = static_cast<SensorType>(t);
      known = true;
    }
  }
  if (!known) {
    r.fail(*r.find("type"), fmt::format("'type' = \"{}\" is not {}", *type, kTypeList));
  }
  r.reject_unknown(known_keys(c.type), *type);
  const double physics_rate = 1.0 / world.timestep();
  c.rate_hz = kDefaultRates[static_cast<std::size_t>(c.type)];
  if (const toml::node* rate = r.find("rate_hz")) {
    c.rate_hz = r.number_of(*rate, "'rate_hz' [Hz]");
    if (!(c.rate_hz > 0.0) || c.rate_hz > physics_rate * (1.0 + 1e-9)) {
      r.fail(*rate, fmt::format("'rate_hz' = {} Hz must be > 0 and at most the physics rate {} Hz "
                                "(timestep {} s)",
                                c.rate_hz, physics_rate, world.timestep()));
    }
  }
  c.noise = r.number("noise", 0.0, 1e3, "(V, m or rad)").value_or(0.0);
  c.seed = name_seed(c.name);
  if (const toml::node* seed = r.find("seed")) {
    const auto value = seed->value<std::int64_t>();
    if (!seed->is_integer() || !value || *value < 0)
      r.fail(*seed, "'seed' must be an integer >= 0");
    c.seed = static_cast<std::uint64_t>(*value);
  }
  switch (c.type) {
    case SensorType::strain_gauges:
      read_mount(r, world, c);
      read_gauges(r, c);
      break;
    case SensorType::range:
      read_mount(r, world, c);
      c.max_range = r.number("max_range", 1e-3, 100.0, "m").value_or(4.0);
      break;
    case SensorType::encoder: read_encoder(r, world, c); break;
    case SensorType::camera: read_camera(r, world, c); break;
    case SensorType::grasp: read_grasp(r, world, c); break;
    case SensorType::engraving: read_engraving(r, world, c); break;
  }
  return c;
}

}  // namespace

const char* sensor_type_name(SensorType type) noexcept {
  const auto i = static_cast<std::size_t>(type);
  return i < kTypeNames.size() ? kTypeNames[i] : "?";
}

GaugeMatrix default_gauge_matrix() noexcept {
  constexpr std::array<double, 6> sensitivity = {0.01, 0.01, 0.01, 0.1, 0.1, 0.1};
  GaugeMatrix g{};
  for (std::size_t i = 0; i < 6; ++i) {
    g[6 * i + i] = sensitivity[i];
    g[6 * i + (i + 1) % 6] = 0.02 * sensitivity[i];
    g[6 * i + (i + 5) % 6] = -0.01 * sensitivity[i];
  }
  return g;
}

std::vector<SensorConfig> read_sensor_configs(const fs::path& file, const CellWorld& world) {
  toml::table root;
  try {
    root = toml::parse_file(file.string());
  } catch (const toml::parse_error& e) {
    throw ConfigError(SourceLocation{file.string(), static_cast<int>(e.source().begin.line)},
                      std::string(e.description()));
  }
  std::vector<SensorConfig> out;
  const toml::node* node = root["scene"]["sensor"].node();
  if (node == nullptr) return out;
  const toml::array* array = node->as_array();
  const auto fail = [&](const toml::node& n) {
    throw ConfigError(SourceLocation{file.string(), static_cast<int>(n.source().begin.line)},
                      "'sensor' must be [[scene.sensor]] tables");
  };
  if (array == nullptr) fail(*node);
  for (const toml::node& element : *array) {
    if (!element.is_table()) fail(element);
    SensorConfig c = read_sensor(file, *element.as_table(), world);
    for (const SensorConfig& other : out) {
      if (other.name == c.name) {
        throw ConfigError(c.where, fmt::format("duplicate sensor name '{}' (first used at {})",
                                               c.name, other.where.str()));
      }
    }
    out.push_back(std::move(c));
  }
  return out;
}

// ---- The devices ----

struct SensorDevices::Device {
  SensorConfig config;
  double period_s = 0.0;
  double next_due_s = 0.0;
  std::int64_t next_sample_no = 0;
  std::mt19937_64 random;
  std::normal_distribution<double> normal{0.0, 1.0};
  vsp::RawSample sample;  ///< the one to publish

  // Mounted devices (strain gauges, range).
  int body = 0;
  Matrix3 local_rotation = Matrix3::Identity();
  Vector3 local_position = Vector3::Zero();
  int exclude_body = -1;  ///< range: the mounting body (none on the world)

  // Strain gauges.
  std::vector<char> outboard;            ///< per body
  std::vector<int> weighed;              ///< outboard bodies with mass
  std::vector<std::size_t> held_grasps;  ///< grasps whose gripper is the mounting body or outboard
  std::array<double, 6> wrench{};

  // Encoder.
  std::size_t robot = 0;
  std::string axis_name;
  std::vector<double> positions;

  // Camera: samples waiting for their publication (a ring).
  std::vector<int> object_bodies;
  struct Pending {
    double taken_s = 0.0;
    std::int64_t sample_no = 0;
    bool valid = false;
    std::array<double, 7> values{};
  };
  std::vector<Pending> queue;
  std::size_t head = 0;
  std::size_t count = 0;
  std::int64_t latency_us = 0;

  // Grasp: the object and its grasps (CellWorld indices).
  std::size_t held = 0;
  int object_body = 0;
  std::vector<std::size_t> grasps;

  // Engraving: the cut (CellWorld index).
  std::size_t cut = 0;

  double noise() noexcept { return config.noise > 0.0 ? config.noise * normal(random) : 0.0; }

  /// Sensor frame in the world: rotation and origin.
  void frame(const mjData* d, Matrix3& rotation, Vector3& origin) const noexcept {
    const Eigen::Map<const RowMajor3> body_rotation(d->xmat + 9 * at(body));
    const Eigen::Map<const Vector3> body_position(d->xpos + 3 * at(body));
    rotation = body_rotation * local_rotation;
    origin = body_position + body_rotation * local_position;
  }
};

SensorDevices::SensorDevices(const fs::path& scene_file, const CellWorld& world)
    : SensorDevices(read_sensor_configs(scene_file, world), world) {}

SensorDevices::~SensorDevices() = default;

SensorDevices::SensorDevices(std::vector<SensorConfig> configs, const CellWorld& world)
    : timestep_(world.timestep()) {
  const mjModel* m = world.model();
  for (std::size_t g = 0; g < world.grasp_count(); ++g)
    world_grippers_.push_back(world.grasp(g).gripper);
  for (SensorConfig& c : configs) {
    auto dev = std::make_unique<Device>();
    Device& d = *dev;
    const auto fail = [&](const std::string& text) {
      throw ConfigError(c.where, fmt::format("sensor '{}': {}", c.name, text));
    };
    d.period_s = 1.0 / c.rate_hz;
    d.next_due_s = world.time() + d.period_s;
    d.random.seed(c.seed);
    d.sample.device = c.name;
    switch (c.type) {
      case SensorType::strain_gauges:
      case SensorType::range: {
        d.body = c.body == "world" ? 0 : world.body_id(c.body);
        if (d.body < 0) fail(fmt::format("body '{}' is not in the scene ({})", c.body, kBodyHint));
        d.local_rotation = rotation_matrix(c.rotation);
        d.local_position = Vector3(c.position[0], c.position[1], c.position[2]);
        if (c.type == SensorType::range) {
          d.exclude_body = d.body == 0 ? -1 : d.body;
          d.sample.names = {"distance"};
          d.sample.units = {"m"};
          break;
        }
        d.outboard.assign(at(m->nbody), 0);
        for (int b = 1; b < m->nbody; ++b) {
          int a = m->body_parentid[b];
          while (a != d.body && a != 0) a = m->body_parentid[a];
          if (a == d.body) {
            d.outboard[at(b)] = 1;
            if (m->body_mass[b] > 0.0) d.weighed.push_back(b);
          }
        }
        // A gripper is on the tool side of a wrist sensor: a grasp whose gripper is the
        // mounting body itself counts too.
        for (std::size_t k = 0; k < world.grasp_count(); ++k) {
          const int gripper = world.grasp_gripper_body(k);
          if (gripper == d.body || (gripper > 0 && d.outboard[at(gripper)] != 0))
            d.held_grasps.push_back(k);
        }
        const Eigen::Map<const Eigen::Matrix<double, 6, 6, Eigen::RowMajor>> g(
            c.gauge_matrix.data());
        if (!(Eigen::JacobiSVD<Eigen::Matrix<double, 6, 6>>(g).singularValues()(5) > 0.0))
          fail("'gauge_matrix' is singular");
        d.sample.names = {"g0", "g1", "g2", "g3", "g4", "g5"};
        d.sample.units.assign(6, "V");
        break;
      }
      case SensorType::encoder: {
        try {
          d.robot = world.robot_index(c.robot);
        } catch (const Error& e) {
          fail(e.what());
        }
        const CellRobot& robot = world.robot(d.robot);
        if (c.axis >= robot.axis_count())
          fail(fmt::format("robot '{}' has no axis {}", robot.name, c.axis));
        d.positions.assign(robot.axis_count(), 0.0);
        d.axis_name = robot.axis_names[c.axis];
        d.sample.names = {"position"};
        d.sample.units = {robot.linear[c.axis] ? "m" : "rad"};
        break;
      }
      case SensorType::camera: {
        for (const std::string& object : c.objects) {
          const int b = world.body_id(object);
          if (b <= 0) fail(fmt::format("object '{}' is not a body of the scene", object));
          d.object_bodies.push_back(b);
        }
        d.queue.resize(static_cast<std::size_t>(std::ceil(c.latency_s * c.rate_hz)) + 2);
        d.latency_us = std::llround(c.latency_s * 1e6);
        d.sample.names = {"x", "y", "z", "qw", "qx", "qy", "qz"};
        d.sample.units = {"m", "m", "m", "", "", "", ""};
        break;
      }
      case SensorType::grasp: {
        try {
          d.held = world.held_object_index(c.object);
        } catch (const Error& e) {
          fail(e.what());
        }
        d.object_body = world.body_id(c.object);
        d.sample.names = {"internal", "x", "y", "z"};
        d.sample.units = {"N", "m", "m", "m"};
        for (std::size_t g = 0; g < world.grasp_count(); ++g) {
          if (world.grasp(g).object != c.object) continue;
          const std::size_t i = d.grasps.size();
          d.grasps.push_back(g);
          for (const char* value : {"engaged", "fx", "fy", "fz"})
            d.sample.names.push_back(fmt::format("{}{}", value, i));
          d.sample.units.insert(d.sample.units.end(), {"", "N", "N", "N"});
        }
        break;
      }
      case SensorType::engraving: {
        try {
          d.cut = world.cut_index(c.object, c.cutter);
        } catch (const Error& e) {
          fail(e.what());
        }
        c.cutter = world.cut(d.cut).cutter;
        d.sample.names = {"x", "y", "depth", "cutting", "force"};
        d.sample.units = {"m", "m", "m", "", "N"};
        break;
      }
    }
    d.sample.values.assign(d.sample.names.size(), 0.0);
    d.config = std::move(c);
    devices_.push_back(std::move(dev));
  }
  ready_.reserve(devices_.size());
}

const SensorConfig& SensorDevices::config(std::size_t i) const { return devices_.at(i)->config; }

std::size_t SensorDevices::index(const std::string& name) const {
  std::vector<std::string> names;
  for (std::size_t i = 0; i < devices_.size(); ++i) {
    if (devices_[i]->config.name == name) return i;
    names.push_back(devices_[i]->config.name);
  }
  throw Error(fmt::format("no sensor device named '{}' (devices: {})", name,
                          names.empty() ? "none" : fmt::format("{}", fmt::join(names, ", "))));
}

std::string SensorDevices::describe(std::size_t i) const {
  const SensorConfig& c = config(i);
  const std::string channel = channels::raw_sensor(c.name);
  const std::string noise =
      c.noise > 0.0 ? fmt::format(", noise {} {}", c.noise, devices_[i]->sample.units[0]) : "";
  const auto mount = [&] {
    return fmt::format("on {} at [{}] m, rotation [{}] rad", c.body, fmt::join(c.position, ", "),
                       fmt::join(c.rotation, ", "));
  };
  switch (c.type) {
    case SensorType::strain_gauges:
      return fmt::format("sensor '{}': strain gauges (6 bridges, V) {}, {} Hz{} -> {}", c.name,
                         mount(), c.rate_hz, noise, channel);
    case SensorType::range:
      return fmt::format("sensor '{}': range finder {}, beam along +z up to {} m, {} Hz{} -> {}",
                         c.name, mount(), c.max_range, c.rate_hz, noise, channel);
    case SensorType::encoder:
      return fmt::format("sensor '{}': encoder of robot '{}' axis {} '{}' ({}), {} Hz{} -> {}",
                         c.name, c.robot, c.axis, devices_[i]->axis_name,
                         devices_[i]->sample.units[0], c.rate_hz, noise, channel);
    case SensorType::camera:
      return fmt::format(
          "sensor '{}': emulated pose camera for {}, region x {}..{} y {}..{} z "
          "{}..{} m, {} Hz, latency {} ms{} -> {}",
          c.name, fmt::join(c.objects, ", "), c.region[0], c.region[1], c.region[2], c.region[3],
          c.region[4], c.region[5], c.rate_hz, c.latency_s * 1e3, noise, channel);
    case SensorType::grasp: {
      std::vector<std::string> grippers;
      for (const std::size_t g : devices_[i]->grasps) grippers.push_back(world_grippers_[g]);
      return fmt::format(
          "sensor '{}': grip on object '{}' by {} (internal force, N), {} Hz{} -> {}", c.name,
          c.object, fmt::join(grippers, ", "), c.rate_hz, noise, channel);
    }
    case SensorType::engraving:
      return fmt::format(
          "sensor '{}': engraving of board '{}' by '{}' (tip x, y, depth m, cutting, force N), "
          "{} Hz{} -> {}",
          c.name, c.object, c.cutter, c.rate_hz,
          c.noise > 0.0 ? fmt::format(", noise {} N", c.noise) : "", channel);
  }
  return c.name;
}

const vsp::RawSample& SensorDevices::sample(std::size_t i) const noexcept {
  return devices_[i]->sample;
}

std::array<double, 6> SensorDevices::wrench(std::size_t i) const noexcept {
  return i < devices_.size() ? devices_[i]->wrench : std::array<double, 6>{};
}

FramePose SensorDevices::sensor_pose(const CellWorld& world, std::size_t i) const noexcept {
  FramePose pose;
  if (i >= devices_.size()) return pose;
  Matrix3 rotation;
  Vector3 origin;
  devices_[i]->frame(world.data(), rotation, origin);
  const Eigen::Quaterniond q(rotation);
  pose.position = {origin.x(), origin.y(), origin.z()};
  pose.quaternion = {q.w(), q.x(), q.y(), q.z()};
  return pose;
}

namespace {

/// The load on the outboard side of a strain-gauge sensor, in its frame (sensors.hpp).
void measure_wrench(const CellWorld& world, const std::vector<char>& outboard,
                    const std::vector<int>& weighed, const std::vector<std::size_t>& grasps,
                    const Matrix3& rotation, const Vector3& origin,
                    std::array<double, 6>& out) noexcept {
  const mjModel* m = world.model();
  const mjData* d = world.data();
  Vector3 force = Vector3::Zero();
  Vector3 torque = Vector3::Zero();
  for (int c = 0; c < d->ncon; ++c) {
    const mjContact& contact = d->contact[c];
    if (contact.efc_address < 0) continue;  // excluded (in the gap, no degrees of freedom ...)
    const bool out1 = outboard[at(m->geom_bodyid[contact.geom1])] != 0;
    const bool out2 = outboard[at(m->geom_bodyid[contact.geom2])] != 0;
    if (out1 == out2) continue;  // internal to either side
    mjtNum local[6];
    mj_contactForce(m, d, c, local);
    // The contact frame's rows are its axes in the world (normal first, from geom1 to geom2);
    // the force is the one geom1 exerts on geom2.
    const Eigen::Map<const RowMajor3> frame(contact.frame);
    Vector3 f = frame.transpose() * Vector3(local[0], local[1], local[2]);
    Vector3 t = frame.transpose() * Vector3(local[3], local[4], local[5]);
    if (out1) {
      f = -f;
      t = -t;
    }
    const Eigen::Map<const Vector3> point(contact.pos);
    force += f;
    torque += (point - origin).cross(f) + t;
  }
  // A held object pulls on its gripper with the opposite of the force the gripper exerts on it
  // (the weld's translational rows; its torque rows are not counted).
  for (const std::size_t g : grasps) {
    if (!world.grasp_engaged(g)) continue;
    const std::array<double, 3> on_object = world.grasp_force(g);
    const std::array<double, 3> point = world.grasp_point(g);
    const Vector3 f = -Vector3(on_object[0], on_object[1], on_object[2]);
    force += f;
    torque += (Vector3(point[0], point[1], point[2]) - origin).cross(f);
  }
  // A cut pushes on its cutter (and back on its board) at the cutter tip.
  for (std::size_t c = 0; c < world.cut_count(); ++c) {
    const CutReading& cut = world.cut_reading(c);
    if (!cut.cutting) continue;
    const bool cutter_out = outboard[at(world.cut(c).cutter_body)] != 0;
    const bool board_out = outboard[at(world.cut(c).board_body)] != 0;
    if (cutter_out == board_out) continue;
    Vector3 f(cut.world_force[0], cut.world_force[1], cut.world_force[2]);
    if (board_out) f = -f;
    force += f;
    torque += (Vector3(cut.point[0], cut.point[1], cut.point[2]) - origin).cross(f);
  }
  const Eigen::Map<const Vector3> gravity(m->opt.gravity);
  for (const int b : weighed) {
    const Vector3 weight = m->body_mass[b] * gravity;
    const Eigen::Map<const Vector3> centre(d->xipos + 3 * at(b));
    force += weight;
    torque += (centre - origin).cross(weight);
  }
  const Vector3 f = rotation.transpose() * force;
  const Vector3 t = rotation.transpose() * torque;
  out = {f.x(), f.y(), f.z(), t.x(), t.y(), t.z()};
}

}  // namespace

std::span<const std::size_t> SensorDevices::update(CellWorld& world,
                                                   std::int64_t wall_utime) noexcept {
  ready_.clear();
  const mjModel* m = world.model();
  const double now = world.time();
  const double slack = 0.5 * timestep_;
  bool forces_solved = false;
  for (std::size_t i = 0; i < devices_.size(); ++i) {
    Device& dev = *devices_[i];
    const SensorConfig& c = dev.config;
    const bool due = now + slack >= dev.next_due_s;
    if (due) {
      dev.next_due_s += dev.period_s;
      if (dev.next_due_s <= now + slack) dev.next_due_s = now + dev.period_s;  // fell behind
    }
    vsp::RawSample& s = dev.sample;
    if (c.type == SensorType::camera) {
      const mjData* d = world.data();
      if (due) {
        if (dev.count == dev.queue.size()) {  // cannot happen with the queue's size; drop oldest
          dev.head = (dev.head + 1) % dev.queue.size();
          --dev.count;
        }
        Device::Pending& p = dev.queue[(dev.head + dev.count) % dev.queue.size()];
        ++dev.count;
        p.taken_s = now;
        p.sample_no = dev.next_sample_no++;
        p.valid = false;
        p.values = {0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0};
        for (const int b : dev.object_bodies) {
          const double* x = d->xpos + 3 * at(b);
          const auto& r = c.region;
          if (x[0] < r[0] || x[0] > r[1] || x[1] < r[2] || x[1] > r[3] || x[2] < r[4] ||
              x[2] > r[5])
            continue;
          p.valid = true;
          for (std::size_t k = 0; k < 3; ++k) p.values[k] = x[k] + dev.noise();
          for (std::size_t k = 0; k < 4; ++k) p.values[3 + k] = d->xquat[4 * at(b) + k];
          break;
        }
      }
      if (dev.count > 0 && now + slack >= dev.queue[dev.head].taken_s + c.latency_s) {
        const Device::Pending& p = dev.queue[dev.head];
        s.sample_no = p.sample_no;
        s.sample_utime = wall_utime - dev.latency_us;
        s.valid = p.valid;
        std::copy(p.values.begin(), p.values.end(), s.values.begin());
        dev.head = (dev.head + 1) % dev.queue.size();
        --dev.count;
        ready_.push_back(i);
      }
      continue;
    }
    if (!due) continue;
    s.sample_no = dev.next_sample_no++;
    s.sample_utime = wall_utime;
    s.valid = true;
    switch (c.type) {
      case SensorType::strain_gauges: {
        if (!forces_solved) {
          world.solve_constraint_forces();
          forces_solved = true;
        }
        const mjData* d = world.data();
        Matrix3 rotation;
        Vector3 origin;
        dev.frame(d, rotation, origin);
        measure_wrench(world, dev.outboard, dev.weighed, dev.held_grasps, rotation, origin,
                       dev.wrench);
        for (std::size_t r = 0; r < 6; ++r) {
          double v = c.offset[r];
          for (std::size_t k = 0; k < 6; ++k) v += c.gauge_matrix[6 * r + k] * dev.wrench[k];
          s.values[r] = v + dev.noise();
        }
        break;
      }
      case SensorType::range: {
        const mjData* d = world.data();
        Matrix3 rotation;
        Vector3 origin;
        dev.frame(d, rotation, origin);
        const Vector3 beam = rotation.col(2);
        int geom = -1;
        const double distance =
            mj_ray(m, d, origin.data(), beam.data(), nullptr, 1, dev.exclude_body, &geom);
        s.valid = distance >= 0.0 && distance <= c.max_range;
        s.values[0] = s.valid ? std::max(0.0, distance + dev.noise()) : c.max_range;
        break;
      }
      case SensorType::encoder:
        (void)world.actuator_positions(dev.robot, dev.positions);
        s.values[0] = dev.positions[c.axis] + dev.noise();
        break;
      case SensorType::grasp: {
        const mjData* d = world.data();
        s.values[0] = world.internal_force(dev.held) + dev.noise();
        for (std::size_t k = 0; k < 3; ++k) s.values[1 + k] = d->xpos[3 * at(dev.object_body) + k];
        for (std::size_t j = 0; j < dev.grasps.size(); ++j) {
          const std::size_t g = dev.grasps[j];
          const std::array<double, 3> f = world.grasp_force(g);
          s.values[4 + 4 * j] = world.grasp_engaged(g) ? 1.0 : 0.0;
          for (std::size_t k = 0; k < 3; ++k) s.values[5 + 4 * j + k] = f[k] + dev.noise();
        }
        break;
      }
      case SensorType::engraving: {
        const CutReading& cut = world.cut_reading(dev.cut);
        s.values[0] = cut.tip[0];
        s.values[1] = cut.tip[1];
        s.values[2] = cut.depth;
        s.values[3] = cut.cutting ? 1.0 : 0.0;
        s.values[4] = cut.force_norm + (cut.cutting ? dev.noise() : 0.0);
        break;
      }
      case SensorType::camera: break;
    }
    ready_.push_back(i);
  }
  return ready_;
}

// ---- Publishing ----

RawSamplePublisher::RawSamplePublisher(lcm::LCM& lcm, const SensorDevices& devices,
                                       const std::string& sender, comm::Authenticator* auth)
    : lcm_(lcm), auth_(auth) {
  for (std::size_t i = 0; i < devices.size(); ++i) {
    Channel c;
    c.name = channels::raw_sensor(devices.config(i).name);
    c.message = comm::encode(devices.sample(i));
    c.message.header.sender = sender;
    c.message.header.kind = mrroc_lcm::header_t::BROADCAST;
    c.message.header.auth_tag.reserve(sizeof(comm::Authenticator::Tag));
    if (auth_ != nullptr) {
      c.unsigned_bytes.resize(static_cast<std::size_t>(c.message.getEncodedSize()));
      c.mac_input.reserve(comm::Authenticator::mac_input_size(c.name, c.unsigned_bytes.size()));
      c.buffer.resize(c.unsigned_bytes.size() + sizeof(comm::Authenticator::Tag));
    } else {
      c.buffer.resize(static_cast<std::size_t>(c.message.getEncodedSize()));
    }
    channels_.push_back(std::move(c));
  }
}

bool RawSamplePublisher::publish(std::size_t i, const vsp::RawSample& sample,
                                 std::int64_t wall_utime) noexcept {
  if (i >= channels_.size()) return false;
  Channel& c = channels_[i];
  mrroc_lcm::raw_sensor_t& m = c.message;
  if (sample.values.size() != m.values.size()) return false;
  m.header.utime = wall_utime;
  m.header.seq = sample.sample_no;
  m.sample_utime = sample.sample_utime;
  m.sample_no = sample.sample_no;
  m.valid = sample.valid ? 1 : 0;
  std::copy(sample.values.begin(), sample.values.end(), m.values.begin());
  bool ok = true;
  if (auth_ != nullptr) {
    // As comm::sign: the tag covers the channel and the message encoded with an empty tag.
    try {
      m.header.auth_counter = auth_->next_counter();
      m.header.auth_tag.clear();
      m.header.auth_len = 0;
      const int plain = static_cast<int>(c.unsigned_bytes.size());
      ok = m.encode(c.unsigned_bytes.data(), 0, plain) == plain;
      const comm::Authenticator::Tag tag =
          auth_->mac(c.name, c.unsigned_bytes.data(), c.unsigned_bytes.size(), c.mac_input);
      m.header.auth_tag.assign(tag.begin(), tag.end());
      m.header.auth_len = static_cast<std::int16_t>(tag.size());
    } catch (const std::exception&) {
      ok = false;  // OpenSSL failed: nothing unsigned goes out
    }
  }
  const int size = static_cast<int>(c.buffer.size());
  ok = ok && m.encode(c.buffer.data(), 0, size) == size &&
       lcm_.publish(c.name, c.buffer.data(), static_cast<unsigned>(size)) == 0;
  ++(ok ? published_ : failed_);
  return ok;
}

}  // namespace mrroc::emu
