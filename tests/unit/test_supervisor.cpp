#include "supervisor.hpp"

#include "launch_plan.hpp"
#include "log_file.hpp"
#include "status_board.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <mutex>
#include <ostream>
#include <regex>
#include <sstream>
#include <streambuf>
#include <string>
#include <thread>
#include <vector>

#include <fmt/format.h>

#include "mrroc/core/error.hpp"
#include "mrroc/core/process.hpp"

namespace mrroc::launch {
namespace {

using namespace std::chrono_literals;
using std::chrono::milliseconds;
using testing::HasSubstr;

/// An ostream target that can be read while the supervisor's thread writes to it.
class CaptureBuf : public std::streambuf {
 public:
  [[nodiscard]] std::string text() const {
    std::lock_guard lock(mu_);
    return data_;
  }

 protected:
  int_type overflow(int_type ch) override {
    if (!traits_type::eq_int_type(ch, traits_type::eof())) {
      std::lock_guard lock(mu_);
      data_ += traits_type::to_char_type(ch);
    }
    return traits_type::not_eof(ch);
  }
  std::streamsize xsputn(const char* s, std::streamsize n) override {
    std::lock_guard lock(mu_);
    data_.append(s, static_cast<std::size_t>(n));
    return n;
  }

 private:
  mutable std::mutex mu_;
  std::string data_;
};

class Capture {
 public:
  std::ostream& stream() { return os_; }
  [[nodiscard]] std::string text() const { return buf_.text(); }
  /// Waits until a line "HH:MM:SS.mmm [name] content" (with any padding after the name) was
  /// written.
  bool wait_for_line(const std::string& name, const std::string& content,
                     milliseconds timeout = 5000ms) const {
    const auto deadline = std::chrono::steady_clock::now() + timeout;
    while (std::chrono::steady_clock::now() < deadline) {
      if (has_line(name, content)) return true;
      std::this_thread::sleep_for(5ms);
    }
    return false;
  }
  /// True if a line "HH:MM:SS.mmm [name] content" was written (`content` is a regex).
  [[nodiscard]] bool has_line(const std::string& name, const std::string& content) const {
    const std::regex re("(^|\n)\\d\\d:\\d\\d:\\d\\d\\.\\d{3} \\[" + name + "\\] +" + content +
                        "\n");
    return std::regex_search(text(), re);
  }
  /// Waits until the output contains `needle`.
  bool wait_for(const std::string& needle, milliseconds timeout = 5000ms) const {
    const auto deadline = std::chrono::steady_clock::now() + timeout;
    while (std::chrono::steady_clock::now() < deadline) {
      if (text().find(needle) != std::string::npos) return true;
      std::this_thread::sleep_for(5ms);
    }
    return false;
  }

