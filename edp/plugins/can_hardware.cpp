/// @file
/// The `can` EDP hardware plugin: a robot's axes as CiA 402 drives on a CAN bus (SocketCAN or
/// the virtual bus), driven in cyclic synchronous position mode (include/mrroc/can/).
///
/// Plugin parameters ([robot.edp.params]; unknown keys are rejected):
///   - `bus` (string, required): "socketcan:can0", "virtual:cell1", ...
///   - `nodes` (list of integers, default 1..n): node id of each axis' drive, in axis order.
///   - `counts_per_unit` (number, default 100000): encoder counts per rad (or m) of the drives'
///     axis coordinates (the motors' side of the transmission, a = M q).
///   - `bitrate` (number, bit/s, default 1000000): the bus' bit rate, for the bus-load check.
///   - `following_error_window` (number, rad, default 0.05) and `following_error_timeout_ms`
///     (integer, default 50): the drives' following-error monitor.
///   - `silent_cycles` (integer, 2..1000): cycles without an answer before a drive is lost.
///     Default 10 on SocketCAN; on a virtual bus as many as make 150 ms (75 at 2 ms), as the
///     heartbeat timeout: the emulator's CPU may stop for up to 60 ms while the EDP's runs on.
///   - `bring_up_timeout_s` (number, default 5).
///   - `heartbeat_ms` (integer, default 100).
///   - `heartbeat_timeout_ms` (integer, 11..65535): the drives' consumer time for the master's
///     heartbeat (0x1016 sub 1); the master sends its heartbeat every 10 ms. Default 50 ms on
///     SocketCAN; 150 ms on a virtual bus, whose drives are emulated on this same host: a shared
///     host stops one CPU for up to 60 ms while the other runs on (measured with
///     scripts/stall-check, docs/operating.md), and the emulated drives must ride through that.
///   - `digital_lines` (boolean, default true): use the drives' digital output lines (0x60FE,
///     where a drive's file has it); false: no outputs (the EDP refuses SET OUTPUTS), inputs as
///     before.
///   - `eds` (string, or a list of one per axis): the drives' EDS or DCF files (relative to the
///     config file); default: mrroc's emulated drive (configs/drives/emu-csp.eds). Every object
///     the master touches is checked against it (drive_setup.hpp), here and at `--check`.
///   - `mode` ("csp", "ip" or "csv", or a list of one per axis; default: csp where the drive
///     supports it, else ip): cyclic synchronous position, interpolated position, or cyclic
///     synchronous velocity (the master turns the positions into velocities, Cia402Master).
///   - `identity` ([vendor, product] or [vendor, product, revision], or a list of one such row per
///     axis): what 0x1018 of each drive must say; bring-up refuses a drive that says otherwise.
///   - `sdo` (list of rows [node, index, sub, value]; node 0: every drive): SDO writes at
///     bring-up, after the master's own, each checked against the drive's file and read back.
///   - `sdo_text` (list of strings "node index sub text"; node 0: every drive): SDO writes of
///     string objects at bring-up (segmented when longer than 4 bytes), after `sdo`'s, each
///     checked against the drive's file and read back.
///   - `homing` (list of rows [node (0: every drive without a row of its own), method, switch
///     search speed (units/s), zero search speed (units/s), acceleration (units/s^2), offset
///     (units), timeout_s]): these drives home by their own homing mode (CiA 402 mode 6, 0x6098,
///     0x6099, 0x609A, 0x607C; values in counts by counts_per_unit), checked against the drive's
///     file (homing in 0x6502, the objects writable, every value within its object), and run
///     by `home_axes` at the EDP's SYNCHRO (Cia402Master::home). The EDP takes those axes as
///     synchronised where their homing leaves them (the offset is the position at the home
///     point) and searches the home switches of the others.
///   - `rpdo`, `tpdo` (lists of rows [node (0: every drive), PDO number, COB-ID (0: the
///     predefined one), transmission type, event timer ms, entries...]; an entry is
///     index << 16 | sub << 8 | bits, bits 0 for the object's width, or an index alone): the
///     drives' PDOs as the config chooses them, instead of mrroc's own (drive_setup.hpp); each
///     checked against the drive's file at its row.
/// The cyclic traffic's bus load is computed at configure time and printed; a worst case above
/// 100 % is refused, above 70 % warned about (docs/hil.md).
///
/// Joint coordinates q and drive coordinates a are related by the robot's transmission coupling
/// (parameters.toml [robot.transmission] coupling, default identity): targets are sent as a = M q
/// and positions read back as q = M^-1 a. Positions are incremental (zero at the drives' power-on);
/// the EDP's SYNCHRO finds the offset by the home switch each drive reports in its TPDO, or, for
/// the drives with a `homing` row, has them home themselves (home_axes) and takes their positions
/// as they are then.
/// Binary I/O on the drives' digital lines (CiA 402 0x60FD, 0x60FE; 8 input and 8 output lines a
/// drive, canopen.hpp): inputs 0..15 are the home switches of axes 0..15 (as the mujoco plugin's
/// synchronisation switches), inputs 16..23 the input lines 0..7 of axis 0's drive and 24..31
/// those of axis 1's; outputs 0..7 are axis 0's drive's output lines 0..7 and 8..15 axis 1's
/// (a one-axis robot has outputs 0..7 only; the EDP refuses the others). Inputs are sampled at
/// the last SYNC, as the positions; outputs go out in the cycle after the SET (an RPDO2). When
/// the plugin is destroyed (the EDP's end) it switches the outputs off; a bring-up after a fault
/// sets them again.
/// Emergency stop sends the drives quick stop (they decelerate at the robot's largest
/// acceleration, in drive coordinates, and hold); release re-enables them where they stand.
#include <Eigen/Dense>
#include <algorithm>
#include <atomic>
#include <climits>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include <fmt/format.h>

