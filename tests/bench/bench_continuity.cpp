// B9: continuity under load. The two-robot bar carry (configs/tight-bar.toml) and the RNT
// engraving (configs/engrave-rnt.toml), real time with the 2 ms servo, each run while one
// CPU-bound busy loop per core (nice 0) runs beside it, against the same sets in the same run
// without load; then the bar carry with its MP, and with one ECP, stopped for 50 ms (SIGSTOP,
// SIGCONT) 3.5 s after the carry began.
//
// Value: standstills, the EDPs' "no next macro-step from the ECP in time" warnings (each one a
// robot brought to rest because its queue of macro-steps ran dry), and the physical outcome the
// tasks report: the bar's grip-distance error, the cutter's distance from the strokes. Baseline:
// the same figures without load. Target: 0 standstills under load and across the stops, grip
// error within 0.2 mm.
//
// --sweep D1,D2,...: runs both sets under load with each lookahead depth instead (copies of the
// configs with `lookahead = D` in every [robot.edp], written beside the originals and removed
// again), for the table in docs/edp.md; prints "SWEEP set depth runs standstills error_mm".
//
// Usage (inside scripts/netns-run): bench_continuity [runs] [--sweep D1,D2,...] [--loops N]
// (default 2 runs, one busy loop per core). Prints "RESULT B9 ..." and "NOTE B9 ...".
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <regex>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "busy_loops.hpp"

namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;
using mrroc::test::BusyLoops;

const fs::path kSource = MRROC_SOURCE_DIR;

struct Run {
  int exit_code = -1;
  int standstills = 0;
  double error_mm = -1.0;  ///< grip-distance deviation or cutter distance from the strokes
  bool paused = false;     ///< the victim was stopped and continued
  std::string output;
};

/// Runs mrroc-launch on `config`; with `victim`, stops it for 50 ms `delay` after `trigger`.
Run launch(const fs::path& launcher, const fs::path& config, const std::string& victim = {},
           const std::string& trigger = {}, std::chrono::milliseconds delay = {}) {
  int out[2];
  Run run;
  if (pipe(out) != 0) return run;
  const pid_t pid = fork();
  if (pid == 0) {
    dup2(out[1], STDOUT_FILENO);
    dup2(out[1], STDERR_FILENO);
    close(out[0]);
    close(out[1]);
    execl(launcher.c_str(), launcher.c_str(), config.c_str(), static_cast<char*>(nullptr));
    _exit(127);
  }
  close(out[1]);
  FILE* in = fdopen(out[0], "r");
  char line[4096];
  const std::regex started("started " + victim + " \\(pid ([0-9]+)\\)");
  pid_t victim_pid = 0;
  Clock::time_point act_at{};
  while (std::fgets(line, sizeof line, in) != nullptr) {
    run.output += line;
    if (victim.empty() || run.paused) continue;
    std::cmatch m;
    if (victim_pid == 0 && std::regex_search(line, m, started)) victim_pid = std::atoi(m[1].first);
    if (victim_pid != 0 && act_at == Clock::time_point{} && std::strstr(line, trigger.c_str()))
      act_at = Clock::now() + delay;
    if (act_at != Clock::time_point{}) {
      // The launcher's output is line-buffered and the carry prints nothing for seconds: wait
      // here (the pipe holds what comes meanwhile).
      std::this_thread::sleep_until(act_at);
      kill(victim_pid, SIGSTOP);
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
      kill(victim_pid, SIGCONT);
      run.paused = true;
    }
  }
  std::fclose(in);
  int status = 0;
  waitpid(pid, &status, 0);
  run.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  for (std::size_t at = run.output.find("no next macro-step from the ECP in time");
       at != std::string::npos;
       at = run.output.find("no next macro-step from the ECP in time", at + 1))
    ++run.standstills;
  std::smatch m;
  static const std::regex grip("grip distance within ([0-9.]+) mm");
  static const std::regex cut("cutter tip within ([0-9.]+) mm of the strokes");
  if (std::regex_search(run.output, m, grip) || std::regex_search(run.output, m, cut))
    run.error_mm = std::stod(m[1]);
  return run;
}

struct Summary {
  int runs = 0;
  int failed = 0;  ///< runs that did not exit 0
  int standstills = 0;
  double worst_mm = 0.0;
};

