// Stream diagnostics: what is dirty in a log that the reader accepted (docs/log-format.md,
// "Dirty but usable"). Each finding is one stderr line
//
//   warning: gyro.csv: gap of 15.0 s at t=5.0
//
// and is counted in metrics.json's `diagnostics` block (docs/outputs.md). Nothing here changes
// what the estimators are given; it says what they were given.
//
// Kinds, per stream (file) of the log:
//   gap            an interval longer than gap_factor × the stream's median interval
//   time_order     a stamp not after the previous one (the reader rejects these; a stream built
//                  in memory or read with skip_bad_rows may still hold them)
//   rate_change    the median interval over a window of rate_window samples differs from the
//                  previous rate by more than rate_change_factor
//   no_overlap     the stream's time span does not meet the joints' (gyro's, for joints.csv)
//   late_start, early_end
//                  it starts later / ends earlier than the reference by more than
//                  gap_factor × the larger of the two median intervals
//   stuck          a gyro, accelerometer or wheel-drive channel repeats one reading exactly for
//                  at least stuck_min_s and stuck_min_samples while another wheel turns by
//                  more than motion_wheel_rad through the middle half of that stretch
//   spike          a gyro, accelerometer or joint-angle sample farther than spike_k robust σ
//                  from the median of the spike_half_window samples either side (σ = 1.4826
//                  MAD, never below the noise rover.yaml declares for that sensor) and, away
//                  from the ends, farther than that from the median of each side's h samples,
//                  in the same sense (an onset differs from one side only), in a run of at
//                  most spike_max_run such samples (more in a row are a real transient: a
//                  brief turn, a bump); a spike in an angle is the spike pair the joint rates
//                  would carry
//   sun_invalid    every sun reading has valid = 0
//   sun_out_of_view
//                  valid readings whose fish-eye radius puts the sun outside the field of view
//   clock_offset   joints.csv's clock against the gyro and accelerometer (found by the pipeline,
//                  est::estimateJointsClockOffset, not by diagnose; the stamps are then moved)
#pragma once

#include <map>
#include <string>
#include <vector>

#include "traverse/io/log.h"

namespace traverse::io {

struct DiagnosticsOptions {
  double gap_factor = 3.0;          ///< as `traverse info`'s gap column
  int rate_window = 50;             ///< samples per rate estimate
  double rate_change_factor = 1.5;  ///< a new rate differs from the previous by this ratio
  double stuck_min_s = 2.0;
  int stuck_min_samples = 20;
  double motion_wheel_rad = 0.1;  ///< a drive angle change that is motion
  int spike_half_window = 10;
  double spike_k = 10.0;
  int spike_max_run = 2;        ///< consecutive outlying samples that are still a glitch
  int max_lines_per_kind = 10;  ///< stderr lines per (stream, kind); all are counted
};

struct Finding {
  std::string file;         ///< "gyro.csv"
  std::string kind;         ///< one of kFindingKinds
  double t = 0.0;           ///< where it starts, s
  double duration_s = 0.0;  ///< gap, stuck stretch, run of out-of-view readings; else 0
  std::string column;       ///< stuck, spike: the channel; else empty
  double value = 0.0;       ///< spike: the sample; stuck: the repeated reading; else 0
  std::string message;      ///< "gap of 15.0 s at t=5.0" (no file, no "warning:")
  bool not_used = false;    ///< the estimators were not given this sample (a rejected spike)
};

/// Every kind, in the order metrics.json lists them.
inline const std::vector<std::string> kFindingKinds = {
    "gap",   "time_order", "rate_change", "no_overlap",      "late_start",   "early_end",
    "stuck", "spike",      "sun_invalid", "sun_out_of_view", "clock_offset", "noise"};

struct Diagnostics {
  std::vector<Finding> findings;  ///< by stream in the contract's file order, then by time

  /// Findings per kind (every kind listed, 0 when none).
  std::map<std::string, long> countsByKind() const;
  /// Findings per file, then per kind (only files and kinds that have some).
  std::map<std::string, std::map<std::string, long>> countsByFile() const;
  /// The stderr lines: "warning: FILE: MESSAGE", at most max_lines_per_kind per (file, kind),
  /// then one "warning: FILE: N more KIND findings not shown".
  std::vector<std::string> warningLines(int max_lines_per_kind = 10) const;
};

/// Gaps of one stream: (index of the sample before the gap, length in s) for every interval
/// longer than factor × the median interval.
struct Gap {
  Eigen::Index before = 0;
  double length_s = 0.0;
};
std::vector<Gap> findGaps(const Stream& s, double factor = 3.0);

/// A stream's gaps as time spans (the stamps either side of each findGaps interval): where the
/// stream says nothing. The estimators ask it whether a time or an interval is unobserved, so
/// a gap is never read as a reading interpolated across it (a rate, a rest).
class TimeGaps {
 public:
  TimeGaps() = default;
  explicit TimeGaps(const Stream& s, double factor = 3.0);
  /// t lies strictly inside a gap.
  bool contains(double t) const;
  /// The open interval (t0, t1) meets a gap's open interval.
  bool overlaps(double t0, double t1) const;
  bool empty() const { return spans_.empty(); }
  const std::vector<std::pair<double, double>>& spans() const { return spans_; }

 private:
  std::vector<std::pair<double, double>> spans_;  ///< (t before, t after), in time order
};
/// The median interval of a stream (the mean of the two middle ones for an even count); 0 with
/// fewer than two samples.
double medianInterval(const Stream& s);

/// Checks every stream of the log (see the kinds above).
Diagnostics diagnose(const TraverseLog& log, const DiagnosticsOptions& options = {});

/// Single-stream checks, for a stream of any origin: gaps, time order, rate changes, and the
/// spikes of every channel (noise_floors: per column, or one for all — the least robust σ, the
/// declared sensor noise).
void diagnoseTiming(const Stream& s, const std::string& file, const DiagnosticsOptions& options,
                    std::vector<Finding>* out);
void diagnoseSpikes(const Stream& s, const std::string& file,
                    const std::vector<double>& noise_floors, const DiagnosticsOptions& options,
                    std::vector<Finding>* out);

/// "15.0", "0.85", "1000.05": at most three decimals, at least one.
std::string formatSeconds(double s);

}  // namespace traverse::io