#include "mrroc/can/bus.hpp"
#include "mrroc/can/canopen.hpp"
#include "mrroc/can/cia402_master.hpp"
#include "mrroc/can/drive_setup.hpp"
#include "mrroc/can/eds.hpp"
#include "mrroc/config/check.hpp"
#include "mrroc/core/error.hpp"
#include "mrroc/edp/hardware.hpp"
#include "mrroc/robot/robot_model.hpp"

namespace mrroc::edp {
namespace {

class CanHardware final : public Hardware {
 public:
  [[nodiscard]] std::string name() const override { return "can"; }
  [[nodiscard]] std::size_t axis_count() const override { return axes_; }

  CanHardware() = default;
  CanHardware(const CanHardware&) = delete;
  CanHardware& operator=(const CanHardware&) = delete;
  ~CanHardware() override {
    if (master_) master_->switch_outputs_off();
  }

  void check(const HardwareSetup& setup) override { (void)read_settings(setup); }

  void configure(const HardwareSetup& setup) override {
    master_.reset();
    bus_.reset();
    const Settings settings = read_settings(setup);
    const RobotModel& model = settings.model;
    axes_ = model.axes();
    coupling_ = settings.coupling;
    inverse_ = settings.inverse;
    load_text_ = settings.load_text;
    std::fprintf(stderr, "%s\n", load_text_.c_str());
    if (settings.load_worst > can::canopen::kRecommendedMaxLoad)
      std::fprintf(stderr,
                   "can: warning: worst-case bus load %.0f %% is above the recommended "
                   "%.0f %%\n",
                   settings.load_worst * 100.0, can::canopen::kRecommendedMaxLoad * 100.0);
    // The joints read from homed drives only (read_settings refuses a joint read from homed
    // and unhomed ones): their positions are absolute after home_axes().
    self_homing_ = 0;
    for (std::size_t i = 0; i < std::min<std::size_t>(axes_, 32); ++i) {
      bool homed = true;
      for (std::size_t j = 0; j < axes_; ++j)
        if (std::abs(inverse_(static_cast<Eigen::Index>(i), static_cast<Eigen::Index>(j))) >
                1e-12 &&
            !settings.plans[j].homing)
          homed = false;
      if (homed) self_homing_ |= 1U << i;
    }
    for (std::size_t i = 0; i < settings.plans.size(); ++i)
      if (settings.plans[i].homing)
        std::fprintf(stderr,
                     "can: node %u (axis '%s'): SYNCHRO homes it by its drive's homing mode "
                     "(method %d)\n",
                     static_cast<unsigned>(settings.plans[i].node), settings.plans[i].axis.c_str(),
                     static_cast<int>(settings.plans[i].homing->method));
    const auto n = static_cast<Eigen::Index>(axes_);
    const std::vector<std::int64_t>& nodes = settings.nodes;
    const double counts = settings.counts;
    const double window = settings.window;
    const std::int64_t window_ms = settings.window_ms;
    const std::int64_t silent = settings.silent;
    const double timeout_s = settings.timeout_s;
    const std::int64_t heartbeat = settings.heartbeat;
    const std::int64_t heartbeat_timeout = settings.heartbeat_timeout;
    const std::string& url = settings.url;

    std::vector<can::MasterAxis> axes;
    for (std::size_t i = 0; i < axes_; ++i) {
      can::MasterAxis a;
      a.name = model.joint_names[i];
      a.node = static_cast<std::uint8_t>(nodes[i]);
      a.counts_per_unit = counts;
      a.unit = model.unit(i);
      // Deceleration in drive coordinates: |M| times the joints' largest accelerations.
      double decel = 0.0;
      for (std::size_t c = 0; c < axes_; ++c)
        decel += std::abs(coupling_(static_cast<Eigen::Index>(i), static_cast<Eigen::Index>(c))) *
                 model.max_acceleration[c];
      a.quick_stop_deceleration = decel;
      a.following_error_window = window;
      a.following_error_timeout_ms = static_cast<std::uint16_t>(window_ms);
      a.plan = settings.plans[i];
      axes.push_back(a);
    }
    can::MasterOptions options;
    options.period_s = setup.servo_period_s;
    options.silent_cycles = static_cast<int>(silent);
    options.heartbeat_ms = static_cast<std::uint16_t>(heartbeat);
    options.heartbeat_consumer_ms = static_cast<std::uint16_t>(heartbeat_timeout);
    options.digital_lines = settings.digital_lines;
    timeout_ = std::chrono::milliseconds(std::llround(timeout_s * 1000.0));
    period_s_ = setup.servo_period_s;
    bus_ = can::open_bus(url);
    bus_->receive_error_frames(true);
    master_ = std::make_unique<can::Cia402Master>(*bus_, std::move(axes), options);
    a_.resize(n);
    q_.resize(n);
    a_velocity_.resize(n);
    q_velocity_.resize(n);
    fresh_from_.assign(axes_, 0);
    target_a_.assign(axes_, 0.0);
    first_read_ = true;
  }

