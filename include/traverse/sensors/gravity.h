// At-rest attitude from gravity (Nickels & Baker, "Attitude estimate — rest mode"; K-10 at rest).
//
// At rest the mean specific force f̄ = R(q)ᵀ (0, 0, g) fixes the gravity direction in the body,
// i.e. roll and pitch (Z-Y-X Euler):  roll = atan2(f_y, f_z),  pitch = atan2(−f_x, √(f_y² + f_z²)).
// Yaw is unobservable from gravity. The magnitude of f̄ is not used.
#pragma once

#include <cmath>

#include "traverse/core/so3.h"
#include "traverse/core/types.h"

namespace traverse::sensors {

/// Roll and pitch (rad) from a specific-force vector in the body frame.
template <typename T>
Vec2<T> rollPitchFromSpecificForce(const Vec3<T>& f) {
  using std::atan2;
  using std::sqrt;
  return Vec2<T>(atan2(f.y(), f.z()), atan2(-f.x(), sqrt(f.y() * f.y() + f.z() * f.z())));
}

/// The at-rest measurement model: predicted (roll, pitch) of attitude q, through the same
/// gravity direction the accelerometer sees, so it is consistent with rollPitchYaw().
template <typename T>
Vec2<T> gravityRollPitchPredict(const Quat<T>& q_site_body) {
  return rollPitchFromSpecificForce(Vec3<T>(q_site_body.conjugate() * Vec3<T>::UnitZ()));
}

/// The same with an accelerometer bias b_a (body, m/s²): the window's mean specific force is
/// R(q)ᵀ (0, 0, g) + b_a (K-10 at rest plus the bias), so b_a tilts the apparent gravity by
/// about |b_a⊥| / g. At b_a = 0 it equals the bias-free form for any g > 0.
template <typename T>
Vec2<T> gravityRollPitchPredict(const Quat<T>& q_site_body, const Vec3<T>& accel_bias,
                                double gravity) {
  return rollPitchFromSpecificForce(
      Vec3<T>(q_site_body.conjugate() * Vec3<T>(T(0), T(0), T(gravity)) + accel_bias));
}

/// A roll/pitch measurement with its covariance.
struct RollPitchMeasurement {
  Vec2d roll_pitch = Vec2d::Zero();
  Eigen::Matrix2d covariance = Eigen::Matrix2d::Identity();
};

/// Roll/pitch from the mean specific force of a rest window and the covariance of that mean
/// (first-order propagation through the atan2 map; for N samples of white noise σ the mean's
/// covariance is σ²/N · I).
RollPitchMeasurement rollPitchAtRest(const Vec3d& mean_specific_force,
                                     const Mat3d& mean_covariance);

}  // namespace traverse::sensors
