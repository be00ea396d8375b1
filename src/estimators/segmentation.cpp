#include "traverse/estimators/segmentation.h"

#include <algorithm>
#include <cmath>

#include "traverse/estimators/ekf.h"  // chiSquareQuantile
#include "traverse/io/diagnostics.h"  // findGaps, TimeGaps
#include "traverse/rover/joint_rates.h"
#include "traverse/rover/rover_geometry.h"
#include "traverse/sensors/gyro.h"

namespace traverse::est {
namespace {

/// Nickels' transient flag per gyro sample: any axis differs from the mean of the previous
/// `window` samples by more than the threshold.
std::vector<unsigned char> gyroTransients(const io::Stream& gyro, const SegmentationOptions& o) {
  const Eigen::Index n = gyro.size(), c = gyro.values.cols();
  std::vector<unsigned char> flag(static_cast<size_t>(n), 0);
  Eigen::RowVectorXd sum = Eigen::RowVectorXd::Zero(c);
  for (Eigen::Index k = 0; k < n; ++k) {
    const Eigen::Index m = std::min<Eigen::Index>(k, o.mean_window);
    if (m > 0) {
      const Eigen::RowVectorXd mean = sum / static_cast<double>(m);
      flag[static_cast<size_t>(k)] =
          (gyro.values.row(k) - mean).cwiseAbs().maxCoeff() > o.gyro_threshold_rad_s;
    }
    sum += gyro.values.row(k);
    if (k >= o.mean_window) sum -= gyro.values.row(k - o.mean_window);
  }
  return flag;
}

/// Index of the sample of `t` nearest to time x.
Eigen::Index nearest(const Eigen::VectorXd& t, double x) {
  const double* b = t.data();
  const double* e = b + t.size();
  const double* it = std::lower_bound(b, e, x);
  if (it == e) return t.size() - 1;
  if (it != b && x - *(it - 1) < *it - x) --it;
  return it - b;
}

/// Hysteresis over the activity flags; returns per-sample rest (1) / motion (0), with motion
/// runs snapped to their first and last active sample.
std::vector<unsigned char> hysteresis(const std::vector<unsigned char>& active,
                                      const SegmentationOptions& o) {
  const size_t n = active.size();
  std::vector<unsigned char> rest(n, 1);
  bool moving = false;
  size_t run_start = 0, last_active = 0;
  int run = 0;
  for (size_t k = 0; k < n; ++k) {
    const bool a = active[k];
    if (!moving) {
      run = a ? run + 1 : 0;
      if (run == 1) run_start = k;
      if (run >= o.enter_count) {
        moving = true;
        for (size_t j = run_start; j <= k; ++j) rest[j] = 0;
        last_active = k;
        run = 0;
      }
    } else {
      rest[k] = 0;
      if (a) {
        last_active = k, run = 0;
      } else if (++run >= o.leave_count) {
        moving = false;
        for (size_t j = last_active + 1; j <= k; ++j) rest[j] = 1;
        run = 0;
      }
    }
  }
  if (moving) {
    for (size_t j = last_active + 1; j < n; ++j) rest[j] = 1;
  }
  return rest;
}

void restMeasurements(const io::TraverseLog& log, const SegmentationOptions& o, RestWindow& w) {
  const double a = w.t_start + o.edge_margin_s, b = w.t_end - o.edge_margin_s;
  const io::Stream& g = log.gyro;
  const sensors::GyroAxes axes = sensors::GyroAxes::forColumns(g.values.cols());
  w.bias_axes = {axes.measures(0), axes.measures(1), axes.measures(2)};
  std::vector<Eigen::Index> idx;
  for (Eigen::Index k = 0; k < g.size(); ++k) {
    if (g.t[k] >= a && g.t[k] <= b) idx.push_back(k);
  }
  w.gyro_samples = static_cast<int>(idx.size());
  if (idx.size() >= 2) {
    for (Eigen::Index c = 0; c < g.values.cols(); ++c) {
      const int axis = axes.axis(c);
      double s = 0, s2 = 0;
      for (Eigen::Index k : idx) s += g.values(k, c);
      const double mean = s / static_cast<double>(idx.size());
      for (Eigen::Index k : idx) s2 += (g.values(k, c) - mean) * (g.values(k, c) - mean);
      const double var = s2 / static_cast<double>(idx.size() - 1);
      w.bias[axis] = mean;
      // Standard error of the mean, floored by the configured white noise (short windows).
      w.bias_sigma[axis] =
          std::sqrt(std::max(var, log.config.gyro.noise_rad_s * log.config.gyro.noise_rad_s) /
                    static_cast<double>(idx.size()));
    }
  }
  if (log.accel) {
    const io::Stream& acc = *log.accel;
    Vec3d sum = Vec3d::Zero();
    Mat3d sum2 = Mat3d::Zero();
    int n = 0;
    for (Eigen::Index k = 0; k < acc.size(); ++k) {
      if (acc.t[k] < a || acc.t[k] > b) continue;
      const Vec3d f = acc.values.row(k).transpose();
      sum += f, sum2 += f * f.transpose(), ++n;
    }
    if (n >= 3) {
      const Vec3d mean = sum / n;
      Mat3d cov = (sum2 - n * mean * mean.transpose()) / (n - 1);
      const double floor = log.config.accel.noise_mps2 * log.config.accel.noise_mps2;
      for (int i = 0; i < 3; ++i) cov(i, i) = std::max(cov(i, i), floor);
      w.has_gravity = true;
      w.mean_specific_force = mean;
      w.roll_pitch = sensors::rollPitchAtRest(mean, cov / n);
    }
  }
  if (log.sun) {
    const io::Stream& s = *log.sun;
    Vec2d sum = Vec2d::Zero();
    int n = 0;
    for (Eigen::Index k = 0; k < s.size(); ++k) {
      if (s.t[k] < a || s.t[k] > b || s.values(k, 2) < 0.5) continue;
      sum += Vec2d(s.values(k, 0), s.values(k, 1)), ++n;
    }
    if (n > 0) w.has_sun = true, w.mean_sun = sum / n, w.sun_samples = n;
  }
}

/// Nickels' per-axis drift filter run over the whole gyro stream; its state at each window end.
void driftFilter(const io::TraverseLog& log, const Segmentation& seg,
                 std::vector<RestWindow>& rests) {
  const io::Stream& g = log.gyro;
  const sensors::GyroAxes axes = sensors::GyroAxes::forColumns(g.values.cols());
  const double q = log.config.gyro.bias_random_walk_rad_s_per_sqrt_s;
  const double r = std::max(log.config.gyro.noise_rad_s * log.config.gyro.noise_rad_s, 1e-12);
  Vec3d d = Vec3d::Zero();
  Vec3d P = Vec3d::Constant(log.config.gyro.initial_bias_sigma_rad_s *
                            log.config.gyro.initial_bias_sigma_rad_s);
  size_t w = 0;
  for (Eigen::Index k = 0; k < g.size(); ++k) {
    const double dt = k > 0 ? g.t[k] - g.t[k - 1] : 0.0;
    P.array() += q * q * dt;  // bias random walk (maneuvering: estimate held, uncertainty grows)
    if (seg.gyro_rest[static_cast<size_t>(k)]) {
      for (Eigen::Index c = 0; c < g.values.cols(); ++c) {
        const int axis = axes.axis(c);
        const double K = P[axis] / (P[axis] + r);
        d[axis] += K * (g.values(k, c) - d[axis]);
        P[axis] *= 1.0 - K;
      }
    }
    while (w < rests.size() && (k + 1 == g.size() || g.t[k + 1] > rests[w].t_end)) {
      rests[w].drift = d, rests[w].drift_sigma = P.cwiseSqrt();
      ++w;
    }
  }
}

}  // namespace

Eigen::VectorXd wheelSpeeds(const io::TraverseLog& log, int half_window) {
  const io::Stream& j = log.joints;
  const Eigen::MatrixXd rates = rover::jointRates(
      std::span<const double>(j.t.data(), static_cast<size_t>(j.size())), j.values,
      {half_window > 0 ? half_window : log.config.joints.rate_filter_half_window});
  Eigen::VectorXd speed = Eigen::VectorXd::Zero(j.size());
  for (const rover::Wheel& w : log.geometry.wheels)
    speed += w.radius * rates.col(w.coord).cwiseAbs();
  return speed / log.geometry.numWheels();
}

bool Segmentation::atRest(double t) const {
  for (const Segment& s : segments) {
    if (t >= s.t_start && t <= s.t_end) return s.kind == Segment::Kind::kRest;
  }
  return false;
}

/// Moves the end of every motion run back to its last raw-active sample: a rate away from the
/// previous rest's bias, or turning wheels. Nickels' running mean keeps flagging transients for
/// up to `mean_window` samples after a turn stops (new samples differ from the old mean), which
/// would otherwise leak into the next rest window.
void snapMotionEnds(const io::Stream& g, const std::vector<unsigned char>& wheels_active,
                    const SegmentationOptions& o, std::vector<unsigned char>& rest) {
  const auto n = static_cast<Eigen::Index>(rest.size());
  Eigen::RowVectorXd bias = Eigen::RowVectorXd::Zero(g.values.cols()), sum = bias;
  long count = 0;
  for (Eigen::Index k = 0; k < n; ++k) {
    if (rest[static_cast<size_t>(k)]) {
      sum += g.values.row(k), ++count;
      continue;
    }
    if (count > 0) bias = sum / static_cast<double>(count);
    sum.setZero(), count = 0;
    Eigen::Index e = k;
    while (e + 1 < n && !rest[static_cast<size_t>(e + 1)]) ++e;
    // Raw activity on a 3-sample average, so a single noisy sample does not hold the run open.
    auto raw_active = [&](Eigen::Index j) {
      if (wheels_active[static_cast<size_t>(j)]) return true;
      const Eigen::Index a = std::max<Eigen::Index>(j - 1, 0),
                         b = std::min<Eigen::Index>(j + 1, n - 1);
      const Eigen::RowVectorXd mean = g.values.middleRows(a, b - a + 1).colwise().mean();
      return (mean - bias).cwiseAbs().maxCoeff() > o.gyro_threshold_rad_s;
    };
    Eigen::Index last = e;
    while (last > k && !raw_active(last)) --last;
    for (Eigen::Index j = last + 1; j <= e; ++j) rest[static_cast<size_t>(j)] = 1;
    k = e;
  }
}

/// Trims each rest run (gyro sample indices, rest = 1) to the part whose integrated rotation and
/// wheel travel are consistent with rest at the declared noise. The reference is the run's core
/// (its middle half): its mean gyro reading b̂ is the bias, its mean wheel angles the wheels'
/// rest position. From the core outward, U(q) = Σ_{k=q}^{core−1} (ω_k − b̂) Δt is a random walk
/// at rest (variance m σ_g² Δt² + m² Δt² σ_b̂², m samples), and each wheel's V_i(q) = ψ_i(q) −
/// ψ̄_i,core is white (variance σ_ψ² (1 + 1/n_core); each wheel on its own, since a turn in place
/// rolls the two sides in opposite senses and leaves their mean still). Walking outward, the first
/// sample at which either statistic (any gyro axis, any wheel) exceeds `rest_trim_sigma` standard
/// deviations and everything beyond it become motion: a slow start or stop whose rate stays
/// under the transient detector's threshold still turns a measurable angle or rolls a
/// measurable distance. Repeated (at most three times) with the core of the shortened run.
/// Edges at the start or end of the log are not trimmed (nothing moves before or after them).
void trimRestRuns(const io::TraverseLog& log, const SegmentationOptions& o,
                  std::vector<unsigned char>& rest) {
  if (o.rest_trim_sigma <= 0) return;
  const io::Stream& g = log.gyro;
  const io::Stream& j = log.joints;
  const auto n = static_cast<Eigen::Index>(rest.size());
  // Declared noise, floored at a resolution no real sensor beats (a noise-free simulated log
  // declares 0 and would turn rounding into motion).
  constexpr double kMinNoise = 1e-5;  // rad/s per gyro sample, rad per wheel angle
  const double sg2 = std::pow(std::max(log.config.gyro.noise_rad_s, kMinNoise), 2);
  const double thr2 = o.rest_trim_sigma * o.rest_trim_sigma;
  // Each wheel on its own (a turn in place moves the wheels in opposite senses, so their mean
  // stays put): its angle's deviation from the core's mean angle, variance σ_ψ² (1 + 1/n_core).
  const double sw2 = std::pow(std::max(log.config.joints.wheel_noise_rad, kMinNoise), 2);
  const int nw = log.geometry.numWheels();
  Eigen::MatrixXd psi(j.size(), nw);  // the wheels' drive angles
  for (int i = 0; i < nw; ++i) psi.col(i) = j.values.col(log.geometry.wheels[i].coord);
  const auto wheel_angles = [&](Eigen::Index m) { return psi.row(m).transpose(); };
  for (Eigen::Index k = 0; k < n;) {
    if (!rest[static_cast<size_t>(k)]) {
      ++k;
      continue;
    }
    Eigen::Index a = k, b = k;
    while (b + 1 < n && rest[static_cast<size_t>(b + 1)]) ++b;
    const Eigen::Index a0 = a, b0 = b;
    const bool trim_start = a > 0, trim_end = b + 1 < n;
    for (int iter = 0; iter < 3 && (trim_start || trim_end); ++iter) {
      const Eigen::Index len = b - a + 1;
      if (len < 8) break;
      const Eigen::Index c0 = a + len / 4, c1 = b - len / 4;  // the core
      const double nc = static_cast<double>(c1 - c0 + 1);
      const Eigen::RowVectorXd bias = g.values.middleRows(c0, c1 - c0 + 1).colwise().mean();
      // Wheels: the core's mean angle of each.
      const Eigen::Index j0 = nearest(j.t, g.t[c0]), j1 = nearest(j.t, g.t[c1]);
      const Eigen::VectorXd ref = psi.middleRows(j0, j1 - j0 + 1).colwise().mean().transpose();
      const double vw = sw2 * (1.0 + 1.0 / static_cast<double>(j1 - j0 + 1));
      // Outward from the core; returns the innermost index (towards the edge) still consistent.
      auto scan = [&](Eigen::Index from, Eigen::Index to, int step) {
        Eigen::RowVectorXd sum = Eigen::RowVectorXd::Zero(g.values.cols());
        Eigen::Index keep = to;  // edge index the run keeps
        double m = 0;
        for (Eigen::Index q = from; q != to - step; q -= step) {
          sum += g.values.row(q) - bias, m += 1;
          const double var = m * sg2 + m * m * sg2 / nc;
          const double d2 = (wheel_angles(nearest(j.t, g.t[q])) - ref).cwiseAbs2().maxCoeff();
          if (sum.cwiseAbs2().maxCoeff() > thr2 * var || d2 > thr2 * vw) {
            keep = q + step;
            break;
          }
        }
        return keep;
      };
      const Eigen::Index na = trim_start ? scan(c0 - 1, a, 1) : a;
      const Eigen::Index nb = trim_end ? scan(c1 + 1, b, -1) : b;
      if (na == a && nb == b) break;
      a = na, b = nb;
    }
    for (Eigen::Index m = a0; m < a; ++m) rest[static_cast<size_t>(m)] = 0;
    for (Eigen::Index m = b + 1; m <= b0; ++m) rest[static_cast<size_t>(m)] = 0;
    k = b0 + 1;
  }
}

namespace {

/// A gap is never evidence of rest: rest needs positive evidence from the gyro and the wheels
/// both. The gyro samples either side of a gyro gap (io::findGaps), and every gyro sample that
/// falls inside a joints.csv gap or outside the joint stream's span (beyond its gap tolerance),
/// are motion — so a rest window ends at the last sample that saw rest, the segment boundary
/// falls at the gap's edge instead of its middle, and no zero-velocity or zero-rate constraint
/// is put where nothing was measured.
void gapsAreNotRest(const io::TraverseLog& log, std::vector<unsigned char>& rest) {
  constexpr double kGapFactor = 3.0;  // as io::diagnose and `traverse info`
  const io::Stream& g = log.gyro;
  const io::Stream& j = log.joints;
  for (const io::Gap& gap : io::findGaps(g, kGapFactor)) {
    rest[static_cast<size_t>(gap.before)] = 0;
    rest[static_cast<size_t>(gap.before) + 1] = 0;
  }
  if (j.empty()) return;
  const io::TimeGaps joint_gaps(j, kGapFactor);
  const double tol = kGapFactor * io::medianInterval(j);
  for (Eigen::Index k = 0; k < g.size(); ++k) {
    const double t = g.t[k];
    if (joint_gaps.contains(t) || t < j.t[0] - tol || t > j.t[j.size() - 1] + tol)
      rest[static_cast<size_t>(k)] = 0;
  }
}

struct RestStatistic {
  double chi2 = 0.0;
  int dof = 0;
};

/// The χ² rest statistic of gyro samples a..b (testRestRuns says what it is).
RestStatistic restStatistic(const io::TraverseLog& log, Eigen::Index a, Eigen::Index b) {
  const io::Stream& g = log.gyro;
  const io::Stream& j = log.joints;
  constexpr double kMinNoise = 1e-5;  // as trimRestRuns: a noise-free log declares 0
  const double sg2 = std::pow(std::max(log.config.gyro.noise_rad_s, kMinNoise), 2);
  const double qb2 = std::pow(log.config.gyro.bias_random_walk_rad_s_per_sqrt_s, 2);
  const double sw2 = std::pow(std::max(log.config.joints.wheel_noise_rad, kMinNoise), 2);
  // z² of the least-squares slope of column c of rows a0..b0 against t.
  auto slope_z2 = [](const Eigen::VectorXd& t, const Eigen::MatrixXd& values, Eigen::Index c,
                     Eigen::Index a0, Eigen::Index b0, double noise_var, double extra_var) {
    if (b0 - a0 < 2) return 0.0;
    const double t_mean = t.segment(a0, b0 - a0 + 1).mean();
    const double y_mean = values.col(c).segment(a0, b0 - a0 + 1).mean();
    double stt = 0, sty = 0;
    for (Eigen::Index k = a0; k <= b0; ++k) {
      stt += (t[k] - t_mean) * (t[k] - t_mean);
      sty += (t[k] - t_mean) * (values(k, c) - y_mean);
    }
    if (stt <= 0) return 0.0;
    const double slope = sty / stt;
    return slope * slope / (noise_var / stt + extra_var);
  };
  RestStatistic s;
  const double span = std::max(g.t[b] - g.t[a], 1e-9);
  for (Eigen::Index c = 0; c < g.values.cols(); ++c)
    s.chi2 += slope_z2(g.t, g.values, c, a, b, sg2, 1.2 * qb2 / span);
  // Wheels: each wheel's travel between the first and last quarter of the run (means), with
  // variance 2σ_ψ² — not divided by the sample count: an encoder's quantisation error at rest
  // is one constant, not white, so averaging does not shrink it.
  const Eigen::Index j0 = nearest(j.t, g.t[a]), j1 = nearest(j.t, g.t[b]);
  const Eigen::Index quarter = std::max<Eigen::Index>((j1 - j0 + 1) / 4, 1);
  for (const rover::Wheel& w : log.geometry.wheels) {
    const Eigen::Index c = w.coord;
    const double d = j.values.col(c).segment(j1 - quarter + 1, quarter).mean() -
                     j.values.col(c).segment(j0, quarter).mean();
    s.chi2 += d * d / (2 * sw2);
  }
  s.dof = static_cast<int>(g.values.cols()) + log.geometry.numWheels();
  return s;
}

/// χ² rest test of each rest run (gyro sample indices, rest = 1) as a whole. At rest every
/// measured gyro axis is its bias plus white noise, so its least-squares slope over the run is
/// zero within σ_g² / Σ(t − t̄)², plus 1.2 q_b² / T for the bias random walk over the run's length
/// T (the slope of a Brownian path of density q_b² fitted over T); and every wheel stands still,
/// so the difference of its mean angle over the run's last and first quarters is zero within
/// 2σ_ψ² (not divided by the sample count: an encoder's quantisation error at rest is one
/// constant, not white noise). A run that creeps — a slow, steady roll or turn that neither the
/// transient detector nor the trim can see, because no edge stands out or the run borders the
/// log's ends — fails it. Σ z² over the measured axes and the wheels is χ² with that many degrees
/// of freedom, compared with its quantile at `rest_test_probability`. A run that fails is halved
/// and each half tested again, down to `min_rest_s`: the parts that pass stay rest (a creep next
/// to a true rest leaves the rest), the others become motion and are recorded in `refused`.
/// Runs shorter than `min_rest_s` are left to the merge that follows.
void testRestRuns(const io::TraverseLog& log, const SegmentationOptions& o,
                  std::vector<unsigned char>& rest, std::vector<RefusedRest>& refused) {
  if (o.rest_test_probability <= 0) return;
  const io::Stream& g = log.gyro;
  const auto n = static_cast<Eigen::Index>(rest.size());
  const int dof = static_cast<int>(g.values.cols()) + log.geometry.numWheels();
  const double threshold = chiSquareQuantile(o.rest_test_probability, dof);
  auto refuse = [&](Eigen::Index a, Eigen::Index b, double chi2) {
    std::fill(rest.begin() + a, rest.begin() + b + 1, 0);
    if (a > 0 && !refused.empty() && refused.back().t_end == g.t[a - 1]) {  // adjacent halves
      refused.back().t_end = g.t[b], refused.back().chi2 = std::max(refused.back().chi2, chi2);
    } else {
      refused.push_back({g.t[a], g.t[b], chi2, threshold, dof});
    }
  };
  auto check = [&](auto& self, Eigen::Index a, Eigen::Index b) -> void {
    const RestStatistic s = restStatistic(log, a, b);
    if (s.chi2 <= threshold) return;
    if (g.t[b] - g.t[a] < 2 * o.min_rest_s) return refuse(a, b, s.chi2);
    const Eigen::Index mid = a + (b - a) / 2;
    self(self, a, mid);
    self(self, mid + 1, b);
  };
  for (Eigen::Index k = 0; k < n;) {
    if (!rest[static_cast<size_t>(k)]) {
      ++k;
      continue;
    }
    Eigen::Index b = k;
    while (b + 1 < n && rest[static_cast<size_t>(b + 1)]) ++b;
    if (g.t[b] - g.t[k] >= o.min_rest_s) check(check, k, b);
    k = b + 1;
  }
}

}  // namespace

Segmentation segment(const io::TraverseLog& log, const SegmentationOptions& options) {
  SegmentationOptions o = options;
  o.gyro_threshold_rad_s =
      std::max(o.gyro_threshold_rad_s, o.gyro_threshold_noise_sigmas * log.config.gyro.noise_rad_s);
  Segmentation seg;
  const io::Stream& g = log.gyro;
  seg.gyro_t = g.t;
  std::vector<unsigned char> active = gyroTransients(g, o);
  // Wheel activity with the shortest differencing (±1 sample): the smoothing filter's window
  // would smear a stop over its width.
  const Eigen::VectorXd speed = wheelSpeeds(log, 1);
  std::vector<unsigned char> wheels(active.size(), 0);
  for (Eigen::Index k = 0; k < g.size(); ++k) {
    if (speed[nearest(log.joints.t, g.t[k])] > o.wheel_speed_threshold_mps) {
      active[static_cast<size_t>(k)] = 1, wheels[static_cast<size_t>(k)] = 1;
    }
  }
  seg.gyro_rest = hysteresis(active, o);
  snapMotionEnds(g, wheels, o, seg.gyro_rest);
  gapsAreNotRest(log, seg.gyro_rest);
  trimRestRuns(log, o, seg.gyro_rest);
  testRestRuns(log, o, seg.gyro_rest, seg.refused_rests);
  // Runs of equal mode → segments; short rests are merged into the motion around them.
  const auto n = static_cast<size_t>(g.size());
  for (size_t k = 0; k < n;) {
    size_t e = k;
    while (e + 1 < n && seg.gyro_rest[e + 1] == seg.gyro_rest[k]) ++e;
    const bool rest = seg.gyro_rest[k];
    const double t0 =
        k == 0 ? g.t[0]
               : 0.5 * (g.t[static_cast<Eigen::Index>(k) - 1] + g.t[static_cast<Eigen::Index>(k)]);
    const double t1 =
        e + 1 == n
            ? g.t[g.size() - 1]
            : 0.5 * (g.t[static_cast<Eigen::Index>(e)] + g.t[static_cast<Eigen::Index>(e) + 1]);
    const bool short_rest = rest && (t1 - t0) < o.min_rest_s && k > 0 && e + 1 < n;
    if (short_rest)
      std::fill(seg.gyro_rest.begin() + static_cast<long>(k),
                seg.gyro_rest.begin() + static_cast<long>(e) + 1, 0);
    const Segment::Kind kind = rest && !short_rest ? Segment::Kind::kRest : Segment::Kind::kMotion;
    if (!seg.segments.empty() && seg.segments.back().kind == kind) {
      seg.segments.back().t_end = t1;
    } else {
      seg.segments.push_back({kind, t0, t1, -1});
    }
    k = e + 1;
  }
  for (Segment& s : seg.segments) {
    if (s.kind != Segment::Kind::kRest) continue;
    RestWindow w;
    w.t_start = s.t_start, w.t_end = s.t_end;
    restMeasurements(log, o, w);
    const Eigen::Index a = nearest(g.t, w.t_start), b = nearest(g.t, w.t_end);
    const RestStatistic stat = restStatistic(log, a, b);
    w.rest_chi2 = stat.chi2, w.rest_dof = stat.dof;
    s.rest_index = static_cast<int>(seg.rests.size());
    seg.rests.push_back(w);
  }
  driftFilter(log, seg, seg.rests);
  return seg;
}

}  // namespace traverse::est
