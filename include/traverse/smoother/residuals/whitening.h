// Square-root information: for a residual r with covariance Σ = L Lᵀ, the whitened residual
// L⁻¹ r has identity covariance and ‖L⁻¹ r‖² = rᵀ Σ⁻¹ r. Every residual functor stores its
// L⁻¹ (or a diagonal 1/σ) and applies it inside operator().
#pragma once

#include <stdexcept>
#include <string>

#include <Eigen/Cholesky>

#include "traverse/core/error.h"

namespace traverse::smoother {

/// L⁻¹ with Σ = L Lᵀ (lower-triangular Cholesky). Throws if Σ is not positive definite.
template <int N>
Eigen::Matrix<double, N, N> sqrtInformation(const Eigen::Matrix<double, N, N>& covariance,
                                            const char* what) {
  const Eigen::LLT<Eigen::Matrix<double, N, N>> llt(covariance);
  if (llt.info() != Eigen::Success)
    throw NumericalError(std::string(what) + ": covariance is not positive definite");
  return llt.matrixL().solve(Eigen::Matrix<double, N, N>::Identity());
}

}  // namespace traverse::smoother
