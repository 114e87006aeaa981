/// @file
/// The `[collision]` table (collision_reader.hpp).

#include <fmt/format.h>

#include <cmath>
#include <set>

#include "collision_reader.hpp"

namespace mrroc::config_detail {
namespace {

class CollisionReader {
 public:
  explicit CollisionReader(const std::filesystem::path& file) : file_(file.string()) {}

  [[nodiscard]] SourceLocation where(const toml::node& node) const {
    return SourceLocation{file_, static_cast<int>(node.source().begin.line)};
  }
  [[noreturn]] void fail(const toml::node& node, const std::string& text) const {
    throw ConfigError(where(node), text);
  }

  void only_keys(const toml::table& t, const char* table_name,
                 std::initializer_list<const char*> allowed) const {
    for (const auto& [key, node] : t) {
      bool known = false;
      std::string list;
      for (const char* a : allowed) {
        known = known || key.str() == a;
        list += (list.empty() ? "" : ", ") + std::string(a);
      }
      if (!known)
        fail(node,
             fmt::format("unknown key '{}' in [{}] (allowed: {})", key.str(), table_name, list));
    }
  }

  /// `count` finite numbers at `key` of `t`; `what` describes them for the message.
  [[nodiscard]] std::vector<double> numbers(const toml::table& t, const char* key,
                                            std::size_t count, const char* what) const {
    const toml::node* node = t.get(key);
    if (node == nullptr)
      throw ConfigError(where(t), fmt::format("missing key '{}' ({})", key, what));
    const toml::array* arr = node->as_array();
    if (arr == nullptr || arr->size() != count)
      fail(*node, fmt::format("'{}' must be {}", key, what));
    std::vector<double> out;
    for (const auto& n : *arr) {
      double v = 0;
      if (n.is_floating_point())
        v = **n.as_floating_point();
      else if (n.is_integer())
        v = static_cast<double>(**n.as_integer());
      else
        fail(n, fmt::format("'{}' must contain only numbers ({})", key, what));
      if (!std::isfinite(v)) fail(n, fmt::format("'{}' value {} is not a finite number", key, v));
      out.push_back(v);
    }
    return out;
  }

  [[nodiscard]] CollisionObject object(const toml::table& t, std::set<std::string>& names) const {
    only_keys(t, "collision.object", {"name", "type", "size", "pos", "rotation"});
    CollisionObject o;
    o.where = where(t);
    const toml::node* name = t.get("name");
    if (name == nullptr || !name->is_string())
      throw ConfigError(where(name != nullptr ? *name : static_cast<const toml::node&>(t)),
                        "[[collision.object]] needs a 'name' (a string)");
    o.name = **name->as_string();
    if (o.name.empty() || o.name.find('/') != std::string::npos)
      fail(*name, fmt::format("object name '{}' must be non-empty and without '/' (a '/' names "
                              "a robot's link)",
                              o.name));
    if (!names.insert(o.name).second)
      fail(*name, fmt::format("object name '{}' is used twice", o.name));
    if (const toml::node* type = t.get("type");
        type != nullptr && (!type->is_string() || **type->as_string() != "box"))
      fail(*type,
           fmt::format("object '{}': 'type' must be \"box\" (the only shape so far)", o.name));
    const std::vector<double> size = numbers(t, "size", 3, "[x, y, z] half-sizes in m");
    for (std::size_t i = 0; i < 3; ++i) {
      if (!(size[i] > 0.0 && size[i] <= 100.0))
        fail(*t.get("size"), fmt::format("object '{}': half-size {} = {} m is outside (0, 100] m",
                                         o.name, "xyz"[i], size[i]));
      o.half_size[i] = size[i];
    }
    const std::vector<double> pos = numbers(t, "pos", 3, "[x, y, z] of the centre in m");
    for (std::size_t i = 0; i < 3; ++i) o.pose[i] = pos[i];
    if (t.get("rotation") != nullptr) {
      const std::vector<double> r =
          numbers(t, "rotation", 3, "a rotation vector [rx, ry, rz] in rad");
      for (std::size_t i = 0; i < 3; ++i) o.pose[3 + i] = r[i];
    }
    return o;
  }

