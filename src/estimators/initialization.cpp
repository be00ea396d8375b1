#include "traverse/estimators/initialization.h"

#include <algorithm>
#include <cmath>
#include <span>

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
  s.t = std::min(log.gyro.t[0], log.joints.t[0]);
  s.p_site = o.position_site;
  s.bias_sigma.setConstant(log.config.gyro.initial_bias_sigma_rad_s);
  double roll = 0.0, pitch = 0.0, yaw = o.yaw_without_sun_rad;
  const RestWindow* w = nullptr;
  if (!seg.segments.empty() && seg.segments.front().kind == Segment::Kind::kRest) {
    w = &seg.rests[static_cast<size_t>(seg.segments.front().rest_index)];
  }
  if (w && w->has_gravity) {
    roll = w->roll_pitch.roll_pitch.x(), pitch = w->roll_pitch.roll_pitch.y();
    s.attitude_sigma.head<2>() = w->roll_pitch.covariance.diagonal().cwiseSqrt();
    s.roll_pitch_from_gravity = true;
  }
  Vec2d sun = Vec2d::Zero();
  bool have_sun = false;
  if (w && w->has_sun) {
    sun = w->mean_sun, have_sun = true;
  } else if (log.sun) {
    for (Eigen::Index k = 0; k < log.sun->size() && !have_sun; ++k) {
      if (log.sun->values(k, 2) > 0.5)
        sun = log.sun->values.row(k).head<2>().transpose(), have_sun = true;
    }
  }
  if (have_sun) {
    yaw = yawFromSun(sun, roll, pitch, log.config.sun_sensor.R_body_sensor,
                     log.config.sun.directionAt(s.t));
    // Yaw error ≈ sensor noise (averaged) over the horizontal lever |s| of the reading.
    const double n = w && w->has_sun ? w->sun_samples : 1;
    s.attitude_sigma.z() = log.config.sun_sensor.noise / std::sqrt(n) / std::max(sun.norm(), 0.05) +
                           0.5 * (s.attitude_sigma.x() + s.attitude_sigma.y());
  } else {
    // No sun anywhere in the log: nothing measures the heading, so it is the gauge — the site
    // frame's x axis is the rover's heading at the start (yaw = InitOptions::yaw_without_sun_rad)
    // and every yaw σ that follows is relative to it, as the position's is to the given start.
    s.attitude_sigma.z() = 0.0;
  }
  s.q_site_body = so3::fromRollPitchYaw(roll, pitch, yaw);
  if (w && w->gyro_samples > 1) {
    for (int a = 0; a < 3; ++a) {
      if (w->bias_axes[static_cast<size_t>(a)])
        s.bias[a] = w->bias[a], s.bias_sigma[a] = w->bias_sigma[a];
    }
  }
  if (!w && log.joints.size() >= 3) {  // starting in motion: the speed from the wheels
    const int h = log.config.joints.rate_filter_half_window;
    const Eigen::Index m = std::min<Eigen::Index>(log.joints.size(), 2 * h + 1);
    const Eigen::MatrixXd rates =
        rover::jointRates(std::span<const double>(log.joints.t.data(), static_cast<size_t>(m)),
                          log.joints.values.topRows(m), {h});
    const double wz = log.gyro.values(0, log.gyro.values.cols() - 1) - s.bias.z();
    double v = 0.0;
    for (const rover::Wheel& wh : log.geometry.wheels)
      v += wh.radius * rates(0, wh.coord) + wz * wh.icr_offset_y;
    s.v_body.x() = v / log.geometry.numWheels();
  }
  return s;
}

}  // namespace traverse::est
