// mrroc-render on a real recorded run: the IRb-6 demo recorded by `mrroc-launch --record` (in
// this test's own network namespace), drawn to PNG frames and an MP4. The frames differ where
// the arm moved and are identical where it rested; the video has every frame. And its errors.
#include <fmt/format.h>
#include <gtest/gtest.h>
#include <png.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <lcm/lcm-cpp.hpp>
#include <memory>
#include <string>
#include <vector>

#include "mrroc_lcm/process_status_t.hpp"
#include "mrroc_lcm/robot_state_t.hpp"
#include "mrroc_lcm/scene_objects_t.hpp"
#include "srp_process.hpp"

namespace fs = std::filesystem;
using mrroc::test::ChildProcess;

namespace {

const std::string kRender = std::string(MRROC_BIN_DIR) + "/mrroc-render";
const std::string kConfig = std::string(MRROC_SOURCE_DIR) + "/configs/demo-irb6.toml";
constexpr double kFps = 25.0;
constexpr int kWidth = 240;
constexpr int kHeight = 180;

struct Image {
  int width = 0;
  int height = 0;
  std::vector<std::uint8_t> rgb;
};

Image read_png(const fs::path& file) {
  Image out;
  png_image image{};
  image.version = PNG_IMAGE_VERSION;
  if (png_image_begin_read_from_file(&image, file.c_str()) == 0) return out;
  image.format = PNG_FORMAT_RGB;
  std::vector<std::uint8_t> rgb(PNG_IMAGE_SIZE(image));
  if (png_image_finish_read(&image, nullptr, rgb.data(), 0, nullptr) == 0) return out;
  out.width = static_cast<int>(image.width);
  out.height = static_cast<int>(image.height);
  out.rgb = std::move(rgb);
  return out;
}

/// Pixels that differ between two images of one size, and the box around them.
struct Difference {
  std::size_t pixels = 0;
  int left = 1 << 30, top = 1 << 30, right = -1, bottom = -1;
};

Difference compare(const Image& a, const Image& b) {
  Difference d;
  for (int y = 0; y < a.height; ++y) {
    for (int x = 0; x < a.width; ++x) {
      const auto i = static_cast<std::size_t>(y * a.width + x) * 3;
      if (a.rgb[i] == b.rgb[i] && a.rgb[i + 1] == b.rgb[i + 1] && a.rgb[i + 2] == b.rgb[i + 2])
        continue;
      ++d.pixels;
      d.left = std::min(d.left, x);
      d.right = std::max(d.right, x);
      d.top = std::min(d.top, y);
      d.bottom = std::max(d.bottom, y);
    }
  }
  return d;
}

/// The robot states of the log: time [s since the first] and q, in log order.
struct State {
  double t = 0.0;
  std::vector<double> q;
};

std::vector<State> read_states(const fs::path& file) {
  std::vector<State> out;
  lcm::LogFile log(file.string(), "r");
  std::int64_t first = -1;
  while (const lcm::LogEvent* event = log.readNextEvent()) {
    if (event->channel != "irb6/edp/state") continue;
    mrroc_lcm::robot_state_t s;
    if (s.decode(event->data, 0, event->datalen) < 0) continue;
    if (first < 0) first = s.header.utime;
    out.push_back({static_cast<double>(s.header.utime - first) * 1e-6, s.q});
  }
  return out;
}

/// q at time t, linearly between states (as mrroc-render interpolates).
std::vector<double> q_at(const std::vector<State>& states, double t) {
  if (t <= states.front().t) return states.front().q;
  if (t >= states.back().t) return states.back().q;
  std::size_t k = 1;
  while (states[k].t < t) ++k;
  const State& a = states[k - 1];
  const State& b = states[k];
  const double w = b.t > a.t ? (t - a.t) / (b.t - a.t) : 1.0;
  std::vector<double> q(a.q.size());
  for (std::size_t j = 0; j < q.size(); ++j) q[j] = a.q[j] + (b.q[j] - a.q[j]) * w;
  return q;
}

double distance(const std::vector<double>& a, const std::vector<double>& b) {
  double d = 0.0;
  for (std::size_t j = 0; j < a.size(); ++j) d = std::max(d, std::abs(a[j] - b[j]));
  return d;
}

class Render : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = fs::temp_directory_path() / ("mrroc-test-render-" + std::to_string(getpid()));
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  static void TearDownTestSuite() {
    if (!::testing::UnitTest::GetInstance()->Failed()) fs::remove_all(dir_);
  }
  static fs::path dir_;
};
fs::path Render::dir_;

