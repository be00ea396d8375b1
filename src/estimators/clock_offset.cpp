#include "traverse/estimators/clock_offset.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <limits>
#include <optional>
#include <stdexcept>
#include <vector>

#include "traverse/core/so3.h"
#include "traverse/estimators/ekf.h"  // jointSamples
#include "traverse/io/diagnostics.h"
#include "traverse/rover/nominal_slip.h"
#include "traverse/sensors/gyro.h"
#include "traverse/sensors/sun_sensor.h"

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

/// x's centred moving average over ±half seconds.
std::vector<double> movingAverage(const std::vector<double>& t, const std::vector<double>& x,
                                  double half) {
  std::vector<double> out = highPass(t, x, half);
  for (size_t k = 0; k < x.size(); ++k) out[k] = x[k] - out[k];
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

/// The number of contiguous blocks (of the wheel samples) a correlation is split into for its
/// jackknife: the lag's σ from the peaks of the correlation with one block left out at a time.
constexpr size_t kJackknifeBlocks = 16;

/// The normalised correlation Σ a w / √(Σ a² Σ w²) of a pair at each lag (the inertial signal
/// read at t + lag), and the same with each of kJackknifeBlocks blocks of the wheel samples left
/// out (`loo[b][lag]`).
struct Correlation {
  std::vector<double> rho;
  std::vector<std::vector<double>> loo;
};
Correlation correlation(const Pair& p, const std::vector<double>& lags) {
  Correlation c;
  c.rho.assign(lags.size(), 0.0);
  c.loo.assign(kJackknifeBlocks, std::vector<double>(lags.size(), 0.0));
  const size_t n = p.t_wheel.size();
  std::array<double, kJackknifeBlocks> aw{}, aa{}, ww{};
  const auto ratio = [](double xy, double xx, double yy) {
    return xx > 0 && yy > 0 ? xy / std::sqrt(xx * yy) : 0.0;
  };
  for (size_t l = 0; l < lags.size(); ++l) {
    aw.fill(0.0), aa.fill(0.0), ww.fill(0.0);
    size_t cursor = 0;
    for (size_t j = 0; j < n; ++j) {
      const double a = p.inertial.at(p.t_wheel[j] + lags[l], cursor);
      if (std::isnan(a)) continue;
      const size_t b = j * kJackknifeBlocks / n;
      aw[b] += a * p.wheel[j], aa[b] += a * a, ww[b] += p.wheel[j] * p.wheel[j];
    }
    double taw = 0, taa = 0, tww = 0;
    for (size_t b = 0; b < kJackknifeBlocks; ++b) taw += aw[b], taa += aa[b], tww += ww[b];
    c.rho[l] = ratio(taw, taa, tww);
    for (size_t b = 0; b < kJackknifeBlocks; ++b)
      c.loo[b][l] = ratio(taw - aw[b], taa - aa[b], tww - ww[b]);
  }
  return c;
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

/// The jackknife σ of the peak's lag: √((B−1)/B Σ (lag₋ᵦ − mean)²) over the B correlations with
/// one block left out. It is what the data say of the peak's scatter: a flat correlation (a
/// noisy gyro against slowly changing turns) gives a large one, a sharp peak a small one.
double jackknifeSigma(const std::vector<std::vector<double>>& loo,
                      const std::vector<double>& lags) {
  std::vector<double> peaks;
  for (const std::vector<double>& r : loo) {
    size_t k = 0;
    peaks.push_back(peakLag(r, lags, &k));
  }
  double mean = 0.0;
  for (double x : peaks) mean += x;
  mean /= static_cast<double>(peaks.size());
  double ss = 0.0;
  for (double x : peaks) ss += (x - mean) * (x - mean);
  const double b = static_cast<double>(peaks.size());
  return std::sqrt((b - 1) / b * ss);
}

}  // namespace

std::string ClockOffset::message() const {
  char buf[480];
  if (!detail.empty()) {
    std::snprintf(buf, sizeof buf, "clock offset of %+.3f s against %s (%s%s%s)", offset_s,
                  against.c_str(), detail.c_str(), note.empty() ? "" : "; ", note.c_str());
    return buf;
  }
  std::snprintf(buf, sizeof buf,
                "clock offset of %+.3f s against %s (%s %s: correlation %.2f, against %.2f at "
                "zero lag, offset 1-sigma %.3f s%s%s)",
                offset_s, against.c_str(), signals.c_str(), how.c_str(), correlation,
                correlation_at_zero, sigma_s, note.empty() ? "" : "; ", note.c_str());
  return buf;
}

const ClockOffset* ClockAlignment::find(const std::string& file) const {
  for (const ClockOffset& c : shifted)
    if (c.file == file) return &c;
  return nullptr;
}

namespace {

/// The wheels' v_x and ω_z at every measured joint sample: the longitudinal slip rows of the
/// wheels in use, zero slip (the nominal ω_z y_ICR of skid steering), least squares. Each row
/// is affine in (v_x, ω_z), so three evaluations give it exactly.
struct WheelMotion {
  std::vector<double> t, vx, wz;
};
WheelMotion wheelMotion(const io::TraverseLog& log) {
  WheelMotion m;
  const rover::RoverGeometry& geo = log.geometry;
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
    m.t.push_back(js.t), m.vx.push_back(s[0]), m.wz.push_back(s[1]);
  }
  return m;
}

/// The inertial pairs: the gyro's yaw rate and (with accel.csv) the forward acceleration, each
/// against what the wheels say; `file` names the inertial stream.
struct NamedPair {
  std::string file;
  Pair pair;
};
std::vector<NamedPair> inertialPairs(const io::TraverseLog& log, const WheelMotion& wm, double dt,
                                     const ClockOffsetOptions& o) {
  const double half = 0.5 * o.highpass_s;
  std::vector<NamedPair> pairs;
  {  // yaw rate: the gyro's heading axis (its last column in both layouts)
    Pair p;
    p.name = "yaw rate";
    const io::Stream& g = log.gyro;
    p.inertial.t.assign(g.t.data(), g.t.data() + g.size());
    p.inertial.x.resize(p.inertial.t.size());
    for (Eigen::Index k = 0; k < g.size(); ++k)
      p.inertial.x[static_cast<size_t>(k)] = g.values(k, g.values.cols() - 1);
    // Averaged over the span the wheels' rates are differenced over (±h joint intervals), so
    // both signals have one bandwidth — and so the gyro's white noise is not halved where a lag
    // reads it between two samples and left whole where it reads one: interpolating the raw
    // samples made the correlation a saw-tooth over the lags, half a gyro interval apart, whose
    // teeth placed a clean log's peak 0.07 s off (an independent generator's turns, seed 1).
    const double span = std::max(
        static_cast<double>(log.config.joints.rate_filter_half_window) * dt, io::medianPeriod(g));
    p.inertial.x = movingAverage(p.inertial.t, p.inertial.x, span);
    p.inertial.x = highPass(p.inertial.t, p.inertial.x, half);
    p.t_wheel = wm.t, p.wheel = highPass(wm.t, wm.wz, half);
    pairs.push_back({"gyro.csv", std::move(p)});
  }
  if (log.accel && log.accel->size() >= 10) {
    // Forward acceleration: the wheels' v_x differenced over ±m samples against the
    // accelerometer's x axis averaged over the same span (centred: no phase). The gravity a tilt
    // puts on that axis changes slowly and is mostly removed by the high-pass.
    const auto m = static_cast<size_t>(std::max(1L, std::lround(0.15 / dt)));
    const std::vector<double>& tw = wm.t;
    Pair p;
    p.name = "forward acceleration";
    std::vector<double> ax;
    for (size_t j = m; j + m < tw.size(); ++j) {
      const double span = tw[j + m] - tw[j - m];
      if (span > 2.5 * static_cast<double>(m) * dt) continue;  // across a gap: no derivative
      p.t_wheel.push_back(tw[j]);
      ax.push_back((wm.vx[j + m] - wm.vx[j - m]) / span);
    }
    p.wheel = highPass(p.t_wheel, ax, half);
    const io::Stream& a = *log.accel;
    p.inertial.t.assign(a.t.data(), a.t.data() + a.size());
    std::vector<double> x(p.inertial.t.size());
    for (Eigen::Index k = 0; k < a.size(); ++k) x[static_cast<size_t>(k)] = a.values(k, 0);
    p.inertial.x =
        highPass(p.inertial.t, movingAverage(p.inertial.t, x, static_cast<double>(m) * dt), half);
    if (p.t_wheel.size() >= 10) pairs.push_back({"accel.csv", std::move(p)});
  }
  return pairs;
}

/// Lags `step` apart over ±max_lag_s — and around −d as well when `moving` begins and ends d
/// later than `reference` (to two of `period`) with |d| beyond that range: the stamps themselves
/// then point at an offset that large (a 5 s offset on multi-stop gave the smoother a 269 m
/// final error before). Returns the lags and the index of lag 0.
std::vector<double> lagGrid(const std::vector<std::pair<double, double>>& ranges, double step,
                            size_t* zero) {
  double lo = 0.0, hi = 0.0;
  for (const auto& [a, b] : ranges) lo = std::min(lo, a), hi = std::max(hi, b);
  const int l_lo = static_cast<int>(std::ceil(lo / step)), l_hi = static_cast<int>(hi / step);
  std::vector<double> lags;
  for (int l = l_lo; l <= l_hi; ++l) lags.push_back(l * step);
  *zero = static_cast<size_t>(-l_lo);
  return lags;
}
std::pair<double, double> lagRange(const io::Stream& reference, const io::Stream& moving,
                                   double period, double max_lag) {
  const double d0 = moving.t[0] - reference.t[0];
  const double d1 = moving.t[moving.size() - 1] - reference.t[reference.size() - 1];
  double lo = -max_lag, hi = max_lag;
  if (std::abs(d0 - d1) <= 2 * period && std::abs(d0) > max_lag)
    lo = std::min(lo, -d0 - max_lag), hi = std::max(hi, -d0 + max_lag);
  return {lo, hi};
}

/// The signals that hold motion, each weighted by its own peak correlation squared, combined;
/// the offset of the stream correlated against (+: its stamps late: the other signal read at
/// t − d). `significant` as for estimateJointsClockOffset, with `min_offset` for the offset.
ClockOffset combine(const std::vector<std::pair<std::string, const Correlation*>>& signals,
                    const std::vector<double>& lags, size_t zero, double span_s, double min_offset,
                    const ClockOffsetOptions& o) {
  ClockOffset out;
  std::vector<double> rho(lags.size(), 0.0);
  std::vector<std::vector<double>> loo(kJackknifeBlocks, std::vector<double>(lags.size(), 0.0));
  double weight = 0.0;
  for (const auto& [name, c] : signals) {
    const double peak = *std::max_element(c->rho.begin(), c->rho.end());
    if (peak < o.min_signal_correlation) continue;
    const double w = peak * peak;
    for (size_t l = 0; l < lags.size(); ++l) {
      rho[l] += w * c->rho[l];
      for (size_t b = 0; b < kJackknifeBlocks; ++b) loo[b][l] += w * c->loo[b][l];
    }
    weight += w;
    out.signals += (out.signals.empty() ? "" : " and ") + name;
  }
  if (weight <= 0.0) return out;
  for (double& r : rho) r /= weight;
  out.estimated = true;
  size_t k = 0;
  out.offset_s = -peakLag(rho, lags, &k);
  out.correlation = rho[k];
  out.correlation_at_zero = rho[zero];
  out.sigma_s = jackknifeSigma(loo, lags);
  const bool interior = k > 0 && k + 1 < lags.size();
  const double n_eff = span_s / o.correlation_time_s;
  out.significant =
      interior && out.correlation >= o.min_correlation &&
      out.correlation >= 4.0 / std::sqrt(std::max(n_eff, 1.0)) &&
      std::abs(out.offset_s) >= std::max(min_offset, o.min_offset_sigmas * out.sigma_s);
  return out;
}

/// The joints' offset against the inertial pairs (all of them, or one), and each pair's
/// correlation over the lags.
struct InertialCorrelation {
  std::vector<NamedPair> pairs;
  std::vector<Correlation> rho;  ///< per pair, over lags
  std::vector<double> lags;
  size_t zero = 0;
  double dt = 0.0, span_s = 0.0;
  ClockOffset of(const std::vector<size_t>& which, const ClockOffsetOptions& o) const {
    std::vector<std::pair<std::string, const Correlation*>> s;
    for (size_t i : which) s.emplace_back(pairs[i].pair.name, &rho[i]);
    return combine(s, lags, zero, span_s, o.min_offset_periods * dt, o);
  }
};
std::optional<InertialCorrelation> correlateInertial(const io::TraverseLog& log,
                                                     const ClockOffsetOptions& o) {
  if (log.joints.size() < 10 || log.gyro.size() < 10) return std::nullopt;
  InertialCorrelation c;
  c.dt = io::medianPeriod(log.joints);
  if (!(c.dt > 0.0)) return std::nullopt;
  const WheelMotion wm = wheelMotion(log);
  if (wm.t.size() < 10) return std::nullopt;
  c.span_s = wm.t.back() - wm.t.front();
  c.pairs = inertialPairs(log, wm, c.dt, o);
  // Lags a quarter of the joint interval apart; the joints are the moving stream.
  std::vector<std::pair<double, double>> ranges;
  for (const NamedPair& p : c.pairs) {
    const io::Stream& inertial = p.file == "gyro.csv" ? log.gyro : *log.accel;
    ranges.push_back(lagRange(inertial, log.joints, c.dt, o.max_lag_s));
  }
  c.lags = lagGrid(ranges, 0.25 * c.dt, &c.zero);
  for (const NamedPair& p : c.pairs) c.rho.push_back(correlation(p.pair, c.lags));
  return c;
}

}  // namespace

