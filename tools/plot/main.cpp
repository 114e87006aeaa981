// mrroc-plot: plots of the robot states in an LCM log file (joint positions, joint velocities,
// servo lateness over time, one set per robot), drawn by gnuplot.
#include <fmt/format.h>
#include <spawn.h>
#include <sys/wait.h>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "mrroc/core/command_line.hpp"
#include "mrroc/core/error.hpp"
#include "robot_log.hpp"

extern char** environ;

namespace {

namespace fs = std::filesystem;
using mrroc::Error;
using mrroc::plot::RobotSeries;

struct Options {
  std::string log;
  std::string out_dir = ".";
  std::string gnuplot = "gnuplot";
  int width = 1200;
  int height = 600;
};

/// Data file: one line per state: t_s, servo_step, q[1..n], dq[1..n], q_desired[1..n],
/// lateness_mean_us, lateness_max_us, overruns.
void write_data(const RobotSeries& series, const fs::path& file) {
  std::ofstream out(file);
  if (!out) throw Error(fmt::format("cannot write data file '{}'", file.string()));
  std::string header = "# robot " + series.robot + ": t_s servo_step";
  for (const char* name : {"q", "dq", "q_desired"})
    for (std::size_t j = 1; j <= series.n_joints; ++j) header += fmt::format(" {}{}", name, j);
  header += " lateness_mean_us lateness_max_us overruns\n";
  out << "# units: s, steps, rad, rad/s, rad, us, us, cycles\n" << header;
  for (const auto& s : series.samples) {
    std::string line = fmt::format("{:.6f} {}", s.t_s, s.servo_step);
    for (const auto* v : {&s.q, &s.dq, &s.q_desired})
      for (double x : *v) line += fmt::format(" {:.9g}", x);
    line += fmt::format(" {:.3f} {:.3f} {}\n", s.lateness_mean_us, s.lateness_max_us, s.overruns);
    out << line;
  }
  if (!out) throw Error(fmt::format("cannot write data file '{}'", file.string()));
}

/// gnuplot string literal (single quotes; a quote is doubled).
std::string quoted(const std::string& s) {
  std::string out = "'";
  for (char c : s) {
    if (c == '\'')
      out += "''";
    else
      out += c;
  }
  return out + "'";
}

std::string plot_script(const RobotSeries& series, const fs::path& data, const fs::path& joints,
                        const fs::path& velocities, const fs::path& lateness,
                        const Options& options) {
  const std::size_t n = series.n_joints;
  std::string s = fmt::format(
      "set terminal png size {},{}\nset grid\nset key outside right\n"
      "set xlabel 'time [s]'\n",
      options.width, options.height);
  const auto columns = [&](std::size_t first_column, const char* name) {
    std::string cmd = "plot ";
    for (std::size_t j = 0; j < n; ++j)
      cmd += fmt::format("{}{} using 1:{} with lines title '{}{}'", j == 0 ? "" : ", ",
                         quoted(data.string()), first_column + j, name, j + 1);
    return cmd + "\n";
  };
  s += fmt::format("set output {}\nset title {}\nset ylabel 'joint position [rad]'\n",
                   quoted(joints.string()), quoted(series.robot + ": joint positions"));
  s += columns(3, "q");
  s += fmt::format("set output {}\nset title {}\nset ylabel 'joint velocity [rad/s]'\n",
                   quoted(velocities.string()), quoted(series.robot + ": joint velocities"));
  s += columns(3 + n, "dq");
  const std::size_t lateness_column = 3 + 3 * n;
  s += fmt::format("set output {}\nset title {}\nset ylabel 'wake-up lateness [us]'\n",
                   quoted(lateness.string()), quoted(series.robot + ": servo lateness"));
  s += fmt::format(
      "plot {0} using 1:{1} with lines title 'mean', {0} using 1:{2} with lines "
      "title 'max'\nset output\n",
      quoted(data.string()), lateness_column, lateness_column + 1);
  return s;
}

void run_gnuplot(const std::string& gnuplot, const fs::path& script) {
  std::vector<std::string> args{gnuplot, script.string()};
  std::vector<char*> argv;
  for (auto& a : args) argv.push_back(a.data());
  argv.push_back(nullptr);
  pid_t pid = 0;
  const int rc = posix_spawnp(&pid, gnuplot.c_str(), nullptr, nullptr, argv.data(), environ);
  if (rc != 0)
    throw Error(fmt::format("cannot run '{}': {} (install gnuplot-nox, or name it with --gnuplot)",
                            gnuplot, std::strerror(rc)));
  int status = 0;
  while (waitpid(pid, &status, 0) < 0 && errno == EINTR) {
  }
  if (!WIFEXITED(status) || WEXITSTATUS(status) != 0)
    throw Error(fmt::format("'{}' failed on '{}' ({})", gnuplot, script.string(),
                            WIFEXITED(status) ? fmt::format("exit code {}", WEXITSTATUS(status))
                                              : fmt::format("signal {}", WTERMSIG(status))));
}

int run(const Options& options) {
  const mrroc::plot::RobotLog log = mrroc::plot::read_robot_log(options.log);
  std::size_t states = 0;
  for (const auto& [name, series] : log.robots) states += series.samples.size();
  if (states == 0)
    throw Error(
        fmt::format("log file '{}' holds no robot state: {} events, none on a channel "
                    "'<robot>{}' that decodes as robot_state_t{}",
                    options.log, log.events, mrroc::plot::kStateSuffix,
                    log.malformed > 0 ? fmt::format(" ({} malformed)", log.malformed) : ""));
  const fs::path out_dir(options.out_dir);
  std::error_code ec;
  fs::create_directories(out_dir, ec);
  if (!fs::is_directory(out_dir))
    throw Error(fmt::format("cannot create output folder '{}'", out_dir.string()));
  std::printf("%s: %llu events, %zu robot states of %zu robots\n", options.log.c_str(),
              static_cast<unsigned long long>(log.events), states, log.robots.size());
  if (log.malformed > 0)
    std::printf("%llu robot states did not decode and were skipped\n",
                static_cast<unsigned long long>(log.malformed));
  for (const auto& [name, series] : log.robots) {
    if (series.samples.empty()) continue;
    const fs::path data = out_dir / (name + ".dat");
    const fs::path script = out_dir / (name + ".gp");
    const fs::path joints = out_dir / (name + "-joints.png");
    const fs::path velocities = out_dir / (name + "-velocities.png");
    const fs::path lateness = out_dir / (name + "-lateness.png");
    write_data(series, data);
    {
      std::ofstream out(script);
      out << plot_script(series, data, joints, velocities, lateness, options);
      if (!out) throw Error(fmt::format("cannot write gnuplot script '{}'", script.string()));
    }
    run_gnuplot(options.gnuplot, script);
    std::printf("robot %s: %zu states, %zu joints, %.3f s\n", name.c_str(), series.samples.size(),
                series.n_joints, series.samples.back().t_s - series.samples.front().t_s);
    if (series.other_joint_counts > 0)
      std::printf("robot %s: %llu states with another number of joints skipped\n", name.c_str(),
                  static_cast<unsigned long long>(series.other_joint_counts));
    for (const fs::path& p : {data, script, joints, velocities, lateness})
      std::printf("wrote %s\n", p.string().c_str());
  }
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  mrroc::CommandLine cli(
      "mrroc-plot",
      "mrroc-plot: plots the robot states of an LCM log file written by lcm-logger (for "
      "example by `mrroc-launch` with [launch] record, or `lcm-logger FILE` beside a set).\n"
      "For every robot (channels <robot>/edp/state, robot_state_t) it writes into the output "
      "folder:\n"
      "  <robot>.dat             the data: t_s servo_step q1..qn dq1..dqn q_desired1..n "
      "lateness_mean_us lateness_max_us overruns\n"
      "  <robot>.gp              the gnuplot script\n"
      "  <robot>-joints.png      joint positions [rad] over time [s]\n"
      "  <robot>-velocities.png  joint velocities [rad/s]\n"
      "  <robot>-lateness.png    servo wake-up lateness, mean and max [us]\n"
      "and prints every file it wrote. Time 0 is the first robot state of the log.");
  Options options;
  cli.option("log", options.log, "LCM log file").required();
  cli.option("-o,--output", options.out_dir, "output folder (created if missing)").show_default();
  cli.option("--width", options.width, "PNG width [pixels]").range(200, 10000).show_default();
  cli.option("--height", options.height, "PNG height [pixels]").range(150, 10000).show_default();
  cli.option("--gnuplot", options.gnuplot, "gnuplot executable").show_default();
  if (const auto exit_code = cli.parse(argc, argv)) return *exit_code;
  try {
    return run(options);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "mrroc-plot: %s\n", e.what());
    return 2;
  }
}
