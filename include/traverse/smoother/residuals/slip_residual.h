// Slip constraint (K-17 … K-20) of wheel i at a node: four rows, the contact point's slip
// velocity along the contact frame's x, y, z and the spin about the contact normal,
//
//   r = L⁻¹ (t_nom − t_i(v, ω, ξ_i)),   t_i = Bᵀ Ad⁻¹_{g_{s l_i}}(ξ_i) ([v; ω] + J q̇)
//
// t_nom is the nominal slip of K §2.3.4 (transverse slip and spin a turn cannot avoid), Σ = L Lᵀ
// the slip noise of rover.yaml plus the joint-rate noise carried through ∂t/∂[v; ω] and the
// steering-angle noise (as in the EKF; evaluated once, at the seed). A robust loss is attached
// where the residual is added.
//
// This is the smoother's hot residual (24 rows per node), so its Jacobian is analytic —
// rover::slipConstraintWithJacobian, itself tested against the Jet derivative of
// rover::slipConstraint, the templated model every estimator shares.
//
// Parameter blocks: v (body, m/s), ω (body, rad/s), ξ (all six contact angles, rad).
#pragma once

#include <ceres/sized_cost_function.h>

#include "traverse/rover/slip_constraint.h"

namespace traverse::smoother {

class SlipResidual final : public ceres::SizedCostFunction<4, 3, 3, 6> {
 public:
  SlipResidual(int wheel, const Posed& T_body_wheel, double radius, const Twistd& joint_twist,
               const Vec4d& nominal_slip, const Eigen::Matrix4d& sqrt_info)
      : wheel_(wheel),
        T_body_wheel_(T_body_wheel),
        radius_(radius),
        joint_twist_(joint_twist),
        nominal_(nominal_slip),
        sqrt_info_(sqrt_info) {}

  bool Evaluate(double const* const* parameters, double* residuals,
                double** jacobians) const override {
    const Eigen::Map<const Vec3d> v(parameters[0]), w(parameters[1]);
    const double xi = parameters[2][wheel_];
    Eigen::Matrix<double, 4, 7> J;
    const Vec4d t =
        rover::slipConstraintWithJacobian(T_body_wheel_, radius_, joint_twist_, v, w, xi, &J);
    Eigen::Map<Vec4d>{residuals} = sqrt_info_ * (nominal_ - t);
    if (jacobians) {
      using Rm43 = Eigen::Matrix<double, 4, 3, Eigen::RowMajor>;
      using Rm46 = Eigen::Matrix<double, 4, 6, Eigen::RowMajor>;
      if (jacobians[0]) Eigen::Map<Rm43>{jacobians[0]} = -sqrt_info_ * J.leftCols<3>();
      if (jacobians[1]) Eigen::Map<Rm43>{jacobians[1]} = -sqrt_info_ * J.middleCols<3>(3);
      if (jacobians[2]) {
        Eigen::Map<Rm46> Jxi(jacobians[2]);
        Jxi.setZero();
        Jxi.col(wheel_) = -sqrt_info_ * J.col(6);
      }
    }
    return true;
  }

  /// The same residual through the templated model (the autodiff twin the tests compare with).
  template <typename T>
  Vec4<T> residual(const Vec3<T>& v, const Vec3<T>& w, const Eigen::Matrix<T, 6, 1>& xi) const {
    const Vec4<T> t =
        rover::slipConstraint<T>(T_body_wheel_, radius_, joint_twist_, v, w, xi[wheel_]);
    return sqrt_info_.cast<T>() * (nominal_.cast<T>() - t);
  }

 private:
  int wheel_;
  Posed T_body_wheel_;
  double radius_;
  Twistd joint_twist_;
  Vec4d nominal_;
  Eigen::Matrix4d sqrt_info_;
};

}  // namespace traverse::smoother
