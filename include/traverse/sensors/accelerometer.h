// Accelerometer (K-10, K-11; O-4) and its at-rest form (Nickels, "rest mode").
//
//   a_m = a + ω × v − R(q)ᵀ g_s + ω × (ω × L) + ω̇ × L + n_a,     g_s = (0, 0, −g)   (K-10)
//
// a = v̇ is the body-frame derivative of the body velocity v, L the lever arm from the body
// origin to the accelerometer. At rest (a = v = ω = ω̇ = 0) it reads R(q)ᵀ (0, 0, g): (0, 0, g)
// for a level rover. The sensor-integrating velocity model (K-11/O-4) is the same equation
// solved for a, so it calls this one.
#pragma once

#include "traverse/core/types.h"

namespace traverse::sensors {

template <typename T>
Vec3<T> accelPredict(const Quat<T>& q_site_body, const Vec3<T>& a_body, const Vec3<T>& v_body,
                     const Vec3<T>& w_body, const Vec3<T>& w_dot_body, const Vec3d& lever_arm,
                     double gravity) {
  const Vec3<T> L = lever_arm.cast<T>();
  const Vec3<T> g_site(T(0), T(0), T(-gravity));
  return a_body + w_body.cross(v_body) - q_site_body.conjugate() * g_site +
         w_body.cross(w_body.cross(L)) + w_dot_body.cross(L);
}

/// At rest: specific force R(q)ᵀ (0, 0, g).
template <typename T>
Vec3<T> accelAtRest(const Quat<T>& q_site_body, double gravity) {
  return q_site_body.conjugate() * Vec3<T>(T(0), T(0), T(gravity));
}

/// Sensor-integrating velocity model (K-11, O-4): v̇ = a_m − (ω × v − Rᵀ g_s + ω×(ω×L) + ω̇×L).
template <typename T>
Vec3<T> velocityRateFromAccel(const Vec3<T>& a_meas, const Quat<T>& q_site_body,
                              const Vec3<T>& v_body, const Vec3<T>& w_body,
                              const Vec3<T>& w_dot_body, const Vec3d& lever_arm, double gravity) {
  return a_meas - accelPredict(q_site_body, Vec3<T>::Zero().eval(), v_body, w_body, w_dot_body,
                               lever_arm, gravity);
}

}  // namespace traverse::sensors
