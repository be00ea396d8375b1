// Forward kinematics, spatial Jacobian and contact frames (K §2.1, K-17 … K-19).
//
// Forward kinematics composes the joint transforms of the URDF tree (product of exponentials
// about each joint axis). The spatial Jacobian J^s_{s f_i} maps the joint-rate vector q̇ to the
// twist [v; ω] of wheel i (including its drive rotation) relative to the body, expressed in the
// body frame at the body origin: column j is the joint's twist [q_j × ω_j; ω_j] (Murray §3.2)
// times its mimic multiplier, for the joints on the wheel's chain, zero elsewhere.
#pragma once

#include <vector>

#include "traverse/core/se3.h"
#include "traverse/rover/rover_geometry.h"

namespace traverse::rover {

/// J^s_{s f_i}: 6 × numCoords (fixed storage of kMaxCoords columns).
template <typename T>
using WheelJacobian = Eigen::Matrix<T, 6, Eigen::Dynamic, 0, 6, kMaxCoords>;

template <typename T>
struct WheelKinematicsT {
  Pose<T> T_body_wheel;  ///< g_{s f_i} without the drive rotation ψ (rotational symmetry, K §2.3.4)
  WheelJacobian<T> J;    ///< J^s_{s f_i}(γ, λ)
};
using WheelKinematics = WheelKinematicsT<double>;

/// One entry per wheel of the geometry.
template <typename T>
using RoverKinematicsT = std::vector<WheelKinematicsT<T>>;
using RoverKinematics = RoverKinematicsT<double>;

/// Pose of every joint frame in the body frame (after the joint's own rotation) for joint
/// coordinates q. Element j of the result corresponds to geometry.joints[j].
template <typename T>
std::vector<Pose<T>> jointPoses(const RoverGeometry& geometry, const JointVector<T>& q,
                                std::vector<Pose<T>>* before_rotation = nullptr) {
  std::vector<Pose<T>> poses(geometry.joints.size());
  if (before_rotation) before_rotation->resize(geometry.joints.size());
  for (size_t j = 0; j < geometry.joints.size(); ++j) {
    const KinematicJoint& jt = geometry.joints[j];
    const Pose<T> parent = jt.parent < 0 ? Pose<T>{} : poses[jt.parent];
    const Pose<T> at_zero = parent * jt.origin.cast<T>();
    if (before_rotation) (*before_rotation)[j] = at_zero;
    if (jt.coord < 0) {
      poses[j] = at_zero;
    } else {
      const T angle = T(jt.multiplier) * q[jt.coord] + T(jt.offset);
      poses[j] = at_zero * Pose<T>{axisAngle(jt.axis, angle), Vec3<T>::Zero()};
    }
  }
  return poses;
}

/// Wheel frames and spatial Jacobians for joint coordinates q.
template <typename T>
RoverKinematicsT<T> forwardKinematics(const RoverGeometry& geometry, const JointVector<T>& q) {
  std::vector<Pose<T>> before;
  const std::vector<Pose<T>> after = jointPoses(geometry, q, &before);
  RoverKinematicsT<T> out(geometry.wheels.size());
  for (size_t i = 0; i < out.size(); ++i) {
    const int d = geometry.wheels[i].drive_joint;
    out[i].T_body_wheel = before[d];
    out[i].J.setZero(6, geometry.numCoords());
    for (int j = d; j >= 0; j = geometry.joints[j].parent) {
      const KinematicJoint& jt = geometry.joints[j];
      if (jt.coord < 0) continue;
      // Joint axis and a point on it, both in the body frame.
      const Vec3<T> w = after[j].R * jt.axis.cast<T>();
      const Vec3<T> p = after[j].p;
      out[i].J.template block<3, 1>(0, jt.coord) += T(jt.multiplier) * p.cross(w);
      out[i].J.template block<3, 1>(3, jt.coord) += T(jt.multiplier) * w;
    }
  }
  return out;
}

/// g_{f l}(ξ): wheel frame → contact frame l_i at contact angle ξ on the wheel's equator.
/// ξ = 0 is the wheel bottom; ξ > 0 moves the contact forward (towards +x of the wheel, as when
/// climbing a step). The contact frame's z axis is the surface normal (contact → wheel centre),
/// x the rolling direction in the tangent plane, y the axle.
template <typename T>
Pose<T> wheelToContact(const T& xi, double radius) {
  using std::cos;
  using std::sin;
  Pose<T> g;
  g.R = axisAngle(Vec3d::UnitY(), T(-xi));
  g.p = Vec3<T>(T(radius) * sin(xi), T(0), -T(radius) * cos(xi));
  return g;
}

/// g_{s l_i}: body frame → contact frame of a wheel (K-17's g_{s l_i}(γ, λ, ξ_i)).
template <typename T>
Pose<T> contactFrame(const Posed& T_body_wheel, double radius, const T& xi) {
  return T_body_wheel.cast<T>() * wheelToContact(xi, radius);
}

}  // namespace traverse::rover
