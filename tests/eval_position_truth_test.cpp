// Evaluation against position-only truth (gps.csv): the weighted and robust posyaw alignment,
// the antenna lever arm, the consistency figures and the drift metrics, each on a hand-checked
// case (include/traverse/eval/position_truth.h, docs/evaluation.md).
#include <cmath>
#include <vector>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "traverse/eval/alignment.h"
#include "traverse/eval/position_truth.h"

namespace traverse::eval {
namespace {

constexpr double kTol = 1e-9;

Quatd yawQuat(double yaw) {
  return Quatd(Eigen::AngleAxisd(yaw, Vec3d::UnitZ()));
}

io::Stream gpsStream(const std::vector<double>& t, const std::vector<Vec3d>& p,
                     const std::vector<Vec3d>& sigma) {
  io::Stream s;
  s.columns = {"x", "y", "z", "sx", "sy", "sz"};
  s.t = Eigen::VectorXd::Map(t.data(), static_cast<Eigen::Index>(t.size()));
  s.values.resize(static_cast<Eigen::Index>(t.size()), 6);
  for (std::size_t k = 0; k < t.size(); ++k) {
    s.values.row(static_cast<Eigen::Index>(k)) << p[k].transpose(), sigma[k].transpose();
  }
  return s;
}

double metric(const Metrics& m, std::string_view key) {
  const auto v = m.get(key);
  EXPECT_TRUE(v.has_value()) << key;
  return v.value_or(std::nan(""));
}

// Hand-checked: the truth is twice as long as the estimate along x. Weights 3:1 put the
// horizontal centroids at x̂ = 0.25, x = 0.5, so yaw 0 and t_x = 0.25 (equal weights: 0.5);
// the heights 1 and 2 with vertical weights 1:3 give t_z = (1·1 + 3·2)/4 = 1.75.
TEST(EvalPositionTruth, WeightedAlignmentUsesItsWeights) {
  const std::vector<Vec3d> est = {Vec3d(0, 0, 0), Vec3d(1, 0, 0)};
  const std::vector<Vec3d> truth = {Vec3d(0, 0, 1), Vec3d(2, 0, 2)};
  const PosYawAlignment a = alignPosYawWeighted(est, truth, {3, 1}, {1, 3});
  EXPECT_NEAR(a.yaw, 0.0, kTol);
  EXPECT_NEAR(a.translation.x(), 0.25, kTol);
  EXPECT_NEAR(a.translation.y(), 0.0, kTol);
  EXPECT_NEAR(a.translation.z(), 1.75, kTol);
  const PosYawAlignment equal = alignPosYawWeighted(est, truth, {1, 1}, {1, 1});
  EXPECT_NEAR(equal.translation.x(), 0.5, kTol);
  EXPECT_NEAR(equal.translation.z(), 1.5, kTol);
  EXPECT_THROW(alignPosYawWeighted(est, truth, {0, 0}, {1, 1}), std::invalid_argument);
  EXPECT_THROW(alignPosYawWeighted(est, truth, {-1, 1}, {1, 1}), std::invalid_argument);
}

/// 12 points on a circle of radius 5 m and their truth Rz(0.3) p + (1, −2, 0.5).
struct CircleCase {
  std::vector<Vec3d> est, truth, sigma;
  static constexpr double kYaw = 0.3;
  const Vec3d t{1.0, -2.0, 0.5};
  explicit CircleCase(double sigma_m) {
    for (int k = 0; k < 12; ++k) {
      const double a = 2 * M_PI * k / 12;
      est.emplace_back(5 * std::cos(a), 5 * std::sin(a), 0.1 * k);
      truth.push_back(yawQuat(kYaw) * est.back() + t);
      sigma.emplace_back(sigma_m, sigma_m, 2 * sigma_m);
    }
  }
};

// One fix 3 m off (60 σ of 5 cm): least squares shifts the whole fit by ~3/12 m; the Huber fit
// bounds the outlier's pull to k σ = 15 cm shared by 12 points (1.25 cm, and 0.15 · 0.68 · 5 m
// of torque over Σ r² = 300 m²: 1.7 mrad of yaw), and flags that fix only.
TEST(EvalPositionTruth, RobustAlignmentIgnoresAnOutlierItsSigmaCannotExplain) {
  CircleCase c(0.05);
  c.truth[4] += Vec3d(3.0, 0.0, 0.0);
  const PosYawAlignment plain = alignPosYaw(c.est, c.truth);
  EXPECT_GT((plain.translation - c.t).norm(), 0.2);
  const RobustPosYawAlignment r =
      alignPosYawRobust(c.est, c.truth, c.sigma, std::vector<bool>(12, true));
  EXPECT_NEAR(r.alignment.yaw, CircleCase::kYaw, 3e-3);
  EXPECT_LT((r.alignment.translation - c.t).norm(), 0.02);
  for (std::size_t k = 0; k < 12; ++k) {
    EXPECT_EQ(r.outlier(k, 5.0), k == 4) << k;
    if (k != 4) {
      EXPECT_LT((r.alignment.apply(c.est[k]) - c.truth[k]).norm(), 0.03) << k;
    }
  }
  EXPECT_DOUBLE_EQ(r.s_h, 1.0);  // the inliers fit: the σ are trusted as given
  EXPECT_GT(r.r_h[4], 50.0);
}

// The one whole-track fit the metrics and the report share: the circle's 3 m outlier is the only
// fix left out, the fit is the robust alignment's, and `used` counts the rest.
TEST(EvalPositionTruth, WholeTrackAlignmentFlagsTheOutlierOnly) {
  CircleCase c(0.05);
  c.truth[4] += Vec3d(3.0, 0.0, 0.0);
  FixPairs pairs;
  for (std::size_t k = 0; k < 12; ++k) {
    pairs.t.push_back(static_cast<double>(k));
    pairs.antenna_hat.push_back(c.est[k]);
    pairs.fix.push_back(c.truth[k]);
    pairs.sigma.push_back(c.sigma[k]);
  }
  const WholeTrackAlignment fit = alignWholeTrack(pairs, PositionTruthOptions{});
  EXPECT_EQ(fit.used, 11u);
  ASSERT_EQ(fit.inlier.size(), 12u);
  for (std::size_t k = 0; k < 12; ++k) EXPECT_EQ(fit.inlier[k], k != 4) << k;
  EXPECT_NEAR(fit.whole.alignment.yaw, CircleCase::kYaw, 3e-3);
  EXPECT_LT((fit.whole.alignment.translation - c.t).norm(), 0.02);
  PositionTruthOptions strict;
  strict.outlier_threshold = 1e-9;  // every fix beyond it: none kept
  EXPECT_EQ(alignWholeTrack(pairs, strict).used, 0u);
}

// s5t1's case: fixes jump by up to their own σ (2.5 m). Every residual is within k σ, so the
// robust fit is exactly the 1/σ²-weighted least squares, and nothing is rejected.
TEST(EvalPositionTruth, JumpsWithinTheirSigmaAreWeightedNotRejected) {
  CircleCase c(2.5);
  c.truth[4] += Vec3d(2.0, 0.0, 0.0);
  c.sigma[4] = Vec3d(3.0, 3.0, 6.0);
  const RobustPosYawAlignment r =
      alignPosYawRobust(c.est, c.truth, c.sigma, std::vector<bool>(12, true));
  std::vector<double> w_h, w_z;
  for (const Vec3d& s : c.sigma)
    w_h.push_back(1 / (s.x() * s.x())), w_z.push_back(1 / (s.z() * s.z()));
  const PosYawAlignment wls = alignPosYawWeighted(c.est, c.truth, w_h, w_z);
  EXPECT_NEAR(r.alignment.yaw, wls.yaw, 1e-12);
  EXPECT_LT((r.alignment.translation - wls.translation).norm(), 1e-12);
  for (std::size_t k = 0; k < 12; ++k) EXPECT_FALSE(r.outlier(k, 5.0)) << k;
}

/// A rover spinning in place at the origin through one turn, a node every 45°; with
/// covariance `P` on every node when given.
est::Trajectory spinInPlace(const std::optional<Mat6d>& P = std::nullopt) {
  est::Trajectory tr;
  tr.name = "ekf";
  tr.has_covariance = P.has_value();
  for (int k = 0; k < 8; ++k) {
    est::TrajectoryNode n;
    n.t = k;
    n.q_site_body = yawQuat(M_PI / 4 * k);
    if (P) n.covariance = *P;
    tr.nodes.push_back(n);
  }
  return tr;
}

// Hand-checked lever arm: the antenna 0.5 m ahead of and 1 m above the body origin draws a
// circle of radius 0.5 m at height 1 m. With the lever arm the estimate's antenna is the fix:
// ATE 0. Without it the estimate is one point; the alignment moves it to the circle's centre
// (the fixes' mean, height included), leaving 0.5 m at every fix.
TEST(EvalPositionTruth, LeverArmMovesTheEstimateToTheAntenna) {
  const Vec3d lever(0.5, 0.0, 1.0);
  std::vector<double> t;
  std::vector<Vec3d> p, sigma;
  for (int k = 0; k < 8; ++k) {
    t.push_back(k);
    p.push_back(yawQuat(M_PI / 4 * k) * lever);
    sigma.emplace_back(0.01, 0.01, 0.02);
  }
  const io::Stream gps = gpsStream(t, p, sigma);
  const Metrics with = evaluateAgainstFixes(spinInPlace(), PositionTruth(gps, lever));
  EXPECT_NEAR(metric(with, "ate_posyaw_m"), 0.0, kTol);
  const Metrics without = evaluateAgainstFixes(spinInPlace(), PositionTruth(gps, Vec3d::Zero()));
  EXPECT_NEAR(metric(without, "ate_posyaw_m"), 0.5, kTol);
  EXPECT_NEAR(metric(without, "ate_posyaw_horizontal_m"), 0.5, kTol);
  EXPECT_EQ(metric(without, "gps_fixes_rejected"), 0.0);
  EXPECT_FALSE(with.has("roll_rmse_deg"));  // no attitude in the truth, no attitude metrics
  EXPECT_FALSE(with.has("yaw_rmse_deg"));
}

// The attitude covariance reaches the antenna through the lever arm: δâ = −R [L]× δθ. A yaw σ
// of 0.1 rad and a 1 m forward lever arm (heading 0 at node 0) give 0.1² m² across the track.
TEST(EvalPositionTruth, AttitudeCovarianceReachesTheAntenna) {
  Mat6d P = Mat6d::Zero();
  P(5, 5) = 0.01;
  const est::Trajectory tr = spinInPlace(P);
  const io::Stream gps = gpsStream({0.0}, {Vec3d(1, 0, 0)}, {Vec3d(0.01, 0.01, 0.01)});
  const FixPairs pairs = pairWithFixes(tr, PositionTruth(gps, Vec3d(1, 0, 0)));
  ASSERT_EQ(pairs.covariance.size(), 1u);
  EXPECT_NEAR(pairs.covariance[0](1, 1), 0.01, kTol);
  EXPECT_NEAR(pairs.covariance[0](0, 0), 0.0, kTol);
  EXPECT_NEAR(pairs.antenna_hat[0].x(), 1.0, kTol);
}

// Hand-checked consistency. A straight 3 m drive along x; the fixes are off only in height, by
// +0.5, −0.5, +1, −1 m (mean 0: the alignment leaves them), σ_fix 0.1 m per axis, σ_z of the
// estimate 0.2 m, so C_zz = 0.01 + 0.04 = 0.05 and eᵀC⁻¹e = 5, 5, 20, 20: 2 of 4 within the
// 3σ ellipsoid (≤ 9), NEES mean 12.5, position_rmse_over_sigma = √(2.5 / (4 · 0.07)) = 2.988,
// ATE √(2.5 / 4) = 0.7906 m, final error 1 m (the last fix, vertical).
TEST(EvalPositionTruth, ConsistencyFigures) {
  est::Trajectory tr;
  tr.name = "ekf";
  tr.has_covariance = true;
  Mat6d P = Mat6d::Zero();
  P(2, 2) = 0.04;
  for (int k = 0; k <= 3; ++k) {
    est::TrajectoryNode n;
    n.t = k;
    n.p_site = Vec3d(k, 0, 0);
    n.covariance = P;
    tr.nodes.push_back(n);
  }
  const std::vector<double> dz = {0.5, -0.5, 1.0, -1.0};
  std::vector<Vec3d> p, sigma;
  for (int k = 0; k <= 3; ++k) {
    p.emplace_back(k, 0, dz[static_cast<std::size_t>(k)]);
    sigma.emplace_back(0.1, 0.1, 0.1);
  }
  const Metrics m =
      evaluateAgainstFixes(tr, PositionTruth(gpsStream({0, 1, 2, 3}, p, sigma), Vec3d::Zero()));
  // Consistency in the start-pinned gauge: the four fixes lie in one bin of the track (within
  // start_span_m of its start), so all pin it — translation the weighted mean (z: 0), its
  // variance 1/Σw = 1/400 in C — and e_z = −dz: C_zz = 0.04 + 0.01 + 0.0025 = 0.0525, d² =
  // 0.25/0.0525 twice and 1/0.0525 twice (mean 2.5 / 0.21), two of four within 9; Σ tr C =
  // 4 (0.0125 + 0.0125 + 0.0525).
  EXPECT_NEAR(metric(m, "gps_within_3sigma_pct"), 50.0, kTol);
  EXPECT_NEAR(metric(m, "nees_position_mean"), 2.5 / 0.21, 1e-9);
  EXPECT_EQ(metric(m, "nees_dof"), 3.0);
  EXPECT_NEAR(metric(m, "position_rmse_over_sigma"), std::sqrt(2.5 / 0.31), 1e-9);
  EXPECT_NEAR(metric(m, "ate_posyaw_m"), std::sqrt(2.5 / 4), 1e-9);
  EXPECT_NEAR(metric(m, "ate_posyaw_horizontal_m"), 0.0, 1e-9);
  EXPECT_NEAR(metric(m, "final_position_error_m"), 1.0, 1e-9);
  EXPECT_NEAR(metric(m, "final_vertical_error_m"), 1.0, 1e-9);
  EXPECT_EQ(metric(m, "gps_fixes_used"), 4.0);
  tr.has_covariance = false;  // dead reckoning: no σ, no consistency figures
  const Metrics dr =
      evaluateAgainstFixes(tr, PositionTruth(gpsStream({0, 1, 2, 3}, p, sigma), Vec3d::Zero()));
  EXPECT_FALSE(dr.has("gps_within_3sigma_pct"));
  EXPECT_FALSE(dr.has("nees_position_mean"));
  EXPECT_TRUE(dr.has("ate_posyaw_m"));
}

// The gauge of the consistency figures: a straight 40 m drive whose odometry is 5 % long, with
// the σ a consider scale of 5 % gives (σ_x = 0.05 x, zero at the start). Pinned at the start the
// error is 0.05 x against that σ: every fix within 3σ, RMSE/σ just under 1. Against the
// whole-track alignment the error would be −1 m at the start, where σ is 0 (that alignment is
// the ATE's: 0.05 · 40/√12 = 0.58 m RMS).
TEST(EvalPositionTruth, ConsistencyIsMeasuredInTheEstimatesStartPinnedGauge) {
  est::Trajectory tr;
  tr.name = "ekf";
  tr.has_covariance = true;
  std::vector<double> t;
  std::vector<Vec3d> p, sigma;
  for (int k = 0; k <= 400; ++k) {
    const double x = 0.1 * k;
    est::TrajectoryNode n;
    n.t = 0.1 * k;
    n.p_site = Vec3d(1.05 * x, 0, 0);
    n.covariance = Mat6d::Identity() * 1e-8;
    n.covariance(0, 0) += std::pow(0.05 * x, 2);
    tr.nodes.push_back(n);
    t.push_back(n.t);
    p.emplace_back(x, 0, 0);
    sigma.emplace_back(0.01, 0.01, 0.01);
  }
  const Metrics m = evaluateAgainstFixes(tr, PositionTruth(gpsStream(t, p, sigma), Vec3d::Zero()));
  EXPECT_NEAR(metric(m, "ate_posyaw_m"), 0.05 * 40 / std::sqrt(12.0), 0.01);
  EXPECT_EQ(metric(m, "gps_within_3sigma_pct"), 100.0);
  EXPECT_GT(metric(m, "position_rmse_over_sigma"), 0.9);
  EXPECT_LE(metric(m, "position_rmse_over_sigma"), 1.0);
  EXPECT_LT(metric(m, "nees_position_mean"), 1.0);
}

// Drift: the truth drives straight along x at 1 m/s; the estimate is exact for its first 11 m,
// then turns by 0.01 rad per metre. Aligned on the whole track the fit spreads the error (a
// smaller ATE); aligned on the first 10 m of track only, the alignment is the identity and the
// final error is the estimate's own, 4.34 m after 40 m.
TEST(EvalPositionTruth, FirstSpanAlignmentShowsDrift) {
  est::Trajectory tr;
  tr.name = "dr";
  std::vector<double> t;
  std::vector<Vec3d> p, sigma;
  double yaw = 0.0;
  Vec3d pos = Vec3d::Zero();
  for (int k = 0; k <= 40; ++k) {
    est::TrajectoryNode n;
    n.t = k;
    n.p_site = pos;
    n.q_site_body = yawQuat(yaw);
    tr.nodes.push_back(n);
    if (k >= 11) yaw += 0.01;  // turns after the first 11 m
    pos += Vec3d(std::cos(yaw), std::sin(yaw), 0);
  }
  for (int k = 0; k <= 400; ++k) {  // 10 Hz fixes of the true straight line
    t.push_back(k / 10.0);
    p.emplace_back(k / 10.0, 0, 0);
    sigma.emplace_back(0.01, 0.01, 0.01);
  }
  const Metrics m = evaluateAgainstFixes(tr, PositionTruth(gpsStream(t, p, sigma), Vec3d::Zero()));
  // The track of 1 s medians starts at the first bin's middle (t = 0.5 s), so its first 10 m
  // hold the fixes up to t = 10.5 s, where the estimate is exact.
  const Vec3d last = tr.nodes.back().p_site - Vec3d(40, 0, 0);
  EXPECT_NEAR(metric(m, "final_position_error_m"), last.norm(), 1e-6);
  EXPECT_GT(last.norm(), 1.0);
  EXPECT_LT(metric(m, "ate_posyaw_m"), metric(m, "ate_first_span_m"));
  EXPECT_NEAR(metric(m, "final_error_pct_of_path"), last.norm() / 40.0 * 100, 0.5);
}

// startPinnedErrors by hand: the estimate is the truth turned by −0.2 rad about the truth's
// start (0, 0, 0) and moved by (3, 4, 1). The first two fixes (t = 0, 0.1; 0.1 m of track)
// pin it: c_â = estimate's start + (0.05 along the turned x), c_fix = (0.05, 0, 0), so the
// fitted yaw is +0.2 and every error is 0. Moving fix 5 by (0, 0.3, 0) leaves the pin (only
// fixes within 0.5 m of track pin it) and shows as e_5 = (0, −0.3, 0); a fix not used for the
// pin or the yaw still gets its error and covariance; C_k = R P̂ Rᵀ + diag(σ² + σ_pin²).
TEST(EvalPositionTruth, StartPinnedErrorsByHand) {
  const double turn = -0.2;
  const Vec3d move(3, 4, 1);
  std::vector<Vec3d> truth, sigma;
  for (int k = 0; k <= 20; ++k) {
    truth.emplace_back(0.1 * k, 0.2 * (k >= 10 ? 0.1 * (k - 10) : 0.0), 0);
    sigma.emplace_back(0.01, 0.01, 0.02);
  }
  FixPairs pairs;
  for (int k = 0; k <= 20; ++k) {
    const auto K = static_cast<std::size_t>(k);
    pairs.t.push_back(0.1 * k);
    pairs.antenna_hat.push_back(yawQuat(turn) * truth[K] + move);
    pairs.fix.push_back(truth[K]);
    pairs.sigma.push_back(sigma[K]);
    pairs.covariance.push_back(Mat3d::Identity() * 1e-4 * k);
  }
  pairs.fix[15] += Vec3d(0, 0.3, 0);
  std::vector<bool> pin(pairs.t.size(), true);
  pin[15] = false;  // as an outlier: not in the yaw fit, but its error is still given
  std::vector<double> ts(pairs.t);
  const PositionTruth gps(gpsStream(ts, pairs.fix, sigma), Vec3d::Zero());
  const StartPinnedErrors e = startPinnedErrors(pairs, gps, pin, 0.5);
  ASSERT_TRUE(e.valid);
  EXPECT_NEAR(e.yaw, -turn, 1e-9);
  ASSERT_EQ(e.error.size(), pairs.t.size());
  ASSERT_EQ(e.covariance.size(), pairs.t.size());
  for (std::size_t k = 0; k < e.error.size(); ++k) {
    const Vec3d expected = k == 15 ? Vec3d(0, -0.3, 0) : Vec3d::Zero();
    EXPECT_NEAR((e.error[k] - expected).norm(), 0.0, 1e-9) << k;
  }
  // The pin's variance: 1/Σw over the pinning fixes (horizontal w = 2/(σx² + σy²) = 1e4).
  const int pinned = static_cast<int>(std::round(1.0 / (e.pin_variance.x() * 1e4)));
  EXPECT_GE(pinned, 2);
  EXPECT_NEAR(e.pin_variance.z(), 4e-4 / pinned, 1e-12);
  EXPECT_NEAR(e.covariance[7](0, 0), 7e-4 + 1e-4 + e.pin_variance.x(), 1e-12);
  EXPECT_NEAR(e.covariance[7](2, 2), 7e-4 + 4e-4 + e.pin_variance.z(), 1e-12);
  EXPECT_FALSE(startPinnedErrors(pairs, gps, std::vector<bool>(pairs.t.size(), false), 0.5).valid);
}

}  // namespace
}  // namespace traverse::eval
