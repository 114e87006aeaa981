#include "supervisor.hpp"

#include <fcntl.h>
#include <poll.h>
#include <pthread.h>
#include <signal.h>
#include <sys/prctl.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <condition_variable>
#include <cstdlib>
#include <cstring>
#include <functional>
#include <mutex>
#include <thread>
#include <utility>

#include <fmt/format.h>

#include "log_file.hpp"
#include "mrroc/core/error.hpp"
#include "mrroc/core/time.hpp"

namespace mrroc::launch {

namespace {

using Clock = std::chrono::steady_clock;
using std::chrono::milliseconds;

/// How often the output thread checks for exited children while some are running (or have
/// left processes in their group), and how often otherwise.
constexpr int kTickMs = 25;
constexpr int kIdleTickMs = 200;
constexpr milliseconds kStopSlice{10};
/// How long stop_all waits for a group to vanish after SIGKILL.
constexpr milliseconds kKillWait{5000};
/// Longer waits and grace periods are cut to this (it keeps time arithmetic from overflowing).
constexpr milliseconds kMaxWait{std::chrono::hours(24 * 365)};
/// Bytes read from one pipe per poll round (so a chatty child cannot starve the others).
constexpr std::size_t kReadPerRound = 256 * 1024;
/// Bytes read from a child's pipes when it is reaped (whatever is in the pipe buffer).
constexpr std::size_t kReadAtExit = 1024 * 1024;
/// A line longer than this is written in pieces.
constexpr std::size_t kMaxLine = 64 * 1024;
/// Exit status of a child whose exec failed (the real errno goes through the error pipe).
constexpr int kExecFailedStatus = 127;

// ---- stop signals --------------------------------------------------------------------------

std::atomic<int> g_stop_signal_count{0};
std::atomic<int> g_first_stop_signal{0};
std::atomic<int> g_signal_pipe_r{-1};
std::atomic<int> g_signal_pipe_w{-1};
std::mutex g_install_mutex;
bool g_installed = false;
static_assert(std::atomic<int>::is_always_lock_free, "signal handler needs lock-free atomics");

void on_stop_signal(int sig) {
  const int saved_errno = errno;
  int expected = 0;
  g_first_stop_signal.compare_exchange_strong(expected, sig);
  g_stop_signal_count.fetch_add(1);
  const int fd = g_signal_pipe_w.load();
  if (fd >= 0) {
    const char byte = 1;
    [[maybe_unused]] const ssize_t n = ::write(fd, &byte, 1);  // full pipe: a wake-up is pending
  }
  errno = saved_errno;
}

// ---- small helpers -------------------------------------------------------------------------

std::string errno_text(int err) { return std::strerror(err); }

/// An owned file descriptor.
class Fd {
 public:
  Fd() = default;
  explicit Fd(int fd) : fd_(fd) {}
  ~Fd() { reset(); }
  Fd(Fd&& o) noexcept : fd_(std::exchange(o.fd_, -1)) {}
  Fd& operator=(Fd&& o) noexcept {
    if (this != &o) {
      reset();
      fd_ = std::exchange(o.fd_, -1);
    }
    return *this;
  }
  Fd(const Fd&) = delete;
  Fd& operator=(const Fd&) = delete;

  [[nodiscard]] int get() const { return fd_; }
  int release() { return std::exchange(fd_, -1); }
  void reset() {
    if (fd_ >= 0) ::close(fd_);
    fd_ = -1;
  }

