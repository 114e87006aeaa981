#pragma once
/// @file
/// A cell scene file: the robots and objects that `mrroc-axis-emu` simulates in one MuJoCo world.
///
///     [scene]
///     name = "two-irb6"
///     timestep = 0.001                # s, MuJoCo step (optional: the robots' MJCF timestep)
///
///     [[scene.robot]]
///     name = "left"                   # prefix of every MuJoCo name of the robot: "left/..."
///     model = "../../robots/irb6"     # model folder, relative to the scene file
///     base = [0.0, 0.0, 0.0, 0.0, 0.0, 0.0]  # optional: x y z [m], rotation vector [rad]
///     mjcf = "irb6.xml"               # optional: MJCF file in the model folder (default:
///                                     #   robot.mjcf of its parameters.toml)
///     initial_joint_positions = [...] # optional: joint pose q at power-on [rad or m]; default:
///                                     #   synchronisation pose + 0.05 clamped into the ranges
///     gravity_compensation = true     # optional: gravity/Coriolis feed-forward on its joints
///     [scene.robot.drives]            # optional: the axes' wiring as CAN drives, read by the
///                                     #   emulator (emu/drives.hpp), not by load_scene()
///
///     [[scene.object]]
///     name = "part"
///     type = "box"                    # box | sphere | cylinder | capsule
///     size = [0.05, 0.05, 0.05]       # m, MuJoCo geom sizes: box half-sizes x y z; sphere
///                                     #   radius; cylinder and capsule radius, half-length
///     pos = [1.0, 0.0, 0.8]           # m, in the frame of `attach` (default: the world)
///     rotation = [0.0, 0.0, 0.0]      # optional: rotation vector [rad] (same frame)
///     mass = 0.5                      # kg (> 0)
///     rgba = [0.8, 0.2, 0.2, 1.0]     # optional colour
///     attach = "conveyor/belt_link"   # optional: a body the object is fixed to ("world" or a
///                                     #   body of a robot or an earlier object); without it
///                                     #   the object is a free body (6 degrees of freedom)
///     contact = true                  # optional: false makes it visual only (no contacts)
///     solref = [-20000.0, -400.0]     # optional: contact softness, see below
///     friction = [0.2]                # optional: sliding [1], torsional [m], rolling [m]
///                                     #   coefficients (1 to 3 numbers; MuJoCo's defaults
///                                     #   1, 0.005, 0.0001 for those not given)
///
///     [[scene.object.grasp]]          # optional, free objects only: where a gripper holds it
///     site = "left/flange"            # the gripper frame: a site of a robot (or `body`, a
///                                     #   body, with optional `pos` [m] and `rotation` [rad]
///                                     #   of the frame in that body)
///     at = [-0.2, 0.0, 0.0]           # m, the gripper frame's origin in the object's frame
///                                     #   when it holds the object
///     at_rotation = [0.0, 1.5708, 0.0]  # optional: its rotation vector [rad], same frame
///     engage_distance = 0.01          # optional (these are the defaults): the gripper closes
///     engage_angle = 0.1              #   when its frame is this near its grasp frame [m],
///     engage_speed = 0.002            #   turned by at most this [rad], moving relative to the
///                                     #   object at most this fast [m/s] (it has arrived)
///     stiffness = 1e5                 # optional [N/m], default 1e5: the grip's spring
///     damping = 600.0                 # optional [N s/m], default 600
///
///     [[scene.object.cutter]]         # optional, box objects with `attach` only: a tool that
///                                     #   cuts the object's top face (a board to engrave)
///     site = "rnt/tool"               # the cutter tip: a site of a robot
///     radius = 0.004                  # m, the cutter's radius (0.0001 .. 0.05)
///     specific_force = 2e6            # optional [N/m^2], default 2e6: cutting resistance per
///                                     #   unit of the cut's cross-section (1 .. 1e9)
///
/// Contacts. An object's geom collides with every other contact-capable geom (other objects, the
/// floor) but not with robot links (their geoms are visual only). An object attached to a robot
/// body (a tool, a probe) moves with the robot and is gravity-compensated with it.
/// `solref` takes MuJoCo's two forms:
///   - [timeconst, dampratio], both positive: MuJoCo's standard form [s, 1], passed on as is
///     (MuJoCo's default is [0.02, 1]);
///   - [-stiffness, -damping], both negative (damping may be 0): a contact spring of that stiffness
///     [N/m] and damping [N s/m] acting along the contact normal. MuJoCo's own negative form is
///     per unit of the contact's effective mass; the cell world converts (see
///     CellWorld::CellWorld) so that the static contact force is stiffness * penetration. The
///     conversion is exact for contacts with bodies fixed to the world (a table, the floor, an
///     object attached to "world"); against another moving body the spring is softer by
///     w / (w + w_other), w being the bodies' MuJoCo mean inverse weights (body_invweight0). Not
///     for an object fixed to the world itself (give the spring to the moving object).
/// An object with `solref` or `friction` gets contact priority 1, so that its parameters (and its
/// contact dimension 3) are used for its contacts with geoms that give none (the floor, other
/// objects); between two such objects MuJoCo combines them (friction: the larger; solref and
/// solimp: the mean), so do not let objects with the two solref forms touch.
/// `solref` and `friction` are refused with `contact = false`; the sliding friction must be > 0.
///
///     [[scene.sensor]]                # optional: raw sensor devices, read by the emulator
///                                     #   (emu/sensors.hpp), not by load_scene()
///
/// Grasps. A grasp is a MuJoCo weld equality constraint "<object>/grasp<i>" between the gripper's
/// body and the object, inactive until the gripper engages (CellWorld::step: the conditions
/// above), then active until reset(). It binds the object at its grasp frame `at`: a
/// self-centring gripper, whose jaws pull the object to where its geometry says the gripper holds
/// it (engaging pulls the object by up to engage_distance). Two grippers that disagree about
/// where the object is strain it: a grip k whose frame is off its grasp frame by r pulls with
/// stiffness * r (+ damping * dr/dt) on its translational rows, the static force exactly (the
/// cell world converts the stiffness into MuJoCo's per-unit-mass solref of the weld, as for
/// contact springs, with the bodies' mean inverse weights; its rotational rows get the same
/// solref). A recorded relative pose (a grip that engages unstrained wherever it closes) would
/// absorb a robot's calibration error when it grasps, and a carry by translations would never
/// show it.
///
/// Cutting (CellWorld, "Cutting"). An object with cutters is a board: a box whose top face is its
/// frame's +z face (z = +hz), fixed where `attach` puts it (it must not be a free body). A cutter
/// cuts while its tip (the site's origin) is below the top face and inside the face's rectangle
/// (|x| <= hx, |y| <= hy in the object's frame; the cutter's radius is not counted at the edges).
/// The cut resists the tip's motion relative to the board: along the face with specific_force *
/// depth * 2 radius (the groove's cross-section), down into the board with specific_force *
/// pi radius^2 (the cutter's end face), both opposing the tip's velocity; no force lifting out.
/// The cutter is taken as perpendicular to the face (a tilted cutter cuts as an upright one). The
/// groove is recorded, not removed from the board: cutting along it again meets uncut wood.
///
/// The base pose uses the same convention as `[[robot]] base` of process-set configs (position
/// and rotation vector of the robot's base frame in the cell). Robot and object names must be
/// unique, non-empty, without '/' or spaces, and other than "world", "floor" and "light" (the
/// world body, the scene's own floor and light).
///
/// Errors are `ConfigError`s "file:line: error: ..." naming the key, the value, its unit and the
/// limit. Unknown keys are rejected.

