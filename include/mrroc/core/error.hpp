#pragma once
/// @file
/// Error types shared by every process. Messages always name the value, the unit and the limit
/// (for limits) or `file:line` (for configuration).

#include <stdexcept>
#include <string>

namespace mrroc {

/// Where a value was written: `file:line`. Empty file when the value did not come from a file.
struct SourceLocation {
  std::string file;
  int line = 0;

  /// "file:line" (or "<no file>" when unknown).
  [[nodiscard]] std::string str() const;
};

/// Base of every mrroc error.
class Error : public std::runtime_error {
 public:
  explicit Error(const std::string& what) : std::runtime_error(what) {}
};

/// A configuration error; `what()` reads "file:line: error: ...".
class ConfigError : public Error {
 public:
  using Error::Error;
};

/// A request did not get a reply within its time limit.
class TimeoutError : public Error {
 public:
  using Error::Error;
};

/// A peer answered, but with an error (the peer's code and text are kept).
class RemoteError : public Error {
 public:
  RemoteError(int code, const std::string& text) : Error(text), code_(code) {}
  [[nodiscard]] int code() const { return code_; }

 private:
  int code_;
};

/// A command was refused before anything moved (limits, state machine, bad argument).
class CommandError : public Error {
 public:
  CommandError(int code, const std::string& text) : Error(text), code_(code) {}
  [[nodiscard]] int code() const { return code_; }

 private:
  int code_;
};

/// Hardware plugin failure (the EDP goes to a safe state).
class HardwareError : public Error {
 public:
  using Error::Error;
};

}  // namespace mrroc