 private:
  int fd_ = -1;
};

/// A close-on-exec pipe: {read end, write end}.
std::pair<Fd, Fd> make_pipe(int extra_flags = 0) {
  int fds[2];
  if (::pipe2(fds, O_CLOEXEC | extra_flags) != 0) {
    throw Error(fmt::format("cannot create a pipe: {}", errno_text(errno)));
  }
  return {Fd(fds[0]), Fd(fds[1])};
}

void set_nonblocking(int fd) {
  const int flags = ::fcntl(fd, F_GETFL);
  if (flags >= 0) ::fcntl(fd, F_SETFL, flags | O_NONBLOCK);
}

void drain_fd(int fd) {
  char buf[256];
  while (::read(fd, buf, sizeof buf) > 0) {
  }
}

std::string signal_name(int sig) {
  if (const char* abbrev = ::sigabbrev_np(sig)) return fmt::format("SIG{}", abbrev);
  return fmt::format("signal {}", sig);
}

bool is_executable_file(const std::string& path) {
  struct stat st {};
  return ::stat(path.c_str(), &st) == 0 && S_ISREG(st.st_mode) && ::access(path.c_str(), X_OK) == 0;
}

/// The path to exec for `program` (execvp's PATH search, done before fork).
std::optional<std::string> resolve_program(const std::string& program) {
  if (program.find('/') != std::string::npos) return program;
  const char* path_env = std::getenv("PATH");
  std::string_view rest = path_env != nullptr ? path_env : "/usr/local/bin:/usr/bin:/bin";
  for (;;) {
    const std::size_t colon = rest.find(':');
    const std::string_view dir = rest.substr(0, colon);  // empty means the current directory
    std::string candidate =
        fmt::format("{}/{}", dir.empty() ? std::string_view(".") : dir, program);
    if (is_executable_file(candidate)) return candidate;
    if (colon == std::string_view::npos) return std::nullopt;
    rest.remove_prefix(colon + 1);
  }
}

/// The inherited environment with `overrides` ("NAME=value") applied.
std::vector<std::string> child_environment(const std::vector<std::string>& overrides) {
  std::vector<std::string> env;
  for (char** e = environ; e != nullptr && *e != nullptr; ++e) env.emplace_back(*e);
  for (const auto& o : overrides) {
    const std::size_t eq = o.find('=');
    const std::string key = o.substr(0, eq == std::string::npos ? o.size() : eq + 1);
    auto it = std::find_if(env.begin(), env.end(), [&](const std::string& e) {
      return e.compare(0, key.size(), key) == 0 &&
             (eq != std::string::npos || e.size() == key.size() || e[key.size()] == '=');
    });
    if (it != env.end()) {
      *it = o;
    } else {
      env.push_back(o);
    }
  }
  return env;
}

std::vector<char*> c_strings(std::vector<std::string>& strings) {
  std::vector<char*> out;
  out.reserve(strings.size() + 1);
  for (auto& s : strings) out.push_back(s.data());
  out.push_back(nullptr);
  return out;
}

/// Everything the child needs between fork and exec, prepared before fork (no allocation
/// happens in the child).
struct ExecPlan {
  const char* path;
  char* const* argv;
  char* const* envp;
  int input;  // stdin: /dev/null or the read end of the input pipe
  int out_w;
  int err_w;
  int error_w;  // close-on-exec; receives errno if exec (or the set-up) fails
  pid_t parent;
  const sigset_t* empty_mask;
  int life_r;                // read end of the launcher's life pipe: EOF when the launcher is gone
  struct timespec escalate;  // after the launcher is gone (and SIGTERM came): SIGKILL then
};

/// The stop guard, forked by the child before exec (only async-signal-safe calls): when the
/// launcher dies the child gets SIGTERM (PR_SET_PDEATHSIG) and may ramp down; if its group is
/// still there `escalate` later, the guard SIGKILLs it. The guard dies with the child
/// (PR_SET_PDEATHSIG SIGKILL), holds no descriptor but the life pipe, and is a member of the
/// child's process group.
void fork_stop_guard(const ExecPlan& p) {
  const pid_t child = ::getpid();
  const pid_t guard = ::fork();
  if (guard != 0) return;  // the child (or fork failed: no guard, PDEATHSIG still applies)
  if (::prctl(PR_SET_PDEATHSIG, SIGKILL) != 0 || ::getppid() != child) ::_exit(0);
  ::prctl(PR_SET_NAME, "mrroc-stopguard");
  if (p.life_r > 0) ::close_range(0, static_cast<unsigned>(p.life_r) - 1U, 0);
  ::close_range(static_cast<unsigned>(p.life_r) + 1U, ~0U, 0);
  char c = 0;
  for (;;) {
    const ssize_t n = ::read(p.life_r, &c, 1);
    if (n == 0) break;                        // the launcher is gone
    if (n < 0 && errno != EINTR) ::_exit(0);  // cannot watch
  }
  struct timespec left = p.escalate;
  while (::nanosleep(&left, &left) != 0 && errno == EINTR) {
  }
  ::kill(-child, SIGKILL);  // the child's group (the guard with it)
  ::_exit(0);
}

/// Runs in the child after fork: only async-signal-safe calls.
[[noreturn]] void exec_child(const ExecPlan& p) {
  auto fail = [&p](int err) {
    [[maybe_unused]] const ssize_t n = ::write(p.error_w, &err, sizeof err);
    ::_exit(kExecFailedStatus);
  };

  ::setpgid(0, 0);
  // The launcher's death stops the child as a stop request would (SIGTERM: an EDP ramps its
  // robot down); the stop guard escalates to SIGKILL if the child does not end in time.
  if (::prctl(PR_SET_PDEATHSIG, SIGTERM) != 0) fail(errno);
  if (::getppid() != p.parent) ::_exit(kExecFailedStatus);  // the launcher already died
  fork_stop_guard(p);

  // Default dispositions for everything (ignored signals would survive exec). All signals
  // are blocked here (the parent blocked them around fork), so no launcher handler can run.
  struct sigaction dfl {};
  dfl.sa_handler = SIG_DFL;
  ::sigemptyset(&dfl.sa_mask);
  for (int sig = 1; sig < NSIG; ++sig) {
    if (sig != SIGKILL && sig != SIGSTOP) ::sigaction(sig, &dfl, nullptr);
  }

  // Move the sources out of 0..2 first (they might be there if the launcher's stdio is closed).
  int sources[3] = {p.input, p.out_w, p.err_w};
  for (int& fd : sources) {
    if (fd < 3) {
      fd = ::fcntl(fd, F_DUPFD_CLOEXEC, 3);
      if (fd < 0) fail(errno);
    }
  }
  for (int target = 0; target < 3; ++target) {
    if (::dup2(sources[target], target) < 0) fail(errno);  // dup2 clears FD_CLOEXEC
  }
  // Nothing else of the launcher leaks into the child (e.g. sockets opened without CLOEXEC).
  ::close_range(3, ~0U, CLOSE_RANGE_CLOEXEC);

  ::sigprocmask(SIG_SETMASK, p.empty_mask, nullptr);
  ::execve(p.path, p.argv, p.envp);
  fail(errno);
  ::_exit(kExecFailedStatus);  // not reached
}

// ---- children ------------------------------------------------------------------------------

struct Stream {
  int fd = -1;  // non-blocking read end, -1 once closed
  bool is_stderr = false;
  std::string partial;
};

struct Child {
  std::string name;
  pid_t pid = -1;
  std::chrono::milliseconds grace{};
  int stop_signal = SIGTERM;
  std::size_t order = 0;         // place in the stop order (that of the name's first start)
  std::unique_ptr<LogFile> log;  // null: no log file
  Fd input_w;  // write end of the child's stdin pipe (ChildSpec::stop_by_closing_input), or none
  Stream out;
  Stream err;
  bool reaped = false;
  bool group_done = false;  // reaped and no process of the group is left
  bool forced = false;      // SIGKILLed by stop_all after the grace period
  ChildExit exit;
};

}  // namespace

// ---- Supervisor::Impl ----------------------------------------------------------------------

struct Supervisor::Impl {
  explicit Impl(std::ostream& o) : out(o) {}

