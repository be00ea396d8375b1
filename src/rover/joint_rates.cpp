#include "traverse/rover/joint_rates.h"

#include <algorithm>
#include <stdexcept>

#include <Eigen/Dense>

namespace traverse::rover {

SmoothedJoints smoothJoints(std::span<const double> t, const Eigen::MatrixXd& angles,
                            const JointRateFilter& filter) {
  const Eigen::Index n = angles.rows();
  if (static_cast<Eigen::Index>(t.size()) != n) {
    throw std::invalid_argument("jointRates: time and angle sample counts differ");
  }
  SmoothedJoints out{angles, Eigen::MatrixXd::Zero(n, angles.cols())};
  if (n < 2) return out;
  // With fewer than three samples only a straight line can be fitted.
  const int order = n >= 3 ? 2 : 1;
  const Eigen::Index h = std::max<Eigen::Index>(filter.half_window, order);
  const Eigen::Index width = std::min<Eigen::Index>(2 * h + 1, n);
  Eigen::MatrixXd A(width, order + 1);
  for (Eigen::Index k = 0; k < n; ++k) {
    const Eigen::Index first = std::clamp<Eigen::Index>(k - h, 0, n - width);
    for (Eigen::Index r = 0; r < width; ++r) {
      const double tau = t[first + r] - t[k];
      A(r, 0) = 1.0;
      A(r, 1) = tau;
      if (order == 2) A(r, 2) = tau * tau;
    }
    // Rows 0 and 1 of the pseudo-inverse give the value and derivative weights for every
    // channel at once (normal equations: (AᵀA)⁻¹Aᵀ, AᵀA is at most 3×3).
    const Eigen::MatrixXd pinv = (A.transpose() * A).ldlt().solve(A.transpose());
    const auto window = angles.middleRows(first, width);
    out.values.row(k) = pinv.row(0) * window;
    out.rates.row(k) = pinv.row(1) * window;
  }
  return out;
}

Eigen::MatrixXd jointRates(std::span<const double> t, const Eigen::MatrixXd& angles,
                           const JointRateFilter& filter) {
  return smoothJoints(t, angles, filter).rates;
}

double smoothedValueVarianceFactor(int h) {
  const double H = h;
  return 3.0 * (3 * H * H + 3 * H - 1) / ((2 * H - 1) * (2 * H + 1) * (2 * H + 3));
}

double smoothedRateVarianceFactor(int h) {
  const double H = h;
  return 3.0 / (H * (H + 1) * (2 * H + 1));
}

}  // namespace traverse::rover
