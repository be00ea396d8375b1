// Evaluation against position-only truth: gps.csv (t,x,y,z,sx,sy,sz — the antenna in the site
// frame with its 1σ per axis) and the antenna's lever arm L (rover.yaml gps.antenna_body_m).
// Definitions: docs/evaluation.md, "Position-only truth".
//
// At each fix time t_k inside the estimate's span the estimate is interpolated (position and
// its covariance linearly, attitude by slerp) and moved to the antenna: â_k = p̂(t_k) + R̂(t_k) L.
// Heading in the site frame is not known from onboard sensors, so every comparison aligns the
// estimate by yaw and translation (alignPosYawRobust: per-fix σ weights, Huber, outlier flags):
//  - over the whole track: ate_posyaw_m (3-D), ate_posyaw_horizontal_m;
//  - pinned at the start (the estimate's own gauge: its covariance is relative to its given
//    start pose): translation from the fixes of the first start_span_m of track (weighted mean;
//    its variance σ_pin² = 1/Σw joins C), yaw about that point over every fix. The consistency
//    figures compare that error e_k with C_k = Rz(ψ) (P̂_pp + R̂ [L]× P̂_θθ [L]×ᵀ R̂ᵀ) Rz(ψ)ᵀ +
//    diag(σ_k² + σ_pin²) (the position and body-frame attitude blocks of the estimate's
//    covariance, as the trajectory files carry them; trajectories with covariance only):
//    nees_position_mean (mean eᵀC⁻¹e, nees_dof = 3), position_rmse_over_sigma
//    (√(Σ‖e‖² / Σ tr C)), gps_within_3sigma_pct (% of fixes with eᵀC⁻¹e ≤ 9);
//  - on the fixes of the first first_span_m of track only, as the estimator itself starts from
//    a known pose, then applied to all: ate_first_span_m, final_position_error_m and
//    final_vertical_error_m at the last fix, final_error_pct_of_path — the drift.
// Fixes flagged as outliers by the whole-track alignment (beyond outlier_threshold scaled σ)
// take no part in any metric; gps_fixes_used and gps_fixes_rejected count them. Attitude
// metrics are not computed: the truth has no attitude.
#pragma once

#include <string>
#include <vector>

#include "traverse/core/types.h"
#include "traverse/estimators/trajectory.h"
#include "traverse/eval/alignment.h"
#include "traverse/eval/metrics.h"
#include "traverse/io/log.h"

namespace traverse::eval {

struct PositionFix {
  double t = 0.0;
  Vec3d p_site = Vec3d::Zero();  ///< antenna position, site frame, m
  Vec3d sigma = Vec3d::Ones();   ///< 1σ per site axis, m
};

class PositionTruth {
 public:
  /// From a gps.csv stream and the antenna's lever arm (body frame, m). Throws
  /// std::invalid_argument when the stream is empty or lacks a column.
  PositionTruth(const io::Stream& gps, const Vec3d& antenna_body_m);

  const std::vector<PositionFix>& fixes() const { return fixes_; }
  const Vec3d& antennaBody() const { return antenna_body_m_; }

  /// Horizontal distance along the track from the first fix to time t: the polyline through
  /// the per-axis medians of the fixes in bins of max(1 s, 5 fix periods) (the raw polyline
  /// would add s5t1's jumps between solutions, metres per second, to the length), interpolated
  /// in time.
  double distanceTravelled(double t) const;
  double pathLength(double t0, double t1) const {
    return distanceTravelled(t1) - distanceTravelled(t0);
  }

 private:
  std::vector<PositionFix> fixes_;
  Vec3d antenna_body_m_;
  std::vector<double> track_t_, track_s_;  ///< median track: bin middle time, distance
};

struct PositionTruthOptions {
  double huber_k = 3.0;            ///< Huber threshold of the alignment, scaled σ
  double outlier_threshold = 5.0;  ///< a fix beyond this many scaled σ is rejected
  double first_span_m = 10.0;      ///< track distance of the "first span" alignment
  double start_span_m = 0.5;       ///< track distance whose fixes pin the consistency gauge
  int max_iterations = 50;
};

/// The estimate's antenna at the fix times inside its span (the pairing above).
struct FixPairs {
  std::vector<double> t;
  std::vector<Vec3d> antenna_hat;  ///< â_k, the estimate's frame
  std::vector<Vec3d> fix, sigma;
  std::vector<Mat3d> covariance;  ///< P̂_pp + R̂[L]×P̂_θθ[L]×ᵀR̂ᵀ, before the alignment's rotation
};
FixPairs pairWithFixes(const est::Trajectory& trajectory, const PositionTruth& truth);

/// The whole-track robust alignment of the pairs (alignPosYawRobust over every fix, with the
/// options' Huber threshold) and the fixes it keeps: inlier[k] unless fix k lies beyond
/// outlier_threshold scaled σ. The ATE, the start-pinned gauge and the report's views all use
/// this one fit. Throws as alignPosYawRobust (fewer than two pairs, a σ not positive).
struct WholeTrackAlignment {
  RobustPosYawAlignment whole;
  std::vector<bool> inlier;
  std::size_t used = 0;  ///< inliers
};
WholeTrackAlignment alignWholeTrack(const FixPairs& pairs, const PositionTruthOptions& options);

/// The error in the estimate's own gauge, pinned at the start (the consistency figures above,
/// and the report's error plots): translation from the fixes with pin[k] inside the first
/// start_span_m of track (1/σ² weights per axis), yaw about that point over every fix with
/// pin[k]. e_k = Rz(ψ)(â_k − c_â) + c_fix − fix_k and, when the pairs carry covariance,
/// C_k = Rz(ψ) P̂_k Rz(ψ)ᵀ + diag(σ_k² + σ_pin²) — for every pair k, used or not.
struct StartPinnedErrors {
  bool valid = false;                  ///< false when no fix with pin[k] lies in the start span
  double yaw = 0.0;                    ///< ψ, rad
  Vec3d pin_variance = Vec3d::Zero();  ///< σ_pin² per site axis
  std::vector<Vec3d> error;            ///< e_k, site frame, m
  std::vector<Mat3d> covariance;       ///< C_k (empty when the pairs have no covariance)
};
StartPinnedErrors startPinnedErrors(const FixPairs& pairs, const PositionTruth& truth,
                                    const std::vector<bool>& pin, double start_span_m);

/// The metrics above for one trajectory; none when no fix falls inside its span.
Metrics evaluateAgainstFixes(const est::Trajectory& trajectory, const PositionTruth& truth,
                             const PositionTruthOptions& options = {});

/// Every trajectory against the fixes; path_length_m is the track's over their joint span.
MetricsReport evaluateAllAgainstFixes(std::string log_name,
                                      const std::vector<est::Trajectory>& trajectories,
                                      const PositionTruth& truth,
                                      const PositionTruthOptions& options = {});

}  // namespace traverse::eval
