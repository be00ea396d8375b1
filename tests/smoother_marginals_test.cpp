// Exact chain marginals: against the dense inverse, ceres::Covariance and a Monte Carlo of a
// linear-Gaussian chain.
#include <algorithm>
#include <cmath>
#include <random>

#include <ceres/ceres.h>
#include <gtest/gtest.h>
#include <Eigen/Cholesky>

#include "traverse/smoother/chain_marginals.h"

namespace traverse::smoother {
namespace {

using Eigen::MatrixXd;
using Eigen::VectorXd;
using RowMajorMatrixXd = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

MatrixXd gaussianMatrix(std::mt19937& rng, int rows, int cols) {
  std::normal_distribution<double> n(0.0, 1.0);
  MatrixXd M(rows, cols);
  for (Eigen::Index i = 0; i < M.size(); ++i) M.data()[i] = n(rng);
  return M;
}

/// A random full-column-rank chain Jacobian: d rows on each node pair (k, k+1) and the global
/// columns, d rows on each node and the global columns, m rows on the global columns alone.
MatrixXd randomChainJacobian(std::mt19937& rng, int n, int d, int m) {
  const int cols = n * d + m;
  MatrixXd J = MatrixXd::Zero((2 * n - 1) * d + m, cols);
  int r = 0;
  for (int k = 0; k < n; ++k) {
    const int span = k + 1 < n ? 2 * d : d;
    for (int pass = 0; pass < (k + 1 < n ? 2 : 1); ++pass, r += d) {
      const int width = pass == 0 ? span : d;  // the second pass touches node k alone
      J.block(r, k * d, d, width) = gaussianMatrix(rng, d, width);
      J.block(r, n * d, d, m) = gaussianMatrix(rng, d, m);
    }
  }
  J.block(r, n * d, m, m) = gaussianMatrix(rng, m, m) + 3.0 * MatrixXd::Identity(m, m);
  return J;
}

ChainInformation chainFromDense(const MatrixXd& H, int n, int d, int m) {
  ChainInformation C = makeChainInformation(n, d, m);
  for (int k = 0; k < n; ++k) {
    C.diag[k] = H.block(k * d, k * d, d, d);
    C.global_coupling[k] = H.block(k * d, n * d, d, m);
    if (k + 1 < n) C.upper[k] = H.block(k * d, (k + 1) * d, d, d);
  }
  C.global = H.block(n * d, n * d, m, m);
  return C;
}

ceres::CRSMatrix denseToCrs(const MatrixXd& J) {
  ceres::CRSMatrix crs;
  crs.num_rows = static_cast<int>(J.rows());
  crs.num_cols = static_cast<int>(J.cols());
  crs.rows.push_back(0);
  for (int r = 0; r < crs.num_rows; ++r) {
    for (int c = 0; c < crs.num_cols; ++c) {
      if (J(r, c) == 0.0) continue;
      crs.cols.push_back(c);
      crs.values.push_back(J(r, c));
    }
    crs.rows.push_back(static_cast<int>(crs.cols.size()));
  }
  return crs;
}

MatrixXd crsToDense(const ceres::CRSMatrix& crs) {
  MatrixXd J = MatrixXd::Zero(crs.num_rows, crs.num_cols);
  for (int r = 0; r < crs.num_rows; ++r)
    for (int i = crs.rows[r]; i < crs.rows[r + 1]; ++i) J(r, crs.cols[i]) += crs.values[i];
  return J;
}

/// Every block chainMarginals returns equals the same block of `Sigma` to `tol` relative to
/// Σ's largest entry.
void expectMatchesCovariance(const ChainMarginals& M, const MatrixXd& Sigma, int n, int d, int m,
                             double tol) {
  ASSERT_TRUE(M.ok);
  ASSERT_EQ(M.node.size(), static_cast<size_t>(n));
  ASSERT_EQ(M.node_global.size(), static_cast<size_t>(n));
  const double scale = tol * Sigma.cwiseAbs().maxCoeff();
  for (int k = 0; k < n; ++k) {
    EXPECT_LE((M.node[k] - Sigma.block(k * d, k * d, d, d)).cwiseAbs().maxCoeff(), scale)
        << "node " << k;
    EXPECT_EQ(M.node[k], M.node[k].transpose()) << "node " << k;
    if (m > 0) {
      EXPECT_LE((M.node_global[k] - Sigma.block(k * d, n * d, d, m)).cwiseAbs().maxCoeff(), scale)
          << "node-global " << k;
    }
  }
  ASSERT_EQ(M.global.rows(), m);
  if (m > 0) {
    EXPECT_LE((M.global - Sigma.bottomRightCorner(m, m)).cwiseAbs().maxCoeff(), scale);
  }
}

/// Every stored block of C equals expected's to 1e-12 relative.
void expectSameInformation(const ChainInformation& C, const ChainInformation& expected) {
  const auto close = [](const MatrixXd& a, const MatrixXd& b) {
    return (a - b).cwiseAbs().maxCoeff() <= 1e-12 * std::max(1.0, b.cwiseAbs().maxCoeff());
  };
  const int n = expected.numNodes(), m = expected.global_dim;
  ASSERT_EQ(C.numNodes(), n);
  for (int k = 0; k < n; ++k) {
    EXPECT_TRUE(close(C.diag[k], expected.diag[k])) << k;
    if (m > 0) {
      EXPECT_TRUE(close(C.global_coupling[k], expected.global_coupling[k])) << k;
    }
    if (k + 1 < n) {
      EXPECT_TRUE(close(C.upper[k], expected.upper[k])) << k;
    }
  }
  if (m > 0) {
    EXPECT_TRUE(close(C.global, expected.global));
  }
}

TEST(Marginals, MatchDenseInverse) {
  std::mt19937 rng(7);
  const int d = 4;
  for (int n : {1, 2, 7}) {
    for (int m : {0, 3}) {
      SCOPED_TRACE("N = " + std::to_string(n) + ", m = " + std::to_string(m));
      const MatrixXd J = randomChainJacobian(rng, n, d, m);
      const MatrixXd H = J.transpose() * J;
      const MatrixXd Sigma = H.llt().solve(MatrixXd::Identity(H.rows(), H.cols()));
      expectMatchesCovariance(chainMarginals(chainFromDense(H, n, d, m)), Sigma, n, d, m, 1e-9);
    }
  }
}

TEST(Marginals, NotPositiveDefiniteIsReported) {
  std::mt19937 rng(3);
  const int n = 4, d = 3, m = 2;
  MatrixXd J = randomChainJacobian(rng, n, d, m);
  J.col(2 * d + 1).setZero();  // a node direction nothing observes
  EXPECT_FALSE(chainMarginals(chainFromDense(J.transpose() * J, n, d, m)).ok);
  J = randomChainJacobian(rng, n, d, m);
  J.col(n * d).setZero();  // an unobserved global direction
  EXPECT_FALSE(chainMarginals(chainFromDense(J.transpose() * J, n, d, m)).ok);
}

TEST(Marginals, InformationFromCrsMatchesDenseNormalEquations) {
  std::mt19937 rng(11);
  for (int m : {0, 3}) {
    const int n = 6, d = 3;
    MatrixXd J = randomChainJacobian(rng, n, d, m);
    // Sparsify, and shuffle the rows so windows change often (single-node rows at the last node,
    // global-only rows between node rows).
    std::bernoulli_distribution keep(0.7);
    for (Eigen::Index i = 0; i < J.size(); ++i)
      if (!keep(rng)) J.data()[i] = 0.0;
    std::vector<int> order(static_cast<size_t>(J.rows()));
    for (size_t i = 0; i < order.size(); ++i) order[i] = static_cast<int>(i);
    std::shuffle(order.begin(), order.end(), rng);
    const MatrixXd Js = J(order, Eigen::all);
    const MatrixXd H = Js.transpose() * Js;
    const ChainInformation C = chainInformationFromJacobian(denseToCrs(Js), n, d, m);
    const ChainInformation expected = chainFromDense(H, n, d, m);
    expectSameInformation(C, expected);
  }
}
TEST(Marginals, InformationFromResidualBlocksMatchesDenseNormalEquations) {
  // Residual blocks of 1-4 rows over 1-5 parameter blocks, in random order, whose places split
  // the node columns unevenly (d = 5: columns 0-1, 2, 3-4) and the global ones (m = 3: 0, 1-2):
  // the sum of their JᵀJ must equal the dense normal equations.
  std::mt19937 rng(17);
  for (int m : {0, 3}) {
    const int n = 5, d = 5;
    const std::vector<std::pair<int, int>> node_parts{{0, 2}, {2, 1}, {3, 2}};
    const std::vector<std::pair<int, int>> global_parts{{0, 1}, {1, 2}};
    std::vector<ChainPlace> all;
    MatrixXd J_all(0, n * d + m);
    ChainInformation C = makeChainInformation(n, d, m);
    std::uniform_int_distribution<int> node(0, n - 1), rows(1, 4), coin(0, 1);
    for (int r = 0; r < 60; ++r) {
      const int k = node(rng), k2 = std::min(k + coin(rng), n - 1);
      std::vector<ChainPlace> places;
      const std::vector<int> touched = k2 == k ? std::vector<int>{k} : std::vector<int>{k, k2};
      for (int kk : touched) {
        for (const auto& [col, size] : node_parts)
          if (coin(rng)) places.push_back({kk, col, size});
      }
      if (m > 0) {
        for (const auto& [col, size] : global_parts)
          if (coin(rng)) places.push_back({ChainPlace::kGlobal, col, size});
      }
      if (places.empty()) continue;
      std::shuffle(places.begin(), places.end(), rng);
      const int nr = rows(rng);
      std::vector<RowMajorMatrixXd> blocks;
      std::vector<const double*> ptrs;
      MatrixXd dense = MatrixXd::Zero(nr, n * d + m);
      for (const ChainPlace& p : places) {
        blocks.push_back(gaussianMatrix(rng, nr, p.size));
        const int c0 = p.node == ChainPlace::kGlobal ? n * d + p.col : p.node * d + p.col;
        dense.middleCols(c0, p.size) = blocks.back();
      }
      for (const auto& b : blocks) ptrs.push_back(b.data());
      addChainResidual(C, places, ptrs.data(), nr);
      J_all.conservativeResize(J_all.rows() + nr, Eigen::NoChange);
      J_all.bottomRows(nr) = dense;
    }
    const ChainInformation expected = chainFromDense(J_all.transpose() * J_all, n, d, m);
    expectSameInformation(C, expected);
  }
}

TEST(Marginals, InformationFromResidualBlocksRejectsBadPlaces) {
  ChainInformation C = makeChainInformation(3, 2, 1);
  const double J[2] = {1.0, 2.0};
  const double* ptrs[2] = {J, J};
  const std::vector<ChainPlace> far{{0, 0, 1}, {2, 0, 1}};  // nodes 0 and 2
  EXPECT_THROW(addChainResidual(C, far, ptrs, 2), std::invalid_argument);
  const std::vector<ChainPlace> wide{{1, 1, 2}};  // columns 1-2 of a 2-column node
  EXPECT_THROW(addChainResidual(C, wide, ptrs, 1), std::invalid_argument);
  const std::vector<ChainPlace> global{{ChainPlace::kGlobal, 1, 1}};  // m = 1
  EXPECT_THROW(addChainResidual(C, global, ptrs, 1), std::invalid_argument);
}

TEST(Marginals, InformationFromCrsRejectsNonAdjacentRow) {
  const int n = 3, d = 2, m = 1;
  MatrixXd J = MatrixXd::Zero(4, n * d + m);
  J(0, 0) = J(1, 2) = J(2, 6) = 1.0;
  J(3, 1) = J(3, 5) = 1.0;  // nodes 0 and 2
  try {
    chainInformationFromJacobian(denseToCrs(J), n, d, m);
    FAIL() << "expected std::invalid_argument";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("row 3"), std::string::npos) << e.what();
  }
  EXPECT_THROW(chainInformationFromJacobian(denseToCrs(J), n, d, m + 1), std::invalid_argument);
}

/// r = Σᵢ Aᵢ xᵢ − b over any number of parameter blocks: a linear residual of any shape.
class LinearCost final : public ceres::CostFunction {
 public:
  LinearCost(std::vector<MatrixXd> A, VectorXd b) : A_(std::move(A)), b_(std::move(b)) {
    set_num_residuals(static_cast<int>(b_.size()));
    for (const MatrixXd& Ai : A_) mutable_parameter_block_sizes()->push_back(Ai.cols());
  }
  bool Evaluate(double const* const* x, double* residuals, double** jacobians) const override {
    Eigen::Map<VectorXd> r(residuals, b_.size());
    r = -b_;
    for (size_t i = 0; i < A_.size(); ++i) {
      r += A_[i] * Eigen::Map<const VectorXd>(x[i], A_[i].cols());
      if (jacobians != nullptr && jacobians[i] != nullptr)
        Eigen::Map<RowMajorMatrixXd>(jacobians[i], A_[i].rows(), A_[i].cols()) = A_[i];
    }
    return true;
  }