  void activate() override {
    master_->bring_up(timeout_);
    for (std::size_t i = 0; i < axes_; ++i)
      std::fprintf(stderr, "can: %s\n", master_->bring_up_report(i).c_str());
    active_ = true;
    first_read_ = true;
  }

  void deactivate() override {
    if (master_ && active_) master_->shut_down();
    active_ = false;
  }

  CycleStatus read(std::span<AxisFeedback> out) override {
    master_->receive();
    for (std::size_t i = 0; i < axes_; ++i)
      a_(static_cast<Eigen::Index>(i)) = master_->status(i).position;
    q_.noalias() = inverse_ * a_;
    // Velocity from each drive's last two TPDOs with its position and the cycles between them
    // (the master keeps both): a TPDO that comes a cycle late (a drive, or an emulator on a busy
    // host) leaves the estimate as it was, not 0 (a standstill that did not happen), the one after
    // it is not read as twice the speed, and after a homing, during which this plugin reads
    // nothing, it is the drive's speed now, not the mean over the homing.
    for (std::size_t i = 0; i < axes_; ++i) {
      const auto k = static_cast<Eigen::Index>(i);
      const can::DriveStatus& s = master_->status(i);
      if (first_read_) fresh_from_[i] = s.last_tpdo_cycle;  // nothing before it counts
      if (s.previous_tpdo_cycle == 0 || s.previous_tpdo_cycle < fresh_from_[i] ||
          s.last_tpdo_cycle <= s.previous_tpdo_cycle) {
        a_velocity_(k) = 0.0;
      } else {
        a_velocity_(k) =
            (s.position - s.previous_position) /
            (static_cast<double>(s.last_tpdo_cycle - s.previous_tpdo_cycle) * period_s_);
      }
    }
    q_velocity_.noalias() = inverse_ * a_velocity_;
    for (std::size_t i = 0; i < axes_; ++i) {
      const auto k = static_cast<Eigen::Index>(i);
      out[i].position = q_(k);
      out[i].velocity = q_velocity_(k);
      out[i].synchro_switch = master_->status(i).home_switch;
    }
    first_read_ = false;
    return master_->faulted() ? CycleStatus::fault : CycleStatus::ok;
  }

  CycleStatus write(std::span<const double> setpoints) override {
    for (std::size_t i = 0; i < axes_; ++i) q_(static_cast<Eigen::Index>(i)) = setpoints[i];
    a_.noalias() = coupling_ * q_;
    for (std::size_t i = 0; i < axes_; ++i) target_a_[i] = a_(static_cast<Eigen::Index>(i));
    master_->send(target_a_, quick_stop_.load(std::memory_order_relaxed));
    return master_->faulted() ? CycleStatus::fault : CycleStatus::ok;
  }

  void emergency_stop(bool engaged) override {
    quick_stop_.store(engaged, std::memory_order_relaxed);
  }

  [[nodiscard]] bool binary_io() const override { return true; }
  [[nodiscard]] std::uint32_t output_lines() const override {
    std::uint32_t lines = 0;
    for (std::size_t i = 0; i < std::min<std::size_t>(axes_, 2); ++i)
      if (master_ && master_->has_outputs(i)) lines |= 0xFFU << (8U * i);
    return lines;
  }
  void write_outputs(std::uint32_t values) override {
    for (std::size_t i = 0; i < std::min<std::size_t>(axes_, 2); ++i)
      master_->set_outputs(i, static_cast<std::uint8_t>(values >> (8U * i)));
  }
  [[nodiscard]] std::uint32_t read_inputs() const override {
    std::uint32_t inputs = 0;
    for (std::size_t i = 0; i < std::min<std::size_t>(axes_, 16); ++i)
      if (master_->status(i).home_switch) inputs |= 1U << i;
    for (std::size_t i = 0; i < std::min<std::size_t>(axes_, 2); ++i)
      inputs |= static_cast<std::uint32_t>(master_->status(i).input_lines) << (16U + 8U * i);
    return inputs;
  }

