#pragma once
/// @file
/// Plain key/value parameters handed from a config file to plugins and tasks.
///
/// Plugins and tasks never see the config file's syntax: they read typed values from a `Params`
/// and every error names the config file and line where the value was (or should have been)
/// written.

#include <cstdint>
#include <map>
#include <set>
#include <string>
#include <variant>
#include <vector>

#include "mrroc/core/error.hpp"

namespace mrroc {

class ConfigErrorList;

/// One parameter value. Lists of numbers and lists of lists of numbers cover poses and pose lists.
using ParamValue = std::variant<bool, std::int64_t, double, std::string, std::vector<double>,
                                std::vector<std::vector<double>>, std::vector<std::string>>;

/// A table of typed parameters with the location of each.
///
/// Every getter throws `ConfigError` with "file:line: error: ..." when the key is missing (for the
/// required getters) or has the wrong type. Keys that were never read can be listed with
/// `unread_keys()` so that callers can reject unknown keys.
class Params {
 public:
  Params() = default;
  explicit Params(SourceLocation table_location) : location_(std::move(table_location)) {}

  void set(const std::string& key, ParamValue value, SourceLocation where);

  [[nodiscard]] bool has(const std::string& key) const;
  [[nodiscard]] const SourceLocation& location() const { return location_; }
  [[nodiscard]] SourceLocation location_of(const std::string& key) const;
  /// Where row `row` of a list of lists was written (its own line when the reader recorded it,
  /// else the key's).
  [[nodiscard]] SourceLocation location_of_row(const std::string& key, std::size_t row) const;
  /// Records where each row of the list of lists `key` was written (see `location_of_row`).
  void set_row_locations(const std::string& key, std::vector<SourceLocation> rows);

  /// Required values. @throws ConfigError when missing or of another type.
  [[nodiscard]] double get_double(const std::string& key) const;
  [[nodiscard]] std::int64_t get_int(const std::string& key) const;
  [[nodiscard]] bool get_bool(const std::string& key) const;
  [[nodiscard]] std::string get_string(const std::string& key) const;
  [[nodiscard]] std::vector<double> get_doubles(const std::string& key) const;
  [[nodiscard]] std::vector<std::vector<double>> get_double_rows(const std::string& key) const;
  [[nodiscard]] std::vector<std::string> get_strings(const std::string& key) const;

  /// Optional values with a default. @throws ConfigError when present with another type; while
  /// a check collects them (`collect_errors`), the error goes to its list instead (once per key)
  /// and the default is returned, so that the check goes on with the other arguments.
  [[nodiscard]] double get_double(const std::string& key, double fallback) const;
  [[nodiscard]] std::int64_t get_int(const std::string& key, std::int64_t fallback) const;
  [[nodiscard]] bool get_bool(const std::string& key, bool fallback) const;
  [[nodiscard]] std::string get_string(const std::string& key, const std::string& fallback) const;
  [[nodiscard]] std::vector<double> get_doubles(const std::string& key,
                                                const std::vector<double>& fallback) const;

  /// Keys present in the table but never read by any getter.
  [[nodiscard]] std::vector<std::string> unread_keys() const;
  /// @throws ConfigError naming the first unread key ("unknown key 'x' in [robot.edp.params]").
  /// With a sink (`collect_unknown_keys`, `collect_errors`) it adds every unread key to it and
  /// returns.
  void reject_unread(const std::string& table_name) const;

  /// Makes `reject_unread` add every unknown key to `sink` instead of throwing at the first, so
  /// that a check reports them all and goes on with the other checks (null: throw, the
  /// default). A copy of the table does not collect: the sink belongs to the check that set it,
  /// and a copy kept beyond it (by a plugin, say) throws as usual.
  void collect_unknown_keys(ConfigErrorList* sink) const {
    sink_.list = sink;
    sink_.type_errors = false;
    sink_.reported.clear();
  }
  /// As `collect_unknown_keys`, and the optional getters add a value of another type to `sink`
  /// and return their default, so that the check goes on with the other arguments. For code that
  /// only checks (a task's constructor, a plugin's check(), a simulation's configure()), never
  /// for code that opens devices: that would go on with a default the user did not choose. The
  /// required getters throw as always (there is no value to go on with): a task that reads its
  /// arguments one by one in `ConfigErrorList::run` gets the others checked too.
  void collect_errors(ConfigErrorList* sink) const {
    collect_unknown_keys(sink);
    sink_.type_errors = sink != nullptr;
  }

  [[nodiscard]] const std::map<std::string, ParamValue>& values() const { return values_; }

 private:
  struct Entry {
    ParamValue value;
    SourceLocation where;
  };
  const Entry* find(const std::string& key) const;
  [[noreturn]] void type_error(const std::string& key, const char* expected) const;
  [[noreturn]] void missing(const std::string& key) const;
  /// True when a check collects: `error` (of `key`) is added to its list, the first time only.
  bool collected(const ConfigError& error, const std::string& key) const;

  SourceLocation location_;
  std::map<std::string, ParamValue> values_;
  std::map<std::string, SourceLocation> where_;
  std::map<std::string, std::vector<SourceLocation>> row_where_;
  mutable std::map<std::string, bool> read_;
  /// The sink of `collect_unknown_keys` or `collect_errors` (`type_errors`) and the keys of
  /// another type it has; a copy is empty.
  struct Sink {
    ConfigErrorList* list = nullptr;
    bool type_errors = false;
    std::set<std::string> reported;
    Sink() = default;
    Sink(const Sink& /*other*/) noexcept {}
    Sink& operator=(const Sink& /*other*/) noexcept {
      list = nullptr;
      type_errors = false;
      reported.clear();
      return *this;
    }
    ~Sink() = default;
  };
  mutable Sink sink_;
};

}  // namespace mrroc