 private:
  std::vector<MatrixXd> A_;
  VectorXd b_;
};

/// A chain problem's parameter storage: N node blocks then one global block.
struct ChainParameters {
  std::vector<VectorXd> nodes;
  VectorXd global;
  std::vector<double*> order() {
    std::vector<double*> p;
    for (VectorXd& x : nodes) p.push_back(x.data());
    if (global.size() > 0) p.push_back(global.data());
    return p;
  }
};

MatrixXd evaluateJacobian(ceres::Problem& problem, ChainParameters& params) {
  ceres::Problem::EvaluateOptions options;
  options.parameter_blocks = params.order();
  ceres::CRSMatrix crs;
  EXPECT_TRUE(problem.Evaluate(options, nullptr, nullptr, nullptr, &crs));
  return crsToDense(crs);
}

TEST(Marginals, MatchCeresCovariance) {
  std::mt19937 rng(5);
  const int n = 6, d = 3, m = 3;
  ChainParameters p;
  for (int k = 0; k < n; ++k) p.nodes.push_back(gaussianMatrix(rng, d, 1));
  p.global = gaussianMatrix(rng, m, 1);
  ceres::Problem problem;
  for (int k = 0; k < n; ++k) {
    problem.AddResidualBlock(new LinearCost({gaussianMatrix(rng, d, d), gaussianMatrix(rng, d, m)},
                                            gaussianMatrix(rng, d, 1)),
                             nullptr, p.nodes[k].data(), p.global.data());
    if (k + 1 < n) {
      problem.AddResidualBlock(new LinearCost({gaussianMatrix(rng, d, d), gaussianMatrix(rng, d, d),
                                               gaussianMatrix(rng, d, m)},
                                              gaussianMatrix(rng, d, 1)),
                               nullptr, p.nodes[k].data(), p.nodes[k + 1].data(), p.global.data());
    }
  }
  problem.AddResidualBlock(new LinearCost({MatrixXd::Identity(m, m)}, VectorXd::Zero(m)), nullptr,
                           p.global.data());

  const MatrixXd J = evaluateJacobian(problem, p);
  const ChainMarginals M = chainMarginals(chainInformationFromJacobian(denseToCrs(J), n, d, m));
  ASSERT_TRUE(M.ok);

  ceres::Covariance::Options options;
  options.algorithm_type = ceres::SPARSE_QR;
  options.sparse_linear_algebra_library_type = ceres::SUITE_SPARSE;
  ceres::Covariance covariance(options);
  std::vector<std::pair<const double*, const double*>> blocks;
  for (int k = 0; k < n; ++k) {
    blocks.emplace_back(p.nodes[k].data(), p.nodes[k].data());
    blocks.emplace_back(p.nodes[k].data(), p.global.data());
  }
  blocks.emplace_back(p.global.data(), p.global.data());
  ASSERT_TRUE(covariance.Compute(blocks, &problem));

  RowMajorMatrixXd S(d, d), S_g(d, m), S_gg(m, m);
  const double tol = 1e-9 * std::max(1.0, M.global.cwiseAbs().maxCoeff());
  for (int k = 0; k < n; ++k) {
    ASSERT_TRUE(covariance.GetCovarianceBlock(p.nodes[k].data(), p.nodes[k].data(), S.data()));
    ASSERT_TRUE(covariance.GetCovarianceBlock(p.nodes[k].data(), p.global.data(), S_g.data()));
    EXPECT_LE((M.node[k] - S).cwiseAbs().maxCoeff(), tol * std::max(1.0, S.cwiseAbs().maxCoeff()))
        << "node " << k << "\nchain:\n"
        << M.node[k] << "\nceres:\n"
        << S;
    EXPECT_LE((M.node_global[k] - S_g).cwiseAbs().maxCoeff(), tol) << "node " << k;
  }
  ASSERT_TRUE(covariance.GetCovarianceBlock(p.global.data(), p.global.data(), S_gg.data()));
  EXPECT_LE((M.global - S_gg).cwiseAbs().maxCoeff(), tol);
}

// A 2-D random walk x_{k+1} = x_k + u_k (odometry u_k measured with σ_p), each node observed as
// z_k = x_k + b (σ_m) through one global offset b, and a prior on x_0 (σ_0). The problem is
// linear, so the least-squares error is exactly N(0, H⁻¹): the sample covariance of the
// estimates' errors must match the chain marginals.
struct RandomWalkChain {
  static constexpr int kNodes = 10, kDim = 2;
  double sigma_prior = 0.1, sigma_process = 0.05, sigma_meas = 0.2;
  std::vector<VectorXd> truth;
  VectorXd offset = (VectorXd(kDim) << 0.3, -0.2).finished();

