#include "mrroc/config/check.hpp"

namespace mrroc {

namespace {
std::string joined(const std::vector<ConfigError>& errors) {
  std::string text;
  for (const auto& e : errors) {
    // Appended piece by piece: GCC 12's -O3 warns (-Wstringop-overflow) about the temporaries
    // of `a + std::string(b)` here, a false positive that fails a Release build with -Werror.
    if (!text.empty()) text += '\n';
    text += e.what();
  }
  return text;
}
}  // namespace

ConfigErrors::ConfigErrors(std::vector<ConfigError> errors)
    : ConfigError(errors.empty() ? ConfigError("no error") : errors.front()),
      errors_(std::move(errors)),
      text_(joined(errors_)) {
  if (errors_.empty()) errors_.push_back(ConfigError("no error"));
}

void ConfigErrorList::add(const ConfigError& error, const SourceLocation& where) {
  errors_.push_back(where.known() ? error.at(where) : error);
}

void ConfigErrorList::add(const std::exception& error, const SourceLocation& where) {
  if (const auto* many = dynamic_cast<const ConfigErrors*>(&error)) {
    for (const auto& e : many->errors()) add(e, where);
  } else if (const auto* one = dynamic_cast<const ConfigError*>(&error)) {
    add(*one, where);
  } else if (where.known()) {
    errors_.emplace_back(where, error.what());
  } else {
    errors_.emplace_back(std::string(error.what()));
  }
}

void ConfigErrorList::add(const std::vector<ConfigError>& errors) {
  errors_.insert(errors_.end(), errors.begin(), errors.end());
}

std::vector<ConfigError> noted(const std::vector<ConfigError>& errors, const std::string& note) {
  std::vector<ConfigError> out;
  out.reserve(errors.size());
  for (const auto& e : errors) {
    std::string message = e.message();
    message += ' ';
    message += note;
    out.push_back(e.located() ? ConfigError(e.where(), std::move(message))
                              : ConfigError(std::move(message)));
  }
  return out;
}

void ConfigErrorList::throw_if_any() const {
  if (errors_.size() == 1) throw errors_.front();
  if (!errors_.empty()) throw ConfigErrors(errors_);
}

}  // namespace mrroc
