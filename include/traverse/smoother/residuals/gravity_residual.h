// At-rest gravity (Nickels' rest mode; K-10 with a = v = ω = 0): roll and pitch from the mean
// specific force of a rest window, one residual per window at the window's middle node,
//
//   r = L⁻¹ wrap(rp_m − h(q)),    h = sensors::gravityRollPitchPredict,  Σ_rp = L Lᵀ
//
// (Σ_rp from sensors::rollPitchAtRest: the accelerometer noise of the window's mean). When the
// segment carries the accelerometer's bias b_a, h = gravityRollPitchPredict(q, b_a, g): the
// window's mean specific force is R(q)ᵀ (0, 0, g) + b_a (GravityBiasResidual).
//
// Parameter blocks: q (x, y, z, w); with the bias also b_a (body, m/s²).
#pragma once

#include <cmath>

#include <ceres/autodiff_cost_function.h>

#include "traverse/sensors/gravity.h"
#include "traverse/smoother/residual_collector.h"
#include "traverse/smoother/residuals/whitening.h"

namespace traverse::smoother {

namespace detail {
inline double scalarPart(double x) {
  return x;
}
template <typename J>
double scalarPart(const J& x) {
  return x.a;
}

/// r = L⁻¹ wrap(rp_m − h): the roll/pitch error wrapped to (−π, π] (the wrap is a constant
/// shift, so it leaves the Jacobian alone), whitened. Shared by both gravity residuals.
template <typename T>
void whitenedRollPitchError(const Vec2d& roll_pitch, const Vec2<T>& h,
                            const Eigen::Matrix2d& sqrt_info, T* r) {
  Vec2<T> e = roll_pitch.cast<T>() - h;
  for (int i = 0; i < 2; ++i) e[i] -= T(2.0 * M_PI * std::round(scalarPart(e[i]) / (2.0 * M_PI)));
  Eigen::Map<Vec2<T>>{r} = sqrt_info.cast<T>() * e;
}
}  // namespace detail

struct GravityResidual {
  GravityResidual(const Vec2d& roll_pitch, const Eigen::Matrix2d& sqrt_info)
      : roll_pitch(roll_pitch), sqrt_info(sqrt_info) {}

  template <typename T>
  bool operator()(const T* q, T* r) const {
    detail::whitenedRollPitchError<T>(
        roll_pitch, sensors::gravityRollPitchPredict<T>(Quat<T>(Eigen::Map<const Quat<T>>(q))),
        sqrt_info, r);
    return true;
  }

  static ceres::CostFunction* Create(const Vec2d& roll_pitch, const Eigen::Matrix2d& sqrt_info) {
    return new ceres::AutoDiffCostFunction<GravityResidual, 2, 4>(
        new GravityResidual(roll_pitch, sqrt_info));
  }

  Vec2d roll_pitch;
  Eigen::Matrix2d sqrt_info;
};

/// The same seen through an accelerometer bias b_a.
struct GravityBiasResidual {
  GravityBiasResidual(const Vec2d& roll_pitch, const Eigen::Matrix2d& sqrt_info,
                      double gravity_mps2)
      : roll_pitch(roll_pitch), sqrt_info(sqrt_info), gravity(gravity_mps2) {}

  template <typename T>
  bool operator()(const T* q, const T* b_a, T* r) const {
    detail::whitenedRollPitchError<T>(
        roll_pitch,
        sensors::gravityRollPitchPredict<T>(Quat<T>(Eigen::Map<const Quat<T>>(q)),
                                            Vec3<T>(Eigen::Map<const Vec3<T>>(b_a)), gravity),
        sqrt_info, r);
    return true;
  }

  static ceres::CostFunction* Create(const Vec2d& roll_pitch, const Eigen::Matrix2d& sqrt_info,
                                     double gravity_mps2) {
    return new ceres::AutoDiffCostFunction<GravityBiasResidual, 2, 4, 3>(
        new GravityBiasResidual(roll_pitch, sqrt_info, gravity_mps2));
  }

  Vec2d roll_pitch;
  Eigen::Matrix2d sqrt_info;
  double gravity;
};

/// Constraint (residual_collector.h): a rest window's roll and pitch at its middle node k,
/// whitened by the measurement's covariance. Block q_k, and the accelerometer bias when the
/// segment has one (k.ba; gravity_mps2 then scales the bias's tilt).
inline void addGravity(ResidualCollector& out, const sensors::RollPitchMeasurement& m,
                       const NodeHandles& k, double gravity_mps2) {
  const Eigen::Matrix2d sqrt_info = sqrtInformation<2>(m.covariance, "gravity");
  if (k.ba.size > 0) {
    out.add("gravity", GravityBiasResidual::Create(m.roll_pitch, sqrt_info, gravity_mps2), nullptr,
            k.q, k.ba);
    return;
  }
  out.add("gravity", GravityResidual::Create(m.roll_pitch, sqrt_info), nullptr, k.q);
}

}  // namespace traverse::smoother