  std::ostream& out;
  std::mutex out_mu;  // guards `out`; taken after `mu` if both are needed
  mutable std::mutex mu;
  std::condition_variable cv;  // notified on exits, stop requests and signals
  std::mutex stop_mu;          // serializes stop_all()

  std::vector<std::unique_ptr<Child>> children;  // in start order
  std::vector<ChildExit> pending;
  std::vector<ChildExit> all;
  std::size_t name_width = 0;
  std::size_t next_order = 0;
  /// The child that prints every report (the SRP), while it is not reaped; null if none.
  const Child* report_printer = nullptr;
  bool stop = false;
  bool shutdown = false;
  int seen_signals = 0;

  Fd wake_r;
  Fd wake_w;
  /// Life pipe: the launcher alone holds the write end; each child's stop guard reads EOF when
  /// the launcher is gone.
  Fd life_r;
  Fd life_w;
  std::thread thread;

  /// Appends "HH:MM:SS.mmm text\n" (the local time now) to `batch`.
  static void add_line(std::string& batch, std::string_view text) {
    fmt::format_to(std::back_inserter(batch), "{} {}\n", format_utime(now_utime()), text);
  }

  /// Writes one of the supervisor's own lines (time stamped).
  void say(std::string_view text) {
    std::string line;
    add_line(line, text);
    emit(line);
  }

  void emit(std::string_view text) {
    if (text.empty()) return;
    std::lock_guard lock(out_mu);
    out.write(text.data(), static_cast<std::streamsize>(text.size()));
    out.flush();
  }

  void wake() {
    const char byte = 1;
    [[maybe_unused]] const ssize_t n = ::write(wake_w.get(), &byte, 1);
  }

