#include "traverse/pipeline/pipeline.h"

#include <chrono>

#include <algorithm>
#include <set>

namespace traverse::pipeline {

using est::RestWindow;
using est::Segment;
using est::TrajectoryNode;

std::vector<SegmentRow> segmentRows(const Segmentation& seg, const Trajectory& tr, bool accel_bias,
                                    bool icr) {
  std::vector<SegmentRow> rows;
  for (size_t s = 0; s < seg.segments.size(); ++s) {
    const Segment& sg = seg.segments[s];
    SegmentRow r;
    r.segment = static_cast<int>(s);
    r.t_start = sg.t_start, r.t_end = sg.t_end, r.kind = sg.kind;
    // The trajectory node nearest the segment's end.
    const auto it = std::lower_bound(tr.nodes.begin(), tr.nodes.end(), sg.t_end,
                                     [](const TrajectoryNode& n, double t) { return n.t < t; });
    if (!tr.nodes.empty()) {
      const TrajectoryNode& n = it == tr.nodes.end() ? tr.nodes.back() : *it;
      r.bias = n.bias, r.sigma_bias = n.bias_sigma;
      if (accel_bias) r.accel_bias = n.accel_bias, r.sigma_accel_bias = n.accel_bias_sigma;
      if (icr) r.icr = n.icr, r.sigma_icr = n.icr_sigma;
    }
    if (sg.kind == Segment::Kind::kRest) {
      const RestWindow& w = seg.rests[static_cast<size_t>(sg.rest_index)];
      for (int a = 0; a < 3; ++a) {
        if (w.bias_axes[static_cast<size_t>(a)] && w.gyro_samples > 1)
          r.bias[a] = w.bias[a], r.sigma_bias[a] = w.bias_sigma[a];
      }
    }
    rows.push_back(r);
  }
  return rows;
}

namespace {

/// The stream without the rows at the given times.
io::Stream withoutRows(const io::Stream& s, const std::set<double>& times) {
  io::Stream out;
  out.columns = s.columns;
  std::vector<Eigen::Index> keep;
  keep.reserve(static_cast<size_t>(s.size()));
  for (Eigen::Index k = 0; k < s.size(); ++k) {
    if (!times.contains(s.t[k])) keep.push_back(k);
  }
  out.t.resize(static_cast<Eigen::Index>(keep.size()));
  out.values.resize(out.t.size(), s.values.cols());
  for (Eigen::Index i = 0; i < out.t.size(); ++i) {
    out.t[i] = s.t[keep[static_cast<size_t>(i)]];
    out.values.row(i) = s.values.row(keep[static_cast<size_t>(i)]);
  }
  return out;
}

}  // namespace

io::TraverseLog withoutSpikes(const io::TraverseLog& log, const io::Diagnostics& diagnostics,
                              std::vector<io::Finding>* rejected) {
  io::TraverseLog out = log;
  std::set<double> gyro, accel, joints, sun;
  for (const io::Finding& f : diagnostics.findings) {
    if (f.kind != "spike") continue;
    std::set<double>* times = f.file == "gyro.csv"     ? &gyro
                              : f.file == "accel.csv"  ? &accel
                              : f.file == "joints.csv" ? &joints
                              : f.file == "sun.csv"    ? &sun
                                                       : nullptr;
    if (times == nullptr) continue;
    times->insert(f.t);  // f.t is the sample's own stamp, as read
    if (rejected) rejected->push_back(f);
  }
  if (!gyro.empty()) out.gyro = withoutRows(log.gyro, gyro);
  if (!joints.empty()) out.joints = withoutRows(log.joints, joints);
  if (!accel.empty() && log.accel) out.accel = withoutRows(*log.accel, accel);
  if (!sun.empty() && log.sun) out.sun = withoutRows(*log.sun, sun);
  return out;
}

io::TraverseLog withoutStuckWheels(const io::TraverseLog& log, const io::Diagnostics& diagnostics,
                                   std::vector<io::Finding>* rejected) {
  io::TraverseLog out = log;
  for (const io::Finding& f : diagnostics.findings) {
    if (f.kind != "stuck" || f.file != "joints.csv") continue;
    for (int i = 0; i < log.geometry.numWheels(); ++i) {
      const int coord = log.geometry.wheels[static_cast<size_t>(i)].coord;
      if (coord >= static_cast<int>(log.joints.columns.size()) ||
          log.joints.columns[static_cast<size_t>(coord)] != f.column)
        continue;
      out.wheel_outages.push_back({i, f.t, f.t + f.duration_s});
      if (rejected) rejected->push_back(f);
    }
  }
  return out;
}

io::TraverseLog screenedLog(const io::TraverseLog& input, const PipelineConfig& config,
                            const io::Diagnostics* diagnostics, Estimates& e) {
  io::TraverseLog screened = input;
  if (config.reject_spikes || config.drop_stuck_wheels) {
    const io::Diagnostics found = diagnostics ? io::Diagnostics{} : io::diagnose(input);
    const io::Diagnostics& d = diagnostics ? *diagnostics : found;
    if (config.reject_spikes) screened = withoutSpikes(screened, d, &e.rejected);
    if (config.drop_stuck_wheels) screened = withoutStuckWheels(screened, d, &e.rejected);
  }
  if (config.joints_clock_offset_s) {
    e.joints_shift_s = -*config.joints_clock_offset_s;
    if (e.joints_shift_s != 0.0) screened = est::withJointsShifted(screened, -e.joints_shift_s);
  } else if (config.align_joints_clock) {
    e.clocks = est::estimateClockAlignment(screened);
    if (const est::ClockOffset* j = e.clocks.find("joints.csv")) {
      e.joints_clock = *j;
      e.joints_shift_s = -j->offset_s;
    }
    screened = est::withClocksAligned(screened, e.clocks);
  }
  return screened;
}

ScreenedDeadReckoning screenedDeadReckoning(const io::TraverseLog& input,
                                            const PipelineConfig& config) {
  Estimates e;
  ScreenedDeadReckoning out{screenedLog(input, config, nullptr, e), {}, {}};
  out.segmentation = est::segment(out.log, config.segmentation);
  const InitialState init = est::initialState(out.log, out.segmentation, config.init);
  out.dr = est::deadReckoning(out.log, out.segmentation, init, config.dead_reckoning);
  return out;
}

double odometryScaleVariance(const io::TraverseLog& log) {
  const auto& wheels = log.geometry.wheels;
  if (wheels.empty()) return 0.0;
  double left = 0.0;
  for (const rover::Wheel& w : wheels) left += w.left_share;
  return log.config.odometry.meanScaleVariance(left / static_cast<double>(wheels.size()));
}

Estimates estimate(const io::TraverseLog& input, const PipelineConfig& config,
                   const io::Diagnostics* diagnostics) {
  Estimates e;
  io::TraverseLog screened = screenedLog(input, config, diagnostics, e);
  e.segmentation = est::segment(screened, config.segmentation);
  if (config.measure_rest_noise) {
    // A noise the rests refute is replaced before anything assumes it — the rest test of the
    // segmentation included, which runs again.
    e.noise = est::restNoise(screened);
    if (!e.noise.empty()) {
      screened = est::withRestNoise(screened, e.noise);
      e.segmentation = est::segment(screened, config.segmentation);
    }
  }
  if (config.check_slip_correlation && !(screened.config.slip_noise.common_yaw_rate_rad_s > 0)) {
    // Slip correlated in time turns the wheels against the gyro: carried where the data show it.
    e.slip_correlation = est::wheelYawRateCheck(screened, e.segmentation);
    if (e.slip_correlation.refuted) screened = est::withCommonYawSlip(screened, e.slip_correlation);
  }
  const io::TraverseLog& log = screened;
  e.init = est::initialState(log, e.segmentation, config.init);
  using Clock = std::chrono::steady_clock;
  auto seconds = [](Clock::time_point a) {
    return std::chrono::duration<double>(Clock::now() - a).count();
  };
  auto t0 = Clock::now();
  e.dr = est::deadReckoning(log, e.segmentation, e.init, config.dead_reckoning);
  e.seconds.dr = seconds(t0);
  t0 = Clock::now();
  e.ekf = est::runEkf(log, e.segmentation, e.init, config.ekf);
  e.seconds.rts = e.ekf.rts_seconds;
  e.seconds.ekf = seconds(t0) - e.seconds.rts;
  e.segments = segmentRows(e.segmentation, e.ekf.trajectory, log.config.accel.hasBias(),
                           log.config.estimatesIcr());
  if (config.smooth) {
    smoother::SmootherOptions so = config.smoother;
    // kAuto follows the EKF's choice: when the EKF gave up the accelerometer-driven velocity
    // (runEkf's rule), so does the smoother it seeds.
    if (so.velocity == smoother::SmootherOptions::VelocityModel::kAuto &&
        e.ekf.velocity == est::EkfOptions::VelocityModel::kPerturbation)
      so.velocity = smoother::SmootherOptions::VelocityModel::kPerturbation;
    t0 = Clock::now();
    e.smoothed = smoother::smooth(log, e.segmentation, e.ekf.trajectory, so);
    e.seconds.smoother = seconds(t0);
    e.segments = smoother::smootherSegmentRows(e.segments, *e.smoothed);
  }
  // What the wheels' unknown rolling radius leaves in every position (after the smoother, which
  // seeds from the EKF's covariance where its marginals fail).
  e.odometry_scale_variance = odometryScaleVariance(log);
  est::addOdometryScaleCovariance(&e.ekf.trajectory, e.odometry_scale_variance);
  if (e.ekf.rts) est::addOdometryScaleCovariance(&*e.ekf.rts, e.odometry_scale_variance);
  if (e.smoothed)
    est::addOdometryScaleCovariance(&e.smoothed->trajectory, e.odometry_scale_variance);
  // ... and the IMU's unknown mounting against the wheels (the same kind of consider term).
  const double mount = log.config.odometry.imu_mounting_sigma_rad;
  est::addMountingCovariance(&e.ekf.trajectory, mount);
  if (e.ekf.rts) est::addMountingCovariance(&*e.ekf.rts, mount);
  if (e.smoothed) est::addMountingCovariance(&e.smoothed->trajectory, mount);
  return e;
}

}  // namespace traverse::pipeline