  /// One noise realisation's residual blocks, added to `problem` in a fixed order. Every block's
  /// right side b is appended to `y`, so y is the whitened measurement vector in Ceres' row
  /// order (the residual at x = 0 is −y).
  void addResiduals(std::mt19937& rng, ChainParameters& p, ceres::Problem& problem,
                    VectorXd& y) const {
    std::normal_distribution<double> n(0.0, 1.0);
    const auto noise = [&](double sigma) {
      return VectorXd(VectorXd::NullaryExpr(kDim, [&] { return sigma * n(rng); }));
    };
    const MatrixXd I = MatrixXd::Identity(kDim, kDim);
    std::vector<VectorXd> bs;
    const auto add = [&](std::vector<MatrixXd> A, VectorXd b, std::vector<double*> blocks) {
      bs.push_back(b);
      problem.AddResidualBlock(new LinearCost(std::move(A), std::move(b)), nullptr, blocks);
    };
    add({I / sigma_prior}, (truth[0] + noise(sigma_prior)) / sigma_prior, {p.nodes[0].data()});
    for (int k = 0; k < kNodes; ++k) {
      if (k + 1 < kNodes) {
        const VectorXd u = truth[k + 1] - truth[k] + noise(sigma_process);
        add({-I / sigma_process, I / sigma_process}, u / sigma_process,
            {p.nodes[k].data(), p.nodes[k + 1].data()});
      }
      const VectorXd z = truth[k] + offset + noise(sigma_meas);
      add({I / sigma_meas, I / sigma_meas}, z / sigma_meas, {p.nodes[k].data(), p.global.data()});
    }
    y.resize(static_cast<Eigen::Index>(bs.size()) * kDim);
    for (size_t i = 0; i < bs.size(); ++i)
      y.segment(static_cast<Eigen::Index>(i) * kDim, kDim) = bs[i];
  }

