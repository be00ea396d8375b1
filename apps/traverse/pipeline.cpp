#include "pipeline.h"

#include "batch.h"

#include <algorithm>
#include <cstdio>
#include <iomanip>
#include <iostream>
#include <limits>
#include <sstream>

#include "traverse/eval/metrics.h"
#include "traverse/eval/position_truth.h"
#include "traverse/io/diagnostics.h"
#include "traverse/io/log_reader.h"
#include "traverse/report/report.h"

namespace traverse::app {

void addPipelineOptions(CLI::App& cmd, PipelineOptions& o) {
  cmd.add_option("LOGDIR", o.log_dirs,
                 "Log directories (docs/log-format.md); with several, each goes to "
                 "OUTDIR/<its name>/ and OUTDIR/summary.csv lists them")
      ->required();
  cmd.add_option("-o,--output", o.out_dir, "Output directory")->required();
  cmd.add_option("-j,--jobs", o.jobs, "Logs run in parallel, each its own process (0: all cores)")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  cmd.add_flag("--force", o.force,
               "Several logs: run a log even when its outputs are newer than its inputs");
  cmd.add_flag("--batch", o.batch,
               "OUTDIR/<log name>/, status.json and summary.csv even for one log (one log per "
               "cluster task into a shared OUTDIR; `traverse summarize` then lists them all)");
  cmd.add_flag("--skip-bad-rows", o.skip_bad_rows,
               "Drop malformed rows (counted) instead of stopping");
  cmd.add_option(
      "--calibration", o.calibration,
      "rover.yaml overlay applied over the log's (the file `traverse calibrate` writes)");
  cmd.add_option("--initial-position", o.initial_position,
                 "Start position x y z in the site frame (m)")
      ->expected(3)
      ->capture_default_str();
  cmd.add_option("--attitude-model", o.attitude_model,
                 "gyro-driven (O-1 hybrid) or gyro-measurement (K-2 + K-12)")
      ->check(CLI::IsMember({"gyro-driven", "gyro-measurement"}))
      ->capture_default_str();
  cmd.add_option("--velocity-model", o.velocity_model,
                 "perturbation (K-1) or accel (O-4, accelerometer-driven)")
      ->check(CLI::IsMember({"perturbation", "accel"}))
      ->capture_default_str();
  cmd.add_flag("--no-sun", o.no_sun, "Ignore the sun sensor");
  cmd.add_flag("--no-slip", o.no_slip, "Ignore the slip constraint (EKF without kinematics)");
  cmd.add_flag("--no-gating", o.no_gating,
               "Accept every sun and slip innovation (no chi-square gate)");
  cmd.add_flag("--pitch-projection", o.pitch_projection,
               "Dead reckoning: project wheel speed by the pitch");
  cmd.add_flag("--no-rts", o.no_rts,
               "Skip the Rauch-Tung-Striebel smoother over the EKF's states (rts.csv)");
  cmd.add_flag("--no-clock-align", o.no_clock_align,
               "Keep joints.csv's stamps as logged (no clock offset estimated against the gyro "
               "and accelerometer)");
  cmd.add_flag("--no-noise-check", o.no_noise_check,
               "Keep rover.yaml's gyro and accelerometer noise even where the rests' readings "
               "are noisier, and its slip white even where the gyro shows it correlated (no "
               "noise finding)");
  cmd.add_option("--joints-clock-offset", o.joints_clock_offset_s,
                 "joints.csv's known clock offset in seconds (+: its stamps late); removed "
                 "instead of estimating one")
      ->check(CLI::Range(-60.0, 60.0));
}

void addSmootherOptions(CLI::App& cmd, PipelineOptions& o) {
  cmd.add_option("--node-period", o.node_period_s,
                 "Smoother node period in seconds (0: a node at every joint sample)")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  cmd.add_option("--bias-model", o.bias_model,
                 "Gyro bias per segment: constant, random-walk (one per node, K-9), or auto "
                 "(random walk where rover.yaml's drift over the segment exceeds the gyro's "
                 "resolution of a constant bias)")
      ->check(CLI::IsMember({"auto", "constant", "random-walk"}))
      ->capture_default_str();
  cmd.add_option("--loss", o.loss,
                 "Robust loss on the sun and slip residuals: huber, cauchy or none (default: "
                 "rover.yaml's smoother.loss, else huber)")
      ->check(CLI::IsMember({"huber", "cauchy", "none"}));
  cmd.add_option("--loss-scale", o.loss_scale,
                 "Robust loss scale in standard deviations (default: rover.yaml's, else 3)")
      ->check(CLI::PositiveNumber);
  cmd.add_option("--contact-loss-scale", o.contact_loss_scale,
                 "Cauchy scale (standard deviations) on each wheel's contact-angle increment; "
                 "0: Gaussian K-8")
      ->capture_default_str()
      ->check(CLI::NonNegativeNumber);
  cmd.add_option("--max-iterations", o.max_iterations, "Levenberg-Marquardt iterations per segment")
      ->check(CLI::Range(1, 100000))
      ->capture_default_str();
  cmd.add_option("--threads", o.threads, "Segments solved in parallel (0: all cores)")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  cmd.add_flag("--solver-report", o.solver_report, "Print Ceres' report for every segment");
  cmd.add_flag("--no-report", o.no_report, "Do not write report.html");
  cmd.add_flag("--no-covariance", o.no_covariance,
               "Skip the smoother's marginal covariances (σ columns then come from the EKF)");
}

pipeline::PipelineConfig pipelineConfig(const PipelineOptions& o) {
  pipeline::PipelineConfig c;
  c.init.position_site = Vec3d(o.initial_position[0], o.initial_position[1], o.initial_position[2]);
  c.ekf.attitude = o.attitude_model == "gyro-measurement"
                       ? est::EkfOptions::AttitudeModel::kGyroMeasurement
                       : est::EkfOptions::AttitudeModel::kGyroDriven;
  using VM = est::EkfOptions::VelocityModel;
  c.ekf.velocity = o.velocity_model == "accel"          ? VM::kAccelDriven
                   : o.velocity_model == "perturbation" ? VM::kPerturbation
                                                        : VM::kAuto;
  c.ekf.use_sun = !o.no_sun;
  c.ekf.use_slip = !o.no_slip;
  c.ekf.gating = !o.no_gating;
  c.ekf.rts = !o.no_rts;
  c.dead_reckoning.pitch_projection = o.pitch_projection;
  c.align_joints_clock = !o.no_clock_align;
  c.measure_rest_noise = !o.no_noise_check;
  c.check_slip_correlation = !o.no_noise_check;
  c.joints_clock_offset_s = o.joints_clock_offset_s;
  auto& so = c.smoother;
  so.node_period_s = o.node_period_s;
  using BiasModel = smoother::SmootherOptions::BiasModel;
  so.bias_model = o.bias_model == "random-walk" ? BiasModel::kRandomWalk
                  : o.bias_model == "constant"  ? BiasModel::kConstant
                                                : BiasModel::kAuto;
  using Loss = smoother::SmootherOptions::Loss;
  so.loss = o.loss == "cauchy"  ? Loss::kCauchy
            : o.loss == "none"  ? Loss::kNone
            : o.loss == "huber" ? Loss::kHuber
                                : Loss::kRoverConfig;
  so.loss_scale = o.loss_scale;
  so.contact_loss_scale = o.contact_loss_scale;
  so.max_iterations = o.max_iterations;
  so.threads = o.threads;
  so.covariance = !o.no_covariance;
  so.solver_report = o.solver_report;
  using SVM = smoother::SmootherOptions::VelocityModel;
  so.velocity = o.velocity_model == "accel"          ? SVM::kAccelDriven
                : o.velocity_model == "perturbation" ? SVM::kPerturbation
                                                     : SVM::kAuto;
  so.use_sun = !o.no_sun;
  so.use_slip = !o.no_slip;
  return c;
}

void setRestBiasMetric(eval::MetricsReport& report, const est::Segmentation& seg,
                       const eval::TruthTrajectory& truth) {
  const auto [within, windows] = eval::restBiasConsistency(seg.rests, truth);
  if (windows == 0) return;
  for (eval::EstimatorMetrics& em : report.estimators) {
    if (em.estimator == "dr")
      em.metrics.set("rest_bias_z_within_3sigma_pct", 100.0 * within / windows);
  }
}

namespace {

/// metrics.json (and the table) when the log has truth: truth.csv, else the position-only
/// gps.csv (docs/evaluation.md). Nothing without either.
eval::MetricsReport evaluateAgainstLogTruth(const io::TraverseLog& log,
                                            const est::Segmentation& seg,
                                            const std::vector<est::Trajectory>& trajectories,
                                            const io::Diagnostics& diagnostics,
                                            const eval::RunSummary& run, const PipelineOptions& o) {
  const auto dir_name = std::filesystem::absolute(o.log_dir).lexically_normal().filename().string();
  const std::string name = dir_name.empty() ? o.log_dir : dir_name;
  eval::MetricsReport report;
  if (!log.truth && !log.gps) {  // nothing to evaluate; the diagnostics are written all the same
    report.log = name;
    report.evaluated = false;
  } else if (log.truth) {
    const eval::TruthTrajectory truth(*log.truth);
    eval::EvaluateOptions eo;
    eo.heading_is_gauge = o.no_sun || !io::hasValidSunReading(log.sun);
    report = eval::evaluateAll(name, trajectories, truth, eo);
    setRestBiasMetric(report, seg, truth);
  } else {
    report = eval::evaluateAllAgainstFixes(
        name, trajectories, eval::PositionTruth(*log.gps, log.config.gps.antenna_body_m));
  }
  report.diagnostics = diagnostics;
  report.run = run;
  eval::writeMetricsJson(std::filesystem::path(o.out_dir) / "metrics.json", report);
  return report;
}

/// The log's span: its earliest to latest stamp over the streams the estimators read.
double logDuration(const io::TraverseLog& log) {
  double t0 = std::numeric_limits<double>::infinity(), t1 = -t0;
  const io::Stream* accel = log.accel ? &*log.accel : nullptr;
  const io::Stream* sun = log.sun ? &*log.sun : nullptr;
  for (const io::Stream* s : {&log.gyro, &log.joints, accel, sun}) {
    if (!s || s->t.size() == 0) continue;
    t0 = std::min(t0, s->t[0]);
    t1 = std::max(t1, s->t[s->t.size() - 1]);
  }
  return t1 >= t0 ? t1 - t0 : 0.0;
}

eval::RunSummary runSummary(const io::TraverseLog& log, const pipeline::Estimates& e) {
  eval::RunSummary r;
  r.duration_s = logDuration(log);
  const est::Trajectory& best = e.smoothed ? e.smoothed->trajectory : e.ekf.trajectory;
  for (size_t i = 1; i < best.nodes.size(); ++i)
    r.estimated_path_length_m += (best.nodes[i].p_site - best.nodes[i - 1].p_site).norm();
  r.segments = static_cast<int>(e.segmentation.segments.size());
  r.rest_windows = static_cast<int>(e.segmentation.rests.size());
  if (e.smoothed) {
    for (const auto& g : e.smoothed->segments)
      r.smoother_fallbacks += g.status == smoother::SegmentStatus::kFallbackEkf;
  }
  const est::EkfStats& s = e.ekf.stats;
  r.slip_updates_gated_pct =
      s.slip_updates > 0 ? 100.0 * static_cast<double>(s.slip_rejected) / s.slip_updates : 0.0;
  return r;
}

}  // namespace

int runLogs(PipelineOptions options, const GlobalOptions& global, bool smooth) {
  if (options.log_dirs.size() == 1 && !options.batch) {
    options.log_dir = options.log_dirs.front();
    runPipeline(options, global, smooth);
    return 0;
  }
  return runBatch(options.log_dirs, options, BatchOptions{options.jobs, options.force}, global,
                  smooth);
}

pipeline::Estimates runPipeline(const PipelineOptions& o, const GlobalOptions& global,
                                bool smooth) {
  io::ReadReport report;
  const io::TraverseLog log =
      io::readLog(o.log_dir, io::ReadOptions{o.skip_bad_rows, o.calibration}, &report);
  for (const auto& [file, n] : report.skipped_rows)
    std::cerr << file << ": skipped " << n << " bad rows\n";
  io::Diagnostics diagnostics = io::diagnose(log);
  pipeline::PipelineConfig config = pipelineConfig(o);
  config.smooth = smooth;
  pipeline::Estimates e = pipeline::estimate(log, config, &diagnostics);
  // Each clock moved is a finding like the others: printed and counted.
  std::vector<est::ClockOffset> moved = e.clocks.shifted;
  if (config.joints_clock_offset_s && e.joints_shift_s != 0.0) {
    est::ClockOffset given;
    given.offset_s = -e.joints_shift_s;
    moved.push_back(given);
  }
  for (const est::ClockOffset& c : moved) {
    const bool given = config.joints_clock_offset_s.has_value();
    const io::Stream* stream = nullptr;
    for (const io::NamedStream& n : io::logStreams(log))
      if (c.file == n.file) stream = n.stream;
    io::Finding f;
    f.file = c.file, f.kind = "clock_offset";
    f.t = stream && stream->size() > 0 ? stream->t[0] : 0.0;
    f.column = "t", f.value = c.offset_s;  // metrics.json: the offset, s
    char shift[64];
    std::snprintf(shift, sizeof shift, "its stamps moved by %+.3f s", -c.offset_s);
    f.message = (given ? std::string("clock offset given on the command line") : c.message()) +
                ": " + shift + " (--no-clock-align keeps them)";
    auto at = std::find_if(diagnostics.findings.begin(), diagnostics.findings.end(),
                           [&](const io::Finding& g) { return g.file == c.file; });
    diagnostics.findings.insert(at, f);
  }
  // A noise the rests refuted: one finding per sensor, before that file's others.
  for (const est::RestNoise& n : e.noise) {
    io::Finding f;
    f.file = n.file, f.kind = "noise", f.t = n.t;
    f.column = n.column, f.value = n.measured;  // metrics.json: the measured σ
    f.message = n.message();
    auto at = std::find_if(diagnostics.findings.begin(), diagnostics.findings.end(),
                           [&](const io::Finding& g) { return g.file == n.file; });
    diagnostics.findings.insert(at, f);
  }
  // Slip the gyro shows correlated in time: a noise finding on joints.csv, before its others.
  if (e.slip_correlation.refuted) {
    io::Finding f;
    f.file = "joints.csv", f.kind = "noise", f.t = e.slip_correlation.t;
    f.column = "yaw_rate", f.value = e.slip_correlation.sigma_yaw_rate;  // the measured σ
    f.message = e.slip_correlation.message();
    auto at = std::find_if(diagnostics.findings.begin(), diagnostics.findings.end(),
                           [&](const io::Finding& g) { return g.file == f.file; });
    diagnostics.findings.insert(at, f);
  }
  for (io::Finding& f : diagnostics.findings) {
    for (const io::Finding& r : e.rejected) {
      if (r.file == f.file && r.t == f.t && r.kind == f.kind && r.column == f.column) {
        f.not_used = true;
        f.message += f.kind == "stuck" ? " (its slip rows not used there)" : " (sample not used)";
      }
    }
  }
  for (const std::string& line : diagnostics.warningLines()) std::cerr << line << "\n";
  std::vector<std::string> said;  // what the run says besides the diagnostics (report.html too)
  for (const est::RefusedRest& r : e.segmentation.refused_rests) {
    std::ostringstream w;
    w << "warning: " << o.log_dir << ": apparent rest " << r.t_start << " .. " << r.t_end
      << " s is not at rest (chi2 of gyro slope and wheel travel " << r.chi2 << " > " << r.threshold
      << ", " << r.dof << " dof): treated as motion";
    std::cerr << w.str() << "\n";
    said.push_back(w.str());
  }
  std::filesystem::create_directories(o.out_dir);
  est::writeTrajectory(o.out_dir, e.dr);
  est::writeTrajectory(o.out_dir, e.ekf.trajectory);
  std::vector<est::Trajectory> trajectories{e.dr, e.ekf.trajectory};
  if (e.ekf.rts) {
    est::writeTrajectory(o.out_dir, *e.ekf.rts);
    trajectories.push_back(*e.ekf.rts);
  }
  if (e.smoothed) {
    est::writeTrajectory(o.out_dir, e.smoothed->trajectory);
    trajectories.push_back(e.smoothed->trajectory);
  }
  est::writeSegments(std::filesystem::path(o.out_dir) / "segments.csv", e.segments);
  // Evaluated as written, so that `traverse evaluate` on these files gives this metrics.json.
  std::vector<est::Trajectory> written;
  for (const est::Trajectory& tr : trajectories) written.push_back(est::asWritten(tr));
  const eval::MetricsReport metrics =
      evaluateAgainstLogTruth(log, e.segmentation, written, diagnostics, runSummary(log, e), o);
  if (!global.quiet && metrics.evaluated) std::cout << eval::formatMetricsTable(metrics);
  for (const std::string& w : e.ekf.warnings) {
    std::cerr << "warning: " << w << "\n";
    said.push_back("warning: " + w);
  }
  std::ostringstream out;
  const est::EkfStats& s = e.ekf.stats;
  out << "segments: " << e.segmentation.segments.size() << " (" << e.segmentation.rests.size()
      << " rest windows)\n"
      << "ekf: " << e.ekf.trajectory.nodes.size() << " nodes; updates: slip " << s.slip_updates
      << " (" << s.slip_rejected << " gated out"
      << (s.slip_not_used > 0 ? ", " + std::to_string(s.slip_not_used) + " not used: wheel outages"
                              : std::string())
      << "), sun " << s.sun_updates << " (" << s.sun_rejected << " gated out), zero-velocity "
      << s.zero_velocity_updates << ", zero-rate " << s.zero_rate_updates << ", bias "
      << s.bias_updates << ", gravity " << s.gravity_updates << ", gyro " << s.gyro_updates
      << (s.common_slip_jumps > 0 ? "; common slip jumps " + std::to_string(s.common_slip_jumps)
                                  : std::string())
      << "\n";
  if (log.config.accel.hasBias() && !e.ekf.trajectory.nodes.empty()) {
    // b_a as the EKF ends (m/s², body axes) against its prior σ: what the data told it.
    const est::TrajectoryNode& n = e.ekf.trajectory.nodes.back();
    out << std::setprecision(3) << "ekf: accelerometer bias at the end (" << n.accel_bias.x()
        << ", " << n.accel_bias.y() << ", " << n.accel_bias.z() << ") +- ("
        << n.accel_bias_sigma.x() << ", " << n.accel_bias_sigma.y() << ", "
        << n.accel_bias_sigma.z() << ") m/s^2 (prior sigma " << log.config.accel.bias_sigma_mps2
        << ")" << std::setprecision(6) << "\n";
  }
  if (log.config.estimatesIcr() && !e.ekf.trajectory.nodes.empty()) {
    // δ as the EKF ends against its prior σ (the smoother's per segment: segments.csv).
    const est::TrajectoryNode& n = e.ekf.trajectory.nodes.back();
    const io::SkidSteerConfig& k = *log.config.skid_steer;
    out << std::setprecision(3) << "ekf: skid-steer ICRs' half-track error at the end " << n.icr
        << " +- " << n.icr_sigma << " m (prior sigma " << k.icrHalfTrackSigma()
        << "): ICRs at y = " << k.icr_y_left_m + n.icr << ", " << k.icr_y_right_m - n.icr
        << " m; per segment in segments.csv" << std::setprecision(6) << "\n";
  }
  if (e.odometry_scale_variance > 0.0)
    out << "odometry: the wheels' rolling radius is known to " << std::setprecision(3)
        << 100.0 * std::sqrt(e.odometry_scale_variance) << std::setprecision(6)
        << " % (rover.yaml odometry.wheel_radius_scale_*sigma): carried in every position sigma\n";
  if (const double m = log.config.odometry.imu_mounting_sigma_rad; m > 0.0)
    out << "odometry: the IMU's mounting against the wheels is known to " << std::setprecision(3)
        << m * 180.0 / 3.14159265358979323846 << std::setprecision(6)
        << " deg (rover.yaml odometry.imu_mounting_sigma_rad): carried in every position sigma\n";
  if (e.smoothed) {
    int converged = 0, fallback = 0;
    double solve = 0, cov = 0;
    size_t nodes = 0;
    for (const auto& g : e.smoothed->segments) {
      converged += g.status == smoother::SegmentStatus::kConverged,
          fallback += g.status == smoother::SegmentStatus::kFallbackEkf;
      solve += g.solve_seconds, cov += g.covariance_seconds, nodes += g.num_nodes;
    }
    int random_walk = 0;
    for (const auto& g : e.smoothed->segments) random_walk += g.random_walk_bias;
    out << "smoother: " << e.smoothed->segments.size() << " segments (" << converged
        << " converged, " << fallback << " fell back to the EKF), " << nodes << " nodes; solve "
        << solve << " s, covariance " << cov << " s (CPU, summed)";
    if (random_walk > 0) out << "; gyro bias a random walk in " << random_walk << " of them";
    out << "\n";
    for (const auto& g : e.smoothed->segments) {
      if (g.status == smoother::SegmentStatus::kFallbackEkf)
        out << "smoother: segment " << g.index << " (" << g.t_start << " .. " << g.t_end
            << " s) kept the EKF's states: " << g.message << "\n";
      // A segment spanning a gap is marked: there its states rest on the process model alone.
      for (const io::Finding& f : diagnostics.findings) {
        if (f.kind == "gap" && f.t >= g.t_start && f.t < g.t_end &&
            (f.file == "gyro.csv" || f.file == "joints.csv" || f.file == "accel.csv"))
          out << "smoother: segment " << g.index << " (" << g.t_start << " .. " << g.t_end
              << " s) spans a " << f.file << " " << f.message
              << " (its states there rest on the process model)\n";
      }
    }
  }
  out << "time: dead reckoning " << e.seconds.dr << " s, ekf " << e.seconds.ekf << " s"
      << (e.ekf.rts ? ", rts " + std::to_string(e.seconds.rts) + " s" : std::string())
      << (e.smoothed ? ", smoother " + std::to_string(e.seconds.smoother) + " s" : std::string())
      << " (wall)\n";
  std::istringstream lines(out.str());
  for (std::string line; std::getline(lines, line);) said.push_back(line);
  const bool write_report = smooth && !o.no_report;
  if (write_report) {
    report::ReportInput in;
    in.log_name = metrics.log;
    std::string command = "traverse " + o.command_name + " " + o.log_dir + " -o " + o.out_dir;
    for (const std::string& a : pipelineArguments(o, smooth)) command += " " + a;
    in.command = command;
    in.log = &log;
    in.segmentation = &e.segmentation;
    for (const est::Trajectory& tr : trajectories) in.trajectories.push_back(&tr);
    in.segments = e.segments;
    in.metrics = &metrics;
    in.run_lines = said;
    report::writeReport(std::filesystem::path(o.out_dir) / "report.html", in);
  }
  if (!global.quiet) {
    std::string names = "dr,ekf";
    if (e.ekf.rts) names += ",rts";
    if (e.smoothed) names += ",smoothed";
    std::cout << out.str() << "wrote " << o.out_dir << "/{" << names << "}"
              << ".{csv,tum}, segments.csv, metrics.json" << (write_report ? ", report.html" : "")
              << "\n";
  }
  return e;
}

}  // namespace traverse::app