ClockOffset estimateJointsClockOffset(const io::TraverseLog& log, const ClockOffsetOptions& o) {
  const std::optional<InertialCorrelation> c = correlateInertial(log, o);
  if (!c) return {};
  std::vector<size_t> all(c->pairs.size());
  for (size_t i = 0; i < all.size(); ++i) all[i] = i;
  return c->of(all, o);
}

ClockOffset estimateSunClockOffset(const io::TraverseLog& log, const ClockOffsetOptions& o) {
  ClockOffset out;
  out.file = "sun.csv", out.against = "the gyro";
  if (!log.sun || log.sun->size() < 10 || log.gyro.size() < 10) return out;
  const io::Stream& sun = *log.sun;
  const io::Stream& g = log.gyro;
  const double sun_dt = io::medianPeriod(sun), gyro_dt = io::medianPeriod(g);
  if (!(sun_dt > 0.0) || !(gyro_dt > 0.0)) return out;
  const sensors::GyroAxes axes = sensors::GyroAxes::forColumns(g.values.cols());
  const Mat3d& R_bs = log.config.sun_sensor.R_body_sensor;
  // Chains of consecutive valid readings (each well off the body z axis, no gyro gap or long
  // wait between two): the measured turn of the sun's azimuth about the body z axis between two
  // readings, and the coefficients a with φ̇ = a·ω (u the sun in the body frame, u̇ = −ω × u).
  const io::TimeGaps gyro_gaps(g);
  struct Step {
    double t0, t1, turn;
    Vec3d a;
  };
  std::vector<std::vector<Step>> chains(1);
  std::vector<std::vector<double>> sigma(1);  // per reading of a chain: the azimuth's 1σ
  const auto usable = [&](Eigen::Index k) {
    const Vec2d m = sun.values.row(k).head<2>().transpose();
    return sun.values(k, 2) > 0.5 && std::isfinite(m.x()) && std::isfinite(m.y()) &&
           m.norm() > 0.15;
  };
  for (Eigen::Index k = 0; k + 1 < sun.size(); ++k) {
    const bool linked = usable(k) && usable(k + 1) && sun.t[k + 1] - sun.t[k] <= 2.5 * sun_dt &&
                        !gyro_gaps.overlaps(sun.t[k], sun.t[k + 1]);
    if (!linked) {
      if (!chains.back().empty()) chains.emplace_back(), sigma.emplace_back();
      continue;
    }
    const Vec2d m0 = sun.values.row(k).head<2>().transpose();
    const Vec2d m1 = sun.values.row(k + 1).head<2>().transpose();
    const Vec3d u0 = R_bs * sensors::fisheyeUnproject(m0);
    const Vec3d u1 = R_bs * sensors::fisheyeUnproject(m1);
    const Vec3d u = (u0 + u1).normalized();
    const double rho2 = u.x() * u.x() + u.y() * u.y();
    if (rho2 < 0.04 || std::hypot(u0.x(), u0.y()) < 0.2 || std::hypot(u1.x(), u1.y()) < 0.2) {
      if (!chains.back().empty()) chains.emplace_back(), sigma.emplace_back();
      continue;
    }
    Vec3d a;
    for (int i = 0; i < 3; ++i) {
      const Vec3d ud = u.cross(Vec3d::Unit(i));
      a[i] = (u.x() * ud.y() - u.y() * ud.x()) / rho2;
    }
    if (chains.back().empty()) sigma.back().push_back(log.config.sun_sensor.noise / m0.norm());
    chains.back().push_back(
        {sun.t[k], sun.t[k + 1],
         so3::wrapAngle(std::atan2(u1.y(), u1.x()) - std::atan2(u0.y(), u0.x())),
         a.cwiseProduct(axes.mask())});
    sigma.back().push_back(log.config.sun_sensor.noise / m1.norm());
  }
  if (chains.back().empty()) chains.pop_back(), sigma.pop_back();
  size_t steps = 0;
  for (const auto& c : chains) steps += c.size();
  if (steps < 10) return out;
  // The gyro's running integral per column (trapezoid): a turn over an interval is a difference
  // of two interpolated values.
  const std::vector<double> tg(g.t.data(), g.t.data() + g.size());
  std::vector<Series> integral(static_cast<size_t>(g.values.cols()));
  for (Eigen::Index c = 0; c < g.values.cols(); ++c) {
    Series& s = integral[static_cast<size_t>(c)];
    s.t = tg, s.x.assign(tg.size(), 0.0);
    for (size_t k = 1; k < tg.size(); ++k) {
      const auto i = static_cast<Eigen::Index>(k);
      s.x[k] = s.x[k - 1] + 0.5 * (g.values(i, c) + g.values(i - 1, c)) * (tg[k] - tg[k - 1]);
    }
  }
  // At a lag, each chain's residual level e_k — the sun's azimuth minus what the gyro read at
  // t + lag turned it by since the chain began — is a constant heading offset plus a slow drift
  // (the gyro bias) plus the readings' white noise when the lag is right; where the rover turns,
  // a wrong lag adds ω·(lag + d). Its centred moving average over ±half removes the constant and
  // the drift (a linear trend exactly); the weighted sum of squares left is the cost.
  const double half = std::max(5.0, 10.0 * sun_dt);
  const double step = 0.25 * gyro_dt;
  size_t zero = 0;
  const std::vector<double> lags = lagGrid({lagRange(g, sun, sun_dt, o.max_lag_s)}, step, &zero);
  std::vector<double> cost(lags.size(), 0.0);  // mean weighted square per reading
  size_t used = 0;                             // readings at lag 0
  for (size_t l = 0; l < lags.size(); ++l) {
    double sum = 0.0;
    size_t n = 0;
    for (size_t c = 0; c < chains.size(); ++c) {
      const std::vector<Step>& chain = chains[c];
      // A run of steps the gyro covers at this lag (the log's ends cut it).
      std::vector<double> t, e, w;
      const auto flush = [&] {
        if (t.size() >= 3) {
          const std::vector<double> hp = highPass(t, e, half);
          for (size_t k = 0; k < hp.size(); ++k) sum += hp[k] * hp[k] * w[k];
          n += hp.size();
        }
        t.clear(), e.clear(), w.clear();
      };
      std::vector<size_t> cur0(integral.size(), 0), cur1(integral.size(), 0);
      for (size_t i = 0; i < chain.size(); ++i) {
        const Step& st = chain[i];
        double pred = 0.0;
        bool ok = true;
        for (Eigen::Index col = 0; col < g.values.cols() && ok; ++col) {
          const auto cc = static_cast<size_t>(col);
          const double i0 = integral[cc].at(st.t0 + lags[l], cur0[cc]);
          const double i1 = integral[cc].at(st.t1 + lags[l], cur1[cc]);
          if (std::isnan(i0) || std::isnan(i1))
            ok = false;
          else
            pred += st.a[axes.axis(col)] * (i1 - i0);
        }
        if (!ok) {
          flush();
          continue;
        }
        if (t.empty())
          t.push_back(st.t0), e.push_back(0.0), w.push_back(1.0 / (sigma[c][i] * sigma[c][i]));
        t.push_back(st.t1), e.push_back(e.back() + st.turn - pred);
        w.push_back(1.0 / (sigma[c][i + 1] * sigma[c][i + 1]));
      }
      flush();
    }
    cost[l] = n > 0 ? sum / static_cast<double>(n) : std::numeric_limits<double>::infinity();
    if (l == zero) used = n;
  }
  if (used < 10) return out;
  // The minimum, refined by a parabola; its σ from the curvature with the noise scaled by the
  // residual (the reduced χ² at the minimum, when above 1: terrain and model misfit count).
  std::vector<double> neg(cost.size());
  for (size_t l = 0; l < cost.size(); ++l) neg[l] = -cost[l];
  size_t k = 0;
  const double lag = peakLag(neg, lags, &k);
  const size_t h = std::max<size_t>(1, static_cast<size_t>(std::lround(0.05 / step)));
  out.estimated = true;
  out.offset_s = -lag;
  out.signals = "azimuth";
  const double chi2 = cost[k];
  out.correlation = chi2, out.correlation_at_zero = cost[zero];
  if (k < h || k + h >= cost.size()) return out;  // at the range's edge: no minimum inside
  const double hs = static_cast<double>(h) * step;
  const double curvature =  // of the summed cost
      static_cast<double>(used) * (cost[k - h] - 2 * cost[k] + cost[k + h]) / (hs * hs);
  if (!(curvature > 0.0)) return out;
  out.sigma_s = std::sqrt(2.0 * std::max(chi2, 1.0) / curvature);
  // The fit must also explain the readings better than the stamps as they are, by a margin
  // noise and the terrain do not reach: Δχ² (scaled by the reduced χ²) and a share of the
  // residual. The cost's curvature alone is over-confident where nothing turns (a straight
  // drive's azimuth moves only with the tilt, which a heading gyro does not see), and over ten
  // thousand readings (planar-18m's 20 Hz sun) such misfit alone reaches Δχ² ≈ 15 at a 0.1 %
  // share; a 0.3 s offset on multi-stop gives 21–64 at 3–8 %.
  const double delta_chi2 =
      static_cast<double>(used) * (cost[zero] - cost[k]) / std::max(chi2, 1.0);
  out.significant = std::abs(out.offset_s) >= std::max(o.min_sun_offset_s, 4.0 * out.sigma_s) &&
                    delta_chi2 >= o.min_sun_delta_chi2 &&
                    cost[zero] - cost[k] >= o.min_sun_cost_share * cost[k];
  char detail[240];
  std::snprintf(detail, sizeof detail,
                "the sun's azimuth about the body z axis against the gyro's turn over %zu "
                "readings: reduced chi2 %.2f at the offset against %.2f at zero (delta %.0f), "
                "offset 1-sigma %.3f s",
                used, chi2, out.correlation_at_zero, delta_chi2, out.sigma_s);
  out.detail = detail;
  return out;
}

