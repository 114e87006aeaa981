#include "mrroc/robot/robot_model.hpp"

#include <fmt/format.h>

#include <toml++/toml.h>
#include <urdf_parser/urdf_parser.h>
#include <cmath>

#include "mrroc/core/error.hpp"
#include "mrroc/msg/edp_instruction.hpp"

namespace mrroc {

namespace fs = std::filesystem;

void RobotModel::check_joint_limits(const std::vector<double>& q, const char* what) const {
  if (q.size() != axes())
    throw CommandError(edp::error_code::bad_argument,
                       fmt::format("{} has {} joint values, robot '{}' has {} axes", what, q.size(),
                                   name, axes()));
  for (std::size_t i = 0; i < q.size(); ++i) {
    if (!std::isfinite(q[i]))
      throw CommandError(
          edp::error_code::bad_argument,
          fmt::format("joint {} ({}) {} {} is not a finite number", i, joint_names[i], what, q[i]));
    if (q[i] > upper_limits[i])
      throw CommandError(edp::error_code::out_of_limits,
                         fmt::format("joint {} ({}) {} {:.6f} rad exceeds upper limit {:.6f} rad",
                                     i, joint_names[i], what, q[i], upper_limits[i]));
    if (q[i] < lower_limits[i])
      throw CommandError(edp::error_code::out_of_limits,
                         fmt::format("joint {} ({}) {} {:.6f} rad is below lower limit {:.6f} rad",
                                     i, joint_names[i], what, q[i], lower_limits[i]));
  }
}

namespace {

/// fs::exists without exceptions: a path the system cannot even look up (name too long, no
/// permission) counts as missing; `why` receives the system's reason.
bool exists(const fs::path& path, std::string& why) {
  std::error_code ec;
  const bool found = fs::exists(path, ec);
  why = ec ? fmt::format(" ({})", ec.message()) : std::string{};
  return found;
}

std::vector<double> numbers(const toml::table& t, const char* key, const fs::path& file,
                            std::size_t n) {
  const toml::node* node = t.get(key);
  if (node == nullptr)
    throw ConfigError(SourceLocation{file.string(), static_cast<int>(t.source().begin.line)},
                      fmt::format("missing key '{}' in [robot]", key));
  const toml::array* arr = node->as_array();
  if (arr == nullptr || arr->size() != n)
    throw ConfigError(SourceLocation{file.string(), static_cast<int>(node->source().begin.line)},
                      fmt::format("'{}' must be a list of {} numbers", key, n));
  std::vector<double> out;
  for (const auto& v : *arr) {
    auto d = v.value<double>();
    if (!d)
      throw ConfigError(SourceLocation{file.string(), static_cast<int>(v.source().begin.line)},
                        fmt::format("'{}' must contain only numbers", key));
    out.push_back(*d);
  }
  return out;
}

}  // namespace

RobotModel load_robot_model(const fs::path& folder) {
  const fs::path file = folder / kRobotParametersFile;
  if (std::string why; !exists(file, why))
    throw ConfigError(SourceLocation::whole_file(file.string()),
                      fmt::format("robot parameters file not found{}", why));
  toml::table root;
  try {
    root = toml::parse_file(file.string());
  } catch (const toml::parse_error& e) {
    throw ConfigError(SourceLocation{file.string(), static_cast<int>(e.source().begin.line)},
                      std::string(e.description()));
  }
  const toml::table* robot = root["robot"].as_table();
  if (robot == nullptr)
    throw ConfigError(SourceLocation{file.string(), 1}, "missing table [robot]");
  RobotModel m;
  m.folder = folder;
  m.name = robot->get_as<std::string>("name") ? **robot->get_as<std::string>("name") : "";
  const toml::array* names = robot->get_as<toml::array>("joint_names");
  if (names == nullptr)
    throw ConfigError(SourceLocation{file.string(), static_cast<int>(robot->source().begin.line)},
                      "missing 'joint_names' in [robot]");
  for (const auto& n : *names) m.joint_names.push_back(n.value_or(std::string{}));
  const std::size_t axes = m.joint_names.size();
  const auto urdf_name = robot->get_as<std::string>("urdf");
  const auto mjcf_name = robot->get_as<std::string>("mjcf");
  if (urdf_name == nullptr)
    throw ConfigError(SourceLocation{file.string(), static_cast<int>(robot->source().begin.line)},
                      "missing 'urdf' in [robot]");
  m.urdf = folder / std::string(**urdf_name);
  if (mjcf_name != nullptr) m.mjcf = folder / std::string(**mjcf_name);
  m.max_velocity = numbers(*robot, "max_joint_velocity", file, axes);
  m.max_acceleration = numbers(*robot, "max_joint_acceleration", file, axes);
  m.synchro_joint_positions = numbers(*robot, "synchro_joint_positions", file, axes);

  if (const toml::table* kin = robot->get_as<toml::table>("kinematics")) {
    if (const auto* solver = kin->get_as<std::string>("solver")) m.kinematics = **solver;
    if (const toml::array* models = kin->get_as<toml::array>("models")) {
      for (const auto& entry : *models) {
        const auto name = entry.value<std::string>();
        if (!name)
          throw ConfigError(
              SourceLocation{file.string(), static_cast<int>(entry.source().begin.line)},
              "'models' must be a list of URDF file names");
        const fs::path path = folder / *name;
        if (std::string why; !exists(path, why))
          throw ConfigError(
              SourceLocation{file.string(), static_cast<int>(entry.source().begin.line)},
              fmt::format("kinematic model file '{}' not found{}", path.string(), why));
        m.kinematic_models.push_back(path);
      }
    }
    if (const toml::array* list = kin->get_as<toml::array>("correctors")) {
      for (const auto& row : *list) {
        const toml::array* values = row.as_array();
        std::array<double, 6> c{};
        if (values == nullptr || values->size() != 6)
          throw ConfigError(
              SourceLocation{file.string(), static_cast<int>(row.source().begin.line)},
              "each corrector must be [x, y, z, rx, ry, rz] (m, rad)");
        for (std::size_t i = 0; i < 6; ++i) {
          const auto v = (*values)[i].value<double>();
          if (!v)
            throw ConfigError(
                SourceLocation{file.string(), static_cast<int>(row.source().begin.line)},
                "corrector values must be numbers");
          c[i] = *v;
        }
        m.correctors.push_back(c);
      }
    }
  }
  if (const toml::table* transmission = robot->get_as<toml::table>("transmission")) {
    if (const toml::node* node = transmission->get("coupling")) {
      const toml::array* rows = node->as_array();
      const auto shape = [&](const toml::node& where) {
        return ConfigError(
            SourceLocation{file.string(), static_cast<int>(where.source().begin.line)},
            fmt::format("robot.transmission.coupling must be a {} x {} matrix of numbers", axes,
                        axes));
      };
      if (rows == nullptr || rows->size() != axes) throw shape(*node);
      for (const auto& row_node : *rows) {
        const toml::array* row = row_node.as_array();
        if (row == nullptr || row->size() != axes) throw shape(row_node);
        std::vector<double> values;
        for (const auto& v : *row) {
          const auto d = v.value<double>();
          if (!d || !std::isfinite(*d)) throw shape(v);
          values.push_back(*d);
        }
        m.coupling.push_back(std::move(values));
      }
    }
  }
  if (std::string why; !exists(m.urdf, why))
    throw ConfigError(SourceLocation::whole_file(m.urdf.string()),
                      fmt::format("URDF file not found{}", why));
  urdf::ModelInterfaceSharedPtr urdf = urdf::parseURDFFile(m.urdf.string());
  if (!urdf)
    throw ConfigError(SourceLocation::whole_file(m.urdf.string()), "the URDF does not parse");
  for (const auto& jn : m.joint_names) {
    auto joint = urdf->getJoint(jn);
    if (!joint || !joint->limits)
      throw ConfigError(
          SourceLocation::whole_file(m.urdf.string()),
          fmt::format("joint '{}' (from {}) missing or without <limit>", jn, file.string()));
    m.lower_limits.push_back(joint->limits->lower);
    m.upper_limits.push_back(joint->limits->upper);
    m.prismatic.push_back(joint->type == urdf::Joint::PRISMATIC);
  }
  return m;
}

}  // namespace mrroc