  [[nodiscard]] bool stop_requested_locked() const {
    return stop || g_stop_signal_count.load() > 0;
  }

  void format_line(const Child& c, const Stream& s, std::string_view line,
                   std::string& batch) const {
    if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
    if (c.log) {
      c.log->write_line(line);
      if (const auto notice = c.log->take_notice())
        add_line(batch, fmt::format("mrroc-launch: {}: {}", c.name, *notice));
    }
    if (!shows_on_console(c.name, s.is_stderr, line, report_printer != nullptr)) return;
    fmt::format_to(std::back_inserter(batch), "{} {:<{}} {}\n", format_utime(now_utime()),
                   fmt::format("[{}]", c.name), name_width + 2, line);
  }

  void split_lines(const Child& c, Stream& s, std::string& batch) const {
    std::size_t begin = 0;
    for (;;) {
      const std::size_t nl = s.partial.find('\n', begin);
      if (nl == std::string::npos) break;
      format_line(c, s, std::string_view(s.partial).substr(begin, nl - begin), batch);
      begin = nl + 1;
    }
    s.partial.erase(0, begin);
    while (s.partial.size() > kMaxLine) {
      format_line(c, s, std::string_view(s.partial).substr(0, kMaxLine), batch);
      s.partial.erase(0, kMaxLine);
    }
  }

  void flush_partial(const Child& c, Stream& s, std::string& batch) const {
    if (!s.partial.empty()) format_line(c, s, s.partial, batch);
    s.partial.clear();
  }

  void close_stream(const Child& c, Stream& s, std::string& batch) {
    flush_partial(c, s, batch);
    ::close(s.fd);
    s.fd = -1;
    if (std::this_thread::get_id() != thread.get_id()) wake();  // it may be polling the fd
  }

  /// Reads what is available (up to `limit` bytes) from one stream.
  void read_stream(const Child& c, Stream& s, std::size_t limit, std::string& batch) {
    char buf[16384];
    std::size_t total = 0;
    while (s.fd >= 0 && total < limit) {
      const ssize_t n = ::read(s.fd, buf, sizeof buf);
      if (n > 0) {
        total += static_cast<std::size_t>(n);
        s.partial.append(buf, static_cast<std::size_t>(n));
        split_lines(c, s, batch);
      } else if (n == 0) {
        close_stream(c, s, batch);
      } else if (errno == EINTR) {
        continue;
      } else if (errno == EAGAIN || errno == EWOULDBLOCK) {
        break;
      } else {
        close_stream(c, s, batch);
      }
    }
  }

  Child* find_unreaped(pid_t pid) {
    for (auto& c : children) {
      if (!c->reaped && c->pid == pid) return c.get();
    }
    return nullptr;
  }

  void on_reaped(Child& c, std::optional<int> status) {
    c.input_w.reset();
    std::string batch;
    read_stream(c, c.out, kReadAtExit, batch);
    read_stream(c, c.err, kReadAtExit, batch);
    flush_partial(c, c.out, batch);
    flush_partial(c, c.err, batch);
    // From here on the reports are not printed by this child: every line is shown again.
    if (report_printer == &c) report_printer = nullptr;

    ChildExit e;
    e.name = c.name;
    e.pid = c.pid;
    e.forced = c.forced;
    if (!status) {
      e.exit_code = -1;
      add_line(batch, fmt::format("{} (pid {}) ended, exit status unknown", c.name, c.pid));
    } else if (WIFEXITED(*status)) {
      e.exit_code = WEXITSTATUS(*status);
      add_line(batch, fmt::format("{} exited with code {}", c.name, e.exit_code));
    } else {
      e.signal = WTERMSIG(*status);
      e.exit_code = 128 + e.signal;
      if (!c.forced) {
        add_line(batch,
                 fmt::format("{} killed by signal {} ({}){}", c.name, e.signal,
                             signal_name(e.signal), WCOREDUMP(*status) ? ", core dumped" : ""));
      }
    }
    if (c.log) {
      c.log->write_line(e.signal != 0 ? fmt::format("--- {} (pid {}) killed by signal {} ({})",
                                                    c.name, c.pid, e.signal, signal_name(e.signal))
                                      : fmt::format("--- {} (pid {}) exited with code {}", c.name,
                                                    c.pid, e.exit_code));
    }
    emit(batch);
    c.reaped = true;
    c.exit = e;
    pending.push_back(e);
    all.push_back(std::move(e));
    cv.notify_all();
  }

