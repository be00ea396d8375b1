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

#include "traverse/smoother/residual_collector.h"
#include "traverse/smoother/residuals/interpolation.h"
#include "traverse/smoother/residuals/midpoint_attitude_cost.h"

namespace traverse::smoother {

struct PositionProcessResidual {
  PositionProcessResidual(double dt, double sqrt_info) : dt(dt), sqrt_info(sqrt_info) {}

  /// The residual given the midpoint attitude; blocks in the cost function's order (2 and 3,
  /// the attitudes, are not read).
  template <typename T>
  bool atMidpoint(const Quat<T>& q_mid, const T* const* blocks, T* r) const {
    const Eigen::Map<const Vec3<T>> xa(blocks[0]), xb(blocks[1]), va(blocks[4]), vb(blocks[5]);
    const Vec3<T> v_mid = T(0.5) * (va + vb);
    Eigen::Map<Vec3<T>>{r} = T(sqrt_info) * (xb - xa - (q_mid * v_mid) * T(dt));
    return true;
  }

  /// The whole residual in one template (the full-autodiff twin of Create's cost function).
  template <typename T>
  bool operator()(const T* x_k, const T* x_k1, const T* q_k, const T* q_k1, const T* v_k,
                  const T* v_k1, T* r) const {
    const T* blocks[] = {x_k, x_k1, q_k, q_k1, v_k, v_k1};
    return atMidpoint(midpointAttitude(q_k, q_k1), blocks, r);
  }

  static double sqrtInfo(double dt, double q_v, double floor_m) {
    return 1.0 / std::sqrt(q_v * dt * dt * dt / 12.0 + floor_m * floor_m);
  }

  /// Differentiated in two stages (midpoint_attitude_cost.h).
  static ceres::CostFunction* Create(const PositionProcessResidual& f) {
    return new MidpointAttitudeCost<PositionProcessResidual, 3, 2, 3, 3, 3, 4, 4, 3, 3>(f);
  }
  static ceres::CostFunction* Create(double dt, double sqrt_info) {
    return Create(PositionProcessResidual(dt, sqrt_info));
  }
  /// One 20-wide AutoDiffCostFunction over operator() (tests compare the two).
  static ceres::CostFunction* CreateFullAutodiff(double dt, double sqrt_info) {
    return new ceres::AutoDiffCostFunction<PositionProcessResidual, 3, 3, 3, 4, 4, 3, 3>(
        new PositionProcessResidual(dt, sqrt_info));
  }

  bool operator==(const PositionProcessResidual&) const = default;

  double dt, sqrt_info;
};

/// Constraint (residual_collector.h): the position process between nodes k and k + 1, blocks
/// x_k, x_{k+1}, q_k, q_{k+1}, v_k, v_{k+1}; sqrt_info from sqrtInfo, or the zero-velocity σ over
/// Δt inside a rest window. Consecutive equal ones share a cost function.
inline void addPositionProcess(ResidualCollector& out, CostMemo<PositionProcessResidual>& memo,
                               double dt, double sqrt_info, const NodeHandles& k,
                               const NodeHandles& k1) {
  out.addShared("position", memo, PositionProcessResidual(dt, sqrt_info), nullptr, k.x, k1.x, k.q,
                k1.q, k.v, k1.v);
}

}  // namespace traverse::smoother