#include <array>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "mrroc/config/params.hpp"
#include "mrroc/sim/robot_parameters.hpp"

namespace mrroc::emu {

/// One robot of the cell.
struct SceneRobot {
  std::string name;
  std::filesystem::path model_dir;  ///< absolute, normalised
  std::optional<std::string> mjcf;  ///< MJCF file name override (relative to model_dir)
  std::array<double, 6> base{};     ///< x, y, z [m], rotation vector [rad]
  std::optional<std::vector<double>> initial_joint_positions;  ///< [rad or m]
  bool gravity_compensation = true;
  SourceLocation where;          ///< of the [[scene.robot]] table
  SourceLocation initial_where;  ///< of initial_joint_positions (when given)
};

enum class ObjectShape { box, sphere, cylinder, capsule };

/// Where a gripper holds an object ([[scene.object.grasp]]).
struct SceneGrasp {
  std::string site;                     ///< the gripper frame is this site, or:
  std::string body;                     ///< this body's frame moved by position, rotation
  std::array<double, 3> position{};     ///< [m] in `body`
  std::array<double, 3> rotation{};     ///< rotation vector [rad] in `body`
  std::array<double, 3> at{};           ///< [m] the gripper frame in the object's frame
  std::array<double, 3> at_rotation{};  ///< rotation vector [rad], same frame
  double engage_distance = 0.01;        ///< [m]
  double engage_angle = 0.1;            ///< [rad]
  double engage_speed = 0.002;          ///< [m/s]
  double stiffness = 1e5;               ///< [N/m]
  double damping = 600.0;               ///< [N s/m]
  SourceLocation where;                 ///< of the [[scene.object.grasp]] table

