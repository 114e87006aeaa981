/// @file
/// Stock sensor plugins of the VSP (docs/sensors.md):
///   force_torque  wrist force/torque from six strain gauges: calibration matrix, bias (zeroing),
///                 first-order low-pass filter, tool gravity compensation;
///   range         ultrasonic / infrared range finders: median filter, the nearest of the sources;
///   conveyor      conveyor position and speed from its encoder;
///   object_pose   an object's pose from a camera (emulated: see mrroc-axis-emu's camera).
#include <fmt/format.h>
#include <Eigen/Dense>

#include <algorithm>
#include <cmath>
#include <deque>
#include <limits>

#include "mrroc/core/error.hpp"
#include "mrroc/vsp/sensor.hpp"

namespace mrroc::vsp {
namespace {

void require_sources(const SensorSetup& setup, std::size_t min, std::size_t max,
                     const char* plugin) {
  if (setup.sources.size() < min || setup.sources.size() > max)
    throw ConfigError(
        setup.params.location(),
        fmt::format("sensor plugin '{}' of VSP '{}' takes {} source(s), got {}", plugin, setup.name,
                    min == max ? std::to_string(min) : fmt::format("{}..{}", min, max),
                    setup.sources.size()));
}

void require_values(const RawSample& s, std::size_t n, const char* plugin) {
  if (s.values.size() != n)
    throw Error(fmt::format("{}: source '{}' sent {} values, {} expected", plugin, s.device,
                            s.values.size(), n));
}

double seconds(std::int64_t a_us, std::int64_t b_us) {
  return static_cast<double>(a_us - b_us) * 1e-6;
}

/// First-order low-pass: y += (x - y) * dt / (rc + dt); cut-off 0 passes x through.
double low_pass(double y, double x, double cutoff_hz, double dt) {
  if (!(cutoff_hz > 0.0) || !(dt > 0.0)) return x;
  const double rc = 1.0 / (2.0 * M_PI * cutoff_hz);
  return y + (x - y) * dt / (rc + dt);
}

class ForceTorque final : public SensorPlugin {
 public:
  [[nodiscard]] std::string plugin_name() const override { return "force_torque"; }

  void configure(const SensorSetup& setup) override {
    require_sources(setup, 1, 1, "force_torque");
    const Params& p = setup.params;
    calibration_ = Eigen::Matrix<double, 6, 6>::Identity();
    if (p.has("calibration")) {
      const auto rows = p.get_double_rows("calibration");
      if (rows.size() != 6)
        throw ConfigError(p.location_of("calibration"),
                          "'calibration' must be 6 rows of 6 numbers (gauge volts -> N, N m)");
      for (std::size_t r = 0; r < 6; ++r) {
        if (rows[r].size() != 6)
          throw ConfigError(
              p.location_of("calibration"),
              fmt::format("'calibration' row {} has {} numbers, 6 needed", r, rows[r].size()));
        for (std::size_t c = 0; c < 6; ++c)
          calibration_(static_cast<Eigen::Index>(r), static_cast<Eigen::Index>(c)) = rows[r][c];
      }
    }
    filter_hz_ = p.get_double("filter_hz", 0.0);
    if (filter_hz_ < 0.0 || !std::isfinite(filter_hz_))
      throw ConfigError(
          p.location_of("filter_hz"),
          fmt::format("'filter_hz' = {} Hz must be >= 0 Hz (0: no filter)", filter_hz_));
    tool_mass_ = p.get_double("tool_mass", 0.0);
    if (tool_mass_ < 0.0 || tool_mass_ > 1000.0)
      throw ConfigError(p.location_of("tool_mass"),
                        fmt::format("'tool_mass' = {} kg is outside 0..1000 kg", tool_mass_));
    const std::vector<double> com = p.get_doubles("tool_com", {0.0, 0.0, 0.0});
    if (com.size() != 3)
      throw ConfigError(p.location_of("tool_com"), "'tool_com' must be [x, y, z] in m");
    tool_com_ = Eigen::Vector3d(com[0], com[1], com[2]);
    gravity_ = p.get_double("gravity", 9.81);
    p.reject_unread("vsp.params");
  }

