// The EDP's collision guard (edp/collision_guard.hpp) on the IRb-6's own MJCF model with a box of
// the cell: a path through the box is refused naming both bodies, the distance, the clearance
// and the servo step, before any servo step that touches it; a path beside it passes; the
// `[collision]` section's mistakes and allowed pairs naming unknown links are `file:line` errors.
#include <fmt/format.h>
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <optional>
#include <regex>
#include <string>
#include <vector>

#include "collision_guard.hpp"
#include "edp_parts.hpp"
#include "mrroc/config/process_set.hpp"
#include "mrroc/core/error.hpp"
#include "mrroc/msg/edp_instruction.hpp"
#include "mrroc/robot/robot_model.hpp"

using namespace mrroc;
using namespace mrroc::edp;
namespace fs = std::filesystem;

namespace {

constexpr double kPi = std::numbers::pi;

/// The file the configs below pretend to come from (never read).
const fs::path kFile = fs::path(MRROC_SOURCE_DIR) / "configs" / "collision-test.toml";

/// A one-IRb-6 set whose `[collision]` section is `collision` (appended at the end).
std::string set_text(const std::string& collision) {
  return "[system]\nname = \"t\"\n\n[mp]\ntask = \"start_and_wait\"\n\n[[robot]]\nname = "
         "\"irb6\"\nmodel = \"" +
         std::string(MRROC_SOURCE_DIR) +
         "/robots/irb6\"\n[robot.edp]\nplugin = \"mujoco\"\n[robot.ecp]\ntask = "
         "\"visit_joint_poses\"\n\n" +
         collision;
}

/// 1-based line of the first occurrence of `needle` in `text`.
int line_of(const std::string& text, const std::string& needle) {
  const auto at = text.find(needle);
  EXPECT_NE(at, std::string::npos) << needle;
  return 1 + static_cast<int>(std::count(text.begin(), text.begin() + static_cast<long>(at), '\n'));
}

/// A box of half-size 0.05 m centred at (0.6, 0.6, z): at a column angle of 45 degrees the
/// IRb-6's horizontal upper arm and wrist (z = 1.155 m at the synchronisation pose) pass 0.85 m
/// from the column, through the box when z = 1.155.
std::string box_section(double z, const std::string& extra = "") {
  return fmt::format(
      "[collision]\nclearance = 0.02\n{}\n[[collision.object]]\nname = \"box\"\nsize = [0.05, "
      "0.05, 0.05]\npos = [0.6, 0.6, {}]\n",
      extra, z);
}

struct Cell {
  explicit Cell(const std::string& collision) : text(set_text(collision)) {
    config = parse_process_set(text, kFile);
    model = test::stock_model("irb6");
    guard =
        std::make_unique<CollisionGuard>(model, config.robots.at(0), config.collision, model.mjcf);
  }
  std::string text;
  ProcessSetConfig config;
  RobotModel model;
  std::unique_ptr<CollisionGuard> guard;
};

std::vector<double> along(const std::vector<double>& a, const std::vector<double>& b, int k,
                          int steps) {
  std::vector<double> q(a.size());
  for (std::size_t i = 0; i < q.size(); ++i)
    q[i] = a[i] + (b[i] - a[i]) * static_cast<double>(k) / steps;
  return q;
}

/// The refusal of `check_path`, or nothing when it passes.
std::optional<CommandError> refusal(CollisionGuard& guard, const std::vector<double>& start,
                                    const std::vector<double>& target, int steps) {
  try {
    guard.check_path(start, target, steps);
  } catch (const CommandError& e) {
    return e;
  }
  return std::nullopt;
}

const std::vector<double> kSynchro{0.0, -kPi / 2, 0.0, 0.0, 0.0};
/// The column turned by 90 degrees: the arm sweeps through the column angle of 45 degrees.
const std::vector<double> kTurned{kPi / 2, -kPi / 2, 0.0, 0.0, 0.0};
constexpr int kSteps = 500;  // 1 s at 2 ms

}  // namespace