// The IRb-6 demo, recorded by the launcher and drawn: the arm's pictures change as it moves.
TEST_F(Render, DrawsTheRecordedDemoWhereTheArmMoved) {
  const fs::path log_file = dir_ / "demo.lcmlog";
  ChildProcess launch(
      {std::string(MRROC_BIN_DIR) + "/mrroc-launch", "--record", log_file.string(), kConfig});
  ASSERT_EQ(launch.wait(), 0) << launch.output();
  ASSERT_TRUE(fs::exists(log_file)) << launch.output();
  const std::vector<State> states = read_states(log_file);
  ASSERT_GT(states.size(), 100U) << "a state every 20 ms for several seconds";

  const fs::path out = dir_ / "frames";
  ChildProcess render({kRender, "--config", kConfig, "--log", log_file.string(), "--out",
                       out.string(), "--fps", "25", "--width", std::to_string(kWidth), "--height",
                       std::to_string(kHeight), "--hold", "0.4"});
  ASSERT_EQ(render.wait(), 0) << render.output();
  const std::string output = render.output();
  EXPECT_NE(output.find("OpenGL"), std::string::npos) << output;
  const fs::path video = out / "run.mp4";
  EXPECT_NE(output.find("video: " + fs::absolute(video).string()), std::string::npos) << output;

  // One frame every 0.04 s from the first state to the last, then the last pose for 0.4 s more.
  const double duration = states.back().t;
  const auto run_frames = static_cast<std::size_t>(std::floor(duration * kFps + 1e-9)) + 1;
  const std::size_t frames = run_frames + 10;
  for (std::size_t i = 0; i < frames; ++i)
    ASSERT_TRUE(fs::exists(out / fmt::format("frame_{:05d}.png", i))) << i;
  EXPECT_FALSE(fs::exists(out / fmt::format("frame_{:05d}.png", frames)));

  std::vector<std::vector<double>> poses;
  for (std::size_t i = 0; i < run_frames; ++i)
    poses.push_back(q_at(states, static_cast<double>(i) / kFps));
  const auto frame = [&](std::size_t i) {
    return read_png(out / fmt::format("frame_{:05d}.png", i));
  };

  // The first frame (power-on pose) and the last (the demo's final pose [0, -1.5708, 0, 0, 0])
  // differ where the arm is, not everywhere: the floor and sky around it stay.
  const Image first = frame(0);
  const Image last = frame(run_frames - 1);
  ASSERT_EQ(first.width, kWidth);
  ASSERT_EQ(first.height, kHeight);
  ASSERT_EQ(last.width, kWidth);
  ASSERT_GT(distance(poses.front(), poses.back()), 0.04) << "the arm moved";
  const Difference moved = compare(first, last);
  const std::size_t all = static_cast<std::size_t>(kWidth) * kHeight;
  EXPECT_GT(moved.pixels, all / 200) << "the arm's pixels changed";
  EXPECT_LT(moved.pixels, all / 2) << "only where the arm is";
  EXPECT_FALSE(moved.left == 0 && moved.top == 0 && moved.right == kWidth - 1 &&
               moved.bottom == kHeight - 1)
      << "the changed region is not the whole image";

  // Frames of the demo's motion differ from their neighbour. Neighbours with the arm at rest
  // (before it moves and at its end: poses within 0.1 urad, the simulated servo's last
  // settling) differ in a few edge pixels at most (rounding of the transforms).
  std::size_t rest = 0;
  std::size_t different = 0;
  for (std::size_t i = 1; i < run_frames; ++i) {
    const double step = distance(poses[i - 1], poses[i]);
    if (step < 1e-7) {
      EXPECT_LE(compare(frame(i - 1), frame(i)).pixels, all / 2000)
          << "frames " << i - 1 << " and " << i << " show poses " << step << " rad apart";
      ++rest;
    } else if (step > 0.01 && different < 5) {
      const Difference d = compare(frame(i - 1), frame(i));
      EXPECT_GT(d.pixels, 0U) << "frames " << i - 1 << " and " << i << " show poses " << step
                              << " rad apart";
      EXPECT_LT(d.pixels, all / 2);
      ++different;
    }
  }
  std::printf("%zu frames; %zu pairs of neighbours at rest, %zu in motion compared\n", run_frames,
              rest, different);
  EXPECT_GT(different, 0U);
  // The frames held after the end (--hold) show the last measured pose: identical pictures.
  const Image held = frame(run_frames);
  EXPECT_LE(compare(last, held).pixels, all / 2000) << "the arm rests at its end";
  for (std::size_t i = run_frames + 1; i < frames; ++i) {
    EXPECT_EQ(compare(held, frame(i)).pixels, 0U) << "held frame " << i;
  }

  // The video: as many frames as PNGs, at the frame size.
  ASSERT_TRUE(fs::exists(video));
  ChildProcess probe({"ffprobe", "-v", "error", "-count_frames", "-select_streams", "v:0",
                      "-show_entries", "stream=nb_read_frames,width,height,codec_name", "-of",
                      "default=noprint_wrappers=1", video.string()});
  ASSERT_EQ(probe.wait(), 0) << probe.output();
  EXPECT_NE(probe.output().find(fmt::format("nb_read_frames={}", frames)), std::string::npos)
      << probe.output();
  EXPECT_NE(probe.output().find("codec_name=h264"), std::string::npos) << probe.output();
  EXPECT_NE(probe.output().find(fmt::format("width={}", kWidth)), std::string::npos);

  // A shorter render into the same folder leaves none of the earlier frames behind.
  ChildProcess again({kRender, "--config", kConfig, "--log", log_file.string(), "--out",
                      out.string(), "--fps", "10", "--width", "64", "--height", "48", "--to", "1",
                      "--no-video"});
  ASSERT_EQ(again.wait(), 0) << again.output();
  EXPECT_TRUE(fs::exists(out / "frame_00010.png"));
  EXPECT_FALSE(fs::exists(out / "frame_00011.png")) << again.output();
  EXPECT_EQ(read_png(out / "frame_00000.png").width, 64);
}

