// Odometry calibration (`traverse calibrate`, docs/calibration.md): the wheels' effective rolling
// radius per side and, for a skid-steer rover, the two instantaneous centres of rotation, fitted
// to a log with truth (gps.csv or truth.csv) and the log's own gyro.
//
// The model is dead reckoning's (est::deadReckoning): at joint sample k the turn-centre point
// moves along the gyro heading ψ_k at the speed
//     v_k = mean_i ( s_side(i) r_i ψ̇_ik + ω_k (y_ICR,side(i) − y_i) )
// (r_i the URDF radius, s the per-side scale, y_i the wheel's body y at zero joint angles; the
// ω term only for skid steering, io::SkidSteerConfig), projected on the horizontal by the held
// pitch. Two kinds of residual, both linear in the scales:
//  - truth increments: between truth samples at least `increment_s` apart, the horizontal
//    displacement of the antenna (gps.csv; the body origin for truth.csv) against the odometry's,
//    rotated by one heading offset α (the log's heading is not in the truth), one σ for all,
//    estimated from the residuals (the fixes' own σ describe one fix's error, most of which
//    fixes seconds apart share);
//  - yaw rates: at every moving joint sample, the sides' speed difference s_R ā_R − s_L ā_L
//    against the one the gyro's yaw rate makes, B ω_k (the error is the wheels'; ā_side the
//    mean rolling speed of that side's unsteered wheels,
//    B = y_ICR,L − y_ICR,R the ICRs' track; for a rover without skid steering, the unsteered
//    wheels' track, held), σ estimated from the residuals. No truth is needed for these: they
//    fix the ratio of the sides' scales and, with turns, the scale over B.
// The ICRs are fitted as their track B and their centre (y_ICR,L + y_ICR,R) / 2, which only the
// truth's speed in turns tells (dropped when the fit cannot: σ > 0.1 m).
// The truth fixes the common scale. Huber loss (k = huber_k scaled σ) on both kinds. The
// parameters' σ are the least-squares covariance with each kind's σ as estimated, inflated by
// √((1 + ρ)/(1 − ρ)) for the lag-one correlation ρ of that kind's residuals in time (an AR(1)
// effective sample size): slip and GPS errors are not white, and a σ that ignored it would be
// optimistic by that factor.
#pragma once

#include <string>
#include <vector>

#include <Eigen/Core>

#include "traverse/estimators/segmentation.h"
#include "traverse/estimators/trajectory.h"
#include "traverse/io/log.h"

namespace traverse::eval {

struct CalibrationOptions {
  double increment_s = 5.0;   ///< truth samples at least this far apart bound an increment
  double min_travel_m = 0.2;  ///< an increment whose odometry travel is shorter is not used
  double huber_k = 3.0;       ///< Huber threshold, scaled σ
  bool fit_icr = true;        ///< fit the ICRs (skid-steer rovers only)
  /// The ICRs are fitted only when the log turns at least this much (∫|ω| dt over the moving
  /// samples): on a straight run the yaw rate's wiggles are not the wheels' doing.
  double min_turning_rad = 2.0 * 3.14159265358979323846;
  int reweight_iterations = 4;
};

/// One fitted (or held) rover.yaml value.
struct CalibratedParameter {
  std::string key;  ///< rover.yaml dotted key, e.g. odometry.wheel_radius_scale_left
  double nominal = 0.0;
  double value = 0.0;
  double sigma = 0.0;   ///< 1σ; 0 when not fitted
  bool fitted = false;  ///< held at nominal otherwise (`note` says why)
  std::string note;
};

/// What one kind of residual says about the fit.
struct ResidualGroup {
  int used = 0;              ///< residuals in the fit
  int outliers = 0;          ///< beyond huber_k scaled σ (down-weighted by the loss)
  double rms_before = 0.0;   ///< RMS at the nominal parameters (units of the residual)
  double rms_after = 0.0;    ///< RMS at the fitted parameters
  double noise_sigma = 0.0;  ///< the σ estimated for one residual (q for increments)
  double lag1_correlation = 0.0;
  double sigma_inflation = 1.0;  ///< √((1 + ρ)/(1 − ρ)), ρ = max(lag1, 0)
};

struct OdometryCalibration {
  std::vector<CalibratedParameter> parameters;  ///< scale left, scale right[, icr left, right]
  /// Correlation of the fitted parameters of the fit's own parametrisation, named in
  /// correlation_names: the scales, the ICRs' track icr_track (y_ICR,L − y_ICR,R) and centre
  /// icr_centre ((y_ICR,L + y_ICR,R) / 2), those that were fitted.
  Eigen::MatrixXd correlation;
  std::vector<std::string> correlation_names;
  /// Whether the ICR centre was fitted; else the ICRs moved symmetrically about rover.yaml's.
  bool icr_centre_fitted = false;
  double turned_rad = 0.0;  ///< ∫|ω| dt over the yaw-rate samples
  double heading_offset_rad = 0.0, heading_offset_sigma_rad = 0.0;
  /// 1σ of the fitted mean scale (s_L + s_R)/2: what the calibration leaves unknown of the
  /// wheels' rolling radius (the overlay's odometry.wheel_radius_scale_sigma; its
  /// wheel_radius_scale_side_sigma is 0: the sides' difference is fitted).
  double mean_scale_sigma = 0.0;
  std::string truth_file;     ///< gps.csv or truth.csv
  ResidualGroup increments;   ///< horizontal, m (per axis)
  ResidualGroup yaw_rates;    ///< the sides' speed difference, m/s
  double truth_path_m = 0.0;  ///< horizontal length of the increments used
};

/// Fits the calibration to `log` (which must hold gps.csv or truth.csv) along its dead
/// reckoning `dr` (one node per joint sample, as est::deadReckoning) and segmentation `seg`
/// (rest windows: no yaw-rate residual there). The log's current scales and ICRs (rover.yaml,
/// with any overlay) are the nominal values. Throws InputError (file 0: what is missing) when the
/// log has no truth or too little motion to fit.
OdometryCalibration calibrateOdometry(const io::TraverseLog& log, const est::Trajectory& dr,
                                      const est::Segmentation& seg,
                                      const CalibrationOptions& options = {});

/// The rover.yaml overlay (io::loadRoverConfig) holding the fitted values, with their σ and the
/// fit's figures in comments. `source` names the log in the header comment.
std::string calibrationOverlay(const OdometryCalibration& calibration, const std::string& source);

}  // namespace traverse::eval
