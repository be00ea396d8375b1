// Reading a whole traverse log directory (docs/log-format.md) and summarising it
// (`traverse info LOGDIR`).
#pragma once

#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "traverse/io/log.h"

namespace traverse::io {

/// Reads rover.yaml, the URDF it names, gyro.csv and joints.csv (required) and sun.csv,
/// accel.csv, cmd.csv, truth.csv, gps.csv (when present). Every problem is an InputError naming the
/// file and line (a missing required file: that file, line 0). The gyro header must agree with
/// rover.yaml's gyro.axes. Rows skipped under options.skip_bad_rows are added to *report.
TraverseLog readLog(const std::filesystem::path& dir, const ReadOptions& options = {},
                    ReadReport* report = nullptr);

/// One stream of a log, as `traverse info` shows it.
struct StreamSummary {
  std::string name;  ///< "gyro", "joints", …
  std::string file;  ///< "gyro.csv", …
  long rows = 0;
  std::vector<std::string> columns;  ///< value columns, without `t`
  double t_first = 0.0;              ///< s
  double t_last = 0.0;               ///< s
  double median_rate_hz = 0.0;       ///< 1 / median sample interval; 0 with fewer than 2 rows
  long gaps = 0;                     ///< intervals longer than 3× the median interval
  double largest_gap_s = 0.0;        ///< longest such interval; 0 when there is none
  std::optional<long> valid_rows;    ///< sun.csv: rows with valid = 1
};

struct LogSummary {
  std::string dir;
  std::string rover_name;
  int format = 1;
  std::vector<StreamSummary> streams;  ///< present streams, in the contract's file order
  double t_start = 0.0;                ///< earliest time of any stream, s
  double t_end = 0.0;                  ///< latest time of any stream, s
  double duration_s = 0.0;             ///< t_end − t_start
};

/// Interval statistics of one stream (`name` e.g. "gyro", file = name + ".csv").
StreamSummary summarizeStream(const std::string& name, const Stream& stream);

LogSummary summarize(const TraverseLog& log);

/// A human-readable multi-line table of the summary (ends with a newline).
std::string formatSummary(const LogSummary& summary);

}  // namespace traverse::io