// --live beside the running demo: frames of the arm as it moves, drawn from the states its EDP
// broadcasts, one every 1/fps s of wall time, until the states stop when the set ends.
TEST_F(Render, DrawsTheRunningDemoLive) {
  const fs::path out = dir_ / "live";
  ChildProcess render({kRender, "--config", kConfig, "--live", "--out", out.string(), "--fps", "10",
                       "--width", std::to_string(kWidth), "--height", std::to_string(kHeight),
                       "--idle", "1", "--wait", "60"});
  const fs::path log_file = dir_ / "live.lcmlog";
  ChildProcess launch(
      {std::string(MRROC_BIN_DIR) + "/mrroc-launch", "--record", log_file.string(), kConfig});
  ASSERT_EQ(launch.wait(), 0) << launch.output();
  ASSERT_EQ(render.wait(), 0) << render.output();
  const std::string output = render.output();
  std::printf("%s", output.c_str());
  EXPECT_NE(output.find("live: stopped (no state for 1 s (the set ended?))"), std::string::npos)
      << output;
  const fs::path video = out / "run.mp4";
  EXPECT_NE(output.find("video: " + fs::absolute(video).string()), std::string::npos) << output;

  std::size_t frames = 0;
  while (fs::exists(out / fmt::format("frame_{:05d}.png", frames))) ++frames;
  // The demo moves for about 6 s after its EDP is ready: at 10 frames a second, at least 40
  // frames (whatever the drawing speed: a late frame repeats its predecessor).
  const std::vector<State> states = read_states(log_file);
  ASSERT_GT(states.size(), 100U);
  std::printf("%zu frames over a run of %.2f s of states\n", frames, states.back().t);
  EXPECT_GE(static_cast<double>(frames), 0.7 * states.back().t * 10.0) << output;

  // The arm moved between the first frame (it has just powered on, before its first motion)
  // and the last (the demo's final pose), where the arm is, not everywhere.
  const Image first = read_png(out / "frame_00000.png");
  const Image last = read_png(out / fmt::format("frame_{:05d}.png", frames - 1));
  ASSERT_EQ(first.width, kWidth);
  ASSERT_EQ(last.height, kHeight);
  const std::size_t all = static_cast<std::size_t>(kWidth) * kHeight;
  const Difference moved = compare(first, last);
  EXPECT_GT(moved.pixels, all / 400) << "the arm's pixels changed";
  EXPECT_LT(moved.pixels, all / 2) << "only where the arm is";
  // Frames on the way differ from the first: the motion was drawn, not only its end.
  std::size_t changed = 0;
  for (std::size_t i = 1; i + 1 < frames; ++i)
    if (compare(first, read_png(out / fmt::format("frame_{:05d}.png", i))).pixels > all / 400)
      ++changed;
  EXPECT_GT(changed, frames / 3) << "frames in motion";

  ChildProcess probe({"ffprobe", "-v", "error", "-count_frames", "-select_streams", "v:0",
                      "-show_entries", "stream=nb_read_frames", "-of", "default=noprint_wrappers=1",
                      video.string()});
  ASSERT_EQ(probe.wait(), 0) << probe.output();
  EXPECT_NE(probe.output().find(fmt::format("nb_read_frames={}", frames)), std::string::npos)
      << probe.output();
}