  /// The gripper's name as the scene gives it (its site or body).
  [[nodiscard]] const std::string& gripper() const noexcept { return site.empty() ? body : site; }
};

/// A tool that cuts an object's top face ([[scene.object.cutter]]).
struct SceneCutter {
  std::string site;             ///< the cutter tip: a site of a robot
  double radius = 0.0;          ///< [m]
  double specific_force = 2e6;  ///< [N/m^2] per unit of the cut's cross-section
  SourceLocation where;         ///< of the [[scene.object.cutter]] table
};

/// One object of the cell: a rigid body with one geom.
struct SceneObject {
  std::string name;
  ObjectShape shape = ObjectShape::box;
  std::vector<double> size;          ///< [m], MuJoCo geom size (see the file comment)
  std::array<double, 3> position{};  ///< [m]
  std::array<double, 3> rotation{};  ///< rotation vector [rad]
  double mass = 0.0;                 ///< [kg]
  std::array<double, 4> rgba = {0.8, 0.3, 0.2, 1.0};
  std::string attach;   ///< body it is fixed to; empty: a free body
  bool contact = true;  ///< false: contype = conaffinity = 0 (visual only)
  /// Contact softness as given: [timeconst s, dampratio] (positive) or [-stiffness N/m,
  /// -damping N s/m] (negative; see the file comment); none: MuJoCo's default.
  std::optional<std::array<double, 2>> solref;
  std::vector<double> friction;  ///< 0 to 3 coefficients (empty: MuJoCo's defaults)
  std::vector<SceneGrasp> grasps;
  std::vector<SceneCutter> cutters;  ///< tools that cut it (a board)
  SourceLocation where;              ///< of the [[scene.object]] table
  SourceLocation solref_where;       ///< of `solref` (when given)

