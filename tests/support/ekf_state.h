// Shared test helpers for the EKF's nominal and error states: a random nominal state and
// x̂ ⊞ δx in the filter's error coordinates (est_ekf_process_jacobian_test.cpp,
// est_common_slip_test.cpp).
#pragma once

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
inline est::EkfState randomEkfState(std::mt19937& rng, int wheels, bool common_slip = false,
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
  if (common_slip) x.common_slip = randomVector<2>(rng, 0.03);
  if (accel_bias) x.accel_bias = randomVector<3>(rng, 0.2);
  return x;
}

/// x̂ ⊞ δx in the filter's error coordinates (attitude on the body side: q̂ ⊗ Exp(δθ)); c and
/// b_a move when δx has their states (told apart by its size: ekfStates(N, C, A)).
inline est::EkfState ekfBoxplus(const est::EkfState& x, const est::EkfVector& dx) {
  using I = est::EkfIndex;
  const int wheels = static_cast<int>(x.xi.size());
  est::EkfState y = x;
  y.q_site_body = so3::boxplus(x.q_site_body, Vec3d(dx.segment<3>(I::kTheta)));
  y.w_p += dx.segment<3>(I::kRate);
  y.p_site += dx.segment<3>(I::kPos);
  y.v_p += dx.segment<3>(I::kVel);
  y.xi += dx.segment(I::kXi, wheels);
  y.bias += dx.segment<3>(I::kBias);
  const int n = static_cast<int>(dx.size());
  const bool c = n == est::ekfStates(wheels, est::kCommonSlipStates) ||
                 n == est::ekfStates(wheels, est::kCommonSlipStates, est::kAccelBiasStates);
  const bool a = n == est::ekfStates(wheels, 0, est::kAccelBiasStates) ||
                 n == est::ekfStates(wheels, est::kCommonSlipStates, est::kAccelBiasStates);
  if (c) y.common_slip += dx.segment<2>(I::commonSlip(wheels));
  if (a) y.accel_bias += dx.segment<3>(I::accelBias(wheels, c ? est::kCommonSlipStates : 0));
  return y;
}

}  // namespace traverse::testing
