// Deterministic (nominal) slip for steering and turning (K §2.3.4).
//
// A turning rover slips even when every wheel is perfectly controlled: every wheel spins about
// its contact normal at the body's yaw rate (plus its steering rate), and the unsteered bogie
// wheels, whose axles lie on parallel lines offset in x, slide sideways unless the centre of
// rotation is on their axle line. The paper computes these for Ackermann motion on flat ground
// and uses them as the nominal t_m even on rough terrain; so does traverse.
#pragma once

#include "traverse/rover/slip_constraint.h"

namespace traverse::rover {

/// Body twist of a rigid planar motion with forward speed v_x (m/s) and yaw rate w_z (rad/s)
/// whose instantaneous centre of rotation lies on the line x = geometry.turn_centre_x:
/// v = (v_x, −w_z·x_c, 0), ω = (0, 0, w_z). A turn in place is v_x = 0.
inline Twistd nominalBodyTwist(const RoverGeometry& geometry, double v_x, double w_z) {
  Twistd V;
  V << v_x, -w_z * geometry.turn_centre_x, 0.0, 0.0, 0.0, w_z;
  return V;
}

/// Nominal slip of one wheel: the slip constraint on flat ground (ξ = 0) for the nominal body
/// twist, keeping what rolling cannot absorb — the transverse slip (row 1) and the spin about
/// the normal (row 3) — and zero normal slip (the wheel stays on the ground). Longitudinally a
/// wheel rolls (zero), except on a skid-steered rover, whose wheels roll at the speed of their
/// side's centre of rotation: ω_z · icr_offset_y (Wheel::icr_offset_y). `joint_twist` carries
/// the steering rate's contribution to the spin.
inline Vec4d nominalSlip(const Posed& T_body_wheel, double radius, const Twistd& body_twist,
                         const Twistd& joint_twist, double icr_offset_y = 0.0) {
  const Vec3d v = body_twist.head<3>();
  const Vec3d w = body_twist.tail<3>();
  Vec4d t = slipConstraint<double>(T_body_wheel, radius, joint_twist, v, w, 0.0);
  t[0] = w.z() * icr_offset_y;
  t[2] = 0.0;
  return t;
}

/// ∂nominalSlip/∂(v_x, w_z) of nominalSlip(T, r, nominalBodyTwist(geometry, v_x, w_z), …): the
/// nominal slip is affine in (v_x, w_z) — the ξ = 0 constraint is linear in the twist, and the
/// twist (v_x, −w_z x_c, 0, 0, 0, w_z) in (v_x, w_z) — so this is exact everywhere. Used where
/// the nominal follows the estimate (no cmd.csv: the EKF's slip H, the smoother's slip residual).
inline Eigen::Matrix<double, 4, 2> nominalSlipJacobian(const RoverGeometry& geometry,
                                                       const Posed& T_body_wheel, double radius,
                                                       const Twistd& joint_twist,
                                                       double icr_offset_y = 0.0) {
  Eigen::Matrix<double, 4, 7> J0;  // ∂t/∂(v, ω, ξ) at ξ = 0; t is linear in (v, ω)
  slipConstraintWithJacobian(T_body_wheel, radius, joint_twist, Vec3d::Zero(), Vec3d::Zero(), 0.0,
                             &J0);
  Eigen::Matrix<double, 4, 2> N = Eigen::Matrix<double, 4, 2>::Zero();
  for (const int row : {1, 3}) {
    N(row, 0) = J0(row, 0);
    N(row, 1) = J0(row, 5) - geometry.turn_centre_x * J0(row, 1);
  }
  N(0, 1) = icr_offset_y;
  return N;
}

}  // namespace traverse::rover
