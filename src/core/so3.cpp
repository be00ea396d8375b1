#include "traverse/core/so3.h"

namespace traverse::so3 {

// Jr(φ) = I − (1 − cos θ)/θ² φ^ + (θ − sin θ)/θ³ (φ^)²   (Chirikjian; Forster et al. 2017, eq 8)
Mat3d rightJacobian(const Vec3d& phi) {
  const double t2 = phi.squaredNorm();
  const Mat3d W = skew(phi);
  double a, b;
  if (t2 < 1e-8) {
    a = 0.5 - t2 / 24.0;
    b = 1.0 / 6.0 - t2 / 120.0;
  } else {
    const double t = std::sqrt(t2);
    a = (1.0 - std::cos(t)) / t2;
    b = (t - std::sin(t)) / (t2 * t);
  }
  return Mat3d::Identity() - a * W + b * W * W;
}

// Jr⁻¹(φ) = I + ½ φ^ + (1/θ² − (1 + cos θ)/(2 θ sin θ)) (φ^)²
Mat3d rightJacobianInverse(const Vec3d& phi) {
  const double t2 = phi.squaredNorm();
  const Mat3d W = skew(phi);
  double c;
  if (t2 < 1e-8) {
    c = 1.0 / 12.0 + t2 / 720.0;
  } else {
    const double t = std::sqrt(t2);
    c = 1.0 / t2 - (1.0 + std::cos(t)) / (2.0 * t * std::sin(t));
  }
  return Mat3d::Identity() + 0.5 * W + c * W * W;
}

Mat3d leftJacobian(const Vec3d& phi) {
  return rightJacobian(Vec3d(-phi));
}

}  // namespace traverse::so3
