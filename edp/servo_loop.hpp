#pragma once
/// @file
/// The EDP's servo loop: a periodic thread (absolute-time clock_nanosleep) that reads the axes,
/// interpolates the current macro-step, runs synchronisation, and writes the setpoints.
///
/// Macro-step semantics (paper, section 5): a SET ARM is divided into `steps` interpolation steps,
/// one per servo period; the reading for the QUERY reply is taken in step `value_in_step_no`
/// (1..steps; steps+1 means "after the motion stopped"). Macro-steps wait in a queue of bounded
/// depth (the lookahead, `[robot.edp] lookahead`) and each starts in the servo cycle right after
/// its predecessor ends, so a continuous trajectory has no idle servo step; only a macro-step
/// that promised a successor (value_in_step_no < steps) and ends with the queue empty brings the
/// robot to a standstill (docs/edp.md, "Lookahead").
///
/// Threads: the servo thread owns the hardware; the command, bus and state threads call the
/// public methods. The servo thread holds no lock across the plugin's read() and write(); its
/// shared state sits behind a priority-inheriting mutex held only for copies, and it wakes
/// waiters through a futex that never blocks (rt_sync.hpp). The cycle does not allocate.

#include <array>
#include <atomic>
#include <cstdint>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "macro_step_queue.hpp"
#include "mrroc/edp/arm_kinematics.hpp"
#include "mrroc/edp/hardware.hpp"
#include "mrroc/robot/robot_model.hpp"
#include "rt_sync.hpp"
#include "servo_timing.hpp"
#include "synchroniser.hpp"

namespace mrroc::edp {

/// One reading of the arm, taken in a given step of a macro-step.
struct Reading {
  std::uint64_t macro_step = 0;  ///< id of the macro-step (0: none)
  int step_no = 0;
  std::int64_t cycle = 0;  ///< servo cycle counter
  bool synchronised = false;
  AxisArray joints{};         ///< measured [rad] (raw axis positions before synchronisation)
  AxisArray desired{};        ///< commanded [rad]
  AxisArray velocities{};     ///< [rad/s]
  std::uint32_t inputs = 0;   ///< binary inputs
  std::uint32_t outputs = 0;  ///< binary outputs as last written
  std::array<std::int8_t, kMaxAxes> servo_algorithm{};
  std::array<std::int8_t, kMaxAxes> servo_parameter_set{};
  /// The plugin's device reply (Hardware::read_device), `device_fields` values.
  std::array<double, kMaxDeviceFields> device{};
  std::size_t device_fields = 0;
  /// Macro-steps queued when the reading was taken, the running one included.
  int macro_steps_ahead = 0;
  /// Stopping ramps for a missing successor (lost or waived) before the reading: a reading kept
  /// for a late QUERY answers it only while this is still the count (the robot kept to the
  /// planned motion since).
  std::int64_t ramps_before = 0;
};

/// One servo cycle as recorded by the trace (see ServoLoop::enable_trace).
struct TraceSample {
  std::int64_t cycle = 0;
  bool synchronised = false;  ///< false: positions are raw axis positions, not joint coordinates
  AxisArray desired{};        ///< commanded joint position written in this cycle [rad]
  AxisArray measured{};       ///< measured joint position read in this cycle [rad]
  std::uint32_t outputs = 0;  ///< binary outputs written in this cycle
};

/// What the EDP allows before SYNCHRO ([robot.edp] unsynchronised_*; docs/edp.md, "Motion
/// before synchronisation"): RELATIVE MOTOR and JOINT moves, planned and stopped within these
/// fractions of every joint's velocity and acceleration limit, each moving no joint by more than
/// `max_move` (the joint limits cannot be checked while the position is unknown).
struct UnsynchronisedLimits {
  double velocity_fraction = 0.1;      ///< of RobotModel::max_velocity, 0.01..1
  double acceleration_fraction = 0.1;  ///< of RobotModel::max_acceleration, 0.01..1
  double max_move = 0.1;               ///< [rad | m], > 0
};

class ServoLoop {
 public:
  ServoLoop(Hardware& hardware, const RobotModel& model, double period_s);
  ~ServoLoop();
  ServoLoop(const ServoLoop&) = delete;
  ServoLoop& operator=(const ServoLoop&) = delete;

