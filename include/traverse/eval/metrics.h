// Accuracy of an estimated trajectory against truth: the metrics of metrics.json
// (../shared/docs/outputs.md; conventions in docs/evaluation.md).
//
// Conventions (p̂, q̂ estimate; p, q truth interpolated at each node's time t_k):
//  - Initial translation. The initial position is not observable from onboard sensors, so every
//    metric except the ATE first translates the estimate by p(t_0) − p̂_0. There is no rotation:
//    heading is observable through the sun sensor and its error is part of what is measured.
//  - Path length L_path: the 3-D length of the truth polyline between the estimate's first and
//    last node times.
//  - distance_error_pct = |‖p̂_N − p̂_0‖ − ‖p(t_N) − p(t_0)‖| / ‖p(t_N) − p(t_0)‖ × 100.
//  - final_position_error_m = ‖p̂_N − p(t_N)‖; final_error_pct_of_path = that / L_path × 100.
//  - max_cross_track_m = max_k |e_h · n_k|, e_h the horizontal error, n_k the horizontal unit
//    vector perpendicular to the true direction of travel (true site velocity, or the true
//    heading (cos ψ, sin ψ) when the horizontal speed is below min_speed_mps).
//  - position_rmse_m = sqrt(mean_k ‖p̂_k − p(t_k)‖²).
//  - roll/pitch/yaw_rmse_deg: RMSE of wrap(rpy(q̂_k) − rpy(q(t_k))) to (−π, π], Z-Y-X angles of
//    so3::rollPitchYaw.
//  - contact_angle_rmse_deg: RMSE over nodes and the six wheels of ξ̂ − ξ (truth has xi).
//  - bias_z_error_dps = mean_k |b̂_z − b_z| in deg/s (truth has bz).
//  - bias_z_within_3sigma_pct: % of nodes with |b̂_z − b_z| ≤ 3σ_bz (nodes with σ_bz > 0; the
//    smoother's segment bias is compared at every node of its segment, so segments count by
//    their length).
//  - rest_bias_z_within_3sigma_pct (`restBiasConsistency`, set on "dr" by the bench and the
//    CLI: dead reckoning's bias is the rest windows' own measurement): % of rest windows whose
//    mean-gyro bias is within 3σ of the true b_z at the window's middle.
//  - final_vertical_error_m = |ẑ_N − z(t_N)| (after the initial translation).
//  - ate_posyaw_m: RMSE after the best translation + yaw alignment (eval/alignment.h).
//  - rpe_pct_per_m (OpenVINS-style, by distance travelled): segment d = rpe_segment_m, or
//    rpe_short_fraction × L_path when L_path < rpe_short_path_m; for each node i the first
//    node j with s(t_j) − s(t_i) ≥ d (s: truth distance travelled); error
//    ‖R̂_iᵀ(p̂_j − p̂_i) − R_iᵀ(p_j − p_i)‖ / (s(t_j) − s(t_i)) × 100; mean over pairs.
//  - NEES (trajectories with covariance): e_p = p − p̂, e_θ = Log(q̂⁻¹ q) = so3::boxminus(q, q̂)
//    (the body-frame error of q = q̂ ⊗ Exp(δθ)); eᵀ P⁻¹ e with P the position or attitude 3×3
//    block; mean over nodes whose block has all eigenvalues ≥ min_covariance_eigenvalue
//    (the zero covariance of a given initial position is skipped). nees_dof = 3.
//  - position_rmse_over_sigma = √(Σ‖e_p‖² / Σ tr P_pp), yaw_rmse_over_sigma = √(Σ e_θz² / Σ P_θz)
//    over the same nodes: the error's RMS over the RMS of the reported σ (1 when the σ columns
//    are honest; e_θz, the body-z small angle, is the yaw error for a near-level rover).
// A metric that cannot be computed (no truth group, zero path, no covariance) is omitted.
// Against position-only truth (gps.csv) the metrics are eval/position_truth.h's.
#pragma once

#include <array>
#include <filesystem>
#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "traverse/estimators/segmentation.h"
#include "traverse/estimators/trajectory.h"
#include "traverse/eval/truth.h"
#include "traverse/io/diagnostics.h"

namespace traverse::eval {

/// Every metric key of outputs.md, in the order metrics.json lists them.
inline constexpr std::array<std::string_view, 25> kMetricKeys = {
    "distance_error_pct", "final_position_error_m", "final_error_pct_of_path", "max_cross_track_m",
    "position_rmse_m", "roll_rmse_deg", "pitch_rmse_deg", "yaw_rmse_deg", "contact_angle_rmse_deg",
    "bias_z_error_dps", "ate_posyaw_m", "rpe_pct_per_m", "nees_position_mean", "nees_attitude_mean",
    "nees_dof", "position_rmse_over_sigma", "yaw_rmse_over_sigma", "final_vertical_error_m",
    "bias_z_within_3sigma_pct", "rest_bias_z_within_3sigma_pct",
    // position-only truth (eval/position_truth.h)
    "ate_posyaw_horizontal_m", "ate_first_span_m", "gps_within_3sigma_pct", "gps_fixes_used",
    "gps_fixes_rejected"};

/// Metric key → value, in insertion order (evaluate returns them in kMetricKeys order).
struct Metrics {
  std::vector<std::pair<std::string, double>> entries;

