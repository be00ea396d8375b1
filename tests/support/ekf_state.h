// Shared test helpers for the EKF's nominal and error states: a random nominal state and
// x̂ ⊞ δx in the filter's error coordinates (est_ekf_process_jacobian_test.cpp,
// est_common_slip_test.cpp, est_accel_bias_test.cpp, est_icr_test.cpp), the textbook update
// those tests compare the filter's with, and a check of a compiled covariance kernel.
#pragma once

#include <gtest/gtest.h>

#include <random>

#include "support/jacobian_check.h"
#include "traverse/estimators/ekf.h"

namespace traverse::testing {

/// A random well-conditioned n × n covariance of scale 1e-3: 1e-3 (L Lᵀ + I), L's entries uniform
/// in [−1, 1] drawn column by column.
inline est::EkfMatrix randomSmallCovariance(std::mt19937& rng, int n) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  est::EkfMatrix L(n, n);
  for (int j = 0; j < n; ++j)
    for (int i = 0; i < n; ++i) L(i, j) = u(rng);
  return 1e-3 * (L * L.transpose() + est::EkfMatrix::Identity(n, n));
}

/// A random nominal state of a rover with `wheels` wheels (unit quaternion uniform on SO(3)); the
/// common slip c random too when `common_slip`, the accelerometer bias b_a when `accel_bias`.
/// `common_slip`: c's states (0, 2 or 3).
inline est::EkfState randomEkfState(std::mt19937& rng, int wheels, int common_slip = 0,
                                    bool accel_bias = false) {
  est::EkfState x;
  x.q_site_body = randomUnitQuaternion(rng);
  x.w_p = randomVector<3>(rng, 0.3);
  x.p_site = randomVector<3>(rng, 5.0);
  x.v_p = randomVector<3>(rng, 0.3);
  std::uniform_real_distribution<double> u(-0.4, 0.4);
  x.xi.resize(wheels);
  for (int i = 0; i < wheels; ++i) x.xi[i] = u(rng);
  x.bias = randomVector<3>(rng, 0.02);
  if (common_slip > 0) x.common_slip.head<2>() = randomVector<2>(rng, 0.03);
  if (common_slip == 3) x.common_slip.z() = randomVector<1>(rng, 0.01)[0];
  if (accel_bias) x.accel_bias = randomVector<3>(rng, 0.2);
  return x;
}

/// x̂ ⊞ δx in the filter's error coordinates (attitude on the body side: q̂ ⊗ Exp(δθ)); c
/// (`common_slip` states: 0, 2 or 3), b_a and δ move when the layout has them.
inline est::EkfState ekfBoxplus(const est::EkfState& x, const est::EkfVector& dx, int common_slip,
                                bool accel_bias, bool icr = false) {
  using I = est::EkfIndex;
  const int wheels = static_cast<int>(x.xi.size());
  const int na = accel_bias ? est::kAccelBiasStates : 0;
  EXPECT_EQ(dx.size(), est::ekfStates(wheels, common_slip, na, icr ? est::kIcrStates : 0));
  est::EkfState y = x;
  y.q_site_body = so3::boxplus(x.q_site_body, Vec3d(dx.segment<3>(I::kTheta)));
  y.w_p += dx.segment<3>(I::kRate);
  y.p_site += dx.segment<3>(I::kPos);
  y.v_p += dx.segment<3>(I::kVel);
  y.xi += dx.segment(I::kXi, wheels);
  y.bias += dx.segment<3>(I::kBias);
  for (int j = 0; j < common_slip; ++j) y.common_slip[j] += dx[I::commonSlip(wheels) + j];
  if (accel_bias) y.accel_bias += dx.segment<3>(I::accelBias(wheels, common_slip));
  if (icr) y.icr += dx[I::icr(wheels, common_slip, na)];
  return y;
}

/// Random filter inputs for a slip update: a gyro reading, with `has_cmd` a commanded twist, and
/// an accelerometer reading (used when `accel`).
inline est::EkfInputs randomSlipInputs(std::mt19937& rng, bool has_cmd, bool accel) {
  est::EkfInputs in;
  in.gyro = randomVector<3>(rng, 0.5);
  if (has_cmd) in.v_cmd = randomVector<3>(rng, 0.2), in.w_cmd = randomVector<3>(rng, 0.4);
  in.accel = randomVector<3>(rng, 0.5) + Vec3d(0, 0, 9.8), in.has_accel = accel;
  return in;
}

