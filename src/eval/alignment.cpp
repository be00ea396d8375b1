#include "traverse/eval/alignment.h"

#include <cmath>
#include <stdexcept>

namespace traverse::eval {

Vec3d PosYawAlignment::apply(const Vec3d& p) const {
  return Eigen::AngleAxisd(yaw, Vec3d::UnitZ()) * p + translation;
}

PosYawAlignment alignPosYaw(const std::vector<Vec3d>& estimate, const std::vector<Vec3d>& truth) {
  if (estimate.empty() || estimate.size() != truth.size()) {
    throw std::invalid_argument("alignPosYaw: need equally many (> 0) estimate and truth points");
  }
  const double n = static_cast<double>(estimate.size());
  Vec3d mean_est = Vec3d::Zero(), mean_true = Vec3d::Zero();
  for (std::size_t k = 0; k < estimate.size(); ++k) {
    mean_est += estimate[k];
    mean_true += truth[k];
  }
  mean_est /= n;
  mean_true /= n;
  // Σ b·Rz(ψ)a = cos ψ Σ (a_x b_x + a_y b_y) + sin ψ Σ (a_x b_y − a_y b_x) (+ ψ-free z terms).
  double c = 0.0, s = 0.0;
  for (std::size_t k = 0; k < estimate.size(); ++k) {
    const Vec3d a = estimate[k] - mean_est, b = truth[k] - mean_true;
    c += a.x() * b.x() + a.y() * b.y();
    s += a.x() * b.y() - a.y() * b.x();
  }
  PosYawAlignment out;
  out.yaw = (c == 0.0 && s == 0.0) ? 0.0 : std::atan2(s, c);
  out.translation = mean_true - Eigen::AngleAxisd(out.yaw, Vec3d::UnitZ()) * mean_est;
  return out;
}

double absoluteTrajectoryErrorPosYaw(const std::vector<Vec3d>& estimate,
                                     const std::vector<Vec3d>& truth) {
  const PosYawAlignment align = alignPosYaw(estimate, truth);
  double sum_sq = 0.0;
  for (std::size_t k = 0; k < estimate.size(); ++k) {
    sum_sq += (align.apply(estimate[k]) - truth[k]).squaredNorm();
  }
  return std::sqrt(sum_sq / static_cast<double>(estimate.size()));
}

}  // namespace traverse::eval
