#include "traverse/estimators/rts.h"

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>

#include "traverse/core/so3.h"

namespace traverse::est {

using I = EkfIndex;

EkfVector ekfStateDifference(const EkfState& a, const EkfState& b, int wheels, int common_slip,
                             bool accel_bias, bool icr) {
  const int nc = common_slip, na = accel_bias ? kAccelBiasStates : 0;
  EkfVector d = EkfVector::Zero(ekfStates(wheels, nc, na, icr ? kIcrStates : 0));
  d.segment<3>(I::kTheta) = so3::boxminus(a.q_site_body, b.q_site_body);
  d.segment<3>(I::kRate) = a.w_p - b.w_p;
  d.segment<3>(I::kPos) = a.p_site - b.p_site;
  d.segment<3>(I::kVel) = a.v_p - b.v_p;
  d.segment<3>(I::kBias) = a.bias - b.bias;
  d.segment(I::kXi, wheels) = a.xi.head(wheels) - b.xi.head(wheels);
  if (nc > 0) d.segment(I::commonSlip(wheels), nc) = (a.common_slip - b.common_slip).head(nc);
  if (accel_bias) d.segment<3>(I::accelBias(wheels, nc)) = a.accel_bias - b.accel_bias;
  if (icr) d[I::icr(wheels, nc, na)] = a.icr - b.icr;
  return d;
}

EkfState ekfStatePlus(const EkfState& x, const EkfVector& delta, int wheels, int common_slip,
                      bool accel_bias, bool icr) {
  const int nc = common_slip, na = accel_bias ? kAccelBiasStates : 0;
  EkfState out = x;
  out.q_site_body = so3::boxplus(x.q_site_body, Vec3d(delta.segment<3>(I::kTheta))).normalized();
  out.w_p += delta.segment<3>(I::kRate);
  out.p_site += delta.segment<3>(I::kPos);
  out.v_p += delta.segment<3>(I::kVel);
  out.bias += delta.segment<3>(I::kBias);
  out.xi.head(wheels) += delta.segment(I::kXi, wheels);
  if (nc > 0) out.common_slip.head(nc) += delta.segment(I::commonSlip(wheels), nc);
  if (accel_bias) out.accel_bias += delta.segment<3>(I::accelBias(wheels, nc));
  if (icr) out.icr += delta[I::icr(wheels, nc, na)];
  return out;
}

namespace {

/// C = P Φᵀ (P⁻)⁻¹, as (P⁻)⁻¹ Φ P transposed (P⁻ and P symmetric).
Eigen::MatrixXd gain(const Eigen::MatrixXd& P, const Eigen::MatrixXd& phi,
                     const Eigen::MatrixXd& P_prior) {
  const Eigen::MatrixXd phiP = phi * P;
  Eigen::LDLT<Eigen::MatrixXd> ldlt(P_prior);
  if (ldlt.info() == Eigen::Success && ldlt.isPositive()) {
    const Eigen::VectorXd d = ldlt.vectorD();
    if (d.minCoeff() > 1e-15 * d.maxCoeff()) return ldlt.solve(phiP).transpose();
  }
  Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> es(P_prior);
  const Eigen::VectorXd ev = es.eigenvalues();
  const double floor = 1e-15 * std::max(ev.maxCoeff(), 0.0);
  Eigen::VectorXd inv = Eigen::VectorXd::Zero(ev.size());
  for (Eigen::Index i = 0; i < ev.size(); ++i) inv[i] = ev[i] > floor ? 1.0 / ev[i] : 0.0;
  const Eigen::MatrixXd pinv = es.eigenvectors() * inv.asDiagonal() * es.eigenvectors().transpose();
  return (pinv * phiP).transpose();
}

}  // namespace

RtsStates rtsBackward(const RtsChain& chain, int wheels, int common_slip, bool accel_bias,
                      bool icr) {
  RtsStates s;
  const size_t n = chain.points.size();
  s.x.resize(n);
  s.P.resize(n);
  if (n == 0) return s;
  s.x[n - 1] = chain.points[n - 1].posterior;
  s.P[n - 1] = chain.points[n - 1].P_post;
  for (size_t k = n - 1; k-- > 0;) {
    const RtsPoint& p = chain.points[k];
    const Eigen::MatrixXd C = gain(p.P_post, p.phi, p.P_prior);
    const EkfVector delta =
        ekfStateDifference(s.x[k + 1], p.prior, wheels, common_slip, accel_bias, icr);
    s.x[k] = ekfStatePlus(p.posterior, EkfVector(C * delta), wheels, common_slip, accel_bias, icr);
    Eigen::MatrixXd P = p.P_post + C * (s.P[k + 1] - p.P_prior) * C.transpose();
    s.P[k] = 0.5 * (P + P.transpose());
  }
  return s;
}

Trajectory rtsSmooth(const Ekf& ekf, const RtsChain& chain) {
  const int wheels =
      static_cast<int>(chain.points.empty() ? 0 : chain.points[0].posterior.xi.size());
  const RtsStates s =
      rtsBackward(chain, wheels, ekf.commonSlipStates(), ekf.hasAccelBias(), ekf.hasIcr());
  Trajectory tr;
  tr.name = "rts";
  tr.has_covariance = true;
  tr.nodes.reserve(chain.node_points.size());
  for (size_t j = 0; j < chain.node_points.size(); ++j) {
    const size_t k = std::min(chain.node_points[j], s.x.size() - 1);
    tr.nodes.push_back(
        ekf.nodeOf(s.x[k], EkfMatrix(s.P[k]), chain.node_t[j], chain.node_inputs[j]));
  }
  return tr;
}

}  // namespace traverse::est