  /// Activates the hardware and starts the servo thread. @throws HardwareError.
  void start();
  /// Stops the thread (holding the last setpoint) and deactivates the hardware. Idempotent.
  void stop();
  /// Tests of the cycle itself: activates the hardware as start() does but starts no thread;
  /// the caller runs every cycle with step(). @throws HardwareError.
  void start_stepped();
  /// Runs one cycle on the calling thread (only after start_stepped()), as the servo thread runs
  /// one that woke `missed_periods` whole periods after its deadline (0: on time): a stall is an
  /// argument, not a sleep, so what the loop does after it is the same in every run.
  void step(std::int64_t missed_periods = 0);

  /// Macro-steps that may wait ahead of the servo loop (1..kMaxLookahead; default 1, the
  /// paper's single successor). Set before start().
  void set_lookahead(int depth);
  [[nodiscard]] int lookahead() const { return lookahead_; }

  /// Queues a macro-step towards `target` (joint coordinates, already limit-checked). Blocks
  /// while the queue is full (a second client beside one that fills the lookahead). Returns its
  /// id; ids increase by one per macro-step.
  std::uint64_t submit(const std::vector<double>& target, int steps, int value_in_step_no);
  /// The id of the macro-step whose reading answers macro-step `id` with this lookahead: `id`
  /// itself when it promises no successor or the lookahead is 1, else the one lookahead - 1
  /// places before it (its reading in step value_in_step_no).
  [[nodiscard]] std::uint64_t reply_due_at(std::uint64_t id, bool promises_successor) const;
  /// Waits until the reading that answers macro-step `id` (taken in macro-step `due_at`, see
  /// reply_due_at) exists: that reading, or the latest one if `due_at` passed its reading step
  /// before. Nothing on timeout, fault, emergency stop, or when `id` was refused.
  std::optional<Reading> wait_reply(std::uint64_t id, std::uint64_t due_at, double timeout_s);
  /// Servo steps still to run in everything queued, the running macro-step included.
  [[nodiscard]] std::int64_t queued_steps() const;
  /// Desired joint position at the end of everything queued.
  [[nodiscard]] std::vector<double> planned_end() const;
  /// Waits for the reading of macro-step `id`. Returns nothing on timeout, fault, or when the
  /// macro-step was refused when it was due to start (see `refusal`).
  std::optional<Reading> wait_reading(std::uint64_t id, double timeout_s);
  /// Why macro-step `id` was refused when it was due to start, or "" if it was not: the straight
  /// line from where the robot stands to its target would need more than a joint's velocity limit
  /// (e.g. after a stopping ramp left the robot away from the path its task planned). The robot
  /// holds, and every macro-step queued behind the refused one is refused with it.
  [[nodiscard]] std::string refusal(std::uint64_t id) const;
  /// The error code of that refusal (error_code::too_fast, too_abrupt or out_of_limits), 0 if
  /// macro-step `id` was not refused.
  [[nodiscard]] int refusal_code(std::uint64_t id) const;
  /// The newest macro-step id refused so far (0: none).
  [[nodiscard]] std::uint64_t refused_upto() const;
  /// The reading of the latest cycle.
  [[nodiscard]] Reading latest() const;

  /// Starts synchronisation (searching every axis' switch, then moving to the synchronisation
  /// pose) from where the robot stands, also after motion before it. Only while stopped() (the
  /// command interpreter refuses SYNCHRO otherwise). Returns at once; `wait_synchronised` waits for
  /// the end. When the hardware homes axes itself (Hardware::self_homing_axes), the servo thread
  /// first calls Hardware::home_axes() between two cycles, off the cycle as the reset after a fault
  /// (no cycle runs meanwhile; the periods it takes are neither counted late nor made up), holds
  /// every axis where the homing left it, and searches only the other axes' switches; the homed
  /// axes are synchronised with offset 0 and approach the pose with the others. A homing that
  /// fails (its exception's text), or leaves a homed axis outside its joint limits, is a fault
  /// (faulted(), fault_text()) and the robot is held unsynchronised; the next SYNCHRO resets it
  /// and homes again. An emergency stop mid-homing reaches the hardware through
  /// Hardware::emergency_stop, which ends the homing as a failure.
  void begin_synchronisation();
  bool wait_synchronised(double timeout_s);
  [[nodiscard]] bool synchronised() const { return synchronised_.load(); }
  [[nodiscard]] bool moving() const;
  /// True when nothing is queued or running and the commanded velocity is zero.
  [[nodiscard]] bool stopped() const;

