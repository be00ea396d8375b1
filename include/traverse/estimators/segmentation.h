// Rest/motion segmentation (Nickels & Baker's transient detector, with the wheels) and the
// at-rest measurements each rest window gives: gyro bias and roll/pitch from gravity.
//
// Detector (Nickels): each gyro sample is compared with the running mean of the previous
// `mean_window` samples; a difference above `gyro_threshold_rad_s` on any axis makes it a
// transient sample. A sample is also active when the wheels turn (mean |r ψ̇_i| above
// `wheel_speed_threshold_mps`) — a rover whose wheels turn is not at rest, however slowly it
// yaws. `enter_count` consecutive active samples enter motion, `leave_count` inactive ones leave
// it (hysteresis). A motion run starts at the first active sample of the run that triggered it,
// and ends at its last raw-active sample (rate away from the previous rest's bias, or turning
// wheels): the running mean would otherwise keep flagging transients after a turn stops.
#pragma once

#include <vector>

#include "traverse/io/log.h"
#include "traverse/sensors/gravity.h"

namespace traverse::est {

struct SegmentationOptions {
  int mean_window = 30;
  double gyro_threshold_rad_s = 0.5 * M_PI / 180.0;
  /// ... and never below this many σ of the gyro's declared white noise: Nickels' 0.5 °/s is
  /// 2.8 σ of Rocky-7's QRS-11 (0.0031 rad/s), so a noisier gyro keeps that false-alarm rate
  /// instead of flagging every sample (a gyro ten times noisier left no rest at all).
  double gyro_threshold_noise_sigmas = 2.8;
  int enter_count = 5;
  int leave_count = 30;
  double wheel_speed_threshold_mps = 0.002;
  double min_rest_s = 2.0;      ///< shorter rests are merged into the motion around them
  double edge_margin_s = 0.25;  ///< trimmed from each end of a rest window for its measurements
  /// A rest window is cut back from each edge that borders motion until its integrated rotation
  /// (bias-corrected gyro) and wheel travel, counted from the window's core outward, stay within
  /// this many σ of the declared gyro and wheel noise (0: off). See trimRestRuns.
  double rest_trim_sigma = 4.5;
  /// Every rest run that survives the trim is tested once more as a whole against the declared
  /// noise: the least-squares slope of each measured gyro axis and each wheel's travel over the
  /// run (χ² with one degree of freedom per axis and wheel). A run whose statistic exceeds the
  /// χ² quantile at this probability is halved and retested; what fails is not rest — it becomes
  /// motion and is never used as a zero-rate / zero-velocity constraint (0: no test).
  double rest_test_probability = 0.9999;
};

/// A rest run the χ² test refused (it became motion): its span, statistic and degrees of freedom.
struct RefusedRest {
  double t_start = 0.0, t_end = 0.0;
  double chi2 = 0.0, threshold = 0.0;
  int dof = 0;
};

/// What one rest window measures.
struct RestWindow {
  double t_start = 0.0, t_end = 0.0;  ///< the whole window
  /// Mean gyro reading over the trimmed window per body axis, its standard error, and which
  /// axes the gyro has (heading-only: z). This is a bias measurement: at rest ω = 0 (K-12).
  Vec3d bias = Vec3d::Zero(), bias_sigma = Vec3d::Zero();
  std::array<bool, 3> bias_axes{false, false, true};
  int gyro_samples = 0;
  /// Nickels' per-axis drift filter at the end of the window (all rest samples so far).
  Vec3d drift = Vec3d::Zero(), drift_sigma = Vec3d::Zero();
  bool has_gravity = false;  ///< accel.csv present with samples in the window
  Vec3d mean_specific_force = Vec3d::Zero();
  sensors::RollPitchMeasurement roll_pitch;
  bool has_sun = false;  ///< valid sun readings in the window
  Vec2d mean_sun = Vec2d::Zero();
  int sun_samples = 0;
  /// The χ² consistency statistic the window passed (testRestRuns) and its degrees of freedom.
  double rest_chi2 = 0.0;
  int rest_dof = 0;
};

struct Segment {
  enum class Kind { kRest, kMotion };
  Kind kind = Kind::kRest;
  double t_start = 0.0, t_end = 0.0;
  int rest_index = -1;  ///< into Segmentation::rests for rest segments
};

struct Segmentation {
  std::vector<Segment> segments;  ///< alternating rest / motion, covering the log
  std::vector<RestWindow> rests;
  std::vector<RefusedRest> refused_rests;  ///< runs the χ² rest test turned into motion
  Eigen::VectorXd gyro_t;                  ///< gyro sample times
  std::vector<unsigned char> gyro_rest;    ///< per gyro sample: 1 = rest
  /// True if t lies inside a rest segment.
  bool atRest(double t) const;
};

Segmentation segment(const io::TraverseLog& log, const SegmentationOptions& options = {});

/// Mean wheel rolling speed mean_i |r_i ψ̇_i| at each joint sample (m/s), from the joint-rate
/// filter of rover/joint_rates.h with the given half window (0: rover.yaml's).
Eigen::VectorXd wheelSpeeds(const io::TraverseLog& log, int half_window = 0);

}  // namespace traverse::est
