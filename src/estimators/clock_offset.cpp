#include "traverse/estimators/clock_offset.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <vector>

#include "traverse/estimators/ekf.h"  // jointSamples
#include "traverse/rover/nominal_slip.h"

namespace traverse::est {
namespace {

/// x minus its centred moving average over ±half seconds (samples at stamps t, in order).
std::vector<double> highPass(const std::vector<double>& t, const std::vector<double>& x,
                             double half) {
  std::vector<double> out(x.size());
  size_t lo = 0, hi = 0;
  double sum = 0.0;
  for (size_t k = 0; k < x.size(); ++k) {
    while (hi < x.size() && t[hi] <= t[k] + half) sum += x[hi++];
    while (t[lo] < t[k] - half) sum -= x[lo++];
    out[k] = x[k] - sum / static_cast<double>(hi - lo);
  }
  return out;
}

/// A signal sampled at its own stamps, linearly interpolated (NaN outside its span).
struct Series {
  std::vector<double> t, x;
  double at(double s, size_t& cursor) const {
    if (t.size() < 2 || s < t.front() || s > t.back()) return std::nan("");
    while (cursor > 0 && t[cursor] > s) --cursor;
    while (cursor + 2 < t.size() && t[cursor + 1] < s) ++cursor;
    const double u = (s - t[cursor]) / (t[cursor + 1] - t[cursor]);
    return (1 - u) * x[cursor] + u * x[cursor + 1];
  }
};

/// One pair: the inertial signal and what the wheels say of the same quantity at joint times.
struct Pair {
  std::string name;
  Series inertial;
  std::vector<double> t_wheel, wheel;
};

/// The normalised correlation Σ a w / √(Σ a² Σ w²) of the pair at each lag (the inertial signal
/// read at t + lag).
std::vector<double> correlation(const Pair& p, const std::vector<double>& lags) {
  std::vector<double> rho(lags.size(), 0.0);
  for (size_t l = 0; l < lags.size(); ++l) {
    double aw = 0, aa = 0, ww = 0;
    size_t cursor = 0;
    for (size_t j = 0; j < p.t_wheel.size(); ++j) {
      const double a = p.inertial.at(p.t_wheel[j] + lags[l], cursor);
      if (std::isnan(a)) continue;
      aw += a * p.wheel[j], aa += a * a, ww += p.wheel[j] * p.wheel[j];
    }
    rho[l] = aa > 0 && ww > 0 ? aw / std::sqrt(aa * ww) : 0.0;
  }
  return rho;
}

/// The lag of the highest correlation, refined by a parabola through it and its neighbours.
double peakLag(const std::vector<double>& rho, const std::vector<double>& lags, size_t* index) {
  const size_t k = static_cast<size_t>(std::max_element(rho.begin(), rho.end()) - rho.begin());
  *index = k;
  double lag = lags[k];
  if (k > 0 && k + 1 < lags.size()) {
    const double den = rho[k - 1] - 2 * rho[k] + rho[k + 1];
    if (den < 0) lag += 0.5 * (lags[1] - lags[0]) * (rho[k - 1] - rho[k + 1]) / den;
  }
  return lag;
}

}  // namespace

std::string ClockOffset::message() const {
  char buf[320];
  std::snprintf(buf, sizeof buf,
                "clock offset of %+.3f s against the gyro and accelerometer (%s from the wheels "
                "cross-correlated with the inertial sensors: correlation %.2f, against %.2f at "
                "zero lag)",
                offset_s, signals.c_str(), correlation, correlation_at_zero);
  return buf;
}

ClockOffset estimateJointsClockOffset(const io::TraverseLog& log, const ClockOffsetOptions& o) {
  ClockOffset out;
  if (log.joints.size() < 10 || log.gyro.size() < 10) return out;
  const double dt = io::medianPeriod(log.joints);
  if (!(dt > 0.0)) return out;
  // The wheels' v_x and ω_z at every measured joint sample: the longitudinal slip rows of the
  // wheels in use, zero slip (the nominal ω_z y_ICR of skid steering), least squares. Each row
  // is affine in (v_x, ω_z), so three evaluations give it exactly.
  const rover::RoverGeometry& geo = log.geometry;
  std::vector<double> tw, vx, wz;
  for (const rover::JointSample& js : jointSamples(log)) {
    if (!js.measured) continue;
    Eigen::Matrix2d N = Eigen::Matrix2d::Zero();
    Eigen::Vector2d b = Eigen::Vector2d::Zero();
    int rows = 0;
    for (int i = 0; i < geo.numWheels(); ++i) {
      if (!js.wheelUsed(i)) continue;
      const auto k = static_cast<size_t>(i);
      const rover::Wheel& w = geo.wheels[k];
      const auto row = [&](const Vec3d& v, const Vec3d& om) {
        return rover::slipConstraint<double>(js.T_body_wheel[k], w.radius, js.joint_twist[k], v, om,
                                             0.0)[0];
      };
      const double c = row(Vec3d::Zero(), Vec3d::Zero());
      const Eigen::Vector2d a(row(Vec3d::UnitX(), Vec3d::Zero()) - c,
                              row(Vec3d::Zero(), Vec3d::UnitZ()) - c - w.icr_offset_y);
      N += a * a.transpose(), b -= a * c, ++rows;
    }
    if (rows < 2 || std::abs(N.determinant()) < 1e-12 * N.squaredNorm()) continue;
    const Eigen::Vector2d s = N.ldlt().solve(b);
    tw.push_back(js.t), vx.push_back(s[0]), wz.push_back(s[1]);
  }
  if (tw.size() < 10) return out;
  const double half = 0.5 * o.highpass_s;
  std::vector<Pair> pairs;
  {  // yaw rate: the gyro's heading axis (its last column in both layouts)
    Pair p;
    p.name = "yaw rate";
    const io::Stream& g = log.gyro;
    p.inertial.t.assign(g.t.data(), g.t.data() + g.size());
    p.inertial.x.resize(p.inertial.t.size());
    for (Eigen::Index k = 0; k < g.size(); ++k)
      p.inertial.x[static_cast<size_t>(k)] = g.values(k, g.values.cols() - 1);
    p.inertial.x = highPass(p.inertial.t, p.inertial.x, half);
    p.t_wheel = tw, p.wheel = highPass(tw, wz, half);
    pairs.push_back(std::move(p));
  }
  if (log.accel) {
    // Forward acceleration: the wheels' v_x differenced over ±m samples against the
    // accelerometer's x axis averaged over the same span (centred: no phase). The gravity a tilt
    // puts on that axis changes slowly and is mostly removed by the high-pass.
    const auto m = static_cast<size_t>(std::max(1L, std::lround(0.15 / dt)));
    Pair p;
    p.name = "forward acceleration";
    std::vector<double> ax;
    for (size_t j = m; j + m < tw.size(); ++j) {
      const double span = tw[j + m] - tw[j - m];
      if (span > 2.5 * static_cast<double>(m) * dt) continue;  // across a gap: no derivative
      p.t_wheel.push_back(tw[j]);
      ax.push_back((vx[j + m] - vx[j - m]) / span);
    }
    p.wheel = highPass(p.t_wheel, ax, half);
    const io::Stream& a = *log.accel;
    p.inertial.t.assign(a.t.data(), a.t.data() + a.size());
    std::vector<double> x(p.inertial.t.size());
    for (Eigen::Index k = 0; k < a.size(); ++k) x[static_cast<size_t>(k)] = a.values(k, 0);
    const std::vector<double> fast = highPass(p.inertial.t, x, static_cast<double>(m) * dt);
    for (size_t k = 0; k < x.size(); ++k) x[k] -= fast[k];  // the moving average itself
    p.inertial.x = highPass(p.inertial.t, x, half);
    if (p.t_wheel.size() >= 10) pairs.push_back(std::move(p));
  }
  // Lags a quarter of the joint interval apart, over ±max_lag_s — and around −d as well when
  // joints.csv begins and ends d later than gyro.csv (to two joint intervals) with |d| beyond
  // that range: the stamps themselves then point at an offset that large (a 5 s offset on
  // multi-stop gave the smoother a 269 m final error before).
  const double step = 0.25 * dt;
  const io::Stream& g = log.gyro;
  const double d0 = log.joints.t[0] - g.t[0];
  const double d1 = log.joints.t[log.joints.size() - 1] - g.t[g.size() - 1];
  double lo = -o.max_lag_s, hi = o.max_lag_s;
  if (std::abs(d0 - d1) <= 2 * dt && std::abs(d0) > o.max_lag_s) {
    lo = std::min(lo, -d0 - o.max_lag_s), hi = std::max(hi, -d0 + o.max_lag_s);
  }
  const int l_lo = static_cast<int>(std::ceil(lo / step)), l_hi = static_cast<int>(hi / step);
  std::vector<double> lags;
  for (int l = l_lo; l <= l_hi; ++l) lags.push_back(l * step);
  const auto zero = static_cast<size_t>(-l_lo);  // the index of lag 0
  // The signals that hold motion, each weighted by its own peak correlation squared.
  std::vector<double> rho(lags.size(), 0.0);
  double weight = 0.0;
  for (const Pair& p : pairs) {
    const std::vector<double> r = correlation(p, lags);
    const double peak = *std::max_element(r.begin(), r.end());
    if (peak < o.min_signal_correlation) continue;
    for (size_t l = 0; l < lags.size(); ++l) rho[l] += peak * peak * r[l];
    weight += peak * peak;
    out.signals += (out.signals.empty() ? "" : " and ") + p.name;
  }
  if (weight <= 0.0) return out;
  for (double& r : rho) r /= weight;
  out.estimated = true;
  size_t k = 0;
  out.offset_s = -peakLag(rho, lags, &k);  // joints late by d: the inertial signal at t − d
  out.correlation = rho[k];
  out.correlation_at_zero = rho[zero];
  const bool interior = k > 0 && k + 1 < lags.size();
  const double n_eff = (tw.back() - tw.front()) / o.correlation_time_s;
  out.significant = interior && out.correlation >= o.min_correlation &&
                    out.correlation >= 4.0 / std::sqrt(std::max(n_eff, 1.0)) &&
                    std::abs(out.offset_s) >= o.min_offset_periods * dt;
  return out;
}

io::TraverseLog withJointsShifted(const io::TraverseLog& log, double offset_s) {
  io::TraverseLog out = log;
  out.joints.t.array() -= offset_s;
  for (auto& w : out.wheel_outages) w.t_start -= offset_s, w.t_end -= offset_s;
  return out;
}

}  // namespace traverse::est