  /// Lock-step (simulated hardware only; call before start()): while there is motion to execute
  /// (a macro-step, synchronisation, a stopping ramp, a reading due after a stop) the cycles run
  /// back to back, without waiting for the next period, so simulated time advances as fast as
  /// the machine allows; when idle the loop waits for work for at most one period and then runs
  /// a holding cycle. A macro-step that promised a successor (value_in_step_no < steps) waits
  /// before its last step, with simulated time standing still, up to `successor_wait_s` of wall
  /// time for it (and before it starts, for the successors its client may already have sent, so
  /// that it is joined to them as in real time); only then is the successor lost and the robot
  /// ramped to a standstill. Lateness and overruns are not measured in lock-step (there are no
  /// deadlines).
  void set_lock_step(bool on, double successor_wait_s = 1.0) {
    lock_step_ = on;
    successor_wait_s_ = successor_wait_s;
  }
  [[nodiscard]] bool lock_step() const { return lock_step_; }

  /// Motion before SYNCHRO: its limits (default UnsynchronisedLimits{}). Before start().
  /// Until the robot is synchronised, every macro-step is planned (motion_blend.hpp) and every
  /// stopping ramp (a lost successor, the emergency stop) braked within these fractions of the
  /// joints' velocity and acceleration limits, in raw axis positions, with no joint-limit check
  /// (they are not known); the command interpreter admits only RELATIVE MOTOR and JOINT moves
  /// of at most `max_move`. @throws Error for a fraction outside 0.01..1 or max_move <= 0.
  void set_unsynchronised_limits(const UnsynchronisedLimits& limits);
  [[nodiscard]] const UnsynchronisedLimits& unsynchronised_limits() const { return unsynced_; }

  /// Limits the stopping ramp must respect (besides the model's joint limits): a ramp step that
  /// would leave them ends the ramp where it is. Set before start(); may be null.
  void set_limit_guard(const ArmKinematics* guard) { guard_ = guard; }

  /// Emergency stop: drops the queued motion, decelerates all axes by one common factor (the
  /// axis with the least acceleration to spare at its maximum; never past a joint limit) to a
  /// standstill and holds, and writes the binary outputs' safe state (set_stop_outputs()) in the
  /// next cycle; no motion, SET OUTPUTS or SET SERVO is accepted until release_emergency_stop(),
  /// which restores no output. Callable from any thread.
  void emergency_stop();
  void release_emergency_stop();
  [[nodiscard]] bool emergency_stopped() const;
  /// Macro-steps that promised a successor (value_in_step_no < motion_steps) which never came;
  /// each brought the robot to a standstill within its acceleration limits.
  [[nodiscard]] std::int64_t lost_successors() const;
  /// Servo steps of missed periods (the loop woke late) that the motion made up since start:
  /// on hardware that keeps its own clock (Hardware::simulated() false) a motion runs up to 25 %
  /// faster than planned, within the joints' limits, until it is back on its time line, so that
  /// robots moving together stay in step when one servo thread is held back (docs/edp.md,
  /// "Catch-up"). On simulated hardware (its world steps once a cycle) the periods missed are run
  /// as cycles of their own in the idle time before the next deadline, as many as fit (at most 50
  /// owed), so that robots simulated by separate EDPs stay in step; those count here.
  [[nodiscard]] std::int64_t caught_up_steps() const;
  /// The client said no macro-step follows those queued (it pauses or stops on purpose): if the
  /// last of them promised a successor, the stopping ramp at its end is a planned stop.
  void waive_successor();
  /// Stopping ramps that ended a motion whose successor was waived.
  [[nodiscard]] std::int64_t planned_stops() const;
  /// After a fault: the servo thread deactivates and re-activates the plugin, clears the fault,
  /// forgets the synchronisation (the position reference is lost) and holds where the axes are.
  /// Waits until the plugin's re-activation ended and a cycle read its result, at most
  /// `timeout_s` (a safety net against a plugin that never returns: the plugin bounds its own
  /// bring-up, e.g. the CAN plugin by `bring_up_timeout_s`); returns false if the fault persists.
  bool reset_fault(double timeout_s);

