#include "traverse/estimators/initialization.h"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <span>

#include "traverse/io/diagnostics.h"
#include "traverse/rover/joint_rates.h"

#include "traverse/sensors/sun_sensor.h"

namespace traverse::est {

double yawFromSun(const Vec2d& s_m, double roll, double pitch, const Mat3d& R_body_sensor,
                  const Vec3d& sun_site) {
  const Vec3d s_body = R_body_sensor * sensors::fisheyeUnproject(s_m);
  const Vec3d u = so3::fromRollPitchYaw(roll, pitch, 0.0) * s_body;
  return so3::wrapAngle(std::atan2(sun_site.y(), sun_site.x()) - std::atan2(u.y(), u.x()));
}

InitialState initialState(const io::TraverseLog& log, const Segmentation& seg,
                          const InitOptions& o) {
  InitialState s;
  // The estimates start at the first joint sample (every estimator writes a node per joint
  // sample). Readings of other streams before it are not used: before the joints the wheels say
  // nothing, and an accelerometer integrated over that stretch with the tilt not yet measured
  // drifted metres (joints.csv beginning 10 s late on multi-stop: the EKF's first node 3.6 m
  // off, and the smoother's whole track with it, which the evaluation's start alignment hid).
  // The given position is the position there. (A gyro that begins later is a gyro gap.)
  s.t = log.joints.t[0];
  s.p_site = o.position_site;
  s.bias_sigma.setConstant(log.config.gyro.initial_bias_sigma_rad_s);
  double roll = 0.0, pitch = 0.0, yaw = o.yaw_without_sun_rad;
  const RestWindow* w = nullptr;
  // The segment holding the start (the first, unless a stream began late).
  const auto first = std::find_if(seg.segments.begin(), seg.segments.end(),
                                  [&](const Segment& g) { return g.t_end > s.t; });
  if (first != seg.segments.end() && first->kind == Segment::Kind::kRest) {
    w = &seg.rests[static_cast<size_t>(first->rest_index)];
    s.rest_index = first->rest_index;
  }
  if (w && w->has_gravity) {
    roll = w->roll_pitch.roll_pitch.x(), pitch = w->roll_pitch.roll_pitch.y();
    s.attitude_sigma.head<2>() = w->roll_pitch.covariance.diagonal().cwiseSqrt();
    s.roll_pitch_from_gravity = true;
  }
  if (w && w->gyro_samples > 1) {
    for (int a = 0; a < 3; ++a) {
      if (w->bias_axes[static_cast<size_t>(a)])
        s.bias[a] = w->bias[a], s.bias_sigma[a] = w->bias_sigma[a], s.bias_from_rest = true;
    }
  }
  Vec2d sun = Vec2d::Zero();
  bool have_sun = false;
  double t_sun = s.t;
  if (w && w->has_sun) {
    sun = w->mean_sun, have_sun = true, s.yaw_from_rest_sun = true;
  } else if (log.sun) {
    for (Eigen::Index k = 0; k < log.sun->size() && !have_sun; ++k) {
      if (log.sun->values(k, 2) > 0.5)
        sun = log.sun->values.row(k).head<2>().transpose(), have_sun = true, t_sun = log.sun->t[k];
    }
  }
  if (have_sun) {
    s.yaw_from_sun = true;
    // A reading after the start (no sun in the first rest: the sun behind the mast, a dropout)
    // gives the heading at its own time: the rover may have turned since the start, so the
    // gyro's bias-corrected z rate integrated from the start to the reading is taken off
    // (heading change ≈ body z rotation on gentle slopes), and its σ grows by the bias's σ
    // over that time. (Before session 22 the reading's heading was taken as the start's: a
    // sun dropout over the first rest and leg of multi-stop gave 25° of yaw RMSE.)
    // Across a gap in the gyro (io::TimeGaps, as the EKF's) the turn is unknown.
    double turned = 0.0;
    const io::Stream& g = log.gyro;
    const bool gap = t_sun > s.t && io::TimeGaps(g).overlaps(s.t, t_sun);
    const Eigen::Index z = g.values.cols() - 1;
    for (Eigen::Index k = 0; k + 1 < g.size() && g.t[k] < t_sun; ++k) {
      const double t0 = std::max(g.t[k], s.t), t1 = std::min(g.t[k + 1], t_sun);
      if (t1 > t0) turned += (g.values(k, z) - s.bias.z()) * (t1 - t0);
    }
    yaw = so3::wrapAngle(yawFromSun(sun, roll, pitch, log.config.sun_sensor.R_body_sensor,
                                    log.config.sun.directionAt(t_sun)) -
                         turned);
    const double drift = s.bias_sigma.z() * (t_sun - s.t);
    // Yaw error ≈ sensor noise (averaged) over the horizontal lever |s| of the reading.
    const double n = w && w->has_sun ? w->sun_samples : 1;
    s.attitude_sigma.z() =
        std::hypot(log.config.sun_sensor.noise / std::sqrt(n) / std::max(sun.norm(), 0.05) +
                       0.5 * (s.attitude_sigma.x() + s.attitude_sigma.y()),
                   drift);
    s.attitude_prior_sigma.z() =
        gap ? std::numbers::pi
            : std::min(std::hypot(s.attitude_prior_sigma.z(), drift), std::numbers::pi);
    // A reading after the first rest is taken with the start's roll and pitch, and the body z
    // rate integrated is the heading's rate only on level ground: on the undulating K-22 a
    // reading half a turn later was 5° off (EstInitialAttitude.ASunReading…). Its σ is then
    // the prior's, which the filter's updates shrink.
    if (t_sun > s.t) s.attitude_sigma.z() = s.attitude_prior_sigma.z();
  } else {
    // No sun anywhere in the log: nothing measures the heading, so it is the gauge — the site
    // frame's x axis is the rover's heading at the start (yaw = InitOptions::yaw_without_sun_rad)
    // and every yaw σ that follows is relative to it, as the position's is to the given start.
    s.attitude_sigma.z() = 0.0;
    s.attitude_prior_sigma.z() = 0.0;
  }
  s.q_site_body = so3::fromRollPitchYaw(roll, pitch, yaw);
  // Starting in motion: the speed from the wheels at the first joint sample from the start.
  const io::Stream& j = log.joints;
  const Eigen::Index j0 = std::lower_bound(j.t.data(), j.t.data() + j.size(), s.t) - j.t.data();
  if (!w && j.size() - j0 >= 3) {
    const int h = log.config.joints.rate_filter_half_window;
    const Eigen::Index m = std::min<Eigen::Index>(j.size() - j0, 2 * h + 1);
    const Eigen::MatrixXd rates =
        rover::jointRates(std::span<const double>(j.t.data() + j0, static_cast<size_t>(m)),
                          j.values.middleRows(j0, m), {h});
    const io::Stream& g = log.gyro;
    const Eigen::Index g0 = std::min<Eigen::Index>(
        std::lower_bound(g.t.data(), g.t.data() + g.size(), s.t) - g.t.data(), g.size() - 1);
    const double wz = g.values(g0, g.values.cols() - 1) - s.bias.z();
    double v = 0.0;
    for (const rover::Wheel& wh : log.geometry.wheels)
      v += wh.radius * rates(0, wh.coord) + wz * wh.icr_offset_y;
    s.v_body.x() = v / log.geometry.numWheels();
  }
  return s;
}

}  // namespace traverse::est
