// An estimated trajectory: what every estimator (dead reckoning, EKF, smoother) produces and
// what evaluation and the output files consume (../shared/docs/outputs.md, docs/outputs.md).
#pragma once

#include <array>
#include <filesystem>
#include <string>
#include <vector>

#include "traverse/core/types.h"
#include "traverse/io/log.h"
#include "traverse/rover/rover_geometry.h"

namespace traverse::est {

/// One estimator node. Attitude error convention: q = q̂ ⊗ Exp(δθ) (body-frame small angle).
struct TrajectoryNode {
  double t = 0.0;
  Vec3d p_site = Vec3d::Zero();
  Quatd q_site_body = Quatd::Identity();
  Vec3d v_body = Vec3d::Zero();
  Vec3d w_body = Vec3d::Zero();
  rover::WheelVectord xi;      ///< contact angles ξ1..ξN, one per wheel
  Vec3d bias = Vec3d::Zero();  ///< gyro bias (rad/s, body axes)
  /// Covariance of [δp_site (m); δθ_body (rad)] — valid when the trajectory has_covariance.
  Mat6d covariance = Mat6d::Zero();
  Vec3d bias_sigma = Vec3d::Zero();  ///< 1σ of the bias (not written to the node files)
  /// The wheels' common slip c (body x, y in m/s; yaw rate c_ω in rad/s) when the estimator
  /// carries it (rover.yaml slip_noise.common_*), else zero (not written to the node files).
  Vec3d common_slip = Vec3d::Zero();
  /// The accelerometer's bias b_a (body, m/s²) and its 1σ when the estimator carries it
  /// (rover.yaml accelerometer.bias_sigma_mps2), else zero (not written to the node files).
  Vec3d accel_bias = Vec3d::Zero(), accel_bias_sigma = Vec3d::Zero();
  /// The skid-steer ICRs' half-track error δ and its σ (m; zero without the state).
  double icr = 0.0, icr_sigma = 0.0;
};

struct Trajectory {
  std::string name;  ///< "dr", "ekf", "smoothed"
  bool has_covariance = false;
  std::vector<TrajectoryNode> nodes;
};

/// Consider covariance of the wheels' common rolling-radius scale (io::OdometryConfig): a scale
/// error δ that no estimator sees multiplies every displacement from the log's start by 1 + δ
/// (speeds from the wheels, heading from the gyro and sun), so node k's position covariance
/// gains `variance` (x_k − x_0)(x_k − x_0)ᵀ — the sensitivity ∂x_k/∂δ = x_k − x_0 times the
/// scale's variance (Bierman's consider covariance: the estimate does not move). No-op at 0 or
/// without covariance.
void addOdometryScaleCovariance(Trajectory* trajectory, double variance);

/// Consider covariance of a constant misalignment δ (body small angle, σ `sigma_rad` per axis)
/// between the frame that gives the attitude (the IMU) and the wheels' rolling direction
/// (io::OdometryConfig::imu_mounting_sigma_rad): the velocity the wheels give is turned by δ,
/// δv = δ × v, before R carries it to the site, so x_k moves by J_k δ with
/// J_k = −Σ_{j<k} R_j [v_j]× Δt_j (left sums over the nodes' attitude and body velocity; a
/// forward drive gains pitch σ × distance of height and yaw σ × distance of cross-track σ);
/// node k's position covariance gains σ² J_k J_kᵀ. No-op at 0 or without covariance.
void addMountingCovariance(Trajectory* trajectory, double sigma_rad);

/// Output columns (outputs.md): t,x,y,z,qw,qx,qy,qz,vx,vy,vz,wx,wy,wz,xi1..xiN (N wheels, the
/// size of the nodes' xi),bx,by,bz, then
/// with covariance the 1σ columns sx,sy,sz,sroll,spitch,syaw (attitude σ: body-frame small
/// angles about x, y, z, radians) and the off-diagonal terms cxy,cxz,cyz (m²) and
/// crp,cry,cpy (rad²) of the position and attitude blocks, appended so that NEES can be
/// computed from the file alone.
io::Stream toStream(const Trajectory& trajectory);
/// Inverse of toStream (covariance: the position and attitude blocks; cross terms zero).
Trajectory fromStream(const io::Stream& stream, const std::string& name);

/// The trajectory as writeTrajectory stores it and readTrajectory returns it — the attitude
/// normalised, the covariance rebuilt from the written σ and off-diagonal terms (the
/// position–attitude cross terms zero) — with the fields the files do not carry (bias σ, common
/// slip, accelerometer bias) kept. Metrics computed on it are those `traverse evaluate`
/// computes from the files, to the bit.
Trajectory asWritten(const Trajectory& trajectory);

/// Writes NAME.csv and NAME.tum (`t tx ty tz qx qy qz qw`, scalar last, readable by evo)
/// into `dir`, each atomically.
void writeTrajectory(const std::filesystem::path& dir, const Trajectory& trajectory);
/// Reads NAME.csv from `dir`.
Trajectory readTrajectory(const std::filesystem::path& dir, const std::string& name);

}  // namespace traverse::est
