// Evaluation against position-only truth (include/traverse/eval/position_truth.h,
// docs/evaluation.md).
#include "traverse/eval/position_truth.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>
#include <stdexcept>

#include <Eigen/Cholesky>

#include "eval/table.h"
#include "traverse/core/so3.h"
#include "traverse/eval/alignment.h"

namespace traverse::eval {
namespace {

constexpr double kMinLength = 1e-9;  // m; as metrics.cpp
/// χ²₃ at the 3σ ellipsoid: eᵀC⁻¹e ≤ 9 (holds 97.1 % of honest 3-D Gaussian errors).
constexpr double kThreeSigmaSquared = 9.0;

double median(std::vector<double> v) {
  const auto mid = v.begin() + static_cast<long>(v.size() / 2);
  std::nth_element(v.begin(), mid, v.end());
  if (v.size() % 2 == 1) return *mid;
  return 0.5 * (*mid + *std::max_element(v.begin(), mid));
}

/// Linear interpolation weight of t between the brackets of a sorted time vector: index i and
/// a ∈ [0, 1] of i + 1 (t clamped to the span).
std::pair<std::size_t, double> bracket(const std::vector<double>& ts, double t) {
  if (ts.size() < 2 || t <= ts.front()) return {0, 0.0};
  if (t >= ts.back()) return {ts.size() - 2, 1.0};
  const std::size_t i =
      static_cast<std::size_t>(std::upper_bound(ts.begin(), ts.end(), t) - ts.begin()) - 1;
  return {i, (t - ts[i]) / (ts[i + 1] - ts[i])};
}

double rms(const std::vector<double>& sq) {
  double sum = 0.0;
  for (double v : sq) sum += v;
  return std::sqrt(sum / static_cast<double>(sq.size()));
}

}  // namespace

PositionTruth::PositionTruth(const io::Stream& gps, const Vec3d& antenna_body_m)
    : antenna_body_m_(antenna_body_m) {
  if (gps.empty()) throw std::invalid_argument("gps: no fixes");
  for (const char* c : {"x", "y", "z", "sx", "sy", "sz"}) {
    if (!gps.has(c)) throw std::invalid_argument(std::string("gps: no column ") + c);
  }
  const auto x = gps.channel("x"), y = gps.channel("y"), z = gps.channel("z");
  const auto sx = gps.channel("sx"), sy = gps.channel("sy"), sz = gps.channel("sz");
  for (Eigen::Index k = 0; k < gps.size(); ++k) {
    fixes_.push_back({gps.t[k], Vec3d(x[k], y[k], z[k]), Vec3d(sx[k], sy[k], sz[k])});
  }
  // Medians (per axis) of the fixes in bins of 1 s, or of 5 fix periods when the fixes are
  // sparser (a median of fewer than ~5 fixes does not reject a jump), at each bin's middle.
  const double width = std::max(1.0, 5.0 * io::medianPeriod(gps));
  const double t0 = fixes_.front().t;
  std::size_t k = 0;
  Eigen::Vector2d prev = Eigen::Vector2d::Zero();
  while (k < fixes_.size()) {
    const double bin = std::floor((fixes_[k].t - t0) / width);
    std::vector<double> bx, by;
    for (; k < fixes_.size() && std::floor((fixes_[k].t - t0) / width) == bin; ++k) {
      bx.push_back(fixes_[k].p_site.x()), by.push_back(fixes_[k].p_site.y());
    }
    const Eigen::Vector2d m(median(bx), median(by));
    track_s_.push_back(track_t_.empty() ? 0.0 : track_s_.back() + (m - prev).norm());
    track_t_.push_back(t0 + (bin + 0.5) * width);
    prev = m;
  }
}

double PositionTruth::distanceTravelled(double t) const {
  const auto [i, a] = bracket(track_t_, t);
  if (track_t_.size() < 2) return 0.0;
  return (1.0 - a) * track_s_[i] + a * track_s_[i + 1];
}

FixPairs pairWithFixes(const est::Trajectory& trajectory, const PositionTruth& truth) {
  FixPairs out;
  const auto& nodes = trajectory.nodes;
  if (nodes.empty()) return out;
  std::vector<double> ts;
  for (const est::TrajectoryNode& n : nodes) ts.push_back(n.t);
  const Vec3d& lever = truth.antennaBody();
  for (const PositionFix& f : truth.fixes()) {
    if (f.t < ts.front() || f.t > ts.back()) continue;  // no extrapolation
    const auto [i, a] = bracket(ts, f.t);
    const est::TrajectoryNode& n0 = nodes[i];
    const est::TrajectoryNode& n1 = nodes[std::min(i + 1, nodes.size() - 1)];
    const Vec3d p = (1.0 - a) * n0.p_site + a * n1.p_site;
    const Quatd q = n0.q_site_body.normalized().slerp(a, n1.q_site_body.normalized());
    const Mat3d R = q.toRotationMatrix();
    out.t.push_back(f.t);
    out.antenna_hat.push_back(p + R * lever);
    out.fix.push_back(f.p_site);
    out.sigma.push_back(f.sigma);
    if (trajectory.has_covariance) {
      // δâ = δp − R [L]× δθ for q = q̂ ⊗ Exp(δθ). The position–attitude cross-covariance is
      // left out: the trajectory files do not carry it, and `evaluate` (from the files) must
      // give what `run` (in memory) gives.
      const Mat6d P = (1.0 - a) * n0.covariance + a * n1.covariance;
      const Mat3d J_theta = -R * so3::skew(lever);
      out.covariance.push_back(P.topLeftCorner<3, 3>() +
                               J_theta * P.bottomRightCorner<3, 3>() * J_theta.transpose());
    }
  }
  return out;
}

StartPinnedErrors startPinnedErrors(const FixPairs& pairs, const PositionTruth& truth,
                                    const std::vector<bool>& pin, double start_span_m) {
  StartPinnedErrors out;
  const std::size_t n = pairs.t.size();
  if (n == 0 || pin.size() != n) return out;
  const double s0 = truth.distanceTravelled(pairs.t.front());
  double wh_sum = 0.0, wz_sum = 0.0;
  Vec3d ca = Vec3d::Zero(), cb = Vec3d::Zero();  // weighted start of estimate and fixes
  for (std::size_t k = 0; k < n; ++k) {
    if (!pin[k] || truth.distanceTravelled(pairs.t[k]) - s0 > start_span_m) continue;
    const double wh = 1.0 / pairs.sigma[k].head<2>().squaredNorm() * 2.0;
    const double wz = 1.0 / (pairs.sigma[k].z() * pairs.sigma[k].z());
    ca.head<2>() += wh * pairs.antenna_hat[k].head<2>(),
        cb.head<2>() += wh * pairs.fix[k].head<2>();
    ca.z() += wz * pairs.antenna_hat[k].z(), cb.z() += wz * pairs.fix[k].z();
    wh_sum += wh, wz_sum += wz;
  }
  if (!(wh_sum > 0.0 && wz_sum > 0.0)) return out;
  ca.head<2>() /= wh_sum, cb.head<2>() /= wh_sum, ca.z() /= wz_sum, cb.z() /= wz_sum;
  double num = 0.0, den = 0.0;  // yaw about the pinned start, horizontal weights
  for (std::size_t k = 0; k < n; ++k) {
    if (!pin[k]) continue;
    const Vec3d a = pairs.antenna_hat[k] - ca, b = pairs.fix[k] - cb;
    const double w = 2.0 / pairs.sigma[k].head<2>().squaredNorm();
    num += w * (a.x() * b.y() - a.y() * b.x()), den += w * (a.x() * b.x() + a.y() * b.y());
  }
  out.valid = true;
  out.yaw = std::atan2(num, den);
  out.pin_variance = Vec3d(1.0 / wh_sum, 1.0 / wh_sum, 1.0 / wz_sum);
  const Mat3d R = Eigen::AngleAxisd(out.yaw, Vec3d::UnitZ()).toRotationMatrix();
  for (std::size_t k = 0; k < n; ++k) {
    out.error.push_back(R * (pairs.antenna_hat[k] - ca) + cb - pairs.fix[k]);
    if (k < pairs.covariance.size())
      out.covariance.push_back(
          R * pairs.covariance[k] * R.transpose() +
          Mat3d(
              (pairs.sigma[k].array().square() + out.pin_variance.array()).matrix().asDiagonal()));
  }
  return out;
}

WholeTrackAlignment alignWholeTrack(const FixPairs& pairs, const PositionTruthOptions& o) {
  const std::size_t n = pairs.t.size();
  WholeTrackAlignment out;
  out.whole = alignPosYawRobust(pairs.antenna_hat, pairs.fix, pairs.sigma,
                                std::vector<bool>(n, true), o.huber_k, o.max_iterations);
  out.inlier.resize(n);
  for (std::size_t k = 0; k < n; ++k) {
    out.inlier[k] = !out.whole.outlier(k, o.outlier_threshold);
    out.used += out.inlier[k] ? 1 : 0;
  }
  return out;
}

Metrics evaluateAgainstFixes(const est::Trajectory& trajectory, const PositionTruth& truth,
                             const PositionTruthOptions& o) {
  Metrics m;
  const FixPairs pairs = pairWithFixes(trajectory, truth);
  const std::size_t n = pairs.t.size();
  if (n == 0) return m;
  const WholeTrackAlignment fit = alignWholeTrack(pairs, o);
  const RobustPosYawAlignment& whole = fit.whole;
  const std::vector<bool>& inlier = fit.inlier;
  const std::size_t used = fit.used;
  m.set("gps_fixes_used", static_cast<double>(used));
  m.set("gps_fixes_rejected", static_cast<double>(n - used));
  if (used == 0) return m;

  std::vector<double> e2, e2_h;
  for (std::size_t k = 0; k < n; ++k) {
    if (!inlier[k]) continue;
    const Vec3d e = whole.alignment.apply(pairs.antenna_hat[k]) - pairs.fix[k];
    e2.push_back(e.squaredNorm());
    e2_h.push_back(e.head<2>().squaredNorm());
  }
  m.set("ate_posyaw_m", rms(e2));
  m.set("ate_posyaw_horizontal_m", rms(e2_h));

  // Consistency, in the estimate's own gauge: its covariance is that of the state relative to
  // its start (the start pose is given), so the error it describes is the start-pinned one.
  // (Against the whole-track alignment, the error near the start is the fit's offset while
  // the σ there is ~0.)
  if (!pairs.covariance.empty()) {
    const StartPinnedErrors pinned = startPinnedErrors(pairs, truth, inlier, o.start_span_m);
    if (pinned.valid) {
      double sum_nees = 0.0, sum_e2 = 0.0, sum_trace = 0.0;
      std::size_t count = 0, within = 0;
      for (std::size_t k = 0; k < n; ++k) {
        if (!inlier[k]) continue;
        const Vec3d& e = pinned.error[k];
        const Mat3d& C = pinned.covariance[k];
        const Eigen::LDLT<Mat3d> ldlt(0.5 * (C + C.transpose()));
        const double d2 = e.dot(ldlt.solve(e));
        sum_nees += d2, sum_e2 += e.squaredNorm(), sum_trace += C.trace();
        ++count;
        within += d2 <= kThreeSigmaSquared;
      }
      m.set("nees_position_mean", sum_nees / static_cast<double>(count));
      m.set("nees_dof", 3.0);
      m.set("position_rmse_over_sigma", std::sqrt(sum_e2 / sum_trace));
      m.set("gps_within_3sigma_pct",
            100.0 * static_cast<double>(within) / static_cast<double>(count));
    }
  }

  // Drift: aligned on the first span of track only, compared everywhere.
  const double s0 = truth.distanceTravelled(pairs.t.front());
  std::vector<bool> first(n);
  for (std::size_t k = 0; k < n; ++k)
    first[k] = inlier[k] && truth.distanceTravelled(pairs.t[k]) - s0 <= o.first_span_m;
  const RobustPosYawAlignment early = alignPosYawRobust(pairs.antenna_hat, pairs.fix, pairs.sigma,
                                                        first, o.huber_k, o.max_iterations);
  std::vector<double> e2_first;
  std::optional<Vec3d> last_error;
  double t_last = 0.0;
  for (std::size_t k = 0; k < n; ++k) {
    if (!inlier[k]) continue;
    last_error = early.alignment.apply(pairs.antenna_hat[k]) - pairs.fix[k];
    e2_first.push_back(last_error->squaredNorm());
    t_last = pairs.t[k];
  }
  m.set("final_position_error_m", last_error->norm());
  const double path = truth.pathLength(pairs.t.front(), t_last);
  if (path > kMinLength) m.set("final_error_pct_of_path", last_error->norm() / path * 100.0);
  m.set("final_vertical_error_m", std::abs(last_error->z()));
  m.set("ate_first_span_m", rms(e2_first));
  std::stable_sort(m.entries.begin(), m.entries.end(), [](const auto& a, const auto& b) {
    return detail::metricKeyRank(a.first) < detail::metricKeyRank(b.first);
  });
  return m;
}

MetricsReport evaluateAllAgainstFixes(std::string log_name,
                                      const std::vector<est::Trajectory>& trajectories,
                                      const PositionTruth& truth,
                                      const PositionTruthOptions& options) {
  MetricsReport report;
  report.log = std::move(log_name);
  double t0 = std::numeric_limits<double>::infinity();
  double t1 = -std::numeric_limits<double>::infinity();
  for (const est::Trajectory& tr : trajectories) {
    report.estimators.push_back({estimatorKey(tr.name), evaluateAgainstFixes(tr, truth, options)});
    if (tr.nodes.empty()) continue;
    t0 = std::min(t0, tr.nodes.front().t);
    t1 = std::max(t1, tr.nodes.back().t);
  }
  report.path_length_m = t0 <= t1 ? truth.pathLength(t0, t1) : 0.0;
  return report;
}

}  // namespace traverse::eval
