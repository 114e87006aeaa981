#pragma once
/// @file
/// The ECP's robot: its image (the state the user's generators read and the command they write)
/// kept current through the robot's EDP client (edp::Client, mrroc/edp/client.hpp; paper,
/// section 4), and the stop and pause of the task that drives it. No LCM here.

#include <atomic>
#include <condition_variable>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "mrroc/ecp/robot_image.hpp"
#include "mrroc/edp/arm_kinematics.hpp"
#include "mrroc/edp/client.hpp"
#include "mrroc/msg/edp_instruction.hpp"
#include "mrroc/robot/robot_model.hpp"

namespace mrroc::ecp {

/// A robot with a device beside its arm (the paper's device-dependent buffers and images, e.g. a
/// gripper) derives from Robot, keeps its device's command and reply fields in its own members
/// and converts them in the two hooks write_device_command and read_device_reply; its task code
/// calls its own methods (ecp/tasks/gripper.hpp: `gripper.close(force)`, `gripper.width()`). A
/// task says which robot class it drives when it is registered
/// (MRROC_REGISTER_ECP_TASK_WITH_ROBOT) and reaches it through TaskContext::robot_as.
class Robot {
 public:
  /// @param process_name  the caller's name (e.g. "ecp/irb6"), for its EDP client.
  /// @param robot_name    the robot's name in the process set (channels are named after it).
  Robot(comm::Bus& bus, const std::string& process_name, const std::string& robot_name,
        RobotModel model, edp::ClientOptions options = {});
  /// With the request/reply layer's own options (mrroc/comm/request_reply.hpp).
  Robot(comm::Bus& bus, const std::string& process_name, const std::string& robot_name,
        RobotModel model, const comm::ClientOptions& options);
  virtual ~Robot() = default;
  Robot(const Robot&) = delete;
  Robot& operator=(const Robot&) = delete;

  [[nodiscard]] const std::string& name() const { return name_; }
  [[nodiscard]] const RobotModel& model() const { return model_; }
  [[nodiscard]] RobotImage& image() { return image_; }
  [[nodiscard]] const RobotImage& image() const { return image_; }

  /// The image's measured (or desired) arm pose in any representation, converted by the library
  /// from the joint coordinates (frames are the tool frame in the robot's base frame) with the
  /// tool, kinematic model and corrector the EDP uses: those the task SET, or the EDP's own as
  /// the last GET of TOOL / MODEL returned (read_state and synchronise read them).
  /// @throws CommandError when the robot has no Cartesian kinematics and a frame is asked for.
  [[nodiscard]] std::vector<double> pose(edp::ArmRepresentation representation,
                                         bool desired = false) const;

  /// Sends `image().command` and updates the image from its result: one exchange (the command
  /// goes with `with_query`, and the EDP answers with what its QUERY would return), or, with
  /// set_separate_query(true), the paper's two: the command, then QUERY. A command that SETs
  /// DEVICE carries the device part write_device_command makes; a reply to a GET of DEVICE goes
  /// to `image().device` and to read_device_reply.
  /// @throws EdpRefused (the EDP refused; nothing moved), TimeoutError.
  void execute();
  /// True: execute() sends a separate QUERY after every command (the paper's sequence; one more
  /// round trip per macro-step). Default false.
  void set_separate_query(bool separate) { separate_query_ = separate; }
  [[nodiscard]] bool separate_query() const { return separate_query_; }
  /// Reads the arm (GET ARM JOINT + QUERY) into the image.
  void read_state();
  /// Tells the EDP that no macro-step follows those already sent (the task pauses or stops on
  /// purpose), so the stopping ramp at the end of its queue is a planned stop, not a lost
  /// successor. The image is left as it is. Never throws: a failure only leaves the EDP to
  /// report a lost successor.
  void announce_no_successor() noexcept;
  /// The next instruction takes the EDP over (edp_instruction_t.take_over; docs/edp.md, "One
  /// owner at a time"): the EDP then obeys this client only, and forgets a QUERY that was due.
  /// Set by the constructor and after a timeout; the console sets it before every jog.
  void take_over_next() { client_.take_over_next(); }
  /// The EDP client the image is kept current through.
  [[nodiscard]] edp::Client& client() { return client_; }
  /// SYNCHRO + QUERY unless the EDP is already synchronised.
  void synchronise();

  /// Makes Move/Wait throw TaskStopped at their next step (and ends a pause); an instruction
  /// waiting for the EDP's reply stops waiting and throws TaskStopped at once (a STOP never waits
  /// for a silent EDP's last attempts; the EDP itself ramps the arm down when its queue runs dry).
  void request_stop();
  void clear_stop() { stop_.store(false); }
  [[nodiscard]] bool stop_requested() const { return stop_.load(); }

  /// PAUSE: Move and Wait hold before their next step (the current macro-step completes, then
  /// the robot stands) until resume() or request_stop().
  void pause();
  void resume();
  [[nodiscard]] bool paused() const;
  /// Blocks while paused; returns true if it did block. @throws TaskStopped when a stop is
  /// requested.
  bool wait_while_paused();

 protected:
  /// Extension point of a derived robot with a device: fills the device part of a SET DEVICE
  /// from the derived robot's command fields, one number per command field of the EDP plugin's
  /// device, in its order and units. `command` arrives holding `image().command.device`; the
  /// default leaves it so.
  virtual void write_device_command(std::vector<double>& command) const { (void)command; }
  /// Extension point of a derived robot with a device: reads the reply fields of a GET DEVICE
  /// (one number per reply field of the plugin's device) into the derived robot's own fields.
  /// @throws Error when they do not fit (e.g. the EDP's plugin drives another device).
  virtual void read_device_reply(const std::vector<double>& reply) { (void)reply; }

 private:
  edp::Reply exchange(const edp::Instruction& instruction);
  /// `asked`: the GET items of the instruction the reply answers.
  void update_image(const edp::Reply& reply, std::uint8_t asked);
  /// After the EDP accepted `sent`: the tool and model it set, as pose() must use them.
  void follow_settings(const edp::Instruction& sent);

  std::string name_;
  RobotModel model_;
  std::unique_ptr<edp::ArmKinematics> kinematics_;
  edp::Client client_;
  RobotImage image_;
  std::atomic<bool> stop_{false};
  mutable std::mutex pause_mutex_;
  std::condition_variable pause_cv_;
  bool paused_ = false;
  bool separate_query_ = false;
};

}  // namespace mrroc::ecp
