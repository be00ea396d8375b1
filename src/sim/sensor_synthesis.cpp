#include "sim/sensor_synthesis.h"

#include <algorithm>
#include <cmath>
#include <functional>

#include "traverse/sensors/accelerometer.h"
#include "traverse/sensors/gyro.h"
#include "traverse/sensors/sun_sensor.h"
#include "traverse/sim/random.h"

namespace traverse::sim {
namespace {

double quantize(double x, double q) {
  return q > 0 ? q * std::round(x / q) : x;
}

/// A stream with the given columns sampled at `rate_hz` over the truth's time span.
io::Stream sampled(
    const std::vector<TruthSample>& truth, double rate_hz, std::vector<std::string> columns,
    const std::function<void(const TruthSample&, Eigen::Ref<Eigen::RowVectorXd>)>& fill) {
  io::Stream s;
  s.columns = std::move(columns);
  const double t_end = truth.back().t;
  const long n = static_cast<long>(std::floor(t_end * rate_hz + 1e-9)) + 1;
  s.t.resize(n);
  s.values.resize(n, static_cast<Eigen::Index>(s.columns.size()));
  for (long k = 0; k < n; ++k) {
    s.t[k] = static_cast<double>(k) / rate_hz;
    Eigen::RowVectorXd row(s.values.cols());
    fill(interpolateTruth(truth, s.t[k]), row);
    s.values.row(k) = row;
  }
  return s;
}

double maxSpeed(const Scenario& sc) {
  double v = 0.0;
  for (const Leg& l : sc.legs) {
    if (l.kind == Leg::Kind::kStraight || l.kind == Leg::Kind::kArc) v = std::max(v, l.speed_mps);
  }
  return v;
}

void configureLog(const Scenario& sc, const std::vector<TruthSample>& truth, int wheels,
                  io::RoverConfig& c) {
  const double t_end = truth.back().t;
  const SensorSpec& s = sc.sensors;
  c.gravity_mps2 = sc.gravity_mps2;
  c.gyro.axes = s.gyro_three_axis ? io::GyroAxes::kThreeAxis : io::GyroAxes::kHeadingOnly;
  c.gyro.noise_rad_s = std::max(s.gyro_noise_rad_s, s.gyro_quantum_rad_s / std::sqrt(12.0));
  c.gyro.bias_random_walk_rad_s_per_sqrt_s = s.gyro_bias_random_walk_rad_s_per_sqrt_s;
  // The simulated gyro reads the true rate plus its bias and white noise: no scale factor or
  // misalignment error, so no rate perturbation on its measured axes (O-1's ω_p there, which a
  // real rover's rover.yaml states for its own gyro; the default is 0.1 × the rate noise).
  c.gyro.rate_perturbation_rad_s2_per_sqrt_hz = 0.0;
  c.sun_sensor.noise = s.sun_noise;
  c.sun_sensor.field_of_view_rad = s.sun_fov_rad;
  c.sun.direction_site = s.sun_direction;
  c.sun.azimuth_elevation.clear();
  if (s.sun_azimuth_rate_rad_s != 0.0) {
    // A table every 10 s over the traverse (the estimators interpolate it linearly).
    for (double t = 0.0; t <= t_end + 10.0; t += 10.0) {
      const Vec3d d = sunDirectionAt(s, t);
      c.sun.azimuth_elevation.emplace_back(t, std::atan2(d.y(), d.x()), std::asin(d.z()));
    }
  }
  // Slip noise that says what was injected (the rover's own values stay as the floor:
  // thin-wheel and terrain-curvature model error). What the wheels share is stated as the
  // common slip c (docs/model.md "Common slip"), what each wheel has alone as its rows' white
  // noise — a shared error stated as per-wheel white noise would be averaged down by the wheel
  // count that it does not average over:
  //  - the body's lateral Gauss–Markov slip (σ_y, τ) is c_y as it is;
  //  - the per-wheel longitudinal Gauss–Markov slips (σ, τ, independent) split into their
  //    mean, shared (σ²/N, c_x), and each wheel's deviation from it (σ²(1 − 1/N)), stated as
  //    white noise of equal low-frequency power at the joint rate f: σ_w² = 2 σ² τ f;
  //  - the bursts (every wheel at once, amplitude A for D s, a fraction p of the time) are
  //    shared too: in c_x with the low-frequency power they have, 2 p A² D = 2 σ_b² τ.
  // A scenario without lateral correlated slip gets no c (both axes are needed, rover.yaml);
  // its shared parts then stay in the white rows, as they were before c existed.
  // Every slip term is injected times the leg's progress (|speed| / cruise): each is stated with
  // the power it has on average over the motion, mean(progress²) times its cruise power (a
  // smooth-profile leg: 0.41; ramped legs of a few metres: 0.9–1).
  double p2_sum = 0.0;
  int moving = 0;
  for (const TruthSample& x : truth) {
    if (!x.moving) continue;
    p2_sum += x.progress * x.progress;
    ++moving;
  }
  const double p2 = moving > 0 ? p2_sum / moving : 1.0;
  const SlipSpec& sl = sc.slip;
  const double f = s.joints_rate_hz, tau = sl.correlation_time_s;
  const double burst_fraction = sl.burst_rate_per_m * maxSpeed(sc) * sl.burst_duration_s;
  const double burst_power =
      p2 * 2 * sl.burst_duration_s * burst_fraction * sl.burst_mps * sl.burst_mps;
  const double corr2 = p2 * sl.longitudinal_correlated_mps * sl.longitudinal_correlated_mps;
  const double white2 = p2 * sl.longitudinal_white_mps * sl.longitudinal_white_mps;
  const double n = std::max(wheels, 1);
  double long2 = 0.0, lat2 = 0.0;
  if (sl.lateral_correlated_mps > 0.0) {
    auto& sn = c.slip_noise;
    const double cx2 = corr2 / n + burst_power / (2 * tau);
    const double cy2 = p2 * sl.lateral_correlated_mps * sl.lateral_correlated_mps;
    sn.common_longitudinal_mps =
        std::sqrt(sn.common_longitudinal_mps * sn.common_longitudinal_mps + cx2);
    sn.common_lateral_mps = std::sqrt(sn.common_lateral_mps * sn.common_lateral_mps + cy2);
    sn.common_time_constant_s = tau;
    long2 = white2 + 2 * tau * f * corr2 * (1.0 - 1.0 / n);
  } else {
    long2 = white2 + 2 * tau * f * corr2 + f * burst_power;
  }
  c.slip_noise.longitudinal_mps =
      std::sqrt(c.slip_noise.longitudinal_mps * c.slip_noise.longitudinal_mps + long2);
  c.slip_noise.lateral_mps = std::sqrt(c.slip_noise.lateral_mps * c.slip_noise.lateral_mps + lat2);
  c.accel.lever_arm_m = s.accel_lever_arm_m;
  c.accel.noise_mps2 = s.accel_noise_mps2;
  c.accel.bias_sigma_mps2 = s.accel_bias_sigma_mps2;
  c.gps.antenna_body_m = s.gps_antenna_body_m;
  c.joints.angle_noise_rad =
      std::max(s.joint_angle_noise_rad, s.joint_quantum_rad / std::sqrt(12.0));
  c.joints.steering_noise_rad =
      std::max(s.steering_noise_rad, s.joint_quantum_rad / std::sqrt(12.0));
  c.joints.wheel_noise_rad =
      std::max(s.wheel_angle_noise_rad, s.wheel_quantum_rad / std::sqrt(12.0));
}

}  // namespace

Vec3d sunDirectionAt(const SensorSpec& s, double t) {
  return Eigen::AngleAxisd(s.sun_azimuth_rate_rad_s * t, Vec3d::UnitZ()) * s.sun_direction;
}

TruthSample interpolateTruth(const std::vector<TruthSample>& truth, double t) {
  const auto it = std::upper_bound(truth.begin(), truth.end(), t,
                                   [](double v, const TruthSample& s) { return v < s.t; });
  if (it == truth.begin()) return truth.front();
  if (it == truth.end()) return truth.back();
  const TruthSample& a = *(it - 1);
  const TruthSample& b = *it;
  const double u = (t - a.t) / (b.t - a.t);
  TruthSample s = a;
  s.t = t;
  s.p_site = (1 - u) * a.p_site + u * b.p_site;
  s.q_site_body = a.q_site_body.slerp(u, b.q_site_body);
  s.v_body = (1 - u) * a.v_body + u * b.v_body;
  s.w_body = (1 - u) * a.w_body + u * b.w_body;
  s.a_body = (1 - u) * a.a_body + u * b.a_body;
  s.w_dot_body = (1 - u) * a.w_dot_body + u * b.w_dot_body;
  s.joints = (1 - u) * a.joints + u * b.joints;
  s.joint_rates = (1 - u) * a.joint_rates + u * b.joint_rates;
  s.xi = (1 - u) * a.xi + u * b.xi;
  s.gyro_bias = (1 - u) * a.gyro_bias + u * b.gyro_bias;
  s.cmd = (1 - u) * a.cmd + u * b.cmd;
  return s;
}

io::TraverseLog synthesizeLog(const Scenario& sc, io::RoverConfig config,
                              const rover::RoverGeometry& geo,
                              const std::filesystem::path& rover_dir,
                              const std::vector<TruthSample>& truth, uint64_t seed) {
  const SensorSpec& s = sc.sensors;
  configureLog(sc, truth, geo.numWheels(), config);
  io::TraverseLog log;
  log.dir = rover_dir;
  log.config = config;
  log.geometry = geo;

  Rng gyro_rng(seed, 1), sun_rng(seed, 2), accel_rng(seed, 3), joint_rng(seed, 4);
  const sensors::GyroAxes gyro_axes =
      s.gyro_three_axis ? sensors::GyroAxes::threeAxis() : sensors::GyroAxes::headingOnly();
  const std::vector<std::string> gyro_cols = s.gyro_three_axis
                                                 ? std::vector<std::string>{"wx", "wy", "wz"}
                                                 : std::vector<std::string>{"wz"};
  log.gyro = sampled(truth, s.gyro_rate_hz, gyro_cols, [&](const TruthSample& x, auto row) {
    const Vec3d w = sensors::gyroPredict<double>(x.w_body, x.gyro_bias);  // K-12
    for (Eigen::Index c = 0; c < row.size(); ++c) {
      row[c] = quantize(w[gyro_axes.axis(c)] + s.gyro_noise_rad_s * gyro_rng.normal(),
                        s.gyro_quantum_rad_s);  // B_g (K-13)
    }
  });

  const std::vector<std::string> joint_cols = geo.columnNames();
  log.joints = sampled(truth, s.joints_rate_hz, joint_cols, [&](const TruthSample& x, auto row) {
    for (int c = 0; c < geo.numCoords(); ++c) {
      const rover::CoordKind kind = geo.coords[static_cast<size_t>(c)].kind;
      const bool wheel = kind == rover::CoordKind::kDrive;
      const double noise = wheel                                 ? s.wheel_angle_noise_rad
                           : kind == rover::CoordKind::kSteering ? s.steering_noise_rad
                                                                 : s.joint_angle_noise_rad;
      row[c] = quantize(x.joints[c] + noise * joint_rng.normal(),
                        wheel ? s.wheel_quantum_rad : s.joint_quantum_rad);
    }
  });

  if (s.sun_rate_hz > 0) {
    sensors::SunSensorGeometry sg{config.sun_sensor.R_body_sensor, 0.5 * s.sun_fov_rad};
    log.sun =
        sampled(truth, s.sun_rate_hz, {"s1", "s2", "valid"}, [&](const TruthSample& x, auto row) {
          const Vec3d sun = sunDirectionAt(s, x.t);
          const double n1 = sun_rng.normal(), n2 = sun_rng.normal();
          if (!sensors::sunInFieldOfView(x.q_site_body, sg, sun)) {
            row << 0.0, 0.0, 0.0;
            return;
          }
          const Vec2d m = sensors::sunSensorPredict<double>(x.q_site_body, sg, sun);  // K-15, K-16
          row << std::clamp(m.x() + s.sun_noise * n1, -1.0, 1.0),
              std::clamp(m.y() + s.sun_noise * n2, -1.0, 1.0), 1.0;
        });
  }
  if (s.accel) {
    log.accel =
        sampled(truth, s.accel_rate_hz, {"ax", "ay", "az"}, [&](const TruthSample& x, auto row) {
          const Vec3d a = sensors::accelPredict<double>(x.q_site_body, x.a_body, x.v_body, x.w_body,
                                                        x.w_dot_body, s.accel_lever_arm_m,
                                                        sc.gravity_mps2);  // K-10
          for (int c = 0; c < 3; ++c)
            row[c] = a[c] + s.accel_bias_mps2[c] + s.accel_noise_mps2 * accel_rng.normal();
        });
  }
  if (s.cmd) {
    log.cmd = sampled(truth, s.joints_rate_hz, {"vx", "vy", "vz", "wx", "wy", "wz"},
                      [&](const TruthSample& x, auto row) { row = x.cmd.transpose(); });
  }
  if (s.gps_rate_hz > 0) {
    Rng gps_rng(seed, 5);
    log.gps = sampled(truth, s.gps_rate_hz, {"x", "y", "z", "sx", "sy", "sz"},
                      [&](const TruthSample& x, auto row) {
                        const Vec3d antenna = x.p_site + x.q_site_body * s.gps_antenna_body_m;
                        for (int c = 0; c < 3; ++c) {
                          row[c] = antenna[c] + s.gps_sigma_m[c] * gps_rng.normal();
                          row[3 + c] = s.gps_sigma_m[c];
                        }
                      });
  }
  std::vector<std::string> truth_cols = {"x", "y", "z", "qw", "qx", "qy", "qz"};
  const int nw = geo.numWheels();
  for (int i = 1; i <= nw; ++i) truth_cols.push_back("xi" + std::to_string(i));
  for (const char* c : {"bx", "by", "bz", "vx", "vy", "vz", "wx", "wy", "wz"})
    truth_cols.emplace_back(c);
  log.truth = sampled(truth, sc.truth_output_hz, truth_cols, [&](const TruthSample& x, auto row) {
    const Quatd& q = x.q_site_body;
    row.head(7) << x.p_site.x(), x.p_site.y(), x.p_site.z(), q.w(), q.x(), q.y(), q.z();
    for (int i = 0; i < nw; ++i) row[7 + i] = x.xi[i];
    row.segment(7 + nw, 3) = x.gyro_bias.transpose();
    row.segment(10 + nw, 3) = x.v_body.transpose();
    row.segment(13 + nw, 3) = x.w_body.transpose();
  });
  return log;
}

}  // namespace traverse::sim
