// mrroc-render: pictures of a run without a browser or a display. Reads the robot states of an
// LCM log (recorded by `mrroc-launch --record`), or with --live those a running set broadcasts,
// sets each robot's measured joints into the MuJoCo model of the set's cell, draws it off-screen
// with MuJoCo's own renderer (EGL) into PNG frames, and makes an MP4 of them with ffmpeg.
// docs/recording.md, "Rendering".
#include <fmt/format.h>
#include <lcm/lcm-cpp.hpp>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <map>
#include <mutex>
#include <optional>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "cell_view.hpp"
#include "frames.hpp"
#include "mrroc/comm/auth.hpp"
#include "mrroc/comm/bus.hpp"
#include "mrroc/comm/edge.hpp"
#include "mrroc/comm/messages.hpp"
#include "mrroc/config/process_set.hpp"
#include "mrroc/core/command_line.hpp"
#include "mrroc/core/error.hpp"
#include "mrroc/core/process.hpp"
#include "mrroc/robot/robot_model.hpp"
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
  bool live = false;
  double duration_s = 0.0;  ///< live: stop after this long (0: when the states stop)
  double idle_s = 2.0;      ///< live: stop when no state came for this long
  double wait_s = 30.0;     ///< live: the longest wait for the first state
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

/// The poses of the scene's objects over time (scene_objects_t, which the cell emulator
/// broadcasts about 30 times a second), each sample held until the next.
class ObjectTrack {
 public:
  void add(double t, mrroc::SceneObjects objects) { samples_.emplace_back(t, std::move(objects)); }
  void sort() {
    std::stable_sort(samples_.begin(), samples_.end(),
                     [](const auto& a, const auto& b) { return a.first < b.first; });
  }
  [[nodiscard]] std::size_t size() const { return samples_.size(); }
  /// Sets the free objects of the sample at time t [s] (the last at or before t; the first
  /// before it) into `cell`; returns how many objects were set.
  std::size_t apply(CellView& cell, double t) const {
    if (samples_.empty()) return 0;
    auto next = std::upper_bound(samples_.begin(), samples_.end(), t,
                                 [](double v, const auto& s) { return v < s.first; });
    const auto& sample = next == samples_.begin() ? *next : *(next - 1);
    return set_objects(cell, sample.second);
  }
  /// Sets every free object of `objects` into `cell`; returns how many.
  static std::size_t set_objects(CellView& cell, const mrroc::SceneObjects& objects) {
    std::size_t n = 0;
    for (const auto& o : objects.objects)
      if (o.attach.empty() && cell.set_object(o.name, o.position, o.quaternion)) ++n;
    return n;
  }

 private:
  std::vector<std::pair<double, mrroc::SceneObjects>> samples_;
};

/// The scene_objects_t of an LCM log, timed like the robot states (0: `first_utime`, the first
/// robot state's send time [us]). A log without them gives an empty track.
ObjectTrack read_object_track(const std::string& file, std::int64_t first_utime) {
  ObjectTrack track;
  lcm::LogFile log(file, "r");
  if (!log.good()) return track;
  while (const lcm::LogEvent* event = log.readNextEvent()) {
    if (event->channel != mrroc::channels::scene_objects) continue;
    mrroc::comm::Envelope header;
    auto objects =
        mrroc::comm::decode_bytes<mrroc::SceneObjects>(event->data, event->datalen, &header);
    if (!objects) continue;
    track.add(static_cast<double>(header.utime - first_utime) * 1e-6, std::move(*objects));
  }
  track.sort();
  return track;
}

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

void set_all(CellView& cell, const std::vector<std::pair<std::size_t, Track>>& tracks, double t,
             const ObjectTrack* objects = nullptr) {
  for (const auto& [k, track] : tracks) cell.set_joints(k, track.at(t));
  if (objects != nullptr) objects->apply(cell, t);
  cell.pose();
}

/// Widens [low, high] [m] to hold every robot of `cell` in its current pose.
void grow_box(const CellView& cell, std::array<double, 3>& low, std::array<double, 3>& high) {
  double l[3];
  double h[3];
  cell.robot_bounds(l, h);
  for (std::size_t c = 0; c < 3; ++c) {
    low[c] = std::min(low[c], l[c]);
    high[c] = std::max(high[c], h[c]);
  }
}

