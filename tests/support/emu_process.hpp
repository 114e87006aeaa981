#pragma once
// mrroc-axis-emu as a child process of a test: started with the given arguments, ready once it
// says how it runs ("; lock-step" or "; real time"), its output echoed and kept, stopped with
// SIGTERM by its own pid at the end.
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <mutex>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

namespace mrroc::test {

class EmuProcess {
 public:
  /// `args`: the emulator's arguments (scene, buses, faults); `--lock-step` is added when
  /// `lock_step`.
  EmuProcess(const std::vector<std::string>& arguments, bool lock_step) {
    std::vector<std::string> args{
        (std::filesystem::path(MRROC_BIN_DIR) / "mrroc-axis-emu").string()};
    for (const std::string& a : arguments) args.push_back(a);
    if (lock_step) args.emplace_back("--lock-step");
    int out[2];
    if (pipe(out) != 0) throw std::runtime_error("pipe");
    pid_ = fork();
    if (pid_ < 0) {
      close(out[0]);
      close(out[1]);
      throw std::runtime_error("fork of mrroc-axis-emu failed");
    }
    if (pid_ == 0) {
      dup2(out[1], STDOUT_FILENO);
      dup2(out[1], STDERR_FILENO);
      close(out[0]);
      close(out[1]);
      std::vector<char*> argv;
      for (auto& a : args) argv.push_back(a.data());
      argv.push_back(nullptr);
      execv(argv[0], argv.data());
      _exit(127);
    }
    close(out[1]);
    // Ready when it says how it runs (after loading MuJoCo and powering the drives); slow under
    // the qemu test's software emulation.
    FILE* in = fdopen(out[0], "r");
    char line[512];
    while (std::fgets(line, sizeof line, in) != nullptr) {
      std::fputs(line, stdout);
      startup_ += line;
      if (std::strstr(line, lock_step ? "; lock-step" : "; real time") != nullptr) break;
    }
    reader_ = std::thread([this, in] {
      char rest[512];
      while (std::fgets(rest, sizeof rest, in) != nullptr) {
        std::fputs(rest, stdout);
        const std::lock_guard lock(mutex_);
        output_ += rest;
      }
      std::fclose(in);
    });
  }
  EmuProcess(const EmuProcess&) = delete;
  EmuProcess& operator=(const EmuProcess&) = delete;
  ~EmuProcess() {
    kill(pid_, SIGTERM);  // pid_ > 0: the constructor throws otherwise
    int status = 0;
    waitpid(pid_, &status, 0);
    reader_.join();
  }

  /// What it printed until it was ready.
  [[nodiscard]] const std::string& startup() const { return startup_; }
  /// What it printed since it was ready.
  [[nodiscard]] std::string output() const {
    const std::lock_guard lock(mutex_);
    return output_;
  }
  /// What it printed since it was ready, once that contains `text` (or after `timeout`).
  [[nodiscard]] std::string output_with(
      const std::string& text,
      std::chrono::milliseconds timeout = std::chrono::milliseconds(5000)) const {
    const auto until = std::chrono::steady_clock::now() + timeout;
    for (;;) {
      {
        const std::lock_guard lock(mutex_);
        if (output_.find(text) != std::string::npos || std::chrono::steady_clock::now() > until)
          return output_;
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(5));
    }
  }

 private:
  pid_t pid_ = -1;
  std::string startup_;
  std::thread reader_;
  mutable std::mutex mutex_;
  std::string output_;
};

}  // namespace mrroc::test