TEST(CollisionGuard, APathThroughABoxIsRefusedBeforeTheFirstStepThatTouchesIt) {
  Cell cell(box_section(1.155));
  CollisionGuard& guard = *cell.guard;
  EXPECT_FALSE(guard.closest(kSynchro).has_value()) << "the synchronisation pose is clear";
  const std::optional<CommandError> e = refusal(guard, kSynchro, kTurned, kSteps);
  ASSERT_TRUE(e.has_value()) << "a path through the box passed";
  EXPECT_EQ(e->code(), error_code::collision);
  const std::string text = e->what();
  std::smatch m;
  ASSERT_TRUE(std::regex_search(
      text, m,
      std::regex(
          R"(SET refused: (link '\w+') would (?:come within ([0-9.]+) m of|penetrate) )"
          R"(('box')(?: by ([0-9.]+) m)? \(clearance 0\.02 m\) at servo step (\d+) of 500)")))
      << text;
  const std::string link = m[1].str();
  const int step = std::stoi(m[5].str());
  // The refused step: the guard's own answer there is the named pair within the clearance.
  const std::optional<Proximity> at = guard.closest(along(kSynchro, kTurned, step, kSteps));
  ASSERT_TRUE(at.has_value()) << text;
  EXPECT_LT(at->distance, guard.clearance());
  EXPECT_TRUE((at->first == link && at->second == "'box'") ||
              (at->second == link && at->first == "'box'"))
      << at->first << " - " << at->second << " vs " << text;
  // No servo step before it touches the box (every one of them, not only those it sampled), and
  // the refusal comes before the arm reaches 45 degrees (step 250), where it is inside the box.
  EXPECT_LT(step, 250) << text;
  for (int k = 0; k < step; ++k) {
    const std::optional<Proximity> p = guard.closest(along(kSynchro, kTurned, k, kSteps));
    if (p) {
      EXPECT_GT(p->distance, 0.0) << "step " << k << ": " << p->first << " - " << p->second;
    }
  }
  std::printf("refusal: %s (sampled every %d steps)\n", text.c_str(),
              guard.sample_stride(kSynchro, kTurned, kSteps));
}

TEST(CollisionGuard, TheSamePathInTenMacroStepsIsRefusedAtTheSameServoStep) {
  // Each macro-step starts where the last one that passed ended (the guard reuses that pose's
  // pairs instead of evaluating it again): the refusal falls on the same servo step of the whole
  // path as when it is one macro-step.
  Cell one(box_section(1.155));
  const std::optional<CommandError> whole = refusal(*one.guard, kSynchro, kTurned, kSteps);
  ASSERT_TRUE(whole.has_value());
  std::smatch m;
  const std::string whole_text = whole->what();
  ASSERT_TRUE(std::regex_search(whole_text, m, std::regex(R"(at servo step (\d+) of 500)")));
  const int step = std::stoi(m[1].str());

  Cell cell(box_section(1.155));
  const long poses_before = cell.guard->poses_checked();
  int segment = 0;
  std::optional<CommandError> e;
  for (; segment < 10 && !e; ++segment)
    e = refusal(*cell.guard, along(kSynchro, kTurned, 50 * segment, kSteps),
                along(kSynchro, kTurned, 50 * (segment + 1), kSteps), 50);
  ASSERT_TRUE(e.has_value());
  const std::string text = e->what();
  ASSERT_TRUE(std::regex_search(text, m, std::regex(R"(at servo step (\d+) of 50)"))) << text;
  EXPECT_EQ(50 * (segment - 1) + std::stoi(m[1].str()), step) << text << " vs " << whole_text;
  // The start of every macro-step but the first came from the one before.
  EXPECT_EQ(cell.guard->poses_checked() - poses_before, 1 + step) << text;
}

TEST(CollisionGuard, APathBesideTheBoxWithItsClearancePasses) {
  // The box raised so that its bottom is 0.03 m above the top of the wrist link passing under
  // it (z 1.155 + its radius 0.05; the upper arm, thicker, ends before the box): 0.01 m more
  // than the clearance of 0.02 m.
  Cell cell(box_section(1.155 + 0.05 + 0.03 + 0.05));
  EXPECT_FALSE(refusal(*cell.guard, kSynchro, kTurned, kSteps).has_value());
  // The other way round the column: away from the box.
  Cell low(box_section(1.155));
  const std::vector<double> away{-kPi / 2, -kPi / 2, 0.0, 0.0, 0.0};
  EXPECT_FALSE(refusal(*low.guard, kSynchro, away, kSteps).has_value());
  // Its bottom 0.01 m above the wrist: within the clearance, refused (the figures above are
  // what decide).
  Cell near(box_section(1.155 + 0.05 + 0.01 + 0.05));
  EXPECT_TRUE(refusal(*near.guard, kSynchro, kTurned, kSteps).has_value());
}

