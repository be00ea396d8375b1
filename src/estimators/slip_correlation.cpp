#include "traverse/estimators/slip_correlation.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <vector>

#include "traverse/estimators/ekf.h"
#include "traverse/rover/joint_sample.h"
#include "traverse/rover/slip_constraint.h"

namespace traverse::est {

std::string SlipCorrelation::message() const {
  char buf[420];
  std::snprintf(buf, sizeof buf,
                "the wheels' yaw rate departs from the gyro's by %.2g rad/s RMS over %d windows "
                "(chi2 %.0f for %d dof; white slip of the declared sigma gives %.2g): their slip "
                "is correlated in time; slip_noise.common_yaw_rate_rad_s %.2g (measured) is used",
                rms_residual, windows, chi2, dof, rms_predicted, sigma_yaw_rate);
  return buf;
}

namespace {

/// One joint sample's wheel yaw rate against the gyro's.
struct YawRateSample {
  double t = 0.0;
  int segment = -1;  ///< index into Segmentation::segments
  double d = 0.0;    ///< wheels' ω_z − (gyro − bias)
  double w_gyro = 0.0;
  double variance = 0.0;  ///< of d under the declared (white) noise
};

/// The wheels' (v_x, ω_z) at one joint sample: weighted least squares on every used wheel's
/// longitudinal slip row, K-17 at ξ = 0 with the body twist (v_x, −ω_z x_c, 0; 0, 0, ω_z) equal to
/// the nominal slip ω_z · icr_offset_y. Returns false when the wheels do not determine ω_z.
bool wheelYawRate(const io::TraverseLog& log, const rover::JointSample& js, double* w,
                  double* variance, double* lever2) {
  const rover::RoverGeometry& geo = log.geometry;
  const int n = geo.numWheels();
  Eigen::MatrixXd A(n, 2);
  Eigen::VectorXd y(n);
  std::vector<Eigen::Matrix<double, 4, 6>> Jt(static_cast<size_t>(n));
  std::vector<int> wheel;
  for (int i = 0; i < n; ++i) {
    if (!js.wheelUsed(i)) continue;
    Eigen::Matrix<double, 4, 7> J;
    const Vec4d t0 =
        rover::slipConstraintWithJacobian(js.T_body_wheel[i], geo.wheels[i].radius,
                                          js.joint_twist[i], Vec3d::Zero(), Vec3d::Zero(), 0.0, &J);
    const auto r = static_cast<Eigen::Index>(wheel.size());
    A(r, 0) = J(0, 0);
    A(r, 1) = J(0, 5) - geo.turn_centre_x * J(0, 1) - geo.wheels[i].icr_offset_y;
    y[r] = -t0[0];
    Jt[wheel.size()] = J.leftCols<6>();
    wheel.push_back(i);
  }
  const auto m = static_cast<Eigen::Index>(wheel.size());
  if (m < 2) return false;
  Eigen::Matrix2d AtA = A.topRows(m).transpose() * A.topRows(m);
  if (std::abs(AtA.determinant()) < 1e-12 * AtA.squaredNorm()) return false;
  Eigen::Vector2d x = AtA.ldlt().solve(A.topRows(m).transpose() * y.head(m));
  // Each row's σ from the declared slip noise at that motion (speed and turn terms included).
  const Vec3d v(x[0], -x[1] * geo.turn_centre_x, 0.0), om(0.0, 0.0, x[1]);
  Eigen::VectorXd wt(m);
  for (Eigen::Index r = 0; r < m; ++r) {
    const double s2 =
        rover::slipCovariance(log.config.slip_noise, js, wheel[static_cast<size_t>(r)], v, om,
                              Jt[static_cast<size_t>(r)])(0, 0);
    wt[r] = 1.0 / std::max(s2, 1e-12);
  }
  const Eigen::Matrix2d N = A.topRows(m).transpose() * wt.asDiagonal() * A.topRows(m);
  if (std::abs(N.determinant()) < 1e-12 * N.squaredNorm()) return false;
  x = N.ldlt().solve(A.topRows(m).transpose() * wt.asDiagonal() * y.head(m));
  *w = x[1];
  *variance = N.inverse()(1, 1);
  *lever2 = A.col(1).head(m).squaredNorm();
  return std::isfinite(*w) && std::isfinite(*variance);
}

/// Variance of the mean over a window W of a unit Gauss–Markov process with time constant τ:
/// 2 (x − 1 + e^{−x}) / x², x = W/τ.
double windowedMarkovVariance(double window, double tau) {
  const double x = window / tau;
  return x < 1e-6 ? 1.0 : 2.0 * (x - 1.0 + std::exp(-x)) / (x * x);
}

}  // namespace

SlipCorrelation wheelYawRateCheck(const io::TraverseLog& log, const Segmentation& segmentation,
                                  const SlipCorrelationOptions& options) {
  SlipCorrelation out;
  const io::Stream& g = log.gyro;
  const int gz = g.col("wz");
  if (gz < 0 || g.size() < 2 || log.geometry.numWheels() < 2) return out;
  const double sg2 = std::pow(log.config.gyro.noise_rad_s, 2);
  const double gyro_gap = 3.0 * io::medianPeriod(g);  // as io::findGaps: a gap is not a rate
  std::vector<YawRateSample> samples;
  double lever_sum = 0.0;
  size_t seg = 0;
  for (const rover::JointSample& js : jointSamples(log)) {
    if (!js.measured) continue;
    while (seg + 1 < segmentation.segments.size() && js.t >= segmentation.segments[seg].t_end)
      ++seg;
    if (segmentation.segments.empty() || segmentation.segments[seg].kind != Segment::Kind::kMotion)
      continue;
    if (js.t < g.t[0] || js.t > g.t[g.size() - 1]) continue;
    const Eigen::Index gi = std::max<Eigen::Index>(
        1, std::lower_bound(g.t.data(), g.t.data() + g.size(), js.t) - g.t.data());
    if (g.t[gi] - g.t[gi - 1] > gyro_gap) continue;  // inside a gap of gyro.csv: no gyro rate
    double w = 0.0, var = 0.0, lever2 = 0.0;
    if (!wheelYawRate(log, js, &w, &var, &lever2)) continue;
    lever_sum += lever2;
    // The bias: the latest rest's mean gyro (the first rest's before any; none: zero — the fit's
    // constant takes it).
    double b = 0.0;
    bool have = false;
    for (const RestWindow& r : segmentation.rests) {
      if (r.t_end <= js.t || !have) b = r.bias.z(), have = true;
      if (r.t_end > js.t) break;
    }
    const double wg = io::interpolateRow(g, js.t)[gz] - b;
    samples.push_back({js.t, static_cast<int>(seg), w - wg, wg, var + sg2});
  }
  out.samples = static_cast<int>(samples.size());
  if (samples.size() < 2) return out;
  out.wheel_lever_m2 = lever_sum / static_cast<double>(samples.size());
  // Window means within one motion segment; a window counts when the segment goes on past it.
  std::vector<double> m, wbar, p, t0s;
  double period = 0.0;
  {
    std::vector<double> dt;
    for (size_t k = 1; k < samples.size(); ++k) dt.push_back(samples[k].t - samples[k - 1].t);
    std::nth_element(dt.begin(), dt.begin() + static_cast<long>(dt.size() / 2), dt.end());
    period = dt[dt.size() / 2];
  }
  for (size_t k = 0; k < samples.size();) {
    const double t0 = samples[k].t;
    double sd = 0.0, sw = 0.0, sv = 0.0;
    size_t j = k;
    bool broken = false;
    while (j < samples.size() && samples[j].segment == samples[k].segment &&
           samples[j].t < t0 + options.window_s) {
      if (j > k && samples[j].t - samples[j - 1].t > 3.0 * period) {
        broken = true;
        break;
      }
      sd += samples[j].d, sw += samples[j].w_gyro, sv += samples[j].variance;
      ++j;
    }
    const auto n = static_cast<double>(j - k);
    const bool complete = !broken && j < samples.size() && samples[j].segment == samples[k].segment;
    if (complete && n >= 5) {
      m.push_back(sd / n), wbar.push_back(sw / n), p.push_back(sv / (n * n)), t0s.push_back(t0);
    }
    k = j;
  }
  out.windows = static_cast<int>(m.size());
  out.dof = out.windows - 2;
  if (out.windows < options.min_windows || out.dof < 1) return out;
  out.t = t0s.front();
  // Fit out a constant (the bias's error) and a part proportional to the turn (a track or ICR
  // error, a gyro scale), weighted by the white prediction.
  const auto J = static_cast<Eigen::Index>(m.size());
  Eigen::MatrixXd X(J, 2);
  Eigen::VectorXd z(J), wts(J);
  for (Eigen::Index j = 0; j < J; ++j) {
    const auto u = static_cast<size_t>(j);
    X(j, 0) = 1.0, X(j, 1) = wbar[u], z[j] = m[u], wts[j] = 1.0 / p[u];
  }
  const Eigen::Matrix2d N = X.transpose() * wts.asDiagonal() * X;
  const Eigen::Vector2d beta = N.completeOrthogonalDecomposition().solve(
      Eigen::Vector2d(X.transpose() * wts.asDiagonal() * z));
  const Eigen::VectorXd r = z - X * beta;
  out.chi2 = r.cwiseAbs2().dot(wts);
  const double var_resid = r.squaredNorm() / out.dof;
  double mean_p = 0.0;
  for (const double v : p) mean_p += v;
  mean_p /= static_cast<double>(p.size());
  out.rms_residual = std::sqrt(var_resid);
  out.rms_predicted = std::sqrt(mean_p);
  out.sigma_yaw_rate = std::sqrt(
      std::max(0.0, var_resid - mean_p) /
      windowedMarkovVariance(options.window_s, log.config.slip_noise.common_time_constant_s));
  out.refuted = out.chi2 > chiSquareQuantile(1.0 - options.false_alarm, out.dof) &&
                out.chi2 > options.max_ratio * out.dof && out.sigma_yaw_rate > 0.0;
  return out;
}

io::TraverseLog withCommonYawSlip(const io::TraverseLog& log, const SlipCorrelation& found) {
  io::TraverseLog out = log;
  rover::SlipNoise& sn = out.config.slip_noise;
  if (!sn.hasCommonSlip()) {
    // Independent, alike wheel slips of σ_u give the least-squares yaw rate σ_u / √(Σ y_i²) and
    // the wheels' mean σ_u / √N: c_x and c_y follow from the measured c_ω.
    const double sigma_u = found.sigma_yaw_rate * std::sqrt(found.wheel_lever_m2);
    const double mean = std::max(sigma_u / std::sqrt(static_cast<double>(log.geometry.numWheels())),
                                 kUnmeasuredCommonSlipMps);
    sn.common_longitudinal_mps = sn.common_lateral_mps = mean;
  }
  sn.common_yaw_rate_rad_s = found.sigma_yaw_rate;
  return out;
}

}  // namespace traverse::est
