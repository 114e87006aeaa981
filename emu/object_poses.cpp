/// @file
/// ObjectPosePublisher: the scene objects' poses as scene_objects_t (object_poses.hpp).
#include "object_poses.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <exception>

#include "mrroc/comm/auth.hpp"
#include "mrroc/comm/messages.hpp"
#include "mrroc/config/process_set.hpp"
#include "mrroc/core/error.hpp"

namespace mrroc::emu {

namespace {

SceneObjectShape plain_shape(ObjectShape shape) noexcept {
  switch (shape) {
    case ObjectShape::box: return SceneObjectShape::box;
    case ObjectShape::sphere: return SceneObjectShape::sphere;
    case ObjectShape::cylinder: return SceneObjectShape::cylinder;
    case ObjectShape::capsule: return SceneObjectShape::capsule;
  }
  return SceneObjectShape::box;
}

}  // namespace

SceneObjects ObjectPosePublisher::describe(const Scene& scene) {
  SceneObjects out;
  out.scene = scene.name;
  for (const SceneObject& o : scene.objects) {
    SceneObjectPose p;
    p.name = o.name;
    p.shape = plain_shape(o.shape);
    p.size = o.size;
    // MuJoCo reads the sizes a shape needs and ignores the rest.
    p.size.resize(std::min(p.size.size(), scene_object_size_count(p.shape)));
    p.rgba = o.rgba;
    p.attach = o.attach;
    p.local_position = o.position;
    // The rotation vector as a quaternion (w, x, y, z).
    const double angle = std::hypot(o.rotation[0], o.rotation[1], o.rotation[2]);
    if (angle > 0.0) {
      const double s = std::sin(angle / 2.0) / angle;
      p.local_quaternion = {std::cos(angle / 2.0), s * o.rotation[0], s * o.rotation[1],
                            s * o.rotation[2]};
    }
    out.objects.push_back(std::move(p));
  }
  return out;
}

ObjectPosePublisher::ObjectPosePublisher(lcm::LCM& lcm, const Scene& scene, const CellWorld& world,
                                         const std::string& sender, comm::Authenticator* auth)
    : lcm_(lcm), auth_(auth), channel_(channels::scene_objects) {
  message_ = comm::encode(describe(scene));
  message_.header.sender = sender;
  message_.header.kind = mrroc_lcm::header_t::BROADCAST;
  message_.header.auth_tag.reserve(sizeof(comm::Authenticator::Tag));
  for (const SceneObject& o : scene.objects) {
    const int id = world.body_id(o.name);
    if (id < 0)
      throw Error(
          fmt::format("scene '{}': object '{}' has no body in the cell world", scene.name, o.name));
    bodies_.push_back(id);
  }
  const auto size = static_cast<std::size_t>(message_.getEncodedSize());
  if (auth_ != nullptr) {
    unsigned_bytes_.resize(size);
    mac_input_.reserve(comm::Authenticator::mac_input_size(channel_, size));
    buffer_.resize(size + sizeof(comm::Authenticator::Tag));
  } else {
    buffer_.resize(size);
  }
}

const mrroc_lcm::scene_objects_t& ObjectPosePublisher::fill(const CellWorld& world,
                                                            std::int64_t wall_utime) noexcept {
  message_.header.utime = wall_utime;
  message_.sim_time_s = world.time();
  for (std::size_t i = 0; i < bodies_.size(); ++i) {
    const FramePose pose = world.body_pose(bodies_[i]);
    mrroc_lcm::scene_object_t& o = message_.objects[i];
    std::copy(pose.position.begin(), pose.position.end(), o.position);
    std::copy(pose.quaternion.begin(), pose.quaternion.end(), o.quaternion);
  }
  return message_;
}

bool ObjectPosePublisher::update(const CellWorld& world, std::int64_t wall_utime) noexcept {
  if (bodies_.empty() || wall_utime < next_utime_) return true;
  // On the grid of the first publication; the first one and after a stall of a period or
  // more, from now (no burst).
  next_utime_ =
      wall_utime - next_utime_ >= kPeriodUs ? wall_utime + kPeriodUs : next_utime_ + kPeriodUs;
  return publish(world, wall_utime);
}

bool ObjectPosePublisher::publish(const CellWorld& world, std::int64_t wall_utime) noexcept {
  mrroc_lcm::scene_objects_t& m = message_;
  (void)fill(world, wall_utime);
  m.header.seq = seq_++;
  bool ok = true;
  if (auth_ != nullptr) {
    // As comm::sign: the tag covers the channel and the message encoded with an empty tag.
    try {
      m.header.auth_counter = auth_->next_counter();
      m.header.auth_tag.clear();
      m.header.auth_len = 0;
      const int plain = static_cast<int>(unsigned_bytes_.size());
      ok = m.encode(unsigned_bytes_.data(), 0, plain) == plain;
      const comm::Authenticator::Tag tag =
          auth_->mac(channel_, unsigned_bytes_.data(), unsigned_bytes_.size(), mac_input_);
      m.header.auth_tag.assign(tag.begin(), tag.end());
      m.header.auth_len = static_cast<std::int16_t>(tag.size());
    } catch (const std::exception&) {
      ok = false;  // OpenSSL failed: nothing unsigned goes out
    }
  }
  const int size = static_cast<int>(buffer_.size());
  ok = ok && m.encode(buffer_.data(), 0, size) == size &&
       lcm_.publish(channel_, buffer_.data(), static_cast<unsigned>(size)) == 0;
  ++(ok ? published_ : failed_);
  return ok;
}

}  // namespace mrroc::emu
