#pragma once
// Helpers of the operator tests: run mrroc-launch (or any command) in the background, read its
// output line by line with the time each line arrived, wait for lines, find pids, look for
// processes left behind.
#include <dirent.h>
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <condition_variable>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <mutex>
#include <optional>
#include <regex>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

namespace mrroc::test {

using Clock = std::chrono::steady_clock;
using namespace std::chrono_literals;
namespace fs = std::filesystem;

inline const fs::path kSource{MRROC_SOURCE_DIR};
inline const fs::path kBin{MRROC_BIN_DIR};
inline std::string launcher() { return (kBin / "mrroc-launch").string(); }

/// A command running in the background, its stdout and stderr read line by line.
class Background {
 public:
  explicit Background(const std::vector<std::string>& argv) {
    int out[2];
    if (::pipe(out) != 0) throw std::runtime_error("pipe");
    pid_ = ::fork();
    if (pid_ == 0) {
      ::dup2(out[1], STDOUT_FILENO);
      ::dup2(out[1], STDERR_FILENO);
      ::close(out[0]);
      ::close(out[1]);
      std::vector<char*> args;
      for (const auto& a : argv) args.push_back(const_cast<char*>(a.c_str()));
      args.push_back(nullptr);
      ::execvp(args[0], args.data());
      ::_exit(127);
    }
    ::close(out[1]);
    in_ = ::fdopen(out[0], "r");
    reader_ = std::thread([this] {
      char line[8192];
      while (std::fgets(line, sizeof line, in_) != nullptr) {
        std::lock_guard lock(mutex_);
        lines_.push_back({Clock::now(), line});
        cv_.notify_all();
      }
      std::lock_guard lock(mutex_);
      eof_ = true;
      cv_.notify_all();
    });
  }
  ~Background() {
    if (!exited_) {
      ::kill(pid_, SIGKILL);
      wait(10s);
    }
    if (reader_.joinable()) reader_.join();
    if (in_ != nullptr) std::fclose(in_);
  }
  Background(const Background&) = delete;
  Background& operator=(const Background&) = delete;

  [[nodiscard]] pid_t pid() const { return pid_; }

  /// Everything written so far.
  [[nodiscard]] std::string output() const {
    std::lock_guard lock(mutex_);
    std::string all;
    for (const auto& l : lines_) all += l.text;
    return all;
  }

  /// Waits until a line (from line number `from` on) contains `needle`; returns the time it
  /// arrived, nothing on timeout or end of output.
  std::optional<Clock::time_point> wait_for(const std::string& needle,
                                            std::chrono::milliseconds timeout = 60s,
                                            std::size_t from = 0) {
    std::unique_lock lock(mutex_);
    const auto deadline = Clock::now() + timeout;
    for (;;) {
      for (std::size_t i = from; i < lines_.size(); ++i)
        if (lines_[i].text.find(needle) != std::string::npos) return lines_[i].at;
      if (eof_ || Clock::now() >= deadline) return std::nullopt;
      cv_.wait_until(lock, deadline);
    }
  }
  /// Number of lines read so far.
  [[nodiscard]] std::size_t line_count() const {
    std::lock_guard lock(mutex_);
    return lines_.size();
  }

  /// The pid of the last "started NAME (pid N)" line.
  [[nodiscard]] pid_t pid_of(const std::string& name) const {
    const std::string text = output();
    const std::regex started("started " + name + " \\(pid ([0-9]+)\\)");
    pid_t pid = 0;
    for (auto it = std::sregex_iterator(text.begin(), text.end(), started);
         it != std::sregex_iterator(); ++it)
      pid = std::stoi((*it)[1]);
    return pid;
  }

  /// Waits for the command to end; its exit code (128+N for signal N, -1 on timeout).
  int wait(std::chrono::milliseconds timeout = 120s) {
    if (exited_) return code_;
    const auto deadline = Clock::now() + timeout;
    for (;;) {
      int status = 0;
      const pid_t r = ::waitpid(pid_, &status, WNOHANG);
      if (r == pid_) {
        exited_ = true;
        code_ = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
        if (reader_.joinable()) reader_.join();
        return code_;
      }
      if (Clock::now() >= deadline) return -1;
      std::this_thread::sleep_for(20ms);
    }
  }

 private:
  struct Line {
    Clock::time_point at;
    std::string text;
  };
  pid_t pid_ = -1;
  FILE* in_ = nullptr;
  std::thread reader_;
  mutable std::mutex mutex_;
  std::condition_variable cv_;
  std::vector<Line> lines_;
  bool eof_ = false;
  bool exited_ = false;
  int code_ = -1;
};

/// Runs a command to its end; {exit code, output}.
inline std::pair<int, std::string> run(const std::vector<std::string>& argv,
                                       std::chrono::milliseconds timeout = 60s) {
  Background b(argv);
  const int code = b.wait(timeout);
  return {code, b.output()};
}

/// Processes of the set still alive (command names from /proc; the tests run in their own PID
/// namespace, so only what they started can be there): "pid comm" lines.
inline std::string leftovers() {
  std::string left;
  DIR* proc = ::opendir("/proc");
  if (proc == nullptr) return "cannot read /proc";
  while (const dirent* e = ::readdir(proc)) {
    const std::string name = e->d_name;
    if (name.find_first_not_of("0123456789") != std::string::npos) continue;
    std::ifstream comm("/proc/" + name + "/comm");
    std::string command;
    std::getline(comm, command);
    std::ifstream stat("/proc/" + name + "/stat");
    std::string stat_line;
    std::getline(stat, stat_line);
    const bool zombie = stat_line.find(") Z ") != std::string::npos;
    if (!zombie && (command.rfind("mrroc-", 0) == 0 || command == "lcm-logger"))
      left += name + " " + command + "\n";
  }
  ::closedir(proc);
  return left;
}

inline std::string slurp(const fs::path& p) {
  std::ifstream in(p);
  std::stringstream text;
  text << in.rdbuf();
  return text.str();
}

/// A copy of tests/operator/configs/<base> in `dir` with an absolute model path, `srp_keys`
/// in its [srp] table (the base ends with it) and `tables` (more TOML tables) at the start.
inline fs::path write_config(const fs::path& dir, const std::string& base,
                             const std::string& srp_keys, const std::string& tables = {},
                             const std::string& file_name = "set.toml") {
  std::string text = slurp(kSource / "tests/operator/configs" / base);
  const std::string model = "\"../../../robots/irb6\"";
  const auto at = text.find(model);
  if (at != std::string::npos)
    text.replace(at, model.size(), "\"" + (kSource / "robots/irb6").string() + "\"");
  fs::create_directories(dir);
  const fs::path file = dir / file_name;
  std::ofstream(file) << tables << "\n" << text << srp_keys << "\n";
  return file;
}

inline fs::path temp_dir(const std::string& what) {
  const fs::path dir =
      fs::temp_directory_path() / ("mrroc-operator-" + what + "-" + std::to_string(::getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir;
}

/// Replaces the first `what` in `text` with `with`; a test failure when `text` has no `what`.
inline void replace_once(std::string& text, const std::string& what, const std::string& with) {
  const auto at = text.find(what);
  ASSERT_NE(at, std::string::npos) << what;
  text.replace(at, what.size(), with);
}

inline bool has(const std::string& s, const std::string& what) {
  return s.find(what) != std::string::npos;
}

inline double seconds(Clock::duration d) { return std::chrono::duration<double>(d).count(); }

}  // namespace mrroc::test
