// segments.csv (outputs.md): one row per rest or motion segment with the gyro bias ± σ for
// that segment and, when the smoother ran, its solver summary.
#pragma once

#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "traverse/estimators/segmentation.h"

namespace traverse::est {

struct SegmentRow {
  int segment = 0;
  double t_start = 0.0, t_end = 0.0;
  Segment::Kind kind = Segment::Kind::kRest;
  Vec3d bias = Vec3d::Zero(), sigma_bias = Vec3d::Zero();
  /// The accelerometer's bias (body, m/s²) ± σ when the rover declares it (rover.yaml
  /// accelerometer.bias_sigma_mps2): the estimator's at the segment's end (EKF) or the smoother
  /// segment's constant. Unset: no such columns.
  std::optional<Vec3d> accel_bias;
  Vec3d sigma_accel_bias = Vec3d::Zero();
  /// The skid-steer ICRs' half-track error δ (m) and its σ, when estimated
  /// (io::SkidSteerConfig): as accel_bias. Unset: no such columns.
  std::optional<double> icr;
  double sigma_icr = 0.0;
  std::string status;  ///< converged | no_convergence | fallback_ekf; empty without a smoother
  std::optional<int> iterations;
  std::optional<double> final_cost, solve_seconds;
};

/// Writes the rows atomically (empty fields where a value does not apply). When the rows carry
/// the accelerometer's bias, six columns follow solve_seconds: accel_bias_x, _y, _z and
/// sigma_accel_bias_x, _y, _z (m/s²). When they carry the ICRs' half-track error, two columns
/// follow: icr_half_track_error_m, sigma_icr_half_track_error_m.
void writeSegments(const std::filesystem::path& file, const std::vector<SegmentRow>& rows);

}  // namespace traverse::est
