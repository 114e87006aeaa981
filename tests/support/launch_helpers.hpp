#pragma once
// Helpers of the integration tests: run mrroc-launch on a config, optionally killing one of its
// processes once a line appears in the output.
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <functional>
#include <mutex>
#include <regex>
#include <string>
#include <thread>

namespace mrroc::test {

using Clock = std::chrono::steady_clock;

struct LaunchRun {
  int exit_code = -1;
  std::string output;
  Clock::time_point killed_at{};  ///< when the victim was sent its signal (if it was)
};

/// Launches `config`; when `victim` is not empty, waits until `trigger` appears in the output,
/// waits `delay` and calls `act` with the pid of the process named `victim` (from the launcher's
/// "started <victim> (pid N)" line). A set still running after `time_limit` is stopped: exit
/// code -2, and the output says so.
inline LaunchRun launch_and_act(const std::string& config, const std::string& victim,
                                const std::string& trigger, std::chrono::milliseconds delay,
                                const std::function<void(pid_t)>& act,
                                std::chrono::seconds time_limit = std::chrono::seconds(180)) {
  int out[2];
  if (pipe(out) != 0) return {};
  const pid_t pid = fork();
  if (pid == 0) {
    dup2(out[1], STDOUT_FILENO);
    dup2(out[1], STDERR_FILENO);
    close(out[0]);
    close(out[1]);
    const std::string exe = std::string(MRROC_BIN_DIR) + "/mrroc-launch";
    execl(exe.c_str(), exe.c_str(), config.c_str(), static_cast<char*>(nullptr));
    _exit(127);
  }
  close(out[1]);
  LaunchRun run;
  std::mutex m;
  FILE* in = fdopen(out[0], "r");
  std::thread reader([&] {
    char line[4096];
    while (std::fgets(line, sizeof line, in) != nullptr) {
      std::lock_guard lock(m);
      run.output += line;
    }
  });
  const std::regex started("started " + victim + " \\(pid ([0-9]+)\\)");
  pid_t victim_pid = 0;
  const auto deadline = Clock::now() + std::chrono::seconds(60);
  bool triggered = false;
  int status = 0;
  bool ended = false;  // the launcher ended before the trigger: nothing to wait for
  while (!victim.empty() && Clock::now() < deadline && !triggered && !ended) {
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
    ended = waitpid(pid, &status, WNOHANG) == pid;
    std::lock_guard lock(m);
    std::smatch match;
    if (victim_pid == 0 && std::regex_search(run.output, match, started))
      victim_pid = std::stoi(match[1]);
    triggered = victim_pid != 0 && run.output.find(trigger) != std::string::npos;
  }
  if (triggered && !ended) {
    std::this_thread::sleep_for(delay);
    run.killed_at = Clock::now();
    act(victim_pid);
  }
  // A set that does not end is stopped (the launcher ends its processes on SIGINT) and its output
  // kept: a test that hangs says where, instead of being killed by ctest with nothing to show.
  const auto give_up = Clock::now() + time_limit;
  bool stopped = false;
  while (!ended && waitpid(pid, &status, WNOHANG) == 0) {
    if (!stopped && Clock::now() >= give_up) {
      stopped = true;
      kill(pid, SIGINT);
      std::this_thread::sleep_for(std::chrono::seconds(10));
      if (waitpid(pid, &status, WNOHANG) != 0) break;
      kill(pid, SIGKILL);
      waitpid(pid, &status, 0);
      break;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  reader.join();
  std::fclose(in);
  run.exit_code = stopped ? -2 : WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  if (stopped)
    run.output +=
        "\n[test] the process set did not end within " +
        std::to_string(std::chrono::duration_cast<std::chrono::seconds>(time_limit).count()) +
        " s; the launcher was stopped (SIGINT)\n";
  if (!victim.empty() && !triggered)
    run.output += "\n[test] trigger '" + trigger + "' never came\n";
  return run;
}

/// Launches `config`; when `victim` is not empty, waits until `trigger` appears in the output,
/// waits `delay` and kills the process named `victim` (pid from the launcher's "started <victim>
/// (pid N)" line) with `signal`.
inline LaunchRun launch_and_kill(const std::string& config, const std::string& victim = {},
                                 const std::string& trigger = {},
                                 std::chrono::milliseconds delay = std::chrono::milliseconds(0),
                                 int signal = SIGKILL) {
  return launch_and_act(config, victim, trigger, delay, [signal](pid_t pid) { kill(pid, signal); });
}

inline bool has(const std::string& s, const std::string& what) {
  return s.find(what) != std::string::npos;
}

/// Nothing of the set is left running (the test runs in its own PID namespace).
inline void expect_nothing_left() {
  FILE* ps = popen("ps -eo comm= | grep '^mrroc-' || true", "r");
  char buf[256];
  std::string left;
  while (std::fgets(buf, sizeof buf, ps) != nullptr) left += buf;
  pclose(ps);
  EXPECT_EQ(left, "");
}

}  // namespace mrroc::test