  /// Reaps exited children and orphaned members of their process groups (we are a
  /// subreaper); marks groups that are empty.
  void reap() {
    for (std::size_t i = 0; i < children.size(); ++i) {
      Child& c = *children[i];
      if (c.group_done) continue;
      if (!c.reaped) {
        int status = 0;
        const pid_t r = ::waitpid(c.pid, &status, WNOHANG);
        if (r == c.pid) {
          on_reaped(c, status);
        } else if (r < 0 && errno == ECHILD) {
          on_reaped(c, std::nullopt);  // somebody else reaped it
        }
      }
      for (;;) {
        int status = 0;
        const pid_t r = ::waitpid(-c.pid, &status, WNOHANG);
        if (r <= 0) break;
        if (Child* other = find_unreaped(r)) on_reaped(*other, status);
      }
      if (c.reaped && ::kill(-c.pid, 0) != 0 && errno == ESRCH) c.group_done = true;
    }
  }

  void check_signals() {
    const int count = g_stop_signal_count.load();
    if (count != seen_signals) {
      seen_signals = count;
      cv.notify_all();
    }
  }

  /// The output and reaping thread.
  void run() {
    std::vector<pollfd> pfds;
    std::unique_lock lock(mu);
    while (!shutdown) {
      pfds.clear();
      pfds.push_back({wake_r.get(), POLLIN, 0});
      const int signal_fd = g_signal_pipe_r.load();
      if (signal_fd >= 0) pfds.push_back({signal_fd, POLLIN, 0});
      bool busy = false;
      for (const auto& c : children) {
        if (c->out.fd >= 0) pfds.push_back({c->out.fd, POLLIN, 0});
        if (c->err.fd >= 0) pfds.push_back({c->err.fd, POLLIN, 0});
        busy = busy || !c->group_done;
      }
      lock.unlock();
      const int n =
          ::poll(pfds.data(), static_cast<nfds_t>(pfds.size()), busy ? kTickMs : kIdleTickMs);
      lock.lock();

      if (n > 0) {
        std::string batch;
        for (const pollfd& p : pfds) {
          if (p.revents == 0) continue;
          if (p.fd == wake_r.get()) {
            drain_fd(p.fd);
          } else if (p.fd == signal_fd) {
            drain_fd(p.fd);
          } else {
            // The descriptor may have been closed (and its number reused) meanwhile: look it
            // up again; reading a non-blocking pipe with nothing in it is harmless.
            for (auto& c : children) {
              if (c->out.fd == p.fd) read_stream(*c, c->out, kReadPerRound, batch);
              if (c->err.fd == p.fd) read_stream(*c, c->err, kReadPerRound, batch);
            }
          }
        }
        emit(batch);
      }
      reap();
      check_signals();
    }
    // Shutting down: copy whatever is left and close the pipes.
    std::string batch;
    for (auto& c : children) {
      read_stream(*c, c->out, kReadAtExit, batch);
      read_stream(*c, c->err, kReadAtExit, batch);
      for (Stream* s : {&c->out, &c->err}) {
        flush_partial(*c, *s, batch);
        if (s->fd >= 0) ::close(s->fd);
        s->fd = -1;
      }
    }
    emit(batch);
  }

  /// Signals the child's process group (and the child itself if it left the group).
  void signal_child(const Child& c, int sig) const {
    const int r = ::kill(-c.pid, sig);
    if (!c.reaped && (r != 0 || ::getpgid(c.pid) != c.pid)) ::kill(c.pid, sig);
  }

  /// Waits (with `lock` held on entry and exit) until the child is reaped and its group is
  /// empty, the deadline passes, or (if `hurry` is given) it returns true.
  bool wait_gone(std::unique_lock<std::mutex>& lock, Child& c, Clock::time_point deadline,
                 const std::function<bool()>& hurry) {
    for (;;) {
      reap();
      if (c.group_done) return true;
      if (hurry && hurry()) return false;
      const auto now = Clock::now();
      if (now >= deadline) return false;
      cv.wait_until(lock, std::min(deadline, now + kStopSlice));
    }
  }