  [[nodiscard]] std::string fault_text() const override {
    return master_ ? std::string(master_->fault_text()) : std::string();
  }

  [[nodiscard]] std::uint32_t self_homing_axes() const override { return self_homing_; }

  void home_axes() override {
    master_->home(quick_stop_);
    // The homed drives' positions jumped to their new reference: no velocity across it.
    first_read_ = true;
  }

 private:
  static double canopen_max_node() { return static_cast<double>(can::canopen::kMaxNode); }

  /// The plugin's parameters, read and checked (configure() and the config check).
  struct Settings {
    RobotModel model;
    std::string url;
    std::vector<std::int64_t> nodes;
    double counts = 0.0;
    double window = 0.0;
    std::int64_t window_ms = 0;
    std::int64_t silent = 0;
    double timeout_s = 0.0;
    std::int64_t heartbeat = 0;
    std::int64_t heartbeat_timeout = 0;
    bool digital_lines = true;
    Eigen::MatrixXd coupling;
    Eigen::MatrixXd inverse;
    std::string load_text;
    double load_worst = 0.0;
    std::vector<can::DrivePlan> plans;  ///< per axis
  };

  /// The drives' files and what the config asks of each, planned and checked (all errors of
  /// every drive at once).
  static std::vector<can::DrivePlan> plan_drives(const Params& params, const RobotModel& model,
                                                 const std::vector<std::int64_t>& nodes,
                                                 bool outputs, double counts) {
    const std::size_t axes = model.axes();
    ConfigErrorList errors;
    // A string for every axis, or a list of one per axis.
    const auto per_axis = [&](const char* key) -> std::vector<std::string> {
      if (!params.has(key)) return std::vector<std::string>(axes);
      if (std::holds_alternative<std::string>(params.values().at(key)))
        return std::vector<std::string>(axes, params.get_string(key));
      std::vector<std::string> v = params.get_strings(key);
      if (v.size() != axes)
        throw ConfigError(params.location_of(key),
                          fmt::format("'{}' lists {} values, robot '{}' has {} axes", key, v.size(),
                                      model.name, axes));
      return v;
    };
    const std::vector<std::string> files = per_axis("eds");
    const std::vector<std::string> modes = per_axis("mode");
    std::vector<std::vector<double>> identities(axes);
    if (params.has("identity")) {
      const ParamValue& v = params.values().at("identity");
      if (std::holds_alternative<std::vector<double>>(v)) {
        identities.assign(axes, params.get_doubles("identity"));
      } else {
        identities = params.get_double_rows("identity");
        if (identities.size() != axes)
          throw ConfigError(params.location_of("identity"),
                            fmt::format("'identity' has {} rows, robot '{}' has {} axes",
                                        identities.size(), model.name, axes));
      }
    }
    const std::vector<std::vector<double>> sdo =
        params.has("sdo") ? params.get_double_rows("sdo") : std::vector<std::vector<double>>{};
    const std::vector<std::string> texts =
        params.has("sdo_text") ? params.get_strings("sdo_text") : std::vector<std::string>{};
    const auto integer = [](double v, double lo, double hi) {
      return v == std::floor(v) && v >= lo && v <= hi;
    };
    for (const auto& row : sdo)
      if (row.size() != 4 || !integer(row[0], 0, 127) || !integer(row[1], 0, 0xFFFF) ||
          !integer(row[2], 0, 0xFF) || !integer(row[3], -2147483648.0, 4294967295.0))
        throw ConfigError(params.location_of("sdo"),
                          "each row of 'sdo' is [node (0: every drive), index, sub, value], "
                          "integers: node 0..127, index 0..0xFFFF, sub 0..255, value of 32 bits");
    // The config's PDOs: [node (0: every drive), number, COB-ID (0: predefined), transmission
    // type, event timer ms, entries...], an entry index << 16 | sub << 8 | bits (bits 0: the
    // object's width from the file), or an index alone (sub 0).
    struct PdoRow {
      std::int64_t node = 0;
      can::PdoRequest pdo;
    };
    std::vector<PdoRow> pdo_rows;
    for (const char* key : {"rpdo", "tpdo"}) {
      if (!params.has(key)) continue;
      const std::vector<std::vector<double>> rows = params.get_double_rows(key);
      for (std::size_t r = 0; r < rows.size(); ++r) {
        const std::vector<double>& row = rows[r];
        const SourceLocation at = params.location_of_row(key, r);
        bool ok = row.size() >= 6 && row.size() <= 5 + 64 && integer(row[0], 0, 127) &&
                  integer(row[1], 1, 512) && integer(row[2], 0, 0x7FF) && integer(row[3], 0, 255) &&
                  integer(row[4], 0, 65535);
        for (std::size_t k = 5; ok && k < row.size(); ++k) ok = integer(row[k], 1, 4294967295.0);
        if (!ok) {
          errors.add(ConfigError(
              at, fmt::format("each row of '{}' is [node (0: every drive), {} number 1..512, "
                              "COB-ID (0: the predefined one, else 0x001..0x7FF), transmission "
                              "type 0..255, event timer 0..65535 ms, then 1..64 entries: "
                              "index << 16 | sub << 8 | bits (bits 0: the object's width), or "
                              "an index alone], integers",
                              key, key[0] == 'r' ? "RPDO" : "TPDO")));
          continue;
        }
        if (row[0] != 0 && std::find(nodes.begin(), nodes.end(),
                                     static_cast<std::int64_t>(row[0])) == nodes.end()) {
          errors.add(ConfigError(at, fmt::format("'{}' names node {}, which is none of robot "
                                                 "'{}''s nodes",
                                                 key, row[0], model.name)));
          continue;
        }
        PdoRow p;
        p.node = static_cast<std::int64_t>(row[0]);
        p.pdo.receive = key[0] == 'r';
        p.pdo.number = static_cast<int>(row[1]);
        p.pdo.cob_id = static_cast<std::uint32_t>(row[2]);
        p.pdo.transmission = static_cast<std::uint8_t>(row[3]);
        p.pdo.event_timer_ms = static_cast<std::uint16_t>(row[4]);
        p.pdo.where = at;
        for (std::size_t k = 5; k < row.size(); ++k) {
          const auto raw = static_cast<std::uint32_t>(row[k]);
          p.pdo.entries.push_back(raw <= 0xFFFFU
                                      ? can::PdoEntry{static_cast<std::uint16_t>(raw), 0, 0}
                                      : can::PdoEntry::from_raw(raw));
        }
        pdo_rows.push_back(std::move(p));
      }
    }
    // Homing by the drives: [node (0: every drive not named in a row of its own), method, switch
    // search speed, zero search speed, acceleration, offset, timeout_s].
    std::map<std::int64_t, std::pair<std::vector<double>, SourceLocation>> homing_rows;
    if (params.has("homing")) {
      const std::vector<std::vector<double>> rows = params.get_double_rows("homing");
      for (std::size_t r = 0; r < rows.size(); ++r) {
        const std::vector<double>& row = rows[r];
        const SourceLocation at = params.location_of_row("homing", r);
        if (row.size() != 7 || !integer(row[0], 0, 127) || !integer(row[1], -128, 127) ||
            !std::all_of(row.begin() + 2, row.end(), [](double v) { return std::isfinite(v); })) {
          errors.add(ConfigError(
              at,
              "each row of 'homing' is [node (0: every drive without a row of its own), "
              "method (CiA 402 homing method, 0x6098, an integer -128..127), switch search "
              "speed (units/s), zero search speed (units/s), acceleration (units/s^2), "
              "offset (units), timeout_s (s)], numbers"));
          continue;
        }
        const auto node = static_cast<std::int64_t>(row[0]);
        if (node != 0 && std::find(nodes.begin(), nodes.end(), node) == nodes.end()) {
          errors.add(ConfigError(at, fmt::format("'homing' names node {}, which is none of robot "
                                                 "'{}''s nodes",
                                                 node, model.name)));
          continue;
        }
        if (const auto it = homing_rows.find(node); it != homing_rows.end()) {
          errors.add(
              ConfigError(at, fmt::format("'homing' has a second row for {} (the first is at {})",
                                          node == 0 ? std::string("every drive (node 0)")
                                                    : fmt::format("node {}", node),
                                          it->second.second.str())));
          continue;
        }
        homing_rows[node] = {row, at};
      }
    }
    const std::filesystem::path base =
        std::filesystem::path(params.location_of("eds").file).parent_path();
    std::map<std::string, std::shared_ptr<const can::eds::Dictionary>> loaded;
    std::vector<can::DrivePlan> plans;
    for (std::size_t i = 0; i < axes; ++i) {
      can::DriveRequest request;
      request.node = static_cast<std::uint8_t>(nodes[i]);
      request.axis = model.joint_names[i];
      request.outputs = outputs;
      request.where = params.has("eds") ? params.location_of("eds") : params.location();
      if (!modes[i].empty()) {
        if (modes[i] == "csp")
          request.mode = can::eds::mode::kCyclicSyncPosition;
        else if (modes[i] == "ip")
          request.mode = can::eds::mode::kInterpolatedPosition;
        else if (modes[i] == "csv")
          request.mode = can::eds::mode::kCyclicSyncVelocity;
        else
          throw ConfigError(params.location_of("mode"),
                            fmt::format("'mode' = \"{}\": mrroc drives in \"csp\" (cyclic "
                                        "synchronous position), \"ip\" (interpolated position) "
                                        "or \"csv\" (cyclic synchronous velocity)",
                                        modes[i]));
      }
      if (const auto& id = identities[i]; !id.empty()) {
        if ((id.size() != 2 && id.size() != 3) || !std::all_of(id.begin(), id.end(), [&](double v) {
              return integer(v, 0, 4294967295.0);
            }))
          throw ConfigError(params.location_of("identity"),
                            "'identity' is [vendor, product] or [vendor, product, revision], "
                            "unsigned 32-bit integers (0x1018 sub 1, 2, 3)");
        can::DriveIdentity identity;
        identity.vendor = static_cast<std::uint32_t>(id[0]);
        identity.product = static_cast<std::uint32_t>(id[1]);
        if (id.size() == 3) identity.revision = static_cast<std::uint32_t>(id[2]);
        request.identity = identity;
      }
      for (const auto& row : sdo)
        if (row[0] == 0 || static_cast<std::int64_t>(row[0]) == nodes[i])
          request.writes.push_back({static_cast<std::uint16_t>(row[1]),
                                    static_cast<std::uint8_t>(row[2]),
                                    static_cast<std::uint64_t>(static_cast<std::int64_t>(row[3])),
                                    0, params.location_of("sdo"), std::nullopt});
      for (const std::string& line : texts) {
        // "node index sub text": numbers in C's notation (0x.. hex), the text the rest.
        const char* p = line.c_str();
        char* end = nullptr;
        const long node = std::strtol(p, &end, 0);
        const bool n_ok = end != p && *end == ' ';
        p = end;
        const long index = n_ok ? std::strtol(p, &end, 0) : -1;
        const bool i_ok = n_ok && end != p && *end == ' ';
        p = end;
        const long sub = i_ok ? std::strtol(p, &end, 0) : -1;
        const bool ok = i_ok && end != p && (*end == ' ' || *end == '\0') && node >= 0 &&
                        node <= 127 && index >= 0 && index <= 0xFFFF && sub >= 0 && sub <= 0xFF;
        if (!ok) {
          if (i == 0)
            errors.add(ConfigError(params.location_of("sdo_text"),
                                   fmt::format("'sdo_text' entry \"{}\" is not \"node index sub "
                                               "text\" (node 0..127, 0: every drive; index "
                                               "0..0xFFFF; sub 0..255)",
                                               line)));
          continue;
        }
        if (node != 0 && node != nodes[i]) continue;
        can::SdoWrite w;
        w.index = static_cast<std::uint16_t>(index);
        w.sub = static_cast<std::uint8_t>(sub);
        w.text = std::string(*end == ' ' ? end + 1 : end);
        w.where = params.location_of("sdo_text");
        request.writes.push_back(w);
      }
      for (const PdoRow& row : pdo_rows)
        if (row.node == 0 || row.node == nodes[i]) request.pdos.push_back(row.pdo);
      auto homing_row = homing_rows.find(nodes[i]);
      if (homing_row == homing_rows.end()) homing_row = homing_rows.find(0);
      if (homing_row != homing_rows.end()) {
        const std::vector<double>& row = homing_row->second.first;
        can::HomingRequest h;
        h.method = static_cast<std::int64_t>(row[1]);
        h.switch_speed = row[2];
        h.zero_speed = row[3];
        h.acceleration = row[4];
        h.offset = row[5];
        h.timeout_s = row[6];
        h.counts_per_unit = counts;
        h.unit = model.unit(i);
        h.where = homing_row->second.second;
        request.homing = h;
      }
      std::shared_ptr<const can::eds::Dictionary> file;
      if (files[i].empty()) {
        file = can::default_drive_eds();
      } else {
        std::filesystem::path path(files[i]);
        if (path.is_relative()) path = base / path;
        auto& slot = loaded[path.lexically_normal().string()];
        if (!slot && !errors.run(params.location_of("eds"), [&] {
              slot = std::make_shared<can::eds::Dictionary>(
                  can::eds::Dictionary::load(path.lexically_normal()));
            }))
          continue;
        file = slot;
        if (!file) continue;
      }
      errors.run(request.where, [&] { plans.push_back(can::plan_drive(file, request)); });
    }
    if (plans.size() == axes)
      errors.run(params.location(), [&] { can::check_pdo_identifiers(plans); });
    errors.throw_if_any();
    return plans;
  }

