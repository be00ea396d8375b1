// report.html: one self-contained file per run (docs/report.md). Top view, elevation, position
// and attitude error with ±3σ envelopes (or the σ alone without truth), contact angles, gyro bias
// per segment with σ bars, the solver table, the metrics table and the log summary with every
// diagnostic and every line the run raised. No network, no external file: plots are inline SVG
// (svg_plot.h), the style and the zoom script are inline.
#pragma once

#include <filesystem>
#include <string>
#include <vector>

#include "traverse/estimators/segmentation.h"
#include "traverse/estimators/segments_output.h"
#include "traverse/estimators/trajectory.h"
#include "traverse/eval/metrics.h"
#include "traverse/io/log.h"

namespace traverse::report {

struct ReportInput {
  std::string log_name;
  std::string command;  ///< how the outputs were made ("traverse run LOG -o OUT …")
  const io::TraverseLog* log = nullptr;
  const est::Segmentation* segmentation = nullptr;
  /// In table order (dr, ekf, rts, smoothed), by their names.
  std::vector<const est::Trajectory*> trajectories;
  std::vector<est::SegmentRow> segments;
  /// The evaluation (when the log has truth), the diagnostics and the run block.
  const eval::MetricsReport* metrics = nullptr;
  /// What the run printed besides: update counts, gated-out updates, fallbacks, warnings.
  std::vector<std::string> run_lines;
  size_t max_points = 1500;  ///< per plotted series (drawing only; the CSVs keep every row)
};

/// The whole HTML document.
std::string renderReport(const ReportInput& input);

/// renderReport written to `file` atomically (tmp + rename).
void writeReport(const std::filesystem::path& file, const ReportInput& input);

}  // namespace traverse::report