 private:
  CaptureBuf buf_;
  std::ostream os_{&buf_};
};

ChildSpec sh(const std::string& name, const std::string& script,
             milliseconds grace = milliseconds(3000)) {
  ChildSpec spec;
  spec.name = name;
  spec.argv = {"/bin/sh", "-c", script};
  spec.stop_grace = grace;
  return spec;
}

/// Collects exits until there are `n` of them (or the timeout passes).
std::vector<ChildExit> collect(Supervisor& s, std::size_t n, milliseconds timeout = 5000ms) {
  std::vector<ChildExit> got;
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  while (got.size() < n && std::chrono::steady_clock::now() < deadline) {
    for (auto& e : s.wait_events(100ms)) got.push_back(std::move(e));
  }
  return got;
}

const ChildExit* find_exit(const std::vector<ChildExit>& exits, const std::string& name) {
  for (const auto& e : exits) {
    if (e.name == name) return &e;
  }
  return nullptr;
}

bool alive(pid_t pid) { return ::kill(pid, 0) == 0 || errno != ESRCH; }

bool group_gone(pid_t pgid) { return ::kill(-pgid, 0) == -1 && errno == ESRCH; }

std::size_t position(const std::string& text, const std::string& needle) {
  const std::size_t pos = text.find(needle);
  EXPECT_NE(pos, std::string::npos) << "missing \"" << needle << "\" in:\n" << text;
  return pos;
}

TEST(Supervisor, PrefixesOutputOfEachChildIncludingStderrAndPartialLines) {
  Capture cap;
  {
    Supervisor s(cap.stream());
    s.start(sh("one", "echo hello from one; echo oops >&2; printf partial-one"));
    s.start(sh("two", "echo hello from two; printf 'no newline' >&2"));
    const auto exits = collect(s, 2);
    ASSERT_EQ(exits.size(), 2u);
  }
  const std::string text = cap.text();
  EXPECT_THAT(text, HasSubstr("[one] hello from one\n"));
  EXPECT_THAT(text, HasSubstr("[one] oops\n"));
  EXPECT_THAT(text, HasSubstr("[one] partial-one\n"));
  EXPECT_THAT(text, HasSubstr("[two] hello from two\n"));
  EXPECT_THAT(text, HasSubstr("[two] no newline\n"));
  // The partial line comes before the exit line.
  EXPECT_LT(position(text, "[one] partial-one"), position(text, "one exited with code 0"));
}

TEST(Supervisor, PadsNamesAndNeverMixesLines) {
  Capture cap;
  {
    Supervisor s(cap.stream());
    s.reserve_name_width(6);
    const std::string loop =
        "i=0; while [ $i -lt 300 ]; do echo \"line $i of $0\"; echo \"err $i of $0\" >&2; "
        "i=$((i+1)); done";
    ChildSpec a = sh("a", loop);
    a.argv.push_back("a");  // $0
    ChildSpec b = sh("bb", loop);
    b.argv.push_back("bb");
    s.start(a);
    s.start(b);
    ASSERT_EQ(collect(s, 2).size(), 2u);
  }
  const std::string text = cap.text();
  // "[a]" padded to the reserved width + 2 brackets, then one space.
  EXPECT_THAT(text, HasSubstr("[a]      line 0 of a\n"));
  EXPECT_THAT(text, HasSubstr("[bb]     err 299 of bb\n"));

  // Every line starts with the time it was written.
  const std::regex stamp(R"(\d\d:\d\d:\d\d\.\d{3} )");
  const std::regex child_line(R"(\[(a|bb)\] +(line|err) \d+ of (a|bb))");
  std::istringstream lines(text);
  std::string line;
  int child_lines = 0;
  while (std::getline(lines, line)) {
    std::smatch m;
    ASSERT_TRUE(std::regex_search(line, m, stamp, std::regex_constants::match_continuous)) << line;
    line.erase(0, static_cast<std::size_t>(m.length()));
    if (line.front() != '[') continue;
    ASSERT_TRUE(std::regex_match(line, m, child_line)) << line;
    EXPECT_EQ(m[1], m[3]) << line;
    ++child_lines;
  }
  EXPECT_EQ(child_lines, 4 * 300);
}

TEST(Supervisor, ReportsExitCodesAndSignals) {
  Capture cap;
  Supervisor s(cap.stream());
  const pid_t ok_pid = s.start(sh("ok", "exit 0"));
  s.start(sh("three", "exit 3"));
  s.start(sh("usr1", "kill -USR1 $$; sleep 5"));
  const auto exits = collect(s, 3);
  ASSERT_EQ(exits.size(), 3u);

  const ChildExit* ok = find_exit(exits, "ok");
  ASSERT_NE(ok, nullptr);
  EXPECT_EQ(ok->exit_code, 0);
  EXPECT_EQ(ok->signal, 0);
  EXPECT_EQ(ok->pid, ok_pid);
  EXPECT_EQ(ok->state(), ChildState::exited);
  EXPECT_FALSE(ok->forced);

  const ChildExit* three = find_exit(exits, "three");
  ASSERT_NE(three, nullptr);
  EXPECT_EQ(three->exit_code, 3);
  EXPECT_EQ(three->signal, 0);

  const ChildExit* usr1 = find_exit(exits, "usr1");
  ASSERT_NE(usr1, nullptr);
  EXPECT_EQ(usr1->signal, SIGUSR1);
  EXPECT_EQ(usr1->exit_code, 128 + SIGUSR1);
  EXPECT_EQ(usr1->state(), ChildState::killed);

  EXPECT_EQ(s.state_of("three"), ChildState::exited);
  EXPECT_EQ(s.state_of("usr1"), ChildState::killed);
  EXPECT_EQ(s.state_of("nobody"), std::nullopt);
  EXPECT_FALSE(s.is_running("ok"));
  EXPECT_FALSE(s.pid_of("ok").has_value());
  EXPECT_FALSE(s.any_running());
  EXPECT_EQ(s.exits().size(), 3u);
  EXPECT_TRUE(s.wait_events(0ms).empty());  // already returned once

  const std::string text = cap.text();
  EXPECT_THAT(text, HasSubstr("three exited with code 3\n"));
  EXPECT_THAT(text, HasSubstr("usr1 killed by signal 10 (SIGUSR1)\n"));
}

TEST(Supervisor, StopAllStopsInReverseStartOrder) {
  Capture cap;
  Supervisor s(cap.stream());
  std::vector<pid_t> pids;
  for (const std::string name : {"a", "b", "c"}) {
    pids.push_back(s.start(
        sh(name, "trap 'echo bye " + name + "; exit 0' TERM; echo ready; sleep 100 & wait")));
  }
  for (const std::string name : {"a", "b", "c"}) {
    ASSERT_TRUE(cap.wait_for_line(name, "ready")) << cap.text();
    EXPECT_TRUE(s.is_running(name));
  }
  EXPECT_EQ(s.pid_of("b"), pids[1]);
  EXPECT_EQ(::getpgid(pids[1]), pids[1]);  // own process group

  s.stop_all();
  const std::string text = cap.text();
  EXPECT_LT(position(text, "stopping c (pid"), position(text, "[c] bye c"));
  EXPECT_LT(position(text, "[c] bye c"), position(text, "c exited with code 0"));
  EXPECT_LT(position(text, "c exited with code 0"), position(text, "stopping b (pid"));
  EXPECT_LT(position(text, "[b] bye b"), position(text, "[a] bye a"));
  EXPECT_LT(position(text, "b exited with code 0"), position(text, "stopping a (pid"));

  const auto exits = s.exits();
  ASSERT_EQ(exits.size(), 3u);
  EXPECT_EQ(exits[0].name, "c");
  EXPECT_EQ(exits[1].name, "b");
  EXPECT_EQ(exits[2].name, "a");
  for (const auto& e : exits) {
    EXPECT_EQ(e.exit_code, 0);
    EXPECT_FALSE(e.forced);
  }
  for (pid_t pid : pids) EXPECT_TRUE(group_gone(pid));
  EXPECT_EQ(s.wait_events(0ms).size(), 3u);  // stop_all's exits are collected too
}

TEST(Supervisor, KillsChildIgnoringTermAfterGrace) {
  Capture cap;
  Supervisor s(cap.stream());
  const pid_t pid = s.start(sh("stubborn", "trap '' TERM; echo ready; sleep 100", 200ms));
  ASSERT_TRUE(cap.wait_for("[stubborn] ready\n"));

  const auto t0 = std::chrono::steady_clock::now();
  s.stop_all();
  const auto took = std::chrono::steady_clock::now() - t0;
  EXPECT_GE(took, 200ms);
  EXPECT_LT(took, 3000ms);

  const auto exits = s.exits();
  ASSERT_EQ(exits.size(), 1u);
  EXPECT_EQ(exits[0].signal, SIGKILL);
  EXPECT_TRUE(exits[0].forced);
  EXPECT_EQ(exits[0].state(), ChildState::killed);
  EXPECT_EQ(s.state_of("stubborn"), ChildState::killed);
  EXPECT_THAT(cap.text(), HasSubstr("killed stubborn after 200 ms\n"));
  EXPECT_TRUE(group_gone(pid));
}

TEST(Supervisor, LeavesNoProcessOfAChildsGroup) {
  Capture cap;
  Supervisor s(cap.stream());
  // The grandchild dies with the group's SIGTERM.
  const pid_t plain = s.start(sh("plain", "sleep 100 & echo ready; wait"));
  // The grandchild ignores SIGTERM while the child exits on it.
  const pid_t stubborn = s.start(
      sh("stubborn", "(trap '' TERM; sleep 100) & trap 'exit 0' TERM; echo ready; wait", 200ms));
  // The child is gone already, its background grandchild is not.
  const pid_t orphan = s.start(sh("orphan", "sleep 100 & echo ready"));
  for (const std::string name : {"plain", "stubborn", "orphan"}) {
    ASSERT_TRUE(cap.wait_for_line(name, "ready")) << cap.text();
  }
  ASSERT_EQ(collect(s, 1).size(), 1u);  // orphan's leader
  EXPECT_FALSE(group_gone(orphan));

  s.stop_all();
  EXPECT_TRUE(group_gone(plain));
  EXPECT_TRUE(group_gone(stubborn));
  EXPECT_TRUE(group_gone(orphan));
  const std::string text = cap.text();
  EXPECT_THAT(text, HasSubstr("stubborn exited with code 0\n"));
  EXPECT_THAT(text, HasSubstr("killed the remaining processes of stubborn"));
  EXPECT_THAT(text, HasSubstr("stopping the remaining processes of orphan"));
}

TEST(Supervisor, MissingExecutableThrowsNamingThePath) {
  Capture cap;
  Supervisor s(cap.stream());
  try {
    s.start(ChildSpec{.name = "edp/none", .argv = {"/nonexistent/mrroc-no-such-program"}});
    FAIL() << "no exception";
  } catch (const mrroc::Error& e) {
    EXPECT_THAT(e.what(), HasSubstr("/nonexistent/mrroc-no-such-program"));
    EXPECT_THAT(e.what(), HasSubstr("No such file or directory"));
    EXPECT_THAT(e.what(), HasSubstr("edp/none"));
  }
  try {
    s.start(ChildSpec{.name = "bare", .argv = {"mrroc-no-such-program-in-path"}});
    FAIL() << "no exception";
  } catch (const mrroc::Error& e) {
    EXPECT_THAT(e.what(), HasSubstr("mrroc-no-such-program-in-path"));
  }
  // exec itself fails (not executable): reported through the close-on-exec pipe.
  char path[] = "/tmp/mrroc-test-noexec-XXXXXX";
  const int fd = ::mkstemp(path);  // mode 0600
  ASSERT_GE(fd, 0);
  ::close(fd);
  try {
    s.start(ChildSpec{.name = "noexec", .argv = {path}});
    ADD_FAILURE() << "no exception";
  } catch (const mrroc::Error& e) {
    EXPECT_THAT(e.what(), HasSubstr(std::string(path) + ": Permission denied"));
  }
  ::unlink(path);
  EXPECT_THROW(s.start(ChildSpec{.name = "empty"}), mrroc::Error);
  EXPECT_FALSE(s.any_running());
  EXPECT_TRUE(s.exits().empty());
}

TEST(Supervisor, RejectsADuplicateRunningName) {
  Capture cap;
  Supervisor s(cap.stream());
  s.start(sh("dup", "sleep 100", 200ms));
  EXPECT_THROW(s.start(sh("dup", "true")), mrroc::Error);
}

TEST(Supervisor, SearchesPathAndPassesEnvironmentAndDevNullStdin) {
  Capture cap;
  {
    Supervisor s(cap.stream());
    s.start(ChildSpec{.name = "env",
                      .argv = {"sh", "-c", "echo \"var=$MRROC_TEST_VAR\"; cat; echo after-cat"},
                      .env = {"MRROC_TEST_VAR=42"}});
    // Only 0, 1 and 2 are open in the child: no pipe of the launcher or of other children.
    s.start(sh("fds", "sleep 0.2; ls /proc/$$/fd | tr '\\n' ' '; echo"));
    ASSERT_EQ(collect(s, 2).size(), 2u);
  }
  const std::string text = cap.text();
  EXPECT_THAT(text, HasSubstr("[env] var=42\n"));
  EXPECT_THAT(text, HasSubstr("[env] after-cat\n"));
  EXPECT_THAT(text, HasSubstr("[fds] 0 1 2 \n"));
}

TEST(Supervisor, WaitEventsTimesOutAndWakesOnStopRequest) {
  Capture cap;
  Supervisor s(cap.stream());
  auto t0 = std::chrono::steady_clock::now();
  EXPECT_TRUE(s.wait_events(100ms).empty());
  EXPECT_GE(std::chrono::steady_clock::now() - t0, 100ms);
  EXPECT_FALSE(s.stop_requested());

  std::thread stopper([&] {
    std::this_thread::sleep_for(50ms);
    s.request_stop();
  });
  t0 = std::chrono::steady_clock::now();
  EXPECT_TRUE(s.wait_events(5000ms).empty());
  EXPECT_LT(std::chrono::steady_clock::now() - t0, 2000ms);
  stopper.join();
  EXPECT_TRUE(s.stop_requested());
  EXPECT_TRUE(s.wait_events(5000ms).empty());  // returns at once while stop is requested

  s.start(sh("quick", "exit 7"));
  const auto exits = s.wait_events(5000ms);  // an exit is noticed promptly
  if (exits.empty()) {
    EXPECT_EQ(collect(s, 1).at(0).exit_code, 7);
  } else {
    EXPECT_EQ(exits.at(0).exit_code, 7);
  }
}

TEST(Supervisor, DestructorLeavesNoChildAlive) {
  Capture cap;
  std::vector<pid_t> pids;
  {
    Supervisor s(cap.stream());
    pids.push_back(s.start(sh("sleeper", "echo ready; sleep 100")));
    pids.push_back(s.start(sh("stubborn", "trap '' TERM; echo ready; sleep 100", 200ms)));
    pids.push_back(s.start(sh("done", "echo ready")));
    pids.push_back(s.start(sh("bg", "sleep 100 & echo ready; wait")));
    for (const std::string name : {"sleeper", "stubborn", "done", "bg"}) {
      ASSERT_TRUE(cap.wait_for_line(name, "ready")) << cap.text();
    }
    for (pid_t pid : pids) EXPECT_EQ(::getpgid(pid) == pid || !alive(pid), true);
  }
  for (pid_t pid : pids) {
    EXPECT_FALSE(alive(pid)) << pid;
    EXPECT_TRUE(group_gone(pid)) << pid;
  }
}

/// True if `pid` is gone or a zombie (reaping it if it became our child).
bool dead_or_zombie(pid_t pid) {
  int status = 0;
  ::waitpid(pid, &status, WNOHANG);
  std::ifstream stat("/proc/" + std::to_string(pid) + "/stat");
  std::string line;
  if (!std::getline(stat, line)) return true;
  const std::size_t paren = line.rfind(')');
  return paren != std::string::npos && paren + 2 < line.size() && line[paren + 2] == 'Z';
}

TEST(Supervisor, ChildrenDieWithAKilledLauncher) {
  int fds[2];
  ASSERT_EQ(::pipe(fds), 0);
  const pid_t launcher = ::fork();
  ASSERT_GE(launcher, 0);
  if (launcher == 0) {
    ::close(fds[0]);
    Capture cap;
    Supervisor s(cap.stream());
    const pid_t child = s.start(ChildSpec{.name = "sleeper", .argv = {"/bin/sleep", "100"}});
    [[maybe_unused]] const ssize_t n = ::write(fds[1], &child, sizeof child);
    ::pause();
    ::_exit(1);
  }
  ::close(fds[1]);
  pid_t child = -1;
  ASSERT_EQ(::read(fds[0], &child, sizeof child), static_cast<ssize_t>(sizeof child));
  ::close(fds[0]);
  EXPECT_FALSE(dead_or_zombie(child));
  ::kill(launcher, SIGKILL);
  int status = 0;
  ASSERT_EQ(::waitpid(launcher, &status, 0), launcher);

  const auto deadline = std::chrono::steady_clock::now() + 3000ms;
  while (!dead_or_zombie(child) && std::chrono::steady_clock::now() < deadline) {
    std::this_thread::sleep_for(10ms);
  }
  EXPECT_TRUE(dead_or_zombie(child));
  if (!dead_or_zombie(child)) ::kill(child, SIGKILL);
}

TEST(Supervisor, AKilledLauncherTermsItsChildrenAndTheirGuardsKillOnesThatStayTooLong) {
  // kill -9 of the launcher: each child gets SIGTERM (PR_SET_PDEATHSIG), so that an EDP ramps
  // its robot down; a child still there after its stop_grace is SIGKILLed by its stop guard.
  const std::string dir = ::testing::TempDir() + "/mrroc-pdeath-" + std::to_string(::getpid());
  std::filesystem::create_directories(dir);
  int fds[2];
  ASSERT_EQ(::pipe(fds), 0);
  const pid_t launcher = ::fork();
  ASSERT_GE(launcher, 0);
  if (launcher == 0) {
    ::close(fds[0]);
    Capture cap;
    Supervisor s(cap.stream());
    pid_t pids[2];
    pids[0] = s.start(ChildSpec{.name = "polite",
                                .argv = {"/bin/sh", "-c",
                                         "trap 'echo term > " + dir +
                                             "/polite; exit 0' TERM; while :; do sleep 0.02; done"},
                                .stop_grace = 1500ms});
    pids[1] = s.start(ChildSpec{
        .name = "stubborn",
        .argv = {"/bin/sh", "-c",
                 "trap 'echo term > " + dir + "/stubborn' TERM; while :; do sleep 0.02; done"},
        .stop_grace = 500ms});
    [[maybe_unused]] const ssize_t n = ::write(fds[1], pids, sizeof pids);
    ::pause();
    ::_exit(1);
  }
  ::close(fds[1]);
  pid_t pids[2] = {-1, -1};
  ASSERT_EQ(::read(fds[0], pids, sizeof pids), static_cast<ssize_t>(sizeof pids));
  ::close(fds[0]);
  std::this_thread::sleep_for(200ms);  // the shells have set their traps
  ::kill(launcher, SIGKILL);
  const auto killed = std::chrono::steady_clock::now();
  int status = 0;
  ASSERT_EQ(::waitpid(launcher, &status, 0), launcher);
  double gone_ms[2] = {-1, -1};
  while (std::chrono::steady_clock::now() < killed + 5000ms && (gone_ms[0] < 0 || gone_ms[1] < 0)) {
    for (int i = 0; i < 2; ++i)
      if (gone_ms[i] < 0 && dead_or_zombie(pids[i]))
        gone_ms[i] =
            std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - killed)
                .count();
    std::this_thread::sleep_for(5ms);
  }
  for (const pid_t p : pids)
    if (!dead_or_zombie(p)) ::kill(-p, SIGKILL);
  std::printf(
      "launcher killed: polite child gone after %.0f ms, stubborn child (grace 500 ms) "
      "after %.0f ms\n",
      gone_ms[0], gone_ms[1]);
  EXPECT_TRUE(std::filesystem::exists(dir + "/polite")) << "the child got no SIGTERM";
  EXPECT_TRUE(std::filesystem::exists(dir + "/stubborn")) << "the child got no SIGTERM";
  EXPECT_GE(gone_ms[0], 0.0);
  EXPECT_LT(gone_ms[0], 400.0);  // ended by itself on SIGTERM, well before its grace
  EXPECT_GE(gone_ms[1], 450.0);  // not before its grace
  EXPECT_LT(gone_ms[1], 1500.0);
  std::filesystem::remove_all(dir);
}

/// Runs `body` in a forked copy of this (single-threaded) test process, so that the signal
/// handlers and the process-wide stop flag do not affect the other tests. `body` returns an
/// empty string on success, else a description of the failure.
std::string in_subprocess(std::string (*body)()) {
  int fds[2];
  if (::pipe(fds) != 0) return "pipe failed";
  const pid_t pid = ::fork();
  if (pid == 0) {
    ::close(fds[0]);
    std::string failure;
    try {
      failure = body();
    } catch (const std::exception& e) {
      failure = std::string("exception: ") + e.what();
    }
    if (!failure.empty()) {
      [[maybe_unused]] const ssize_t n = ::write(fds[1], failure.data(), failure.size());
    }
    ::_exit(failure.empty() ? 0 : 1);
  }
  ::close(fds[1]);
  std::string failure;
  char buf[512];
  ssize_t n = 0;
  while ((n = ::read(fds[0], buf, sizeof buf)) > 0)
    failure.append(buf, static_cast<std::size_t>(n));
  ::close(fds[0]);
  int status = 0;
  ::waitpid(pid, &status, 0);
  if (failure.empty() && !(WIFEXITED(status) && WEXITSTATUS(status) == 0)) {
    failure = "subprocess failed with status " + std::to_string(status);
  }
  return failure;
}

TEST(Supervisor, StopSignalsWakeWaitEventsAndASecondOneSkipsTheGrace) {
  const std::string failure = in_subprocess(+[]() -> std::string {
    install_stop_signal_handlers();
    Capture cap;
    Supervisor s(cap.stream());
    s.start(sh("stubborn", "trap '' TERM; echo ready; sleep 100", 10000ms));
    if (!cap.wait_for("[stubborn] ready\n")) return "child not ready";
    if (s.stop_requested() || stop_signal() != 0) return "stop requested too early";

    std::thread first([] {
      std::this_thread::sleep_for(50ms);
      ::kill(::getpid(), SIGINT);
    });
    auto t0 = std::chrono::steady_clock::now();
    s.wait_events(5000ms);
    first.join();
    if (std::chrono::steady_clock::now() - t0 > 2000ms) return "SIGINT did not wake wait_events";
    if (!s.stop_requested()) return "stop not requested after SIGINT";
    if (stop_signal() != SIGINT || stop_signal_count() != 1) return "wrong stop signal";

    std::thread second([] {
      std::this_thread::sleep_for(300ms);
      ::kill(::getpid(), SIGTERM);
    });
    t0 = std::chrono::steady_clock::now();
    s.stop_all();
    second.join();
    if (std::chrono::steady_clock::now() - t0 > 3000ms) return "second signal did not hurry";
    const auto exits = s.exits();
    if (exits.size() != 1 || exits[0].signal != SIGKILL || !exits[0].forced) {
      return "stubborn child not killed:\n" + cap.text();
    }
    if (cap.text().find("another stop signal") == std::string::npos) return cap.text();
    return "";
  });
  EXPECT_EQ(failure, "");
}

// ---- stop signal, log files, restarts ------------------------------------------------------

std::string slurp(const std::filesystem::path& p) {
  std::ifstream in(p);
  std::stringstream text;
  text << in.rdbuf();
  return text.str();
}

std::filesystem::path temp_dir(const std::string& what) {
  const auto dir = std::filesystem::temp_directory_path() /
                   ("mrroc-supervisor-" + what + "-" + std::to_string(::getpid()));
  std::filesystem::remove_all(dir);
  return dir;
}

TEST(Supervisor, StopsWithTheChildsStopSignal) {
  Capture cap;
  Supervisor s(cap.stream());
  ChildSpec spec = sh("int",
                      "trap 'echo got INT; exit 7' INT; trap 'echo got TERM; exit 8' TERM; "
                      "echo ready; sleep 100 & wait");
  spec.stop_signal = SIGINT;
  s.start(spec);
  ASSERT_TRUE(cap.wait_for_line("int", "ready")) << cap.text();
  s.stop_all();
  const std::string text = cap.text();
  EXPECT_THAT(text, HasSubstr("stopping int (pid"));
  EXPECT_THAT(text, HasSubstr(") with SIGINT\n"));
  EXPECT_THAT(text, HasSubstr("[int] got INT\n"));
  EXPECT_THAT(text, testing::Not(HasSubstr("got TERM")));
  ASSERT_EQ(s.exits().size(), 1u);
  EXPECT_EQ(s.exits()[0].exit_code, 7);
}

TEST(Supervisor, StopsAChildByClosingItsInput) {
  Capture cap;
  Supervisor s(cap.stream());
  // Reads its stdin to the end: /dev/null would end it at once, the pipe only when closed.
  ChildSpec spec =
      sh("reader",
         "trap 'echo got TERM; exit 8' TERM; echo ready; "
         "while read -r line; do echo \"read $line\"; done; echo input closed; exit 3");
  spec.stop_by_closing_input = true;
  s.start(spec);
  ASSERT_TRUE(cap.wait_for_line("reader", "ready")) << cap.text();
  std::this_thread::sleep_for(100ms);
  EXPECT_TRUE(s.is_running("reader")) << cap.text();
  s.stop_all();
  const std::string text = cap.text();
  EXPECT_THAT(text,
              testing::ContainsRegex("stopping reader \\(pid [0-9]+\\) by closing its input"));
  EXPECT_THAT(text, HasSubstr("[reader] input closed\n"));
  EXPECT_THAT(text, testing::Not(HasSubstr("got TERM")));
  EXPECT_THAT(text, testing::Not(HasSubstr("read ")));
  ASSERT_EQ(s.exits().size(), 1u);
  EXPECT_EQ(s.exits()[0].exit_code, 3);
  EXPECT_FALSE(s.exits()[0].forced);
}

TEST(Supervisor, AChildWithoutItsOwnInputReadsNothing) {
  Capture cap;
  Supervisor s(cap.stream());
  s.start(sh("devnull", "while read -r line; do echo \"read $line\"; done; echo input ended"));
  ASSERT_EQ(collect(s, 1).size(), 1u) << cap.text();
  EXPECT_THAT(cap.text(), HasSubstr("[devnull] input ended\n"));
}

TEST(Supervisor, RejectsAnInvalidStopSignal) {
  Capture cap;
  Supervisor s(cap.stream());
  ChildSpec spec = sh("bad", "true");
  spec.stop_signal = 0;
  EXPECT_THAT([&] { s.start(spec); },
              testing::ThrowsMessage<Error>(HasSubstr("stop signal 0 is not a signal number")));
  EXPECT_FALSE(s.any_running());
}

TEST(Supervisor, WritesEachChildsLinesWithTimeStampsToItsLogFile) {
  const auto dir = temp_dir("log");
  Capture cap;
  {
    Supervisor s(cap.stream());
    ChildSpec spec = sh("edp/x", "echo first; echo second >&2; exit 3");
    spec.log_file = dir / "edp_x.log";
    const pid_t pid = s.start(spec);
    ASSERT_EQ(collect(s, 1).size(), 1u);
    const std::string log = slurp(dir / "edp_x.log");
    const std::regex stamped(R"(\d{4}-\d\d-\d\dT\d\d:\d\d:\d\d\.\d{3}Z first\n)");
    EXPECT_TRUE(std::regex_search(log, stamped)) << log;
    EXPECT_THAT(log, HasSubstr("Z second\n"));
    EXPECT_THAT(log, HasSubstr("--- edp/x started (pid " + std::to_string(pid) + ")"));
    EXPECT_THAT(log, HasSubstr("--- edp/x (pid " + std::to_string(pid) + ") exited with code 3"));
  }
  // The console output is unchanged.
  EXPECT_THAT(cap.text(), HasSubstr("[edp/x] first\n"));
  std::filesystem::remove_all(dir);
}

TEST(Supervisor, TellsReportLinesFromOtherOutput) {
  for (const char* severity : {"debug", "info", "warning", "error", "fatal"})
    EXPECT_TRUE(is_report_line("ecp/irb6", std::string("ecp/irb6: ") + severity + ": text"))
        << severity;
  EXPECT_TRUE(is_report_line("mp", "mp: fatal: ecp/irb6: VSP 'wrist_force': stale"));
  EXPECT_TRUE(is_report_line("ecp/irb6", "ecp/irb6: info: "));  // an empty text
  // Another process' name, a longer name, not a severity, not the Reporter's punctuation.
  EXPECT_FALSE(is_report_line("ecp/irb6", "edp/irb6: info: driven by 'ecp/irb6#23'"));
  EXPECT_FALSE(is_report_line("ecp/irb6", "ecp/irb6x: info: text"));
  EXPECT_FALSE(is_report_line("emu", "mrroc-axis-emu: error: cannot open the scene"));
  EXPECT_FALSE(is_report_line("ecp/irb6", "ecp/irb6: notice: text"));
  EXPECT_FALSE(is_report_line("ecp/irb6", "ecp/irb6: info text"));
  EXPECT_FALSE(is_report_line("ecp/irb6", "ecp/irb6: infos: text"));
  EXPECT_FALSE(is_report_line("ecp/irb6", "ecp/irb6: info:"));
  EXPECT_FALSE(is_report_line("ecp/irb6", "ecp/irb6:info: text"));
  EXPECT_FALSE(is_report_line("ecp/irb6", " ecp/irb6: info: text"));
  EXPECT_FALSE(is_report_line("ecp/irb6", "Segmentation fault"));
  EXPECT_FALSE(is_report_line("", ": info: text"));
}

TEST(Supervisor, HidesAChildsReportLinesOnlyWhileAReportPrinterRuns) {
  const std::string report = "ecp/irb6: info: task 'touch' started";
  EXPECT_FALSE(shows_on_console("ecp/irb6", true, report, true));
  EXPECT_TRUE(shows_on_console("ecp/irb6", true, report, false));  // no printer: shown
  EXPECT_TRUE(shows_on_console("ecp/irb6", false, report, true));  // stdout: not the Reporter's
  EXPECT_TRUE(shows_on_console("edp/irb6", true, report, true));   // not the child's own name
  EXPECT_TRUE(shows_on_console("emu", true, "mrroc-axis-emu: lock-step", true));
  EXPECT_FALSE(shows_on_console("srp", true, "srp: warning: dropped a message", true));
}

TEST(Supervisor, LeavesReportsToTheReportPrinterAndTheLogFileWhileThePrinterRuns) {
  const auto dir = temp_dir("printer");
  Capture cap;
  Supervisor s(cap.stream());
  // Child "ecp/rN": its own report, the same on stdout, another program's and another
  // process' line in the Reporter's form, on stderr.
  auto run = [&](int n) {
    const std::string name = fmt::format("ecp/r{}", n);
    ChildSpec spec = sh(name,
                        "echo \"$0: info: report\" >&2; echo \"$0: info: stdout\"; "
                        "echo \"mrroc-x: error: other\" >&2; echo \"edp/y: info: foreign\" >&2");
    spec.argv.push_back(name);  // $0
    spec.log_file = dir / fmt::format("r{}.log", n);
    s.start(spec);
    // The exit line comes after the child's last lines.
    EXPECT_TRUE(cap.wait_for(name + " exited with code 0")) << cap.text();
  };
  s.set_report_printer("srp");  // no such child: nothing changes
  run(1);
  const pid_t printer = s.start(sh("srp", "exec sleep 100"));
  s.set_report_printer("srp");
  run(2);
  ::kill(printer, SIGTERM);
  ASSERT_TRUE(cap.wait_for("srp killed by signal")) << cap.text();
  run(3);
  s.start(sh("srp", "exec sleep 100"));  // a new printer: not one until it is named
  run(4);
  s.stop_all();

  const std::string text = cap.text();
  for (int n = 1; n <= 4; ++n) {
    const std::string name = fmt::format("ecp/r{}", n);
    // Only while the printer ran is the report left off the console.
    EXPECT_EQ(cap.has_line(name, name + ": info: report"), n != 2) << text;
    EXPECT_TRUE(cap.has_line(name, name + ": info: stdout")) << text;
    EXPECT_TRUE(cap.has_line(name, "mrroc-x: error: other")) << text;
    EXPECT_TRUE(cap.has_line(name, "edp/y: info: foreign")) << text;
    // The log file has every line.
    EXPECT_THAT(slurp(dir / fmt::format("r{}.log", n)), HasSubstr("Z " + name + ": info: report\n"))
        << n;
  }
  std::filesystem::remove_all(dir);
}

TEST(Supervisor, AnUnusableLogFileStartsNothing) {
  Capture cap;
  Supervisor s(cap.stream());
  ChildSpec spec = sh("x", "sleep 10");
  spec.log_file = "/proc/self/nonexistent/x.log";
  EXPECT_THAT([&] { s.start(spec); },
              testing::ThrowsMessage<Error>(HasSubstr("/proc/self/nonexistent")));
  EXPECT_FALSE(s.any_running());
}

// Logs may hold what processes print (a generated console token among it): a log folder made
// by the launcher is 0700 and every log file 0600, one made earlier with wider rights included.
TEST(LogFile, IsItsOwnersAloneAndSoIsAFolderItMakes) {
  namespace fs = std::filesystem;
  const fs::path dir = temp_dir("logperm");
  const fs::path path = dir / "logs" / "ui.log";
  {
    LogFile log(path, 1000, 2);
    log.write_line("hello");
  }
  EXPECT_EQ(fs::status(dir / "logs").permissions() & fs::perms::all, fs::perms::owner_all);
  EXPECT_EQ(fs::status(path).permissions() & fs::perms::all,
            fs::perms::owner_read | fs::perms::owner_write);
  fs::permissions(path, fs::perms::group_read | fs::perms::others_read, fs::perm_options::add);
  { LogFile again(path, 1000, 2); }
  EXPECT_EQ(fs::status(path).permissions() & fs::perms::all,
            fs::perms::owner_read | fs::perms::owner_write);
}

// A log file that cannot be opened again after a rotation (here its folder has become a file)
// is reported once, tried again every retry interval, and reported when it is open again; the
// lines in between are counted as lost, the later ones written.
TEST(LogFile, AFileThatFailsToReopenIsReportedAndRetried) {
  namespace fs = std::filesystem;
  const fs::path dir = temp_dir("reopen");
  const fs::path folder = dir / "logs";
  const fs::path path = folder / "edp_irb6.log";
  LogFile log(path, 100, 1, std::chrono::milliseconds(100));
  log.write_line(std::string(100, 'a'));  // full: the next line rotates
  EXPECT_FALSE(log.take_notice());
  fs::remove_all(folder);
  std::ofstream(folder) << "not a folder\n";
  log.write_line("lost 1");
  const auto failed = log.take_notice();
  ASSERT_TRUE(failed);
  EXPECT_THAT(*failed, HasSubstr("cannot open the log file '" + path.string() + "'"));
  EXPECT_THAT(*failed, HasSubstr("its lines are lost until it opens (tried again every 0.1 s)"));
  log.write_line("lost 2");
  std::this_thread::sleep_for(std::chrono::milliseconds(150));
  log.write_line("lost 3");  // tried again: still a file there
  EXPECT_FALSE(log.take_notice()) << "a failure is reported once";
  EXPECT_EQ(log.lost_lines(), 3u);
  fs::remove(folder);
  log.write_line("lost 4");  // within the retry interval
  std::this_thread::sleep_for(std::chrono::milliseconds(150));
  log.write_line("written again");
  const auto back = log.take_notice();
  ASSERT_TRUE(back);
  EXPECT_EQ(*back, "the log file '" + path.string() + "' is open again (4 lines lost)");
  EXPECT_EQ(log.lost_lines(), 4u);
  EXPECT_THAT(slurp(path), HasSubstr("Z written again\n"));
  EXPECT_EQ(fs::status(folder).permissions() & fs::perms::all, fs::perms::owner_all);
  fs::remove_all(dir);
}

TEST(LogFile, RotatesWhenLargerThanTheLimitKeepingNFiles) {
  const auto dir = temp_dir("rotate");
  const auto path = dir / "srp.log";
  {
    LogFile log(path, 1000, 2);
    // Each line is 25 (time stamp + space) + 76 + 1 = 102 bytes: 10 lines fill a file.
    const std::string text(76, 'x');
    for (int i = 0; i < 35; ++i) log.write_line(text);
    EXPECT_EQ(log.rotations(), 3);
    EXPECT_EQ(log.errors(), 0);
  }
  EXPECT_TRUE(std::filesystem::exists(path));
  EXPECT_TRUE(std::filesystem::exists(LogFile::rotated(path, 1)));
  EXPECT_TRUE(std::filesystem::exists(LogFile::rotated(path, 2)));
  EXPECT_FALSE(std::filesystem::exists(LogFile::rotated(path, 3)));  // only 2 kept
  EXPECT_EQ(std::filesystem::file_size(LogFile::rotated(path, 1)), 1020u);
  EXPECT_EQ(std::filesystem::file_size(path), 510u);  // 35 = 3 * 10 + 5 lines
  {
    LogFile again(path, 1000, 0);  // appends; keep = 0 empties instead of rotating
    EXPECT_EQ(again.size(), 510u);
    for (int i = 0; i < 6; ++i) again.write_line(std::string(76, 'y'));
    EXPECT_EQ(again.rotations(), 1);
  }
  EXPECT_EQ(std::filesystem::file_size(path), 102u);
  EXPECT_EQ(slurp(path).find('x'), std::string::npos);
  std::filesystem::remove_all(dir);
}

TEST(Supervisor, ARestartedChildKeepsItsPlaceInTheStopOrder) {
  Capture cap;
  Supervisor s(cap.stream());
  const std::string body = "trap 'echo bye; exit 0' TERM; echo ready; sleep 100 & wait";
  s.start(sh("first", body));
  const pid_t old_pid = s.start(sh("second", "echo ready; exit 5"));
  s.start(sh("third", body));
  ASSERT_TRUE(cap.wait_for("second exited with code 5")) << cap.text();
  ASSERT_TRUE(cap.wait_for_line("third", "ready")) << cap.text();
  const pid_t new_pid = s.start(sh("second", body));  // the restart
  EXPECT_NE(new_pid, old_pid);
  EXPECT_EQ(s.pid_of("second"), new_pid);
  const auto deadline = std::chrono::steady_clock::now() + 5s;
  while (std::chrono::steady_clock::now() < deadline &&
         cap.text().find("[second] ready") == cap.text().rfind("[second] ready"))
    std::this_thread::sleep_for(5ms);
  ASSERT_NE(cap.text().find("[second] ready"), cap.text().rfind("[second] ready")) << cap.text();
  s.stop_all();
  const std::string text = cap.text();
  EXPECT_LT(position(text, "stopping third"), position(text, "stopping second"));
  EXPECT_LT(position(text, "stopping second"), position(text, "stopping first"));
}

// ---- the plan ------------------------------------------------------------------------------

TEST(LaunchPlan, QuotesForTheShell) {
  EXPECT_EQ(shell_quote("/usr/bin/mrroc-edp"), "/usr/bin/mrroc-edp");
  EXPECT_EQ(shell_quote("LCM_DEFAULT_URL=udpm://239.255.76.67:7667?ttl=1"),
            "'LCM_DEFAULT_URL=udpm://239.255.76.67:7667?ttl=1'");
  EXPECT_EQ(shell_quote("it's"), "'it'\\''s'");
  EXPECT_EQ(shell_quote(""), "''");
}

/// The words `/bin/sh` makes of `line` (as a remote shell reads the line ssh passes on).
std::vector<std::string> shell_words(const std::string& line) {
  FILE* out = ::popen(("printf '%s\\0' " + line).c_str(), "r");
  if (out == nullptr) return {"popen failed"};
  std::string text;
  char buf[4096];
  std::size_t n = 0;
  while ((n = std::fread(buf, 1, sizeof buf, out)) > 0) text.append(buf, n);
  if (::pclose(out) != 0) return {"sh failed on: " + line};
  std::vector<std::string> words;
  for (std::size_t at = 0; at < text.size();) {
    const std::size_t end = text.find('\0', at);
    words.push_back(text.substr(at, end - at));
    at = end + 1;
  }
  return words;
}

TEST(LaunchPlan, HostTemplatingQuotedAndAsSeparateWords) {
  HostConfig ssh;
  ssh.name = "cell";
  ssh.address = "robot@10.0.0.7";
  ssh.command = {"ssh", "-o", "BatchMode=yes", "{host}"};
  ssh.quote = true;
  EXPECT_EQ(host_command(ssh, {"LCM_DEFAULT_URL=udpm://x?ttl=1"},
                         {"/opt/mrroc-edp", "--config", "/a b.toml"}),
            (std::vector<std::string>{
                "ssh", "-o", "BatchMode=yes", "--", "robot@10.0.0.7",
                "exec sh -c " + shell_quote(remote_stop_script()) +
                    " mrroc-remote TERM 3 env 'LCM_DEFAULT_URL=udpm://x?ttl=1' /opt/mrroc-edp "
                    "--config '/a b.toml'"}));
  HostConfig netns;
  netns.name = "b";
  netns.address = "ns-b";
  netns.command = {"ip", "netns", "exec", "{host}"};
  netns.quote = false;
  EXPECT_EQ(
      host_command(netns, {"K=V"}, {"/bin/prog", "a b"}),
      (std::vector<std::string>{"ip", "netns", "exec", "ns-b", "env", "K=V", "/bin/prog", "a b"}));
  // quote = true for another command: one quoted word, no "--" and no remote stop script.
  netns.quote = true;
  EXPECT_EQ(host_command(netns, {"K=V"}, {"/bin/prog", "a b"}),
            (std::vector<std::string>{"ip", "netns", "exec", "ns-b", "env K=V /bin/prog 'a b'"}));
}

TEST(LaunchPlan, SshHostsPassTheCommandLineAsOneWordTheRemoteShellSplitsBack) {
  // A command of one's own, with quote = false in the struct: ssh is quoted all the same.
  HostConfig host;
  host.name = "cell";
  host.address = "robot@10.0.0.7";
  host.command = {"ssh", "-t", "-t", "-o", "BatchMode=yes", "{host}"};
  host.quote = false;
  const std::string value =
      "LCM_DEFAULT_URL=udpm://239.255.76.67:7667?ttl=1&x=1; echo hi 'q' $HOME";
  const std::vector<std::string> command{"/opt/bin/mrroc-edp", "--config", "/srv/a b/it's.toml",
                                         "--robot", "irb6 & false; $(echo injected) `true`"};
  const auto argv = host_command(host, {value}, command, RemoteStop{SIGINT, 1.2});
  ASSERT_EQ(argv.size(), 8u);
  EXPECT_EQ(
      (std::vector<std::string>(argv.begin(), argv.begin() + 7)),
      (std::vector<std::string>{"ssh", "-t", "-t", "-o", "BatchMode=yes", "--", "robot@10.0.0.7"}));
  std::vector<std::string> expected{"exec",         "sh",  "-c", std::string(remote_stop_script()),
                                    "mrroc-remote", "INT", "2",  "env",
                                    value};
  expected.insert(expected.end(), command.begin(), command.end());
  EXPECT_EQ(shell_words(argv[7]), expected);
}

TEST(LaunchPlan, SshGetsDoubleDashBeforeTheDestinationOnce) {
  HostConfig host;
  host.name = "cell";
  host.address = "cell-pc";
  host.command = {"/usr/bin/ssh", "-o", "HostKeyAlias={host}", "{host}"};
  auto front = [&] {
    auto argv = host_command(host, {}, {"prog"});
    argv.pop_back();
    return argv;
  };
  EXPECT_EQ(front(), (std::vector<std::string>{"/usr/bin/ssh", "-o", "HostKeyAlias=cell-pc", "--",
                                               "cell-pc"}));
  host.command = {"ssh", "-p", "2222", "--", "{host}"};
  EXPECT_EQ(front(), (std::vector<std::string>{"ssh", "-p", "2222", "--", "cell-pc"}));
  host.command = {"ip", "netns", "exec", "{host}"};
  host.quote = false;
  EXPECT_EQ(host_command(host, {}, {"prog"}),
            (std::vector<std::string>{"ip", "netns", "exec", "cell-pc", "prog"}));
  // ssh behind a wrapper (quote = false in the struct): "--" before the destination, the command
  // line one quoted word for the remote shell, whatever the wrapper's own words hold.
  host.command = {"sudo", "-u", "{host}", "ssh", "-o", "BatchMode=yes", "{host}"};
  const auto argv = host_command(host, {}, {"prog", "a b"});
  ASSERT_EQ(argv.size(), 9u);
  EXPECT_EQ((std::vector<std::string>(argv.begin(), argv.begin() + 8)),
            (std::vector<std::string>{"sudo", "-u", "cell-pc", "ssh", "-o", "BatchMode=yes", "--",
                                      "cell-pc"}));
  EXPECT_EQ(shell_words(argv[8]).back(), "a b");
  EXPECT_EQ(shell_words(argv[8]).front(), "exec");
}

TEST(LaunchPlan, OrderGroupsHostsLogFilesAndRecording) {
  const std::string text = R"(
[system]
name = "plan"
lcm_url = "udpm://239.255.76.67:7667?ttl=1"
[launch]
log_dir = "logs"
log_max_kb = 2
log_keep = 4
record = "run.lcmlog"
[[launch.host]]
name = "b"
command = ["ip", "netns", "exec", "{host}"]
quote = false
[srp]
restart = "on-failure"
required = false
[mp]
task = "start_and_wait"
stop_signal = "SIGINT"
[[robot]]
name = "irb6"
model = ")" + std::string(MRROC_SOURCE_DIR) +
                           R"(/robots/irb6"
[robot.edp]
plugin = "mujoco"
host = "b"
stop_grace_s = 1.5
[robot.ecp]
task = "visit_joint_poses"
host = "b"
group = "arm"
)";
  const auto config = parse_process_set(text, "/tmp/plan/set.toml");
  PlanOptions options;
  options.bin_dir = "/opt/bin";
  const auto plan = make_plan(config, options);
  ASSERT_EQ(plan.size(), 5u);
  EXPECT_EQ(plan[0].name, "record");
  EXPECT_EQ(plan[0].group, "record");
  EXPECT_FALSE(plan[0].options.required);
  EXPECT_EQ(plan[0].spec.stop_signal, SIGINT);
  EXPECT_FALSE(plan[0].reports_ready);
  EXPECT_EQ(plan[0].spec.argv,
            (std::vector<std::string>{"lcm-logger", "--lcm-url=udpm://239.255.76.67:7667?ttl=1",
                                      "--force", "--quiet", "/tmp/plan/run.lcmlog"}));
  EXPECT_EQ(plan[1].name, "srp");
  EXPECT_EQ(plan[1].options.restart, RestartPolicy::on_failure);
  EXPECT_EQ(plan[2].name, "edp/irb6");
  EXPECT_EQ(plan[2].group, "edp");
  EXPECT_EQ(plan[2].host, "b");
  EXPECT_EQ(plan[2].spec.stop_grace, 1500ms);
  EXPECT_EQ(
      plan[2].spec.argv,
      (std::vector<std::string>{
          "ip", "netns", "exec", "b", "env", "LCM_DEFAULT_URL=udpm://239.255.76.67:7667?ttl=1",
          "/opt/bin/mrroc-edp", "--config", "/tmp/plan/set.toml", "--robot", "irb6"}));
  EXPECT_TRUE(plan[2].spec.env.empty());             // the environment travels in the command
  EXPECT_FALSE(plan[2].spec.stop_by_closing_input);  // a wrapper that execs: the stop signal
  EXPECT_EQ(plan[2].spec.log_file, std::filesystem::path("/tmp/plan/logs/edp_irb6.log"));
  EXPECT_EQ(plan[2].spec.log_max_bytes, 2048u);
  EXPECT_EQ(plan[2].spec.log_keep, 4);
  EXPECT_EQ(plan[3].name, "ecp/irb6");
  EXPECT_EQ(plan[3].group, "arm");
  EXPECT_EQ(plan[4].name, "mp");
  EXPECT_EQ(plan[4].spec.stop_signal, SIGINT);
  EXPECT_EQ(plan[4].spec.argv,
            (std::vector<std::string>{"/opt/bin/mrroc-mp", "--config", "/tmp/plan/set.toml"}));
  EXPECT_EQ(plan[4].spec.env,
            (std::vector<std::string>{"LCM_DEFAULT_URL=udpm://239.255.76.67:7667?ttl=1"}));

