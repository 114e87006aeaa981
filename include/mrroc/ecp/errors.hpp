#pragma once
/// @file
/// Error conditions of user tasks (paper, section 3: error conditions are handled by exception
/// handling, in parallel to the motion instructions). Throw them from anywhere in ECP task,
/// generator or condition code: the ECP shell catches them, sends no further macro-step (the
/// EDP completes the current one and holds the robot), reports to the SRP, and answers the MP
/// with the error's class, code and text. The MP task decides: `mp::EcpFailed::error_class()`.

#include <string>

#include "mrroc/core/error.hpp"
#include "mrroc/msg/mp_command.hpp"

namespace mrroc::ecp {

class TaskError : public Error {
 public:
  TaskError(ErrorClass error_class, int code, const std::string& text)
      : Error(text), class_(error_class), code_(code) {}
  [[nodiscard]] ErrorClass error_class() const { return class_; }
  [[nodiscard]] int code() const { return code_; }

 private:
  ErrorClass class_;
  int code_;
};

/// This attempt failed, the system is fine: the MP may go on (retry, another strategy).
class NonFatalError : public TaskError {
 public:
  explicit NonFatalError(const std::string& text, int code = error_code::task_error)
      : TaskError(ErrorClass::non_fatal, code, text) {}
};

/// The task cannot go on: the MP should abort it.
class FatalError : public TaskError {
 public:
  explicit FatalError(const std::string& text, int code = error_code::task_error)
      : TaskError(ErrorClass::fatal, code, text) {}
};

/// The system does not work as it should (a process, link or device failed).
class SystemError : public TaskError {
 public:
  explicit SystemError(const std::string& text, int code = error_code::task_error)
      : TaskError(ErrorClass::system, code, text) {}
};

}  // namespace mrroc::ecp
