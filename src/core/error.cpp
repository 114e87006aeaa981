#include "mrroc/core/error.hpp"

#include <fmt/format.h>

namespace mrroc {

std::string SourceLocation::str() const {
  if (file.empty()) return "<no file>";
  return fmt::format("{}:{}", file, line);
}

}  // namespace mrroc
