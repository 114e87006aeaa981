#pragma once
/// @file
/// `CellWorld`: the physics of a whole robot cell in ONE MuJoCo 2.2 world — several robots (two
/// IRb-6s, the conveyor, the RNT, ...) and objects, as a scene file lists them (scene.hpp). The
/// axis emulator exposes every axis of it as an emulated drive.
///
/// Robots and axes. Robot k is the k-th `[[scene.robot]]`; every MuJoCo name of it is prefixed
/// with "<robot>/" ("left/column", "left/flange"), and its base body is named after the robot
/// ("left"). Its axes are its MJCF's actuators in order: axis i is a position servo on one hinge
/// or slide joint, its *actuator joint*, whose position is a_i. The robot's joint coordinates q
/// (its URDF's serial chain) follow from a = M q, M being the coupling of parameters.toml
/// (identity by default; the RNT's elbow drive turns q1 + q2). Drives work in actuator
/// coordinates a: `set_targets`, `actuator_positions`, ... take and give a; `joint_positions`
/// converts to q.
///
/// Units: rad (hinge) or m (slide) for positions; per second for velocities; N m or N for forces;
/// s for time; world frame in m with quaternions (w, x, y, z).
///
/// Physics per step (`step()`): the actuators' position servos track their targets (clamped into
/// the actuators' ctrlrange); a robot with gravity compensation gets the gravity/Coriolis
/// feed-forward qfrc_applied = qfrc_bias on all its degrees of freedom (as the `mujoco` EDP
/// plugin does; objects attached to a robot's body are compensated with it, free objects are
/// not); a velocity feed-forward damping * v_target adds to each actuator joint. Kinematic loops
/// are closed at power-on exactly as in the plugin (sim::close_loops).
///
/// Instability (a non-finite state, a MuJoCo warning, a closed loop opening by more than
/// `kLoopOpenFault`) makes `step()` return false with `fault_text()` naming the robot and axis
/// (or object); the fault is latched — `step()` does nothing — until `reset()`.
///
/// Contacts: objects collide as the scene file says (scene.hpp: `contact`, `solref`,
/// `friction`); a stiffness solref [N/m, N s/m] is converted at construction into MuJoCo's
/// per-unit-mass form (solref and a constant solimp) so that the static contact force is
/// stiffness * penetration against a fixed body (the conversion uses MuJoCo's own approximation of
/// the contact's inverse mass, body_invweight0, the friction cone, the contact dimension and
/// impratio), with kSpringContactAddedMass.
///
/// Grasps (scene.hpp, [[scene.object.grasp]]): each is a weld equality constraint between the
/// gripper's body and a free object, inactive until step() finds the gripper frame within the
/// grasp's engage distance and angle of its grasp frame on the object and moving relative to it
/// no faster than its engage speed; from then on (until reset()) the weld binds the object at its
/// grasp frame, with the grasp's stiffness [N/m] and damping [N s/m] on its translational rows
/// (converted at construction into MuJoCo's per-unit-mass solref and a constant solimp, as for
/// contact springs, with kSpringContactAddedMass and the two bodies' mean inverse weights
/// body_invweight0). step() measures each engaged weld's force on the object (its constraint
/// rows' efc_force through their Jacobian onto the object's translational degrees of freedom)
/// and, for each grasped object, its internal force: with n >= 2 engaged grasps of forces F_k,
/// max_k |F_k - (1/n) sum_j F_j| (for two grasps |F_1 - F_2| / 2: the squeeze, stretch or shear
/// between them, zero when the grippers only share the object's weight and inertia); with fewer,
/// 0. Its peak since reset() is kept.
///
/// Cutting (scene.hpp, [[scene.object.cutter]]): each (board, cutter) pair is a cut. After every
/// step (and at reset()) the cell world finds the cutter tip in the board's frame: its depth
/// below the top face and whether it cuts (below the face, inside its rectangle); from the tip's
/// velocity relative to the board v (board frame) it computes the cutting resistance
///   F_xy = -specific_force * depth * 2 radius * v_xy / s,
///   F_z  = +specific_force * pi radius^2 * max(0, -v_z) / s,   s = max(|v|, kCutCreepSpeed),
/// (depth capped at the board's thickness), which the next step applies at the tip to the
/// cutter's body and, opposite, to the board's (xfrc_applied: a force of the world, not of the
/// drives, so actuator_forces() does not count it; the robot's servos push through it and their
/// tracking shows it). Below kCutCreepSpeed the force fades linearly to 0 with the speed: the
/// explicitly integrated damping this gives (specific_force * depth * 2 radius / kCutCreepSpeed)
/// stays well inside the stability of the 1 ms step for the cutters of the stock scenes.
/// Each cut keeps its groove: the number of strokes (separate cuts: the tip entered the board),
/// the cut length (the tip's path along the face while cutting), the largest depth and force,
/// and the groove's points (tip positions on the face while cutting, one every kGrooveSpacing
/// along a stroke and at each stroke's start, at most kGrooveCapacity, then groove_full()).
///
/// Real time: set_targets, set_velocity_feed_forward, step, solve_constraint_forces, every read
/// (`time`, `actuator_*`, `joint_*`, `synchro_switch`, `body_pose(int)`, `site_pose(int)`,
/// `grasp_*`, `internal_force`, `peak_*`, `cut_*`, `groove*`) and `reset` neither allocate nor
/// throw. A CellWorld is
/// not thread-safe: call it from one thread (or guard it).

