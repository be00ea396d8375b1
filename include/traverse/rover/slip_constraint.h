// The kinematic slip constraint (K-17 … K-20; O-8 … O-10).
//
//   t_i = Bᵀ Ad⁻¹_{g_{s l_i}}(γ, λ, ξ_i) ( [v; ω] + J^s_{s f_i}(γ, λ) q̇ )
//
// [v; ω] is the body twist (body-frame velocity of the body origin and body angular rate),
// J q̇ the wheel's twist relative to the body (joint_twist below, computed once per joint
// sample from the deterministic joint angles and rates), g_{s l_i} the contact frame. With the
// pure-rolling B of K-20, t_i = (slip velocity of the wheel's contact point along the contact
// frame's x, y, z; spin about the contact normal) — zero for pure rolling.
#pragma once

#include "traverse/core/se3.h"
#include "traverse/rover/kinematics.h"

namespace traverse::rover {

/// Rows of the slip constraint per wheel (K-20: three translations and the normal spin).
inline constexpr int kSlipRows = 4;

/// Slip of one wheel, templated on the state-dependent part (v, ω, ξ).
/// `joint_twist` = J^s_{s f_i} q̇ (body frame), see wheelJointTwist().
template <typename T>
Vec4<T> slipConstraint(const Posed& T_body_wheel, double radius, const Twistd& joint_twist,
                       const Vec3<T>& v_body, const Vec3<T>& w_body, const T& xi) {
  const Pose<T> g_sl = contactFrame(T_body_wheel, radius, xi);
  Twist<T> V;
  V.template head<3>() = v_body + joint_twist.head<3>().cast<T>();
  V.template tail<3>() = w_body + joint_twist.tail<3>().cast<T>();
  const Twist<T> V_contact = applyAdjointInverse(g_sl, V);  // Ad⁻¹ (K-18)
  // Bᵀ of K-20 keeps rows 1, 2, 3 and 6.
  return Vec4<T>(V_contact[0], V_contact[1], V_contact[2], V_contact[5]);
}

/// J^s_{s f_i} q̇: the wheel's twist relative to the body caused by the joint rates.
inline Twistd wheelJointTwist(const WheelKinematics& wk, const JointVectord& q_dot) {
  return wk.J * q_dot;
}

/// All wheels stacked (4 rows per wheel: wheel 1 rows 0-3, …).
template <typename T>
Eigen::Matrix<T, Eigen::Dynamic, 1> slipConstraintAll(const RoverGeometry& geometry,
                                                      const RoverKinematics& kin,
                                                      const std::vector<Twistd>& joint_twists,
                                                      const Vec3<T>& v_body, const Vec3<T>& w_body,
                                                      const WheelVector<T>& xi) {
  Eigen::Matrix<T, Eigen::Dynamic, 1> t(kSlipRows * geometry.numWheels());
  for (int i = 0; i < geometry.numWheels(); ++i) {
    t.template segment<kSlipRows>(kSlipRows * i) = slipConstraint(
        kin[i].T_body_wheel, geometry.wheels[i].radius, joint_twists[i], v_body, w_body, xi[i]);
  }
  return t;
}

}  // namespace traverse::rover

namespace traverse::rover {

/// K-17 for one wheel with its analytic Jacobian ∂t/∂(v, ω, ξ) (4×7) — the EKF's hot path;
/// tests check it against the Jet derivative of slipConstraint().
///   t_{0:3} = R_lᵀ (v + j_v + (ω + j_ω) × p_l),  t_3 = e_zᵀ R_lᵀ (ω + j_ω)
///   ∂t_{0:3}/∂v = R_lᵀ,  ∂t_{0:3}/∂ω = −R_lᵀ [p_l]×,  ∂t_3/∂ω = e_zᵀ R_lᵀ,
///   ∂/∂ξ through R_l = R_w R_y(−ξ) and p_l = p_w + r R_w (sin ξ, 0, −cos ξ).
inline Vec4d slipConstraintWithJacobian(const Posed& T_body_wheel, double radius,
                                        const Twistd& joint_twist, const Vec3d& v_body,
                                        const Vec3d& w_body, double xi,
                                        Eigen::Matrix<double, 4, 7>* J) {
  const double c = std::cos(xi), s = std::sin(xi);
  const Mat3d& Rw = T_body_wheel.R;
  Mat3d Ry;  // R_y(−ξ)
  Ry << c, 0, -s, 0, 1, 0, s, 0, c;
  const Mat3d Rl = Rw * Ry;
  const Vec3d pl = T_body_wheel.p + radius * Rw * Vec3d(s, 0, -c);
  const Vec3d V = v_body + joint_twist.head<3>();
  const Vec3d W = w_body + joint_twist.tail<3>();
  const Vec3d u = V + W.cross(pl);  // velocity of the wheel point at the contact
  const Mat3d RlT = Rl.transpose();
  Vec4d t;
  t.head<3>() = RlT * u;
  t[3] = RlT.row(2).dot(W);
  J->setZero();
  J->block<3, 3>(0, 0) = RlT;
  J->block<3, 3>(0, 3) = -RlT * so3::skew(pl);
  J->block<1, 3>(3, 3) = RlT.row(2);
  Mat3d dRy;  // d R_y(−ξ) / dξ
  dRy << -s, 0, -c, 0, 0, 0, c, 0, -s;
  const Mat3d dRlT = (Rw * dRy).transpose();
  const Vec3d dpl = radius * Rw * Vec3d(c, 0, s);
  J->block<3, 1>(0, 6) = dRlT * u + RlT * W.cross(dpl);
  (*J)(3, 6) = dRlT.row(2).dot(W);
  return t;
}

}  // namespace traverse::rover
