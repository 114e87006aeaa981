#pragma once
/// @file
/// Collecting configuration errors: a check that reports every error of a file in one run
/// (`mrroc-launch --check`, and every process at start) instead of stopping at the first.

#include <exception>
#include <string>
#include <vector>

#include "mrroc/core/error.hpp"

namespace mrroc {

/// The LCM URL on which a process checks its config (`--check-config`): LCM's in-process queue,
/// so that the process can build what it builds at start (clients, links) without any network.
inline constexpr const char* kCheckLcmUrl = "memq://";

/// Exit code of a process' `--check-config` that found errors (0: none).
inline constexpr int kExitConfigErrors = 2;

/// Several configuration errors found by one check, each with its own `file:line`. It is a
/// `ConfigError` (the first error's location and message) whose `what()` lists every error,
/// one per line.
class ConfigErrors : public ConfigError {
 public:
  /// @param errors  at least one
  explicit ConfigErrors(std::vector<ConfigError> errors);

  [[nodiscard]] const std::vector<ConfigError>& errors() const { return errors_; }
  [[nodiscard]] const char* what() const noexcept override { return text_.c_str(); }

 private:
  std::vector<ConfigError> errors_;
  std::string text_;
};

/// The errors of one check, in the order found.
class ConfigErrorList {
 public:
  /// Adds `error`, at `where` unless it names its file already (`ConfigError::at`).
  void add(const ConfigError& error, const SourceLocation& where = {});
  /// Adds what `error` says: every error of a `ConfigErrors`, a `ConfigError` (at `where` unless
  /// located), or any other exception's text at `where`.
  void add(const std::exception& error, const SourceLocation& where);
  void add(const std::vector<ConfigError>& errors);

  /// Runs `f`; an exception it throws is added (at `where` unless located). Returns true when
  /// `f` returned normally.
  template <class F>
  bool run(const SourceLocation& where, F&& f) {
    try {
      f();
      return true;
    } catch (const std::exception& e) {
      add(e, where);
      return false;
    }
  }

  [[nodiscard]] bool empty() const { return errors_.empty(); }
  [[nodiscard]] std::size_t size() const { return errors_.size(); }
  [[nodiscard]] const std::vector<ConfigError>& errors() const { return errors_; }
  /// @throws ConfigErrors with every error when there is any.
  void throw_if_any() const;

 private:
  std::vector<ConfigError> errors_;
};

/// `errors` with `note` appended to each message (after a space), at their own locations: e.g.
/// "(checked as ECP task 'engrave')" for the errors of arguments checked against a suggested
/// task.
[[nodiscard]] std::vector<ConfigError> noted(const std::vector<ConfigError>& errors,
                                             const std::string& note);

}  // namespace mrroc
