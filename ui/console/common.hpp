#pragma once
// What the console's parts share: the error the HTTP API answers with, and the way a part
// reports to the SRP without holding the bus.

#include <functional>
#include <string>

#include "mrroc/comm/reporter.hpp"
#include "mrroc/core/error.hpp"

namespace mrroc::ui {

/// An error with its HTTP status code; the HTTP part answers {"error": what()} with `status`.
struct ApiError : Error {
  int status;
  ApiError(int s, const std::string& text) : Error(text), status(s) {}
};

/// Sends one message to the SRP as process "ui" (the console wires it to its Reporter).
using ReportFn = std::function<void(Severity severity, const std::string& text)>;

}  // namespace mrroc::ui