  PlanOptions no_record = options;
  no_record.record = "/tmp/other.lcmlog";  // --record overrides [launch] record
  EXPECT_EQ(make_plan(config, no_record)[0].spec.argv.back(), "/tmp/other.lcmlog");
}

TEST(LaunchPlan, TheWebConsoleStartsAfterTheEcpsAndBeforeTheMp) {
  const std::string text = R"(
[system]
name = "ui"
[ui]
web = true
port = 8123
[mp]
task = "start_and_wait"
[[robot]]
name = "irb6"
model = ")" + std::string(MRROC_SOURCE_DIR) +
                           R"(/robots/irb6"
[robot.edp]
plugin = "mujoco"
[robot.ecp]
task = "visit_joint_poses"
)";
  PlanOptions options;
  options.bin_dir = "/opt/bin";
  const auto plan = make_plan(parse_process_set(text, "/tmp/ui/set.toml"), options);
  ASSERT_EQ(plan.size(), 5u);
  EXPECT_EQ(plan[2].name, "ecp/irb6");
  EXPECT_EQ(plan[3].name, "ui");
  EXPECT_EQ(plan[3].group, "ui");
  EXPECT_TRUE(plan[3].reports_ready);
  EXPECT_EQ(plan[3].spec.argv, (std::vector<std::string>{"/opt/bin/mrroc-ui", "serve", "--config",
                                                         "/tmp/ui/set.toml"}));
  EXPECT_EQ(plan[4].name, "mp");
}

