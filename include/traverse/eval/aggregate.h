// Monte Carlo aggregation of per-run metrics (`traverse bench accuracy`, outputs.md): every
// headline number is reported with its spread over seeds, never from one lucky run.
//
// Per estimator and key, over the runs that have the key: mean, sample standard deviation
// (N − 1 in the denominator; undefined, so NaN → JSON null, for a single run), median (mean of
// the two middle values for even N) and max. A NaN in any run makes all four NaN: a broken run
// must show, not vanish into an average.
#pragma once

#include <cstddef>
#include <filesystem>
#include <string>
#include <utility>
#include <vector>

#include "traverse/eval/metrics.h"

namespace traverse::eval {

struct Statistics {
  double mean = 0.0;
  double stddev = 0.0;  ///< sample standard deviation (N − 1); "std" in JSON
  double median = 0.0;
  double max = 0.0;
  std::size_t count = 0;  ///< number of values
};

/// Statistics of `values` (all NaN for an empty list).
Statistics summarize(std::vector<double> values);

/// The per-run metrics of one estimator.
struct EstimatorRuns {
  std::string estimator;  ///< "dr", "ekf", "smoother"
  std::vector<Metrics> runs;
};

struct EstimatorStatistics {
  std::string estimator;
  std::vector<std::pair<std::string, Statistics>> metrics;  ///< in kMetricKeys order
};

/// The content of `bench accuracy --json`.
struct AccuracyReport {
  std::string scenario;
  long runs = 0;
  std::vector<EstimatorStatistics> estimators;
};

/// Aggregates each estimator's runs; `runs` is the Monte Carlo count written to the JSON.
AccuracyReport aggregate(std::string scenario, long runs, const std::vector<EstimatorRuns>& data);

/// Same from one MetricsReport per run (estimators in order of first appearance).
AccuracyReport aggregate(std::string scenario, const std::vector<MetricsReport>& runs);

/// {"scenario": S, "runs": N, "estimators": {"dr": {"KEY": {"mean": …, "std": …,
/// "median": …, "max": …}}, …}} — newline-ended; non-finite numbers are null.
std::string formatAccuracyJson(const AccuracyReport& report);
/// Writes formatAccuracyJson atomically (tmp file + rename).
void writeAccuracyJson(const std::filesystem::path& file, const AccuracyReport& report);

/// A plain-text table: one row per metric, one column per estimator, each cell
/// "median ± std" (sample std over the runs).
std::string formatAccuracyTable(const AccuracyReport& report);
/// The same as a Markdown section: "### <scenario> — N runs", then one row per metric and one
/// column per estimator, each cell "median (mean ± std)" ("-" when the estimator has none).
std::string formatAccuracyMarkdown(const AccuracyReport& report);

}  // namespace traverse::eval
