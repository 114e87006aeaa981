#pragma once
/// @file
/// Process supervisor of `mrroc-launch`.
///
/// The supervisor starts child processes, copies their output to one stream with a
/// "[name] " prefix, reaps them, and stops them in reverse start order so that no
/// process started by it (nor any process of their process groups) is left behind.
///
/// Every child
///  - runs in its own process group (its pid is the group id), so a Ctrl-C in the terminal
///    reaches only the launcher, which then stops the children in order;
///  - gets `PR_SET_PDEATHSIG = SIGKILL`, so it dies with the launcher even when the launcher
///    is SIGKILLed (Linux ties this to the *thread* that forked: call `start()` from a thread
///    that lives as long as the children, normally the main thread). This covers the child
///    only, not processes it forks: wrapper scripts should `exec` the real program;
///  - has stdin from /dev/null (or a pipe: `ChildSpec::stop_by_closing_input`), stdout and
///    stderr in pipes read by the supervisor, default signal dispositions and an empty signal
///    mask, and inherits no other descriptor of the launcher (all of them are made
///    close-on-exec in the child).
///
/// The constructor makes the calling process a child subreaper (`PR_SET_CHILD_SUBREAPER`):
/// processes that a child forks and orphans are re-parented to the launcher, which reaps those
/// of a child's process group. This is what lets `stop_all()` wait until a group is empty.
/// The constructor also resets SIGCHLD to its default disposition if it was ignored.
///
/// Output: every line written to the stream starts with the local wall-clock time at which the
/// supervisor wrote it, "HH:MM:SS.mmm " (`mrroc::format_utime`, as the SRP shows times).
/// Complete lines of a child are written as "HH:MM:SS.mmm [name] text" (stderr lines too, same
/// prefix); the bracketed name is left-aligned and padded to the longest name started so far
/// (or the width given to `reserve_name_width()`). A partial last line is written when the
/// child exits or closes the pipe. Each write happens under one mutex, so lines never mix; the
/// stream is flushed after each batch. Children that use stdio must flush (or line-buffer)
/// their stdout themselves: a pipe makes stdio fully buffered.
///
/// One copy of each report: a process' Reporter prints each report on its stderr
/// ("process: severity: text") and sends it to the SRP, which prints it on its stdout. Once a
/// child is named the report printer (`set_report_printer()`, the SRP once it is ready), the
/// children's report lines are left off the stream while that child runs; see
/// `shows_on_console()`. They are still written to the child's log file. When the printer ends,
/// every line is shown again (until a printer is named again).
///
/// The supervisor's own messages (unprefixed lines after the time) go to the same stream:
///   "stopping NAME (pid N)", "NAME exited with code C", "NAME killed by signal N (SIGX)",
///   "killed NAME after G ms" (SIGKILL after the grace period), ...
/// Use `log()` to write further lines without mixing them with child output.

#include <signal.h>
#include <sys/types.h>

