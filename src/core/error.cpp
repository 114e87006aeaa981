#include "mrroc/core/error.hpp"

#include <fmt/format.h>

namespace mrroc {

std::string SourceLocation::str() const {
  if (file.empty()) return "<no file>";
  if (line == kWholeFile) return file;
  return fmt::format("{}:{}", file, line);
}

const char* to_string(ErrorClass c) {
  switch (c) {
    case ErrorClass::none: return "none";
    case ErrorClass::non_fatal: return "non-fatal";
    case ErrorClass::fatal: return "fatal";
    case ErrorClass::system: return "system";
  }
  return "unknown";
}

std::string located_message(const SourceLocation& where, const std::string& message) {
  return fmt::format("{}: error: {}", where.str(), message);
}

ConfigError::ConfigError(SourceLocation where, std::string message)
    : Error(located_message(where, message)),
      where_(std::move(where)),
      message_(std::move(message)) {}

ConfigError::ConfigError(std::string message) : Error(message), message_(std::move(message)) {}

ConfigError ConfigError::at(const SourceLocation& where) const {
  if (located()) return *this;
  return ConfigError(where, message_);
}

}  // namespace mrroc