/// Filter options for the update reference tests: the velocity model O-4 (`accel`) or K-1, no χ²
/// gate (random states are far from consistent).
inline est::EkfOptions ungatedOptions(bool accel) {
  est::EkfOptions o;
  o.velocity = accel ? est::EkfOptions::VelocityModel::kAccelDriven
                     : est::EkfOptions::VelocityModel::kPerturbation;
  o.gating = false;
  return o;
}

/// The textbook EKF update the filter's expanded, sparse one must equal: K = P Hᵀ (H P Hᵀ + R)⁻¹,
/// dx = K r, P⁺ = G [(I − KH) P (I − KH)ᵀ + K R Kᵀ] Gᵀ with the attitude reset
/// G = est::detail::resetJacobian(dx_θ) (dense matrices throughout).
struct DenseUpdate {
  est::EkfVector dx;
  Eigen::MatrixXd P;
};
inline DenseUpdate denseEkfUpdate(const Eigen::MatrixXd& P, const Eigen::MatrixXd& H,
                                  const Eigen::MatrixXd& R, const Eigen::VectorXd& r) {
  const Eigen::Index n = P.rows();
  const Eigen::MatrixXd K = P * H.transpose() * (H * P * H.transpose() + R).inverse();
  DenseUpdate u;
  u.dx = K * r;
  const Eigen::MatrixXd IKH = Eigen::MatrixXd::Identity(n, n) - K * H;
  Eigen::MatrixXd G = Eigen::MatrixXd::Identity(n, n);
  G.block<3, 3>(est::EkfIndex::kTheta, est::EkfIndex::kTheta) =
      est::detail::resetJacobian(u.dx.segment<3>(est::EkfIndex::kTheta));
  u.P = G * (IKH * P * IKH.transpose() + K * R * K.transpose()) * G.transpose();
  return u;
}
/// The noise of one wheel's slip rows as the gyro-driven EKF takes it (est::Ekf::updateSlip): the
/// slip noise R plus the gyro reading's white noise, which reaches the rows through ω = S (ω_m − b)
/// + … + ω_p: H_ω S σ² Sᵀ H_ωᵀ, with H_ω the rows' Jacobian on the rate perturbation ω_p and S the
/// gyro's measured axes (a 0/1 diagonal). For one wheel this is exactly the filter's nuisance
/// state marginalised after the update.
inline Eigen::MatrixXd withGyroNoise(const Eigen::MatrixXd& R, const Eigen::MatrixXd& H,
                                     const Mat3d& S, double variance) {
  const Eigen::MatrixXd Hw = H.middleCols<3>(est::EkfIndex::kRate) * S;
  return R + variance * Hw * Hw.transpose();
}

/// max |A − B| / max |B|.
inline double relativeDifference(const Eigen::MatrixXd& A, const Eigen::MatrixXd& B) {
  return (A - B).cwiseAbs().maxCoeff() / B.cwiseAbs().maxCoeff();
}

/// The compiled covariance kernel for n states (est::detail::propagateCovariance) against the
/// dense Φ P Φᵀ, Φ = I + F dt + ½ (F dt)², for five random sparse F (15 % nonzero) and random P.
inline void expectCovarianceKernelMatchesDense(int n, uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  for (int trial = 0; trial < 5; ++trial) {
    est::EkfMatrix F = est::EkfMatrix::Zero(n, n);
    for (int i = 0; i < n; ++i)
      for (int j = 0; j < n; ++j)
        if (u(rng) < 0.15) F(i, j) = 2.0 * u(rng) - 1.0;
    est::EkfMatrix L(n, n);
    for (int i = 0; i < n; ++i)
      for (int j = 0; j < n; ++j) L(i, j) = 2.0 * u(rng) - 1.0;
    const est::EkfMatrix P = L * L.transpose() + est::EkfMatrix::Identity(n, n);
    const double dt = 0.05;
    const est::EkfMatrix Phi = est::EkfMatrix::Identity(n, n) + F * dt + 0.5 * F * dt * F * dt;
    const est::EkfMatrix dense = Phi * P * Phi.transpose();
    EXPECT_LE((est::detail::propagateCovariance(F, dt, P) - dense).cwiseAbs().maxCoeff(),
              1e-12 * dense.cwiseAbs().maxCoeff())
        << "n " << n << " trial " << trial;
  }
}

}  // namespace traverse::testing
