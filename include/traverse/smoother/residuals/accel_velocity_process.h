// Accelerometer-driven velocity process (K-11, O-4): the specific force of K-10 solved for the
// body-frame derivative of the body velocity, integrated over one node interval,
//
//   v̇ = ā_m − b_a − (ω̄ × v̄ − R(q̄)ᵀ g_s + ω̄ × (ω̄ × L) + ω̇ × L)  (sensors::velocityRateFromAccel)
//   r = (v_{k+1} − v_k − v̇ Δt) / σ,     σ² = σ_a² T_a Δt + σ_floor²
//
// ā_m is the mean accelerometer reading over [t_k, t_{k+1}], q̄, v̄, ω̄ the interval midpoints,
// ω̇ = (ω_{k+1} − ω_k)/Δt; σ_a² T_a is the white-noise density of readings σ_a every T_a s.
// Through R(q̄)ᵀ g_s this is what keeps roll and pitch observable while driving.
//
// Parameter blocks: q_k, q_{k+1} (x, y, z, w), v_k, v_{k+1} (m/s), ω_k, ω_{k+1} (rad/s), and,
// when the rover declares the accelerometer's bias (with_bias), b_a (body, m/s²); without it
// b_a = 0.
#pragma once

#include <ceres/autodiff_cost_function.h>

#include "traverse/sensors/accelerometer.h"
#include "traverse/smoother/residual_collector.h"
#include "traverse/smoother/residuals/interpolation.h"
#include "traverse/smoother/residuals/midpoint_attitude_cost.h"

namespace traverse::smoother {

struct AccelVelocityProcessResidual {
  AccelVelocityProcessResidual(double dt, const Vec3d& mean_accel_mps2, const Vec3d& lever_arm_m,
                               double gravity_mps2, double sqrt_info, bool with_bias = false)
      : dt(dt),
        accel(mean_accel_mps2),
        lever_arm(lever_arm_m),
        gravity(gravity_mps2),
        sqrt_info(sqrt_info),
        with_bias(with_bias) {}

  /// The residual given the midpoint attitude; blocks in the cost function's order (0 and 1,
  /// the attitudes, are not read; 6, b_a, only with_bias).
  template <typename T>
  bool atMidpoint(const Quat<T>& q_mid, const T* const* blocks, T* r) const {
    const Eigen::Map<const Vec3<T>> va(blocks[2]), vb(blocks[3]), wa(blocks[4]), wb(blocks[5]);
    const Vec3<T> v_mid = T(0.5) * (va + vb), w_mid = T(0.5) * (wa + wb);
    const Vec3<T> w_dot = (wb - wa) / T(dt);
    Vec3<T> a_m = accel.cast<T>();
    if (with_bias) a_m -= Eigen::Map<const Vec3<T>>(blocks[6]);
    const Vec3<T> v_dot =
        sensors::velocityRateFromAccel<T>(a_m, q_mid, v_mid, w_mid, w_dot, lever_arm, gravity);
    Eigen::Map<Vec3<T>>{r} = T(sqrt_info) * (vb - va - v_dot * T(dt));
    return true;
  }

  /// The whole residual in one template (the full-autodiff twin of Create's cost function).
  template <typename T>
  bool operator()(const T* q_k, const T* q_k1, const T* v_k, const T* v_k1, const T* w_k,
                  const T* w_k1, T* r) const {
    const T* blocks[] = {q_k, q_k1, v_k, v_k1, w_k, w_k1, nullptr};
    return atMidpoint(midpointAttitude(q_k, q_k1), blocks, r);
  }
  /// The same with the bias block (with_bias).
  template <typename T>
  bool operator()(const T* q_k, const T* q_k1, const T* v_k, const T* v_k1, const T* w_k,
                  const T* w_k1, const T* b_a, T* r) const {
    const T* blocks[] = {q_k, q_k1, v_k, v_k1, w_k, w_k1, b_a};
    return atMidpoint(midpointAttitude(q_k, q_k1), blocks, r);
  }

  /// Differentiated in two stages (midpoint_attitude_cost.h); seven blocks with_bias.
  static ceres::CostFunction* Create(double dt, const Vec3d& mean_accel_mps2,
                                     const Vec3d& lever_arm_m, double gravity_mps2,
                                     double sqrt_info, bool with_bias = false) {
    const AccelVelocityProcessResidual f(dt, mean_accel_mps2, lever_arm_m, gravity_mps2, sqrt_info,
                                         with_bias);
    if (with_bias)
      return new MidpointAttitudeCost<AccelVelocityProcessResidual, 3, 0, 1, 4, 4, 3, 3, 3, 3, 3>(
          f);
    return new MidpointAttitudeCost<AccelVelocityProcessResidual, 3, 0, 1, 4, 4, 3, 3, 3, 3>(f);
  }
  /// One AutoDiffCostFunction over operator() (20 wide; 23 with_bias; tests compare the two).
  static ceres::CostFunction* CreateFullAutodiff(double dt, const Vec3d& mean_accel_mps2,
                                                 const Vec3d& lever_arm_m, double gravity_mps2,
                                                 double sqrt_info, bool with_bias = false) {
    auto* f = new AccelVelocityProcessResidual(dt, mean_accel_mps2, lever_arm_m, gravity_mps2,
                                               sqrt_info, with_bias);
    if (with_bias)
      return new ceres::AutoDiffCostFunction<AccelVelocityProcessResidual, 3, 4, 4, 3, 3, 3, 3, 3>(
          f);
    return new ceres::AutoDiffCostFunction<AccelVelocityProcessResidual, 3, 4, 4, 3, 3, 3, 3>(f);
  }

  double dt;
  Vec3d accel, lever_arm;
  double gravity, sqrt_info;
  bool with_bias = false;
};

/// Constraint (residual_collector.h): the accelerometer-driven velocity process between nodes k
/// and k + 1, blocks q_k, q_{k+1}, v_k, v_{k+1}, ω_k, ω_{k+1} and the accelerometer bias when
/// the segment has one (k.ba); σ² = q_a Δt + (10⁻⁶)², q_a = σ_a² T_a the readings' white-noise
/// density.
inline void addAccelVelocityProcess(ResidualCollector& out, double dt, const Vec3d& mean_accel_mps2,
                                    const Vec3d& lever_arm_m, double gravity_mps2, double q_a,
                                    const NodeHandles& k, const NodeHandles& k1) {
  const double sqrt_info = 1.0 / std::sqrt(q_a * dt + 1e-12);
  if (k.ba.size > 0) {
    out.add("accel_velocity",
            AccelVelocityProcessResidual::Create(dt, mean_accel_mps2, lever_arm_m, gravity_mps2,
                                                 sqrt_info, true),
            nullptr, k.q, k1.q, k.v, k1.v, k.w, k1.w, k.ba);
    return;
  }
  out.add("accel_velocity",
          AccelVelocityProcessResidual::Create(dt, mean_accel_mps2, lever_arm_m, gravity_mps2,
                                               sqrt_info),
          nullptr, k.q, k1.q, k.v, k1.v, k.w, k1.w);
}

}  // namespace traverse::smoother