TEST(CollisionGuard, AllowedPairsAndPairsTouchingAtTheSynchronisationPose) {
  // The roll link reaches into the end of the upper arm (by design): allowed at the
  // synchronisation pose, so that a wrist motion is not refused for it.
  Cell cell("[collision]\n");
  EXPECT_NE(cell.guard->describe().find("link 'upper_arm_link' - link 'roll_link'"),
            std::string::npos)
      << cell.guard->describe();
  const std::vector<double> wrist{0.0, -kPi / 2, 0.0, 1.2, 2.0};
  EXPECT_FALSE(refusal(*cell.guard, kSynchro, wrist, kSteps).has_value());

  // Every link the box can meet allowed: the path through it passes.
  Cell allowed(box_section(1.155,
                           "allow = [[\"irb6/upper_arm_link\", \"box\"], [\"irb6/wrist_link\", "
                           "\"box\"], [\"irb6/roll_link\", \"box\"], [\"box\", "
                           "\"irb6/lower_arm_link\"]]"));
  EXPECT_FALSE(refusal(*allowed.guard, kSynchro, kTurned, kSteps).has_value());
}

TEST(CollisionGuard, StartingInsideTheClearanceMayMoveAwayButNotCloser) {
  // The first column angle towards the box at which a link is within the clearance (0.02 m) of
  // it: from there moving back passes, moving on towards the box is refused.
  Cell cell(box_section(1.155));
  std::vector<double> inside = kSynchro;
  std::optional<Proximity> p;
  while (inside[0] < kPi / 4) {
    p = cell.guard->closest(inside);
    if (p) break;
    inside[0] += 0.001;
  }
  ASSERT_TRUE(p.has_value());
  EXPECT_GT(p->distance, 0.0);
  EXPECT_LT(p->distance, 0.02);
  EXPECT_FALSE(refusal(*cell.guard, inside, kSynchro, kSteps).has_value());
  const std::optional<CommandError> e = refusal(*cell.guard, inside, kTurned, kSteps);
  ASSERT_TRUE(e.has_value());
  EXPECT_NE(std::string(e->what()).find("closer than the"), std::string::npos) << e->what();
}

TEST(CollisionGuard, ConfigMistakesNameFileAndLine) {
  {
    const std::string text = set_text("[collision]\nclearance = -0.01\n");
    try {
      parse_process_set(text, kFile);
      ADD_FAILURE() << "a negative clearance was accepted";
    } catch (const ConfigError& e) {
      const std::string prefix =
          kFile.string() + ":" + std::to_string(line_of(text, "clearance")) + ": error: ";
      EXPECT_EQ(std::string(e.what()).rfind(prefix, 0), 0U) << e.what();
      EXPECT_NE(std::string(e.what()).find("'clearance' = -0.01 m is outside (0, 0.5] m"),
                std::string::npos)
          << e.what();
    }
  }
  {
    const std::string text = set_text(box_section(1.0, "allow = [[\"box\", \"table\"]]"));
    try {
      parse_process_set(text, kFile);
      ADD_FAILURE() << "an allowed pair naming no object was accepted";
    } catch (const ConfigError& e) {
      EXPECT_EQ(std::string(e.what()).rfind(
                    kFile.string() + ":" + std::to_string(line_of(text, "allow")) + ": error: ", 0),
                0U)
          << e.what();
      EXPECT_NE(std::string(e.what()).find("'table', which is no [[collision.object]]"),
                std::string::npos)
          << e.what();
    }
  }
  {
    const std::string text = set_text(
        "[collision]\n[[collision.object]]\nname = \"box\"\nsize = [0.05, 0.0, 0.05]\npos = [1, "
        "0, 0]\n");
    try {
      parse_process_set(text, kFile);
      ADD_FAILURE() << "a box of half-size 0 was accepted";
    } catch (const ConfigError& e) {
      EXPECT_EQ(std::string(e.what()).rfind(
                    kFile.string() + ":" + std::to_string(line_of(text, "size")) + ": error: ", 0),
                0U)
          << e.what();
      EXPECT_NE(std::string(e.what()).find("half-size y = 0 m is outside (0, 100] m"),
                std::string::npos)
          << e.what();
    }
  }
  {
    // Parses (the robot exists); the guard finds that its model has no such link.
    const std::string text = set_text(box_section(1.0, "allow = [[\"irb6/hand\", \"box\"]]"));
    const ProcessSetConfig config = parse_process_set(text, kFile);
    const RobotModel model = test::stock_model("irb6");
    try {
      CollisionGuard guard(model, config.robots.at(0), config.collision, model.mjcf);
      ADD_FAILURE() << "an allowed pair naming no link of the model was accepted";
    } catch (const ConfigError& e) {
      EXPECT_EQ(std::string(e.what()).rfind(
                    kFile.string() + ":" + std::to_string(line_of(text, "allow")) + ": error: ", 0),
                0U)
          << e.what();
      EXPECT_NE(std::string(e.what()).find("robot 'irb6' has no link 'hand'"), std::string::npos)
          << e.what();
    }
  }
}

