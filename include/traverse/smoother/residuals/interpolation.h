// Attitude between two nodes: geodesic interpolation on the body side,
//
//   q(u) = q_k ⊗ Exp(u · Log(q_k⁻¹ ⊗ q_{k+1})),   u = (t − t_k)/(t_{k+1} − t_k) ∈ [0, 1],
//
// constant body rate over the interval — the trapezoid of the attitude process. Measurements
// that fall between nodes (sun, gyro, accelerometer samples) are predicted at q(u).
#pragma once

#include "traverse/core/so3.h"

namespace traverse::smoother {

template <typename T>
Quat<T> interpolateAttitude(const Quat<T>& q_k, const Quat<T>& q_k1, double u) {
  if (u == 0.0) return q_k;
  const Vec3<T> d = so3::boxminus(q_k1, q_k);
  return so3::boxplus(q_k, Vec3<T>(T(u) * d));
}

/// The geodesic midpoint q(½) of two stored quaternions (x, y, z, w).
template <typename T>
Quat<T> midpointAttitude(const T* q_k, const T* q_k1) {
  return interpolateAttitude(Quat<T>(Eigen::Map<const Quat<T>>(q_k)),
                             Quat<T>(Eigen::Map<const Quat<T>>(q_k1)), 0.5);
}

}  // namespace traverse::smoother
