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

/// ATE: sqrt(mean ‖Rz(ψ) estimate_k + t − truth_k‖²) after alignPosYaw, m.
double absoluteTrajectoryErrorPosYaw(const std::vector<Vec3d>& estimate,
                                     const std::vector<Vec3d>& truth);

}  // namespace traverse::eval
