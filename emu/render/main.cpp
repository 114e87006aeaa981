// mrroc-render: pictures of a recorded run without a browser or a display. Reads the robot states
// of an LCM log (recorded by `mrroc-launch --record`), sets each robot's measured joints into the
// MuJoCo model of the set's cell, draws it off-screen with MuJoCo's own renderer (EGL) into PNG
// frames, and makes an MP4 of them with ffmpeg. docs/recording.md, "Rendering".
#include <fmt/format.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <map>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

#include "cell_view.hpp"
#include "frames.hpp"
#include "mrroc/config/process_set.hpp"
#include "mrroc/core/command_line.hpp"
#include "mrroc/core/error.hpp"
#include "offscreen.hpp"
#include "robot_log.hpp"

namespace {

namespace fs = std::filesystem;
using mrroc::Error;
using namespace mrroc::render;

/// A run error (bad input, no OpenGL, ffmpeg failing): exit code 1. Usage errors exit 2.
constexpr int kRunError = 1;

struct Options {
  std::string config;
  std::string log;
  std::string out_dir = "render";
  std::string video;
  std::string ffmpeg = "ffmpeg";
  double fps = 30.0;
  int width = 1280;
  int height = 720;
  double from_s = 0.0;
  double to_s = -1.0;
  double hold_s = 0.0;
  std::string lookat;
  double distance = 0.0;
  double azimuth = 135.0;
  double elevation = -22.0;
  bool label = false;
  bool no_video = false;
};

/// Joint positions of one robot over time, interpolated linearly between its states.
class Track {
 public:
  explicit Track(const mrroc::plot::RobotSeries& series) : samples_(series.samples) {
    // A state with a joint that is not a number cannot be drawn: left out (and counted).
    const auto bad = std::remove_if(samples_.begin(), samples_.end(), [](const auto& s) {
      return !std::all_of(s.q.begin(), s.q.end(), [](double v) { return std::isfinite(v); });
    });
    dropped_ = static_cast<std::size_t>(samples_.end() - bad);
    samples_.erase(bad, samples_.end());
    std::stable_sort(samples_.begin(), samples_.end(),
                     [](const auto& a, const auto& b) { return a.t_s < b.t_s; });
  }
  [[nodiscard]] bool empty() const { return samples_.empty(); }
  [[nodiscard]] std::size_t dropped() const { return dropped_; }
  [[nodiscard]] double begin() const { return samples_.front().t_s; }
  [[nodiscard]] double end() const { return samples_.back().t_s; }
  /// q at time t [s since the log's first state]: held before the first and after the last.
  [[nodiscard]] std::vector<double> at(double t) const {
    if (t <= samples_.front().t_s) return samples_.front().q;
    if (t >= samples_.back().t_s) return samples_.back().q;
    const auto next = std::upper_bound(samples_.begin(), samples_.end(), t,
                                       [](double v, const auto& s) { return v < s.t_s; });
    const auto& b = *next;
    const auto& a = *(next - 1);
    const double span = b.t_s - a.t_s;
    const double w = span > 0.0 ? (t - a.t_s) / span : 1.0;
    std::vector<double> q(a.q.size());
    for (std::size_t j = 0; j < q.size(); ++j) q[j] = a.q[j] + (b.q[j] - a.q[j]) * w;
    return q;
  }