  /// True when `solref` is the stiffness form (negative numbers).
  [[nodiscard]] bool spring_contact() const noexcept { return solref && (*solref)[0] < 0.0; }
};

struct Scene {
  std::filesystem::path file;
  std::string name;
  std::optional<double> timestep;  ///< [s]
  std::vector<SceneRobot> robots;
  std::vector<SceneObject> objects;
  SourceLocation where;  ///< of the [scene] table
};

/// Smallest and largest accepted MuJoCo timestep [s].
inline constexpr double kMinTimestep = 1e-5;
inline constexpr double kMaxTimestep = 0.01;

/// Reads a scene file. @throws ConfigError "file:line: error: ..." (see the file comment).
Scene load_scene(const std::filesystem::path& file);
/// Parses scene text; `origin` names it in messages and relative paths start at its folder.
/// @throws ConfigError as load_scene().
Scene parse_scene(const std::string& text, const std::filesystem::path& origin);

/// One robot of a composed scene: what the cell world needs to find the robot in the model.
struct ComposedRobot {
  std::filesystem::path mjcf;       ///< the robot's own MJCF file (absolute)
  sim::RobotParameters parameters;  ///< its parameters.toml
  int first_actuator = 0;           ///< its actuators are first_actuator .. + actuator_count - 1
  int actuator_count = 0;
  int first_equality = 0;  ///< its equality constraints, likewise
  int equality_count = 0;
};

/// The scene as one MJCF document.
struct ComposedScene {
  std::string xml;        ///< the MJCF text (load it with MuJoCo; print it for debugging)
  double timestep = 0.0;  ///< [s]
  std::vector<ComposedRobot> robots;  ///< in scene order
  /// The grasps' welds are equality constraints first_grasp_equality, ... in scene order (objects,
  /// then their grasps).
  int first_grasp_equality = 0;
};

/// Builds one MJCF document (MuJoCo 2.2) from the robots' MJCF files and the objects:
///   - each robot's worldbody content goes into a body named after the robot, placed at its base
///     pose (the robot's world-level lights and plane geoms are dropped; the scene has one floor
///     "floor" and one light "light");
///   - every name of a robot and every reference to one is prefixed with "<robot>/"; a reference
///     to the body "world" becomes the robot's base body; unnamed file assets are named
///     "<robot>/<file stem>" and their files are given as absolute paths;
///   - the robot's top-level <default> becomes the class "<robot>/main" (nested classes keep
///     their nesting, prefixed), used as the childclass of the base body and the class of its
///     class-less actuators, tendons, equality constraints, contact pairs, meshes and materials;
///   - <asset>, <contact>, <equality>, <tendon>, <actuator>, <sensor> and <custom> sections are
///     merged in robot order (so robot k's actuators and equality constraints are consecutive);
///     <size> njmax, nconmax and nstack are summed, nuser_* and nuserdata take the maximum;
///   - <visual>, <statistic> and <keyframe> are not carried over (keyframes do not fit a larger
///     model; MuJoCo computes the statistics of the whole scene);
///   - <compiler>: angle must be "radian" and coordinate "local"; the scene uses
///     inertiafromgeom="auto" (a robot with "false" must give every body an <inertial>, one with
///     "true" none); meshdir/texturedir/assetdir/strippath are resolved into the file paths;
///     every other compiler attribute must be the same in all robots;
///   - <option>: every physics option but the timestep must be the same in all robots (compared
///     on the models MuJoCo compiles from each file alone); the scene's timestep replaces it.
/// Objects are bodies named after the object, with one geom of the same name (class "main":
/// MuJoCo's defaults, so they collide with the floor and with each other, unless `contact` is
/// false); a free object has a free joint of the same name. An object's `solref`, `friction`
/// become its geom's, with priority="1"; a stiffness solref is written as given (negative N/m,
/// N s/m): CellWorld converts it to MuJoCo's form and sets its solimp after compiling, in the
/// model and in its composed_xml(). Each grasp becomes an inactive <weld name="<object>/grasp<i>">
/// between the gripper's body and the object, after every robot's equality constraints (its
/// data, solref and solimp are set by CellWorld).
/// @throws ConfigError "scene:line: error: robot 'x': ..." naming the robot's file and the problem
///   (a file that MuJoCo cannot load alone, disagreeing <compiler>/<option>, an unsupported
///   element such as <include> or <composite>, a missing parameters.toml, an `attach` naming no
///   body, a grasp naming no site or body of a robot).
ComposedScene compose_scene(const Scene& scene);

/// The name of a shape in scene files ("box", ...).
const char* shape_name(ObjectShape shape) noexcept;

}  // namespace mrroc::emu
