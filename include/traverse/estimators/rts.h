// The Rauch–Tung–Striebel fixed-interval smoother over the forward EKF's stored states: the
// classical peer of the batch smoother, the one a rover team would write first (CoreNav-style).
// It reuses the filter's linearisation — no relinearisation, no robust loss, no segments — so a
// comparison with the batch smoother shows what those buy (docs/model.md, "RTS").
//
// The filter records a chain (Ekf::startRecording, RtsChain): posteriors x̂_k, P_k after each
// batch of updates, and between consecutive ones the composed transition Φ_k of the
// propagations and the prior x̂⁻_{k+1}, P⁻_{k+1} they gave. Backwards from the last posterior,
// in the error state of the filter (attitude as the body-frame small angle, q = q̂ ⊗ Exp(δθ)):
//   C_k   = P_k Φ_kᵀ (P⁻_{k+1})⁻¹
//   δ_k   = x^s_{k+1} ⊟ x̂⁻_{k+1}          (attitude: Log(q̂⁻⁻¹ q^s); the rest: differences)
//   x^s_k = x̂_k ⊞ C_k δ_k
//   P^s_k = P_k + C_k (P^s_{k+1} − P⁻_{k+1}) C_kᵀ
// The attitude reset made at every update (K-21) happens between a prior and its posterior,
// inside a point, so the chain's transitions are the propagations alone.
#pragma once

#include "traverse/estimators/ekf.h"
#include "traverse/estimators/trajectory.h"

namespace traverse::est {

/// x_a ⊟ x_b in the filter's error state (numStates entries; ξ, c, b_a and δ by the filter's
/// sizes; `common_slip` is the number of c's states, 0, 2 or 3: Ekf::commonSlipStates()).
EkfVector ekfStateDifference(const EkfState& a, const EkfState& b, int wheels, int common_slip,
                             bool accel_bias = false, bool icr = false);
/// x ⊞ δ (the filter's absorb without the covariance reset).
EkfState ekfStatePlus(const EkfState& x, const EkfVector& delta, int wheels, int common_slip,
                      bool accel_bias = false, bool icr = false);

/// The smoothed states at the chain's points (index as RtsChain::points) and their covariances.
struct RtsStates {
  std::vector<EkfState> x;
  std::vector<Eigen::MatrixXd> P;
};
/// The backward pass above. A prior covariance that is not positive definite (LDLT fails) gives
/// C from its pseudo-inverse (eigenvalues below 1e-15 of the largest dropped).
RtsStates rtsBackward(const RtsChain& chain, int wheels, int common_slip, bool accel_bias = false,
                      bool icr = false);

/// The trajectory "rts": one node per recorded trajectory node, as the filter writes them
/// (Ekf::nodeOf at the smoothed state and covariance).
Trajectory rtsSmooth(const Ekf& ekf, const RtsChain& chain);

}  // namespace traverse::est
