#include "motion_blend.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "mrroc/robot/rest_to_rest.hpp"

namespace mrroc::edp {

namespace {

constexpr double kTolerance = 1e-6;  // relative: rounding of the client's targets
constexpr std::size_t kHorizon = 8;  // queued macro-steps looked at when choosing an end velocity

/// The limits of one joint through one macro-step, as half-planes in (x, y) = (start velocity,
/// end velocity): A x + B y <= C.
struct HalfPlane {
  double a, b, c;
};

/// The half-planes of a macro-step with mean velocity u and duration T: both half accelerations
/// within +-acc, the velocity at half time within +-vmax, both end velocities within +-vmax.
int macro_step_planes(double u, double T, double acc, double vmax, HalfPlane (&out)[10]) {
  int n = 0;
  const auto band = [&](double c, double p, double q, double bound) {
    // |c u - p x - q y| <= bound
    out[n++] = {p, q, c * u + bound};
    out[n++] = {-p, -q, bound - c * u};
  };
  band(4.0, 3.0, 1.0, acc * T);
  band(4.0, 1.0, 3.0, acc * T);
  band(2.0, 0.5, 0.5, vmax);
  out[n++] = {1, 0, vmax};
  out[n++] = {-1, 0, vmax};
  return n;
}

struct Range {
  double lo = 0, hi = 0;
  bool empty = true;
};

/// Start velocities x from which some end velocity y in `end` satisfies the planes: the extreme x
/// of the polygon, found among the intersections of its edges.
Range start_range(const HalfPlane (&planes)[10], int n, Range end) {
  Range out;
  if (end.empty) return out;
  HalfPlane all[12];
  for (int i = 0; i < n; ++i) all[i] = planes[i];
  all[n] = {0, 1, end.hi};
  all[n + 1] = {0, -1, -end.lo};
  const int m = n + 2;
  for (int i = 0; i < m; ++i)
    for (int j = i + 1; j < m; ++j) {
      const double det = all[i].a * all[j].b - all[j].a * all[i].b;
      if (std::abs(det) < 1e-12) continue;
      const double x = (all[i].c * all[j].b - all[j].c * all[i].b) / det;
      const double y = (all[i].a * all[j].c - all[j].a * all[i].c) / det;
      bool inside = true;
      for (int k = 0; k < m && inside; ++k)
        inside = all[k].a * x + all[k].b * y <= all[k].c + 1e-9 * (1.0 + std::abs(all[k].c));
      if (!inside) continue;
      if (out.empty) {
        out = {x, x, false};
      } else {
        out.lo = std::min(out.lo, x);
        out.hi = std::max(out.hi, x);
      }
    }
  return out;
}

/// End velocities y allowed from start velocity x.
Range end_range(const HalfPlane (&planes)[10], int n, double x) {
  Range out{-1e300, 1e300, false};
  for (int i = 0; i < n; ++i) {
    const double rest = planes[i].c - planes[i].a * x;
    if (planes[i].b > 0)
      out.hi = std::min(out.hi, rest / planes[i].b);
    else if (planes[i].b < 0)
      out.lo = std::max(out.lo, rest / planes[i].b);
    else if (rest < -1e-9 * (1.0 + std::abs(planes[i].c)))
      out.empty = true;
  }
  if (out.lo > out.hi) out.empty = true;
  return out;
}

}  // namespace

BlendRefusal plan_blend(const BlendInput& in, const RobotModel& model, std::size_t axes,
                        AxisArray& end_velocity, std::span<char> why) {
  const MacroStep& m = *in.step;
  const double T = static_cast<double>(m.steps) * in.period_s;
  const bool promises = m.promises_successor();
  const char* where = in.after_ramp ? ", starting where a stopping ramp left the robot" : "";
  for (std::size_t i = 0; i < axes; ++i) {
    const double p0 = (*in.start)[i];
    const double p1 = m.target[i];
    const double v0 = (*in.velocity)[i];
    const double u = (p1 - p0) / T;
    const double acc = model.max_acceleration[i];
    const double vmax = model.max_velocity[i];
    const char* unit = model.unit(i);
    if (std::abs(u) > vmax * (1.0 + kTolerance)) {
      std::snprintf(why.data(), why.size(),
                    "joint %zu would move at %.3f %s/s, above its limit of %.3f %s/s (from %.4f "
                    "to %.4f %s in %d steps of %.1f ms%s)",
                    i, std::abs(u), unit, model.max_velocity[i], unit, p0, p1, unit, m.steps,
                    in.period_s * 1e3, where);
      return BlendRefusal::velocity;
    }
    // Planned within the limits; refused only beyond them by more than the rounding tolerance.
    HalfPlane planes[10];
    int n = macro_step_planes(u, T, acc, vmax, planes);
    Range local = end_range(planes, n, v0);
    const auto fits = [&](const Range& r) {
      return promises ? !r.empty : !r.empty && r.lo <= 0.0 && r.hi >= 0.0;
    };
    if (!fits(local)) {
      n = macro_step_planes(u, T, acc * (1.0 + kTolerance), vmax * (1.0 + kTolerance), planes);
      local = end_range(planes, n, v0);
    }
    double v1 = 0.0;
    const bool rest_ok = fits(local);
    if (!rest_ok) {
      // Which limit: the least acceleration any end velocity needs, else the velocity.
      const double needed = promises ? 2.0 * std::abs(u - v0) / T
                                     : std::max(std::abs(4 * u - 3 * v0), std::abs(v0 - 4 * u)) / T;
      if (needed > acc * (1.0 + kTolerance)) {
        if (!promises && v0 == 0.0)
          std::snprintf(why.data(), why.size(),
                        "joint %zu would accelerate at %.3f %s/s^2, above its limit of %.3f "
                        "%s/s^2 (from rest at %.4f to rest at %.4f %s in %d steps of %.1f ms; it "
                        "needs at least %d steps%s)",
                        i, needed, unit, model.max_acceleration[i], unit, p0, p1, unit, m.steps,
                        in.period_s * 1e3,
                        shortest_rest_to_rest_steps(p1 - p0, model.max_velocity[i],
                                                    model.max_acceleration[i], in.period_s),
                        where);
        else if (promises)
          std::snprintf(why.data(), why.size(),
                        "joint %zu would accelerate at %.3f %s/s^2, above its limit of %.3f "
                        "%s/s^2 (from %.4f %s/s to a mean of %.4f %s/s in %d steps of %.1f ms%s)",
                        i, needed, unit, model.max_acceleration[i], unit, v0, unit, u, unit,
                        m.steps, in.period_s * 1e3, where);
        else
          std::snprintf(why.data(), why.size(),
                        "joint %zu would accelerate at %.3f %s/s^2, above its limit of %.3f "
                        "%s/s^2 (from %.4f %s/s to rest at %.4f %s in %d steps of %.1f ms: the "
                        "last macro-step must bring the joint to rest within its limit%s)",
                        i, needed, unit, model.max_acceleration[i], unit, v0, unit, p1, unit,
                        m.steps, in.period_s * 1e3, where);
        return BlendRefusal::acceleration;
      }
      std::snprintf(why.data(), why.size(),
                    "joint %zu cannot go from %.4f %s/s to %s %.4f %s in %d steps of %.1f ms "
                    "within both its velocity limit of %.3f %s/s and its acceleration limit of "
                    "%.3f %s/s^2 (it would pass %.3f %s/s half way%s)",
                    i, v0, unit, promises ? "a mean velocity over" : "rest at", p1, unit, m.steps,
                    in.period_s * 1e3, model.max_velocity[i], unit, model.max_acceleration[i], unit,
                    std::abs(2 * u - 0.5 * v0), unit, where);
      return BlendRefusal::velocity;
    }
    if (promises) {
      // Backwards through the queue: the end velocities from which every queued macro-step can
      // still be joined, down to rest after the last one if it promises no successor.
      // At most kHorizon of them: enough for the stock profiles (a lookahead of 8) and a bounded
      // cost in the servo thread; beyond it any velocity is assumed reachable.
      Range reachable{-vmax, vmax, false};
      const std::size_t count = std::min(in.following.size(), kHorizon);
      if (count == in.following.size() && count > 0 &&
          !in.following[count - 1]->promises_successor())
        reachable = {0, 0, false};
      for (std::size_t k = count; k-- > 0;) {
        const MacroStep& f = *in.following[k];
        const double from = k == 0 ? p1 : in.following[k - 1]->target[i];
        const double Tf = static_cast<double>(f.steps) * in.period_s;
        HalfPlane fp[10];
        const int fn = macro_step_planes((f.target[i] - from) / Tf, Tf, acc, vmax, fp);
        reachable = start_range(fp, fn, reachable);
        if (reachable.empty) break;
      }
      double lo = local.lo, hi = local.hi;
      if (count > 0 && !reachable.empty && reachable.lo <= hi && reachable.hi >= lo) {
        lo = std::max(lo, reachable.lo);
        hi = std::min(hi, reachable.hi);
      }
      double preferred = u;
      if (count > 0)
        preferred = 0.5 * (u + (in.following[0]->target[i] - p1) /
                                   (static_cast<double>(in.following[0]->steps) * in.period_s));
      v1 = std::clamp(preferred, lo, std::max(lo, hi));
    }
    // Between its ends the joint may pass beyond them where its velocity changes sign.
    const double vm = 2.0 * u - 0.5 * (v0 + v1);
    const double half = 0.5 * T;
    double extreme[2];
    int extremes = 0;
    if ((v0 > 0) != (vm > 0) && v0 != vm)
      extreme[extremes++] = p0 + 0.5 * v0 * (v0 / (v0 - vm) * half);
    if ((vm > 0) != (v1 > 0) && vm != v1) {
      const double pm = p0 + 0.5 * (v0 + vm) * half;
      extreme[extremes++] = pm + 0.5 * vm * (vm / (vm - v1) * half);
    }
    for (int k = 0; k < extremes; ++k)
      if (extreme[k] < model.lower_limits[i] || extreme[k] > model.upper_limits[i]) {
        std::snprintf(why.data(), why.size(),
                      "joint %zu would reach %.4f %s between its macro-step's ends, beyond its "
                      "limits %.4f..%.4f %s",
                      i, extreme[k], unit, model.lower_limits[i], model.upper_limits[i], unit);
        return BlendRefusal::limit;
      }
    end_velocity[i] = v1;
  }
  return BlendRefusal::none;
}

int shortest_rest_to_rest_steps(double distance, double max_velocity, double max_acceleration,
                                double period_s) {
  const double t = rest_to_rest_duration(distance, max_velocity, max_acceleration);
  return std::max(1, static_cast<int>(std::ceil(t / period_s - 1e-9)));
}

}  // namespace mrroc::edp
