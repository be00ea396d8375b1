// The clock offset of joints.csv against the inertial streams (gyro.csv, accel.csv), found from
// the data: the yaw rate and the forward acceleration that the wheels imply (the slip
// constraint K-17 with zero slip, solved for v_x and ω_z at every joint sample) are
// cross-correlated with the gyro's heading-axis rate and the accelerometer's x axis. A joints
// stream stamped late by d lags the inertial one by d: the correlation peaks at that lag.
//
// Each signal is high-passed (its centred moving average over `highpass_s` removed) so that a
// constant bias, a tilt's gravity component or a long steady turn do not dominate; what remains
// is where motion changes — starts, stops, the ends of turns — which is where a time offset
// shows. Without such changes (a log that never moves) nothing is estimated.
#pragma once

#include <string>

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
};

struct ClockOffset {
  bool estimated = false;    ///< some signal held enough motion to correlate
  bool significant = false;  ///< the offset is reported and corrected
  double offset_s = 0.0;     ///< joints.csv's stamps minus the inertial clock (+: joints late)
  double correlation = 0.0;  ///< combined correlation at the correlation's offset
  double correlation_at_zero = 0.0;
  std::string signals;  ///< the signals used: "yaw rate", "forward speed"
  /// "clock offset of +0.200 s against gyro.csv/accel.csv (...)": the warning's text.
  std::string message() const;
};

/// Estimates joints.csv's clock offset against gyro.csv (and accel.csv when present) by
/// cross-correlation; `significant` when the combined peak reaches min_correlation inside the
/// lag range and the offset exceeds min_offset_periods intervals.
ClockOffset estimateJointsClockOffset(const io::TraverseLog& log,
                                      const ClockOffsetOptions& options = {});

/// The log with joints.csv's stamps (and its wheel outages) moved by −offset_s, onto the
/// inertial clock.
io::TraverseLog withJointsShifted(const io::TraverseLog& log, double offset_s);

}  // namespace traverse::est