#include <chrono>
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <iostream>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace mrroc::launch {

/// What to run.
struct ChildSpec {
  /// Unique among running children, e.g. "edp/irb6"; used in the output prefix "[edp/irb6] ".
  std::string name{};
  /// argv[0] is the executable: a path if it contains '/', otherwise it is looked up in PATH
  /// (by the parent, before fork). The arguments are passed unchanged.
  std::vector<std::string> argv{};
  /// Extra environment entries "NAME=value", added to (or replacing in) the inherited
  /// environment of the child.
  std::vector<std::string> env{};
  /// Time between the stop signal and SIGKILL in `stop_all()` (negative counts as 0).
  std::chrono::milliseconds stop_grace{3000};
  /// The signal `stop_all()` sends first (to the child's process group).
  int stop_signal = SIGTERM;
  /// Stdin is a pipe the supervisor holds open and never writes to, instead of /dev/null, and
  /// `stop_all()` closes it instead of sending `stop_signal` (then SIGKILL after `stop_grace`
  /// as usual). For ssh: the client passes the end of its input on to the remote side, whose
  /// wrapper then sends the stop signal (launch_plan.hpp, `host_command`). The pipe also closes
  /// when the child is reaped, and with the launcher.
  bool stop_by_closing_input = false;
  /// When not empty, every output line of the child is also appended to this file with a UTC
  /// time stamp (see LogFile), as are the start and the end of the child. The file is rotated
  /// when it holds `log_max_bytes` or more, keeping `log_keep` old files (path.1 .. path.N).
  std::filesystem::path log_file{};
  std::uintmax_t log_max_bytes = 1024 * 1024;
  int log_keep = 3;
};

/// Where a child is in its life.
enum class ChildState {
  running,  ///< started and not reaped yet
  exited,   ///< terminated by `exit()` / return from main; see `ChildExit::exit_code`
  killed,   ///< terminated by a signal; see `ChildExit::signal`
};

/// How a child ended.
struct ChildExit {
  std::string name{};
  /// The exit status if `signal == 0`; 128 + signal if the child was killed by a signal
  /// (the shell convention, so a launcher can return it); -1 if the status was lost
  /// (somebody else reaped the child).
  int exit_code = 0;
  /// The signal that terminated the child, 0 if it exited normally.
  int signal = 0;
  pid_t pid = -1;
  /// True if `stop_all()` had to SIGKILL the child after its grace period.
  bool forced = false;

  [[nodiscard]] ChildState state() const {
    return signal == 0 ? ChildState::exited : ChildState::killed;
  }
};

/// Starts, watches and stops a set of child processes. All public member functions are
/// thread-safe; an internal thread reads the children's output and reaps them (it polls
/// every 25 ms while children run, so exits are noticed within about 25 ms). Do not call
/// `start()` while `stop_all()` runs (children started then are stopped by the destructor).
class Supervisor {
 public:
  /// `out` receives the prefixed child output and the supervisor's progress lines; it must
  /// outlive the supervisor and must not be written to by anybody else except via `log()`.
  explicit Supervisor(std::ostream& out = std::cout);
  /// Calls `stop_all()`, then stops the output thread (after copying what is left in the
  /// pipes) and closes every descriptor. Afterwards no child is alive or left a zombie.
  ~Supervisor();

  Supervisor(const Supervisor&) = delete;
  Supervisor& operator=(const Supervisor&) = delete;
  Supervisor(Supervisor&&) = delete;
  Supervisor& operator=(Supervisor&&) = delete;

  /// Starts a child and returns its pid (also its process group id) once it has called exec.
  /// A name may be started again once its previous child was reaped (a restart); the new child
  /// then takes the place of the first one of that name in the stop order.
  /// Throws mrroc::Error if the name is empty or already used by a running child, argv is
  /// empty, the executable is not found in PATH, or exec fails (the message names the
  /// child, the path and strerror, e.g. "cannot start edp/irb6: /x/edp: No such file or
  /// directory"), or the log file cannot be opened; in that case nothing is left running.
  pid_t start(const ChildSpec& spec);

  /// Waits until a child exits, a stop is requested (`stop_requested()`), or `timeout`
  /// passes, whichever is first. Returns the exits collected since the previous call
  /// (possibly empty), in the order they were reaped; returns at once if some are pending or
  /// a stop is requested (or `timeout` <= 0). Exits seen by `stop_all()` are collected too.
  std::vector<ChildExit> wait_events(std::chrono::milliseconds timeout);

  /// True after `request_stop()` or after SIGINT/SIGTERM/SIGHUP arrived (the latter needs
  /// `install_stop_signal_handlers()`).
  [[nodiscard]] bool stop_requested() const;
  /// Makes `stop_requested()` true and wakes `wait_events()`. Stops nothing by itself.
  void request_stop();

  /// True if a child of this name was started and has not been reaped yet.
  [[nodiscard]] bool is_running(const std::string& name) const;
  /// True if any child has not been reaped yet.
  [[nodiscard]] bool any_running() const;
  /// The pid of the running child of this name; nullopt if there is none.
  [[nodiscard]] std::optional<pid_t> pid_of(const std::string& name) const;
  /// The state of the most recently started child of this name; nullopt if there is none.
  [[nodiscard]] std::optional<ChildState> state_of(const std::string& name) const;

  /// Stops all children in reverse start order (a restarted child counts at the place of its
  /// first start), one after the other: its `stop_signal` (SIGTERM by default) to the child's
  /// process group (or its input closed: `ChildSpec::stop_by_closing_input`), then wait until
  /// the child is reaped and its group is empty, at most its `stop_grace`, then SIGKILL to the
  /// group and wait until it is gone (at most 5 s more; a warning line is written if not).
  /// Children that already exited but left processes in their group are handled the same way.
  /// A further stop signal (e.g. a second Ctrl-C) during `stop_all()` skips the remaining grace
  /// periods (SIGKILL at once). Prints "stopping NAME (pid N)" (plus " with SIGX" for another
  /// stop signal than SIGTERM, or " by closing its input"), the exit line, or "killed NAME
  /// after G ms".
  void stop_all();

  /// All exits so far, in the order they were reaped.
  [[nodiscard]] std::vector<ChildExit> exits() const;

  /// Writes `line` plus '\n' to the output stream (unprefixed), never inside a child's line.
  void log(std::string_view line);

  /// Pads the "[name]" prefix as if a name of `width` characters had been started; call
  /// it with the longest name before starting anything to keep the output aligned.
  void reserve_name_width(std::size_t width);

  /// Names the running child `name` the report printer: from now until that child is reaped,
  /// the children's report lines (`shows_on_console()`) go to their log files only. Call it
  /// when the SRP is ready (it then prints every report), again after each restart of it.
  /// Does nothing if no child of that name runs.
  void set_report_printer(const std::string& name);

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

/// True if `line` is a report line of the process `process`, as `Reporter::report` prints it on
/// stderr: "<process>: <severity>: <text>" with a severity of debug, info, warning, error or
/// fatal.
[[nodiscard]] bool is_report_line(std::string_view process, std::string_view line);

/// Whether the supervisor writes a line of the child `child` to its stream: every line except a
/// report line of the child itself (`is_report_line(child, line)`) on its stderr while a report
/// printer runs (`printer_running`), which prints the same message. Other lines (stdout, other
/// stderr output such as "mrroc-axis-emu: ..." or a crash message) are always shown, and so is
/// everything while no printer runs: a report is never lost from the console.
[[nodiscard]] bool shows_on_console(std::string_view child, bool from_stderr, std::string_view line,
                                    bool printer_running);

/// Installs handlers for SIGINT, SIGTERM and SIGHUP that make `stop_requested()` of every
/// supervisor true and wake `wait_events()` (self-pipe; the handlers are async-signal-safe).
/// Call once from main, before starting threads; calling again does nothing.
/// Throws mrroc::Error if the pipe or a handler cannot be set up.
void install_stop_signal_handlers();

/// The first stop signal received (SIGINT, SIGTERM or SIGHUP), 0 if none.
[[nodiscard]] int stop_signal();

/// How many stop signals have been received.
[[nodiscard]] int stop_signal_count();

}  // namespace mrroc::launch
