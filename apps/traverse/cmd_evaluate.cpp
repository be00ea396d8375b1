// `traverse evaluate OUTDIR --truth LOGDIR`: metrics of whatever trajectories OUTDIR holds
// (dr.csv, ekf.csv, rts.csv, smoothed.csv) against LOGDIR/truth.csv, or, without it, against the
// position-only LOGDIR/gps.csv (lever arm from LOGDIR/rover.yaml); writes OUTDIR/metrics.json
// (with the log's diagnostics when LOGDIR is a whole log).
#include <iostream>
#include <memory>

#include "commands.h"
#include "traverse/core/error.h"
#include "traverse/eval/metrics.h"
#include "traverse/eval/position_truth.h"
#include "traverse/io/csv.h"
#include "traverse/io/diagnostics.h"
#include "traverse/io/log_reader.h"
#include "traverse/io/rover_config.h"

namespace traverse::app {
namespace {

namespace fs = std::filesystem;

/// The trajectories present in `dir`, in the order dr, ekf, rts, smoothed.
std::vector<est::Trajectory> readTrajectories(const fs::path& dir) {
  std::vector<est::Trajectory> out;
  for (const char* name : {"dr", "ekf", "rts", "smoothed"}) {
    const fs::path file = dir / (std::string(name) + ".csv");
    if (!fs::exists(file)) continue;
    try {
      out.push_back(est::readTrajectory(dir, name));
    } catch (const std::invalid_argument& e) {
      // A header that is not the trajectory layout is bad input (exit 2), not an internal error.
      throw InputError(file.string(), 1, e.what());
    }
  }
  return out;
}

/// The log's name for metrics.json: the directory's own name, also for "." or a trailing '/'.
std::string logName(const fs::path& dir) {
  const fs::path canonical = fs::weakly_canonical(dir);
  return canonical.has_filename() ? canonical.filename().string() : canonical.string();
}

}  // namespace

Command addEvaluateCommand(CLI::App& app, const GlobalOptions& global) {
  struct Options {
    std::string out_dir, log_dir;
  };
  auto opt = std::make_shared<Options>();
  CLI::App* cmd = app.add_subcommand(
      "evaluate", "Compare the trajectories in OUTDIR with a log's truth; write metrics.json");
  cmd->add_option("OUTDIR", opt->out_dir,
                  "Output directory holding dr.csv, ekf.csv, rts.csv, smoothed.csv")
      ->required();
  cmd->add_option("--truth", opt->log_dir, "Log directory holding truth.csv or gps.csv")
      ->required();
  return [cmd, opt, &global]() {
    if (!*cmd) return -1;
    const fs::path out_dir(opt->out_dir), log_dir(opt->log_dir);
    const fs::path truth_file = log_dir / "truth.csv", gps_file = log_dir / "gps.csv";
    if (!fs::is_directory(out_dir)) throw InputError(opt->out_dir, 0, "not a directory");
    const bool pose_truth = fs::exists(truth_file);
    if (!pose_truth && !fs::exists(gps_file)) {
      throw InputError(truth_file.string(), 0,
                       "missing (and no gps.csv): no truth to evaluate against");
    }
    const std::vector<est::Trajectory> trajectories = readTrajectories(out_dir);
    if (trajectories.empty()) {
      throw InputError(opt->out_dir, 0,
                       "no trajectory to evaluate (dr.csv, ekf.csv, rts.csv, smoothed.csv)");
    }
    eval::MetricsReport report;
    if (pose_truth) {
      const eval::TruthTrajectory truth(io::readCsv(truth_file, io::logStreamSpec("truth.csv")));
      // No valid sun reading in the log: the start heading was the gauge (as `run` decides).
      eval::EvaluateOptions eo;
      const fs::path sun_file = log_dir / "sun.csv";
      eo.heading_is_gauge = !fs::exists(sun_file) || !io::hasValidSunReading(io::readCsv(
                                                         sun_file, io::logStreamSpec("sun.csv")));
      report = eval::evaluateAll(logName(opt->log_dir), trajectories, truth, eo);
    } else {  // position-only truth; its lever arm is in rover.yaml
      const io::RoverConfig config = io::loadRoverConfig(log_dir / "rover.yaml");
      const eval::PositionTruth truth(io::readCsv(gps_file, io::logStreamSpec("gps.csv")),
                                      config.gps.antenna_body_m);
      report = eval::evaluateAllAgainstFixes(logName(opt->log_dir), trajectories, truth);
    }
    // The log's diagnostics, as `run` writes them, when LOGDIR is a whole log (not only truth).
    // A log the reader refuses still has truth to evaluate against: say why there are no
    // diagnostics, and go on.
    if (fs::exists(log_dir / "gyro.csv") && fs::exists(log_dir / "joints.csv")) {
      try {
        report.diagnostics = io::diagnose(io::readLog(log_dir));
      } catch (const InputError& e) {
        std::cerr << "warning: " << opt->log_dir << ": no diagnostics in metrics.json: " << e.what()
                  << "\n";
      }
    }
    const fs::path json = out_dir / "metrics.json";
    // The run block the estimating run wrote (what it did, not how well) is kept.
    if (fs::exists(json)) {
      try {
        report.run = eval::readMetricsJson(json).run;
      } catch (const InputError&) {  // a damaged file is replaced, as before
      }
    }
    eval::writeMetricsJson(json, report);
    if (!global.quiet)
      std::cout << eval::formatMetricsTable(report) << "wrote " << json.string() << "\n";
    return 0;
  };
}

}  // namespace traverse::app
