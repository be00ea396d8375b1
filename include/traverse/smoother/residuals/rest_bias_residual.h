// At-rest gyro bias (K-12 with ω = 0; Nickels' drift filter): over a rest window each reading
// is bias plus white noise, so the window's N readings on a measured axis a give
//
//   r_a = (b_a − m_a) / (σ_g / √N),    m_a = mean reading over the window
//
// — the same information as the N per-reading residuals it replaces (those readings are not
// also used by the gyro increments). Unmeasured axes give a zero row.
//
// Parameter block: b (rad/s, body axes).
#pragma once

#include <ceres/sized_cost_function.h>

#include <algorithm>

#include "traverse/core/types.h"
#include "traverse/smoother/residual_collector.h"

namespace traverse::smoother {

class RestBiasResidual final : public ceres::SizedCostFunction<3, 3> {
 public:
  /// sqrt_info: √N/σ_g on measured axes, 0 on the others.
  RestBiasResidual(const Vec3d& mean_reading_rad_s, const Vec3d& sqrt_info)
      : mean_(mean_reading_rad_s), sqrt_info_(sqrt_info) {}

  bool Evaluate(double const* const* parameters, double* residuals,
                double** jacobians) const override {
    Eigen::Map<Vec3d>{residuals} =
        sqrt_info_.cwiseProduct(Eigen::Map<const Vec3d>(parameters[0]) - mean_);
    if (jacobians && jacobians[0])
      Eigen::Map<Eigen::Matrix<double, 3, 3, Eigen::RowMajor>>{jacobians[0]} =
          sqrt_info_.asDiagonal();
    return true;
  }

 private:
  Vec3d mean_, sqrt_info_;
};

/// Constraint (residual_collector.h): a rest window's mean gyro reading over `duration` s of
/// readings of noise σ_g every T_g s, on the measured axes (`axes`: 1 measured, 0 not): σ = σ_g
/// √(T_g / duration). Block: the bias node k's residuals use (k the window's middle node).
inline void addRestBias(ResidualCollector& out, const Vec3d& mean_reading_rad_s, double noise,
                        double period, double duration, const Vec3d& axes, const NodeHandles& k) {
  const double sigma = noise * std::sqrt(period / duration);
  out.add("rest_bias", new RestBiasResidual(mean_reading_rad_s, axes / sigma), nullptr, k.bias);
}

/// Constraint: a prior on the bias node k's residuals use — the EKF's estimate and σ (floored at
/// 10⁻⁶ rad/s), for a segment without a rest window.
inline void addBiasPrior(ResidualCollector& out, const Vec3d& bias, const Vec3d& sigma,
                         const NodeHandles& k) {
  const Vec3d s = sigma.cwiseMax(1e-6);
  out.add("bias_prior", new RestBiasResidual(bias, s.cwiseInverse()), nullptr, k.bias);
}

/// Constraint: a prior on the segment's accelerometer bias (k.ba, same form: RestBiasResidual
/// is a diagonal Gaussian on a 3-vector) — the EKF's estimate at the segment's first node with
/// its σ (floored at 10⁻⁶ m/s²).
inline void addAccelBiasPrior(ResidualCollector& out, const Vec3d& accel_bias, const Vec3d& sigma,
                              const NodeHandles& k) {
  const Vec3d s = sigma.cwiseMax(1e-6);
  out.add("accel_bias_prior", new RestBiasResidual(accel_bias, s.cwiseInverse()), nullptr, k.ba);
}

/// A Gaussian prior on one scalar parameter: r = (x − mean) / σ.
class ScalarPriorResidual final : public ceres::SizedCostFunction<1, 1> {
 public:
  ScalarPriorResidual(double mean, double sigma) : mean_(mean), info_(1.0 / sigma) {}
  bool Evaluate(double const* const* parameters, double* residuals,
                double** jacobians) const override {
    residuals[0] = info_ * (parameters[0][0] - mean_);
    if (jacobians && jacobians[0]) jacobians[0][0] = info_;
    return true;
  }

 private:
  double mean_, info_;
};

/// Constraint: a prior on the segment's ICR half-track error δ (k.icr, io::SkidSteerConfig) —
/// the EKF's estimate at the segment's first node with its σ (floored at 10⁻⁶ m).
inline void addIcrPrior(ResidualCollector& out, double icr, double sigma, const NodeHandles& k) {
  out.add("icr_prior", new ScalarPriorResidual(icr, std::max(sigma, 1e-6)), nullptr, k.icr);
}

}  // namespace traverse::smoother
