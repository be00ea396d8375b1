// The estimation pipeline on one log (the layer above estimators and smoother): segmentation →
// initial state → dead reckoning and the forward EKF → the per-segment batch smoother (when asked),
// and the rows of segments.csv.
#pragma once

#include <optional>
#include <vector>

#include "traverse/estimators/clock_offset.h"
#include "traverse/estimators/dead_reckoning.h"
#include "traverse/estimators/ekf.h"
#include "traverse/estimators/rest_noise.h"
#include "traverse/estimators/segments_output.h"
#include "traverse/estimators/slip_correlation.h"
#include "traverse/io/diagnostics.h"
#include "traverse/smoother/smoother.h"

namespace traverse::pipeline {

using est::ClockOffset;
using est::DeadReckoningOptions;
using est::EkfOptions;
using est::EkfResult;
using est::InitialState;
using est::InitOptions;
using est::Segmentation;
using est::SegmentationOptions;
using est::SegmentRow;
using est::Trajectory;

struct PipelineConfig {
  SegmentationOptions segmentation;
  InitOptions init;
  DeadReckoningOptions dead_reckoning;
  EkfOptions ekf;
  bool smooth = false;  ///< run the smoother after the EKF
  /// Give the estimators no sample that io::diagnose calls a spike (gyro.csv, accel.csv: the
  /// sample; joints.csv: the row) — see withoutSpikes.
  bool reject_spikes = true;
  /// Use no drive angle of a wheel over a stretch io::diagnose calls `stuck` (the encoder holds
  /// one reading while the other wheels turn) — see withoutStuckWheels.
  bool drop_stuck_wheels = true;
  /// Estimate the streams' clock offsets (est::estimateClockAlignment: joints.csv against the
  /// gyro and accelerometer, or one inertial stream against the other two, then sun.csv against
  /// the gyro) and move the stamps of each stream found off before estimating.
  bool align_joints_clock = true;
  /// A known offset of joints.csv's clock (s, + = its stamps late) to remove instead of
  /// estimating any.
  std::optional<double> joints_clock_offset_s;
  /// Measure the gyro's and accelerometer's white noise at the rests and use it where it refutes
  /// rover.yaml's (est::restNoise): the estimators then assume the noise the data have.
  bool measure_rest_noise = true;
  /// Test the wheels' yaw rate against the gyro's for slip correlated in time
  /// (est::wheelYawRateCheck) and, where rover.yaml declares no common yaw slip and the test
  /// refutes white slip, carry it at the measured σ (est::withCommonYawSlip).
  bool check_slip_correlation = true;
  smoother::SmootherOptions smoother;
};

/// Wall time of each estimator in one run (s): dead reckoning, the EKF (every run of it, the
/// accelerometer-driven one given up included; its recording for RTS too), the RTS backward pass,
/// the batch smoother (solve and covariance, all segments).
struct EstimatorSeconds {
  double dr = 0.0, ekf = 0.0, rts = 0.0, smoother = 0.0;
};

struct Estimates {
  Segmentation segmentation;
  InitialState init;
  Trajectory dr;
  EkfResult ekf;
  std::optional<smoother::SmootherResult> smoothed;
  std::vector<SegmentRow> segments;   ///< the smoother's bias and summary on motion rows
  std::vector<io::Finding> rejected;  ///< the spikes whose samples the estimators were not given
  /// joints.csv's clock offset as estimated (when align_joints_clock), and the shift applied to
  /// its stamps (−offset; 0 when none was).
  ClockOffset joints_clock;
  double joints_shift_s = 0.0;
  /// Every stream whose clock was found off and moved (est::estimateClockAlignment: joints.csv
  /// as above, or gyro.csv / accel.csv alone, and sun.csv), when align_joints_clock.
  est::ClockAlignment clocks;
  /// The inertial noise the rests refuted (est::restNoise), when measure_rest_noise: the
  /// estimators ran with the measured σ.
  std::vector<est::RestNoise> noise;
  /// The wheels' yaw rate against the gyro's (est::wheelYawRateCheck), when
  /// check_slip_correlation and rover.yaml declares no common yaw slip; refuted: the estimators
  /// ran with c_ω at its measured σ.
  est::SlipCorrelation slip_correlation;
  /// Variance (fraction²) of the wheels' mean rolling-radius scale that rover.yaml declares
  /// (io::OdometryConfig), carried in every estimator's position covariance
  /// (est::addOdometryScaleCovariance); 0 when it declares none.
  double odometry_scale_variance = 0.0;
  EstimatorSeconds seconds;
};

/// The log without its spikes (step 0 of estimate): every gyro.csv and accel.csv sample and
/// every joints.csv row that `diagnostics` holds a spike finding for is removed, so a glitch
/// becomes a one-sample gap — propagated across with the noise the elapsed time implies — instead
/// of a rate that the attitude integrates or a rest detector reads as motion. Those findings are
/// appended to `rejected` when given. A spike is an isolated sample far outside its
/// neighbourhood on both sides (io/diagnostics.h), so a real transient that lasts longer than a
/// sample or two is kept.
io::TraverseLog withoutSpikes(const io::TraverseLog& log, const io::Diagnostics& diagnostics,
                              std::vector<io::Finding>* rejected = nullptr);

/// The log with a wheel outage (TraverseLog::wheel_outages) for every `stuck` finding on a
/// wheel's drive angle in joints.csv: over that stretch the EKF and the smoother take no slip
/// rows from that wheel and dead reckoning averages the other wheels — an encoder that holds
/// one reading while the rover drives would otherwise say that its wheel slides at the rover's
/// speed, which the χ² gate lets through (one wheel of six pulls the velocity a sixth of the way,
/// so its innovation stays under the gate). Those findings are appended to `rejected`.
io::TraverseLog withoutStuckWheels(const io::TraverseLog& log, const io::Diagnostics& diagnostics,
                                   std::vector<io::Finding>* rejected = nullptr);

/// The log the estimators are given (the first steps of estimate): without its spikes and stuck
/// wheels (as `config` asks) and with joints.csv's clock aligned; fills e.rejected,
/// e.joints_clock and e.joints_shift_s. `diagnostics` as for estimate.
io::TraverseLog screenedLog(const io::TraverseLog& log, const PipelineConfig& config,
                            const io::Diagnostics* diagnostics, Estimates& e);
/// The screened log (screenedLog), its segmentation and its dead reckoning: what
/// eval::calibrateOdometry fits along (`traverse calibrate`).
struct ScreenedDeadReckoning {
  io::TraverseLog log;
  Segmentation segmentation;
  Trajectory dr;
};
ScreenedDeadReckoning screenedDeadReckoning(const io::TraverseLog& log,
                                            const PipelineConfig& config = {});
/// Estimates::odometry_scale_variance of this log: io::OdometryConfig::meanScaleVariance at the
/// rover's share of left wheels.
double odometryScaleVariance(const io::TraverseLog& log);
/// `diagnostics`: io::diagnose(log) when the caller has it already (it is computed otherwise).
Estimates estimate(const io::TraverseLog& log, const PipelineConfig& config = {},
                   const io::Diagnostics* diagnostics = nullptr);

/// segments.csv rows from the segmentation and a trajectory with bias estimates: a rest row
/// carries the window's own bias measurement on the gyro's axes (mean ± standard error), a
/// motion row the trajectory's bias at the segment's end; with `accel_bias` (the rover declares
/// it) every row also the accelerometer's bias there, and with `icr` the ICRs' half-track error.
std::vector<SegmentRow> segmentRows(const Segmentation& seg, const Trajectory& trajectory,
                                    bool accel_bias = false, bool icr = false);

}  // namespace traverse::pipeline
