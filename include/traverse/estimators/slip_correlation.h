// Whether the wheels' slip is as white as rover.yaml declares, seen in the one direction where a
// second sensor measures the same motion: the yaw rate.
//
// The slip rows of K-17 assume each wheel's slip white in time (rover.yaml `slip_noise`). Real
// wheels slip for seconds at a time, and differently on the two sides: the difference of their
// speeds is then a yaw rate that white rows average away as if it were information, so the
// wheels' odometry outvotes the gyro (docs/results.md, session 26: 3 % per-wheel slip with a 5 s
// correlation time put the EKF's yaw 2.6° off where the gyro alone was 0.5°). Per joint sample in
// motion, the wheels' drive angles give a yaw rate — the least-squares (v_x, ω_z) of every
// wheel's longitudinal slip row (K-17 at ξ = 0, the body twist on the turn-centre line, the
// nominal slip of K §2.3.4, each row weighted by rover::slipCovariance) — and the gyro, less the
// bias of the latest rest, gives another. Their difference, averaged over windows of a few
// seconds, has a variance the declared white noise predicts; a proportional part (a track or ICR
// error, a gyro scale: ∝ the turn) and a constant (the bias) are fitted out first. A χ² far above
// its degrees of freedom refutes "white": the run says so and carries the wheels' common yaw slip
// c_ω (rover.yaml slip_noise.common_yaw_rate_rad_s) at the σ the windows show.
#pragma once

#include <string>

#include "traverse/estimators/segmentation.h"
#include "traverse/io/log.h"

namespace traverse::est {

struct SlipCorrelationOptions {
  double window_s = 5.0;  ///< averaging window (within one motion segment)
  int min_windows = 8;    ///< fewer: nothing is judged
  /// Refuted when χ² exceeds both its (1 − false_alarm) quantile and max_ratio × its dof (the
  /// independent generator's slip-free logs give 0.3–0.5 × dof, 3 % correlated slip 19–51 ×).
  double false_alarm = 1e-6;
  double max_ratio = 3.0;
};

struct SlipCorrelation {
  int samples = 0;  ///< joint samples in motion that gave a wheel yaw rate
  int windows = 0;
  int dof = 0;                 ///< windows − 2 (constant and proportional part fitted out)
  double chi2 = 0.0;           ///< of the window means' residuals against the white prediction
  double rms_residual = 0.0;   ///< of the window means' residuals (rad/s)
  double rms_predicted = 0.0;  ///< what white slip of the declared σ gives them (rad/s)
  /// σ of a Gauss–Markov yaw slip (τ = slip_noise.common_time_constant_s) whose window means
  /// have the excess variance: rover.yaml's slip_noise.common_yaw_rate_rad_s as measured.
  double sigma_yaw_rate = 0.0;
  /// Σ_i (∂(longitudinal row)/∂ω_z)² over the wheels, averaged over the samples (m²): Σ y_i² for
  /// wheels at body y_i — how a per-wheel slip maps into the wheels' yaw rate.
  double wheel_lever_m2 = 0.0;
  double t = 0.0;  ///< the first window's start
  bool refuted = false;
  /// "the wheels' yaw rate departs from the gyro's by 0.0034 rad/s RMS over 5 s windows (22),
  /// 7.3 times what white slip of the declared sigma gives: their slip is correlated; ..."
  std::string message() const;
};

/// The check above on a log and its segmentation (motion = outside its rest segments).
SlipCorrelation wheelYawRateCheck(const io::TraverseLog& log, const Segmentation& segmentation,
                                  const SlipCorrelationOptions& options = {});

/// The log with rover.yaml's common slip given c_ω at the measured σ. Where rover.yaml declares
/// no common slip, c_x and c_y get what the same wheel slips give their mean if they are
/// independent and alike: σ_u = σ_ω √(Σ y_i²) per wheel, σ_u / √N for the mean (at least
/// kUnmeasuredCommonSlipMps). A common slip rover.yaml declares is kept.
inline constexpr double kUnmeasuredCommonSlipMps = 1e-5;
io::TraverseLog withCommonYawSlip(const io::TraverseLog& log, const SlipCorrelation& found);

}  // namespace traverse::est