#include <array>
#include <cstddef>
#include <filesystem>
#include <limits>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include <mujoco/mujoco.h>

#include "mrroc/sim/mujoco_support.hpp"
#include "mrroc/sim/robot_axes.hpp"
#include "scene.hpp"

namespace mrroc::emu {

/// Limits of a value; +-infinity where the model sets none.
struct Range {
  double lower = -std::numeric_limits<double>::infinity();
  double upper = std::numeric_limits<double>::infinity();
};

/// A frame in the world: position [m] and unit quaternion (w, x, y, z).
struct FramePose {
  std::array<double, 3> position{};
  std::array<double, 4> quaternion = {1.0, 0.0, 0.0, 0.0};
};

/// What one robot of the cell is (fixed after construction). Per-axis vectors have one entry
/// per axis, in axis order.
struct CellRobot {
  std::string name;                 ///< scene name, also the prefix "<name>/" of its names
  std::filesystem::path model_dir;  ///< robots/<model>/
  std::filesystem::path mjcf;       ///< its own MJCF file
  std::array<double, 6> base{};     ///< base pose in the world: x y z [m], rotation vector [rad]
  bool gravity_compensation = true;
  std::vector<std::string> axis_names;              ///< actuator names without the prefix
  std::vector<bool> linear;                         ///< true: slide joint (m), false: hinge (rad)
  std::vector<double> coupling;                     ///< M of a = M q, row-major axes x axes
  bool coupled = false;                             ///< M is not the identity
  std::vector<double> synchro_joint_positions;      ///< q at the synchronisation switches
  std::vector<double> power_on_joint_positions;     ///< q at power-on (after reset())
  std::vector<double> power_on_actuator_positions;  ///< a = M q at power-on
  std::vector<Range> actuator_ranges;               ///< of the actuator joints' positions a
  std::vector<Range> joint_ranges;     ///< of the joint positions q (where the model has them)
  std::vector<Range> target_ranges;    ///< actuator ctrlrange (targets are clamped into it)
  std::vector<Range> force_limits;     ///< actuator forcerange [N m or N]
  std::vector<double> position_gains;  ///< servo kp [N m/rad or N/m]
  std::vector<double> damping;         ///< actuator joints' viscous damping [N m s/rad or N s/m]