TEST(LaunchPlan, ProcessesOnSshHostsStopByTheirInput) {
  const std::string text = R"(
[system]
name = "ssh"
[[launch.host]]
name = "cell"
address = "robot@10.0.0.7"
[mp]
task = "start_and_wait"
host = "cell"
stop_signal = "SIGINT"
stop_grace_s = 4.5
[[robot]]
name = "irb6"
model = ")" + std::string(MRROC_SOURCE_DIR) +
                           R"(/robots/irb6"
[robot.edp]
plugin = "mujoco"
[robot.ecp]
task = "visit_joint_poses"
)";
  PlanOptions options;
  options.bin_dir = "/opt/bin";
  const auto plan = make_plan(parse_process_set(text, "/tmp/ssh/set.toml"), options);
  ASSERT_EQ(plan.size(), 4u);
  EXPECT_EQ(plan[3].name, "mp");
  EXPECT_TRUE(plan[3].spec.stop_by_closing_input);
  EXPECT_EQ(plan[3].spec.stop_grace, 4500ms);
  ASSERT_EQ(plan[3].spec.argv.size(), 6u);
  EXPECT_EQ(plan[3].spec.argv[3], "--");
  EXPECT_EQ(plan[3].spec.argv[4], "robot@10.0.0.7");
  // The remote side sends the process' stop signal, and SIGKILL after its grace (rounded up).
  const auto words = shell_words(plan[3].spec.argv[5]);
  ASSERT_GE(words.size(), 7u);
  EXPECT_EQ(words[5], "INT");
  EXPECT_EQ(words[6], "5");
  EXPECT_FALSE(plan[2].spec.stop_by_closing_input);  // ecp/irb6 runs here
}

