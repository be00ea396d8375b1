// The joint data of one joint sample as the slip constraint (K-17) sees it, and the covariance
// of a wheel's four slip rows. Shared by the EKF and the smoother; built from a log by
// est::jointSamples.
#pragma once

#include <vector>

#include "traverse/core/se3.h"
#include "traverse/core/types.h"
#include "traverse/rover/kinematics.h"

namespace traverse::rover {

/// Slip-constraint noise per component (K-17's n_i), 1σ per joint sample (rover.yaml slip_noise).
struct SlipNoise {
  double longitudinal_mps = 0.004;
  double lateral_mps = 0.004;
  double normal_mps = 0.004;
  double spin_rad_s = 0.02;
  /// Slip that grows with the turn (skid steering: wheels scrub sideways and the sides'
  /// centres of rotation wander): σ² += (k |ω_z|)² on the longitudinal and lateral rows, k in m.
  double longitudinal_per_yaw_rate_m = 0.0;
  double lateral_per_yaw_rate_m = 0.0;
  /// Longitudinal slip that grows with the speed (a fraction of |v_x|: wheel sinkage, a tyre's
  /// effective radius that varies with the ground): σ² += (k |v_x|)².
  double longitudinal_per_speed = 0.0;
  /// Slip the wheels share, correlated in time (a first-order Gauss–Markov process per body
  /// axis, steady-state σ in m/s, correlation time in s): the ground moving under every wheel
  /// at once (sand, a slope, a burst), which the per-wheel white rows above cannot represent —
  /// six wheels that agree are then taken for the body's motion. The estimators carry it as a
  /// state c = (c_x, c_y): the wheels roll as if the body moved at v + c. Zero (the default):
  /// no such state.
  double common_longitudinal_mps = 0.0;
  double common_lateral_mps = 0.0;
  /// The wheels' common yaw-rate slip c_ω (rad/s, body z; same τ): the part of the wheels' own
  /// correlated slips that looks like a turn — one side slipping more than the other for
  /// seconds. With it c = (c_x, c_y, c_ω) and the wheels roll as if the body moved at
  /// (v + (c_x, c_y, 0), ω + (0, 0, c_ω)); without it the wheels' left–right difference is
  /// white noise to the estimators, and a correlated one is read as the body's yaw rate, against
  /// the gyro. Needs the other two (> 0).
  double common_yaw_rate_rad_s = 0.0;
  double common_time_constant_s = 5.0;
  bool hasCommonSlip() const { return common_longitudinal_mps > 0 || common_lateral_mps > 0; }
  /// States of c: 0 (none), 2 (c_x, c_y) or 3 (with c_ω).
  int commonSlipStates() const { return hasCommonSlip() ? (common_yaw_rate_rad_s > 0 ? 3 : 2) : 0; }
};

/// Joint data at a joint sample: wheel frames g_{s f_i} and the wheels' joint twists J q̇ (K-17).
struct JointSample {
  double t = 0.0;
  std::vector<Posed> T_body_wheel;  ///< one per wheel of the geometry
  std::vector<Twistd> joint_twist;
  /// Covariance of each joint twist J q̇ from the joint-rate noise (J Σ_q̇ Jᵀ, 6×6), and the
  /// steering-angle variance of the wheel's chain (0 for unsteered wheels).
  std::vector<Mat6d> joint_twist_covariance;
  std::vector<double> steering_variance;
  /// Whether each wheel's drive angle may be used here (0 inside a wheel outage: a stuck
  /// encoder); the estimators give such a wheel no slip rows.
  std::vector<unsigned char> used;
  /// False for a sample the estimators insert inside a gap of joints.csv (est::jointSamples):
  /// a node where the trajectory is wanted but nothing was measured — frames from the angles
  /// interpolated across the gap, no joint twists, no slip rows. The state there is carried by
  /// the gyro and accelerometer alone, so its covariance grows with the gap.
  bool measured = true;
  bool wheelUsed(int i) const { return used.empty() || used[static_cast<size_t>(i)] != 0; }
  /// Sizes every per-wheel vector for `n` wheels (every wheel used).
  void resize(int n) {
    const auto m = static_cast<size_t>(n);
    T_body_wheel.resize(m), joint_twist.resize(m), joint_twist_covariance.resize(m);
    steering_variance.assign(m, 0.0);
    used.assign(m, 1);
  }
};

/// Covariance of wheel i's four slip rows (K-17): the slip noise, plus the joint-rate noise
/// carried through ∂t/∂[v; ω] = J_vw, plus the steering-angle noise (transverse row). The EKF and
/// the smoother both whiten the slip constraint with it.
Eigen::Matrix4d slipCovariance(const SlipNoise& noise, const JointSample& js, int wheel,
                               const Vec3d& v_body, const Vec3d& w_body,
                               const Eigen::Matrix<double, 4, 6>& J_vw);

}  // namespace traverse::rover
