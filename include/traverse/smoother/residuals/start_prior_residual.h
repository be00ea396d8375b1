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
#include "traverse/smoother/residual_collector.h"
#include "traverse/smoother/residuals/whitening.h"

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

/// Constraint (residual_collector.h): the start prior at node k, position σ `position_sigma` per
/// axis (the gauge anchor) and the attitude covariance `attitude_cov` (body δθ; 10⁻¹² added to
/// its diagonal). Blocks q_k, x_k.
inline void addStartPrior(ResidualCollector& out, const Quatd& q_prior, const Vec3d& x_prior,
                          double position_sigma, const Mat3d& attitude_cov, const NodeHandles& k) {
  Mat6d cov = Mat6d::Zero();
  cov.topLeftCorner<3, 3>() = Mat3d::Identity() * position_sigma * position_sigma;
  cov.bottomRightCorner<3, 3>() = attitude_cov;
  cov.bottomRightCorner<3, 3>().diagonal().array() += 1e-12;
  out.add("start_prior",
          StartPriorResidual::Create(q_prior, x_prior, sqrtInformation<6>(cov, "start prior")),
          nullptr, k.q, k.x);
}

}  // namespace traverse::smoother
