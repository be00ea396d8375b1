// SO(3) helpers: skew, Exp, Log, Jacobians, Euler angles.
//
// Conventions (see docs/model.md):
//  - rotation vector φ (radians), Exp(φ) = exp(φ^), Hamilton quaternions;
//  - q rotates body vectors into the site frame (K-2, K-5);
//  - attitude error is a body-frame (right) perturbation: q = q̂ ⊗ Exp(δθ).
// Every function is templated on the scalar so that ceres::Jet yields exact derivatives; the
// small-angle branches use Taylor series so derivatives stay finite at φ = 0.
#pragma once

#include <cmath>

#include "traverse/core/types.h"

namespace traverse::so3 {

/// Below this squared angle (rad²) Exp/Log use their Taylor series.
inline constexpr double kSmallAngleSq = 1e-10;

/// φ^ : the cross-product matrix, φ^ a = φ × a (K-3, K-19).
template <typename T>
Mat3<T> skew(const Vec3<T>& w) {
  Mat3<T> m;
  m << T(0), -w.z(), w.y(), w.z(), T(0), -w.x(), -w.y(), w.x(), T(0);
  return m;
}

/// Inverse of skew for a skew-symmetric matrix.
template <typename T>
Vec3<T> vee(const Mat3<T>& m) {
  return Vec3<T>(m(2, 1), m(0, 2), m(1, 0));
}

/// Exp: rotation vector → unit quaternion. K-4 with Θ = |φ|, u = φ/|φ|.
template <typename T>
Quat<T> expQuat(const Vec3<T>& phi) {
  using std::cos;
  using std::sin;
  using std::sqrt;
  const T theta_sq = phi.squaredNorm();
  T w, k;  // q = (w, k φ)
  if (theta_sq > T(kSmallAngleSq)) {
    const T theta = sqrt(theta_sq);
    w = cos(theta / T(2));
    k = sin(theta / T(2)) / theta;
  } else {
    w = T(1) - theta_sq / T(8);
    k = T(0.5) - theta_sq / T(48);
  }
  return Quat<T>(w, k * phi.x(), k * phi.y(), k * phi.z());
}

/// Exp: rotation vector → rotation matrix.
template <typename T>
Mat3<T> exp(const Vec3<T>& phi) {
  return expQuat(phi).toRotationMatrix();
}

/// Log: unit quaternion → rotation vector with |φ| ≤ π. Uses atan2 so that it stays accurate
/// near π (where |vec(q)| → 1 and w → 0) and the Taylor series near 0.
template <typename T>
Vec3<T> log(const Quat<T>& q_in) {
  using std::atan2;
  using std::sqrt;
  // q and −q are the same rotation; pick w ≥ 0 so the angle is in [0, π].
  const Quat<T> q = q_in.w() < T(0) ? Quat<T>(-q_in.w(), -q_in.x(), -q_in.y(), -q_in.z()) : q_in;
  const Vec3<T> v = q.vec();
  const T s_sq = v.squaredNorm();
  T k;  // φ = k v
  if (s_sq > T(kSmallAngleSq)) {
    const T s = sqrt(s_sq);
    k = T(2) * atan2(s, q.w()) / s;
  } else {
    // 2 atan(s/w)/s = (2/w)(1 − s²/(3w²) + …)
    k = (T(2) / q.w()) * (T(1) - s_sq / (T(3) * q.w() * q.w()));
  }
  return k * v;
}

/// Log of a rotation matrix (through the quaternion; Eigen's conversion is branch-stable).
template <typename T>
Vec3<T> log(const Mat3<T>& r) {
  return log(Quat<T>(r));
}

/// Right Jacobian Jr(φ): Exp(φ + δ) ≈ Exp(φ) Exp(Jr(φ) δ).
Mat3d rightJacobian(const Vec3d& phi);
/// Inverse of the right Jacobian: Log(Exp(φ) Exp(δ)) ≈ φ + Jr⁻¹(φ) δ.
Mat3d rightJacobianInverse(const Vec3d& phi);
/// Left Jacobian Jl(φ) = Jr(−φ).
Mat3d leftJacobian(const Vec3d& phi);

/// Box-plus on the body side, the project's perturbation: q ⊞ δθ = q ⊗ Exp(δθ).
template <typename T>
Quat<T> boxplus(const Quat<T>& q, const Vec3<T>& dtheta) {
  return q * expQuat(dtheta);
}

/// Box-minus matching boxplus: q_a ⊟ q_b = Log(q_b⁻¹ ⊗ q_a) (body-frame difference).
template <typename T>
Vec3<T> boxminus(const Quat<T>& q_a, const Quat<T>& q_b) {
  return log(Quat<T>(q_b.conjugate() * q_a));
}

/// Roll, pitch, yaw (radians) of q_site_body in the Z-Y-X convention: R = Rz(yaw) Ry(pitch)
/// Rx(roll). Pitch is clamped to ±π/2 for numerically unit quaternions.
template <typename T>
Vec3<T> rollPitchYaw(const Quat<T>& q) {
  using std::asin;
  using std::atan2;
  const T w = q.w(), x = q.x(), y = q.y(), z = q.z();
  const T roll = atan2(T(2) * (w * x + y * z), T(1) - T(2) * (x * x + y * y));
  T sp = T(2) * (w * y - z * x);
  if (sp > T(1)) sp = T(1);
  if (sp < T(-1)) sp = T(-1);
  const T pitch = asin(sp);
  const T yaw = atan2(T(2) * (w * z + x * y), T(1) - T(2) * (y * y + z * z));
  return Vec3<T>(roll, pitch, yaw);
}

/// Quaternion from roll, pitch, yaw (Z-Y-X).
template <typename T>
Quat<T> fromRollPitchYaw(const T& roll, const T& pitch, const T& yaw) {
  return Quat<T>(Eigen::AngleAxis<T>(yaw, Vec3<T>::UnitZ())) *
         Quat<T>(Eigen::AngleAxis<T>(pitch, Vec3<T>::UnitY())) *
         Quat<T>(Eigen::AngleAxis<T>(roll, Vec3<T>::UnitX()));
}

/// Wraps an angle to (−π, π].
/// E with δθ = E (δroll, δpitch, δyaw) to first order at q (body-frame δθ, q ⊗ Exp(δθ);
/// Z-Y-X angles): the Euler-rate → body-rate matrix. Its yaw column is Rᵀe_z, the site's
/// vertical seen from the body.
inline Mat3d eulerRateToBodyRate(const Quatd& q) {
  const Vec3d rpy = rollPitchYaw(q);
  const double sr = std::sin(rpy.x()), cr = std::cos(rpy.x());
  const double sp = std::sin(rpy.y()), cp = std::cos(rpy.y());
  Mat3d E;
  E << 1, 0, -sp,      //
      0, cr, sr * cp,  //
      0, -sr, cr * cp;
  return E;
}

inline double wrapAngle(double a) {
  a = std::remainder(a, 2.0 * M_PI);
  return a <= -M_PI ? a + 2.0 * M_PI : a;
}

}  // namespace traverse::so3
