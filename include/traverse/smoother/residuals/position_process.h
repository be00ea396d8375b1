// Position process (K-1): ẋ = R(q) v, v the body velocity, over one node interval with the
// midpoint attitude and the mean velocity,
//
//   r = (x_{k+1} − x_k − R(q̄) ½ (v_k + v_{k+1}) Δt) / σ,   q̄ = q_k ⊗ Exp(½ Log(q_k⁻¹ ⊗ q_{k+1})),
//   σ² = q_v Δt³ / 12 + σ_floor²
//
// (the trapezoid error of a white-acceleration velocity, as for the attitude process).
//
// Parameter blocks: x_k, x_{k+1} (site, m), q_k, q_{k+1} (x, y, z, w), v_k, v_{k+1} (body, m/s).
#pragma once

#include <ceres/autodiff_cost_function.h>

#include "traverse/smoother/residuals/interpolation.h"

namespace traverse::smoother {

struct PositionProcessResidual {
  PositionProcessResidual(double dt, double sqrt_info) : dt(dt), sqrt_info(sqrt_info) {}

  template <typename T>
  bool operator()(const T* x_k, const T* x_k1, const T* q_k, const T* q_k1, const T* v_k,
                  const T* v_k1, T* r) const {
    const Eigen::Map<const Vec3<T>> xa(x_k), xb(x_k1), va(v_k), vb(v_k1);
    const Quat<T> q_mid = interpolateAttitude(Quat<T>(Eigen::Map<const Quat<T>>(q_k)),
                                              Quat<T>(Eigen::Map<const Quat<T>>(q_k1)), 0.5);
    const Vec3<T> v_mid = T(0.5) * (va + vb);
    Eigen::Map<Vec3<T>>{r} = T(sqrt_info) * (xb - xa - (q_mid * v_mid) * T(dt));
    return true;
  }

  static double sqrtInfo(double dt, double q_v, double floor_m) {
    return 1.0 / std::sqrt(q_v * dt * dt * dt / 12.0 + floor_m * floor_m);
  }

  static ceres::CostFunction* Create(double dt, double sqrt_info) {
    return new ceres::AutoDiffCostFunction<PositionProcessResidual, 3, 3, 3, 4, 4, 3, 3>(
        new PositionProcessResidual(dt, sqrt_info));
  }

  double dt, sqrt_info;
};

}  // namespace traverse::smoother