ClockAlignment estimateClockAlignment(const io::TraverseLog& log, const ClockOffsetOptions& o) {
  ClockAlignment out;
  ClockOffset gyro_pair;  // the gyro against the wheels alone (yaw rate), when it was formed
  if (const std::optional<InertialCorrelation> c = correlateInertial(log, o)) {
    if (c->pairs.size() == 1) gyro_pair = c->of({0}, o);
    std::vector<size_t> all(c->pairs.size());
    for (size_t i = 0; i < all.size(); ++i) all[i] = i;
    ClockOffset joints = c->of(all, o);
    bool decided = false;
    if (c->pairs.size() == 2) {
      // Each inertial stream on its own: when both hold motion, correlate well and disagree by
      // more than the joints' resolution, the one that agrees with the wheels shares their
      // clock; the other is off (by minus its pair's offset: the joints late against it by d is
      // that stream early by d).
      ClockOffset gyro = c->of({0}, o), accel = c->of({1}, o);
      gyro_pair = gyro;
      const double tol = o.min_offset_periods * c->dt;
      // "Firm": the pair holds motion (its peak reaches min_signal_correlation) and the peak
      // stands above what noise alone reaches over the log (4/√N, as for `significant`). The
      // wheels' yaw rate is noisy (multi-stop's peaks at 0.40 against 0.22 at zero lag for a
      // 0.3 s gyro offset), so the combined min_correlation is not asked of each pair.
      const double floor = 4.0 / std::sqrt(std::max(c->span_s / o.correlation_time_s, 1.0));
      const auto firm = [&](const ClockOffset& x) {
        return x.estimated && x.correlation >= std::max(floor, o.min_signal_correlation);
      };
      // Apart by more than the joints' resolution and by more than the two peaks' scatter.
      const double apart =
          std::max(tol, o.min_offset_sigmas * std::hypot(gyro.sigma_s, accel.sigma_s));
      if (firm(gyro) && firm(accel) && std::abs(gyro.offset_s - accel.offset_s) > apart) {
        decided = true;
        const auto own = [&](ClockOffset x, const std::string& file, const std::string& against,
                             const char* other, double other_offset) {
          x.file = file, x.offset_s = -x.offset_s, x.against = against;
          x.how = x.signals == "yaw rate" ? "from the wheels cross-correlated with the gyro's"
                                          : "from the wheels cross-correlated with the "
                                            "accelerometer's";
          char note[160];
          std::snprintf(note, sizeof note, "%s against the wheels: %+.3f s", other, -other_offset);
          x.note = note;
          // Firm already; the combined min_correlation is not asked of one pair (above).
          x.significant = std::abs(x.offset_s) >= std::max(tol, o.min_offset_sigmas * x.sigma_s);
          return x;
        };
        std::vector<ClockOffset> moved;
        if (std::abs(accel.offset_s) <= tol) {
          moved.push_back(
              own(gyro, "gyro.csv", "joints.csv and accel.csv", "accel.csv", accel.offset_s));
        } else if (std::abs(gyro.offset_s) <= tol) {
          moved.push_back(
              own(accel, "accel.csv", "joints.csv and gyro.csv", "gyro.csv", gyro.offset_s));
        } else {  // all three apart: the wheels' clock is the reference
          moved.push_back(own(gyro, "gyro.csv", "joints.csv", "accel.csv", accel.offset_s));
          moved.push_back(own(accel, "accel.csv", "joints.csv", "gyro.csv", gyro.offset_s));
        }
        for (const ClockOffset& m : moved)
          if (m.significant) out.shifted.push_back(m);
      }
    }
    if (!decided && joints.significant) out.shifted.push_back(joints);
  }
  const io::TraverseLog aligned = withClocksAligned(log, out);
  ClockOffset sun = estimateSunClockOffset(aligned, o);
  if (sun.significant) {
    // The sun against the gyro cannot tell which of the two is off — unless the gyro's own
    // stamps say so: gyro.csv begins and ends d away from joints.csv (beyond the lags searched
    // by default, to two gyro intervals) and the sun's offset is −d. Then the gyro is the
    // stream apart (a straight drive holds no yaw rate to tell it by the wheels) and is moved.
    const io::Stream& g = aligned.gyro;
    const io::Stream& j = aligned.joints;
    const double period = io::medianPeriod(g);
    const double d0 = g.t[0] - j.t[0], d1 = g.t[g.size() - 1] - j.t[j.size() - 1];
    // Nor when the wheels' yaw rate already saw the gyro off by about as much (by less than
    // the joints' resolution, so it was not moved then): two streams against one.
    const double by_wheels = gyro_pair.estimated ? -gyro_pair.offset_s : 0.0;
    const bool wheels_agree = gyro_pair.estimated &&
                              std::abs(by_wheels) >= 0.5 * std::abs(sun.offset_s) &&
                              std::abs(-sun.offset_s - by_wheels) < 0.5 * std::abs(sun.offset_s);
    const bool stamps_agree =
        std::abs(d0 - d1) <= 2 * period && std::abs(d0) > o.max_lag_s &&
        std::abs(sun.offset_s + d0) <= std::max(o.max_lag_s, 4.0 * sun.sigma_s);
    if (!out.find("gyro.csv") && (stamps_agree || wheels_agree)) {
      ClockOffset gyro = sun;
      gyro.file = "gyro.csv", gyro.offset_s = -sun.offset_s;
      gyro.against = stamps_agree ? "sun.csv" : "sun.csv and joints.csv";
      char note[160];
      if (stamps_agree)
        std::snprintf(note, sizeof note,
                      "gyro.csv begins %+.1f s and ends %+.1f s from joints.csv, sun.csv with it",
                      d0, d1);
      else
        std::snprintf(note, sizeof note, "the wheels' yaw rate puts it at %+.3f s", by_wheels);
      gyro.note = note;
      out.shifted.push_back(gyro);
    } else {
      out.shifted.push_back(sun);
    }
  }
  return out;
}