  [[nodiscard]] std::size_t axis_count() const noexcept { return axis_names.size(); }
};

/// One grasp of the cell (fixed after construction).
struct CellGrasp {
  std::string object;            ///< the grasped object
  std::string gripper;           ///< its site or body, as the scene names it
  std::size_t held = 0;          ///< index of the object among the grasped objects (held_object())
  int equality = -1;             ///< its weld in the MuJoCo model
  double engage_distance = 0.0;  ///< [m]
  double engage_angle = 0.0;     ///< [rad]
  double engage_speed = 0.0;     ///< [m/s]
  double stiffness = 0.0;        ///< [N/m]
  double damping = 0.0;          ///< [N s/m]
};

/// One cut of the cell: a board and a cutter (fixed after construction).
struct CellCut {
  std::string object;                 ///< the board
  std::string cutter;                 ///< the cutter tip's site
  double radius = 0.0;                ///< [m]
  double specific_force = 0.0;        ///< [N/m^2]
  std::array<double, 3> half_size{};  ///< the board's box half-sizes [m]; top face at z = hz
  int board_body = 0;                 ///< MuJoCo body ids
  int cutter_body = 0;
};

/// A cut now (after the last step or reset).
struct CutReading {
  std::array<double, 3> tip{};          ///< the cutter tip in the board's frame [m]
  double depth = 0.0;                   ///< below the top face [m] (negative: above it)
  bool cutting = false;                 ///< below the face and inside its rectangle
  std::array<double, 3> force{};        ///< resistance on the cutter, board frame [N]
  double force_norm = 0.0;              ///< |force| [N]
  std::array<double, 3> world_force{};  ///< the force in the world frame [N]
  std::array<double, 3> point{};        ///< the tip in the world [m] (where the force acts)
};

/// What a cut left since reset().
struct CutSummary {
  int strokes = 0;            ///< separate cuts (the tip entered the board)
  double length = 0.0;        ///< the tip's path along the face while cutting [m]
  double max_depth = 0.0;     ///< [m]
  double peak_force = 0.0;    ///< largest |force| [N]
  double cutting_time = 0.0;  ///< [s]
};

/// A point of a groove: the tip on the board's face while cutting.
struct GroovePoint {
  double x = 0.0;      ///< board frame [m]
  double y = 0.0;      ///< [m]
  double depth = 0.0;  ///< [m]
  int stroke = 0;      ///< 0-based stroke
};

class CellWorld {
 public:
  /// A closed kinematic loop opening by more than this is a fault [m or rad].
  static constexpr double kLoopOpenFault = sim::kLoopOpenFault;
  /// A contact with a stiffness solref (N/m) adds this many times the body's own mass (MuJoCo's
  /// mean inverse weight at qpos0) as inertia along the contact normal: MuJoCo's soft contacts
  /// regularise the constraint with R, which acts like an added mass 1 / R. 1 keeps the contact
  /// close to a plain spring-damper on the body and the semi-implicit step stable.
  static constexpr double kSpringContactAddedMass = 1.0;
  /// Below this speed of the cutter tip relative to the board the cutting resistance fades
  /// linearly to 0 [m/s] (see the file comment).
  static constexpr double kCutCreepSpeed = 0.02;
  /// Spacing of a groove's recorded points along a stroke [m].
  static constexpr double kGrooveSpacing = 2e-4;
  /// Most points a groove keeps.
  static constexpr std::size_t kGrooveCapacity = 1U << 16U;

  /// Composes the scene (compose_scene), loads it into MuJoCo, closes every robot's kinematic
  /// loops at its power-on pose and resets to that state.
  /// @throws ConfigError (scene, robot files, a given power-on pose) or HardwareError (a robot
  ///   model that cannot be driven: an actuator not on a joint, a coupling that does not match
  ///   the model, a default power-on pose outside a range ...), naming the robot and the file.
  explicit CellWorld(const Scene& scene);
  /// load_scene(file), then as above.
  explicit CellWorld(const std::filesystem::path& scene_file);

  CellWorld(const CellWorld&) = delete;
  CellWorld& operator=(const CellWorld&) = delete;
  CellWorld(CellWorld&&) noexcept = default;
  CellWorld& operator=(CellWorld&&) noexcept = default;
  ~CellWorld() = default;

  // ---- Description ----
  [[nodiscard]] const std::string& name() const noexcept { return name_; }
  /// The composed MJCF document (what MuJoCo loaded), e.g. for a --print-scene option.
  [[nodiscard]] const std::string& composed_xml() const noexcept { return xml_; }
  [[nodiscard]] std::size_t robot_count() const noexcept { return robots_.size(); }
  /// Robot k (k < robot_count()).
  [[nodiscard]] const CellRobot& robot(std::size_t k) const { return robots_.at(k).info; }
  /// Index of the robot named `robot_name`. @throws Error listing the robots when unknown.
  [[nodiscard]] std::size_t robot_index(std::string_view robot_name) const;
  /// Number of axes of robot k (0 for an unknown k).
  [[nodiscard]] std::size_t axis_count(std::size_t k) const noexcept {
    return k < robots_.size() ? robots_[k].info.axis_count() : 0;
  }
  /// The MuJoCo step [s].
  [[nodiscard]] double timestep() const noexcept { return model_->opt.timestep; }
  /// The MuJoCo model and data, read-only (for viewers and tests).
  [[nodiscard]] const mjModel* model() const noexcept { return model_.get(); }
  [[nodiscard]] const mjData* data() const noexcept { return data_.get(); }

