// At rest the rover neither moves nor turns (rest windows of the segmentation, Nickels):
//
//   zero velocity  r = v / σ_v,        zero rate  r = ω / σ_ω
//
// One functor for both: a 3-vector parameter pulled to zero with a diagonal square-root
// information. Linear, so its Jacobian is the constant diagonal.
//
// Parameter block: v (body, m/s) or ω (body, rad/s).
#pragma once

#include <ceres/sized_cost_function.h>

#include "traverse/core/types.h"

namespace traverse::smoother {

class ZeroMotionResidual final : public ceres::SizedCostFunction<3, 3> {
 public:
  explicit ZeroMotionResidual(double sigma) : sqrt_info_(1.0 / sigma) {}

  bool Evaluate(double const* const* parameters, double* residuals,
                double** jacobians) const override {
    Eigen::Map<Vec3d>{residuals} = sqrt_info_ * Eigen::Map<const Vec3d>(parameters[0]);
    if (jacobians && jacobians[0])
      Eigen::Map<Eigen::Matrix<double, 3, 3, Eigen::RowMajor>>{jacobians[0]} =
          sqrt_info_ * Mat3d::Identity();
    return true;
  }

 private:
  double sqrt_info_;
};

}  // namespace traverse::smoother