  void stop_child(std::unique_lock<std::mutex>& lock, Child& c, bool& hurrying,
                  int signals_at_start) {
    const auto t0 = Clock::now();
    const bool leader_running = !c.reaped;
    const bool close_input = leader_running && c.input_w.get() >= 0;
    if (close_input) {
      say(fmt::format("stopping {} (pid {}) by closing its input", c.name, c.pid));
    } else if (leader_running) {
      say(fmt::format(
          "stopping {} (pid {}){}", c.name, c.pid,
          c.stop_signal == SIGTERM ? std::string() : " with " + signal_name(c.stop_signal)));
    } else {
      say(fmt::format("stopping the remaining processes of {} (process group {})", c.name, c.pid));
    }
    auto hurry = [&] {
      if (!hurrying && g_stop_signal_count.load() > signals_at_start) {
        hurrying = true;
        say("another stop signal: killing the remaining processes now");
      }
      return hurrying;
    };
    if (!hurry()) {
      if (close_input) {
        c.input_w.reset();
      } else {
        signal_child(c, c.stop_signal);
      }
      if (wait_gone(lock, c, t0 + c.grace, hurry)) return;
    }

    const auto waited = std::chrono::duration_cast<milliseconds>(Clock::now() - t0);
    const auto shown = hurrying ? waited : c.grace;
    if (!c.reaped) {
      c.forced = true;
      say(fmt::format("killed {} after {} ms", c.name, shown.count()));
    } else {
      say(fmt::format("killed the remaining processes of {} (process group {}) after {} ms", c.name,
                      c.pid, shown.count()));
    }
    signal_child(c, SIGKILL);
    if (!wait_gone(lock, c, Clock::now() + kKillWait, {})) {
      say(
          fmt::format("warning: processes of {} (process group {}) still exist {} ms after "
                      "SIGKILL",
                      c.name, c.pid, kKillWait.count()));
    }
  }
};

// ---- Supervisor ----------------------------------------------------------------------------

Supervisor::Supervisor(std::ostream& out) : impl_(std::make_unique<Impl>(out)) {
  // Orphaned descendants come to us, so that we can reap the members of a child's group.
  ::prctl(PR_SET_CHILD_SUBREAPER, 1);
  // Ignored SIGCHLD (or SA_NOCLDWAIT) would make the kernel reap children for us.
  struct sigaction old {};
  if (::sigaction(SIGCHLD, nullptr, &old) == 0 &&
      (old.sa_handler == SIG_IGN || (old.sa_flags & SA_NOCLDWAIT) != 0)) {
    struct sigaction dfl {};
    dfl.sa_handler = SIG_DFL;
    ::sigemptyset(&dfl.sa_mask);
    ::sigaction(SIGCHLD, &dfl, nullptr);
  }
  auto [r, w] = make_pipe(O_NONBLOCK);
  impl_->wake_r = std::move(r);
  impl_->wake_w = std::move(w);
  auto [lr, lw] = make_pipe();
  impl_->life_r = std::move(lr);
  impl_->life_w = std::move(lw);
  impl_->seen_signals = g_stop_signal_count.load();
  impl_->thread = std::thread([impl = impl_.get()] { impl->run(); });
}

Supervisor::~Supervisor() {
  try {
    stop_all();
  } catch (...) {  // NOLINT(bugprone-empty-catch): nothing sensible to do in a destructor
  }
  {
    std::lock_guard lock(impl_->mu);
    impl_->shutdown = true;
  }
  impl_->wake();
  impl_->thread.join();
}

pid_t Supervisor::start(const ChildSpec& spec) {
  if (spec.name.empty()) throw Error("cannot start a child without a name");
  if (spec.argv.empty() || spec.argv.front().empty()) {
    throw Error(fmt::format("cannot start {}: no program given", spec.name));
  }
  if (is_running(spec.name)) {
    throw Error(fmt::format("cannot start {}: a child of that name is running", spec.name));
  }
  if (spec.stop_signal <= 0 || spec.stop_signal >= NSIG) {
    throw Error(fmt::format("cannot start {}: stop signal {} is not a signal number (1..{})",
                            spec.name, spec.stop_signal, NSIG - 1));
  }
  // Opened before fork, so that an unusable log file leaves nothing running.
  std::unique_ptr<LogFile> log;
  if (!spec.log_file.empty()) {
    try {
      log = std::make_unique<LogFile>(spec.log_file, spec.log_max_bytes, spec.log_keep);
    } catch (const Error& e) {
      throw Error(fmt::format("cannot start {}: {}", spec.name, e.what()));
    }
  }
  const std::string& program = spec.argv.front();
  const std::optional<std::string> path = resolve_program(program);
  if (!path) {
    throw Error(fmt::format("cannot start {}: {}: {} (searched PATH)", spec.name, program,
                            errno_text(ENOENT)));
  }

  // Everything the child needs, allocated before fork.
  std::vector<std::string> args = spec.argv;
  std::vector<char*> argv = c_strings(args);
  std::vector<std::string> env = child_environment(spec.env);
  std::vector<char*> envp = c_strings(env);
  sigset_t empty_mask;
  ::sigemptyset(&empty_mask);

  // Stdin: /dev/null, or a pipe whose write end the supervisor keeps (and closes to stop it).
  Fd input_r;
  Fd input_w;
  if (spec.stop_by_closing_input) {
    auto [r, w] = make_pipe();
    input_r = std::move(r);
    input_w = std::move(w);
  } else {
    input_r = Fd(::open("/dev/null", O_RDONLY | O_CLOEXEC));
    if (input_r.get() < 0) {
      throw Error(fmt::format("cannot start {}: /dev/null: {}", spec.name, errno_text(errno)));
    }
  }
  auto [out_r, out_w] = make_pipe();
  auto [err_r, err_w] = make_pipe();
  auto [error_r, error_w] = make_pipe();
  set_nonblocking(out_r.get());
  set_nonblocking(err_r.get());

  const auto grace = std::clamp(spec.stop_grace, milliseconds(0), kMaxWait);
  const ExecPlan plan{path->c_str(),
                      argv.data(),
                      envp.data(),
                      input_r.get(),
                      out_w.get(),
                      err_w.get(),
                      error_w.get(),
                      ::getpid(),
                      &empty_mask,
                      impl_->life_r.get(),
                      {static_cast<time_t>(grace.count() / 1000),
                       static_cast<long>(grace.count() % 1000) * 1000000L}};

  // Block all signals around fork so that no launcher handler runs in the child before it
  // has reset the dispositions.
  sigset_t all_signals;
  sigset_t old_mask;
  ::sigfillset(&all_signals);
  ::pthread_sigmask(SIG_SETMASK, &all_signals, &old_mask);
  const pid_t pid = ::fork();
  if (pid == 0) exec_child(plan);
  const int fork_errno = errno;
  ::pthread_sigmask(SIG_SETMASK, &old_mask, nullptr);

  out_w.reset();
  err_w.reset();
  error_w.reset();
  input_r.reset();
  if (pid < 0) {
    throw Error(fmt::format("cannot start {}: fork: {}", spec.name, errno_text(fork_errno)));
  }
  ::setpgid(pid, pid);  // also done by the child; whoever is first wins

  // The error pipe closes on a successful exec; otherwise it carries errno.
  int child_errno = 0;
  ssize_t n = 0;
  do {
    n = ::read(error_r.get(), &child_errno, sizeof child_errno);
  } while (n < 0 && errno == EINTR);
  if (n != 0) {
    int status = 0;
    while (::waitpid(pid, &status, 0) < 0 && errno == EINTR) {
    }
    if (n != static_cast<ssize_t>(sizeof child_errno)) child_errno = EIO;
    throw Error(fmt::format("cannot start {}: {}: {}", spec.name, *path, errno_text(child_errno)));
  }

  auto child = std::make_unique<Child>();
  child->name = spec.name;
  child->pid = pid;
  child->grace = std::clamp(spec.stop_grace, milliseconds(0), kMaxWait);
  child->stop_signal = spec.stop_signal;
  child->input_w = std::move(input_w);
  child->out.fd = out_r.release();
  child->err.fd = err_r.release();
  child->err.is_stderr = true;
  if (log)
    log->write_line(
        fmt::format("--- {} started (pid {}): {}", spec.name, pid, fmt::join(spec.argv, " ")));
  child->log = std::move(log);
  {
    std::lock_guard lock(impl_->mu);
    child->order = impl_->next_order;
    for (const auto& c : impl_->children) {
      if (c->name == spec.name) {
        child->order = c->order;
        break;
      }
    }
    if (child->order == impl_->next_order) ++impl_->next_order;
    impl_->name_width = std::max(impl_->name_width, spec.name.size());
    impl_->children.push_back(std::move(child));
  }
  impl_->wake();
  return pid;
}

std::vector<ChildExit> Supervisor::wait_events(std::chrono::milliseconds timeout) {
  std::unique_lock lock(impl_->mu);
  impl_->cv.wait_for(lock, std::clamp(timeout, milliseconds(0), kMaxWait), [&] {
    impl_->check_signals();
    return !impl_->pending.empty() || impl_->stop_requested_locked();
  });
  return std::exchange(impl_->pending, {});
}

bool Supervisor::stop_requested() const {
  std::lock_guard lock(impl_->mu);
  return impl_->stop_requested_locked();
}

void Supervisor::request_stop() {
  std::lock_guard lock(impl_->mu);
  impl_->stop = true;
  impl_->cv.notify_all();
}

bool Supervisor::is_running(const std::string& name) const {
  std::lock_guard lock(impl_->mu);
  return std::any_of(impl_->children.begin(), impl_->children.end(),
                     [&](const auto& c) { return !c->reaped && c->name == name; });
}

bool Supervisor::any_running() const {
  std::lock_guard lock(impl_->mu);
  return std::any_of(impl_->children.begin(), impl_->children.end(),
                     [](const auto& c) { return !c->reaped; });
}

std::optional<pid_t> Supervisor::pid_of(const std::string& name) const {
  std::lock_guard lock(impl_->mu);
  for (const auto& c : impl_->children) {
    if (!c->reaped && c->name == name) return c->pid;
  }
  return std::nullopt;
}

std::optional<ChildState> Supervisor::state_of(const std::string& name) const {
  std::lock_guard lock(impl_->mu);
  for (auto it = impl_->children.rbegin(); it != impl_->children.rend(); ++it) {
    const Child& c = **it;
    if (c.name != name) continue;
    if (!c.reaped) return ChildState::running;
    return c.exit.state();
  }
  return std::nullopt;
}

void Supervisor::stop_all() {
  std::lock_guard stop_lock(impl_->stop_mu);
  std::unique_lock lock(impl_->mu);
  const int signals_at_start = g_stop_signal_count.load();
  bool hurrying = false;
  impl_->reap();
  // Reverse start order; a restarted child stands where its name was first started (the
  // later start of a name first).
  std::vector<std::size_t> order(impl_->children.size());
  for (std::size_t i = 0; i < order.size(); ++i) order[i] = i;
  std::stable_sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) {
    const std::size_t oa = impl_->children[a]->order;
    const std::size_t ob = impl_->children[b]->order;
    return oa != ob ? oa > ob : a > b;
  });
  for (const std::size_t i : order) {
    Child& c = *impl_->children[i];
    if (c.group_done) continue;
    impl_->stop_child(lock, c, hurrying, signals_at_start);
  }
}