  // ---- Commands (real time) ----
  /// Position targets a of robot k's axes, held until the next call [rad or m]; MuJoCo clamps
  /// them into the actuators' ctrlrange. Returns false (and changes nothing) for an unknown k, a
  /// wrong number of values or a value that is not finite.
  [[nodiscard]] bool set_targets(std::size_t k, std::span<const double> positions) noexcept;
  /// Velocity feed-forward of robot k's axes [rad/s or m/s], held until the next call (like a
  /// CiA 402 velocity offset): each actuator joint gets damping * velocity added to its force,
  /// which removes the lag of a position servo against its joint's viscous friction. Zero after
  /// construction and reset(). Returns false (and changes nothing) as set_targets().
  [[nodiscard]] bool set_velocity_feed_forward(std::size_t k,
                                               std::span<const double> velocities) noexcept;
  /// Advances the world by one MuJoCo step (timestep()). Returns false when the simulation is
  /// (or already was) unstable; see fault_text().
  [[nodiscard]] bool step() noexcept;
  /// Solves the constraint forces (contacts, joint limits, loops) of the current state, so that
  /// data()'s efc_force and mj_contactForce() belong to its current contacts (d->contact). step()
  /// ends with the new state's positions and contacts but leaves the forces solved for the
  /// previous state, in the previous constraint layout. Changes no state (the next step()
  /// solves the same again; its result changes by round-off through the solver's warm start).
  /// Does nothing while faulted.
  void solve_constraint_forces() noexcept;
  /// Back to the power-on state: time 0, every robot at its power-on pose with closed loops and
  /// targets there, velocity feed-forward 0, objects at their initial poses, fault cleared.
  void reset() noexcept;

  // ---- Readings (real time) ----
  /// Simulated time since reset() [s].
  [[nodiscard]] double time() const noexcept { return data_->time; }
  /// Robot k's actuator joint positions a [rad or m]. Returns false (out untouched) for an
  /// unknown k or out.size() != axis_count(k); likewise every reading below.
  bool actuator_positions(std::size_t k, std::span<double> out) const noexcept;
  /// Actuator joint velocities [rad/s or m/s].
  bool actuator_velocities(std::size_t k, std::span<double> out) const noexcept;
  /// The force each drive applied in the last step [N m or N]: the position servo's actuator
  /// force plus the feed-forward on the actuator joint (gravity compensation and velocity
  /// feed-forward).
  bool actuator_forces(std::size_t k, std::span<double> out) const noexcept;
  /// Joint positions q = M^-1 a [rad or m].
  bool joint_positions(std::size_t k, std::span<double> out) const noexcept;
  /// Joint velocities M^-1 da/dt [rad/s or m/s].
  bool joint_velocities(std::size_t k, std::span<double> out) const noexcept;
  /// Synchronisation switch of robot k's axis i: closed (true) while q_i is strictly above the
  /// synchronisation position (as the `mujoco` plugin). False for an unknown robot or axis.
  [[nodiscard]] bool synchro_switch(std::size_t k, std::size_t axis) const noexcept;

  /// Id of a body ("part", "left", "left/column_link"), or -1 when there is none.
  [[nodiscard]] int body_id(std::string_view body_name) const noexcept;
  /// Id of a site ("left/flange"), or -1.
  [[nodiscard]] int site_id(std::string_view site_name) const noexcept;
  /// World pose of body `id` (identity for a bad id), as of the last step or reset.
  [[nodiscard]] FramePose body_pose(int id) const noexcept;
  /// World pose of site `id` (identity for a bad id).
  [[nodiscard]] FramePose site_pose(int id) const noexcept;
  /// By name. @throws Error naming the body or site when there is none.
  [[nodiscard]] FramePose body_pose(std::string_view body_name) const;
  [[nodiscard]] FramePose site_pose(std::string_view site_name) const;