 private:
  std::vector<mrroc::plot::StateSample> samples_;
  std::size_t dropped_ = 0;
};

std::optional<std::array<double, 3>> parse_point(const std::string& text) {
  std::array<double, 3> p{};
  std::string s = text;
  std::replace(s.begin(), s.end(), ',', ' ');
  std::istringstream in(s);
  for (double& v : p) {
    if (!(in >> v) || !std::isfinite(v)) return std::nullopt;
  }
  std::string rest;
  if (in >> rest) return std::nullopt;
  return p;
}

void set_all(CellView& cell, const std::vector<std::pair<std::size_t, Track>>& tracks, double t) {
  for (const auto& [k, track] : tracks) cell.set_joints(k, track.at(t));
  cell.pose();
}

/// The camera: looking at the middle of the box every robot fills during the run, from a
/// distance that keeps the box in view (unless the options give them).
CameraView frame_camera(CellView& cell, const std::vector<std::pair<std::size_t, Track>>& tracks,
                        const std::vector<double>& times, const Options& options) {
  std::array<double, 3> low{1e30, 1e30, 1e30};
  std::array<double, 3> high{-1e30, -1e30, -1e30};
  const std::size_t stride = std::max<std::size_t>(1, times.size() / 40);
  for (std::size_t i = 0; i < times.size(); i += stride) {
    set_all(cell, tracks, times[i]);
    double l[3];
    double h[3];
    cell.robot_bounds(l, h);
    for (int c = 0; c < 3; ++c) {
      low[static_cast<std::size_t>(c)] = std::min(low[static_cast<std::size_t>(c)], l[c]);
      high[static_cast<std::size_t>(c)] = std::max(high[static_cast<std::size_t>(c)], h[c]);
    }
  }
  CameraView view;
  double radius = 0.0;
  for (std::size_t c = 0; c < 3; ++c) {
    view.lookat[c] = 0.5 * (low[c] + high[c]);
    radius += 0.25 * (high[c] - low[c]) * (high[c] - low[c]);
  }
  radius = std::sqrt(radius);
  const double fovy = cell.model()->vis.global.fovy * M_PI / 180.0;
  view.distance = std::max(0.5, 0.7 * radius / std::sin(0.5 * fovy));
  if (!options.lookat.empty()) {
    const auto p = *parse_point(options.lookat);
    std::copy(p.begin(), p.end(), view.lookat);
  }
  if (options.distance > 0.0) view.distance = options.distance;
  view.azimuth = options.azimuth;
  view.elevation = options.elevation;
  return view;
}

void mujoco_error(const char* message) {
  std::fprintf(stderr, "mrroc-render: MuJoCo cannot go on: %s\n", message);
  std::fflush(stderr);
  std::_Exit(kRunError);
}

void mujoco_warning(const char* message) {
  std::fprintf(stderr, "mrroc-render: MuJoCo warning: %s\n", message);
}

int run(const Options& options) {
  const mrroc::ProcessSetConfig set = mrroc::load_process_set(options.config);
  const mrroc::plot::RobotLog log = mrroc::plot::read_robot_log(options.log);
  if (log.robots.empty()) {
    throw Error(
        fmt::format("log file '{}' holds no robot state: {} events, none on a channel "
                    "'<robot>/edp/state' that decodes as robot_state_t",
                    options.log, log.events));
  }
  mju_user_error = mujoco_error;
  mju_user_warning = mujoco_warning;
  CellView cell(set);

  std::vector<std::pair<std::size_t, Track>> tracks;
  double begin = 1e300;
  double end = -1e300;
  for (const auto& [robot, series] : log.robots) {
    const auto k = cell.robot_index(robot);
    if (!k) {
      std::fprintf(stderr,
                   "mrroc-render: robot '%s' of the log is not in the set '%s' (its robots: %s); "
                   "not drawn\n",
                   robot.c_str(), set.name.c_str(), cell.robot_names().c_str());
      continue;
    }
    if (series.n_joints != cell.axis_count(*k)) {
      throw Error(
          fmt::format("robot '{}': its states in '{}' have {} joints, its model in the "
                      "set '{}' has {}",
                      robot, options.log, series.n_joints, set.name, cell.axis_count(*k)));
    }
    Track track(series);
    if (track.dropped() > 0) {
      std::fprintf(stderr,
                   "mrroc-render: robot '%s': %zu states with a joint position that is not a "
                   "number left out\n",
                   robot.c_str(), track.dropped());
    }
    if (track.empty()) {
      throw Error(
          fmt::format("robot '{}': none of its {} states in '{}' has finite joint "
                      "positions",
                      robot, series.samples.size(), options.log));
    }
    begin = std::min(begin, track.begin());
    end = std::max(end, track.end());
    tracks.emplace_back(*k, std::move(track));
  }
  if (tracks.empty()) {
    std::string names;
    for (const auto& entry : log.robots) names += (names.empty() ? "" : ", ") + entry.first;
    throw Error(fmt::format("none of the robots of the log '{}' ({}) is in the set '{}' ({})",
                            options.log, names, set.name, cell.robot_names()));
  }
  const double from = std::max(begin, options.from_s);
  const double to = options.to_s >= 0.0 ? std::min(end, options.to_s) : end;
  if (to < from) {
    throw Error(
        fmt::format("--from {} s is after the end of the run ({:.3f} s)", options.from_s, end));
  }
  const auto run_frames =
      static_cast<std::size_t>(std::floor((to - from) * options.fps + 1e-9)) + 1;
  const auto hold_frames = static_cast<std::size_t>(std::lround(options.hold_s * options.fps));
  const std::size_t count = run_frames + hold_frames;
  std::vector<double> times(count, to);  // the held frames show the last pose
  for (std::size_t i = 0; i < run_frames; ++i) {
    times[i] = from + static_cast<double>(i) / options.fps;
  }

  const CameraView view = frame_camera(cell, tracks, times, options);
  const fs::path out(options.out_dir);
  std::error_code ec;
  fs::create_directories(out, ec);
  if (ec || !fs::is_directory(out)) {
    throw Error(fmt::format("cannot make the output folder '{}': {}", out.string(),
                            ec ? ec.message() : "not a folder"));
  }
  const std::size_t removed = remove_old_frames(out);
  if (removed > 0)
    std::printf("removed %zu frames of an earlier render from %s\n", removed, out.string().c_str());

  GlContext gl;
  std::printf("%s\n", gl.description().c_str());
  Renderer renderer(cell.model(), options.width, options.height);
  std::size_t states = 0;
  for (const auto& entry : log.robots) states += entry.second.samples.size();
  fmt::print(
      "{}: {} robot states of {} robots, {:.3f} s; drawing {} frames of {} x {} at {} fps{} "
      "(camera: lookat {:.3f} {:.3f} {:.3f} m, distance {:.3f} m, azimuth {} deg, "
      "elevation {} deg)\n",
      options.log, states, log.robots.size(), end - begin, count, options.width, options.height,
      options.fps, hold_frames > 0 ? fmt::format(", the last {} held", hold_frames) : "",
      view.lookat[0], view.lookat[1], view.lookat[2], view.distance, view.azimuth, view.elevation);
  std::fflush(stdout);
  const auto started = std::chrono::steady_clock::now();
  for (std::size_t i = 0; i < count; ++i) {
    set_all(cell, tracks, times[i]);
    const std::string label =
        options.label ? fmt::format("{}   t = {:.2f} s", set.name, times[i] - begin) : "";
    write_png(out / frame_name(i), renderer.draw(cell.data(), view, label), options.width,
              options.height);
  }
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count();
  std::printf("wrote %s .. %s (%zu frames in %.1f s)\n", (out / frame_name(0)).string().c_str(),
              frame_name(count - 1).c_str(), count, seconds);
  if (!options.no_video) {
    const fs::path video = options.video.empty() ? out / "run.mp4" : fs::path(options.video);
    encode_video(options.ffmpeg, out, options.fps, video);
    std::printf("video: %s\n", fs::absolute(video).lexically_normal().string().c_str());
  }
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  mrroc::CommandLine cli(
      "mrroc-render",
      "mrroc-render: draws a recorded run with MuJoCo's own renderer, off-screen (EGL; no "
      "display or GPU needed), into PNG frames and an MP4 video.\n"
      "The log is an LCM log of the set (mrroc-launch --record FILE, or lcm-logger beside it); "
      "each robot's measured joints (robot_state_t on <robot>/edp/state) are set into the MuJoCo "
      "model of the set's cell (its [emulator] scene, or its robots' model folders at their "
      "bases), between states linearly interpolated. Writes OUT/frame_00000.png ... and "
      "OUT/run.mp4 (ffmpeg, H.264), and prints the video's path last ('video: PATH'). Time 0 is "
      "the first robot state of the log. Exit status 1 when the run cannot be drawn (the message "
      "says why), 2 for a bad command line.");
  Options options;
  cli.option("-c,--config", options.config, "process-set config (TOML) the log was recorded with")
      .required();
  cli.option("-l,--log", options.log, "LCM log file").required();
  cli.option("-o,--out", options.out_dir,
             "output folder (created if missing; frames of an "
             "earlier render there are removed)")
      .show_default();
  cli.option("--fps", options.fps, "frames a second of run time").range(1, 240).show_default();
  cli.option("--width", options.width, "image width [pixels]").range(16, 8192).show_default();
  cli.option("--height", options.height, "image height [pixels]").range(16, 8192).show_default();
  cli.option("--from", options.from_s, "first frame's time [s]").range(0, 1e6).show_default();
  cli.option("--to", options.to_s, "last frame's time [s] (default: the run's end)").range(0, 1e6);
  cli.option("--hold", options.hold_s,
             "after the last frame, show its pose this much longer [s] (a still end of the "
             "video)")
      .range(0, 60)
      .show_default();
  cli.option("--lookat", options.lookat,
             "point the camera looks at, 'x,y,z' [m] in the cell (default: the middle of the "
             "space the robots fill during the run)");
  cli.option("--distance", options.distance,
             "camera distance from that point [m] (default: the whole space in view)")
      .range(0.05, 1000);
  cli.option("--azimuth", options.azimuth, "camera azimuth about the vertical [deg]")
      .range(-360, 360)
      .show_default();
  cli.option("--elevation", options.elevation, "camera elevation [deg] (negative: from above)")
      .range(-90, 90)
      .show_default();
  cli.flag("--label", options.label, "write the set's name and the time in the top left corner");
  cli.flag("--no-video", options.no_video, "write the frames only");
  cli.option("--video", options.video, "video file (default: OUT/run.mp4)");
  cli.option("--ffmpeg", options.ffmpeg, "ffmpeg executable").show_default();
  if (const auto exit_code = cli.parse(argc, argv)) return *exit_code;
  if (!options.lookat.empty() && !parse_point(options.lookat)) {
    std::fprintf(stderr,
                 "mrroc-render: --lookat '%s' is not three numbers 'x,y,z' [m]\nRun with --help "
                 "for more information.\n",
                 options.lookat.c_str());
    return mrroc::kUsageError;
  }
  if (options.to_s >= 0.0 && options.to_s < options.from_s) {
    std::fprintf(stderr,
                 "mrroc-render: --to %g s is before --from %g s\nRun with --help for more "
                 "information.\n",
                 options.to_s, options.from_s);
    return mrroc::kUsageError;
  }
  try {
    return run(options);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "mrroc-render: %s\n", e.what());
    return kRunError;
  }
}