/// A stand-in for ssh with this computer as the remote host, as far as stopping goes: the
/// remote command line runs in a session (and process group) of its own, as sshd starts it,
/// and gets this program's input through a pipe, as through the connection: it ends when
/// this program ends or its own input ends.
void write_local_ssh(const std::filesystem::path& file) {
  std::ofstream(file) << R"(#!/bin/sh
while [ "$#" -gt 0 ] && [ "$1" != -- ]; do shift; done
[ "$#" -eq 3 ] || { echo "local ssh: expected -- HOST LINE, got $# words" >&2; exit 255; }
cat | setsid -w sh -c "$3"
)";
  std::filesystem::permissions(file, std::filesystem::perms::owner_all);
}

/// Waits until `pid` has ended: gone, or a zombie. (An orphan whose parent was killed with it
/// comes to this process, a subreaper for the Supervisor, which reaps it here.)
bool gone(pid_t pid, milliseconds timeout = 3000ms) {
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  while (std::chrono::steady_clock::now() < deadline) {
    ::waitpid(pid, nullptr, WNOHANG);
    if (::kill(pid, 0) != 0 && errno == ESRCH) return true;
    const std::string stat = slurp("/proc/" + std::to_string(pid) + "/stat");
    const std::size_t paren = stat.rfind(')');
    if (paren != std::string::npos && paren + 2 < stat.size() && stat[paren + 2] == 'Z')
      return true;
    std::this_thread::sleep_for(10ms);
  }
  return false;
}