/// Grip or cutter error above which a run's whole output is kept for a look at its cause.
constexpr double kKeepOutputMm = 0.2;

void add(Summary& s, const Run& r) {
  if (r.error_mm > kKeepOutputMm || r.exit_code != 0 || r.standstills > 0) {
    // The run missed the target: its output (every process' reports, the overruns) is the only
    // record of why.
    char name[] = "/tmp/bench_continuity-run-XXXXXX";
    const int fd = mkstemp(name);
    if (fd >= 0) {
      const ssize_t written = write(fd, r.output.data(), r.output.size());
      close(fd);
      std::printf("run with exit %d, %d standstills, error %.3f mm: its output is in %s%s\n",
                  r.exit_code, r.standstills, r.error_mm, name,
                  written == static_cast<ssize_t>(r.output.size()) ? "" : " (cut short)");
      std::fflush(stdout);
    }
  }
  ++s.runs;
  if (r.exit_code != 0) ++s.failed;
  s.standstills += r.standstills;
  s.worst_mm = std::max(s.worst_mm, r.error_mm);
}

/// A copy of `config` beside it with `lookahead = depth` in every [robot.edp].
fs::path with_lookahead(const fs::path& config, int depth) {
  std::ifstream in(config);
  std::stringstream text;
  text << in.rdbuf();
  std::string out;
  std::string line;
  std::istringstream lines(text.str());
  while (std::getline(lines, line)) {
    out += line + "\n";
    if (line == "[robot.edp]") out += "lookahead = " + std::to_string(depth) + "\n";
  }
  const fs::path copy =
      config.parent_path() / (".b9-" + std::to_string(getpid()) + "-" + config.stem().string() +
                              "-" + std::to_string(depth) + ".toml");
  std::ofstream(copy) << out;
  return copy;
}

}  // namespace

