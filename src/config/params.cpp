#include "mrroc/config/params.hpp"

#include <fmt/format.h>

#include "mrroc/config/check.hpp"

namespace mrroc {

void Params::set(const std::string& key, ParamValue value, SourceLocation where) {
  values_[key] = std::move(value);
  where_[key] = std::move(where);
  read_[key] = false;
}

bool Params::has(const std::string& key) const { return values_.count(key) != 0; }

SourceLocation Params::location_of(const std::string& key) const {
  auto it = where_.find(key);
  return it == where_.end() ? location_ : it->second;
}

SourceLocation Params::location_of_row(const std::string& key, std::size_t row) const {
  auto it = row_where_.find(key);
  return it == row_where_.end() || row >= it->second.size() ? location_of(key) : it->second[row];
}

void Params::set_row_locations(const std::string& key, std::vector<SourceLocation> rows) {
  row_where_[key] = std::move(rows);
}

const Params::Entry* Params::find(const std::string& key) const {
  static thread_local Entry entry;
  auto it = values_.find(key);
  if (it == values_.end()) return nullptr;
  read_[key] = true;
  entry = Entry{it->second, where_.at(key)};
  return &entry;
}

namespace {

/// The value as the error names it: `5`, `"fast"`, `a list of 3 numbers`.
std::string describe(const ParamValue& value) {
  const auto list = [](std::size_t n, const char* of) {
    return n == 0 ? std::string("an empty list") : fmt::format("a list of {} {}", n, of);
  };
  if (const auto* b = std::get_if<bool>(&value)) return *b ? "true" : "false";
  if (const auto* i = std::get_if<std::int64_t>(&value)) return std::to_string(*i);
  if (const auto* d = std::get_if<double>(&value)) return fmt::format("{}", *d);
  if (const auto* s = std::get_if<std::string>(&value)) return fmt::format("\"{}\"", *s);
  if (const auto* v = std::get_if<std::vector<double>>(&value)) return list(v->size(), "numbers");
  if (const auto* r = std::get_if<std::vector<std::vector<double>>>(&value))
    return list(r->size(), "lists");
  if (const auto* n = std::get_if<std::vector<std::string>>(&value))
    return list(n->size(), "strings");
  return "another type";
}

}  // namespace

void Params::type_error(const std::string& key, const char* expected) const {
  throw ConfigError(location_of(key), fmt::format("'{}' must be {}, not {}", key, expected,
                                                  describe(values_.at(key))));
}

bool Params::collected(const ConfigError& error, const std::string& key) const {
  if (sink_.list == nullptr || !sink_.type_errors) return false;
  if (sink_.reported.insert(key).second) sink_.list->add(error);
  return true;
}

void Params::missing(const std::string& key) const {
  throw ConfigError(location_, fmt::format("missing required key '{}'", key));
}

namespace {
template <class T>
const T* as(const ParamValue& v) {
  return std::get_if<T>(&v);
}
}  // namespace

double Params::get_double(const std::string& key) const {
  const Entry* e = find(key);
  if (e == nullptr) missing(key);
  if (auto d = as<double>(e->value)) return *d;
  if (auto i = as<std::int64_t>(e->value)) return static_cast<double>(*i);
  type_error(key, "a number");
}

std::int64_t Params::get_int(const std::string& key) const {
  const Entry* e = find(key);
  if (e == nullptr) missing(key);
  if (auto i = as<std::int64_t>(e->value)) return *i;
  type_error(key, "an integer");
}

bool Params::get_bool(const std::string& key) const {
  const Entry* e = find(key);
  if (e == nullptr) missing(key);
  if (auto b = as<bool>(e->value)) return *b;
  type_error(key, "true or false");
}

std::string Params::get_string(const std::string& key) const {
  const Entry* e = find(key);
  if (e == nullptr) missing(key);
  if (auto s = as<std::string>(e->value)) return *s;
  type_error(key, "a string");
}

std::vector<double> Params::get_doubles(const std::string& key) const {
  const Entry* e = find(key);
  if (e == nullptr) missing(key);
  if (auto v = as<std::vector<double>>(e->value)) return *v;
  type_error(key, "a list of numbers");
}

std::vector<std::vector<double>> Params::get_double_rows(const std::string& key) const {
  const Entry* e = find(key);
  if (e == nullptr) missing(key);
  if (auto v = as<std::vector<std::vector<double>>>(e->value)) return *v;
  type_error(key, "a list of lists of numbers");
}

std::vector<std::string> Params::get_strings(const std::string& key) const {
  const Entry* e = find(key);
  if (e == nullptr) missing(key);
  if (auto v = as<std::vector<std::string>>(e->value)) return *v;
  type_error(key, "a list of strings");
}

// An optional value of another type: thrown, or (collecting) reported once and the default used,
// so that the task's other arguments are checked too.
double Params::get_double(const std::string& key, double fallback) const {
  if (!has(key)) return fallback;
  try {
    return get_double(key);
  } catch (const ConfigError& e) {
    if (!collected(e, key)) throw;
    return fallback;
  }
}
std::int64_t Params::get_int(const std::string& key, std::int64_t fallback) const {
  if (!has(key)) return fallback;
  try {
    return get_int(key);
  } catch (const ConfigError& e) {
    if (!collected(e, key)) throw;
    return fallback;
  }
}
bool Params::get_bool(const std::string& key, bool fallback) const {
  if (!has(key)) return fallback;
  try {
    return get_bool(key);
  } catch (const ConfigError& e) {
    if (!collected(e, key)) throw;
    return fallback;
  }
}
std::string Params::get_string(const std::string& key, const std::string& fallback) const {
  if (!has(key)) return fallback;
  try {
    return get_string(key);
  } catch (const ConfigError& e) {
    if (!collected(e, key)) throw;
    return fallback;
  }
}
std::vector<double> Params::get_doubles(const std::string& key,
                                        const std::vector<double>& fallback) const {
  if (!has(key)) return fallback;
  try {
    return get_doubles(key);
  } catch (const ConfigError& e) {
    if (!collected(e, key)) throw;
    return fallback;
  }
}

std::vector<std::string> Params::unread_keys() const {
  std::vector<std::string> out;
  for (const auto& [key, was_read] : read_)
    if (!was_read) out.push_back(key);
  return out;
}

void Params::reject_unread(const std::string& table_name) const {
  for (const auto& key : unread_keys()) {
    if (sink_.list != nullptr) {
      sink_.list->add(
          ConfigError(location_of(key), fmt::format("unknown key '{}' in [{}]", key, table_name)));
      read_[key] = true;  // reported once
      continue;
    }
    throw ConfigError(location_of(key), fmt::format("unknown key '{}' in [{}]", key, table_name));
  }
}

}  // namespace mrroc