/// A program for the remote side: writes its pid and $V to files, then runs until SIGTERM,
/// which it notes in a third file.
std::vector<std::string> remote_program(const std::filesystem::path& dir) {
  return {"/bin/sh", "-c",
          "echo $$ > " + (dir / "pid").string() + "; printf %s \"$V\" > " +
              (dir / "value").string() + "; trap 'echo TERM > " + (dir / "stopped").string() +
              "; exit 0' TERM; echo ready; while :; do sleep 0.02; done"};
}

/// Expects `pid` to end (`gone`); if it does not, kills its process group (never this
/// process' own) so that a failing test leaves nothing behind.
void expect_gone(pid_t pid) {
  const bool ended = gone(pid);
  EXPECT_TRUE(ended) << "pid " << pid << " still runs";
  const pid_t group = ::getpgid(pid);
  if (!ended && group > 1 && group != ::getpgrp()) ::kill(-group, SIGKILL);
}

pid_t read_pid(const std::filesystem::path& file) {
  const std::string text = slurp(file);
  return text.empty() ? -1 : static_cast<pid_t>(std::stol(text));
}

TEST(LaunchPlan, TheSupervisorStopsAProgramOnAnSshHost) {
  const auto dir = temp_dir("ssh-stop");
  std::filesystem::create_directories(dir);
  write_local_ssh(dir / "ssh");
  HostConfig host;
  host.name = "cell";
  host.address = "robot@10.0.0.7";
  host.command = {(dir / "ssh").string(), "-o", "BatchMode=yes", "{host}"};
  const std::string value = "a&b; c 'd' $(e) `f`";
  ChildSpec spec;
  spec.name = "remote";
  spec.argv = host_command(host, {"V=" + value}, remote_program(dir), RemoteStop{SIGTERM, 2.0});
  spec.stop_by_closing_input = true;
  spec.stop_grace = 3000ms;

  Capture cap;
  Supervisor s(cap.stream());
  s.start(spec);
  ASSERT_TRUE(cap.wait_for_line("remote", "ready")) << cap.text();
  const pid_t remote = read_pid(dir / "pid");
  ASSERT_GT(remote, 0);
  EXPECT_EQ(slurp(dir / "value"), value);
  // Not in the launcher's process group of the child: its stop signal would not reach it.
  EXPECT_NE(::getpgid(remote), *s.pid_of("remote"));
  const auto t0 = std::chrono::steady_clock::now();
  s.stop_all();
  EXPECT_LT(std::chrono::steady_clock::now() - t0, 2000ms) << cap.text();
  EXPECT_THAT(cap.text(), HasSubstr("by closing its input")) << cap.text();
  EXPECT_EQ(slurp(dir / "stopped"), "TERM\n");
  expect_gone(remote);
  ASSERT_EQ(s.exits().size(), 1u);
  EXPECT_EQ(s.exits()[0].exit_code, 0) << cap.text();  // the program's own
  EXPECT_FALSE(s.exits()[0].forced);
  std::filesystem::remove_all(dir);
}

