// Attitude process (K-2 / K-7): q̇ = ½ q ⊗ [ω; 0] over one node interval, trapezoid rule,
//
//   r = (Log(q_k⁻¹ ⊗ q_{k+1}) − ½ (ω_k + ω_{k+1}) Δt) / σ,     σ² = q_ω Δt³ / 12 + σ_floor²
//
// With the rate a white-acceleration process (ω̇ = n_ω, density q_ω), the trapezoid error of
// the integrated rate has variance q_ω Δt³/12 per axis and is uncorrelated with the rate
// increment ω_{k+1} − ω_k (the Gaussian-process motion prior of Barfoot et al.): this
// residual and the rate process (markov_process.h) are independent.
//
// Parameter blocks: q_k, q_{k+1} (x, y, z, w; BodyQuaternionManifold), ω_k, ω_{k+1} (rad/s).
#pragma once

#include <ceres/autodiff_cost_function.h>

#include "traverse/core/so3.h"
#include "traverse/smoother/residual_collector.h"

namespace traverse::smoother {

struct AttitudeProcessResidual {
  AttitudeProcessResidual(double dt, const Vec3d& sqrt_info) : dt(dt), sqrt_info(sqrt_info) {}

  template <typename T>
  bool operator()(const T* q_k, const T* q_k1, const T* w_k, const T* w_k1, T* r) const {
    const Eigen::Map<const Quat<T>> qa(q_k), qb(q_k1);
    const Eigen::Map<const Vec3<T>> wa(w_k), wb(w_k1);
    const Vec3<T> e = so3::boxminus(Quat<T>(qb), Quat<T>(qa)) - T(0.5 * dt) * (wa + wb);
    Eigen::Map<Vec3<T>>{r} = sqrt_info.cast<T>().cwiseProduct(e);
    return true;
  }

  /// σ per axis from the rate-noise density q_ω (rad²/s³) and a floor (rad).
  static Vec3d sqrtInfo(double dt, const Vec3d& q_w, double floor_rad) {
    return ((q_w * (dt * dt * dt / 12.0)).array() + floor_rad * floor_rad).rsqrt().matrix();
  }

  static ceres::CostFunction* Create(const AttitudeProcessResidual& f) {
    return new ceres::AutoDiffCostFunction<AttitudeProcessResidual, 3, 4, 4, 3, 3>(
        new AttitudeProcessResidual(f));
  }
  static ceres::CostFunction* Create(double dt, const Vec3d& sqrt_info) {
    return Create(AttitudeProcessResidual(dt, sqrt_info));
  }

  bool operator==(const AttitudeProcessResidual&) const = default;

  double dt;
  Vec3d sqrt_info;
};

/// Constraint (residual_collector.h): the attitude process between nodes k and k + 1, blocks
/// q_k, q_{k+1}, ω_k, ω_{k+1}; sqrt_info from sqrtInfo, or the zero-rate σ over Δt inside a
/// rest window. Consecutive equal ones share a cost function.
inline void addAttitudeProcess(ResidualCollector& out, CostMemo<AttitudeProcessResidual>& memo,
                               double dt, const Vec3d& sqrt_info, const NodeHandles& k,
                               const NodeHandles& k1) {
  out.addShared("attitude", memo, AttitudeProcessResidual(dt, sqrt_info), nullptr, k.q, k1.q, k.w,
                k1.w);
}

}  // namespace traverse::smoother
