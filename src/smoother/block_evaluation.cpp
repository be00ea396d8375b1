// include/traverse/smoother/block_evaluation.h
#include "traverse/smoother/block_evaluation.h"

#include <cmath>
#include <stdexcept>

#include <Eigen/Core>

namespace traverse::smoother {

namespace {

using RowMajor = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

bool allFinite(const double* v, size_t n) {
  for (size_t i = 0; i < n; ++i)
    if (!std::isfinite(v[i])) return false;
  return true;
}

}  // namespace

bool BlockEvaluator::evaluate(const ceres::CostFunction& f, const ceres::LossFunction* loss,
                              std::span<double* const> blocks,
                              std::span<const ceres::Manifold* const> manifolds, double* cost,
                              double* residuals, double* const* jacobians) {
  const std::vector<int32_t>& sizes = f.parameter_block_sizes();
  if (blocks.size() != sizes.size() || manifolds.size() != sizes.size())
    throw std::invalid_argument("BlockEvaluator: one parameter block and manifold per block");
  const int rows = f.num_residuals();
  residuals_.resize(static_cast<size_t>(rows));
  double* r = residuals ? residuals : residuals_.data();
  // Ambient Jacobians first, where a block has a manifold (then projected onto its tangent);
  // straight into the caller's buffer where it has none.
  ambient_ptrs_.assign(sizes.size(), nullptr);
  size_t ambient_total = 0;
  if (jacobians) {
    for (size_t i = 0; i < sizes.size(); ++i)
      if (jacobians[i] && manifolds[i]) ambient_total += static_cast<size_t>(rows * sizes[i]);
    ambient_.resize(ambient_total);
    for (size_t i = 0, offset = 0; i < sizes.size(); ++i) {
      if (!jacobians[i]) continue;
      if (manifolds[i]) {
        ambient_ptrs_[i] = ambient_.data() + offset;
        offset += static_cast<size_t>(rows * sizes[i]);
      } else {
        ambient_ptrs_[i] = jacobians[i];
      }
    }
  }
  if (!f.Evaluate(blocks.data(), r, jacobians ? ambient_ptrs_.data() : nullptr)) return false;
  if (!allFinite(r, static_cast<size_t>(rows))) return false;
  if (jacobians) {
    for (size_t i = 0; i < sizes.size(); ++i) {
      if (!jacobians[i]) continue;
      const int tangent = manifolds[i] ? manifolds[i]->TangentSize() : sizes[i];
      if (manifolds[i]) {
        plus_jacobian_.resize(static_cast<size_t>(sizes[i] * tangent));
        if (!manifolds[i]->PlusJacobian(blocks[i], plus_jacobian_.data())) return false;
        Eigen::Map<RowMajor>(jacobians[i], rows, tangent) =
            Eigen::Map<const RowMajor>(ambient_ptrs_[i], rows, sizes[i]) *
            Eigen::Map<const RowMajor>(plus_jacobian_.data(), sizes[i], tangent);
      }
      if (!allFinite(jacobians[i], static_cast<size_t>(rows * tangent))) return false;
    }
  }
  Eigen::Map<Eigen::VectorXd> rv(r, rows);
  const double s = rv.squaredNorm();
  if (!loss) {
    if (cost) *cost = 0.5 * s;
    return true;
  }
  double rho[3];
  loss->Evaluate(s, rho);
  if (cost) *cost = 0.5 * rho[0];
  if (!std::isfinite(rho[0])) return false;
  // Ceres' Corrector (header comment).
  const double sqrt_rho1 = std::sqrt(rho[1]);
  double residual_scaling = sqrt_rho1, alpha_sq_norm = 0.0;
  if (s > 0.0 && rho[2] > 0.0) {
    const double alpha = 1.0 - std::sqrt(1.0 + 2.0 * s * rho[2] / rho[1]);
    residual_scaling = sqrt_rho1 / (1.0 - alpha);
    alpha_sq_norm = alpha / s;
  }
  if (jacobians) {
    for (size_t i = 0; i < sizes.size(); ++i) {
      if (!jacobians[i]) continue;
      const int tangent = manifolds[i] ? manifolds[i]->TangentSize() : sizes[i];
      Eigen::Map<RowMajor> J(jacobians[i], rows, tangent);
      if (alpha_sq_norm != 0.0) {
        const Eigen::RowVectorXd rtJ = rv.transpose() * J;
        J -= alpha_sq_norm * rv * rtJ;
      }
      J *= sqrt_rho1;
    }
  }
  if (residuals) rv *= residual_scaling;
  return true;
}

}  // namespace traverse::smoother