TEST(LaunchPlan, AProgramOnAnSshHostEndsWhenItsConnectionIsGone) {
  const auto dir = temp_dir("ssh-lost");
  std::filesystem::create_directories(dir);
  write_local_ssh(dir / "ssh");
  HostConfig host;
  host.name = "cell";
  host.command = {(dir / "ssh").string(), "{host}"};
  host.address = "cell";
  ChildSpec spec;
  spec.name = "remote";
  spec.argv = host_command(host, {"V=x"}, remote_program(dir), RemoteStop{SIGTERM, 2.0});
  spec.stop_by_closing_input = true;

  Capture cap;
  Supervisor s(cap.stream());
  const pid_t client = s.start(spec);
  ASSERT_TRUE(cap.wait_for_line("remote", "ready")) << cap.text();
  const pid_t remote = read_pid(dir / "pid");
  ASSERT_GT(remote, 0);
  // The ssh client killed (the launcher gone, the network down): its input ends too.
  ::kill(-client, SIGKILL);
  expect_gone(remote);
  EXPECT_EQ(slurp(dir / "stopped"), "TERM\n");
  s.stop_all();
  std::filesystem::remove_all(dir);
}

TEST(LaunchPlan, TheRemoteSideKillsAProgramThatIgnoresTheStopSignal) {
  const auto dir = temp_dir("ssh-kill");
  std::filesystem::create_directories(dir);
  write_local_ssh(dir / "ssh");
  HostConfig host;
  host.name = "cell";
  host.command = {(dir / "ssh").string(), "{host}"};
  host.address = "cell";
  ChildSpec spec;
  spec.name = "remote";
  spec.argv = host_command(host, {},
                           {"/bin/sh", "-c",
                            "echo $$ > " + (dir / "pid").string() +
                                "; trap '' TERM; echo ready; while :; do sleep "
                                "0.02; done"},
                           RemoteStop{SIGTERM, 0.5});
  spec.stop_by_closing_input = true;
  spec.stop_grace = 3000ms;

  Capture cap;
  Supervisor s(cap.stream());
  s.start(spec);
  ASSERT_TRUE(cap.wait_for_line("remote", "ready")) << cap.text();
  const pid_t remote = read_pid(dir / "pid");
  ASSERT_GT(remote, 0);
  const auto t0 = std::chrono::steady_clock::now();
  s.stop_all();
  // The remote side's SIGKILL after 1 s, before the launcher's own after 3 s.
  EXPECT_LT(std::chrono::steady_clock::now() - t0, 2500ms) << cap.text();
  expect_gone(remote);
  ASSERT_EQ(s.exits().size(), 1u);
  EXPECT_NE(s.exits()[0].exit_code, 0) << cap.text();
  EXPECT_FALSE(s.exits()[0].forced) << cap.text();
  std::filesystem::remove_all(dir);
}