io::TraverseLog withJointsShifted(const io::TraverseLog& log, double offset_s) {
  return withStreamShifted(log, "joints.csv", offset_s);
}

io::TraverseLog withStreamShifted(const io::TraverseLog& log, const std::string& file,
                                  double offset_s) {
  io::TraverseLog out = log;
  if (file == "joints.csv") {
    out.joints.t.array() -= offset_s;
    for (auto& w : out.wheel_outages) w.t_start -= offset_s, w.t_end -= offset_s;
  } else if (file == "gyro.csv") {
    out.gyro.t.array() -= offset_s;
  } else if (file == "accel.csv" && out.accel) {
    out.accel->t.array() -= offset_s;
  } else if (file == "sun.csv" && out.sun) {
    out.sun->t.array() -= offset_s;
  } else if (file == "cmd.csv" && out.cmd) {
    out.cmd->t.array() -= offset_s;
  } else if (file != "accel.csv" && file != "sun.csv" && file != "cmd.csv") {
    throw std::invalid_argument("withStreamShifted: no stream " + file);
  }
  return out;
}

io::TraverseLog withClocksAligned(const io::TraverseLog& log, const ClockAlignment& alignment) {
  io::TraverseLog out = log;
  for (const ClockOffset& c : alignment.shifted) out = withStreamShifted(out, c.file, c.offset_s);
  return out;
}

}  // namespace traverse::est
