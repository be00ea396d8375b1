// The clock offsets between the streams of a log, found from the data. joints.csv against the
// inertial streams (gyro.csv, accel.csv): the yaw rate and the forward acceleration that the wheels
// imply (the slip constraint K-17 with zero slip, solved for v_x and ω_z at every joint sample) are
// cross-correlated with the gyro's heading-axis rate and the accelerometer's x axis. A joints
// stream stamped late by d lags the inertial one by d: the correlation peaks at that lag.
//
// Each signal is high-passed (its centred moving average over `highpass_s` removed) so that a
// constant bias, a tilt's gravity component or a long steady turn do not dominate; what remains
// is where motion changes — starts, stops, the ends of turns — which is where a time offset
// shows. Without such changes (a log that never moves) nothing is estimated.
//
// Which clock is wrong (estimateClockAlignment): each inertial stream is also correlated with
// the wheels on its own. When both hold motion and disagree, the one that agrees with the wheels
// shares their clock and the other is moved (a gyro or accelerometer stamped late alone); when
// they agree, or only one holds motion, the inertial clock is the reference and joints.csv is
// moved (one IMU, one clock: the likely case, and the only one a log without turns or without an
// accelerometer can tell). Then sun.csv against the gyro, by least squares: the sun's azimuth
// about the body z axis turns as the gyro says (u̇ = −ω × u, u the sun in the body frame), so
// along a run of readings the azimuth minus the gyro's turn since the run began is a constant
// (and a slow bias drift) plus the readings' noise at the right lag, and carries ω·(error) where
// the rover turns at a wrong one. The lag minimising its high-passed, noise-weighted sum of
// squares is the offset; its σ comes from the cost's curvature.
#pragma once

#include <string>
#include <vector>

#include "traverse/io/log.h"

namespace traverse::est {

struct ClockOffsetOptions {
  double max_lag_s = 1.0;        ///< lags searched: ±max_lag_s
  double highpass_s = 2.0;       ///< moving-average window removed from every signal
  double min_correlation = 0.5;  ///< the combined peak correlation needed to report an offset
  /// Noise alone correlates too, the more the shorter the log: the peak must also exceed
  /// 4/√N with N = the joints' span / correlation_time_s (the filtered signals' correlation
  /// time), so a 2 s log never reports and a log at rest does not either.
  double correlation_time_s = 0.25;
  /// A signal takes part when its own peak correlation reaches this (else it holds no motion).
  double min_signal_correlation = 0.3;
  /// An offset is reported only when it exceeds this many median joint intervals: the
  /// correlation's scatter on clean simulated logs reaches 1.5 intervals (straight-1m: one start
  /// and one stop on undulating ground, whose gravity on the accelerometer's x axis moves with
  /// the rover; docs/results.md), so a smaller offset is not told from none.
  double min_offset_periods = 3.0;
  /// ...and this many of its own σ: the jackknife scatter of the correlation's peak over 16
  /// blocks of the log (a flat correlation — a noisy gyro against slowly changing turns — gives
  /// a broad one).
  double min_offset_sigmas = 4.0;
  /// sun.csv: an offset is reported only beyond this (s) and beyond 4 of its own σ.
  double min_sun_offset_s = 0.1;
  /// sun.csv: and the fit's χ² must fall below the unshifted stamps' by this (scaled by the
  /// reduced χ²): 16, a 4σ improvement.
  double min_sun_delta_chi2 = 16.0;
  /// sun.csv: and fall by at least this share of the fit's own χ².
  double min_sun_cost_share = 0.01;
};

struct ClockOffset {
  bool estimated = false;    ///< some signal held enough motion to correlate
  bool significant = false;  ///< the offset is reported and corrected
  double offset_s = 0.0;     ///< joints.csv's stamps minus the inertial clock (+: joints late)
  double correlation = 0.0;  ///< combined correlation at the correlation's offset
  double correlation_at_zero = 0.0;
  std::string signals;  ///< the signals used: "yaw rate", "forward speed"
  /// The stream whose stamps the offset is of, and what it was measured against.
  std::string file = "joints.csv";
  std::string against = "the gyro and accelerometer";
  std::string how = "from the wheels cross-correlated with the inertial sensors";
  std::string note;  ///< appended to the parenthesis (why this stream, not another)
  /// sun.csv: the parenthesis in full (a least-squares fit, not a correlation; `correlation`
  /// and `correlation_at_zero` then hold the reduced χ² at the offset and at zero).
  /// `sigma_s`: the offset's 1σ (s): the fit's curvature for sun.csv, the correlation peak's
  /// block jackknife for the others.
  std::string detail;
  double sigma_s = 0.0;
  /// "clock offset of +0.200 s against the gyro and accelerometer (...)": the warning's text.
  std::string message() const;
};

/// Every clock found to be off, in the order they were applied: at most one of joints.csv,
/// gyro.csv, accel.csv (or both inertial streams), then sun.csv.
struct ClockAlignment {
  std::vector<ClockOffset> shifted;  ///< each significant; its stamps moved by −offset_s
  const ClockOffset* find(const std::string& file) const;
};

/// Estimates joints.csv's clock offset against gyro.csv (and accel.csv when present) by
/// cross-correlation; `significant` when the combined peak reaches min_correlation inside the
/// lag range and the offset exceeds min_offset_periods intervals.
ClockOffset estimateJointsClockOffset(const io::TraverseLog& log,
                                      const ClockOffsetOptions& options = {});

/// Every stream's clock (see the top of this file): which stream is off and by how much.
ClockAlignment estimateClockAlignment(const io::TraverseLog& log,
                                      const ClockOffsetOptions& options = {});

/// sun.csv's clock offset against gyro.csv (+: the sun's stamps late); not significant without
/// turns, without a sun stream or with too few valid readings.
ClockOffset estimateSunClockOffset(const io::TraverseLog& log,
                                   const ClockOffsetOptions& options = {});

/// The log with joints.csv's stamps (and its wheel outages) moved by −offset_s, onto the
/// inertial clock.
io::TraverseLog withJointsShifted(const io::TraverseLog& log, double offset_s);

/// The log with `file`'s stamps (joints.csv, gyro.csv, accel.csv, sun.csv or cmd.csv) moved by
/// −offset_s.
io::TraverseLog withStreamShifted(const io::TraverseLog& log, const std::string& file,
                                  double offset_s);

/// The log with every clock of `alignment` moved.
io::TraverseLog withClocksAligned(const io::TraverseLog& log, const ClockAlignment& alignment);

}  // namespace traverse::est
