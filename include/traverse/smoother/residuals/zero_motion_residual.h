// At rest the rover neither moves nor turns (rest windows of the segmentation, Nickels):
//
//   zero velocity  r = v / σ_v,        zero rate  r = ω / σ_ω
//
// One functor for both: a 3-vector parameter pulled to zero with a diagonal square-root
// information. Linear, so its Jacobian is the constant diagonal.
//
// Parameter block: v (body, m/s) or ω (body, rad/s).
#pragma once

#include "traverse/core/types.h"
#include "traverse/smoother/residual_collector.h"
#include "traverse/smoother/residuals/analytic_cost.h"

namespace traverse::smoother {

/// The functor (ZeroMotionResidual is its cost function).
class ZeroMotion {
 public:
  explicit ZeroMotion(double sigma) : sqrt_info_(1.0 / sigma) {}

  bool Evaluate(double const* const* parameters, double* residuals, double** jacobians) const {
    Eigen::Map<Vec3d>{residuals} = sqrt_info_ * Eigen::Map<const Vec3d>(parameters[0]);
    if (jacobians && jacobians[0])
      Eigen::Map<Eigen::Matrix<double, 3, 3, Eigen::RowMajor>>{jacobians[0]} =
          sqrt_info_ * Mat3d::Identity();
    return true;
  }

  bool operator==(const ZeroMotion&) const = default;

  static ceres::CostFunction* Create(const ZeroMotion& f) {
    return new AnalyticCost<ZeroMotion, 3, 3>(f);
  }

 private:
  double sqrt_info_;
};

using ZeroMotionResidual = AnalyticCost<ZeroMotion, 3, 3>;

/// Constraint (residual_collector.h): zero velocity and zero rate at node k, σ_v and σ_ω.
/// Blocks v_k and ω_k; consecutive equal ones share a cost function.
inline void addZeroMotion(ResidualCollector& out, CostMemo<ZeroMotion>& velocity_memo,
                          CostMemo<ZeroMotion>& rate_memo, double sigma_v, double sigma_w,
                          const NodeHandles& k) {
  out.addShared("zero_velocity", velocity_memo, ZeroMotion(sigma_v), nullptr, k.v);
  out.addShared("zero_rate", rate_memo, ZeroMotion(sigma_w), nullptr, k.w);
}

}  // namespace traverse::smoother
