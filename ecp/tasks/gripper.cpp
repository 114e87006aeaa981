#include "gripper.hpp"

#include <fmt/format.h>

#include <chrono>
#include <cmath>
#include <thread>

namespace mrroc::ecp {

namespace {
constexpr std::size_t kReplyFields = 4;  // opening, speed, force, holding
constexpr double kSettleTimeoutS = 10.0;
// Readings in a row below kStoppedSpeed that count as stopped, and the first readings ignored
// (the reply to the SET itself was measured before the fingers were commanded).
constexpr int kStoppedReadings = 5;
constexpr int kIgnoredReadings = 3;
}  // namespace

void Gripper::write_device_command(std::vector<double>& command) const {
  command = {command_opening_, command_force_};
}

void Gripper::read_device_reply(const std::vector<double>& reply) {
  if (reply.size() != kReplyFields)
    throw Error(
        fmt::format("robot '{}': the EDP's device replied {} fields, a gripper has {} "
                    "(opening, speed, force, holding): is its plugin's device a gripper?",
                    name(), reply.size(), kReplyFields));
  width_ = reply[0];
  speed_ = reply[1];
  force_ = reply[2];
  holding_ = reply[3] > 0.5;
}

void Gripper::read_device() {
  const edp::Instruction saved = image().command;
  image().command = edp::Instruction{};
  image().command.type = edp::InstructionType::get;
  image().command.get = edp::item::device;
  execute();
  image().command = saved;
}

void Gripper::move_fingers(double opening_m, double force_n) {
  if (stop_requested()) throw TaskStopped("task stopped on request");
  wait_while_paused();  // as Move: a PAUSE holds before the next command
  command_opening_ = opening_m;
  command_force_ = force_n;
  const edp::Instruction saved = image().command;
  image().command = edp::Instruction{};
  image().command.type = edp::InstructionType::set_get;
  image().command.set = edp::item::device;
  image().command.get = edp::item::device;
  execute();
  image().command = saved;
  const auto deadline =
      std::chrono::steady_clock::now() + std::chrono::duration<double>(kSettleTimeoutS);
  int readings = 0;
  int stopped = 0;
  while (stopped < kStoppedReadings) {
    if (stop_requested()) throw TaskStopped("task stopped on request");
    if (std::chrono::steady_clock::now() > deadline)
      throw TimeoutError(
          fmt::format("robot '{}': the gripper's fingers did not stop within {} s "
                      "(opening {:.4f} m, speed {:.4f} m/s)",
                      name(), kSettleTimeoutS, width_, speed_));
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
    read_device();
    ++readings;
    stopped = readings > kIgnoredReadings && std::abs(speed_) < kStoppedSpeed ? stopped + 1 : 0;
  }
}

void Gripper::close(double force_n) { move_fingers(0.0, force_n); }

void Gripper::open() { move_fingers(kMaxOpening, kOpenForce); }

}  // namespace mrroc::ecp
