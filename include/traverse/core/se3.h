// Rigid transforms and the adjoint map (K-18, K-19; Murray, Li & Sastry ch. 2).
#pragma once

#include "traverse/core/so3.h"
#include "traverse/core/types.h"

namespace traverse {

/// g = (R, p): maps a point from the child frame to the parent frame, x_parent = R x + p.
/// Names carry frames: `Pose<T> T_body_wheel` maps wheel-frame points to body coordinates.
template <typename T>
struct Pose {
  Mat3<T> R = Mat3<T>::Identity();
  Vec3<T> p = Vec3<T>::Zero();

  static Pose identity() { return Pose{}; }
  Vec3<T> operator*(const Vec3<T>& x) const { return R * x + p; }
  Pose operator*(const Pose& o) const { return Pose{R * o.R, R * o.p + p}; }
  Pose inverse() const { return Pose{R.transpose(), -(R.transpose() * p)}; }
  template <typename U>
  Pose<U> cast() const {
    return Pose<U>{R.template cast<U>(), p.template cast<U>()};
  }
};
using Posed = Pose<double>;

/// Ad_g: maps a twist expressed in the child frame into the parent frame.
template <typename T>
Mat6<T> adjoint(const Pose<T>& g) {
  Mat6<T> ad = Mat6<T>::Zero();
  ad.template topLeftCorner<3, 3>() = g.R;
  ad.template topRightCorner<3, 3>() = so3::skew(g.p) * g.R;
  ad.template bottomRightCorner<3, 3>() = g.R;
  return ad;
}

/// Ad_g⁻¹ = [Rᵀ  −Rᵀ p^; 0  Rᵀ]  (K-18).
template <typename T>
Mat6<T> adjointInverse(const Pose<T>& g) {
  Mat6<T> ad = Mat6<T>::Zero();
  const Mat3<T> rt = g.R.transpose();
  ad.template topLeftCorner<3, 3>() = rt;
  ad.template topRightCorner<3, 3>() = -rt * so3::skew(g.p);
  ad.template bottomRightCorner<3, 3>() = rt;
  return ad;
}

/// Ad_g⁻¹ V without forming the 6×6 matrix: [Rᵀ(v + ω × p); Rᵀ ω].
template <typename T>
Twist<T> applyAdjointInverse(const Pose<T>& g, const Twist<T>& V) {
  const Vec3<T> v = V.template head<3>();
  const Vec3<T> w = V.template tail<3>();
  Twist<T> out;
  out.template head<3>() = g.R.transpose() * (v + w.cross(g.p));
  out.template tail<3>() = g.R.transpose() * w;
  return out;
}

/// Rotation about a unit axis by angle a (Rodrigues).
template <typename T>
Mat3<T> axisAngle(const Vec3d& axis, const T& a) {
  return so3::exp(Vec3<T>(axis.cast<T>() * a));
}

}  // namespace traverse
