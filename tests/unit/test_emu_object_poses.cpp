/// @file
/// The cell emulator's publication of its scene objects (emu/object_poses.hpp): every object of
/// the scene file (tests/browser/view-objects/scene.toml: one of each shape, fixed to the world,
/// to the conveyor's belt, or free) with its shape, size, colour and attach as the file gives
/// them, and its pose equal to the MuJoCo world's at the moment of publication, while the belt
/// carries the part and the free bodies settle; about 30 messages a second of wall-clock time,
/// without allocating; signed with the set's key for its channel; decoded by comm::decode.

#include <array>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <mujoco/mujoco.h>
#include <lcm/lcm-cpp.hpp>

#include "cell_world.hpp"
#include "mrroc/comm/auth.hpp"
#include "mrroc/comm/messages.hpp"
#include "mrroc/config/process_set.hpp"
#include "mrroc/core/error.hpp"
#include "object_poses.hpp"
#include "scene.hpp"

#ifndef MRROC_SOURCE_DIR
#error "MRROC_SOURCE_DIR must be defined (absolute path of the source tree)"
#endif

#include "heap_counter.hpp"

namespace {

using mrroc::emu::CellWorld;
using mrroc::emu::ObjectPosePublisher;

constexpr std::int64_t kEpochUtime = 1'700'000'000'000'000;  // the tests' wall clock at t = 0

std::filesystem::path scene_path() {
  return std::filesystem::path(MRROC_SOURCE_DIR) / "tests/browser/view-objects/scene.toml";
}

struct Received {
  std::vector<mrroc_lcm::scene_objects_t> messages;
  std::vector<std::string> channels;
  static void on(const lcm::ReceiveBuffer*, const std::string& channel,
                 const mrroc_lcm::scene_objects_t* message, Received* self) {
    self->messages.push_back(*message);
    self->channels.push_back(channel);
  }
};

/// The world's pose of body `name` (position, quaternion w x y z) and of its geom.
struct WorldPose {
  std::array<double, 3> position{}, geom_position{};
  std::array<double, 4> quaternion{};
};

WorldPose world_pose(const CellWorld& world, const std::string& name) {
  const mjModel* m = world.model();
  const mjData* d = world.data();
  const int body = mj_name2id(m, mjOBJ_BODY, name.c_str());
  const int geom = mj_name2id(m, mjOBJ_GEOM, name.c_str());
  EXPECT_GE(body, 0) << name;
  EXPECT_GE(geom, 0) << name;
  WorldPose p;
  for (int i = 0; i < 3; ++i) {
    p.position[static_cast<std::size_t>(i)] = d->xpos[3 * body + i];
    p.geom_position[static_cast<std::size_t>(i)] = d->geom_xpos[3 * geom + i];
  }
  for (int i = 0; i < 4; ++i) p.quaternion[static_cast<std::size_t>(i)] = d->xquat[4 * body + i];
  return p;
}

/// Steps `world` for `steps` ms with the belt's target at `belt` m, calling update() after each
/// step with a wall clock 1 ms per step; records the world's poses of every object whenever a
/// message went out. Returns the allocations made by update().
long run(CellWorld& world, ObjectPosePublisher& publisher, lcm::LCM& lcm, int steps, double belt,
         const mrroc::emu::Scene& scene, std::vector<std::vector<WorldPose>>& expected) {
  long allocations = 0;
  const std::size_t conveyor = world.robot_index("conveyor");
  const std::array<double, 1> target = {belt};
  EXPECT_TRUE(world.set_targets(conveyor, target));
  for (int i = 0; i < steps; ++i) {
    EXPECT_TRUE(world.step()) << world.fault_text();
    const std::int64_t now = kEpochUtime + std::llround(world.time() * 1e6);
    const std::uint64_t before = publisher.published();
    g_heap.allocations = 0;
    g_heap.counting = true;
    EXPECT_TRUE(publisher.update(world, now));
    g_heap.counting = false;
    allocations += g_heap.allocations;
    if (publisher.published() != before) {
      std::vector<WorldPose> poses;
      for (const auto& o : scene.objects) poses.push_back(world_pose(world, o.name));
      expected.push_back(std::move(poses));
    }
    while (lcm.handleTimeout(0) > 0) {
    }
  }
  return allocations;
}

const char* shape_text(mrroc::SceneObjectShape shape) {
  switch (shape) {
    case mrroc::SceneObjectShape::box: return "box";
    case mrroc::SceneObjectShape::sphere: return "sphere";
    case mrroc::SceneObjectShape::cylinder: return "cylinder";
    case mrroc::SceneObjectShape::capsule: return "capsule";
  }
  return "?";
}

}  // namespace

