#include "traverse/eval/alignment.h"

#include <algorithm>
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

namespace traverse::eval {
namespace {

double median(std::vector<double> v) {
  if (v.empty()) return 0.0;
  const auto mid = v.begin() + static_cast<long>(v.size() / 2);
  std::nth_element(v.begin(), mid, v.end());
  if (v.size() % 2 == 1) return *mid;
  return 0.5 * (*mid + *std::max_element(v.begin(), mid));
}

double huber(double u, double k) {
  return u <= k ? 1.0 : k / u;
}

}  // namespace

PosYawAlignment alignPosYawWeighted(const std::vector<Vec3d>& estimate,
                                    const std::vector<Vec3d>& truth, const std::vector<double>& w_h,
                                    const std::vector<double>& w_z) {
  const std::size_t n = estimate.size();
  if (n == 0 || truth.size() != n || w_h.size() != n || w_z.size() != n) {
    throw std::invalid_argument("alignPosYawWeighted: need equally many (> 0) points and weights");
  }
  double sum_h = 0.0, sum_z = 0.0, dz = 0.0;
  Eigen::Vector2d mean_est = Eigen::Vector2d::Zero(), mean_true = Eigen::Vector2d::Zero();
  for (std::size_t k = 0; k < n; ++k) {
    if (!(w_h[k] >= 0.0) || !(w_z[k] >= 0.0))
      throw std::invalid_argument("alignPosYawWeighted: weights must be >= 0");
    sum_h += w_h[k], sum_z += w_z[k];
    mean_est += w_h[k] * estimate[k].head<2>();
    mean_true += w_h[k] * truth[k].head<2>();
    dz += w_z[k] * (truth[k].z() - estimate[k].z());
  }
  if (!(sum_h > 0.0) || !(sum_z > 0.0))
    throw std::invalid_argument("alignPosYawWeighted: zero total weight");
  mean_est /= sum_h, mean_true /= sum_h;
  double c = 0.0, s = 0.0;
  for (std::size_t k = 0; k < n; ++k) {
    const Eigen::Vector2d a = estimate[k].head<2>() - mean_est, b = truth[k].head<2>() - mean_true;
    c += w_h[k] * (a.x() * b.x() + a.y() * b.y());
    s += w_h[k] * (a.x() * b.y() - a.y() * b.x());
  }
  PosYawAlignment out;
  out.yaw = (c == 0.0 && s == 0.0) ? 0.0 : std::atan2(s, c);
  const Eigen::Vector2d t_xy = mean_true - Eigen::Rotation2Dd(out.yaw) * mean_est;
  out.translation = Vec3d(t_xy.x(), t_xy.y(), dz / sum_z);
  return out;
}

RobustPosYawAlignment alignPosYawRobust(const std::vector<Vec3d>& estimate,
                                        const std::vector<Vec3d>& truth,
                                        const std::vector<Vec3d>& sigma,
                                        const std::vector<bool>& use, double huber_k,
                                        int max_iterations) {
  const std::size_t n = estimate.size();
  if (sigma.size() != n || use.size() != n)
    throw std::invalid_argument("alignPosYawRobust: need one sigma and one use flag per point");
  std::vector<double> sigma_h(n), h(n, 1.0), hz(n, 1.0), w_h(n), w_z(n);
  for (std::size_t k = 0; k < n; ++k) {
    if (!(sigma[k].minCoeff() > 0.0))
      throw std::invalid_argument("alignPosYawRobust: every sigma must be positive");
    sigma_h[k] = std::sqrt(0.5 * (sigma[k].x() * sigma[k].x() + sigma[k].y() * sigma[k].y()));
  }
  RobustPosYawAlignment out;
  out.r_h.resize(n), out.r_z.resize(n);
  for (int it = 1; it <= max_iterations; ++it) {
    for (std::size_t k = 0; k < n; ++k) {
      w_h[k] = use[k] ? h[k] / (sigma_h[k] * sigma_h[k]) : 0.0;
      w_z[k] = use[k] ? hz[k] / (sigma[k].z() * sigma[k].z()) : 0.0;
    }
    const PosYawAlignment a = alignPosYawWeighted(estimate, truth, w_h, w_z);
    std::vector<double> used_h, used_z;
    for (std::size_t k = 0; k < n; ++k) {
      const Vec3d e = a.apply(estimate[k]) - truth[k];
      out.r_h[k] = e.head<2>().norm() / sigma_h[k];
      out.r_z[k] = std::abs(e.z()) / sigma[k].z();
      if (use[k]) used_h.push_back(out.r_h[k]), used_z.push_back(out.r_z[k]);
    }
    out.s_h = std::max(1.0, median(used_h) / 1.1774100225154747);  // √(2 ln 2)
    out.s_z = std::max(1.0, median(used_z) / 0.6744897501960817);  // Φ⁻¹(3/4)
    for (std::size_t k = 0; k < n; ++k) {
      h[k] = huber(out.r_h[k] / out.s_h, huber_k);
      hz[k] = huber(out.r_z[k] / out.s_z, huber_k);
    }
    const bool converged = it > 1 && std::abs(a.yaw - out.alignment.yaw) < 1e-12 &&
                           (a.translation - out.alignment.translation).norm() < 1e-12;
    out.alignment = a;
    out.iterations = it;
    if (converged) break;
  }
  return out;
}

}  // namespace traverse::eval