/// The camera looking at the middle of the box [low, high] from a distance that keeps it in view,
/// unless the options give the point, the distance; their azimuth and elevation.
CameraView camera_for_box(const CellView& cell, const std::array<double, 3>& low,
                          const std::array<double, 3>& high, const Options& options) {
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

/// The output folder, made when missing, without the frames of an earlier render.
fs::path output_folder(const Options& options) {
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
  return out;
}

/// The frames of `out` as a video (unless --no-video); prints its path last.
void write_video(const Options& options, const fs::path& out) {
  if (options.no_video) return;
  const fs::path video = options.video.empty() ? out / "run.mp4" : fs::path(options.video);
  encode_video(options.ffmpeg, out, options.fps, video);
  std::printf("video: %s\n", fs::absolute(video).lexically_normal().string().c_str());
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
    grow_box(cell, low, high);
  }
  return camera_for_box(cell, low, high, options);
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
  const ObjectTrack objects = read_object_track(options.log, log.first_utime);
  const fs::path out = output_folder(options);

  GlContext gl;
  std::printf("%s\n", gl.description().c_str());
  Renderer renderer(cell.model(), options.width, options.height);
  std::size_t states = 0;
  for (const auto& entry : log.robots) states += entry.second.samples.size();
  fmt::print(
      "{}: {} robot states of {} robots{}, {:.3f} s; drawing {} frames of {} x {} at {} fps{} "
      "(camera: lookat {:.3f} {:.3f} {:.3f} m, distance {:.3f} m, azimuth {} deg, "
      "elevation {} deg)\n",
      options.log, states, log.robots.size(),
      objects.size() > 0 ? fmt::format(" and {} poses of the scene's objects", objects.size()) : "",
      end - begin, count, options.width, options.height, options.fps,
      hold_frames > 0 ? fmt::format(", the last {} held", hold_frames) : "", view.lookat[0],
      view.lookat[1], view.lookat[2], view.distance, view.azimuth, view.elevation);
  std::fflush(stdout);
  const auto started = std::chrono::steady_clock::now();
  for (std::size_t i = 0; i < count; ++i) {
    set_all(cell, tracks, times[i], &objects);
    const std::string label =
        options.label ? fmt::format("{}   t = {:.2f} s", set.name, times[i] - begin) : "";
    write_png(out / frame_name(i), renderer.draw(cell.data(), view, label), options.width,
              options.height);
  }
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count();
  std::printf("wrote %s .. %s (%zu frames in %.1f s)\n", (out / frame_name(0)).string().c_str(),
              frame_name(count - 1).c_str(), count, seconds);
  write_video(options, out);
  return 0;
}

/// --live: the latest measured joints of each robot of the cell, from its EDP's state
/// broadcasts (robot_state_t on <robot>/edp/state), received on the bus' thread.
class LiveStates {
 public:
  using Clock = std::chrono::steady_clock;

  LiveStates(mrroc::comm::Bus& bus, const CellView& cell) : latest_(cell.robot_count()) {
    const auto quiet = mrroc::comm::SubscriberOptions::unreported();
    for (std::size_t k = 0; k < cell.robot_count(); ++k) {
      const std::size_t axes = cell.axis_count(k);
      subscribers_.emplace_back(
          bus, mrroc::channels::robot_state(cell.robot_name(k)),
          [this, k, axes](const mrroc::RobotState& s, const mrroc::comm::Received& in) {
            const bool drawable =
                s.q.size() == axes &&
                std::all_of(s.q.begin(), s.q.end(), [](double v) { return std::isfinite(v); });
            if (!drawable || !in.authentic()) {
              std::lock_guard lock(mutex_);
              ++rejected_;
              return;
            }
            std::lock_guard lock(mutex_);
            latest_[k] = s.q;
            last_ = Clock::now();
            ++received_;
          },
          quiet);
    }
    objects_.emplace(
        bus, mrroc::channels::scene_objects,
        [this](const mrroc::SceneObjects& o, const mrroc::comm::Received& in) {
          if (!in.authentic()) return;
          std::lock_guard lock(mutex_);
          objects_latest_ = o;
        },
        quiet);
  }

