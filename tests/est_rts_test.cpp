// The Rauch–Tung–Striebel smoother over the EKF (estimators/rts.h): its state algebra at random
// states, the backward pass against the batch least-squares solution of a linear-Gaussian chain
// (for which RTS is exact), and the smoother on a bundled log (one node per filter node, the
// last equal to the filter's, attitude no worse).
#include <array>
#include <random>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "support/ekf_state.h"
#include "support/jacobian_check.h"
#include "traverse/estimators/ekf.h"
#include "traverse/estimators/initialization.h"
#include "traverse/estimators/rts.h"
#include "traverse/estimators/segmentation.h"
#include "traverse/eval/metrics.h"
#include "traverse/eval/truth.h"
#include "traverse/io/log_reader.h"

namespace traverse::est {
namespace {

using I = EkfIndex;

TEST(EstRts, StateDifferenceAndPlusAreInversesAtRandomStates) {
  std::mt19937 rng(7);
  for (int trial = 0; trial < 50; ++trial) {
    const int wheels = 4 + trial % 3;
    // every combination of c (none, c_x c_y, with c_ω) and b_a
    const int c = std::array{0, 2, 3}[trial % 3];
    const bool ab = trial % 4 < 2;
    const EkfState a = testing::randomEkfState(rng, wheels, c, ab);
    const EkfState b = testing::randomEkfState(rng, wheels, c, ab);
    const EkfVector d = ekfStateDifference(a, b, wheels, c, ab);
    ASSERT_EQ(d.size(), ekfStates(wheels, c, ab ? kAccelBiasStates : 0));
    const EkfState back = ekfStatePlus(b, d, wheels, c, ab);
    EXPECT_LT(so3::boxminus(back.q_site_body, a.q_site_body).norm(), 1e-12);
    EXPECT_LT((back.p_site - a.p_site).norm(), 1e-12);
    EXPECT_LT((back.xi - a.xi).norm(), 1e-12);
    EXPECT_LT((back.common_slip - a.common_slip).norm(), 1e-12);
    EXPECT_LT((back.accel_bias - a.accel_bias).norm(), 1e-12);
    // The filter's own ⊞ (the tests' reference) agrees.
    const EkfState ref = testing::ekfBoxplus(b, d, c, ab);
    EXPECT_LT(so3::boxminus(ref.q_site_body, back.q_site_body).norm(), 1e-12);
  }
  // Hand-checked: 0.1 rad about z between identity and Rz(0.1), 2 m in x.
  EkfState a, b;
  a.xi.resize(4), b.xi.resize(4);
  a.xi.setZero(), b.xi.setZero();
  a.q_site_body = Quatd(Eigen::AngleAxisd(0.1, Vec3d::UnitZ()));
  a.p_site = Vec3d(2, 0, 0);
  const EkfVector d = ekfStateDifference(a, b, 4, 0);
  EXPECT_NEAR(d[I::kTheta + 2], 0.1, 1e-15);
  EXPECT_NEAR(d[I::kPos], 2.0, 1e-15);
  EXPECT_NEAR(d.norm(), std::hypot(0.1, 2.0), 1e-15);
}

/// A linear-Gaussian chain in two of the filter's states — position x and velocity v along
/// body x: x' = x + dt v, v' = v + w (var q), z_k = x_k + e (var r) — filtered by hand into an
/// RtsChain; every other state constant with unit variance and no measurement.
TEST(EstRts, BackwardPassEqualsBatchLeastSquaresOnALinearChain) {
  const int wheels = 4, n = ekfStates(wheels);
  const int N = 25;
  const double dt = 0.5, q = 0.04, r = 0.09;
  std::mt19937 rng(3);
  std::normal_distribution<double> g(0.0, 1.0);
  std::vector<double> z(N);
  double xt = 0, vt = 0.3;
  for (int k = 0; k < N; ++k) {
    z[k] = xt + std::sqrt(r) * g(rng);
    xt += dt * vt;
    vt += std::sqrt(q) * g(rng);
  }
  const int ix = I::kPos, iv = I::kVel;
  Eigen::MatrixXd phi = Eigen::MatrixXd::Identity(n, n);
  phi(ix, iv) = dt;
  Eigen::MatrixXd Q = Eigen::MatrixXd::Zero(n, n);
  Q(iv, iv) = q;
  EkfState x;
  x.xi.resize(wheels);
  x.xi.setZero();
  Eigen::MatrixXd P = Eigen::MatrixXd::Identity(n, n);  // prior: x0, v0 ~ N(0, 1)
  RtsChain chain;
  auto get = [&](const EkfState& s) { return Eigen::Vector2d(s.p_site.x(), s.v_p.x()); };
  for (int k = 0; k < N; ++k) {
    if (k > 0) {  // propagate from the previous posterior
      chain.points.back().phi = phi;
      const Eigen::Vector2d m = get(x);
      x.p_site.x() = m[0] + dt * m[1];
      P = phi * P * phi.transpose() + Q;
      chain.points.back().prior = x;
      chain.points.back().P_prior = P;
    }
    // Update with z_k on x.
    const double S = P(ix, ix) + r;
    const Eigen::VectorXd K = P.col(ix) / S;
    const double innov = z[k] - x.p_site.x();
    x.p_site.x() += K[ix] * innov;
    x.v_p.x() += K[iv] * innov;
    P = P - K * P.row(ix);
    P = 0.5 * (P + P.transpose());
    chain.points.push_back({x, P, {}, {}, {}});
  }
  const RtsStates s = rtsBackward(chain, wheels, 0);

  // Batch least squares. The position follows the velocities exactly, so the unknowns are
  // u = (x_0, v_0 … v_{N−1}) and the states (x_k, v_k) = T u with x_k = x_0 + dt Σ_{j<k} v_j.
  const int m = 2 * N, nu = N + 1;
  Eigen::MatrixXd T = Eigen::MatrixXd::Zero(m, nu);
  for (int k = 0; k < N; ++k) {
    T(2 * k, 0) = 1.0;
    for (int j = 0; j < k; ++j) T(2 * k, 1 + j) = dt;
    T(2 * k + 1, 1 + k) = 1.0;
  }
  Eigen::MatrixXd A = Eigen::MatrixXd::Zero(nu, nu);
  Eigen::VectorXd bvec = Eigen::VectorXd::Zero(nu);
  A(0, 0) += 1.0, A(1, 1) += 1.0;  // prior x_0, v_0 ~ N(0, 1)
  for (int k = 0; k < N; ++k) {    // z_k = x_k + e
    const Eigen::RowVectorXd h = T.row(2 * k);
    A += h.transpose() * h / r;
    bvec += h.transpose() * z[k] / r;
  }
  for (int k = 0; k + 1 < N; ++k) {  // v_{k+1} − v_k ~ N(0, q)
    Eigen::RowVectorXd h = Eigen::RowVectorXd::Zero(nu);
    h[2 + k] = 1.0, h[1 + k] = -1.0;
    A += h.transpose() * h / q;
  }
  const Eigen::MatrixXd cov_u = A.inverse();
  const Eigen::VectorXd mean = T * (cov_u * bvec);
  const Eigen::MatrixXd cov = T * cov_u * T.transpose();
  for (int k = 0; k < N; ++k) {
    EXPECT_NEAR(s.x[k].p_site.x(), mean[2 * k], 1e-9) << k;
    EXPECT_NEAR(s.x[k].v_p.x(), mean[2 * k + 1], 1e-9) << k;
    EXPECT_NEAR(s.P[k](ix, ix), cov(2 * k, 2 * k), 1e-9) << k;
    EXPECT_NEAR(s.P[k](iv, iv), cov(2 * k + 1, 2 * k + 1), 1e-9) << k;
    EXPECT_NEAR(s.P[k](I::kBias, I::kBias), 1.0, 1e-12);  // untouched states stay as they were
  }
  // The last smoothed point is the last filtered one.
  EXPECT_EQ(s.x[N - 1].p_site, chain.points[N - 1].posterior.p_site);
}

TEST(EstRts, OnTheBundledLogOneNodePerFilterNodeAndTheLastIsTheFilters) {
  const io::TraverseLog log =
      io::readLog(std::filesystem::path(testing::sourceDir()) / "datasets/logs/straight-1m");
  const Segmentation seg = segment(log);
  const InitialState init = initialState(log, seg, InitOptions{});
  EkfOptions options;
  options.rts = true;
  const EkfResult r = runEkf(log, seg, init, options);
  ASSERT_TRUE(r.rts);
  const Trajectory& ekf = r.trajectory;
  const Trajectory& rts = *r.rts;
  EXPECT_EQ(rts.name, "rts");
  ASSERT_EQ(rts.nodes.size(), ekf.nodes.size());
  for (size_t i = 0; i < ekf.nodes.size(); i += 97) EXPECT_EQ(rts.nodes[i].t, ekf.nodes[i].t);
  EXPECT_LT((rts.nodes.back().p_site - ekf.nodes.back().p_site).norm(), 1e-9);
  // Smoothing uses later data: attitude no worse, and its σ no larger anywhere.
  const eval::TruthTrajectory truth(*log.truth);
  const eval::Metrics me = eval::evaluate(ekf, truth), mr = eval::evaluate(rts, truth);
  EXPECT_LE(*mr.get("yaw_rmse_deg"), *me.get("yaw_rmse_deg"));
  EXPECT_LE(*mr.get("roll_rmse_deg"), *me.get("roll_rmse_deg"));
  for (size_t i = 0; i < ekf.nodes.size(); ++i) {
    ASSERT_LE(rts.nodes[i].covariance.trace(), ekf.nodes[i].covariance.trace() * (1 + 1e-9) + 1e-15)
        << i;
  }
  // Without the option: nothing recorded, nothing returned.
  EXPECT_FALSE(runEkf(log, seg, init, EkfOptions{}).rts);
}

}  // namespace
}  // namespace traverse::est