TEST(CollisionGuard, AnObjectTouchingTheSynchronisationPoseIsAConfigError) {
  // A floor whose top is at z = 0: the column's capsule (radius 0.12 m from z = 0) reaches into
  // it. Without an allowed pair the guard refuses the configuration, at the object's table.
  auto floor = [](const std::string& allow) {
    return "[collision]\n" + allow +
           "[[collision.object]]\nname = \"floor\"\nsize = [3.0, 3.0, 0.05]\npos = [0.0, "
           "0.0, -0.05]\n";
  };
  const std::string text = set_text(floor(""));
  const ProcessSetConfig config = parse_process_set(text, kFile);
  const RobotModel model = test::stock_model("irb6");
  try {
    CollisionGuard guard(model, config.robots.at(0), config.collision, model.mjcf);
    ADD_FAILURE() << "a floor through the column was accepted";
  } catch (const ConfigError& e) {
    const std::string what = e.what();
    EXPECT_EQ(what.rfind(kFile.string() + ":" +
                             std::to_string(line_of(text, "[[collision.object]]")) + ": error: ",
                         0),
              0U)
        << what;
    EXPECT_NE(what.find("object 'floor' is inside link 'column_link' of robot 'irb6' at its "
                        "synchronisation pose (distance -0.1200 m, clearance 0.01 m)"),
              std::string::npos)
        << what;
    EXPECT_NE(what.find("allow = [[\"irb6/column_link\", \"floor\"]]"), std::string::npos) << what;
  }
  // With the pair allowed it is accepted, and the column may turn on the floor.
  Cell allowed(floor("allow = [[\"irb6/column_link\", \"floor\"]]\n"));
  EXPECT_FALSE(refusal(*allowed.guard, kSynchro, kTurned, kSteps).has_value());
}

TEST(CollisionGuard, OffUnlessTheSetHasACollisionSection) {
  const RobotModel model = test::stock_model("irb6");
  std::string why;
  const ProcessSetConfig without = parse_process_set(set_text(""), kFile);
  EXPECT_EQ(CollisionGuard::make(model, without.robots.at(0), without.collision, model.mjcf, why),
            nullptr);
  EXPECT_NE(why.find("has no [collision] section"), std::string::npos) << why;
  const ProcessSetConfig off = parse_process_set(set_text("[collision]\nenabled = false\n"), kFile);
  EXPECT_EQ(CollisionGuard::make(model, off.robots.at(0), off.collision, model.mjcf, why), nullptr);
  EXPECT_NE(why.find("enabled = false"), std::string::npos) << why;
  const ProcessSetConfig on = parse_process_set(set_text("[collision]\n"), kFile);
  EXPECT_NE(CollisionGuard::make(model, on.robots.at(0), on.collision, model.mjcf, why), nullptr)
      << why;
}