template <class Msg>
void write_event(lcm::LogFile& log, const std::string& channel, std::int64_t utime,
                 const Msg& msg) {
  std::vector<std::uint8_t> data(static_cast<std::size_t>(msg.getEncodedSize()));
  ASSERT_EQ(msg.encode(data.data(), 0, static_cast<int>(data.size())),
            static_cast<int>(data.size()));
  lcm::LogEvent event{};
  event.timestamp = utime;
  event.channel = channel;
  event.datalen = static_cast<std::int32_t>(data.size());
  event.data = data.data();
  ASSERT_EQ(log.writeEvent(&event), 0);
}

mrroc_lcm::robot_state_t state(const std::string& robot, int joints, std::int64_t utime) {
  mrroc_lcm::robot_state_t s{};
  s.header.utime = utime;
  s.header.sender = "edp/" + robot + "#1";
  s.header.kind = mrroc_lcm::header_t::BROADCAST;
  s.robot = robot;
  s.servo_period_s = 0.002;
  s.n_joints = joints;
  s.q.assign(static_cast<std::size_t>(joints), 0.1);
  s.dq.assign(static_cast<std::size_t>(joints), 0.0);
  s.q_desired.assign(static_cast<std::size_t>(joints), 0.1);
  return s;
}

// The scene's free objects are drawn where the log's scene_objects_t put them: in the two-IRb-6
// cell of tight-bar-can.toml, with both arms still, the bar lifted 0.3 m off its table between
// 0.5 s and 1 s changes the pictures there and only there.
TEST_F(Render, DrawsTheSceneObjectsWhereTheLogPutsThem) {
  const std::string config = std::string(MRROC_SOURCE_DIR) + "/configs/tight-bar-can.toml";
  const fs::path log_file = dir_ / "bar.lcmlog";
  {
    lcm::LogFile log(log_file.string(), "w");
    for (int i = 0; i <= 50; ++i) {  // 0 .. 1 s, every 20 ms
      const std::int64_t utime = 1'000'000 + i * 20'000;
      for (const std::string robot : {"left", "right"}) {
        mrroc_lcm::robot_state_t s = state(robot, 5, utime);
        s.q = {0.0, -1.5708, 0.0, 0.0, 0.0};
        write_event(log, robot + "/edp/state", utime, s);
      }
      mrroc_lcm::scene_objects_t objects{};
      objects.header.utime = utime;
      objects.header.sender = "emu#1";
      objects.header.kind = mrroc_lcm::header_t::BROADCAST;
      objects.scene = "two-irb6";
      mrroc_lcm::scene_object_t bar{};
      bar.name = "bar";
      bar.shape = mrroc_lcm::scene_object_t::BOX;
      bar.n_size = 3;
      bar.size = {0.25, 0.02, 0.02};
      bar.rgba[0] = 0.9;
      bar.rgba[3] = 1.0;
      bar.local_position[0] = 1.0;
      bar.local_position[2] = 1.10;
      bar.local_quaternion[0] = 1.0;
      const double lift = i <= 25 ? 0.0 : 0.3 * (i - 25) / 25.0;  // m
      bar.position[0] = 1.0;
      bar.position[2] = 1.10 + lift;
      bar.quaternion[0] = 1.0;
      objects.objects.push_back(bar);
      objects.n = 1;
      write_event(log, "mrroc/scene/objects", utime, objects);
    }
  }
  const fs::path out = dir_ / "bar";
  ChildProcess render({kRender, "--config", config, "--log", log_file.string(), "--out",
                       out.string(), "--fps", "10", "--width", std::to_string(kWidth), "--height",
                       std::to_string(kHeight), "--lookat", "1.0,0,1.2", "--distance", "2.0",
                       "--no-video"});
  ASSERT_EQ(render.wait(), 0) << render.output();
  EXPECT_NE(render.output().find("and 51 poses of the scene's objects"), std::string::npos)
      << render.output();
  const auto frame = [&](int i) { return read_png(out / fmt::format("frame_{:05d}.png", i)); };
  const std::size_t all = static_cast<std::size_t>(kWidth) * kHeight;
  // Before the lift (0 .. 0.5 s): the same picture.
  for (int i = 1; i <= 5; ++i) EXPECT_LE(compare(frame(0), frame(i)).pixels, all / 2000) << i;
  // After it: the bar has left its place; the change is the bar's, not the whole picture.
  const Difference lifted = compare(frame(0), frame(10));
  EXPECT_GT(lifted.pixels, all / 400) << "the bar's pixels changed";
  EXPECT_LT(lifted.pixels, all / 5) << "only where the bar is";
  EXPECT_GT(compare(frame(8), frame(10)).pixels, 0U) << "it moved on the way";
}