  /// Binary outputs to write from the next cycle on; false (nothing changed) while the emergency
  /// stop is engaged.
  [[nodiscard]] bool request_outputs(std::uint32_t values);
  /// Servo algorithm and parameter set per axis, switched in the next cycle (validated by the
  /// caller against the plugin's counts); false (nothing changed) while the emergency stop is
  /// engaged.
  [[nodiscard]] bool request_servo(const std::vector<std::int8_t>& algorithm,
                                   const std::vector<std::int8_t>& parameter_set);
  /// What emergency_stop() does to the binary outputs: the lines of `kept` stay, every other
  /// line takes its state in `safe` (config [robot.edp] safe_outputs, kept_outputs). Before the
  /// loop starts.
  void set_stop_outputs(std::uint32_t safe, std::uint32_t kept);
  /// Device command (one value per command field of Hardware::device(), checked by the
  /// caller), written to the plugin in the next cycle.
  void request_device(const std::vector<double>& command);
  /// The plugin's device, as it described it when the loop was made.
  [[nodiscard]] const DeviceDescription& device() const { return device_; }
  [[nodiscard]] Hardware& hardware() { return hardware_; }

  /// Set when the hardware reported a fault or synchronisation failed; the loop then holds still.
  [[nodiscard]] bool faulted() const { return faulted_.load(); }
  [[nodiscard]] std::string fault_text() const;

  /// Lateness statistics. Nothing under the lock the servo thread shares allocates: the samples
  /// are copied into memory allocated before.
  [[nodiscard]] TimingStats timing() const;
  /// Lateness since the previous call (the first call: since start()).
  TimingWindow take_timing_window();
  [[nodiscard]] std::size_t axes() const { return axes_; }

  /// Records the next `capacity` cycles into preallocated memory (diagnostics and tests).
  /// Call before start().
  void enable_trace(std::size_t capacity);
  /// The cycles recorded so far.
  [[nodiscard]] std::vector<TraceSample> trace() const;
  /// Id of the servo thread (valid after start()).
  [[nodiscard]] std::thread::id servo_thread_id() const { return thread_.get_id(); }

 private:
  enum class Mode { hold, synchronising, stopping };

  void run();
  void run_lock_step();
  /// The recovery thread: runs each job the servo thread posts (Hardware::deactivate() and
  /// activate() for a reset, Hardware::home_axes() for a homing), one at a time.
  void run_recovery();
  /// Servo thread: posts the recovery the cycle needs (a reset, a homing) to the recovery thread.
  void post_recovery(bool reset);
  /// Servo thread: whether the recovery posted has ended, waiting for it when `wait` (lock-step
  /// and stepped loops: no cycle without it; real time: the loop goes on without the plugin).
  bool recovery_ended(bool wait);
  /// start(), start_stepped(): activates the hardware and takes its first reading (axes,
  /// inputs, device) before any cycle. @throws HardwareError when that read fails.
  void activate_and_read();
  /// Starts the recovery thread (start(), start_stepped()).
  void start_recovery_thread();
  [[nodiscard]] TimingStats timing_stats(const std::vector<float>& sorted) const;
  /// Lock-step: something for the next cycle to do (mutex_ held).
  [[nodiscard]] bool has_work() const;
  /// Lock-step: the next cycle would end a macro-step whose promised successor is not queued.
  [[nodiscard]] bool awaiting_successor() const;
  /// The next macro-step would start before the successors its client may already have sent
  /// are queued (lock-step: before every macro-step; real time: before a motion from rest).
  [[nodiscard]] bool awaiting_lookahead() const;
  /// The last macro-step ended at rest (or none ran): a new one starts a motion from rest.
  [[nodiscard]] bool at_rest() const;
  /// One cycle that woke `late_ns` after its deadline (lock-step: 0 of 1): read, plan (and
  /// record the lateness) under the mutex, write.
  /// `missed`: the periods before it that the loop missed (it woke that late); 0 in lock-step.
  void cycle(std::int64_t late_ns, std::int64_t period_ns, std::int64_t missed);
  /// The part of a cycle that decides the setpoints (mutex_ held; no hardware call).
  void plan_cycle(std::int64_t missed);
  /// After Hardware::home_axes() in this cycle (mutex_ held, feedback_ read after it): holds
  /// every axis where it stands, then a fault (`failure` not empty, or a homed axis outside its
  /// limits) or the synchroniser's start with the homed axes found.
  void finish_homing(const char* failure, bool read_ok);
  /// Advances the motion by `advance` servo steps (1: as planned; more while catching up).
  void motion_cycle(double advance);
  /// The servo steps this cycle advances the motion (see "Catch-up" in docs/edp.md).
  double catch_up_advance(std::int64_t missed);
  /// The largest planned acceleration of axis i [unit/s^2] in the next `reach` servo steps of
  /// the motion (its macro-step's halves and, past its end, its successor's).
  [[nodiscard]] double planned_acceleration_ahead(std::size_t i, double reach) const;
  /// Starts the macro-step at the queue's front, or refuses it with the queue behind it (false).
  /// `mid_cycle`: this cycle already advanced the motion up to where it starts (the rest of a
  /// catch-up's advance), so a refusal of a moving robot starts the ramp in the next cycle.
  bool start_next_macro_step(bool mid_cycle);
  /// Moves the setpoint on at `velocity` for `steps` servo steps' time, within the limits (the
  /// part of a cycle's advance past a motion's end when the stopping ramp follows).
  void coast(const AxisArray& velocity, double steps);
  void set_fault(const char* text);
  /// The limits motion is planned and stopped within: the model's once synchronised, else
  /// unsynced_model_ (reduced velocity and acceleration, no joint limits); and the ramp's guard
  /// (none before synchronisation: the limits are in joint coordinates, the positions raw).
  [[nodiscard]] const RobotModel& motion_limits() const {
    return synchronised_.load(std::memory_order_relaxed) ? model_ : unsynced_model_;
  }
  [[nodiscard]] const ArmKinematics* ramp_guard() const {
    return synchronised_.load(std::memory_order_relaxed) ? guard_ : nullptr;
  }
  void store_reading(std::uint64_t id, int step_no);
  /// Drops every queued macro-step; waiters for them are answered by their refusal or the
  /// emergency stop.
  void drop_queue();
  [[nodiscard]] int queued() const { return static_cast<int>(queue_.size()) + (current_ ? 1 : 0); }

