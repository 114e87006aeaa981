#pragma once
// Jogging: one axis of one robot by a step [rad], from rest to rest, in one macro-step sent by
// the console's own EDP link (docs/operating.md, "Jogging"). The checks use the console's state
// (the MP answering and its task IDLE, FINISHED or FAILED; robot fresh, released, without
// fault, at rest; synchronised for a tool jog); the motion goes through a JogLink, which the
// console makes from its EDP client (edp_jog_link.hpp). A joint jog of a robot not synchronised
// is the EDP's motion before synchronisation (docs/edp.md): within its reduced limits and its
// largest move, and marked UNSYNCHRONISED in its text and result.

#include <cstdint>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "console/common.hpp"
#include "console/state.hpp"
#include "mrroc/edp/arm_kinematics.hpp"

namespace mrroc::ui {

/// What the EDP said when it refused the motion (nothing moved).
class JogRefused : public Error {
 public:
  using Error::Error;
};

/// The link to one robot's EDP that carries the jog's motion.
class JogLink {
 public:
  virtual ~JogLink() = default;
  /// Takes the EDP over (it accepts only while the robot is at rest) and moves the joints by
  /// `delta` [rad] in one SET ARM JOINT RELATIVE macro-step of `motion_steps` servo steps, from
  /// rest to rest; returns the measured joint positions after it [rad].
  /// @throws JogRefused (the EDP's text), TimeoutError (no EDP answers).
  virtual std::vector<double> move_joints_relative(const std::vector<double>& delta,
                                                   int motion_steps) = 0;
  /// Takes the EDP over and synchronises the robot (SYNCHRO: the EDP's own search for its
  /// synchronisation switches, within its limits; seconds); returns the joint positions after it
  /// [rad]. @throws JogRefused (the EDP's text), TimeoutError (no EDP answers).
  virtual std::vector<double> synchronise() = 0;
  /// Takes the EDP over and moves the tool frame by `delta` (x y z [m], rotation vector [rad],
  /// in the EDP's current tool frame) in one SET ARM XYZ_ANGLE_AXIS RELATIVE macro-step of
  /// `motion_steps` servo steps, from rest to rest; returns the joint positions after it.
  /// @throws JogRefused (the EDP's text), TimeoutError (no EDP answers).
  virtual std::vector<double> move_tool_relative(const std::vector<double>& delta,
                                                 int motion_steps) = 0;
};

/// What a jog moves.
enum class JogSpace : std::int8_t {
  joint,  ///< one joint (axis 0..axes-1), step in its unit (rad or m)
  tool    ///< the tool frame along or about its own axis (0..2: x y z [m], 3..5: about x y z [rad])
};

/// A jog as the API asks for it.
struct JogRequest {
  std::string robot;
  std::int64_t axis = 0;
  double step = 0.0;  ///< > 0, in the axis' unit (rad or m)
  int direction = 1;  ///< +1 or -1
  JogSpace space = JogSpace::joint;
};

struct JogOptions {
  double max_step_rad =
      0.2;  ///< largest step accepted [rad] (revolute, prismatic [m], tool rotation)
  double max_step_m = 0.05;  ///< largest tool translation accepted [m]
  /// The motion stays within this fraction of the axis' velocity and acceleration limits.
  double velocity_fraction = 0.25;
  double min_duration_s = 0.1;  ///< shortest macro-step [s]
};

struct JogResult {
  std::string text;              ///< "irb6 axis 0 (column) moved +0.1000 rad in ..."
  std::vector<double> q;         ///< after the motion [rad]
  std::vector<double> q_before;  ///< from the last robot_state_t before it [rad]
  int motion_steps = 0;
  /// False for a jog before synchronisation (q and q_before are raw axis positions).
  bool synchronised = true;
};

class Jogger {
 public:
  /// @param links  one per robot of `state`, by name; a robot without one cannot be jogged.
  Jogger(const ConsoleState& state, JogOptions options,
         std::map<std::string, std::unique_ptr<JogLink>> links, ReportFn report);

  [[nodiscard]] const JogOptions& options() const { return options_; }

  /// True when the robot's kinematics offer Cartesian representations (tool jogs).
  [[nodiscard]] bool cartesian(const std::string& robot) const;
  /// Checks the request against the robot and the state, moves and answers once the robot's
  /// state shows it at rest again (at most 100 ms after the EDP's answer).
  /// @throws ApiError 404 (unknown robot), 400 (axis or step out of range), 409 (refused: the
  /// MP's state unknown (no answer, or none in the last kMpFreshS) or not IDLE, FINISHED or
  /// FAILED, no fresh state, stop engaged, fault, a tool jog not synchronised, moving, another
  /// jog of the robot in progress, or the EDP refused), 504 (no EDP answers). Not synchronised,
  /// a joint jog moves within the smaller of velocity_fraction and the EDP's unsynchronised
  /// fraction of the axis' limits, and a step above its unsynchronised_max_move is a 400.
  JogResult jog(const JogRequest& request);

  /// Synchronises `robot` through its link (the console's Synchronise button) with the checks of
  /// jog() that apply: the MP answering and its task IDLE, FINISHED or FAILED, fresh state, stop
  /// released, no fault, at rest. A robot already synchronised is left alone (the text says so,
  /// `motion_steps` is 0).
  /// @throws ApiError 404 (unknown robot), 409 (refused, or the EDP refused), 504 (no EDP).
  JogResult synchronise(const std::string& robot);
  /// The checks of jog() alone: the joint positions to start from, or the refusal.
  /// @throws ApiError as jog() (but never for a jog in progress or the EDP).
  [[nodiscard]] std::vector<double> check(const JogRequest& request) const;

 private:
  const ConsoleState& state_;
  JogOptions options_;
  struct Link {
    std::unique_ptr<JogLink> link;
    std::mutex busy;  ///< one motion at a time; also guards `kinematics`
    /// The robot's own kinematics (no tool, model 0), for the duration of tool jogs.
    std::unique_ptr<edp::ArmKinematics> kinematics;
  };
  JogResult jog_tool(const JogRequest& request, const std::vector<double>& q);
  /// The checks jog() and synchronise() share; `what` names the action in the refusal.
  /// @throws ApiError 409 naming what is refused and why.
  [[nodiscard]] RobotReading check_ready(std::size_t index, const std::string& what) const;
  /// The robot's link. @throws ApiError 409 when the console has none.
  [[nodiscard]] Link& link_of(const std::string& robot, const std::string& what) const;
  std::map<std::string, std::unique_ptr<Link>> links_;
  ReportFn report_;
};

}  // namespace mrroc::ui
