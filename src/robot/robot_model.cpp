#include "mrroc/robot/robot_model.hpp"

#include <fmt/format.h>

#include <fmt/ranges.h>

#include <toml++/toml.h>
#include <urdf_parser/urdf_parser.h>
#include <algorithm>
#include <array>
#include <cmath>

#include "mrroc/core/error.hpp"
#include "mrroc/msg/edp_instruction.hpp"

namespace mrroc {

namespace fs = std::filesystem;

LimitViolation RobotModel::joint_limit_violation(std::span<const double> q) const noexcept {
  if (q.size() != axes())
    return {LimitKind::invalid, 0, static_cast<double>(q.size()), static_cast<double>(axes())};
  for (std::size_t i = 0; i < q.size(); ++i) {
    if (!std::isfinite(q[i])) return {LimitKind::invalid, i, q[i], 0.0};
    if (q[i] > upper_limits[i]) return {LimitKind::joint, i, q[i], upper_limits[i]};
    if (q[i] < lower_limits[i]) return {LimitKind::joint, i, q[i], lower_limits[i]};
  }
  return {};
}

void RobotModel::check_joint_limits(std::span<const double> q, const char* what) const {
  const LimitViolation v = joint_limit_violation(q);
  if (!v) return;
  const std::size_t i = v.axis;
  if (v.kind == LimitKind::invalid && q.size() != axes())
    throw CommandError(edp::error_code::bad_argument,
                       fmt::format("{} has {} joint values, robot '{}' has {} axes", what, q.size(),
                                   name, axes()));
  if (v.kind == LimitKind::invalid)
    throw CommandError(
        edp::error_code::bad_argument,
        fmt::format("joint {} ({}) {} {} is not a finite number", i, joint_names[i], what, q[i]));
  if (v.above())
    throw CommandError(edp::error_code::out_of_limits,
                       fmt::format("joint {} ({}) {} {:.6f} {} exceeds upper limit {:.6f} {}", i,
                                   joint_names[i], what, q[i], unit(i), v.limit, unit(i)));
  throw CommandError(edp::error_code::out_of_limits,
                     fmt::format("joint {} ({}) {} {:.6f} {} is below lower limit {:.6f} {}", i,
                                 joint_names[i], what, q[i], unit(i), v.limit, unit(i)));
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

int line_of(const toml::node& node) {
  return std::max(1, static_cast<int>(node.source().begin.line));
}

SourceLocation at(const fs::path& file, const toml::node& node) {
  return SourceLocation{file.string(), line_of(node)};
}

/// What a TOML value is, for error texts: "a string", "a list", ...
const char* kind(const toml::node& node) {
  if (node.is_string()) return "a string";
  if (node.is_boolean()) return "a boolean";
  if (node.is_array()) return "a list";
  if (node.is_table()) return "a table";
  if (node.is_number()) return "a number";
  return "a date or time";
}

constexpr std::array<const char*, 10> kRobotKeys = {"name",
                                                    "axes",
                                                    "joint_names",
                                                    "urdf",
                                                    "mjcf",
                                                    "synchro_joint_positions",
                                                    "max_joint_velocity",
                                                    "max_joint_acceleration",
                                                    "kinematics",
                                                    "transmission"};
constexpr std::array<const char*, 3> kKinematicsKeys = {"solver", "models", "correctors"};
constexpr std::array<const char*, 1> kTransmissionKeys = {"coupling"};
constexpr std::array<const char*, 4> kIrb6Lengths = {"d1", "a2", "a3", "d5"};

/// Refuses a key of `table` that is not in `known`; `name` is the table's name ("robot").
void check_known(const toml::table& table, const std::string& name,
                 const std::vector<std::string>& known, const fs::path& file,
                 const std::string& note = {}) {
  for (const auto& [key, node] : table) {
    if (std::find(known.begin(), known.end(), key.str()) != known.end()) continue;
    const std::string where = name.empty() ? "at the top level" : fmt::format("in [{}]", name);
    throw ConfigError(at(file, node), fmt::format("unknown key '{}' {} (known: {}){}", key.str(),
                                                  where, fmt::join(known, ", "), note));
  }
}

std::string solver_of(const toml::table& kinematics, const fs::path& file) {
  const toml::node* node = kinematics.get("solver");
  if (node == nullptr) return {};
  if (!node->is_string())
    throw ConfigError(at(file, *node),
                      fmt::format("robot.kinematics.solver must be a string such as \"irb6\", "
                                  "not {}",
                                  kind(*node)));
  return **node->as_string();
}

void check_keys(const toml::table& root, const fs::path& file) {
  check_known(root, "", {"robot"}, file);
  const toml::table* robot = root["robot"].as_table();
  if (robot == nullptr) return;
  check_known(*robot, "robot", {kRobotKeys.begin(), kRobotKeys.end()}, file);
  if (const toml::node* node = robot->get("kinematics")) {
    const toml::table* kin = node->as_table();
    if (kin == nullptr)
      throw ConfigError(at(file, *node),
                        fmt::format("robot.kinematics must be a table, not {}", kind(*node)));
    const std::string solver = solver_of(*kin, file);
    const auto lengths = solver_link_lengths(solver);
    std::vector<std::string> known(kKinematicsKeys.begin(), kKinematicsKeys.end());
    std::string note;
    if (lengths.empty()) {
      note = fmt::format(
          "; link lengths are read only by solver \"irb6\", solver \"{}\" takes none from "
          "this file",
          solver.empty() ? "urdf" : solver);
    } else {
      known.insert(known.end(), lengths.begin(), lengths.end());
      known.emplace_back("calibrated");
    }
    check_known(*kin, "robot.kinematics", known, file, note);
    // Keys the named solver would not read.
    if (const toml::node* models = kin->get("models"); models != nullptr && !lengths.empty())
      throw ConfigError(at(file, *models),
                        fmt::format("'models' is not read by solver \"{}\": its kinematic models "
                                    "are the link lengths under [robot.kinematics] (model 0) and "
                                    "[robot.kinematics.calibrated] (model 1)",
                                    solver));
    if (solver == "joint-only") {
      for (const char* key : {"models", "correctors"})
        if (const toml::node* n = kin->get(key))
          throw ConfigError(at(file, *n),
                            fmt::format("'{}' is not read by solver \"joint-only\" (no Cartesian "
                                        "kinematics: kinematic model 0 and corrector 0 only)",
                                        key));
    }
    if (const toml::node* cal = kin->get("calibrated")) {
      if (!cal->is_table())
        throw ConfigError(at(file, *cal),
                          fmt::format("robot.kinematics.calibrated must be a table of link "
                                      "lengths [m] ({}), not {}",
                                      fmt::join(lengths, ", "), kind(*cal)));
      check_known(*cal->as_table(), "robot.kinematics.calibrated", {lengths.begin(), lengths.end()},
                  file);
    }
  }
  if (const toml::node* node = robot->get("transmission")) {
    const toml::table* transmission = node->as_table();
    if (transmission == nullptr)
      throw ConfigError(at(file, *node),
                        fmt::format("robot.transmission must be a table, not {}", kind(*node)));
    check_known(*transmission, "robot.transmission",
                {kTransmissionKeys.begin(), kTransmissionKeys.end()}, file);
  }
}

std::string text(double x) { return fmt::format("{}", x); }

/// A link length [m]: a finite number in (0, kMaxLinkLength].
double link_length(const toml::node& node, const std::string& key, const fs::path& file) {
  if (!node.is_number())
    throw ConfigError(at(file, node),
                      fmt::format("{} must be a number [m], not {}", key, kind(node)));
  const double v = *node.value<double>();
  if (!std::isfinite(v))
    throw ConfigError(at(file, node),
                      fmt::format("{} = {} m is not a finite number", key, text(v)));
  if (!(v > 0.0))
    throw ConfigError(at(file, node),
                      fmt::format("{} = {} m must be more than 0 m (a link length)", key, text(v)));
  if (v > kMaxLinkLength)
    throw ConfigError(at(file, node),
                      fmt::format("{} = {} m exceeds the plausible limit {} m of a link length",
                                  key, text(v), text(kMaxLinkLength)));
  return v;
}

/// The link lengths of solver `solver` ([robot.kinematics] and [robot.kinematics.calibrated]).
std::vector<std::vector<double>> link_lengths(const toml::table& kin, const std::string& solver,
                                              const fs::path& file) {
  const auto names = solver_link_lengths(solver);
  std::vector<std::vector<double>> models;
  if (names.empty()) return models;
  std::vector<double> nominal;
  std::vector<int> nominal_line;
  for (const char* name : names) {
    const toml::node* node = kin.get(name);
    if (node == nullptr)
      throw ConfigError(at(file, kin),
                        fmt::format("missing key '{}' in [robot.kinematics]: solver \"{}\" takes "
                                    "its link lengths {} [m] from there",
                                    name, solver, fmt::join(names, ", ")));
    nominal.push_back(link_length(*node, fmt::format("robot.kinematics.{}", name), file));
    nominal_line.push_back(line_of(*node));
  }
  models.push_back(nominal);
  if (const toml::table* cal = kin.get_as<toml::table>("calibrated")) {
    std::vector<double> values = nominal;
    for (std::size_t i = 0; i < names.size(); ++i) {
      const toml::node* node = cal->get(names[i]);
      if (node == nullptr) continue;
      const std::string key = fmt::format("robot.kinematics.calibrated.{}", names[i]);
      const double v = link_length(*node, key, file);
      const double limit = kMaxCalibrationChange * nominal[i];
      if (!(std::abs(v - nominal[i]) <= limit))
        throw ConfigError(
            at(file, *node),
            fmt::format("{} = {} m differs from the nominal {} m (line {}) by {:.6g} m, more than "
                        "the plausible {:.6g} m ({} % of the nominal: a calibration corrects small "
                        "errors of a unit)",
                        key, text(v), text(nominal[i]), nominal_line[i], std::abs(v - nominal[i]),
                        limit, text(100.0 * kMaxCalibrationChange)));
      values[i] = v;
    }
    models.push_back(values);
  }
  return models;
}

toml::table parse(const fs::path& file) {
  if (std::string why; !exists(file, why))
    throw ConfigError(SourceLocation::whole_file(file.string()),
                      fmt::format("robot parameters file not found{}", why));
  try {
    return toml::parse_file(file.string());
  } catch (const toml::parse_error& e) {
    throw ConfigError(SourceLocation{file.string(), static_cast<int>(e.source().begin.line)},
                      std::string(e.description()));
  }
}

/// [robot] `key`: a string, or nullopt when absent.
const std::string* string_of(const toml::table& robot, const char* key, const fs::path& file) {
  const toml::node* node = robot.get(key);
  if (node == nullptr) return nullptr;
  if (!node->is_string())
    throw ConfigError(at(file, *node),
                      fmt::format("robot.{} must be a string, not {}", key, kind(*node)));
  return &node->as_string()->get();
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

std::span<const char* const> solver_link_lengths(std::string_view solver) {
  if (solver == "irb6") return kIrb6Lengths;
  return {};
}

void check_robot_parameter_keys(const fs::path& file) { check_keys(parse(file), file); }

RobotModel load_robot_model(const fs::path& folder) {
  const fs::path file = folder / kRobotParametersFile;
  const toml::table root = parse(file);
  check_keys(root, file);
  const toml::table* robot = root["robot"].as_table();
  if (robot == nullptr)
    throw ConfigError(SourceLocation{file.string(), 1}, "missing table [robot]");
  RobotModel m;
  m.folder = folder;
  if (const std::string* name = string_of(*robot, "name", file)) m.name = *name;
  const toml::array* names = robot->get_as<toml::array>("joint_names");
  if (names == nullptr)
    throw ConfigError(SourceLocation{file.string(), static_cast<int>(robot->source().begin.line)},
                      "missing 'joint_names' in [robot]");
  for (const auto& n : *names) m.joint_names.push_back(n.value_or(std::string{}));
  const std::size_t axes = m.joint_names.size();
  if (const toml::node* node = robot->get("axes")) {
    const auto count = node->value<std::int64_t>();
    if (!node->is_integer() || !count)
      throw ConfigError(at(file, *node),
                        fmt::format("robot.axes must be an integer (the number of joint_names, "
                                    "{}), not {}",
                                    axes, kind(*node)));
    if (*count != static_cast<std::int64_t>(axes))
      throw ConfigError(at(file, *node), fmt::format("robot.axes = {} but joint_names lists {} "
                                                     "axes",
                                                     *count, axes));
  }
  const std::string* urdf_name = string_of(*robot, "urdf", file);
  const std::string* mjcf_name = string_of(*robot, "mjcf", file);
  if (urdf_name == nullptr)
    throw ConfigError(SourceLocation{file.string(), static_cast<int>(robot->source().begin.line)},
                      "missing 'urdf' in [robot]");
  m.urdf = folder / *urdf_name;
  if (mjcf_name != nullptr) m.mjcf = folder / *mjcf_name;
  m.max_velocity = numbers(*robot, "max_joint_velocity", file, axes);
  m.max_acceleration = numbers(*robot, "max_joint_acceleration", file, axes);
  m.synchro_joint_positions = numbers(*robot, "synchro_joint_positions", file, axes);

  if (const toml::table* kin = robot->get_as<toml::table>("kinematics")) {
    m.kinematics = solver_of(*kin, file);
    m.link_lengths = link_lengths(*kin, m.kinematics, file);
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
