// B8: a process set of MP + 2 ECP + 2 EDP + VSP + UI (web console) + SRP from launch to ready.
//
// Value: `mrroc-launch` on a generated config with two IRb-6 (MuJoCo plugin, ECP task "follow_mp",
// MP task "start_and_wait"), a range VSP and the web console ([ui] web = true), timed from
// spawning the launcher until it prints "all N processes ready in X ms" (the launcher starts the
// processes layer by layer, both EDPs together and both ECPs together, and waits for each one's
// ready status before the next layer). The launcher is then
// stopped with SIGTERM (it stops the set in reverse order) before the next repetition. X, the
// launcher's own figure (from its first start to the last ready), is reported beside the wall time.
//
// Baseline: the same number of trivial processes (/bin/true) started one after the other through
// the launcher's own fork/exec path (mrroc::launch::Supervisor), each reaped before the next is
// started -- the cost of starting processes, without any of mrroc's start-up work.
//
// Usage (inside scripts/netns-run): bench_launch [repetitions]   (default 10)
// Prints "RESULT B8 ...".
#include <fcntl.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "bench_args.hpp"
#include "mrroc/core/error.hpp"
#include "supervisor.hpp"

extern char** environ;

namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

double percentile(std::vector<double> v, double p) {
  if (v.empty()) return 0.0;
  std::sort(v.begin(), v.end());
  return v[static_cast<std::size_t>(p * static_cast<double>(v.size() - 1))];
}

double ms_since(Clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
}

struct LaunchTime {
  double wall_ms = 0;      // spawn of mrroc-launch -> the "all ... ready" line
  double launcher_ms = 0;  // X of that line
  int processes = 0;
  /// (process, ms from the previous one's ready to its own), in start order.
  std::vector<std::pair<std::string, double>> stages;
};

/// One launch: spawn, read until the ready line, SIGTERM, drain, reap.
LaunchTime launch_once(const fs::path& launcher, const fs::path& config) {
  int fds[2];
  if (::pipe(fds) != 0) throw mrroc::Error("pipe failed");
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_adddup2(&actions, fds[1], 1);
  posix_spawn_file_actions_adddup2(&actions, fds[1], 2);
  posix_spawn_file_actions_addclose(&actions, fds[0]);
  posix_spawn_file_actions_addclose(&actions, fds[1]);
  const std::string exe = launcher.string();
  const std::string cfg = config.string();
  char* argv[] = {const_cast<char*>(exe.c_str()), const_cast<char*>(cfg.c_str()), nullptr};
  pid_t pid = -1;
  const auto t0 = Clock::now();
  const int rc = posix_spawn(&pid, argv[0], &actions, nullptr, argv, environ);
  posix_spawn_file_actions_destroy(&actions);
  ::close(fds[1]);
  if (rc != 0) {
    ::close(fds[0]);
    throw mrroc::Error("cannot start " + exe + ": " + std::strerror(rc));
  }
  FILE* out = ::fdopen(fds[0], "r");
  LaunchTime t;
  std::string output;
  char line[4096];
  bool ready = false;
  double previous_ready = 0;
  while (std::fgets(line, sizeof line, out) != nullptr) {
    output += line;
    char name[64];
    double at = 0;
    if (const char* stage = std::strstr(line, "mrroc-launch: ");
        stage != nullptr &&
        std::sscanf(stage, "mrroc-launch: %63s ready at %lf ms", name, &at) == 2) {
      t.stages.emplace_back(name, at - previous_ready);
      previous_ready = at;
    }
    if (const char* all = std::strstr(line, "mrroc-launch: all ");
        all != nullptr && std::strstr(line, "processes ready in") != nullptr) {
      t.wall_ms = ms_since(t0);
      if (std::sscanf(all, "mrroc-launch: all %d processes ready in %lf ms", &t.processes,
                      &t.launcher_ms) != 2)
        throw mrroc::Error(std::string("cannot parse: ") + line);
      ready = true;
      ::kill(pid, SIGTERM);
      break;
    }
  }
  while (std::fgets(line, sizeof line, out) != nullptr) output += line;
  std::fclose(out);
  int status = 0;
  ::waitpid(pid, &status, 0);
  if (!ready) throw mrroc::Error("mrroc-launch never reported the set ready:\n" + output);
  return t;
}

/// Baseline: `count` /bin/true started through the Supervisor one after the other, each reaped
/// before the next.
double trivial_processes_ms(int count) {
  std::ostringstream sink;
  mrroc::launch::Supervisor supervisor(sink);
  const auto t0 = Clock::now();
  for (int i = 0; i < count; ++i) {
    mrroc::launch::ChildSpec spec;
    spec.name = "true" + std::to_string(i);
    spec.argv = {"/bin/true"};
    supervisor.start(spec);
    while (supervisor.wait_events(std::chrono::milliseconds(1000)).empty()) {
    }
  }
  return ms_since(t0);
}

}  // namespace