  // ---- Grasps (real time) ----
  [[nodiscard]] std::size_t grasp_count() const noexcept { return grasps_.size(); }
  /// Grasp g (g < grasp_count()), in scene order.
  [[nodiscard]] const CellGrasp& grasp(std::size_t g) const { return grasps_.at(g).info; }
  /// Whether grasp g's gripper holds its object (false for an unknown g).
  [[nodiscard]] bool grasp_engaged(std::size_t g) const noexcept;
  /// When grasp g engaged [s of time()]; -1 while it is not engaged.
  [[nodiscard]] double grasp_engaged_at(std::size_t g) const noexcept;
  /// Force [N, world frame] grasp g's gripper exerted on its object in the last step (zeros
  /// while not engaged or for an unknown g).
  [[nodiscard]] std::array<double, 3> grasp_force(std::size_t g) const noexcept;
  /// MuJoCo body id of grasp g's gripper (-1 for an unknown g).
  [[nodiscard]] int grasp_gripper_body(std::size_t g) const noexcept;
  /// World position [m] of grasp g's gripper frame now (zeros for an unknown g).
  [[nodiscard]] std::array<double, 3> grasp_point(std::size_t g) const noexcept;
  /// Distance [m] of grasp g's gripper frame from its grasp frame on the object now.
  [[nodiscard]] double grasp_offset(std::size_t g) const noexcept;
  /// Objects with grasps, in scene order.
  [[nodiscard]] std::size_t held_object_count() const noexcept { return held_.size(); }
  /// Name of grasped object i ("" for an unknown i).
  [[nodiscard]] const std::string& held_object(std::size_t i) const noexcept;
  /// Index of the grasped object named `object`. @throws Error listing them when unknown.
  [[nodiscard]] std::size_t held_object_index(std::string_view object) const;
  /// Internal force [N] of grasped object i in the last step (see the file comment).
  [[nodiscard]] double internal_force(std::size_t i) const noexcept;
  /// Its largest value since reset() [N], and when [s] (-1: never above 0).
  [[nodiscard]] double peak_internal_force(std::size_t i) const noexcept;
  [[nodiscard]] double peak_internal_force_time(std::size_t i) const noexcept;

  // ---- Cutting (real time) ----
  [[nodiscard]] std::size_t cut_count() const noexcept { return cuts_.size(); }
  /// Cut c (c < cut_count()), in scene order (objects, then their cutters).
  [[nodiscard]] const CellCut& cut(std::size_t c) const { return cuts_.at(c).info; }
  /// Index of the cut of board `object` by `cutter` (its site; empty: the board's only cutter).
  /// @throws Error naming the cuts when there is no such cut (or several for an empty cutter).
  [[nodiscard]] std::size_t cut_index(std::string_view object, std::string_view cutter = {}) const;
  /// Cut c now (a default reading for an unknown c).
  [[nodiscard]] const CutReading& cut_reading(std::size_t c) const noexcept;
  /// What cut c left since reset() (zeros for an unknown c).
  [[nodiscard]] const CutSummary& cut_summary(std::size_t c) const noexcept;
  /// The points of cut c's groove, in order (empty for an unknown c).
  [[nodiscard]] std::span<const GroovePoint> groove(std::size_t c) const noexcept;
  /// True when cut c's groove reached kGrooveCapacity points (later points were not kept).
  [[nodiscard]] bool groove_full(std::size_t c) const noexcept;

  // ---- Faults ----
  [[nodiscard]] bool faulted() const noexcept { return faulted_; }
  /// Why the simulation is unstable (empty when it is not), e.g. "cell 'two-irb6' unstable at
  /// t = 0.123000 s: non-finite state of robot 'left', joint 'left/lower_arm' (axis 1
  /// 'lower_arm')".
  [[nodiscard]] const char* fault_text() const noexcept { return fault_.data(); }

 private:
  /// A robot's description plus what the cycle needs (sizes fixed at construction).
  struct RobotState {
    CellRobot info;
    sim::RobotAxes axes;
    int first_equality = 0;
    int equality_count = 0;
    std::vector<int> dofs;                ///< all degrees of freedom of the robot's joints
    std::vector<double> feed_forward;     ///< per axis [N m or N]
    mutable std::vector<double> scratch;  ///< per axis
  };

