#include "traverse/estimators/dead_reckoning.h"

#include <cmath>

#include "traverse/rover/joint_rates.h"

namespace traverse::est {
namespace {

/// Heading-axis gyro reading (rad/s) linearly interpolated at time t.
double gyroZ(const io::Stream& g, double t) {
  const Eigen::Index c = g.values.cols() - 1;  // wz is the last column in both layouts
  const double* b = g.t.data();
  const double* e = b + g.size();
  const double* it = std::lower_bound(b, e, t);
  if (it == b) return g.values(0, c);
  if (it == e) return g.values(g.size() - 1, c);
  const Eigen::Index k = it - b;
  const double u = (t - g.t[k - 1]) / (g.t[k] - g.t[k - 1]);
  return (1 - u) * g.values(k - 1, c) + u * g.values(k, c);
}

/// Latest rest window starting at or before t (nullptr before the first).
const RestWindow* latestRest(const Segmentation& seg, double t) {
  const RestWindow* w = nullptr;
  for (const RestWindow& r : seg.rests) {
    if (r.t_start <= t) w = &r;
  }
  return w;
}

}  // namespace

Trajectory deadReckoning(const io::TraverseLog& log, const Segmentation& seg,
                         const InitialState& init, const DeadReckoningOptions& options) {
  const io::Stream& j = log.joints;
  const Eigen::MatrixXd rates =
      rover::jointRates(std::span<const double>(j.t.data(), static_cast<size_t>(j.size())),
                        j.values, {log.config.joints.rate_filter_half_window});
  // A rate is differenced over ±h samples: an outage reaches that far (as est::jointSamples).
  const double margin = (log.config.joints.rate_filter_half_window + 1) * io::medianPeriod(j);
  Trajectory tr;
  tr.name = "dr";
  tr.nodes.resize(static_cast<size_t>(j.size()));
  const Vec3d rpy0 = so3::rollPitchYaw(init.q_site_body);
  double yaw = rpy0.z();
  // Integrate the turn-centre point (body x = x_c): in Ackermann motion and turns in place its
  // velocity is along the heading; the body origin, x_c behind or ahead of it, is not.
  const double xc = log.geometry.turn_centre_x;
  auto offset = [&](double y) { return Vec3d(xc * std::cos(y), xc * std::sin(y), 0.0); };
  Vec3d p = init.p_site + offset(yaw);
  double prev_speed = 0.0, prev_rate = 0.0;
  for (Eigen::Index k = 0; k < j.size(); ++k) {
    const double t = j.t[k];
    const RestWindow* w = latestRest(seg, t);
    const double bias = w && w->gyro_samples > 1 ? w->bias.z() : init.bias.z();
    const double roll = w && w->has_gravity ? w->roll_pitch.roll_pitch.x() : rpy0.x();
    const double pitch = w && w->has_gravity ? w->roll_pitch.roll_pitch.y() : rpy0.y();
    // Each wheel rolls at v_x − ω_z y_ICR (skid steering; y_ICR = the wheel's own y otherwise,
    // which the symmetric sides cancel): v_x = mean(r ψ̇ + ω_z (y + icr_offset_y)).
    const double rate = gyroZ(log.gyro, t) - bias;
    // The wheels in use (all of them, unless the screen found one stuck; then the others).
    double speed = 0.0, used = 0.0;
    for (int pass = 0; pass < 2 && used == 0.0; ++pass) {
      for (int i = 0; i < log.geometry.numWheels(); ++i) {
        if (pass == 0 && !log.wheelUsed(i, t, margin)) continue;
        const rover::Wheel& w = log.geometry.wheels[static_cast<size_t>(i)];
        speed += w.radius * rates(k, w.coord) + rate * w.icr_offset_y, used += 1.0;
      }
    }
    speed /= used;
    if (k > 0) {  // trapezoid on heading and on the horizontal velocity
      const double dt = t - j.t[k - 1];
      const double yaw0 = yaw;
      yaw += 0.5 * dt * (rate + prev_rate);
      const double h = options.pitch_projection ? std::cos(pitch) : 1.0;
      p.x() += 0.5 * dt * h * (prev_speed * std::cos(yaw0) + speed * std::cos(yaw));
      p.y() += 0.5 * dt * h * (prev_speed * std::sin(yaw0) + speed * std::sin(yaw));
      if (options.pitch_projection) p.z() -= 0.5 * dt * (prev_speed + speed) * std::sin(pitch);
    }
    prev_speed = speed, prev_rate = rate;
    TrajectoryNode& n = tr.nodes[static_cast<size_t>(k)];
    n.t = t;
    n.p_site = p - offset(yaw);
    n.q_site_body = so3::fromRollPitchYaw(roll, pitch, yaw);
    n.v_body = Vec3d(speed, -rate * xc, 0);
    n.w_body = Vec3d(0, 0, rate);
    n.bias = Vec3d(0, 0, bias);
    n.xi = rover::WheelVectord::Zero(log.geometry.numWheels());
  }
  return tr;
}

}  // namespace traverse::est