int main(int argc, char** argv) {
  if (mrroc::bench::help_requested(
          argc, argv,
          "Usage (inside scripts/netns-run): bench_launch [REPETITIONS]\n"
          "B8: a process set from launch to ready, REPETITIONS (default 10) launches, against as\n"
          "many /bin/true started through the launcher's supervisor. Prints RESULT B8 and NOTE.\n"))
    return 0;
  const int repetitions = argc > 1
                              ? static_cast<int>(mrroc::bench::whole_number(
                                    "bench_launch", "REPETITIONS", argv[1], 1, 10000, "launches"))
                              : 10;
  try {
    const fs::path bin = fs::read_symlink("/proc/self/exe").parent_path();
    const fs::path dir =
        fs::temp_directory_path() / ("mrroc-bench-launch-" + std::to_string(getpid()));
    fs::create_directories(dir);
    const fs::path config = dir / "two-robots.toml";
    {
      std::ofstream f(config);
      f << "[system]\nname = \"bench-two-robots\"\nlcm_url = \"udpm://239.255.76.67:7667?ttl=0\"\n"
        << "[srp]\n[mp]\ntask = \"start_and_wait\"\n"
        // The operator's web console, started by the launcher like the rest of the set
        // (loopback of this private network namespace).
        << "[ui]\nweb = true\nbind = \"127.0.0.1\"\nport = 18080\n"
        << "[[vsp]]\nname = \"range\"\nplugin = \"range\"\nsources = [\"sonar\"]\n";
      for (const char* robot : {"left", "right"})
        f << "[[robot]]\nname = \"" << robot << "\"\nmodel = \"" << MRROC_SOURCE_DIR
          << "/robots/irb6\"\n[robot.edp]\nplugin = \"mujoco\"\n[robot.ecp]\ntask = "
             "\"follow_mp\"\n";
    }
    (void)launch_once(bin / "mrroc-launch", config);  // warm-up (page cache)
    std::vector<double> wall;
    std::vector<double> launcher;
    std::vector<double> baseline;
    std::vector<std::string> stage_names;
    std::vector<std::vector<double>> stage_ms;
    int processes = 0;
    for (int i = 0; i < repetitions; ++i) {
      const LaunchTime t = launch_once(bin / "mrroc-launch", config);
      wall.push_back(t.wall_ms);
      launcher.push_back(t.launcher_ms);
      processes = t.processes;
      for (std::size_t k = 0; k < t.stages.size(); ++k) {
        if (k >= stage_names.size()) {
          stage_names.push_back(t.stages[k].first);
          stage_ms.emplace_back();
        }
        stage_ms[k].push_back(t.stages[k].second);
      }
      baseline.push_back(trivial_processes_ms(processes));
    }
    fs::remove_all(dir);
    std::string stages;
    for (std::size_t k = 0; k < stage_names.size(); ++k)
      stages += (k == 0 ? "" : ", ") + stage_names[k] + " " +
                std::to_string(static_cast<long>(percentile(stage_ms[k], 0.5) + 0.5)) + " ms";
    std::printf("B8 process set of %d processes (SRP, VSP, 2 EDP, 2 ECP, UI, MP), %d launches\n",
                processes, repetitions);
    std::printf("  %d x /bin/true through the supervisor: p50 %.1f ms, p99 %.1f ms\n", processes,
                percentile(baseline, 0.5), percentile(baseline, 0.99));
    std::printf(
        "  launch -> all ready (wall): p50 %.1f ms, p99 %.1f ms; launcher's own figure "
        "p50 %.1f ms, p99 %.1f ms\n",
        percentile(wall, 0.5), percentile(wall, 0.99), percentile(launcher, 0.5),
        percentile(launcher, 0.99));
    std::printf("  start to ready per process (p50): %s\n", stages.c_str());
    std::printf(
        "NOTE B8 %d launches of mrroc-launch on two IRb-6 (MuJoCo, follow_mp) with SRP, a "
        "VSP, the UI (web console) and MP: %d processes started layer by layer (both EDPs "
        "together, both ECPs together), each waited for until it reports "
        "ready; timed from spawning the launcher to its 'all %d processes ready' line "
        "(the launcher's own figure, from its first start: p50 %.0f ms, p99 %.0f ms). "
        "Baseline: %d x /bin/true started and reaped one after the other through the "
        "launcher's Supervisor. Start to ready of each process (p50): %s.\n",
        repetitions, processes, processes, percentile(launcher, 0.5), percentile(launcher, 0.99),
        processes, stages.c_str());
    std::printf(
        "RESULT B8 baseline_p50=%.2f baseline_p99=%.2f value_p50=%.2f value_p99=%.2f "
        "samples=%d unit=ms\n",
        percentile(baseline, 0.5), percentile(baseline, 0.99), percentile(wall, 0.5),
        percentile(wall, 0.99), repetitions);
    return 0;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "bench_launch: %s\n", e.what());
    return 1;
  }
}
