// Gyro (K-12, K-13) integrated over one node interval — the gyro drives the attitude on the
// axes it measures (O-1's hybrid model, the EKF's default):
//
//   Δθ_g = ∫ ω_m dt over [t_k, t_{k+1}]   (readings interpolated linearly)
//   r_a  = (e_aᵀ Log(q_k⁻¹ ⊗ q_{k+1}) − (Δθ_g,a − b_a Δt)) / σ_a   for each measured axis a
//          (B_g of K-13 selects them; unmeasured axes give a zero row),
//   σ_a² = σ_g² T_g Δt   (readings with white noise σ_g every T_g seconds)
//
// The integrated form uses every reading once, whatever the ratio of gyro to node rate.
// Log(q_k⁻¹ q_{k+1}) = ∫ ω dt holds to first order in the interval's rotation (the rotation
// over one node interval of a rover is a fraction of a degree).
//
// Parameter blocks: q_k, q_{k+1} (x, y, z, w), b (rad/s, body axes).
#pragma once

#include <ceres/autodiff_cost_function.h>

#include "traverse/core/so3.h"
#include "traverse/smoother/residual_collector.h"

namespace traverse::smoother {

struct GyroIncrementResidual {
  /// sqrt_info per axis: 1/σ_a on measured axes, 0 on the others.
  GyroIncrementResidual(double dt, const Vec3d& increment_rad, const Vec3d& sqrt_info)
      : dt(dt), increment(increment_rad), sqrt_info(sqrt_info) {}

  template <typename T>
  bool operator()(const T* q_k, const T* q_k1, const T* b, T* r) const {
    const Eigen::Map<const Quat<T>> qa(q_k), qb(q_k1);
    const Eigen::Map<const Vec3<T>> bias(b);
    const Vec3<T> e =
        so3::boxminus(Quat<T>(qb), Quat<T>(qa)) - (increment.cast<T>() - bias * T(dt));
    Eigen::Map<Vec3<T>>{r} = sqrt_info.cast<T>().cwiseProduct(e);
    return true;
  }

  static ceres::CostFunction* Create(double dt, const Vec3d& increment_rad,
                                     const Vec3d& sqrt_info) {
    return new ceres::AutoDiffCostFunction<GyroIncrementResidual, 3, 4, 4, 3>(
        new GyroIncrementResidual(dt, increment_rad, sqrt_info));
  }

  double dt;
  Vec3d increment, sqrt_info;
};

/// Constraint (residual_collector.h): the gyro increment between nodes k and k + 1, readings of
/// noise σ_g every T_g s on the measured axes (`axes`: 1 measured, 0 not). Blocks q_k, q_{k+1} and
/// the bias node k's residuals use.
inline void addGyroIncrement(ResidualCollector& out, double dt, const Vec3d& increment_rad,
                             double noise, double period, const Vec3d& axes, const NodeHandles& k,
                             const NodeHandles& k1) {
  const double sigma = noise * std::sqrt(period * dt);
  out.add("gyro", GyroIncrementResidual::Create(dt, increment_rad, axes / sigma), nullptr, k.q,
          k1.q, k.bias);
}

}  // namespace traverse::smoother