// Each error says what is wrong and ends the program with 1 (2 for a bad command line).
TEST_F(Render, ClearErrors) {
  const fs::path out = dir_ / "errors";
  const auto run = [&](std::vector<std::string> args) {
    args.insert(args.begin(), kRender);
    auto child = std::make_unique<ChildProcess>(args);
    return child;
  };

  auto missing = run({"--config", kConfig, "--log", (dir_ / "none.lcmlog").string()});
  EXPECT_EQ(missing->wait(), 1);
  EXPECT_NE(missing->output().find("none.lcmlog' does not exist"), std::string::npos)
      << missing->output();

  const fs::path status_only = dir_ / "status-only.lcmlog";
  {
    lcm::LogFile log(status_only.string(), "w");
    mrroc_lcm::process_status_t status{};
    status.process = "mp";
    for (int i = 0; i < 3; ++i) write_event(log, "mrroc/status", 1000 + i, status);
  }
  auto none = run({"--config", kConfig, "--log", status_only.string(), "--out", out.string()});
  EXPECT_EQ(none->wait(), 1);
  EXPECT_NE(none->output().find("holds no robot state: 3 events"), std::string::npos)
      << none->output();

  // States of a robot the set does not have, and states with the wrong number of joints.
  const fs::path other = dir_ / "other-robot.lcmlog";
  const fs::path six = dir_ / "six-joints.lcmlog";
  {
    lcm::LogFile log(other.string(), "w");
    write_event(log, "rnt/edp/state", 1000, state("rnt", 3, 1000));
    lcm::LogFile log6(six.string(), "w");
    write_event(log6, "irb6/edp/state", 1000, state("irb6", 6, 1000));
  }
  auto stranger = run({"--config", kConfig, "--log", other.string(), "--out", out.string()});
  EXPECT_EQ(stranger->wait(), 1);
  EXPECT_NE(stranger->output().find("none of the robots of the log"), std::string::npos)
      << stranger->output();
  EXPECT_NE(stranger->output().find("(rnt) is in the set 'demo-irb6' (irb6)"), std::string::npos)
      << stranger->output();
  auto joints = run({"--config", kConfig, "--log", six.string(), "--out", out.string()});
  EXPECT_EQ(joints->wait(), 1);
  EXPECT_NE(joints->output().find("robot 'irb6': its states in"), std::string::npos)
      << joints->output();
  EXPECT_NE(joints->output().find("have 6 joints, its model in the set 'demo-irb6' has 5"),
            std::string::npos)
      << joints->output();

  // A set whose robot's model folder has no MJCF.
  const fs::path bare = dir_ / "bare-model";
  fs::create_directories(bare);
  std::ofstream(bare / "parameters.toml") << "[robot]\nsynchro_joint_positions = [0.0]\n";
  const fs::path set = dir_ / "bare.toml";
  std::ofstream(set) << fmt::format(
      "[system]\nname = \"bare\"\n[mp]\ntask = \"start_and_wait\"\n[[robot]]\nname = "
      "\"irb6\"\nmodel = \"{}\"\n[robot.edp]\nplugin = \"mujoco\"\n[robot.ecp]\ntask = "
      "\"visit_joint_poses\"\n",
      bare.string());
  auto model = run({"--config", set.string(), "--log", six.string(), "--out", out.string()});
  EXPECT_EQ(model->wait(), 1);
  EXPECT_NE(model->output().find("bare-model"), std::string::npos) << model->output();

  // No OpenGL: EGL finds no vendor library (glvnd reads its vendors from this variable).
  const fs::path log_file = dir_ / "one-state.lcmlog";
  {
    lcm::LogFile log(log_file.string(), "w");
    write_event(log, "irb6/edp/state", 1000, state("irb6", 5, 1000));
  }
  ChildProcess without_gl({"/usr/bin/env", "__EGL_VENDOR_LIBRARY_FILENAMES=/nonexistent.json",
                           kRender, "--config", kConfig, "--log", log_file.string(), "--out",
                           out.string()});
  EXPECT_EQ(without_gl.wait(), 1);
  EXPECT_NE(without_gl.output().find("no OpenGL for off-screen drawing"), std::string::npos)
      << without_gl.output();

  // A single state draws one frame.
  auto one = run({"--config", kConfig, "--log", log_file.string(), "--out", out.string(), "--width",
                  "64", "--height", "48"});
  EXPECT_EQ(one->wait(), 0) << one->output();
  EXPECT_EQ(read_png(out / "frame_00000.png").height, 48);
  EXPECT_FALSE(fs::exists(out / "frame_00001.png"));

  // The command line.
  auto help = run({"--help"});
  EXPECT_EQ(help->wait(), 0);
  EXPECT_NE(help->output().find("--log"), std::string::npos);
  auto version = run({"--version"});
  EXPECT_EQ(version->wait(), 0);
  EXPECT_NE(version->output().find("mrroc-render"), std::string::npos) << version->output();
  auto no_log = run({"--config", kConfig});
  EXPECT_EQ(no_log->wait(), 2);
  EXPECT_NE(no_log->output().find("give either --log FILE"), std::string::npos) << no_log->output();
  auto both = run({"--config", kConfig, "--log", log_file.string(), "--live"});
  EXPECT_EQ(both->wait(), 2);
  EXPECT_NE(both->output().find("give either --log FILE"), std::string::npos) << both->output();
  // --live with no set running: it says what it waited for, and ends.
  auto nobody = run({"--config", kConfig, "--live", "--wait", "0.5", "--out", out.string()});
  EXPECT_EQ(nobody->wait(), 1);
  EXPECT_NE(nobody->output().find("no robot state of set 'demo-irb6' (irb6) arrived within 0.5 s"),
            std::string::npos)
      << nobody->output();
  auto small = run({"--config", kConfig, "--log", log_file.string(), "--width", "5"});
  EXPECT_EQ(small->wait(), 2);
  EXPECT_NE(small->output().find("5"), std::string::npos) << small->output();
  auto lookat = run({"--config", kConfig, "--log", log_file.string(), "--lookat", "1,2"});
  EXPECT_EQ(lookat->wait(), 2);
  EXPECT_NE(lookat->output().find("--lookat '1,2' is not three numbers"), std::string::npos)
      << lookat->output();
}

}  // namespace