  /// Reads and checks every parameter, the coupling and the bus load; opens nothing.
  /// @throws ConfigError naming the key, the value, its unit and the limit.
  static Settings read_settings(const HardwareSetup& setup) {
    Settings s;
    const Params& params = setup.params;
    s.model = load_robot_model(setup.model_dir);
    const RobotModel& model = s.model;
    const std::size_t axes = model.axes();
    s.url = params.get_string("bus");
    if (params.has("nodes")) {
      for (const double n : params.get_doubles("nodes")) {
        if (n != std::floor(n) || n < 1 || n > canopen_max_node())
          throw ConfigError(params.location_of("nodes"),
                            fmt::format("node id {} in 'nodes' must be an integer in 1..127", n));
        s.nodes.push_back(static_cast<std::int64_t>(n));
      }
      if (s.nodes.size() != axes)
        throw ConfigError(params.location_of("nodes"),
                          fmt::format("'nodes' lists {} node ids, robot '{}' has {} axes",
                                      s.nodes.size(), model.name, axes));
    } else {
      for (std::size_t i = 0; i < axes; ++i) s.nodes.push_back(static_cast<std::int64_t>(i + 1));
    }
    s.counts = params.get_double("counts_per_unit", 100000.0);
    const double bitrate = params.get_double("bitrate", 1e6);
    s.window = params.get_double("following_error_window", 0.05);
    s.window_ms = params.get_int("following_error_timeout_ms", 50);
    const bool emulated = s.url.rfind("virtual:", 0) == 0;  // drives emulated on this host
    s.silent = params.get_int(
        "silent_cycles",
        emulated ? static_cast<std::int64_t>(std::ceil(0.150 / setup.servo_period_s - 1e-9)) : 10);
    s.timeout_s = params.get_double("bring_up_timeout_s", 5.0);
    s.heartbeat = params.get_int("heartbeat_ms", 100);
    s.heartbeat_timeout = params.get_int("heartbeat_timeout_ms", emulated ? 150 : 50);
    s.digital_lines = params.get_bool("digital_lines", true);
    s.plans = plan_drives(params, model, s.nodes, s.digital_lines, s.counts);
    params.reject_unread("robot.edp.params");
    try {
      can::check_bus_url(s.url);
    } catch (const ConfigError& e) {
      throw e.at(params.location_of("bus"));
    }
    const auto positive = [&](const char* key, double value, const char* unit) {
      if (!(value > 0.0) || !std::isfinite(value))
        throw ConfigError(params.location_of(key),
                          fmt::format("'{}' = {} {} must be a positive number", key, value, unit));
    };
    positive("counts_per_unit", s.counts, "counts/unit");
    positive("bitrate", bitrate, "bit/s");
    positive("following_error_window", s.window, "rad");
    positive("bring_up_timeout_s", s.timeout_s, "s");
    if (s.window_ms < 1 || s.window_ms > 65535)
      throw ConfigError(
          params.location_of("following_error_timeout_ms"),
          fmt::format("'following_error_timeout_ms' = {} ms must be in 1..65535 ms", s.window_ms));
    if (s.silent < 2 || s.silent > 1000)
      throw ConfigError(params.location_of("silent_cycles"),
                        fmt::format("'silent_cycles' = {} must be in 2..1000", s.silent));
    if (const can::MasterOptions defaults;
        s.heartbeat_timeout <= defaults.master_heartbeat_ms || s.heartbeat_timeout > 65535)
      throw ConfigError(
          params.location_of("heartbeat_timeout_ms"),
          fmt::format("'heartbeat_timeout_ms' = {} ms must be in {}..65535 ms (longer than the "
                      "master's heartbeat period, {} ms)",
                      s.heartbeat_timeout, defaults.master_heartbeat_ms + 1,
                      defaults.master_heartbeat_ms));
    if (s.heartbeat < 0 || s.heartbeat > 65535)
      throw ConfigError(params.location_of("heartbeat_ms"),
                        fmt::format("'heartbeat_ms' = {} ms must be in 0..65535 ms", s.heartbeat));

    // Transmission a = M q.
    const auto n = static_cast<Eigen::Index>(axes);
    s.coupling = Eigen::MatrixXd::Identity(n, n);
    for (std::size_t r = 0; r < model.coupling.size(); ++r)
      for (std::size_t c = 0; c < model.coupling[r].size(); ++c)
        s.coupling(static_cast<Eigen::Index>(r), static_cast<Eigen::Index>(c)) =
            model.coupling[r][c];
    const Eigen::FullPivLU<Eigen::MatrixXd> lu(s.coupling);
    if (!lu.isInvertible())
      throw ConfigError(SourceLocation::whole_file(model.parameters_file().string()),
                        "robot.transmission.coupling is singular");
    s.inverse = lu.inverse();
    // A drive's homing makes a joint's position absolute only with every drive the joint is
    // read from (its row of M^-1) homed too; a joint read from homed and unhomed drives would
    // need both the drive's reference and the EDP's switch search.
    const auto reads_from = [&](std::size_t joint, std::size_t drive) {
      return std::abs(s.inverse(static_cast<Eigen::Index>(joint),
                                static_cast<Eigen::Index>(drive))) > 1e-12;
    };
    ConfigErrorList homing_errors;
    for (std::size_t j = 0; j < axes && j < s.plans.size(); ++j) {
      if (!s.plans[j].homing) continue;
      for (std::size_t i = 0; i < axes; ++i) {
        if (!reads_from(i, j)) continue;
        for (std::size_t k = 0; k < axes && k < s.plans.size(); ++k)
          if (reads_from(i, k) && !s.plans[k].homing)
            homing_errors.add(ConfigError(
                s.plans[j].homing->where,
                fmt::format("node {} (axis '{}'): the transmission (robot.transmission.coupling) "
                            "reads joint {} ({}) from node {} (axis '{}') too, which has no "
                            "'homing' row: home every drive of that joint by its homing mode, "
                            "or none",
                            static_cast<unsigned>(s.plans[j].node), s.plans[j].axis, i,
                            model.joint_names[i], static_cast<unsigned>(s.plans[k].node),
                            s.plans[k].axis)));
      }
    }
    homing_errors.throw_if_any();

    // Every target of the joints' ranges in counts, wherever a drive's power-on put its zero
    // (encoders count from there): |a_i| up to sum_c |M_ic| (upper_c - lower_c). The drives take
    // INTEGER32 counts (0x607A, 0x60C1 sub 1).
    for (std::size_t i = 0; i < axes; ++i) {
      double reach = 0.0;
      for (std::size_t c = 0; c < axes && c < model.upper_limits.size(); ++c)
        reach += std::abs(s.coupling(static_cast<Eigen::Index>(i), static_cast<Eigen::Index>(c))) *
                 (model.upper_limits[c] - model.lower_limits[c]);
      // A joint without finite limits (a continuous one) has no range to check here; its
      // targets are checked as they are sent.
      if (std::isfinite(reach) && !can::to_drive_units(reach, s.counts, INT32_MIN, INT32_MAX))
        throw ConfigError(
            params.location_of("counts_per_unit"),
            fmt::format("'counts_per_unit' = {:g} counts/{}: axis {} ({}) spans {:g} {} of its "
                        "range, {:g} counts, beyond the drives' position range of 2147483647 "
                        "counts (INTEGER32) either side of their zero",
                        s.counts, model.unit(i), i, model.joint_names[i], reach, model.unit(i),
                        reach * s.counts));
    }

    // Bus load of the cyclic traffic.
    const double heartbeat_s = static_cast<double>(s.heartbeat) / 1000.0;
    const can::canopen::BusLoad load =
        can::pdo_bus_load(s.plans, setup.servo_period_s, bitrate, heartbeat_s);
    s.load_text = fmt::format(
        "can: {} for robot '{}': {} drives, cycle {:.3g} ms, {} frames per cycle, bus load "
        "{:.0f} % nominal, {:.0f} % worst case at {:.0f} kbit/s",
        s.url, setup.robot, axes, setup.servo_period_s * 1000.0, load.frames_per_cycle,
        load.load_nominal * 100.0, load.load_worst * 100.0, bitrate / 1000.0);
    s.load_worst = load.load_worst;
    if (load.load_worst > 1.0)
      throw ConfigError(
          params.location(),
          fmt::format("robot '{}' needs {:.0f} % of bus {} at {:.0f} kbit/s with a {:.3g} ms cycle "
                      "(limit 100 %, recommended at most {:.0f} %): lengthen servo_period_ms or "
                      "split the drives over more buses",
                      setup.robot, load.load_worst * 100.0, s.url, bitrate / 1000.0,
                      setup.servo_period_s * 1000.0, can::canopen::kRecommendedMaxLoad * 100.0));
    return s;
  }

  std::size_t axes_ = 0;
  std::unique_ptr<can::Bus> bus_;
  std::unique_ptr<can::Cia402Master> master_;
  Eigen::MatrixXd coupling_;
  Eigen::MatrixXd inverse_;
  Eigen::VectorXd a_;
  Eigen::VectorXd q_;
  Eigen::VectorXd a_velocity_;  ///< drive velocities [units/s] from their last two TPDOs
  Eigen::VectorXd q_velocity_;  ///< joint velocities [rad/s]
  /// Per drive, the master's cycle of its last TPDO at the first read after an activation or a
  /// homing: velocities come from TPDO pairs after it only (a reference may have jumped).
  std::vector<std::uint64_t> fresh_from_;
  std::vector<double> target_a_;
  std::chrono::milliseconds timeout_{5000};
  double period_s_ = kDefaultServoPeriodS;
  bool active_ = false;
  bool first_read_ = true;
  std::atomic<bool> quick_stop_{false};
  std::uint32_t self_homing_ = 0;  ///< self_homing_axes(): joints read from homed drives only
  std::string load_text_;
};

}  // namespace

MRROC_REGISTER_HARDWARE("can", CanHardware);

}  // namespace mrroc::edp
