// smoother::BlockEvaluator (include/traverse/smoother/block_evaluation.h) gives what Ceres'
// Problem::EvaluateResidualBlock(apply_loss = true) gives — cost, loss-corrected residuals and
// tangent-space Jacobians — for the smoother's own residuals with their manifolds and losses at
// random states (random unit quaternions of either sign), including a loss with ρ'' > 0 (the
// corrector's Triggs branch, which Huber and Cauchy never take); and a hand-checked Cauchy value.
#include <gtest/gtest.h>

#include <memory>
#include <random>
#include <vector>

#include <ceres/autodiff_cost_function.h>
#include <ceres/problem.h>

#include "support/jacobian_check.h"
#include "traverse/smoother/block_evaluation.h"
#include "traverse/smoother/body_quaternion_manifold.h"
#include "traverse/smoother/residuals/gyro_increment.h"

namespace traverse::smoother {
namespace {

using testing::randomUnitQuaternion;
using testing::randomVector;
using RowMajorXd = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

/// r = R(q) v − c, three rows over a quaternion (x, y, z, w) and a vector: nonlinear in both.
struct RotatedVector {
  template <typename T>
  bool operator()(const T* q, const T* v, T* r) const {
    const Eigen::Map<const Eigen::Quaternion<T>> Q(q);
    Eigen::Map<Eigen::Matrix<T, 3, 1>>{r} =
        Q * Eigen::Map<const Eigen::Matrix<T, 3, 1>>(v) - Vec3d(0.3, -0.2, 0.5).cast<T>();
    return true;
  }
};

/// ρ(s) = s + 0.05 s²: ρ'' > 0, so the corrector's α ≠ 0 branch is exercised.
class StiffeningLoss final : public ceres::LossFunction {
 public:
  void Evaluate(double s, double rho[3]) const override {
    rho[0] = s + 0.05 * s * s, rho[1] = 1.0 + 0.1 * s, rho[2] = 0.1;
  }
};

/// Compares BlockEvaluator with Problem::EvaluateResidualBlock on one block at the given state.
void expectSameAsCeres(ceres::CostFunction* f, ceres::LossFunction* loss,
                       std::vector<double*> blocks, std::vector<const ceres::Manifold*> manifolds) {
  ceres::Problem::Options po;
  po.cost_function_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  po.loss_function_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  po.manifold_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  ceres::Problem problem(po);
  const std::vector<int32_t>& sizes = f->parameter_block_sizes();
  for (size_t i = 0; i < blocks.size(); ++i)
    problem.AddParameterBlock(blocks[i], sizes[i], const_cast<ceres::Manifold*>(manifolds[i]));
  const ceres::ResidualBlockId id = problem.AddResidualBlock(f, loss, blocks);
  const int rows = f->num_residuals();
  std::vector<std::vector<double>> J_ceres(blocks.size()), J_ours(blocks.size());
  std::vector<double*> p_ceres, p_ours;
  for (size_t i = 0; i < blocks.size(); ++i) {
    const int tangent = manifolds[i] ? manifolds[i]->TangentSize() : sizes[i];
    J_ceres[i].assign(static_cast<size_t>(rows * tangent), 0.0);
    J_ours[i].assign(static_cast<size_t>(rows * tangent), -1.0);
    p_ceres.push_back(J_ceres[i].data()), p_ours.push_back(J_ours[i].data());
  }
  std::vector<double> r_ceres(static_cast<size_t>(rows)), r_ours(static_cast<size_t>(rows));
  double c_ceres = 0, c_ours = 0;
  ASSERT_TRUE(problem.EvaluateResidualBlock(id, true, &c_ceres, r_ceres.data(), p_ceres.data()));
  BlockEvaluator ev;
  ASSERT_TRUE(ev.evaluate(*f, loss, blocks, manifolds, &c_ours, r_ours.data(), p_ours.data()));
  const double tol = 1e-12;
  EXPECT_NEAR(c_ours, c_ceres, tol * std::max(1.0, std::abs(c_ceres)));
  for (int k = 0; k < rows; ++k)
    EXPECT_NEAR(r_ours[static_cast<size_t>(k)], r_ceres[static_cast<size_t>(k)],
                tol * std::max(1.0, std::abs(r_ceres[static_cast<size_t>(k)])));
  for (size_t i = 0; i < blocks.size(); ++i) {
    SCOPED_TRACE(i);
    for (size_t k = 0; k < J_ceres[i].size(); ++k)
      EXPECT_NEAR(J_ours[i][k], J_ceres[i][k], tol * std::max(1.0, std::abs(J_ceres[i][k])));
  }
  // Cost alone, and residuals without Jacobians, agree with the full evaluation (to rounding:
  // autodiff takes its double path then).
  double c_only = 0;
  ASSERT_TRUE(ev.evaluate(*f, loss, blocks, manifolds, &c_only, nullptr, nullptr));
  EXPECT_NEAR(c_only, c_ours, tol * std::max(1.0, std::abs(c_ours)));
  std::vector<double> r_only(static_cast<size_t>(rows));
  ASSERT_TRUE(ev.evaluate(*f, loss, blocks, manifolds, nullptr, r_only.data(), nullptr));
  for (int k = 0; k < rows; ++k)
    EXPECT_NEAR(r_only[static_cast<size_t>(k)], r_ours[static_cast<size_t>(k)],
                tol * std::max(1.0, std::abs(r_ours[static_cast<size_t>(k)])));
}

TEST(BlockEvaluator, MatchesCeresOnQuaternionAndVectorBlocksWithEveryLoss) {
  std::mt19937 rng(11);
  BodyQuaternionManifold quaternion;
  ceres::AutoDiffCostFunction<RotatedVector, 3, 4, 3> f(new RotatedVector);
  ceres::HuberLoss huber(0.5);
  ceres::CauchyLoss cauchy(0.5);
  StiffeningLoss stiffening;
  const std::vector<ceres::LossFunction*> losses = {nullptr, &huber, &cauchy, &stiffening};
  for (int trial = 0; trial < 40; ++trial) {
    SCOPED_TRACE(trial);
    Quatd q = randomUnitQuaternion(rng);
    Vec3d v = randomVector<3>(rng, 2.0);
    expectSameAsCeres(&f, losses[static_cast<size_t>(trial) % losses.size()],
                      {q.coeffs().data(), v.data()}, {&quaternion, nullptr});
  }
}

TEST(BlockEvaluator, MatchesCeresOnTheGyroIncrementWithAHeadingOnlyBias) {
  // The smoother's gyro residual over (q_a, q_b, b) with b's x and y held (SubsetManifold), as a
  // heading-only gyro's segment has it.
  std::mt19937 rng(12);
  BodyQuaternionManifold quaternion;
  ceres::SubsetManifold heading_only(3, {0, 1});
  for (int trial = 0; trial < 20; ++trial) {
    SCOPED_TRACE(trial);
    Quatd qa = randomUnitQuaternion(rng), qb = randomUnitQuaternion(rng);
    Vec3d b = randomVector<3>(rng, 0.01);
    std::unique_ptr<ceres::CostFunction> f(
        GyroIncrementResidual::Create(0.05, randomVector<3>(rng, 0.02), Vec3d(0, 0, 1) / 1e-4));
    expectSameAsCeres(f.get(), nullptr, {qa.coeffs().data(), qb.coeffs().data(), b.data()},
                      {&quaternion, &quaternion, &heading_only});
  }
}

// r = x (one row, J = 1) under Cauchy(1) at x = 2: s = 4, ρ = log(1 + s), ρ' = 1/(1 + s) = 0.2,
// ρ'' < 0 so α = 0: cost ½ log 5, residual √0.2 · 2, Jacobian √0.2.
struct Identity {
  template <typename T>
  bool operator()(const T* x, T* r) const {
    r[0] = x[0];
    return true;
  }
};

TEST(BlockEvaluator, HandCheckedCauchy) {
  ceres::AutoDiffCostFunction<Identity, 1, 1> f(new Identity);
  ceres::CauchyLoss cauchy(1.0);
  double x = 2.0, cost = 0, r = 0, J = 0;
  double* jacobians[] = {&J};
  double* blocks[] = {&x};
  const ceres::Manifold* manifolds[] = {nullptr};
  BlockEvaluator ev;
  ASSERT_TRUE(ev.evaluate(f, &cauchy, blocks, manifolds, &cost, &r, jacobians));
  EXPECT_NEAR(cost, 0.5 * std::log(5.0), 1e-15);
  EXPECT_NEAR(r, std::sqrt(0.2) * 2.0, 1e-15);
  EXPECT_NEAR(J, std::sqrt(0.2), 1e-15);
}

TEST(BlockEvaluator, RejectsANonFiniteResidual) {
  ceres::AutoDiffCostFunction<Identity, 1, 1> f(new Identity);
  double x = std::numeric_limits<double>::quiet_NaN(), cost = 0;
  double* blocks[] = {&x};
  const ceres::Manifold* manifolds[] = {nullptr};
  BlockEvaluator ev;
  EXPECT_FALSE(ev.evaluate(f, nullptr, blocks, manifolds, &cost, nullptr, nullptr));
}

}  // namespace
}  // namespace traverse::smoother
