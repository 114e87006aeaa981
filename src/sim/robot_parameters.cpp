#include "mrroc/sim/robot_parameters.hpp"

#include <cmath>

#include <toml++/toml.h>

#include "mrroc/core/error.hpp"
#include "mrroc/robot/robot_model.hpp"

namespace mrroc::sim {
namespace {

SourceLocation where(const toml::source_region& region, const std::filesystem::path& file) {
  return SourceLocation{file.string(), static_cast<int>(region.begin.line)};
}

/// A list of values of type T under `node`. `what` is the error text when `node` is not a list,
/// `element_what` when an element is not a T.
template <typename T>
std::vector<T> list_of(const toml::node& node, const std::filesystem::path& path,
                       const std::string& what, const std::string& element_what) {
  const toml::array* array = node.as_array();
  if (array == nullptr) throw ConfigError(where(node.source(), path), what);
  std::vector<T> values;
  for (const toml::node& element : *array) {
    const auto value = element.value<T>();
    if (!value) throw ConfigError(where(element.source(), path), element_what);
    values.push_back(*value);
  }
  return values;
}

}  // namespace

RobotParameters read_robot_parameters(const std::filesystem::path& path) {
  RobotParameters out;
  out.path = path;
  toml::table table;
  try {
    table = toml::parse_file(path.string());
  } catch (const toml::parse_error& e) {
    throw ConfigError(where(e.source(), path), std::string(e.description()));
  }
  check_robot_parameter_keys(path);  // an unknown key is an error for every reader
  const toml::node_view robot = table["robot"];
  if (const toml::node* node = robot["mjcf"].node()) {
    const auto value = node->value<std::string>();
    if (!value) {
      throw ConfigError(where(node->source(), path), "robot.mjcf must be a string");
    }
    out.mjcf = *value;
  }
  if (const toml::node* node = robot["synchro_joint_positions"].node()) {
    const std::string what = "robot.synchro_joint_positions must be a list of numbers [rad]";
    out.synchro = list_of<double>(*node, path, what, what);
  }
  if (const toml::node* node = robot["joint_names"].node()) {
    const std::string what = "robot.joint_names must be a list of strings";
    out.joint_names = list_of<std::string>(*node, path, what, what);
  }
  if (const toml::node* node = robot["transmission"]["coupling"].node()) {
    out.coupling_where = where(node->source(), path);
    const std::string shape =
        "robot.transmission.coupling must be a list of rows, each a list of numbers";
    const std::string finite = "robot.transmission.coupling must contain only finite numbers";
    const toml::array* rows = node->as_array();
    if (rows == nullptr) throw ConfigError(out.coupling_where, shape);
    std::vector<std::vector<double>> matrix;
    for (const toml::node& row : *rows) {
      std::vector<double> values = list_of<double>(row, path, shape, finite);
      for (std::size_t c = 0; c < values.size(); ++c) {
        if (!std::isfinite(values[c]))
          throw ConfigError(where((*row.as_array())[c].source(), path), finite);
      }
      matrix.push_back(std::move(values));
    }
    out.coupling = std::move(matrix);
  }
  return out;
}

}  // namespace mrroc::sim
