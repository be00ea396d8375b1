// Shared test helpers for the EKF's nominal and error states: a random nominal state and
// x̂ ⊞ δx in the filter's error coordinates (est_ekf_process_jacobian_test.cpp,
// est_common_slip_test.cpp).
#pragma once

#include <random>

#include "support/jacobian_check.h"
#include "traverse/estimators/ekf.h"

namespace traverse::testing {

/// A random nominal state of a rover with `wheels` wheels (unit quaternion uniform on SO(3)); the
/// common slip c random too when `common_slip`.
inline est::EkfState randomEkfState(std::mt19937& rng, int wheels, bool common_slip = false) {
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
  return x;
}

/// x̂ ⊞ δx in the filter's error coordinates (attitude on the body side: q̂ ⊗ Exp(δθ)); c moves
/// when δx has its two states (size ekfStates(N, 2)).
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
  if (dx.size() == est::ekfStates(wheels, est::kCommonSlipStates))
    y.common_slip += dx.segment<2>(I::commonSlip(wheels));
  return y;
}

}  // namespace traverse::testing
