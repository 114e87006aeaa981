#pragma once
/// @file
/// Error types shared by every process. Messages always name the value, the unit and the limit
/// (for limits) or `file:line` (for configuration).

#include <cstdint>
#include <stdexcept>
#include <string>
#include <utility>

namespace mrroc {

/// Where a value was written: `file:line`, or only `file` when the problem concerns the whole
/// file (not found, unreadable, a model that does not parse). Empty file when the value did not
/// come from a file.
struct SourceLocation {
  /// `line` of a location that names the file only.
  static constexpr int kWholeFile = -1;

  std::string file;
  int line = 0;

  /// The file alone, without a line ("file: error: ...").
  [[nodiscard]] static SourceLocation whole_file(std::string file) {
    return SourceLocation{std::move(file), kWholeFile};
  }

  /// True when a file is named.
  [[nodiscard]] bool known() const { return !file.empty(); }

  /// "file:line", "file" for a whole file, or "<no file>" when unknown.
  [[nodiscard]] std::string str() const;
};

/// "where: error: message", the one form every located message takes (the compiler's).
[[nodiscard]] std::string located_message(const SourceLocation& where, const std::string& message);

/// Base of every mrroc error.
class Error : public std::runtime_error {
 public:
  explicit Error(const std::string& what) : std::runtime_error(what) {}
};

/// A configuration error (process-set file, task arguments, plugin parameters, robot model files,
/// URDF, scene and trajectory files: everything a user writes). `what()` reads
/// "file:line: error: message".
class ConfigError : public Error {
 public:
  ConfigError(SourceLocation where, std::string message);

  /// An error whose thrower does not know the file (a value checked on its own, e.g. a list of
  /// joint poses); `what()` is the message alone. The caller that knows where the value was
  /// written rethrows it with `at(where)`.
  explicit ConfigError(std::string message);

  [[nodiscard]] const SourceLocation& where() const { return where_; }
  /// The text after "error: ".
  [[nodiscard]] const std::string& message() const { return message_; }
  /// True when the error names its file.
  [[nodiscard]] bool located() const { return where_.known(); }

  /// This error, at `where` unless it already names a file (the innermost location wins: it is
  /// the most precise).
  [[nodiscard]] ConfigError at(const SourceLocation& where) const;

 private:
  SourceLocation where_;
  std::string message_;
};

/// A request did not get a reply within its time limit.
class TimeoutError : public Error {
 public:
  using Error::Error;
};

/// A request whose wait for the reply was ended on purpose (comm::Client::abandon), e.g. by a
/// STOP: whatever the peer did with the request is unknown.
class CallAbandoned : public Error {
 public:
  using Error::Error;
};

/// The class of an error, the same in every layer (EDP replies, ECP replies, the task API's
/// exceptions), after MRROC++'s three:
/// - non_fatal: this command or attempt failed and nothing else did; the caller may go on (retry
///   later, another command, another strategy). A refusal before anything moved: a limit, a
///   motion before synchronisation, a bad argument, a too fast or too abrupt macro-step.
/// - fatal: the task cannot go on with this effector as it is: a drive fault, an emergency stop,
///   another client driving the EDP. The robot stands; an operator (or a restart) must act.
/// - system: the system does not work as it should: a lost link, a process that does not answer,
///   a message that does not decode or is not authentic.
enum class ErrorClass : std::int8_t { none = 0, non_fatal = 1, fatal = 2, system = 3 };

/// "non-fatal", "fatal", "system" (and "none").
const char* to_string(ErrorClass c);

/// A peer answered, but with an error (the peer's code, text and class are kept).
class RemoteError : public Error {
 public:
  RemoteError(int code, const std::string& text, ErrorClass error_class = ErrorClass::fatal)
      : Error(text), code_(code), class_(error_class) {}
  [[nodiscard]] int code() const { return code_; }
  /// The peer's class of the error (fatal where the peer names none).
  [[nodiscard]] ErrorClass error_class() const { return class_; }

 private:
  int code_;
  ErrorClass class_;
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
