// Segment start prior: the pose at the segment's first node, from the EKF that seeds it, with
// its covariance. It anchors the gauge (nothing else in a segment sees absolute position, and
// without the sun nothing sees absolute yaw):
//
//   r = L⁻¹ [x − x̄; Log(q̄⁻¹ ⊗ q)],     Σ = L Lᵀ over [δp_site; δθ_body] (6×6)
//
// Parameter blocks: q (x, y, z, w), x (site, m).
#pragma once

#include <ceres/autodiff_cost_function.h>

#include "traverse/core/so3.h"

namespace traverse::smoother {

struct StartPriorResidual {
  StartPriorResidual(const Quatd& q_prior, const Vec3d& x_prior, const Mat6d& sqrt_info)
      : q_prior(q_prior), x_prior(x_prior), sqrt_info(sqrt_info) {}

  template <typename T>
  bool operator()(const T* q, const T* x, T* r) const {
    Vec6<T> e;
    e.template head<3>() = Eigen::Map<const Vec3<T>>(x) - x_prior.cast<T>();
    e.template tail<3>() =
        so3::boxminus(Quat<T>(Eigen::Map<const Quat<T>>(q)), Quat<T>(q_prior.cast<T>()));
    Eigen::Map<Vec6<T>>{r} = sqrt_info.cast<T>() * e;
    return true;
  }

  static ceres::CostFunction* Create(const Quatd& q_prior, const Vec3d& x_prior,
                                     const Mat6d& sqrt_info) {
    return new ceres::AutoDiffCostFunction<StartPriorResidual, 6, 4, 3>(
        new StartPriorResidual(q_prior, x_prior, sqrt_info));
  }

  Quatd q_prior;
  Vec3d x_prior;
  Mat6d sqrt_info;
};

}  // namespace traverse::smoother