  void on_sample(std::size_t, const RawSample& s) override {
    if (!s.valid) {
      sample_valid_ = false;
      return;
    }
    require_values(s, 6, "force_torque");
    Eigen::Matrix<double, 6, 1> g;
    for (int i = 0; i < 6; ++i) g(i) = s.values[static_cast<std::size_t>(i)];
    const Eigen::Matrix<double, 6, 1> w = calibration_ * g;
    const double dt = have_ ? seconds(s.sample_utime, last_utime_) : 0.0;
    Eigen::Matrix<double, 6, 1> next;
    for (int i = 0; i < 6; ++i)
      next(i) = have_ ? low_pass(filtered_(i), w(i), filter_hz_, dt) : w(i);
    // Volts far beyond any gauge's range overflow the calibration or the filter: refused before
    // the filter keeps an infinity for good.
    if (!next.allFinite())
      throw Error(
          fmt::format("force_torque: gauge values up to {:g} V give forces that are not "
                      "finite numbers",
                      g.cwiseAbs().maxCoeff()));
    filtered_ = next;
    have_ = true;
    sample_valid_ = true;
    last_utime_ = s.sample_utime;
  }

  void command(const Params& args) override {
    const bool zero = args.get_bool("zero", false);
    args.reject_unread("CONFIGURE arguments of force_torque");
    if (zero) {
      if (!have_) throw ConfigError("force_torque: cannot zero: no sample from the gauges yet");
      bias_ = filtered_ - tool_load(rotation_);
    }
  }

  Reading make_reading(const Params& context) override {
    if (context.has("rotation")) {
      const std::vector<double> r = context.get_doubles("rotation");
      if (r.size() != 9)
        throw ConfigError(
            "INITIATE_READING: 'rotation' must be 9 numbers (sensor to world, row by "
            "row)");
      for (int i = 0; i < 9; ++i) rotation_(i / 3, i % 3) = r[static_cast<std::size_t>(i)];
    }
    context.reject_unread("INITIATE_READING arguments of force_torque");
    Reading out;
    out.names = {"fx", "fy", "fz", "tx", "ty", "tz"};
    out.units = {"N", "N", "N", "N m", "N m", "N m"};
    if (!have_ || !sample_valid_) {
      out.invalid_reason = "the strain gauges sent no valid sample";
      return out;
    }
    const Eigen::Matrix<double, 6, 1> w = filtered_ - bias_ - tool_load(rotation_);
    out.values.assign(w.data(), w.data() + 6);
    out.valid = w.allFinite();
    if (!out.valid) out.invalid_reason = "the compensated force is not a finite number";
    return out;
  }

 private:
  /// The tool's weight as the sensor feels it, in the sensor frame.
  [[nodiscard]] Eigen::Matrix<double, 6, 1> tool_load(const Eigen::Matrix3d& rotation) const {
    const Eigen::Vector3d f =
        rotation.transpose() * Eigen::Vector3d(0.0, 0.0, -tool_mass_ * gravity_);
    Eigen::Matrix<double, 6, 1> w;
    w << f, tool_com_.cross(f);
    return w;
  }

  Eigen::Matrix<double, 6, 6> calibration_ = Eigen::Matrix<double, 6, 6>::Identity();
  Eigen::Matrix<double, 6, 1> filtered_ = Eigen::Matrix<double, 6, 1>::Zero();
  Eigen::Matrix<double, 6, 1> bias_ = Eigen::Matrix<double, 6, 1>::Zero();
  Eigen::Matrix3d rotation_ = Eigen::Matrix3d::Identity();
  Eigen::Vector3d tool_com_ = Eigen::Vector3d::Zero();
  double filter_hz_ = 0.0;
  double tool_mass_ = 0.0;
  double gravity_ = 9.81;
  bool have_ = false;
  bool sample_valid_ = false;
  std::int64_t last_utime_ = 0;
};

class Range final : public SensorPlugin {
 public:
  [[nodiscard]] std::string plugin_name() const override { return "range"; }

  void configure(const SensorSetup& setup) override {
    require_sources(setup, 1, 16, "range");
    const Params& p = setup.params;
    min_ = p.get_double("min_m", 0.02);
    max_ = p.get_double("max_m", 4.0);
    if (!(min_ >= 0.0 && max_ > min_))
      throw ConfigError(
          p.location(),
          fmt::format("range limits min_m = {} m, max_m = {} m: need 0 <= min_m < max_m", min_,
                      max_));
    const std::int64_t median = p.get_int("median", 1);
    if (median < 1 || median > 99 || median % 2 == 0)
      throw ConfigError(
          p.location_of("median"),
          fmt::format("'median' = {} must be an odd window of 1..99 samples", median));
    window_ = static_cast<std::size_t>(median);
    p.reject_unread("vsp.params");
    history_.assign(setup.sources.size(), {});
    sources_ = setup.sources;
  }