  /// Replaces the value of `key` or appends it.
  void set(std::string_view key, double value);
  std::optional<double> get(std::string_view key) const;
  bool has(std::string_view key) const { return get(key).has_value(); }
  std::vector<std::string> keys() const;
};

struct EvaluateOptions {
  double rpe_segment_m = 1.0;        ///< RPE segment length by distance travelled
  double rpe_short_path_m = 4.0;     ///< below this path length the segment is a fraction
  double rpe_short_fraction = 0.25;  ///< … of the path length
  double min_speed_mps = 1e-3;       ///< below: cross-track direction from the true heading instead
  double min_covariance_eigenvalue = 1e-16;  ///< NEES skips blocks with a smaller eigenvalue
  /// The estimates' start heading is the site frame's gauge (no sun reading in the log, or the
  /// sun switched off): every trajectory is turned about the vertical through its start onto the
  /// truth's start heading before the metrics, as it is translated onto the truth's start
  /// position (docs/evaluation.md). The ATE aligns on its own either way.
  bool heading_is_gauge = false;
};

/// The metrics of one trajectory (conventions above). An empty trajectory gives no metrics.
Metrics evaluate(const est::Trajectory& trajectory, const TruthTrajectory& truth,
                 const EvaluateOptions& options = {});

/// Rest windows whose bias measurement (mean gyro ± standard error) is within 3σ of the true
/// z bias at the window's middle: {within, windows}. Windows without a z measurement are skipped.
std::pair<int, int> restBiasConsistency(const std::vector<est::RestWindow>& rests,
                                        const TruthTrajectory& truth);

/// metrics.json's name of an estimator: the trajectory names "dr", "ekf" are kept, "smoothed"
/// becomes "smoother".
std::string estimatorKey(std::string_view trajectory_name);

struct EstimatorMetrics {
  std::string estimator;  ///< the JSON key: "dr", "ekf", "smoother"
  Metrics metrics;
};

/// The content of metrics.json.
/// What a run of the estimators did, whether or not the log has truth (metrics.json "run").
struct RunSummary {
  double duration_s = 0.0;               ///< the log's span (its earliest to latest stamp)
  double estimated_path_length_m = 0.0;  ///< along the best estimate (smoother, else EKF)
  int segments = 0;                      ///< stop-to-stop legs
  int rest_windows = 0;
  int smoother_fallbacks = 0;           ///< segments that kept the EKF's states
  double slip_updates_gated_pct = 0.0;  ///< of the EKF's slip updates, % gated out
};

struct MetricsReport {
  std::string log;             ///< the log directory's name
  double path_length_m = 0.0;  ///< truth path length over the span of all trajectories
  std::vector<EstimatorMetrics> estimators;
  /// What the stream diagnostics found in the log (io/diagnostics.h), when they ran.
  std::optional<io::Diagnostics> diagnostics = std::nullopt;
  bool evaluated = true;  ///< false: the log has no truth (no path length, no estimators)
  std::optional<RunSummary> run = std::nullopt;  ///< set by the pipeline (not by `evaluate`)
};

/// Evaluates every trajectory (in the given order) against one truth.
MetricsReport evaluateAll(std::string log_name, const std::vector<est::Trajectory>& trajectories,
                          const TruthTrajectory& truth, const EvaluateOptions& options = {});

/// {"log": …, "run": {…}, "path_length_m": …, "estimators": {"dr": {…}, …}, "diagnostics": {…}}
/// (outputs.md), newline-ended; without truth only "log" and "diagnostics". The diagnostics
/// block: "counts" (every kind), "by_file" (file → kind → count), "findings" (one compact
/// object each: file, kind, t, duration_s, column and value when set, message).
std::string formatMetricsJson(const MetricsReport& report);
/// Writes formatMetricsJson atomically (tmp file + rename).
void writeMetricsJson(const std::filesystem::path& file, const MetricsReport& report);

/// Reads metrics.json back (as `traverse summarize` does). Null numbers read as NaN. Throws
/// InputError naming the file when it is not such a document.
MetricsReport parseMetricsJson(const std::string& text, const std::string& file);
MetricsReport readMetricsJson(const std::filesystem::path& file);

/// A plain-text table: one row per metric key, one column per estimator ("-" when omitted).
std::string formatMetricsTable(const MetricsReport& report);

}  // namespace traverse::eval
