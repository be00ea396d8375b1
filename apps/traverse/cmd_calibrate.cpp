// `traverse calibrate LOGDIR -o OVERLAY.yaml`: fit the odometry (wheel-radius scale per side,
// the skid-steer ICRs) to a log with truth and write a rover.yaml overlay that
// `traverse run --calibration` applies (eval/calibration.h, docs/calibration.md).
#include <cstdio>
#include <iostream>
#include <memory>

#include "commands.h"
#include "traverse/eval/calibration.h"
#include "traverse/io/atomic_file.h"
#include "traverse/io/log_reader.h"
#include "traverse/io/rover_config.h"
#include "traverse/pipeline/pipeline.h"

namespace traverse::app {

Command addCalibrateCommand(CLI::App& app, const GlobalOptions& global) {
  struct Options {
    std::string log_dir, out, calibration;
    bool skip_bad_rows = false, no_icr = false;
    eval::CalibrationOptions fit;
  };
  auto opt = std::make_shared<Options>();
  CLI::App* cmd = app.add_subcommand(
      "calibrate",
      "Fit the odometry (wheel-radius scale per side, skid-steer ICRs) to a log with truth "
      "(gps.csv or truth.csv); write a rover.yaml overlay for `run --calibration`");
  cmd->add_option("LOGDIR", opt->log_dir, "Log directory with gps.csv or truth.csv")->required();
  cmd->add_option("-o,--output", opt->out, "Overlay file to write (YAML)")->required();
  cmd->add_option("--increment", opt->fit.increment_s,
                  "Truth samples at least this far apart (s) bound one increment")
      ->capture_default_str()
      ->check(CLI::Range(0.1, 1e6));
  cmd->add_option("--min-travel", opt->fit.min_travel_m,
                  "Increments with less odometry travel (m) are not used")
      ->capture_default_str()
      ->check(CLI::Range(0.0, 1e6));
  cmd->add_flag("--no-icr", opt->no_icr, "Hold the skid-steer ICRs at rover.yaml's values");
  cmd->add_option("--calibration", opt->calibration,
                  "Start from this rover.yaml overlay (its values are the nominal ones)");
  cmd->add_flag("--skip-bad-rows", opt->skip_bad_rows,
                "Drop malformed rows (counted and reported) instead of stopping");
  return [cmd, opt, &global]() {
    if (!*cmd) return -1;
    io::ReadOptions ro;
    ro.skip_bad_rows = opt->skip_bad_rows;
    ro.rover_overlay = opt->calibration;
    const io::TraverseLog input = io::readLog(opt->log_dir, ro);
    // Along the dead reckoning of the log the estimators see (spikes, stuck wheels, clock).
    const pipeline::ScreenedDeadReckoning o = pipeline::screenedDeadReckoning(input);
    eval::CalibrationOptions fit = opt->fit;
    fit.fit_icr = !opt->no_icr;
    const eval::OdometryCalibration c = eval::calibrateOdometry(o.log, o.dr, o.segmentation, fit);
    const std::string text = eval::calibrationOverlay(c, opt->log_dir);
    io::parseRoverConfig(text, opt->out);  // the overlay reads back (a bug otherwise)
    io::writeFileAtomically(opt->out, text);
    if (!global.quiet) {
      std::printf("%-36s %12s %12s %10s\n", "parameter", "nominal", "fitted", "1 sigma");
      for (const eval::CalibratedParameter& p : c.parameters) {
        if (p.fitted)
          std::printf("%-36s %12.6g %12.6g %10.2g\n", p.key.c_str(), p.nominal, p.value, p.sigma);
        else
          std::printf("%-36s %12.6g %12s %10s  %s\n", p.key.c_str(), p.nominal, "-", "-",
                      p.note.c_str());
      }
      std::printf("heading offset %.4f rad (sigma %.2g)\n", c.heading_offset_rad,
                  c.heading_offset_sigma_rad);
      std::printf(
          "increments (%s): %d, %.1f m, RMS %.4g -> %.4g m per axis, sigma %.3g m, lag-1 %.2f, "
          "%d outliers\n",
          c.truth_file.c_str(), c.increments.used, c.truth_path_m, c.increments.rms_before,
          c.increments.rms_after, c.increments.noise_sigma, c.increments.lag1_correlation,
          c.increments.outliers);
      std::printf(
          "yaw rates: %d, sides' speed difference RMS %.4g -> %.4g m/s, sigma %.3g m/s, "
          "lag-1 %.2f, %d outliers\n",
          c.yaw_rates.used, c.yaw_rates.rms_before, c.yaw_rates.rms_after, c.yaw_rates.noise_sigma,
          c.yaw_rates.lag1_correlation, c.yaw_rates.outliers);
      if (c.correlation.rows() > 1) {
        std::printf("correlation of");
        for (const std::string& n : c.correlation_names) std::printf(" %s", n.c_str());
        std::printf(":\n");
        for (int a = 0; a < c.correlation.rows(); ++a) {
          for (int b = 0; b < c.correlation.cols(); ++b) std::printf(" %6.3f", c.correlation(a, b));
          std::printf("\n");
        }
      }
      std::printf("wrote %s\n", opt->out.c_str());
    }
    return 0;
  };
}

}  // namespace traverse::app