  /// A grasp with what step() needs.
  struct GraspState {
    CellGrasp info;
    int gripper_body = 0;
    int object_body = 0;
    int object_dof = 0;                 ///< first (translational) dof of the object's free joint
    std::array<double, 3> frame_pos{};  ///< gripper frame in its body [m]
    std::array<double, 4> frame_quat{1.0, 0.0, 0.0, 0.0};
    std::array<double, 3> at_pos{};  ///< grasp frame in the object [m]
    std::array<double, 4> at_quat{1.0, 0.0, 0.0, 0.0};
    bool engaged = false;
    double engaged_at = -1.0;
    std::array<double, 3> force{};
  };
  /// A grasped object.
  struct HeldObject {
    std::string name;
    std::vector<std::size_t> grasps;
    double internal = 0.0;
    double peak = 0.0;
    double peak_at = -1.0;
  };

  /// A cut with what step() needs.
  struct CutState {
    CellCut info;
    int site = 0;
    CutReading now;
    CutSummary summary;
    bool was_cutting = false;
    std::array<double, 2> last_tip{};  ///< tip on the face at the last cutting step [m]
    double last_depth = 0.0;           ///< and its depth [m]
    std::vector<GroovePoint> groove;   ///< capacity kGrooveCapacity
    bool groove_full = false;
  };

  void build(const Scene& scene);
  /// The cuts' bodies and sites. @throws ConfigError for a cutter site that is not a robot's.
  void setup_cuts(const Scene& scene);
  /// After mj_step1 (or mj_forward): each cut's reading and groove for the current state.
  void measure_cuts() noexcept;
  /// Before mj_step2: the cuts' resistances into xfrc_applied of the cutters' and boards' bodies.
  void apply_cuts() noexcept;
  /// The grasps' welds: their data (grasp frames), solref and solimp. @throws ConfigError for a
  /// grasped object without a free joint.
  void setup_grasps(const Scene& scene, int first_equality);
  /// After mj_step2: the engaged welds' forces on their objects and the internal forces.
  void measure_grasps() noexcept;
  /// After mj_step1: grippers that arrived at their grasp frames engage.
  void engage_grasps() noexcept;
  /// World position of grasp g's gripper frame and of its grasp frame, and the angle between
  /// them [rad].
  void grasp_frames(const GraspState& g, double gripper[3], double target[3],
                    double& angle) const noexcept;
  /// Converts the objects' stiffness solrefs (N/m, N s/m) into MuJoCo's per-unit-mass form, in
  /// the model and in xml_. @throws ConfigError for a stiffness solref on an object that does
  /// not move.
  void convert_spring_contacts(const Scene& scene);
  /// qfrc_applied: gravity/Coriolis compensation and velocity feed-forward of the current state.
  void apply_feed_forward() noexcept;
  bool check_stable() noexcept;
  /// Writes "robot 'r' ... joint 'j' (axis i 'a')" (or the object's joint) into `out`.
  void describe_joint(int joint, std::array<char, 256>& out) const noexcept;
  [[gnu::format(printf, 2, 3)]] void set_fault(const char* format, ...) noexcept;
  bool valid(std::size_t k, std::size_t values) const noexcept {
    return k < robots_.size() && values == robots_[k].info.axis_count();
  }

  std::string name_;
  std::string xml_;
  sim::ModelPtr model_;
  sim::DataPtr data_;
  std::vector<RobotState> robots_;
  std::vector<double> power_on_qpos_;  ///< the whole world's qpos at power-on
  std::vector<int> compensated_dofs_;  ///< dofs with gravity feed-forward
  std::vector<int> plain_dofs_;        ///< robot dofs without it (qfrc_applied = 0)
  std::vector<int> joint_robot_;       ///< per model joint: robot index, -1 for objects
  std::vector<int> joint_axis_;        ///< per model joint: axis index, -1 for passive joints
  std::vector<GraspState> grasps_;
  std::vector<HeldObject> held_;
  std::vector<CutState> cuts_;
  std::vector<int> cut_bodies_;  ///< bodies whose xfrc_applied the cuts set
  int warnings_at_reset_ = 0;
  bool faulted_ = false;
  std::array<char, 512> fault_{};
};

}  // namespace mrroc::emu
