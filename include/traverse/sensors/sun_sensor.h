// Wide-angle sun sensor, fish-eye model (K-14 … K-16; O-6, O-7).
//
//   s = R_bsᵀ R(q)ᵀ s_v                      sun unit vector in the sensor frame (K-16)
//   s_m = (2/π) · α/ρ · (s_x, s_y) + n_s       with ρ = |(s_x, s_y)|, α = atan2(ρ, s_z)  (K-15)
//
// For a unit vector in the upper hemisphere α = arcsin ρ, which is K-15 exactly; atan2 keeps the
// map smooth and monotonic past 90° and its derivative finite. At the boresight (ρ → 0) the
// factor α/ρ → 1/s_z, i.e. (2/π)·arcsin(ρ)/ρ → 2/π: a Taylor branch handles it so Jets stay
// finite. Elevation in the sensor frame is π/2 (1 − |s_m|) as the paper states; azimuth is
// atan2(s_m(2), s_m(1)) in our axis convention (the paper's −s_m(1) reflects its device axes).
#pragma once

#include <cmath>

#include "traverse/core/types.h"

namespace traverse::sensors {

struct SunSensorGeometry {
  Mat3d R_body_sensor = Mat3d::Identity();  ///< sensor → body rotation
  double half_fov_rad = 1.3962634;          ///< half the field of view (80° for 160°)
};

/// Sun unit vector in the sensor frame (K-16's R(q)ᵀ s_v, plus the mounting rotation).
template <typename T>
Vec3<T> sunInSensor(const Quat<T>& q_site_body, const SunSensorGeometry& geo,
                    const Vec3d& sun_site) {
  const Vec3<T> in_body = q_site_body.conjugate() * sun_site.cast<T>();
  return geo.R_body_sensor.transpose().cast<T>() * in_body;
}

/// Fish-eye projection K-15 of a sun direction (any length > 0) in the sensor frame.
template <typename T>
Vec2<T> fisheyeProject(const Vec3<T>& s_sensor) {
  using std::atan2;
  using std::sqrt;
  const Vec3<T> s = s_sensor / s_sensor.norm();
  const T rho_sq = s.x() * s.x() + s.y() * s.y();
  T k;  // α/ρ
  if (rho_sq > T(1e-12)) {
    const T rho = sqrt(rho_sq);
    k = atan2(rho, s.z()) / rho;
  } else {
    k = T(1) / s.z() - rho_sq / (T(3) * s.z() * s.z() * s.z());
  }
  return Vec2<T>(s.x(), s.y()) * (T(2.0 / M_PI) * k);
}

/// Predicted reading (s1, s2) for attitude q (K-15, K-16).
template <typename T>
Vec2<T> sunSensorPredict(const Quat<T>& q_site_body, const SunSensorGeometry& geo,
                         const Vec3d& sun_site) {
  return fisheyeProject(sunInSensor(q_site_body, geo, sun_site));
}

/// Angle between the sun and the sensor boresight (rad).
inline double sunOffBoresight(const Quatd& q_site_body, const SunSensorGeometry& geo,
                              const Vec3d& sun_site) {
  const Vec3d s = sunInSensor(q_site_body, geo, sun_site).normalized();
  return std::atan2(std::hypot(s.x(), s.y()), s.z());
}

/// True when the sun is inside the field of view (reading usable).
inline bool sunInFieldOfView(const Quatd& q_site_body, const SunSensorGeometry& geo,
                             const Vec3d& sun_site) {
  return sunOffBoresight(q_site_body, geo, sun_site) <= geo.half_fov_rad;
}

/// Inverse of K-15: the unit sun vector in the sensor frame from a reading (α = π/2 |s_m|).
inline Vec3d fisheyeUnproject(const Vec2d& s_m) {
  const double r = s_m.norm();
  const double alpha = 0.5 * M_PI * r;
  if (r < 1e-15) return Vec3d::UnitZ();
  return Vec3d(std::sin(alpha) * s_m.x() / r, std::sin(alpha) * s_m.y() / r, std::cos(alpha));
}

}  // namespace traverse::sensors