  Hardware& hardware_;
  const RobotModel& model_;
  std::size_t axes_;
  double period_s_;
  int lookahead_ = 1;

  std::thread thread_;
  std::atomic<bool> running_{false};
  std::atomic<bool> synchronised_{false};
  std::atomic<bool> faulted_{false};
  bool lock_step_ = false;
  double successor_wait_s_ = 1.0;

  mutable PiMutex mutex_;
  Wakeup changed_;               ///< moved whenever a waiter's condition may have changed
  bool notify_pending_ = false;  ///< the servo thread notifies changed_ after unlocking
  Mode mode_ = Mode::hold;
  Synchroniser synchroniser_;
  std::optional<MacroStep> current_;
  MacroStepQueue queue_;
  std::uint64_t next_id_ = 1;
  std::uint64_t reached_id_ = 0;     ///< the newest macro-step past its reading step (or dropped)
  std::uint64_t after_stop_id_ = 0;  ///< macro-step whose reading is due after it stopped
  int after_stop_step_ = 0;
  Reading latest_;
  /// The readings the last kDeliveredKept macro-steps requested, at delivered_[id % size]: a
  /// QUERY that comes late (its client was held up) still gets the reading of the macro-step it
  /// asked about, the same servo step as every other robot of its group, not a later one. After
  /// a stopping ramp the robot left the plan: the freshest reading (where it stands) answers.
  static constexpr std::size_t kDeliveredKept = 64;
  std::array<Reading, kDeliveredKept> delivered_{};
  AxisArray desired_{};             ///< joint coordinates (raw before synchronisation)
  AxisArray commanded_velocity_{};  ///< of desired_ over the last cycle [rad/s]
  AxisArray end_velocity_{};        ///< the velocity the last macro-step ended with (0: at rest)
  std::array<const MacroStep*, MacroStepQueue::kCapacity> following_{};  ///< for plan_blend
  AxisArray scratch_{};  ///< the stopping ramp's proposal
  const ArmKinematics* guard_ = nullptr;
  UnsynchronisedLimits unsynced_;
  /// model_ with the velocity and acceleration limits of unsynced_ and no joint limits (+-inf):
  /// what motion before SYNCHRO is planned and stopped within (constant once the loop runs).
  RobotModel unsynced_model_;
  std::int64_t limit_stops_ = 0;  ///< stopping ramps ended at a limit
  bool emergency_stop_ = false;
  bool hold_at_measured_ = false;  ///< after an emergency stop: hold at the measured joints
  bool reset_pending_ = false;
  bool homing_pending_ = false;   ///< SYNCHRO: the next cycle calls Hardware::home_axes()
  bool homing_running_ = false;   ///< the recovery thread is inside Hardware::home_axes()
  std::uint32_t homed_axes_ = 0;  ///< Hardware::self_homing_axes(), constant after construction
  /// Recovery off the servo thread: the job the servo thread posted (kNoRecovery when none is
  /// in flight; servo thread only); the handshake: recovery_job_ holds the job and its number
  /// (job + 4 * number), recovery_done_ the number of the last job ended; the failure text is
  /// written by the recovery thread before recovery_done_, read by the servo thread after.
  static constexpr int kRecoveryPriority = 70;  ///< SCHED_FIFO, below the servo thread's 80
  bool stepped_ = false;                        ///< start_stepped(): the caller steps the loop
  static constexpr int kNoRecovery = 0;
  static constexpr int kResetRecovery = 1;
  static constexpr int kHomingRecovery = 2;
  int recovery_in_flight_ = kNoRecovery;
  std::thread recovery_thread_;
  std::atomic<std::uint64_t> recovery_job_{0};
  std::atomic<std::uint64_t> recovery_done_{0};
  std::uint64_t recovery_number_ = 0;  ///< servo thread: the number of the last job posted
  std::atomic<bool> recovery_quit_{false};
  Wakeup recovery_wake_;
  char recovery_failure_[256] = {};
  std::int64_t lost_successors_ = 0;
  std::int64_t planned_stops_ = 0;
  std::uint64_t waived_upto_ = 0;       ///< macro-steps up to this id need no successor
  std::uint64_t refused_first_ = 0;     ///< the refused range: the macro-step refused at its start
  std::uint64_t refused_last_ = 0;      ///< ... and the newest one dropped with it
  bool after_ramp_ = false;             ///< the robot stands where a lost successor's ramp left it
  std::int64_t start_held_cycles_ = 0;  ///< cycles a motion from rest waited for its lookahead
  char refused_text_[512] = {};
  int refused_code_ = 0;
  AxisArray offset_{};                           ///< joint = raw + offset (valid once synchronised)
  std::array<AxisFeedback, kMaxAxes> sample_{};  ///< servo thread only
  std::array<AxisFeedback, kMaxAxes> feedback_{};  ///< under mutex_
  std::array<double, kMaxAxes> raw_setpoints_{};   ///< servo thread only (written outside mutex_)
  char fault_[256] = {};

