// Sun sensor (K-15, K-16): the fish-eye reading of the site-frame sun direction at the
// attitude interpolated to the reading's time (interpolation.h),
//
//   r = (s_m − h(q(u))) / σ_s,    h = sensors::sunSensorPredict (K-16 then K-15)
//
// Readings with valid = 0 never become residuals; a robust loss (Huber or Cauchy, chosen in
// the smoother options) is attached where the residual is added to the problem.
//
// Parameter blocks: q_k, q_{k+1} (x, y, z, w).
#pragma once

#include <ceres/autodiff_cost_function.h>

#include "traverse/sensors/sun_sensor.h"
#include "traverse/smoother/residual_collector.h"
#include "traverse/smoother/residuals/interpolation.h"

namespace traverse::smoother {

struct SunSensorResidual {
  SunSensorResidual(double u, const Vec2d& reading, const Vec3d& sun_site,
                    const sensors::SunSensorGeometry& geometry, double sqrt_info)
      : u(u), reading(reading), sun_site(sun_site), geometry(geometry), sqrt_info(sqrt_info) {}

  template <typename T>
  bool operator()(const T* q_k, const T* q_k1, T* r) const {
    const Quat<T> q = interpolateAttitude(Quat<T>(Eigen::Map<const Quat<T>>(q_k)),
                                          Quat<T>(Eigen::Map<const Quat<T>>(q_k1)), u);
    const Vec2<T> h = sensors::sunSensorPredict<T>(q, geometry, sun_site);
    Eigen::Map<Vec2<T>>{r} = T(sqrt_info) * (reading.cast<T>() - h);
    return true;
  }

  static ceres::CostFunction* Create(double u, const Vec2d& reading, const Vec3d& sun_site,
                                     const sensors::SunSensorGeometry& geometry, double sqrt_info) {
    return new ceres::AutoDiffCostFunction<SunSensorResidual, 2, 4, 4>(
        new SunSensorResidual(u, reading, sun_site, geometry, sqrt_info));
  }

  double u;
  Vec2d reading;
  Vec3d sun_site;
  sensors::SunSensorGeometry geometry;
  double sqrt_info;
};

/// Constraint (residual_collector.h): one sun reading at fraction u of the interval between
/// nodes k and k + 1, noise σ_s, under the robust loss. Blocks q_k, q_{k+1}.
inline void addSunReading(ResidualCollector& out, double u, const Vec2d& reading,
                          const Vec3d& sun_site, const sensors::SunSensorGeometry& geometry,
                          double noise, ceres::LossFunction* loss, const NodeHandles& k,
                          const NodeHandles& k1) {
  out.add("sun", SunSensorResidual::Create(u, reading, sun_site, geometry, 1.0 / noise), loss, k.q,
          k1.q);
}

}  // namespace traverse::smoother
