// First-order Gauss-Markov process between consecutive nodes, per component i:
//
//   ẏ_i = a_i (y_i − m_i(t)) + n_i,  E[n_i n_i] = q_i δ(t)           (continuous)
//   r_i = (y_{k+1,i} − m_{k+1,i} − φ_i (y_{k,i} − m_{k,i})) / σ_i,   φ_i = exp(a_i Δt),
//   σ_i² = q_i (1 − φ_i²) / (−2 a_i)   (→ q_i Δt as a_i → 0: a random walk)
//
// One functor, four processes of the papers:
//   - K-1 / K-2: velocity and rate perturbations v_p = v − v_c, ω_p = ω − ω_c around the
//     commanded twist m = (v_c, ω_c), decaying with the time constants of rover.yaml (random
//     walks, a = 0, when the log has no cmd.csv — K §4.2);
//   - K-8: contact angles ξ, m = 0, returning toward 0;
//   - K-9: gyro bias random walk, a = 0, m = 0.
// The residual is linear in (y_k, y_{k+1}): the Jacobians are the constant diagonals
// −φ/σ and 1/σ, written out instead of differentiated.
#pragma once

#include <cmath>

#include <ceres/sized_cost_function.h>

#include "traverse/core/types.h"

namespace traverse::smoother {

template <int N>
class MarkovProcessResidual final : public ceres::SizedCostFunction<N, N, N> {
 public:
  using VecN = Eigen::Matrix<double, N, 1>;

  /// a: rates (1/s, ≤ 0), q: noise densities (units² / s), means at both nodes.
  MarkovProcessResidual(double dt, const VecN& a, const VecN& q, const VecN& mean_k,
                        const VecN& mean_k1)
      : mean_k_(mean_k), mean_k1_(mean_k1) {
    for (int i = 0; i < N; ++i) {
      phi_[i] = std::exp(a[i] * dt);
      const double var = a[i] < 0 ? q[i] * -std::expm1(2.0 * a[i] * dt) / (-2.0 * a[i]) : q[i] * dt;
      sqrt_info_[i] = 1.0 / std::sqrt(var);
    }
  }

  bool Evaluate(double const* const* parameters, double* residuals,
                double** jacobians) const override {
    const Eigen::Map<const VecN> y_k(parameters[0]), y_k1(parameters[1]);
    Eigen::Map<VecN>{residuals} =
        sqrt_info_.cwiseProduct((y_k1 - mean_k1_) - phi_.cwiseProduct(y_k - mean_k_));
    if (jacobians) {
      using RowMajorN = Eigen::Matrix<double, N, N, N == 1 ? Eigen::ColMajor : Eigen::RowMajor>;
      if (jacobians[0])
        Eigen::Map<RowMajorN>{jacobians[0]} = (-sqrt_info_.cwiseProduct(phi_)).asDiagonal();
      if (jacobians[1]) Eigen::Map<RowMajorN>{jacobians[1]} = sqrt_info_.asDiagonal();
    }
    return true;
  }

  const VecN& sqrtInformation() const { return sqrt_info_; }
  const VecN& phi() const { return phi_; }

 private:
  VecN mean_k_, mean_k1_, phi_, sqrt_info_;
};

}  // namespace traverse::smoother

namespace traverse::smoother {

/// The process's stationary distribution at a segment's first node (e.g. K-8's contact angles,
/// ξ ~ N(0, q τ / 2)): r = y / σ. Without it a contact angle no wheel constrains would be
/// unobservable.
template <int N>
class StationaryPriorResidual final : public ceres::SizedCostFunction<N, N> {
 public:
  using VecN = Eigen::Matrix<double, N, 1>;
  explicit StationaryPriorResidual(const VecN& sigma) : sqrt_info_(sigma.cwiseInverse()) {}

  bool Evaluate(double const* const* parameters, double* residuals,
                double** jacobians) const override {
    Eigen::Map<VecN>{residuals} = sqrt_info_.cwiseProduct(Eigen::Map<const VecN>(parameters[0]));
    if (jacobians && jacobians[0]) {
      using RowMajorN = Eigen::Matrix<double, N, N, N == 1 ? Eigen::ColMajor : Eigen::RowMajor>;
      Eigen::Map<RowMajorN>{jacobians[0]} = sqrt_info_.asDiagonal();
    }
    return true;
  }

 private:
  VecN sqrt_info_;
};

}  // namespace traverse::smoother