  bool outputs_pending_ = false;
  std::uint32_t outputs_ = 0;
  std::uint32_t safe_outputs_ = 0;  ///< set_stop_outputs()
  std::uint32_t kept_outputs_ = 0;
  DeviceDescription device_;  ///< constant after construction
  bool device_pending_ = false;
  std::array<double, kMaxDeviceFields> device_command_{};  ///< under mutex_
  std::array<double, kMaxDeviceFields> device_write_{};    ///< servo thread only
  std::array<double, kMaxDeviceFields> device_sample_{};   ///< servo thread only
  bool servo_pending_ = false;
  std::array<std::int8_t, kMaxAxes> servo_algorithm_{};
  std::array<std::int8_t, kMaxAxes> servo_parameter_set_{};
  std::vector<TraceSample> trace_;  ///< preallocated by enable_trace
  std::size_t trace_count_ = 0;
  ServoTiming timing_;
  std::int64_t work_ns_ = 0;  ///< servo thread only: the last cycle's work, wake-up to write end
  /// The hardware keeps its own clock (Hardware::simulated() false): the servo steps of missed
  /// periods are made up (catch_up_advance).
  bool keeps_time_ = false;
  double lag_steps_ = 0.0;            ///< servo steps the motion is behind its planned time line
  double warp_ = 0.0;                 ///< how much faster than planned it runs now (0: as planned)
  AxisArray warp_velocity_{};         ///< the commanded velocity of the cycle before the last
  double previous_rate_ = 1.0;        ///< the rate (1 + warp) of the cycle before the last
  std::int64_t caught_up_total_ = 0;  ///< missed servo steps taken up for catch-up
  /// Simulated hardware: periods missed and not made up yet (run()), at most kMaxOwedCycles.
  std::int64_t owed_cycles_ = 0;
  static constexpr std::int64_t kMaxOwedCycles = 50;
  char scheduling_[80] = {};
};

}  // namespace mrroc::edp
