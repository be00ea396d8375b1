#include "pipeline.h"

#include <iostream>

#include "traverse/eval/metrics.h"
#include "traverse/io/log_reader.h"

namespace traverse::app {

void addPipelineOptions(CLI::App& cmd, PipelineOptions& o) {
  cmd.add_option("LOGDIR", o.log_dir, "Log directory (docs/log-format.md)")->required();
  cmd.add_option("-o,--output", o.out_dir, "Output directory")->required();
  cmd.add_flag("--skip-bad-rows", o.skip_bad_rows,
               "Drop malformed rows (counted) instead of stopping");
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
}

est::PipelineConfig pipelineConfig(const PipelineOptions& o) {
  est::PipelineConfig c;
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
  c.dead_reckoning.pitch_projection = o.pitch_projection;
  return c;
}

est::Estimates runPipeline(const PipelineOptions& o, const GlobalOptions& global, bool /*smooth*/) {
  io::ReadReport report;
  const io::TraverseLog log = io::readLog(o.log_dir, io::ReadOptions{o.skip_bad_rows}, &report);
  for (const auto& [file, n] : report.skipped_rows)
    std::cerr << file << ": skipped " << n << " bad rows\n";
  est::Estimates e = est::estimate(log, pipelineConfig(o));
  std::filesystem::create_directories(o.out_dir);
  est::writeTrajectory(o.out_dir, e.dr);
  est::writeTrajectory(o.out_dir, e.ekf.trajectory);
  est::writeSegments(std::filesystem::path(o.out_dir) / "segments.csv", e.segments);
  if (log.truth) {  // evaluation when the log has truth (outputs.md)
    const eval::TruthTrajectory truth(*log.truth);
    const auto name = std::filesystem::absolute(o.log_dir).lexically_normal().filename().string();
    const eval::MetricsReport report =
        eval::evaluateAll(name.empty() ? o.log_dir : name, {e.dr, e.ekf.trajectory}, truth);
    eval::writeMetricsJson(std::filesystem::path(o.out_dir) / "metrics.json", report);
    if (!global.quiet) std::cout << eval::formatMetricsTable(report);
  }
  if (!global.quiet) {
    const est::EkfStats& s = e.ekf.stats;
    std::cout << "segments: " << e.segmentation.segments.size() << " ("
              << e.segmentation.rests.size() << " rest windows)\n"
              << "ekf: " << e.ekf.trajectory.nodes.size() << " nodes; updates: slip "
              << s.slip_updates << " (" << s.slip_rejected << " gated out), sun " << s.sun_updates
              << " (" << s.sun_rejected << " gated out), zero-velocity " << s.zero_velocity_updates
              << ", zero-rate " << s.zero_rate_updates << ", bias " << s.bias_updates
              << ", gravity " << s.gravity_updates << ", gyro " << s.gyro_updates << "\n"
              << "wrote " << o.out_dir << "/{dr,ekf}.{csv,tum}, segments.csv"
              << (log.truth ? ", metrics.json" : "") << "\n";
  }
  return e;
}

}  // namespace traverse::app
