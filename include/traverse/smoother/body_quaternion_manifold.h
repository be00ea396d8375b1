// The smoother's attitude manifold: a unit quaternion perturbed on the body side with a full
// rotation-vector tangent,
//
//   Plus(q, δθ) = q ⊗ Exp(δθ),      Minus(p, q) = Log(q⁻¹ ⊗ p),
//
// the same body-frame small angle as the EKF's error state and the σ columns of the output
// files (docs/model.md). Ceres 2.1's own EigenQuaternionManifold perturbs on the left with a
// half-angle tangent; a covariance read in that space would be ¼ of ours and site-framed.
//
// Storage: Eigen's coefficient order (x, y, z, w) — a parameter block is Eigen::Quaterniond::
// coeffs().data().
#pragma once

#include <ceres/manifold.h>

#include "traverse/core/so3.h"

namespace traverse::smoother {

class BodyQuaternionManifold final : public ceres::Manifold {
 public:
  int AmbientSize() const override { return 4; }
  int TangentSize() const override { return 3; }

  bool Plus(const double* x, const double* delta, double* x_plus_delta) const override {
    const Eigen::Map<const Quatd> q(x);
    Eigen::Map<Quatd> out(x_plus_delta);
    out = (q * so3::expQuat(Vec3d(Eigen::Map<const Vec3d>(delta)))).normalized();
    return true;
  }

  /// ∂(q ⊗ Exp(δ))/∂δ at δ = 0 = ½ q ⊗ [δ; 0]: rows (x, y, z, w), row-major 4×3:
  /// ½ [w I + [v]×; −vᵀ] with q = (v, w).
  bool PlusJacobian(const double* x, double* jacobian) const override {
    const Eigen::Map<const Quatd> q(x);
    Eigen::Map<Eigen::Matrix<double, 4, 3, Eigen::RowMajor>> J(jacobian);
    J.topRows<3>() = 0.5 * (q.w() * Mat3d::Identity() + so3::skew(Vec3d(q.vec())));
    J.bottomRows<1>() = -0.5 * q.vec().transpose();
    return true;
  }

  bool Minus(const double* y, const double* x, double* y_minus_x) const override {
    const Eigen::Map<const Quatd> p(y), q(x);
    Eigen::Map<Vec3d>{y_minus_x} = so3::log(Quatd(q.conjugate() * p));
    return true;
  }

  /// ∂Log(q⁻¹ ⊗ p)/∂p at p = q: 2 [w I − [v]×, −v] (3×4 row-major), the left inverse of
  /// PlusJacobian for a unit q.
  bool MinusJacobian(const double* x, double* jacobian) const override {
    const Eigen::Map<const Quatd> q(x);
    Eigen::Map<Eigen::Matrix<double, 3, 4, Eigen::RowMajor>> J(jacobian);
    J.leftCols<3>() = 2.0 * (q.w() * Mat3d::Identity() - so3::skew(Vec3d(q.vec())));
    J.rightCols<1>() = -2.0 * q.vec();
    return true;
  }
};

}  // namespace traverse::smoother
