// At-rest gravity (Nickels' rest mode; K-10 with a = v = ω = 0): roll and pitch from the mean
// specific force of a rest window, one residual per window at the window's middle node,
//
//   r = L⁻¹ wrap(rp_m − h(q)),    h = sensors::gravityRollPitchPredict,  Σ_rp = L Lᵀ
//
// (Σ_rp from sensors::rollPitchAtRest: the accelerometer noise of the window's mean).
//
// Parameter block: q (x, y, z, w).
#pragma once

#include <cmath>

#include <ceres/autodiff_cost_function.h>

#include "traverse/sensors/gravity.h"
#include "traverse/smoother/residual_collector.h"
#include "traverse/smoother/residuals/whitening.h"

namespace traverse::smoother {

struct GravityResidual {
  GravityResidual(const Vec2d& roll_pitch, const Eigen::Matrix2d& sqrt_info)
      : roll_pitch(roll_pitch), sqrt_info(sqrt_info) {}

  template <typename T>
  bool operator()(const T* q, T* r) const {
    const Vec2<T> h = sensors::gravityRollPitchPredict<T>(Quat<T>(Eigen::Map<const Quat<T>>(q)));
    Vec2<T> e = roll_pitch.cast<T>() - h;
    for (int i = 0; i < 2; ++i) e[i] -= T(2.0 * M_PI * std::round(scalar(e[i]) / (2.0 * M_PI)));
    Eigen::Map<Vec2<T>>{r} = sqrt_info.cast<T>() * e;
    return true;
  }

  static ceres::CostFunction* Create(const Vec2d& roll_pitch, const Eigen::Matrix2d& sqrt_info) {
    return new ceres::AutoDiffCostFunction<GravityResidual, 2, 4>(
        new GravityResidual(roll_pitch, sqrt_info));
  }

  static double scalar(double x) { return x; }
  template <typename J>
  static double scalar(const J& x) {
    return x.a;
  }

  Vec2d roll_pitch;
  Eigen::Matrix2d sqrt_info;
};

/// Constraint (residual_collector.h): a rest window's roll and pitch at its middle node k,
/// whitened by the measurement's covariance. Block q_k.
inline void addGravity(ResidualCollector& out, const sensors::RollPitchMeasurement& m,
                       const NodeHandles& k) {
  out.add("gravity",
          GravityResidual::Create(m.roll_pitch, sqrtInformation<2>(m.covariance, "gravity")),
          nullptr, k.q);
}

}  // namespace traverse::smoother