  /// One side of an allowed pair: a fixed object's name or "<robot>/<link>" of a set's robot.
  void check_side(const toml::node& node, const std::string& side,
                  const std::set<std::string>& objects,
                  const std::vector<std::string>& robots) const {
    const auto slash = side.find('/');
    if (slash == std::string::npos) {
      if (objects.count(side) == 0) {
        std::string list;
        for (const std::string& o : objects) list += (list.empty() ? "" : ", ") + o;
        fail(node, fmt::format("allowed contact names '{}', which is no [[collision.object]] "
                               "({}); a robot's link is named \"<robot>/<link>\"",
                               side, list.empty() ? "there are none" : "they are " + list));
      }
      return;
    }
    const std::string robot = side.substr(0, slash);
    bool known = false;
    std::string list;
    for (const std::string& r : robots) {
      known = known || r == robot;
      list += (list.empty() ? "" : ", ") + r;
    }
    if (!known)
      fail(node, fmt::format("allowed contact '{}' names robot '{}', which is no [[robot]] of "
                             "the set (they are {})",
                             side, robot, list));
    if (slash + 1 >= side.size())
      fail(node, fmt::format("allowed contact '{}' names no link after '{}/'", side, robot));
  }

 private:
  std::string file_;
};

}  // namespace

CollisionConfig read_collision(const toml::node* node, const std::filesystem::path& file,
                               const std::vector<std::string>& robots) {
  CollisionConfig c;
  c.where = SourceLocation::whole_file(file.string());
  c.enabled_where = c.where;
  if (node == nullptr) return c;
  const CollisionReader r(file);
  if (!node->is_table()) r.fail(*node, "'collision' must be a table ([collision])");
  const toml::table& t = *node->as_table();
  c.where = r.where(t);
  c.enabled_where = c.where;
  c.enabled = true;  // a [collision] section turns the guard on
  r.only_keys(t, "collision", {"enabled", "clearance", "allow", "object"});
  if (const toml::node* enabled = t.get("enabled")) {
    if (!enabled->is_boolean()) r.fail(*enabled, "'enabled' must be true or false");
    c.enabled = **enabled->as_boolean();
    c.enabled_where = r.where(*enabled);
  }
  if (const toml::node* clearance = t.get("clearance")) {
    double v = 0;
    if (clearance->is_floating_point())
      v = **clearance->as_floating_point();
    else if (clearance->is_integer())
      v = static_cast<double>(**clearance->as_integer());
    else
      r.fail(*clearance, "'clearance' must be a number [m]");
    if (!(v > 0.0 && v <= kMaxCollisionClearance))
      r.fail(*clearance,
             fmt::format("'clearance' = {} m is outside (0, {}] m", v, kMaxCollisionClearance));
    c.clearance_m = v;
  }
  std::set<std::string> names;
  if (const toml::node* objects = t.get("object")) {
    const toml::array* list = objects->as_array();
    if (list == nullptr || !list->is_array_of_tables())
      r.fail(*objects, "'object' must be an array of tables ([[collision.object]])");
    for (const auto& entry : *list) c.objects.push_back(r.object(*entry.as_table(), names));
  }
  if (const toml::node* allow = t.get("allow")) {
    const toml::array* list = allow->as_array();
    if (list == nullptr)
      r.fail(*allow, "'allow' must be a list of pairs, e.g. [[\"left/roll_link\", \"bar\"]]");
    for (const auto& entry : *list) {
      const toml::array* pair = entry.as_array();
      if (pair == nullptr || pair->size() != 2 || !pair->is_homogeneous(toml::node_type::string))
        r.fail(entry,
               "each entry of 'allow' must be a pair of names, e.g. [\"left/roll_link\", "
               "\"bar\"]");
      AllowedContact a{**(*pair)[0].as_string(), **(*pair)[1].as_string(), r.where(entry)};
      r.check_side(entry, a.first, names, robots);
      r.check_side(entry, a.second, names, robots);
      if (a.first == a.second)
        r.fail(entry, fmt::format("allowed contact names '{}' twice", a.first));
      c.allowed.push_back(std::move(a));
    }
  }
  return c;
}

}  // namespace mrroc::config_detail
