// The RNT engraves "MRROC" into a board that physics cuts (configs/engrave-rnt-can.toml): the EDP's
// `can` plugin drives the emulated CiA 402 drives of mrroc-axis-emu, whose cell world makes the
// board a body the cutter cuts ([[scene.object.cutter]], configs/scenes/engrave.toml). The groove
// is reconstructed from the emulator's raw sensor device "engraving" (tip on the board, depth,
// cutting, force at 500 Hz) and measured against the letters of the task's own stroke font
// (include/mrroc/ecp/stroke_font.hpp): one groove per stroke, every groove point on its stroke,
// every stroke covered by its groove, 2 mm deep between the stroke ends, nothing cut elsewhere;
// and the motion that cut it (no standstill for want of a macro-step, commanded joint velocities
// and accelerations within the limits, the cutter never still in the wood for long).
#include <gtest/gtest.h>

#include <Eigen/Core>
#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <mutex>
#include <regex>
#include <string>
#include <vector>

#include "launch_helpers.hpp"
#include "mrroc/comm/bus.hpp"
#include "mrroc/comm/codec.hpp"
#include "mrroc/comm/request_reply.hpp"
#include "mrroc/config/process_set.hpp"
#include "mrroc/ecp/stroke_font.hpp"
#include "mrroc/robot/robot_model.hpp"
#include "mrroc_lcm/raw_sensor_t.hpp"
#include "scene.hpp"
#include "state_watch.hpp"

namespace fs = std::filesystem;

namespace {

using mrroc::test::has;

/// Largest distance of a groove point from its letter stroke, and of a stroke point from the
/// groove [m]. Measured in five runs (docs/hil.md, "Boards that are cut"): 0.216 .. 0.220 mm; 1 mm
/// is a quarter of the narrowest letter detail (the R's bowl, 4.5 mm high).
constexpr double kPathTolerance = 0.001;
/// Depth of the groove between the stroke ends [m] around the task's 2 mm. Measured in five runs:
/// 1.928 .. 1.987 mm (the arm yields under the cutting force).
constexpr double kDepthTolerance = 0.0002;
/// Longest time the tip may stay (moving less than kStill per sample) in the wood [s]. Measured in
/// five runs: 0.068 s, the stop between the plunge and the stroke.
constexpr double kLongestStill = 0.2;
constexpr double kStill = 1e-5;          ///< [m] per sample (5 mm/s)
constexpr double kSamplePeriod = 0.002;  ///< [s] of the device "engraving" (500 Hz)

/// The cut as mrroc/raw/engraving publishes it.
struct CutSample {
  std::int64_t no = 0;
  Eigen::Vector2d tip;  ///< board frame [m]
  double depth = 0.0;   ///< [m]
  bool cutting = false;
  double force = 0.0;  ///< [N]
};

class EngravingWatch {
 public:
  explicit EngravingWatch(mrroc::comm::Bus& bus) : bus_(bus) {
    sub_ = bus_.subscribe<EngravingWatch*>(mrroc::channels::raw_sensor("engraving"),
                                           &EngravingWatch::on_sample, this);
  }
  ~EngravingWatch() { bus_.unsubscribe(sub_); }
  EngravingWatch(const EngravingWatch&) = delete;
  EngravingWatch& operator=(const EngravingWatch&) = delete;

  /// Every sample received, in sample order.
  std::vector<CutSample> samples() const {
    std::lock_guard lock(mutex_);
    std::vector<CutSample> out = samples_;
    std::sort(out.begin(), out.end(),
              [](const CutSample& a, const CutSample& b) { return a.no < b.no; });
    return out;
  }

 private:
  static void on_sample(const lcm::ReceiveBuffer* buffer, const std::string&,
                        EngravingWatch* self) {
    mrroc_lcm::raw_sensor_t m;
    if (!mrroc::comm::detail::decode_received(buffer, m)) return;
    if (m.values.size() != 5) return;  // x, y, depth, cutting, force
    std::lock_guard lock(self->mutex_);
    self->samples_.push_back({m.sample_no, Eigen::Vector2d(m.values[0], m.values[1]), m.values[2],
                              m.values[3] == 1.0, m.values[4]});
  }
  mrroc::comm::Bus& bus_;
  mrroc::comm::Subscription* sub_ = nullptr;
  mutable std::mutex mutex_;
  std::vector<CutSample> samples_;
};

using Polyline = std::vector<Eigen::Vector2d>;

double distance_to_segment(const Eigen::Vector2d& p, const Eigen::Vector2d& a,
                           const Eigen::Vector2d& b) {
  const Eigen::Vector2d ab = b - a;
  const double t = std::clamp((p - a).dot(ab) / std::max(ab.squaredNorm(), 1e-18), 0.0, 1.0);
  return (a + t * ab - p).norm();
}

double distance_to_polyline(const Eigen::Vector2d& p, const Polyline& line) {
  double nearest = (p - line.front()).norm();
  for (std::size_t i = 1; i < line.size(); ++i)
    nearest = std::min(nearest, distance_to_segment(p, line[i - 1], line[i]));
  return nearest;
}

/// Points along a polyline, at most `spacing` apart, its vertices included.
std::vector<Eigen::Vector2d> resample(const Polyline& line, double spacing) {
  std::vector<Eigen::Vector2d> out{line.front()};
  for (std::size_t i = 1; i < line.size(); ++i) {
    const Eigen::Vector2d d = line[i] - line[i - 1];
    const int n = std::max(1, static_cast<int>(std::ceil(d.norm() / spacing)));
    for (int k = 1; k <= n; ++k) out.push_back(line[i - 1] + d * (static_cast<double>(k) / n));
  }
  return out;
}

double median(std::vector<double> v) {
  if (v.empty()) return 0.0;
  std::sort(v.begin(), v.end());
  return v[v.size() / 2];
}

}  // namespace