  /// Sets every robot heard from, and the scene's free objects (the cell emulator's latest
  /// scene_objects_t), into `cell` (the others keep their pose); returns how many states have
  /// arrived so far.
  std::size_t apply(CellView& cell) const {
    std::lock_guard lock(mutex_);
    for (std::size_t k = 0; k < latest_.size(); ++k)
      if (!latest_[k].empty()) cell.set_joints(k, latest_[k]);
    ObjectTrack::set_objects(cell, objects_latest_);
    return received_;
  }
  [[nodiscard]] std::size_t received() const {
    std::lock_guard lock(mutex_);
    return received_;
  }
  [[nodiscard]] std::size_t rejected() const {
    std::lock_guard lock(mutex_);
    return rejected_;
  }
  /// When the last state arrived (meaningful once received() > 0).
  [[nodiscard]] Clock::time_point last() const {
    std::lock_guard lock(mutex_);
    return last_;
  }

 private:
  mutable std::mutex mutex_;
  std::vector<std::vector<double>> latest_;
  Clock::time_point last_{};
  std::size_t received_ = 0;
  std::size_t rejected_ = 0;
  mrroc::SceneObjects objects_latest_;
  std::vector<mrroc::comm::Subscriber<mrroc::RobotState>> subscribers_;
  std::optional<mrroc::comm::Subscriber<mrroc::SceneObjects>> objects_;
};

