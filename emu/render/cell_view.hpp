#pragma once
// The cell of a process set as one MuJoCo model for drawing: every robot of the set from its own
// model folder (or the set's cell scene, for sets on the cell emulator), posed from joint
// positions. Nothing is simulated: each pose is set (a = M q on the actuator joints, closed
// kinematic loops solved, forward kinematics), so the picture shows exactly the joints given.

#include <array>
#include <cstddef>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include <mujoco/mujoco.h>

#include "mrroc/config/process_set.hpp"
#include "mrroc/sim/mujoco_support.hpp"

namespace mrroc::render {

class CellView {
 public:
  /// The set's [emulator] scene when it has one (with any robot of the set the scene lacks added
  /// at its base), else a scene of the set's robots, each at its `base`. The robots start at
  /// their power-on poses. The model is dressed for pictures (a tiled floor, a sky, a headlight
  /// and shadows); nothing that moves is added.
  /// @throws ConfigError or HardwareError (a model folder without MJCF, a model MuJoCo cannot
  ///   load ...), naming the robot and the file.
  explicit CellView(const ProcessSetConfig& set);

  [[nodiscard]] const std::string& name() const noexcept { return name_; }
  [[nodiscard]] mjModel* model() noexcept { return model_.get(); }
  [[nodiscard]] const mjModel* model() const noexcept { return model_.get(); }
  [[nodiscard]] const mjData* data() const noexcept { return data_.get(); }
  [[nodiscard]] std::size_t robot_count() const noexcept { return robots_.size(); }
  [[nodiscard]] const std::string& robot_name(std::size_t k) const { return robots_.at(k).name; }
  [[nodiscard]] std::size_t axis_count(std::size_t k) const { return robots_.at(k).q.size(); }
  /// Index of the robot named `robot`, if the cell has it.
  [[nodiscard]] std::optional<std::size_t> robot_index(const std::string& robot) const;
  /// Every robot's names in the model, for messages ("irb6, conveyor").
  [[nodiscard]] std::string robot_names() const;

  /// Robot k's joint positions q [rad or m], used by the next pose(). @throws Error when the
  /// number of values is not the robot's number of axes.
  void set_joints(std::size_t k, std::span<const double> q);
  /// Puts the free object `name` of the scene (a `[[scene.object]]` without `attach`) at a world
  /// pose for the next pose(): position [m], unit quaternion (w, x, y, z; normalised here).
  /// Returns false when the cell has no free object of that name (objects fixed to the world or
  /// to a robot move with what holds them).
  bool set_object(const std::string& name, const std::array<double, 3>& position,
                  const std::array<double, 4>& quaternion);

  /// Puts every robot at its joint positions: actuator joints at a = M q, the kinematic loops
  /// closed, positions of every body and geom computed. Returns the largest loop violation left
  /// [m or rad] (0 without loops).
  double pose();

  /// The world-frame box [m] around every robot's bodies in the current pose: min x y z, max x y
  /// z (the world body and the floor excluded).
  void robot_bounds(double low[3], double high[3]) const;

 private:
  struct Robot {
    std::string name;
    std::vector<double> coupling;  // M of a = M q, row-major
    std::vector<int> qpos_adr;     // of the actuator joints
    std::vector<double> q;         // current joint positions
    std::vector<int> bodies;       // the robot's bodies
  };

  std::string name_;
  sim::ModelPtr model_;
  sim::DataPtr data_;
  std::vector<Robot> robots_;
};

}  // namespace mrroc::render