TEST(EmuObjectPoses, PublishedPosesAreTheWorldsAtThirtyAPerSecond) {
  lcm::LCM lcm("memq://");
  ASSERT_TRUE(lcm.good());
  Received received;
  lcm.subscribeFunction<mrroc_lcm::scene_objects_t, Received*>(".*", &Received::on, &received);
  const mrroc::emu::Scene scene = mrroc::emu::load_scene(scene_path());
  ASSERT_EQ(scene.objects.size(), 6U);
  CellWorld world(scene);
  ObjectPosePublisher publisher(lcm, scene, world, "test#1");
  EXPECT_EQ(publisher.size(), 6U);
  std::vector<std::vector<WorldPose>> expected;
  // 1 s of the belt moving towards 0.5 m, 1 s more.
  EXPECT_EQ(run(world, publisher, lcm, 1000, 0.5, scene, expected), 0);
  EXPECT_EQ(publisher.failed(), 0U);
  // Every 33.3 ms of wall clock from the first step: 30 in 1 s.
  EXPECT_EQ(received.messages.size(), 30U);
  EXPECT_EQ(run(world, publisher, lcm, 1000, 0.5, scene, expected), 0);
  ASSERT_EQ(received.messages.size(), 60U);
  ASSERT_EQ(expected.size(), received.messages.size());

  for (std::size_t k = 0; k < received.messages.size(); ++k) {
    const mrroc_lcm::scene_objects_t& m = received.messages[k];
    EXPECT_EQ(received.channels[k], mrroc::channels::scene_objects);
    EXPECT_EQ(m.header.sender, "test#1");
    EXPECT_EQ(int{m.header.kind}, int{mrroc_lcm::header_t::BROADCAST});
    EXPECT_EQ(m.header.seq, static_cast<std::int64_t>(k));
    EXPECT_EQ(m.header.auth_len, 0);
    const mrroc::SceneObjects plain = mrroc::comm::decode(m);
    EXPECT_EQ(plain.scene, "view-objects");
    ASSERT_EQ(plain.objects.size(), scene.objects.size());
    for (std::size_t i = 0; i < plain.objects.size(); ++i) {
      const mrroc::SceneObjectPose& o = plain.objects[i];
      const mrroc::emu::SceneObject& s = scene.objects[i];
      EXPECT_EQ(o.name, s.name);
      EXPECT_STREQ(shape_text(o.shape), mrroc::emu::shape_name(s.shape));
      EXPECT_EQ(o.size, s.size) << o.name;
      EXPECT_EQ(o.rgba, s.rgba) << o.name;
      EXPECT_EQ(o.attach, s.attach) << o.name;
      EXPECT_EQ(o.local_position, s.position) << o.name;
      const WorldPose& w = expected[k][i];
      EXPECT_EQ(o.position, w.position) << o.name << " in message " << k;
      EXPECT_EQ(o.quaternion, w.quaternion) << o.name << " in message " << k;
      for (std::size_t j = 0; j < 3; ++j)  // the geom sits at its body's origin
        EXPECT_NEAR(o.position[j], w.geom_position[j], 1e-12) << o.name;
    }
    // The bar's rotation vector (0, 0, 0.3) as a quaternion.
    EXPECT_NEAR(plain.objects[2].local_quaternion[0], std::cos(0.15), 1e-15);
    EXPECT_NEAR(plain.objects[2].local_quaternion[3], std::sin(0.15), 1e-15);
  }
  // The belt carried the part along x (towards 0.5 m of belt travel).
  const mrroc::SceneObjects first = mrroc::comm::decode(received.messages.front());
  const mrroc::SceneObjects last = mrroc::comm::decode(received.messages.back());
  EXPECT_GT(last.objects[0].position[0] - first.objects[0].position[0], 0.3);
  EXPECT_NEAR(last.objects[0].position[1], -0.65, 1e-6);
  // The table stays where the file puts it; the bar lies on it, the ball on the floor.
  for (std::size_t j = 0; j < 3; ++j)
    EXPECT_NEAR(last.objects[1].position[j], (std::array<double, 3>{0.0, 0.5, 0.2})[j], 1e-12);
  EXPECT_NEAR(last.objects[2].position[2], 0.42, 2e-3);
  EXPECT_NEAR(last.objects[3].position[2], 0.05, 2e-3);
  EXPECT_GT(last.sim_time_s, first.sim_time_s);
}

