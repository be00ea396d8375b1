// Shared by filter, smooth and run: options, reading the log, running the estimators, writing
// OUTDIR (outputs.md).
#pragma once

#include <string>
#include <vector>

#include <optional>
#include "commands.h"
#include "traverse/eval/metrics.h"

#include "traverse/pipeline/pipeline.h"

namespace traverse::app {

struct PipelineOptions {
  std::string log_dir, out_dir;
  std::vector<std::string> log_dirs;  ///< what the command line named (batch.h when several)
  int jobs = 0;                       ///< logs run in parallel (0: all cores)
  bool force = false;                 ///< rerun logs whose outputs are up to date
  bool batch = false;                 ///< OUTDIR/<log name>/ even for one log
  bool skip_bad_rows = false;
  std::string calibration;  ///< rover.yaml overlay (traverse calibrate), empty: none
  std::vector<double> initial_position{0.0, 0.0, 0.0};
  std::string attitude_model = "gyro-driven";
  std::string velocity_model = "auto";
  bool no_sun = false, no_slip = false, no_gating = false, pitch_projection = false;
  bool no_clock_align = false;
  bool no_noise_check = false;  ///< keep rover.yaml's gyro/accelerometer noise even if refuted
  bool no_rts = false;          ///< no Rauch–Tung–Striebel pass over the EKF (rts.csv)
  std::optional<double> joints_clock_offset_s;
  // Smoother (smooth, run).
  double node_period_s = 0.0;
  std::string bias_model = "auto";
  std::string loss;                 ///< empty: rover.yaml's choice
  double loss_scale = 0.0;          ///< 0: rover.yaml's choice
  double contact_loss_scale = 1.0;  ///< SmootherOptions::contact_loss_scale
  int max_iterations = 50;
  int threads = 0;
  bool no_covariance = false, solver_report = false;
  bool no_report = false;            ///< smooth, run: no report.html
  std::string command_name = "run";  ///< the subcommand that was given (run or smooth)
};

void addPipelineOptions(CLI::App& cmd, PipelineOptions& options);
/// Runs `options` on the log directories named: one log into OUTDIR itself, several (or
/// --batch) into OUTDIR/<name>/ with summary.csv (batch.h). Returns the exit status.
int runLogs(PipelineOptions options, const GlobalOptions& global, bool smooth);
void addSmootherOptions(CLI::App& cmd, PipelineOptions& options);
pipeline::PipelineConfig pipelineConfig(const PipelineOptions& options);
/// Reads the log, estimates, writes OUTDIR; returns what it estimated.
/// Puts rest_bias_z_within_3sigma_pct (eval::restBiasConsistency) on the "dr" estimator, whose
/// bias is the rest windows' own measurement.
void setRestBiasMetric(eval::MetricsReport& report, const est::Segmentation& seg,
                       const eval::TruthTrajectory& truth);

pipeline::Estimates runPipeline(const PipelineOptions& options, const GlobalOptions& global,
                                bool smooth);

}  // namespace traverse::app
