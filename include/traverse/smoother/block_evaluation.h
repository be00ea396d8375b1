// One residual block evaluated as Ceres' Problem::EvaluateResidualBlock(id, apply_loss = true)
// evaluates it — cost ½ρ(‖r‖²), residuals and Jacobians passed through the robust loss's
// corrector, Jacobians in each parameter block's tangent space — but from the cost function,
// loss and manifolds directly, without the Problem.
//
// Why: the smoother evaluates every block of a segment twice before the solve (the seed's cost)
// and once after it (the covariance's JᵀJ). Through the Problem each call allocates its scratch,
// walks the block's parameter objects and copies states; at 10 000 nodes (172 000 blocks) that
// was a third of the covariance's time and grew faster than the node count. Here the scratch is
// reused and nothing is looked up.
//
// The loss correction is Ceres' (internal/ceres/corrector.cc, Triggs et al. 1999 §3.3): with
// s = ‖r‖² and ρ', ρ'' at s,
//   α = 1 − √(1 + 2 s ρ''/ρ')  when s > 0 and ρ'' > 0, else α = 0;
//   r̃ = √ρ' / (1 − α) · r,      J̃ = √ρ' (I − α r rᵀ / s) J,
// so that ½‖r̃ + J̃ δ‖² is the second-order model of ½ρ(‖r + J δ‖²) that the solver minimises.
// Parameter-block storage is the cost function's own: a quaternion block is (x, y, z, w) for
// BodyQuaternionManifold; tangent Jacobians are row-major rows × TangentSize.
#pragma once

#include <span>
#include <vector>

#include <ceres/cost_function.h>
#include <ceres/loss_function.h>
#include <ceres/manifold.h>

namespace traverse::smoother {

class BlockEvaluator {
 public:
  /// Evaluates f at `blocks` (f's parameter blocks in order). `manifolds[i]` is block i's
  /// manifold or nullptr (Euclidean); `loss` may be nullptr. `cost` and `residuals`
  /// (f.num_residuals()) may be nullptr; `jacobians` nullptr, or one pointer per block, each
  /// nullptr or a row-major num_residuals × tangent-size buffer. False if the cost function
  /// fails or anything it returns is not finite.
  bool evaluate(const ceres::CostFunction& f, const ceres::LossFunction* loss,
                std::span<double* const> blocks, std::span<const ceres::Manifold* const> manifolds,
                double* cost, double* residuals, double* const* jacobians);

 private:
  std::vector<double> residuals_, ambient_, plus_jacobian_;
  std::vector<double*> ambient_ptrs_;
};

}  // namespace traverse::smoother