  ChainParameters zeroParameters() const {
    ChainParameters p;
    p.nodes.assign(kNodes, VectorXd::Zero(kDim));
    p.global = VectorXd::Zero(kDim);
    return p;
  }
};

TEST(Marginals, MonteCarloSampleCovarianceMatches) {
  constexpr int kN = RandomWalkChain::kNodes, kD = RandomWalkChain::kDim, kM = kD;
  constexpr int kSamples = 2000, kCeresRuns = 3;
  RandomWalkChain chain;
  std::mt19937 rng(2024);
  std::normal_distribution<double> step(0.0, 1.0);
  chain.truth.assign(kN, VectorXd::Zero(kD));
  for (int k = 1; k < kN; ++k)
    chain.truth[k] = chain.truth[k - 1] + VectorXd::NullaryExpr(kD, [&] { return step(rng); });

  // The Jacobian is the same for every realisation; take it (and the marginals) from Ceres once.
  ChainParameters p0 = chain.zeroParameters();
  MatrixXd J;
  {
    ceres::Problem problem;
    VectorXd y;
    chain.addResiduals(rng, p0, problem, y);
    J = evaluateJacobian(problem, p0);
  }
  const ChainMarginals M = chainMarginals(chainInformationFromJacobian(denseToCrs(J), kN, kD, kM));
  ASSERT_TRUE(M.ok);
  const Eigen::LLT<MatrixXd> normal(J.transpose() * J);

  VectorXd truth(kN * kD + kM);
  for (int k = 0; k < kN; ++k) truth.segment(k * kD, kD) = chain.truth[k];
  truth.tail(kM) = chain.offset;
  MatrixXd scatter = MatrixXd::Zero(truth.size(), truth.size());
  VectorXd mean_error = VectorXd::Zero(truth.size());
  for (int s = 0; s < kSamples; ++s) {
    ChainParameters p = chain.zeroParameters();
    ceres::Problem problem;
    VectorXd y;
    chain.addResiduals(rng, p, problem, y);
    // Linear least squares: one Gauss-Newton step from 0 is the optimum.
    const VectorXd x = normal.solve(J.transpose() * y);
    if (s < kCeresRuns) {  // the same problem solved by Ceres lands on the same estimate
      ceres::Solver::Options options;
      options.linear_solver_type = ceres::DENSE_QR;
      options.initial_trust_region_radius = 1e16;  // LM damping ~ 1/radius: a Gauss-Newton step
      options.max_trust_region_radius = 1e32;
      ceres::Solver::Summary summary;
      ceres::Solve(options, &problem, &summary);
      ASSERT_TRUE(summary.IsSolutionUsable()) << summary.BriefReport();
      for (int k = 0; k < kN; ++k)
        EXPECT_LE((p.nodes[k] - x.segment(k * kD, kD)).cwiseAbs().maxCoeff(), 1e-8) << k;
      EXPECT_LE((p.global - x.tail(kM)).cwiseAbs().maxCoeff(), 1e-8);
    }
    const VectorXd e = x - truth;
    mean_error += e / kSamples;
    scatter.noalias() += e * e.transpose() / kSamples;  // the true mean error is 0
  }

  // With the known zero mean, n·σ̂²/σ² ~ χ²_n, so σ̂²/σ² has standard deviation sqrt(2/n)
  // (3.2 % for n = 2000). 22 variances are checked; at 4 standard deviations (12.6 %) the chance
  // that any one fails by chance is below 22 · 6.3e-5 ≈ 1.4e-3 (union bound), while a wrong
  // recursion changes them by far more: ignoring the global coupling (the K_k terms) gives 28–47 %
  // of the true node variances here, ignoring the chain coupling 5–19 %. The mean error is
  // checked at 4 standard errors σ/sqrt(n).
  const double var_tol = 4.0 * std::sqrt(2.0 / kSamples);
  const auto check = [&](const MatrixXd& marginal, int offset, const std::string& what) {
    for (int i = 0; i < marginal.rows(); ++i) {
      const double var = marginal(i, i), sample = scatter(offset + i, offset + i);
      EXPECT_NEAR(sample / var, 1.0, var_tol) << what << " axis " << i;
      EXPECT_LE(std::abs(mean_error[offset + i]), 4.0 * std::sqrt(var / kSamples))
          << what << " axis " << i;
    }
  };
  for (int k = 0; k < kN; ++k) check(M.node[k], k * kD, "node " + std::to_string(k));
  check(M.global, kN * kD, "offset");
}

}  // namespace
}  // namespace traverse::smoother