std::vector<ChildExit> Supervisor::exits() const {
  std::lock_guard lock(impl_->mu);
  return impl_->all;
}

void Supervisor::log(std::string_view line) { impl_->say(line); }

void Supervisor::reserve_name_width(std::size_t width) {
  std::lock_guard lock(impl_->mu);
  impl_->name_width = std::max(impl_->name_width, width);
}

void Supervisor::set_report_printer(const std::string& name) {
  std::lock_guard lock(impl_->mu);
  for (const auto& c : impl_->children) {
    if (!c->reaped && c->name == name) impl_->report_printer = c.get();
  }
}

// ---- what is shown -------------------------------------------------------------------------

bool is_report_line(std::string_view process, std::string_view line) {
  if (process.empty() || line.size() <= process.size() + 2 || !line.starts_with(process) ||
      line.substr(process.size(), 2) != ": ")
    return false;
  line.remove_prefix(process.size() + 2);
  for (const std::string_view severity : {"debug", "info", "warning", "error", "fatal"}) {
    if (line.starts_with(severity) && line.substr(severity.size()).starts_with(": ")) return true;
  }
  return false;
}

bool shows_on_console(std::string_view child, bool from_stderr, std::string_view line,
                      bool printer_running) {
  return !(printer_running && from_stderr && is_report_line(child, line));
}

// ---- stop signals --------------------------------------------------------------------------

void install_stop_signal_handlers() {
  std::lock_guard lock(g_install_mutex);
  if (g_installed) return;
  auto [r, w] = make_pipe(O_NONBLOCK);
  g_signal_pipe_r.store(r.release());
  g_signal_pipe_w.store(w.release());

  struct sigaction sa {};
  sa.sa_handler = on_stop_signal;
  ::sigemptyset(&sa.sa_mask);
  sa.sa_flags = SA_RESTART;
  for (int sig : {SIGINT, SIGTERM, SIGHUP}) {
    if (::sigaction(sig, &sa, nullptr) != 0) {
      throw Error(
          fmt::format("cannot install a handler for {}: {}", signal_name(sig), errno_text(errno)));
    }
  }
  g_installed = true;
}

int stop_signal() { return g_first_stop_signal.load(); }

int stop_signal_count() { return g_stop_signal_count.load(); }

}  // namespace mrroc::launch