  void on_sample(std::size_t source, const RawSample& s) override {
    auto& h = history_[source];
    if (!s.valid) {
      h.clear();  // out of range: nothing echoed
      return;
    }
    require_values(s, 1, "range");
    h.push_back(s.values[0]);
    while (h.size() > window_) h.pop_front();
  }

  Reading make_reading(const Params& context) override {
    context.reject_unread("INITIATE_READING arguments of range");
    Reading out;
    double nearest = std::numeric_limits<double>::infinity();
    for (std::size_t i = 0; i < history_.size(); ++i) {
      std::vector<double> v(history_[i].begin(), history_[i].end());
      double d = std::numeric_limits<double>::infinity();
      if (!v.empty()) {
        std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2), v.end());
        d = v[v.size() / 2];
      }
      nearest = std::min(nearest, d);
    }
    out.names = {"distance"};
    out.units = {"m"};
    if (!(nearest >= min_ && nearest <= max_)) {
      out.invalid_reason =
          std::isfinite(nearest)
              ? fmt::format("distance {:.3f} m outside {:.3f}..{:.3f} m", nearest, min_, max_)
              : fmt::format("no echo within {:.3f} m", max_);
      return out;
    }
    out.values = {nearest};
    out.valid = true;
    return out;
  }

 private:
  double min_ = 0.02;
  double max_ = 4.0;
  std::size_t window_ = 1;
  std::vector<std::deque<double>> history_;
  std::vector<std::string> sources_;
};

class Conveyor final : public SensorPlugin {
 public:
  [[nodiscard]] std::string plugin_name() const override { return "conveyor"; }

  void configure(const SensorSetup& setup) override {
    require_sources(setup, 1, 1, "conveyor");
    filter_hz_ = setup.params.get_double("speed_filter_hz", 20.0);
    if (!(filter_hz_ >= 0.0))
      throw ConfigError(setup.params.location_of("speed_filter_hz"),
                        fmt::format("'speed_filter_hz' = {} Hz must be >= 0 Hz", filter_hz_));
    setup.params.reject_unread("vsp.params");
  }

  void on_sample(std::size_t, const RawSample& s) override {
    if (!s.valid) return;
    require_values(s, 1, "conveyor");
    if (have_) {
      const double dt = seconds(s.sample_utime, last_utime_);
      if (dt > 0.0) speed_ = low_pass(speed_, (s.values[0] - position_) / dt, filter_hz_, dt);
    }
    position_ = s.values[0];
    last_utime_ = s.sample_utime;
    have_ = true;
  }

  Reading make_reading(const Params& context) override {
    context.reject_unread("INITIATE_READING arguments of conveyor");
    Reading out;
    out.names = {"position", "speed"};
    out.units = {"m", "m/s"};
    if (!have_) {
      out.invalid_reason = "no encoder sample yet";
      return out;
    }
    out.values = {position_, speed_};
    out.valid = true;
    return out;
  }

 private:
  double filter_hz_ = 20.0;
  double position_ = 0.0;
  double speed_ = 0.0;
  std::int64_t last_utime_ = 0;
  bool have_ = false;
};

class ObjectPose final : public SensorPlugin {
 public:
  [[nodiscard]] std::string plugin_name() const override { return "object_pose"; }

  void configure(const SensorSetup& setup) override {
    require_sources(setup, 1, 1, "object_pose");
    setup.params.reject_unread("vsp.params");
  }

  void on_sample(std::size_t, const RawSample& s) override {
    visible_ = s.valid;
    if (!s.valid) return;
    require_values(s, 7, "object_pose");
    pose_ = s.values;
    have_ = true;
  }

  Reading make_reading(const Params& context) override {
    context.reject_unread("INITIATE_READING arguments of object_pose");
    Reading out;
    out.names = {"visible", "x", "y", "z", "qw", "qx", "qy", "qz"};
    out.units = {"", "m", "m", "m", "", "", "", ""};
    out.values.assign(8, 0.0);
    out.values[4] = 1.0;
    if (visible_ && have_) {
      out.values[0] = 1.0;
      std::copy(pose_.begin(), pose_.end(), out.values.begin() + 1);
    }
    out.valid = true;  // "nothing seen" is a valid reading
    return out;
  }

 private:
  std::vector<double> pose_;
  bool visible_ = false;
  bool have_ = false;
};

}  // namespace

MRROC_REGISTER_SENSOR("force_torque", ForceTorque);
MRROC_REGISTER_SENSOR("range", Range);
MRROC_REGISTER_SENSOR("conveyor", Conveyor);
MRROC_REGISTER_SENSOR("object_pose", ObjectPose);

}  // namespace mrroc::vsp