TEST(Process, SighupRequestsAStopLikeSigterm) {
  const std::string failure = in_subprocess(+[]() -> std::string {
    ::mrroc::install_stop_handlers();
    if (::mrroc::stop_requested()) return "stop requested too early";
    ::raise(SIGHUP);
    return ::mrroc::stop_requested() ? "" : "SIGHUP did not request a stop";
  });
  EXPECT_EQ(failure, "");
}

// ---- the status table ----------------------------------------------------------------------

TEST(LaunchStatus, ReadsCpuTimeAndMemoryOfAProcess) {
  // The process' own CPU clock, independent of /proc: the loop below runs until it advanced
  // 0.3 s, however busy the host is (a loop of 0.3 s of wall time got only 0.13 s of CPU beside
  // two builds).
  const auto cpu_seconds = [] {
    timespec ts{};
    ::clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
    return static_cast<double>(ts.tv_sec) + static_cast<double>(ts.tv_nsec) * 1e-9;
  };
  const auto before = process_cpu_ticks(::getpid());
  ASSERT_TRUE(before.has_value());
  const double c0 = cpu_seconds();
  volatile double x = 0;
  while (cpu_seconds() - c0 < 0.3) x = x + 1.0;
  const auto after = process_cpu_ticks(::getpid());
  ASSERT_TRUE(after.has_value());
  // /proc counts the same 0.3 s in clock ticks (100 per second on Linux), each sample rounded
  // down to a tick: at least 0.25 s.
  EXPECT_GE(*after - *before, static_cast<std::uint64_t>(::sysconf(_SC_CLK_TCK) * 25 / 100));
  const auto rss = process_rss_kb(::getpid());
  ASSERT_TRUE(rss.has_value());
  EXPECT_GT(*rss, 100);
  EXPECT_FALSE(process_cpu_ticks(999999999).has_value());
  EXPECT_FALSE(process_rss_kb(999999999).has_value());
}

TEST(LaunchStatus, FormatsTheTable) {
  LaunchStatus s;
  s.set_name = "demo";
  s.config_file = "/c/demo.toml";
  s.state = "running";
  s.launcher_pid = 42;
  s.uptime_s = 3.25;
  ProcessRow r;
  r.name = "edp/irb6";
  r.group = "edp";
  r.host = "b";
  r.state = "running";
  r.pid = 1234;
  r.cpu_percent = 12.5;
  r.rss_kb = 65536;
  r.restarts = 1;
  r.uptime_s = 2.0;
  r.restart = "on-failure";
  s.processes.push_back(r);
  const std::string table = format_status_table(s);
  EXPECT_THAT(table, HasSubstr("set 'demo' (/c/demo.toml): running, launcher pid 42"));
  EXPECT_THAT(table, HasSubstr("RESTARTS"));
  EXPECT_TRUE(std::regex_search(
      table,
      std::regex(R"(edp/irb6 +edp +b +running +1234 +12\.5 +65536 +1 +2\.0 +- +yes +on-failure)")))
      << table;
}

}  // namespace
}  // namespace mrroc::launch