int main(int argc, char** argv) {
  int runs = 2;
  int loops = static_cast<int>(std::max(1L, sysconf(_SC_NPROCESSORS_ONLN)));
  std::vector<int> sweep;
  bool smoke = false;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "-h" || a == "--help") {
      std::printf(
          "bench_continuity [runs] [--sweep D1,D2,...] [--loops N] [--smoke]: B9, continuity "
          "under load.\n"
          "Runs configs/tight-bar.toml and configs/engrave-rnt.toml RUNS times each (default 2)\n"
          "without load and with N CPU-bound busy loops beside them (default one per core),\n"
          "then the bar carry with its MP and with one ECP stopped for 50 ms mid-carry; counts\n"
          "the EDPs' standstills and reads the tasks' own error figures. --sweep runs both sets\n"
          "under load once per lookahead depth instead. Run inside scripts/netns-run.\n"
          "Prints RESULT B9 and NOTE B9 (or SWEEP lines). --smoke (a check that the benchmark\n"
          "runs, tests/bench/smoke.py): one bar carry with its MP stopped, no load, no figure.\n");
      return 0;
    }
    if (a == "--smoke") {
      smoke = true;
    } else if (a == "--sweep" && i + 1 < argc) {
      std::stringstream list(argv[++i]);
      std::string d;
      while (std::getline(list, d, ',')) {
        const int depth = std::atoi(d.c_str());
        if (depth < 1 || depth > 64) {
          std::fprintf(stderr, "bench_continuity: lookahead '%s' is outside 1..64\n", d.c_str());
          return 2;
        }
        sweep.push_back(depth);
      }
    } else if (a == "--loops" && i + 1 < argc) {
      loops = std::atoi(argv[++i]);
      if (loops < 1 || loops > 64) {
        std::fprintf(stderr, "bench_continuity: --loops %s is outside 1..64\n", argv[i]);
        return 2;
      }
    } else {
      runs = std::atoi(a.c_str());
      if (runs < 1 || runs > 100) {
        std::fprintf(stderr, "bench_continuity: runs '%s' is outside 1..100 (try --help)\n",
                     a.c_str());
        return 2;
      }
    }
  }
  const fs::path bin = fs::canonical("/proc/self/exe").parent_path();
  const fs::path launcher = bin / "mrroc-launch";
  const fs::path bar = kSource / "configs/tight-bar.toml";
  const fs::path engrave = kSource / "configs/engrave-rnt.toml";

  if (!sweep.empty()) {
    for (const fs::path& set : {bar, engrave}) {
      for (int depth : sweep) {
        const fs::path copy = with_lookahead(set, depth);
        Summary s;
        for (int r = 0; r < runs; ++r) {
          BusyLoops busy(loops);
          add(s, launch(launcher, copy));
        }
        fs::remove(copy);
        std::printf(
            "SWEEP %s lookahead=%d runs=%d failed=%d standstills=%d worst_error_mm=%.3f "
            "loops=%d\n",
            set.stem().c_str(), depth, s.runs, s.failed, s.standstills, s.worst_mm, loops);
        std::fflush(stdout);
      }
    }
    return 0;
  }

  Summary bar_idle, bar_load, engrave_idle, engrave_load, stopped_mp, stopped_ecp;
  if (smoke) {
    const Run mp = launch(launcher, bar, "mp", "carrying the bar", std::chrono::milliseconds(3500));
    std::printf(
        "RESULT B9 smoke=1 exit_code=%d paused=%d stop_stops=%d value_grip_mm=%.3f runs=1\n",
        mp.exit_code, mp.paused ? 1 : 0, mp.standstills, mp.error_mm);
    return mp.exit_code == 0 && mp.paused ? 0 : 1;
  }
  for (int r = 0; r < runs; ++r) {
    add(bar_idle, launch(launcher, bar));
    add(engrave_idle, launch(launcher, engrave));
    {
      BusyLoops busy(loops);
      add(bar_load, launch(launcher, bar));
    }
    {
      BusyLoops busy(loops);
      add(engrave_load, launch(launcher, engrave));
    }
    const Run mp = launch(launcher, bar, "mp", "carrying the bar", std::chrono::milliseconds(3500));
    if (!mp.paused) ++stopped_mp.failed;
    add(stopped_mp, mp);
    const Run ecp =
        launch(launcher, bar, "ecp/right", "carrying the bar", std::chrono::milliseconds(3500));
    if (!ecp.paused) ++stopped_ecp.failed;
    add(stopped_ecp, ecp);
  }
  const int failed = bar_idle.failed + bar_load.failed + engrave_idle.failed + engrave_load.failed +
                     stopped_mp.failed + stopped_ecp.failed;
  std::printf(
      "NOTE B9 %d runs of each: configs/tight-bar.toml (two IRb-6, MuJoCo, 327 macro-steps "
      "of 10 servo steps) and configs/engrave-rnt.toml (RNT, MuJoCo), default lookahead, "
      "real time, 2 ms servo; load: %d CPU-bound busy loops at nice 0 (one per core). "
      "Standstills idle: bar %d, engraving %d; under load: bar %d, engraving %d. Grip-"
      "distance error idle %.3f mm, loaded %.3f mm; cutter within %.3f mm of the strokes "
      "idle, %.3f mm loaded. MP stopped 50 ms mid-carry: %d standstills, grip error %.3f "
      "mm; ECP 'right' stopped 50 ms: %d standstills, grip error %.3f mm. Runs that did not "
      "exit 0 (or were never stopped): %d.\n",
      runs, loops, bar_idle.standstills, engrave_idle.standstills, bar_load.standstills,
      engrave_load.standstills, bar_idle.worst_mm, bar_load.worst_mm, engrave_idle.worst_mm,
      engrave_load.worst_mm, stopped_mp.standstills, stopped_mp.worst_mm, stopped_ecp.standstills,
      stopped_ecp.worst_mm, failed);
  std::printf(
      "RESULT B9 baseline_stops=%d value_stops=%d stop_stops=%d baseline_grip_mm=%.3f "
      "value_grip_mm=%.3f baseline_cut_mm=%.3f value_cut_mm=%.3f failed=%d runs=%d\n",
      bar_idle.standstills + engrave_idle.standstills,
      bar_load.standstills + engrave_load.standstills,
      stopped_mp.standstills + stopped_ecp.standstills, bar_idle.worst_mm,
      std::max({bar_load.worst_mm, stopped_mp.worst_mm, stopped_ecp.worst_mm}),
      engrave_idle.worst_mm, engrave_load.worst_mm, failed, runs);
  return 0;
}