TEST(Engrave, TheGroovesOnTheBoardAreTheLettersStrokes) {
  const fs::path file = fs::path(MRROC_SOURCE_DIR) / "configs/engrave-rnt-can.toml";
  const mrroc::ProcessSetConfig config = mrroc::load_process_set(file);
  const mrroc::RobotConfig& rnt = config.robots.at(0);
  const mrroc::RobotModel model = mrroc::load_robot_model(rnt.model_dir);
  // The letters, as the task lays them out (robot base = world: the scene's base is zero) ...
  const mrroc::Params& args = rnt.ecp.args;
  const std::string text = args.get_string("text");
  const std::vector<double> origin = args.get_doubles("origin");
  ASSERT_EQ(origin.size(), 3U);
  const mrroc::ecp::engraving::TextLayout layout{
      Eigen::Vector3d(origin[0], origin[1], origin[2]), args.get_double("letter_height"),
      args.get_double("letter_width"), args.get_double("spacing")};
  const double depth = args.get_double("depth");
  ASSERT_TRUE(mrroc::ecp::engraving::in_font(text));
  // ... in the board's frame (configs/scenes/engrave.toml: not rotated, top face at the text's z).
  const mrroc::emu::Scene scene =
      mrroc::emu::load_scene(fs::path(MRROC_SOURCE_DIR) / "configs/scenes/engrave.toml");
  const mrroc::emu::SceneObject& board = scene.objects.at(0);
  ASSERT_EQ(board.name, "board");
  ASSERT_EQ(board.rotation, (std::array<double, 3>{}));
  ASSERT_EQ(scene.robots.at(0).base, (std::array<double, 6>{}));
  ASSERT_NEAR(board.position[2] + board.size.at(2), origin[2], 1e-12);
  std::vector<Polyline> strokes;
  for (const auto& line : mrroc::ecp::engraving::text_strokes(text, layout)) {
    Polyline p;
    for (const Eigen::Vector3d& v : line)
      p.emplace_back(v.x() - board.position[0], v.y() - board.position[1]);
    strokes.push_back(std::move(p));
  }
  ASSERT_EQ(strokes.size(), 7U) << "M 1, R 2, R 2, O 1, C 1";

  mrroc::comm::Bus bus(config.lcm_url);
  EngravingWatch watch(bus);
  mrroc::test::StateWatch states(bus, "rnt");
  bus.start();
  const mrroc::test::LaunchRun r = mrroc::test::launch_and_kill(file.string());
  bus.stop();

  // The set finished: the task's own check (from the measured joints) and the emulator's groove.
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_TRUE(has(r.output, "task 'engrave' terminated")) << r.output;
  for (const char* p : {"emu", "edp/rnt", "ecp/rnt", "srp", "mp"})
    EXPECT_TRUE(has(r.output, std::string(p) + " exited with code 0")) << p << "\n" << r.output;
  EXPECT_FALSE(has(r.output, "no next macro-step")) << r.output;
  EXPECT_FALSE(has(r.output, "refused")) << r.output;
  std::smatch m;
  ASSERT_TRUE(std::regex_search(
      r.output, m,
      std::regex("board 'board' cut by 'rnt/tool': ([0-9]+) strokes, cut length ([0-9.]+) m, "
                 "max depth ([0-9.]+) mm, peak force ([0-9.]+) N")))
      << r.output;
  EXPECT_EQ(std::stoi(m[1]), 7) << r.output;
  const std::string emulator_groove = m[0];
  std::smatch own;
  ASSERT_TRUE(
      std::regex_search(r.output, own, std::regex("cutter tip within ([0-9.]+) mm of the strokes")))
      << r.output;
  std::printf("the task's own check: cutter tip within %s mm of the strokes; %s\n",
              own[1].str().c_str(), emulator_groove.c_str());
  double letters_length = 0.0;
  for (const Polyline& s : strokes)
    for (std::size_t i = 1; i < s.size(); ++i) letters_length += (s[i] - s[i - 1]).norm();
  EXPECT_NEAR(std::stod(m[2]), letters_length, 0.01) << "the strokes' length";

  // The grooves: runs of cutting samples.
  const std::vector<CutSample> samples = watch.samples();
  ASSERT_GT(samples.size(), 5000U) << "samples of mrroc/raw/engraving";
  std::int64_t lost = 0;
  for (std::size_t i = 1; i < samples.size(); ++i)
    lost += std::max<std::int64_t>(0, samples[i].no - samples[i - 1].no - 1);
  std::vector<std::vector<CutSample>> grooves;
  bool in = false;
  for (const CutSample& s : samples) {
    if (s.cutting && !in) grooves.emplace_back();
    if (s.cutting) grooves.back().push_back(s);
    in = s.cutting;
  }
  ASSERT_EQ(grooves.size(), strokes.size()) << "one groove per stroke, in order";

  double worst_off = 0.0;    // groove point from its stroke
  double worst_cover = 0.0;  // stroke point from its groove
  double shallowest = 1.0;   // between the stroke ends
  double deepest = 0.0;
  double worst_end = 0.0;  // a shallow (plunging, lifting) sample from its stroke's ends
  double longest_still = 0.0;
  std::vector<double> forces;  // at full depth
  double peak_force = 0.0;
  for (std::size_t g = 0; g < grooves.size(); ++g) {
    const std::vector<CutSample>& groove = grooves[g];
    const Polyline& stroke = strokes[g];
    double still = 0.0;
    for (std::size_t i = 0; i < groove.size(); ++i) {
      const CutSample& s = groove[i];
      const double off = distance_to_polyline(s.tip, stroke);
      worst_off = std::max(worst_off, off);
      deepest = std::max(deepest, s.depth);
      peak_force = std::max(peak_force, s.force);
      const double from_ends =
          std::min((s.tip - stroke.front()).norm(), (s.tip - stroke.back()).norm());
      if (s.depth < depth - kDepthTolerance) {
        worst_end = std::max(worst_end, from_ends);
      } else {
        forces.push_back(s.force);
      }
      if (from_ends > kPathTolerance) shallowest = std::min(shallowest, s.depth);
      if (i > 0 &&
          std::hypot((s.tip - groove[i - 1].tip).norm(), s.depth - groove[i - 1].depth) < kStill) {
        still += kSamplePeriod;
        longest_still = std::max(longest_still, still);
      } else {
        still = 0.0;
      }
    }
    for (const Eigen::Vector2d& p : resample(stroke, 2.5e-4)) {
      double nearest = 1.0;
      for (const CutSample& s : groove) nearest = std::min(nearest, (s.tip - p).norm());
      worst_cover = std::max(worst_cover, nearest);
    }
  }
  std::printf(
      "engraving: %zu grooves from %zu samples (%lld lost); grooves within %.3f mm of the "
      "strokes, strokes covered within %.3f mm; depth between the stroke ends %.3f .. %.3f mm "
      "(task %.1f mm); plunges and lifts within %.3f mm of the stroke ends; cutting force at "
      "full depth median %.1f N, peak %.1f N; longest still in the wood %.3f s\n",
      grooves.size(), samples.size(), static_cast<long long>(lost), worst_off * 1e3,
      worst_cover * 1e3, shallowest * 1e3, deepest * 1e3, depth * 1e3, worst_end * 1e3,
      median(forces), peak_force, longest_still);
  EXPECT_LT(worst_off, kPathTolerance) << "a groove left its stroke: something cut elsewhere";
  EXPECT_LT(worst_cover, kPathTolerance) << "a stroke is not (wholly) cut";
  EXPECT_NEAR(shallowest, depth, kDepthTolerance);
  EXPECT_NEAR(deepest, depth, kDepthTolerance);
  EXPECT_LT(worst_end, kPathTolerance) << "the cutter plunged or lifted away from a stroke end";
  EXPECT_LT(longest_still, kLongestStill) << "the cutter stood still in the wood";
  // The board resisted: along the strokes k * depth * 2 r = 32 N (configs/scenes/engrave.toml).
  const mrroc::emu::SceneCutter& cutter = board.cutters.at(0);
  const double side_force = cutter.specific_force * depth * 2.0 * cutter.radius;
  EXPECT_NEAR(median(forces), side_force, 0.1 * side_force);

  // The motion that cut it.
  const auto history = states.history();
  ASSERT_GT(history.size(), 1000U) << "robot states of the RNT's EDP";
  const mrroc::test::MotionCheck motion =
      mrroc::test::check_commanded_motion(history, model, rnt.edp.servo_period_s);
  int moving = 0;
  for (const auto& state : history)
    if (state.max_speed > 1e-3) ++moving;
  std::printf(
      "engraving motion: %d states, %d moving, commanded velocity up to %.0f %% and "
      "acceleration up to %.0f %% of the limits\n",
      motion.states, moving, motion.worst_velocity_share * 100,
      motion.worst_acceleration_share * 100);
  EXPECT_GT(moving, 1000) << "states of the RNT in motion";
}