// With the set's key each message is signed for its channel, still without allocating.
TEST(EmuObjectPoses, SignedMessagesVerifyOnTheirChannel) {
  lcm::LCM lcm("memq://");
  ASSERT_TRUE(lcm.good());
  Received received;
  lcm.subscribeFunction<mrroc_lcm::scene_objects_t, Received*>(".*", &Received::on, &received);
  const std::vector<std::uint8_t> key(32, 7);
  mrroc::comm::Authenticator receiver(key);
  mrroc::comm::Authenticator signer(key);
  const mrroc::emu::Scene scene = mrroc::emu::load_scene(scene_path());
  CellWorld world(scene);
  ObjectPosePublisher publisher(lcm, scene, world, "test#1", &signer);
  std::vector<std::vector<WorldPose>> expected;
  EXPECT_EQ(run(world, publisher, lcm, 200, 0.1, scene, expected), 0);
  ASSERT_EQ(received.messages.size(), 6U);
  for (const auto& m : received.messages) {
    EXPECT_EQ(m.header.auth_len, 32);
    EXPECT_EQ(mrroc::comm::verify(receiver, m, "mrroc/elsewhere"),
              mrroc::comm::Authenticator::Verdict::bad_tag);
    EXPECT_EQ(mrroc::comm::verify(receiver, m, mrroc::channels::scene_objects),
              mrroc::comm::Authenticator::Verdict::ok);
  }
}

// A scene without objects publishes nothing; a stall of the caller gives no burst.
TEST(EmuObjectPoses, NothingWithoutObjectsAndNoBurstAfterAStall) {
  lcm::LCM lcm("memq://");
  ASSERT_TRUE(lcm.good());
  Received received;
  lcm.subscribeFunction<mrroc_lcm::scene_objects_t, Received*>(".*", &Received::on, &received);
  mrroc::emu::Scene scene = mrroc::emu::load_scene(scene_path());
  CellWorld world(scene);
  ObjectPosePublisher publisher(lcm, scene, world, "test#1");
  EXPECT_TRUE(publisher.update(world, kEpochUtime));
  EXPECT_TRUE(publisher.update(world, kEpochUtime + 1000));       // not due
  EXPECT_TRUE(publisher.update(world, kEpochUtime + 1'000'000));  // 1 s later: one, not 30
  EXPECT_TRUE(publisher.update(world, kEpochUtime + 1'001'000));
  EXPECT_TRUE(publisher.update(world, kEpochUtime + 1'000'000 + ObjectPosePublisher::kPeriodUs));
  while (lcm.handleTimeout(0) > 0) {
  }
  EXPECT_EQ(received.messages.size(), 3U);

  scene.objects.clear();
  const CellWorld empty_world(scene);
  ObjectPosePublisher none(lcm, scene, empty_world, "test#2");
  EXPECT_EQ(none.size(), 0U);
  EXPECT_TRUE(none.update(empty_world, kEpochUtime));
  EXPECT_EQ(none.published(), 0U);
}
