// 4-DoF (position + yaw) alignment of an estimated trajectory to truth, the "posyaw" alignment
// of OpenVINS ov_eval for ground vehicles: gravity makes roll and pitch observable, so only a
// translation and a rotation about the vertical are free.
//
// Closed form (Umeyama restricted to rotations about z): with centred points
// a_k = p̂_k − mean(p̂), b_k = p_k − mean(p), the yaw ψ maximising Σ b_kᵀ Rz(ψ) a_k is
//   ψ = atan2(Σ (a_x b_y − a_y b_x), Σ (a_x b_x + a_y b_y)),
// and the translation is t = mean(p) − Rz(ψ) mean(p̂).
#pragma once

#include <vector>

#include "traverse/core/types.h"

namespace traverse::eval {

struct PosYawAlignment {
  double yaw = 0.0;                   ///< ψ, rad
  Vec3d translation = Vec3d::Zero();  ///< t, m
  /// The aligned point Rz(ψ) p + t.
  Vec3d apply(const Vec3d& p) const;
};

/// The alignment minimising Σ ‖Rz(ψ) estimate_k + t − truth_k‖². Throws std::invalid_argument
/// if the sizes differ or are zero. With degenerate geometry (all points on one vertical line)
/// ψ = 0.
PosYawAlignment alignPosYaw(const std::vector<Vec3d>& estimate, const std::vector<Vec3d>& truth);

/// The alignment minimising Σ_k w_h,k ‖(Rz(ψ) estimate_k + t − truth_k)_xy‖² +
/// w_z,k ((estimate_k + t − truth_k)_z)²: the closed form above with weighted means and sums
/// (ψ and t_xy from the horizontal weights; t_z the w_z-weighted mean height difference). Throws
/// std::invalid_argument on unequal or zero sizes, a negative weight or zero total weight.
PosYawAlignment alignPosYawWeighted(const std::vector<Vec3d>& estimate,
                                    const std::vector<Vec3d>& truth, const std::vector<double>& w_h,
                                    const std::vector<double>& w_z);

/// A posyaw alignment robust to truth outliers, against truth points with a 1σ each
/// (σ_x, σ_y, σ_z; horizontal σ_h = √((σ_x² + σ_y²)/2)). Iteratively reweighted least squares:
/// weights w_h = h(r_h / s_h) / σ_h², w_z = h(r_z / s_z) / σ_z² with the normalised residuals
/// r_h = ‖e_xy‖/σ_h, r_z = |e_z|/σ_z, Huber's h(u) = min(1, k/u), and scales
/// s_h = max(1, median(r_h) / 1.1774), s_z = max(1, median(r_z) / 0.6745) (the medians of a
/// 2-D Rayleigh and a 1-D half-normal): while the residuals are what σ says, a point counts by
/// its σ and only points beyond k σ are down-weighted; when the estimate's own error dominates
/// (a drifting dead reckoning against cm-level fixes) the scale follows the typical residual, so
/// only points far beyond the rest lose weight.
struct RobustPosYawAlignment {
  PosYawAlignment alignment;
  std::vector<double> r_h, r_z;  ///< normalised residuals after the final alignment
  double s_h = 1.0, s_z = 1.0;   ///< the final scales
  int iterations = 0;
  /// A point whose residual is beyond `threshold` scaled σ, horizontally or vertically.
  bool outlier(std::size_t k, double threshold) const {
    return r_h[k] > threshold * s_h || r_z[k] > threshold * s_z;
  }
};
/// Points with use[k] = false take no part (their residuals are still reported). Throws
/// std::invalid_argument like alignPosYawWeighted, or when a σ is not positive.
RobustPosYawAlignment alignPosYawRobust(const std::vector<Vec3d>& estimate,
                                        const std::vector<Vec3d>& truth,
                                        const std::vector<Vec3d>& sigma,
                                        const std::vector<bool>& use, double huber_k = 3.0,
                                        int max_iterations = 50);

/// ATE: sqrt(mean ‖Rz(ψ) estimate_k + t − truth_k‖²) after alignPosYaw, m.
double absoluteTrajectoryErrorPosYaw(const std::vector<Vec3d>& estimate,
                                     const std::vector<Vec3d>& truth);

}  // namespace traverse::eval