/// --live: draws the set while it runs, one frame every 1/fps s of wall time from the first
/// state on, each showing the latest state of every robot; a frame whose time passed while an
/// earlier one was drawn repeats the picture before it, so the video keeps the run's time.
int run_live(const Options& options) {
  const mrroc::ProcessSetConfig set = mrroc::load_process_set(options.config);
  mju_user_error = mujoco_error;
  mju_user_warning = mujoco_warning;
  CellView cell(set);
  GlContext gl;
  std::printf("%s\n", gl.description().c_str());
  Renderer renderer(cell.model(), options.width, options.height);
  const fs::path out = output_folder(options);

  mrroc::install_stop_handlers();
  mrroc::comm::Bus bus(set.lcm_url);
  mrroc::comm::enable_auth_from_file(bus, set.auth_key_file);
  LiveStates states(bus, cell);
  bus.start();
  fmt::print("live: waiting for the robot states of set '{}' ({}) on {}\n", set.name,
             cell.robot_names(), set.lcm_url.empty() ? "LCM's default URL" : set.lcm_url);
  std::fflush(stdout);
  using Clock = LiveStates::Clock;
  const auto waited = Clock::now();
  while (states.received() == 0) {
    if (mrroc::stop_requested()) return 0;
    if (std::chrono::duration<double>(Clock::now() - waited).count() > options.wait_s) {
      throw Error(fmt::format(
          "no robot state of set '{}' ({}) arrived within {} s on {}{}: is the set running "
          "(mrroc-launch), and on this LCM URL?",
          set.name, cell.robot_names(), options.wait_s, set.lcm_url,
          states.rejected() > 0
              ? fmt::format(" ({} states refused: wrong joint count, not finite, or not "
                            "authentic)",
                            states.rejected())
              : ""));
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }

  // The camera: the box every robot can fill, from 64 poses spread over its joint ranges (the
  // run's future is unknown), then back to the first states.
  CameraView view;
  {
    std::vector<mrroc::RobotModel> models;
    for (std::size_t k = 0; k < cell.robot_count(); ++k)
      models.push_back(mrroc::load_robot_model(set.robot(cell.robot_name(k)).model_dir));
    std::array<double, 3> low{1e30, 1e30, 1e30};
    std::array<double, 3> high{-1e30, -1e30, -1e30};
    constexpr int kSamples = 64;
    for (int i = 0; i < kSamples; ++i) {
      for (std::size_t k = 0; k < models.size(); ++k) {
        const mrroc::RobotModel& m = models[k];
        std::vector<double> q(m.axes());
        for (std::size_t j = 0; j < q.size(); ++j) {
          // A low-discrepancy sequence per joint (golden-ratio steps, shifted per joint).
          const double u = std::fmod(
              0.5 + (i + 1) * 0.6180339887498949 * (1.0 + 0.37 * static_cast<double>(j)), 1.0);
          q[j] = m.lower_limits[j] + u * (m.upper_limits[j] - m.lower_limits[j]);
        }
        cell.set_joints(k, q);
      }
      cell.pose();
      grow_box(cell, low, high);
    }
    view = camera_for_box(cell, low, high, options);
  }
  states.apply(cell);
  cell.pose();
  fmt::print(
      "live: drawing {} x {} at {} fps until {} (camera: lookat {:.3f} {:.3f} {:.3f} m, "
      "distance {:.3f} m)\n",
      options.width, options.height, options.fps,
      options.duration_s > 0.0
          ? fmt::format("{} s have passed, the states stop for {} s, or SIGINT/SIGTERM",
                        options.duration_s, options.idle_s)
          : fmt::format("the states stop for {} s, or SIGINT/SIGTERM", options.idle_s),
      view.lookat[0], view.lookat[1], view.lookat[2], view.distance);
  std::fflush(stdout);

  const auto start = Clock::now();
  const auto period = std::chrono::duration<double>(1.0 / options.fps);
  std::size_t count = 0;
  std::size_t repeated = 0;
  std::size_t drawn = 0;
  std::vector<std::uint8_t> image;
  const std::string reason = [&]() -> std::string {
    for (;;) {
      std::this_thread::sleep_until(
          start + std::chrono::duration_cast<Clock::duration>(period * static_cast<double>(count)));
      const auto now = Clock::now();
      const double elapsed = std::chrono::duration<double>(now - start).count();
      if (mrroc::stop_requested()) return "stop signal";
      if (options.duration_s > 0.0 && elapsed >= options.duration_s)
        return fmt::format("{} s passed", options.duration_s);
      if (std::chrono::duration<double>(now - states.last()).count() > options.idle_s)
        return fmt::format("no state for {} s (the set ended?)", options.idle_s);
      states.apply(cell);
      cell.pose();
      const std::string label =
          options.label ? fmt::format("{}   t = {:.2f} s (live)", set.name, elapsed) : "";
      image = renderer.draw(cell.data(), view, label);
      write_png(out / frame_name(count++), image, options.width, options.height);
      ++drawn;
      // Frames due while this one was drawn show the same picture.
      const double done = std::chrono::duration<double>(Clock::now() - start).count();
      while (static_cast<double>(count) * period.count() < done - period.count()) {
        write_png(out / frame_name(count++), image, options.width, options.height);
        ++repeated;
      }
    }
  }();
  if (count == 0) throw Error("no frame drawn: " + reason);
  fmt::print(
      "live: stopped ({}); {} robot states received; wrote {} .. {} ({} frames, {} drawn, {} "
      "repeating the frame before them because drawing took longer than 1/{} s)\n",
      reason, states.received(), (out / frame_name(0)).string(), frame_name(count - 1), count,
      drawn, repeated, options.fps);
  write_video(options, out);
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
      "the first robot state of the log. With --live instead of --log it draws a set while it "
      "runs, from the states its EDPs broadcast (on the config's LCM URL; run it in the set's "
      "network namespace), one frame every 1/fps s of wall time, until the states stop, "
      "--duration has passed, or SIGINT/SIGTERM. Exit status 1 when the run cannot be drawn "
      "(the message says why), 2 for a bad command line.");
  Options options;
  cli.option("-c,--config", options.config, "process-set config (TOML) the log was recorded with")
      .required();
  cli.option("-l,--log", options.log, "LCM log file (or --live)");
  cli.flag("--live", options.live,
           "draw the running set from its robots' state broadcasts instead of a log");
  cli.option("--duration", options.duration_s,
             "--live: stop after this many seconds (default: when the states stop)")
      .range(0, 1e6);
  cli.option("--idle", options.idle_s, "--live: stop when no state came for this long [s]")
      .range(0.1, 600)
      .show_default();
  cli.option("--wait", options.wait_s, "--live: the longest wait for the first state [s]")
      .range(0.1, 3600)
      .show_default();
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
  if (options.log.empty() == !options.live) {
    std::fprintf(stderr,
                 "mrroc-render: give either --log FILE (a recorded run) or --live (the running "
                 "set)\nRun with --help for more information.\n");
    return mrroc::kUsageError;
  }
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
    return options.live ? run_live(options) : run(options);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "mrroc-render: %s\n", e.what());
    return kRunError;
  }
}
