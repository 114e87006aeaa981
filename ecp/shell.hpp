#pragma once
/// @file
/// The ECP shell: serves the MP's commands for one robot (paper, section 4).
///
/// | command     | what the ECP does                                   | reply (when) |
/// |-------------|-----------------------------------------------------|-----------------------------------|
/// | START_TASK  | runs the configured task                            | TASK_TERMINATED / ERROR
/// (its end) | | NEXT_STATE  | runs the ECP task named `state_name` with the TOML  |
/// TASK_TERMINATED / ERROR (its end) | |             | `arguments` (sporadic coordination) | | |
/// NEXT_POSE   | one macro-step to the MP's pose (continuous         | ACKNOWLEDGE + reading (in
/// step    | |             | coordination)                                       |
/// value_in_step_no)                 | | END_MOTION  | ends a series of NEXT_POSE (and a STOP that
/// stopped | ACKNOWLEDGE + state               | |             | it): reads the robot's state (GET)
/// |                                   | | STOP        | stops what runs (it ends with ERROR
/// "stopped");     | ACKNOWLEDGE (at once)             | |             | NEXT_POSE stays refused
/// until END_MOTION, START_TASK|                                   | |             | or NEXT_STATE
/// |                                   | | PAUSE       | holds before the next macro-step |
/// ACKNOWLEDGE (at once)             | | RESUME      | goes on | ACKNOWLEDGE (at once) |
///
/// One activity (task, sub-task, pose, end of motion) runs at a time on the worker thread; a
/// second one is refused with `task_running`. STOP, PAUSE and RESUME act at once.

#include <condition_variable>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <thread>
#include <vector>

#include "mrroc/comm/links.hpp"
#include "mrroc/comm/reporter.hpp"
#include "mrroc/config/process_set.hpp"
#include "mrroc/ecp/robot.hpp"
#include "mrroc/ecp/task.hpp"

namespace mrroc::ecp {

class EcpShell {
 public:
  /// Loads the robot model and the configured task (errors name config file and line).
  /// `vsps`: the names of the process set's VSPs, which the task's sensors must be among.
  EcpShell(comm::Bus& bus, const RobotConfig& config, Reporter& reporter,
           std::vector<std::string> vsps);
  ~EcpShell();
  EcpShell(const EcpShell&) = delete;
  EcpShell& operator=(const EcpShell&) = delete;

  /// Serves commands until `stop_requested()` (SIGINT/SIGTERM); stops what runs on the way out.
  /// `scheduling` (what apply_priority said) goes into the ready message.
  void run(const std::string& scheduling);

 private:
  using Responder = comm::EcpServer::Responder;
  /// On the bus thread: a decoded (or malformed) command from the MP.
  void serve(comm::EcpServer::Incoming in);
  void dispatch(const MpCommand& command, const Responder& responder);
  /// Runs `body` on the worker; its reply (or the error it throws) goes to `responder`.
  bool start_activity(const std::string& what, std::function<EcpReply()> body,
                      const Responder& responder);
  EcpReply run_task(const std::string& name, const Params& args);
  EcpReply next_pose(const MpCommand& command);
  EcpReply end_motion();
  EcpReply state_reply(EcpReplyType type) const;
  void worker_loop();

  comm::Bus& bus_;
  const RobotConfig& config_;
  Reporter& reporter_;
  std::vector<std::string> vsps_;
  std::string process_;
  /// The class the configured task drives (make_task_robot).
  std::unique_ptr<Robot> robot_;
  /// The running task's corrector of NEXT_POSE commands (TaskContext::follow_mp_with); used and
  /// replaced on the worker thread only.
  std::unique_ptr<FollowGenerator> follow_;

  std::mutex mutex_;
  std::condition_variable cv_;
  std::function<void()> job_;
  bool busy_ = false;
  bool closing_ = false;
  std::thread worker_;

  std::mutex serve_mutex_;
  bool serving_ = false;                          ///< between "ready" and the stop request
  std::vector<comm::EcpServer::Incoming> early_;  ///< commands that came before "ready"
  /// Last: the bus thread calls into the members above as soon as it exists.
  comm::EcpServer server_;
};

}  // namespace mrroc::ecp
