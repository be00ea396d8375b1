// The batch smoother's residual functors (include/traverse/smoother/residuals/) and its attitude
// manifold (body_quaternion_manifold.h).
//
//  - BodyQuaternionManifold: the invariants Ceres' own manifold tests check (Plus(x, 0) = x,
//    Minus(Plus(x, δ), x) = δ, Minus(x, x) = 0, Plus/Minus Jacobians against finite differences,
//    MinusJacobian · PlusJacobian = I) at random unit quaternions of either sign.
//  - Every residual: the Jacobians the ceres::CostFunction reports (w.r.t. the AMBIENT
//    parameters, 4 per quaternion) times PlusJacobian against central differences of the
//    residual in the tangent space (q ⊗ Exp(δθ), vectors additive) at random plausible states,
//    through one generic helper; and a value worked out by hand.
//  - The constraints that add them (residual_collector.h): the blocks each entry takes, cost
//    functions shared exactly when the functors are equal (CostMemo), and the collector's cost
//    against Ceres' own evaluation of the same problem.
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <memory>
#include <string>
#include <vector>

#include <ceres/cost_function.h>
#include <ceres/loss_function.h>
#include <ceres/problem.h>

#include "support/jacobian_check.h"
#include "support/rocky7_coords.h"
#include "traverse/io/rover_description.h"
#include "traverse/rover/kinematics.h"
#include "traverse/rover/nominal_slip.h"
#include "traverse/rover/slip_constraint.h"
#include "traverse/sensors/gravity.h"
#include "traverse/sensors/sun_sensor.h"
#include "traverse/smoother/body_quaternion_manifold.h"
#include "traverse/smoother/residual_collector.h"
#include "traverse/smoother/residuals/accel_velocity_process.h"
#include "traverse/smoother/residuals/attitude_process.h"
#include "traverse/smoother/residuals/gravity_residual.h"
#include "traverse/smoother/residuals/gyro_increment.h"
#include "traverse/smoother/residuals/markov_process.h"
#include "traverse/smoother/residuals/position_process.h"
#include "traverse/smoother/residuals/rest_bias_residual.h"
#include "traverse/smoother/residuals/slip_residual.h"
#include "traverse/smoother/residuals/start_prior_residual.h"
#include "traverse/smoother/residuals/sun_sensor_residual.h"
#include "traverse/smoother/residuals/whitening.h"
#include "traverse/smoother/residuals/zero_motion_residual.h"

namespace traverse::smoother {
namespace {

using testing::randomUnitQuaternion;
using testing::randomVector;

using RowMajorXd = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
using Params = std::vector<std::vector<double>>;

constexpr double kGravity = 9.80665;
constexpr int kTrials = 25;

std::vector<double> block(const Quatd& q) {
  return {q.x(), q.y(), q.z(), q.w()};
}
template <int N>
std::vector<double> block(const Eigen::Matrix<double, N, 1>& v) {
  return std::vector<double>(v.data(), v.data() + N);
}
Quatd quat(const std::vector<double>& b) {
  return Quatd(b[3], b[0], b[1], b[2]);
}

/// Body-frame tangent Jacobian of the manifold's Plus at x (4×3, row-major).
RowMajorXd plusJacobian(const double* x) {
  RowMajorXd P(4, 3);
  BodyQuaternionManifold().PlusJacobian(x, P.data());
  return P;
}

Eigen::VectorXd evaluate(const ceres::CostFunction& cf, const Params& params, double** jacobians) {
  std::vector<const double*> ptrs;
  for (const auto& b : params) ptrs.push_back(b.data());
  Eigen::VectorXd r(cf.num_residuals());
  EXPECT_TRUE(cf.Evaluate(ptrs.data(), r.data(), jacobians));
  return r;
}

Eigen::VectorXd evaluate(const ceres::CostFunction& cf, const Params& params) {
  return evaluate(cf, params, nullptr);
}

/// Tangent-space Jacobians (one m × tangent-size block per parameter block) as reported by the
/// cost function: the ambient Jacobian, times PlusJacobian for a quaternion block.
std::vector<RowMajorXd> reportedJacobians(const ceres::CostFunction& cf, const Params& params,
                                          const std::vector<bool>& is_quaternion) {
  const int m = cf.num_residuals();
  const auto& sizes = cf.parameter_block_sizes();
  std::vector<RowMajorXd> ambient;
  std::vector<double*> ptrs;
  for (int size : sizes) ambient.emplace_back(RowMajorXd::Constant(m, size, std::nan("")));
  for (auto& J : ambient) ptrs.push_back(J.data());
  evaluate(cf, params, ptrs.data());
  for (size_t b = 0; b < params.size(); ++b)
    if (is_quaternion[b]) ambient[b] = ambient[b] * plusJacobian(params[b].data());
  return ambient;
}

/// The generic check every residual goes through, at one state:
///  - the residual is the same with and without Jacobians requested, and finite;
///  - each block's Jacobian is the same whether or not the other blocks' are requested (Ceres
///    passes nullptr for constant blocks);
///  - ambient Jacobian · PlusJacobian (quaternion blocks) / the Jacobian (vector blocks) equals
///    the central difference of the residual under q ⊗ Exp(δθ) / x + δx, within
///    tol · max(1, |J|) per block;
///  - a quaternion block and its negative (the same attitude) give the same residual.
void checkCostFunctionJacobians(const ceres::CostFunction& cf, const Params& params,
                                const std::vector<bool>& is_quaternion, double tol = 1e-6) {
  const int m = cf.num_residuals();
  const auto& sizes = cf.parameter_block_sizes();
  ASSERT_EQ(sizes.size(), params.size());
  ASSERT_EQ(sizes.size(), is_quaternion.size());
  for (size_t b = 0; b < params.size(); ++b) {
    ASSERT_EQ(static_cast<int>(params[b].size()), sizes[b]) << "block " << b;
    if (is_quaternion[b]) {
      ASSERT_EQ(sizes[b], 4);
      ASSERT_NEAR(quat(params[b]).norm(), 1.0, 1e-12) << "block " << b;
    }
  }

  const Eigen::VectorXd r0 = evaluate(cf, params);
  ASSERT_TRUE(r0.allFinite()) << r0.transpose();
  const std::vector<RowMajorXd> J = reportedJacobians(cf, params, is_quaternion);
  {
    std::vector<RowMajorXd> ambient;
    std::vector<double*> ptrs;
    for (int size : sizes) ambient.emplace_back(m, size);
    for (auto& A : ambient) ptrs.push_back(A.data());
    const Eigen::VectorXd r1 = evaluate(cf, params, ptrs.data());
    EXPECT_LE((r1 - r0).cwiseAbs().maxCoeff(), 1e-12 * std::max(1.0, r0.cwiseAbs().maxCoeff()));
    for (size_t b = 0; b < params.size(); ++b) {
      std::vector<double*> only(params.size(), nullptr);
      RowMajorXd single(m, sizes[b]);
      only[b] = single.data();
      evaluate(cf, params, only.data());
      EXPECT_EQ(single, ambient[b]) << "block " << b << " alone";
    }
  }

  const double h = 1e-6;
  for (size_t b = 0; b < params.size(); ++b) {
    const int tangent = is_quaternion[b] ? 3 : sizes[b];
    RowMajorXd Jn(m, tangent);
    for (int k = 0; k < tangent; ++k) {
      Params plus = params, minus = params;
      if (is_quaternion[b]) {
        const Quatd q = quat(params[b]);
        plus[b] = block(so3::boxplus(q, Vec3d(h * Vec3d::Unit(k))));
        minus[b] = block(so3::boxplus(q, Vec3d(-h * Vec3d::Unit(k))));
      } else {
        plus[b][k] += h;
        minus[b][k] -= h;
      }
      Jn.col(k) = (evaluate(cf, plus) - evaluate(cf, minus)) / (2.0 * h);
    }
    ASSERT_TRUE(J[b].allFinite()) << "block " << b << ":\n" << J[b];
    const double scale = std::max(1.0, Jn.cwiseAbs().maxCoeff());
    EXPECT_LE((J[b] - Jn).cwiseAbs().maxCoeff(), tol * scale)
        << "block " << b << (is_quaternion[b] ? " (quaternion, tangent)" : "") << "\nreported:\n"
        << J[b] << "\nnumeric:\n"
        << Jn;

    if (is_quaternion[b]) {
      Params flipped = params;
      for (double& c : flipped[b]) c = -c;
      EXPECT_LE((evaluate(cf, flipped) - r0).cwiseAbs().maxCoeff(),
                1e-9 * std::max(1.0, r0.cwiseAbs().maxCoeff()))
          << "block " << b << ": q and −q must give the same residual";
    }
  }
}

/// A random attitude, stored with either sign of w.
Quatd randomAttitude(std::mt19937& rng) {
  Quatd q = randomUnitQuaternion(rng);
  if (std::bernoulli_distribution(0.5)(rng)) q.coeffs() = -q.coeffs();
  return q;
}

/// The next node's attitude: a plausible rotation from q (|δ| ≲ 0.09 rad), either sign.
Quatd nextAttitude(std::mt19937& rng, const Quatd& q) {
  Quatd next = so3::boxplus(q, Vec3d(randomVector<3>(rng, 0.05)));
  if (std::bernoulli_distribution(0.5)(rng)) next.coeffs() = -next.coeffs();
  return next;
}

/// Two cost functions of the same residual (two-stage autodiff vs one full AutoDiffCostFunction):
/// the same residual and the same ambient Jacobians, to rounding.
void expectSameCostFunction(const ceres::CostFunction& a, const ceres::CostFunction& b,
                            const Params& params) {
  const std::vector<bool> ambient(params.size(), false);
  const Eigen::VectorXd ra = evaluate(a, params), rb = evaluate(b, params);
  EXPECT_LT((ra - rb).cwiseAbs().maxCoeff(), 1e-12 * std::max(1.0, rb.cwiseAbs().maxCoeff()));
  const std::vector<RowMajorXd> Ja = reportedJacobians(a, params, ambient);
  const std::vector<RowMajorXd> Jb = reportedJacobians(b, params, ambient);
  for (size_t i = 0; i < params.size(); ++i) {
    SCOPED_TRACE(i);
    EXPECT_LT((Ja[i] - Jb[i]).cwiseAbs().maxCoeff(),
              1e-12 * std::max(1.0, Jb[i].cwiseAbs().maxCoeff()));
  }
}

double uniform(std::mt19937& rng, double lo, double hi) {
  return std::uniform_real_distribution<double>(lo, hi)(rng);
}

// ------------------------------------------------------------------------------------------
// BodyQuaternionManifold
// ------------------------------------------------------------------------------------------

Vec3d manifoldMinus(const Quatd& y, const Quatd& x) {
  Vec3d d;
  BodyQuaternionManifold().Minus(y.coeffs().data(), x.coeffs().data(), d.data());
  return d;
}

Quatd manifoldPlus(const Quatd& x, const Vec3d& d) {
  Quatd out;
  BodyQuaternionManifold().Plus(x.coeffs().data(), d.data(), out.coeffs().data());
  return out;
}

std::vector<Quatd> manifoldTestPoints() {
  std::mt19937 rng(100);
  std::vector<Quatd> xs = {Quatd::Identity(), Quatd(-1, 0, 0, 0), Quatd(0, 1, 0, 0),
                           Quatd(std::sqrt(0.5), 0, 0, -std::sqrt(0.5))};
  for (int k = 0; k < kTrials; ++k) xs.push_back(randomAttitude(rng));
  int negative = 0;
  for (const Quatd& x : xs) negative += x.w() < 0;
  EXPECT_GE(negative, 5) << "the points must include w < 0";
  return xs;
}

/// Random tangent vectors with |δ| < π, from tiny (Taylor branch of Exp/Log) to near π.
std::vector<Vec3d> manifoldTestDeltas(std::mt19937& rng) {
  std::vector<Vec3d> ds = {Vec3d::Zero(), Vec3d(1e-9, -2e-9, 3e-9), Vec3d(0, 0, 3.0)};
  for (int k = 0; k < 8; ++k) {
    const Vec3d axis = randomVector<3>(rng).normalized();
    ds.push_back(axis * uniform(rng, 0.0, M_PI - 1e-3));
  }
  return ds;
}

TEST(BodyQuaternionManifold, Sizes) {
  const BodyQuaternionManifold M;
  EXPECT_EQ(M.AmbientSize(), 4);
  EXPECT_EQ(M.TangentSize(), 3);
}

TEST(BodyQuaternionManifold, XPlusZeroIsX) {
  for (const Quatd& x : manifoldTestPoints())
    EXPECT_LT((manifoldPlus(x, Vec3d::Zero()).coeffs() - x.coeffs()).norm(), 1e-15);
}

TEST(BodyQuaternionManifold, XMinusXIsZero) {
  for (const Quatd& x : manifoldTestPoints())
    EXPECT_LT(manifoldMinus(x, x).norm(), 1e-15) << x.coeffs().transpose();
}

// Minus(Plus(x, δ), x) = δ for |δ| < π, and Plus(x, Minus(y, x)) = y as an attitude (up to the
// sign of the stored quaternion: Log picks the w ≥ 0 representative).
TEST(BodyQuaternionManifold, PlusMinusAreInverses) {
  std::mt19937 rng(101);
  for (const Quatd& x : manifoldTestPoints()) {
    for (const Vec3d& d : manifoldTestDeltas(rng)) {
      const Quatd y = manifoldPlus(x, d);
      EXPECT_NEAR(y.norm(), 1.0, 1e-15);
      EXPECT_LT((manifoldMinus(y, x) - d).norm(), 1e-12) << "δ = " << d.transpose();
      const Quatd z = randomAttitude(rng);
      const Quatd back = manifoldPlus(x, manifoldMinus(z, x));
      EXPECT_NEAR(std::abs(back.coeffs().dot(z.coeffs())), 1.0, 1e-12);
    }
  }
}

// Plus is a body-side perturbation: Plus(x, δ) = x ⊗ Exp(δ), not Exp(δ) ⊗ x.
TEST(BodyQuaternionManifold, PerturbsOnTheBodySide) {
  const Quatd x = so3::fromRollPitchYaw(0.0, 0.0, M_PI / 2);  // yaw 90°
  const Quatd y = manifoldPlus(x, Vec3d(0.1, 0, 0));          // roll about the BODY x axis
  const Vec3d rpy = so3::rollPitchYaw(y);
  EXPECT_LT((rpy - Vec3d(0.1, 0, M_PI / 2)).norm(), 1e-14) << rpy.transpose();
}

TEST(BodyQuaternionManifold, PlusJacobianMatchesNumeric) {
  const double h = 1e-6;
  for (const Quatd& x : manifoldTestPoints()) {
    const RowMajorXd J = plusJacobian(x.coeffs().data());
    Eigen::Matrix<double, 4, 3> Jn;
    for (int k = 0; k < 3; ++k)
      Jn.col(k) = (manifoldPlus(x, h * Vec3d::Unit(k)).coeffs() -
                   manifoldPlus(x, -h * Vec3d::Unit(k)).coeffs()) /
                  (2 * h);
    EXPECT_LT((J - Jn).cwiseAbs().maxCoeff(), 1e-9) << "x = " << x.coeffs().transpose();
  }
}

// Ceres differentiates Minus(y, x) w.r.t. y in ambient coordinates, y not renormalised. Log is
// invariant to the scale of a quaternion, so that derivative is well defined (and zero along y).
TEST(BodyQuaternionManifold, MinusJacobianMatchesNumeric) {
  const double h = 1e-6;
  for (const Quatd& x : manifoldTestPoints()) {
    RowMajorXd J(3, 4);
    BodyQuaternionManifold().MinusJacobian(x.coeffs().data(), J.data());
    Eigen::Matrix<double, 3, 4> Jn;
    for (int k = 0; k < 4; ++k) {
      Quatd yp = x, ym = x;
      yp.coeffs()[k] += h;
      ym.coeffs()[k] -= h;
      Jn.col(k) = (manifoldMinus(yp, x) - manifoldMinus(ym, x)) / (2 * h);
    }
    EXPECT_LT((J - Jn).cwiseAbs().maxCoeff(), 1e-8) << "x = " << x.coeffs().transpose();
    EXPECT_LT((J * x.coeffs()).norm(), 1e-15) << "Minus is blind to the quaternion's scale";
  }
}

TEST(BodyQuaternionManifold, MinusJacobianTimesPlusJacobianIsIdentity) {
  for (const Quatd& x : manifoldTestPoints()) {
    RowMajorXd Jm(3, 4);
    BodyQuaternionManifold().MinusJacobian(x.coeffs().data(), Jm.data());
    EXPECT_LT((Jm * plusJacobian(x.coeffs().data()) - Mat3d::Identity()).norm(), 1e-15);
  }
}

// What Ceres calls to project a cost function's ambient Jacobian: the base-class default through
// PlusJacobian.
TEST(BodyQuaternionManifold, RightMultiplyByPlusJacobian) {
  for (const Quatd& x : manifoldTestPoints()) {
    const RowMajorXd A = RowMajorXd::Random(5, 4);
    RowMajorXd out(5, 3);
    ASSERT_TRUE(BodyQuaternionManifold().RightMultiplyByPlusJacobian(x.coeffs().data(), 5, A.data(),
                                                                     out.data()));
    EXPECT_LT((out - A * plusJacobian(x.coeffs().data())).norm(), 1e-15);
  }
}

// ------------------------------------------------------------------------------------------
// Attitude process
// ------------------------------------------------------------------------------------------

TEST(SmootherResidualAttitudeProcess, JacobiansMatchNumeric) {
  std::mt19937 rng(1);
  for (int trial = 0; trial < kTrials; ++trial) {
    SCOPED_TRACE(trial);
    const double dt = uniform(rng, 0.05, 0.2);
    const Vec3d sqrt_info = AttitudeProcessResidual::sqrtInfo(dt, Vec3d(1e-4, 1e-4, 4e-4), 1e-4);
    const std::unique_ptr<ceres::CostFunction> cf(AttitudeProcessResidual::Create(dt, sqrt_info));
    const Quatd q0 = randomAttitude(rng);
    checkCostFunctionJacobians(*cf,
                               {block(q0), block(nextAttitude(rng, q0)),
                                block(randomVector<3>(rng, 0.1)), block(randomVector<3>(rng, 0.1))},
                               {true, true, false, false});
  }
}

// q_k = I, q_{k+1} = Exp(0.1 z), ω_k = ω_{k+1} = (0, 0, 1), Δt = 0.1: the trapezoid rotation
// ½ (1 + 1) 0.1 = 0.1 about z equals Log(q_k⁻¹ q_{k+1}) → r = 0. With ω = 0, e = (0, 0, 0.1) and
// r = sqrt_info ⊙ e = (0, 0, 3) for sqrt_info = (10, 20, 30).
TEST(SmootherResidualAttitudeProcess, HandChecked) {
  const Vec3d sqrt_info(10, 20, 30);
  const std::unique_ptr<ceres::CostFunction> cf(AttitudeProcessResidual::Create(0.1, sqrt_info));
  const auto q1 = block(so3::expQuat(Vec3d(0, 0, 0.1)));
  EXPECT_LT(evaluate(*cf, {block(Quatd::Identity()), q1, {0, 0, 1}, {0, 0, 1}}).norm(), 1e-15);
  EXPECT_LT((evaluate(*cf, {block(Quatd::Identity()), q1, {0, 0, 0}, {0, 0, 0}}) -
             Eigen::Vector3d(0, 0, 3))
                .norm(),
            1e-14);
  // σ² = q_ω Δt³/12 + floor²: q_ω = 1.2, Δt = 0.1 → 1e-4, floor 0 → σ = 0.01 → 100.
  EXPECT_LT(
      (AttitudeProcessResidual::sqrtInfo(0.1, Vec3d::Constant(1.2), 0.0) - Vec3d::Constant(100))
          .norm(),
      1e-9);
}

// ------------------------------------------------------------------------------------------
// Position process
// ------------------------------------------------------------------------------------------

TEST(SmootherResidualPositionProcess, JacobiansMatchNumeric) {
  std::mt19937 rng(2);
  for (int trial = 0; trial < kTrials; ++trial) {
    SCOPED_TRACE(trial);
    const double dt = uniform(rng, 0.05, 0.2);
    const std::unique_ptr<ceres::CostFunction> cf(
        PositionProcessResidual::Create(dt, PositionProcessResidual::sqrtInfo(dt, 0.01, 1e-3)));
    const Quatd q0 = randomAttitude(rng);
    const Vec3d x0 = randomVector<3>(rng, 10.0);
    checkCostFunctionJacobians(*cf,
                               {block(x0), block(Vec3d(x0 + randomVector<3>(rng, 0.02))), block(q0),
                                block(nextAttitude(rng, q0)), block(randomVector<3>(rng, 0.1)),
                                block(randomVector<3>(rng, 0.1))},
                               {false, false, true, true, false, false});
  }
}

TEST(SmootherResidualPositionProcess, TwoStageAutodiffMatchesFullAutodiff) {
  std::mt19937 rng(21);
  for (int trial = 0; trial < kTrials; ++trial) {
    SCOPED_TRACE(trial);
    const double dt = uniform(rng, 0.05, 0.2), si = uniform(rng, 10.0, 1000.0);
    const std::unique_ptr<ceres::CostFunction> two(PositionProcessResidual::Create(dt, si));
    const std::unique_ptr<ceres::CostFunction> full(
        PositionProcessResidual::CreateFullAutodiff(dt, si));
    const Quatd q0 = randomAttitude(rng);
    expectSameCostFunction(*two, *full,
                           {block(randomVector<3>(rng, 10.0)), block(randomVector<3>(rng, 10.0)),
                            block(q0), block(nextAttitude(rng, q0)),
                            block(randomVector<3>(rng, 0.1)), block(randomVector<3>(rng, 0.1))});
  }
}

// Straight motion at v = (0.1, 0, 0) with the body yawed 90°: the body x axis is site +y, so in
// Δt = 0.1 the position moves 0.01 along site +y → r = 0. Turning from yaw 0 to yaw 0.2 the
// midpoint attitude has yaw 0.1: x moves 0.01 (cos 0.1, sin 0.1, 0) → r = 0; left at x_k the
// residual is sqrt_info · (−0.01 (cos 0.1, sin 0.1, 0)).
TEST(SmootherResidualPositionProcess, HandChecked) {
  const std::unique_ptr<ceres::CostFunction> cf(PositionProcessResidual::Create(0.1, 50.0));
  const auto yaw90 = block(so3::fromRollPitchYaw(0.0, 0.0, M_PI / 2));
  const std::vector<double> v = {0.1, 0, 0};
  EXPECT_LT(evaluate(*cf, {{1, 2, 3}, {1, 2.01, 3}, yaw90, yaw90, v, v}).norm(), 1e-13);

  const auto yaw0 = block(Quatd::Identity());
  const auto yaw02 = block(so3::fromRollPitchYaw(0.0, 0.0, 0.2));
  const Vec3d step = 0.01 * Vec3d(std::cos(0.1), std::sin(0.1), 0);
  EXPECT_LT(
      evaluate(*cf, {{1, 2, 3}, block(Vec3d(Vec3d(1, 2, 3) + step)), yaw0, yaw02, v, v}).norm(),
      1e-13);
  EXPECT_LT(
      (evaluate(*cf, {{1, 2, 3}, {1, 2, 3}, yaw0, yaw02, v, v}) - Eigen::VectorXd(-50.0 * step))
          .norm(),
      1e-13);
  // σ² = q_v Δt³/12 + floor²: q_v = 1.2, Δt = 0.1 → 1e-4; floor 0 → 1/σ = 100.
  EXPECT_NEAR(PositionProcessResidual::sqrtInfo(0.1, 1.2, 0.0), 100.0, 1e-9);
}

// ------------------------------------------------------------------------------------------
// Accelerometer velocity process
// ------------------------------------------------------------------------------------------

TEST(SmootherResidualAccelVelocityProcess, JacobiansMatchNumeric) {
  std::mt19937 rng(3);
  for (int trial = 0; trial < kTrials; ++trial) {
    SCOPED_TRACE(trial);
    const double dt = uniform(rng, 0.05, 0.2);
    const Quatd q0 = randomAttitude(rng);
    // A reading near what the rover would feel: gravity in the body plus small accelerations.
    const Vec3d accel = q0.conjugate() * Vec3d(0, 0, kGravity) + Vec3d(randomVector<3>(rng, 0.2));
    const std::unique_ptr<ceres::CostFunction> cf(AccelVelocityProcessResidual::Create(
        dt, accel, Vec3d(0.02, -0.01, 0.05), kGravity, 1.0 / std::sqrt(1e-4 * 0.01 * dt + 1e-6)));
    checkCostFunctionJacobians(*cf,
                               {block(q0), block(nextAttitude(rng, q0)),
                                block(randomVector<3>(rng, 0.1)), block(randomVector<3>(rng, 0.1)),
                                block(randomVector<3>(rng, 0.1)), block(randomVector<3>(rng, 0.1))},
                               {true, true, false, false, false, false});
  }
}

TEST(SmootherResidualAccelVelocityProcess, TwoStageAutodiffMatchesFullAutodiff) {
  std::mt19937 rng(22);
  for (int trial = 0; trial < kTrials; ++trial) {
    SCOPED_TRACE(trial);
    const double dt = uniform(rng, 0.05, 0.2), si = uniform(rng, 10.0, 1000.0);
    const Quatd q0 = randomAttitude(rng);
    const Vec3d accel = q0.conjugate() * Vec3d(0, 0, kGravity) + Vec3d(randomVector<3>(rng, 0.2));
    const Vec3d lever(0.02, -0.01, 0.05);
    const std::unique_ptr<ceres::CostFunction> two(
        AccelVelocityProcessResidual::Create(dt, accel, lever, kGravity, si));
    const std::unique_ptr<ceres::CostFunction> full(
        AccelVelocityProcessResidual::CreateFullAutodiff(dt, accel, lever, kGravity, si));
    expectSameCostFunction(*two, *full,
                           {block(q0), block(nextAttitude(rng, q0)),
                            block(randomVector<3>(rng, 0.1)), block(randomVector<3>(rng, 0.1)),
                            block(randomVector<3>(rng, 0.1)), block(randomVector<3>(rng, 0.1))});
  }
}

// K-10 solved for v̇: v̇ = a_m − (ω × v − Rᵀ g_s + ω × (ω × L) + ω̇ × L), g_s = (0, 0, −g).
//  - At rest, level, reading (0, 0, g), v = ω = 0: v̇ = 0 → r = 0.
//  - Reading (0.1, 0, g), v_k = 0, v_{k+1} = (0.01, 0, 0), Δt = 0.1, ω = 0: v̇ = (0.1, 0, 0)
//    and v_{k+1} − v_k = v̇ Δt → r = 0; with v_{k+1} = 0 instead, r = sqrt_info (−0.01, 0, 0).
//  - Turning at constant ω = (0, 0, 0.1), v = (0.1, 0, 0), lever arm L = (0.1, 0, 0): v̇ = 0
//    when the reading is ω × v + ω × (ω × L) + (0, 0, g) = (0, 0.01, 0) + (−0.001, 0, 0) +
//    (0, 0, g) (the yaw over the interval does not change Rᵀ g_s).
TEST(SmootherResidualAccelVelocityProcess, HandChecked) {
  const auto level = block(Quatd::Identity());
  const std::vector<double> zero = {0, 0, 0};
  const double si = 200.0;
  {
    const std::unique_ptr<ceres::CostFunction> cf(AccelVelocityProcessResidual::Create(
        0.1, Vec3d(0, 0, kGravity), Vec3d(0, 0, 0.05), kGravity, si));
    EXPECT_LT(evaluate(*cf, {level, level, zero, zero, zero, zero}).norm(), 1e-12);
  }
  {
    const std::unique_ptr<ceres::CostFunction> cf(AccelVelocityProcessResidual::Create(
        0.1, Vec3d(0.1, 0, kGravity), Vec3d(0, 0, 0.05), kGravity, si));
    EXPECT_LT(evaluate(*cf, {level, level, zero, {0.01, 0, 0}, zero, zero}).norm(), 1e-12);
    EXPECT_LT(
        (evaluate(*cf, {level, level, zero, zero, zero, zero}) - Eigen::Vector3d(-0.01 * si, 0, 0))
            .norm(),
        1e-12);
  }
  {
    const std::unique_ptr<ceres::CostFunction> cf(AccelVelocityProcessResidual::Create(
        0.1, Vec3d(-0.001, 0.01, kGravity), Vec3d(0.1, 0, 0), kGravity, si));
    const auto q1 = block(so3::expQuat(Vec3d(0, 0, 0.01)));
    const std::vector<double> v = {0.1, 0, 0}, w = {0, 0, 0.1};
    EXPECT_LT(evaluate(*cf, {level, q1, v, v, w, w}).norm(), 1e-12);
  }
}

// With the accelerometer's bias b_a as a seventh block (v̇ sees a_m − b_a): the two-stage cost
// function against central differences and against one full AutoDiffCostFunction, at random
// states (random unit quaternions, random b_a).
TEST(SmootherResidualAccelVelocityProcess, WithBiasJacobiansMatchNumericAndFullAutodiff) {
  std::mt19937 rng(31);
  for (int trial = 0; trial < kTrials; ++trial) {
    SCOPED_TRACE(trial);
    const double dt = uniform(rng, 0.05, 0.2), si = uniform(rng, 10.0, 1000.0);
    const Quatd q0 = randomAttitude(rng);
    const Vec3d accel = q0.conjugate() * Vec3d(0, 0, kGravity) + Vec3d(randomVector<3>(rng, 0.2));
    const Vec3d lever(0.02, -0.01, 0.05);
    const std::unique_ptr<ceres::CostFunction> two(
        AccelVelocityProcessResidual::Create(dt, accel, lever, kGravity, si, true));
    const std::unique_ptr<ceres::CostFunction> full(
        AccelVelocityProcessResidual::CreateFullAutodiff(dt, accel, lever, kGravity, si, true));
    ASSERT_EQ(two->parameter_block_sizes().size(), 7u);
    const Params params = {block(q0),
                           block(nextAttitude(rng, q0)),
                           block(randomVector<3>(rng, 0.1)),
                           block(randomVector<3>(rng, 0.1)),
                           block(randomVector<3>(rng, 0.1)),
                           block(randomVector<3>(rng, 0.1)),
                           block(randomVector<3>(rng, 0.3))};
    checkCostFunctionJacobians(*two, params, {true, true, false, false, false, false, false});
    expectSameCostFunction(*two, *full, params);
  }
}

// The bias only moves the reading: a reading a with bias b gives the residual of the reading
// a − b without one (any state), and ∂r/∂b_a = −sqrt_info Δt (−I of v̇). Level at rest with
// reading (0.05, 0, g) and b_a = (0.05, 0, 0): v̇ = 0, r = 0.
TEST(SmootherResidualAccelVelocityProcess, WithBiasHandChecked) {
  std::mt19937 rng(32);
  const double dt = 0.1, si = 200.0;
  const Vec3d lever(0.02, -0.01, 0.05), b(0.03, -0.02, 0.04);
  const Quatd q0 = randomAttitude(rng);
  const Vec3d accel = q0.conjugate() * Vec3d(0, 0, kGravity) + Vec3d(randomVector<3>(rng, 0.2));
  const Params state = {block(q0),
                        block(nextAttitude(rng, q0)),
                        block(randomVector<3>(rng, 0.1)),
                        block(randomVector<3>(rng, 0.1)),
                        block(randomVector<3>(rng, 0.1)),
                        block(randomVector<3>(rng, 0.1))};
  Params with_b = state;
  with_b.push_back(block(b));
  const std::unique_ptr<ceres::CostFunction> biased(
      AccelVelocityProcessResidual::Create(dt, accel, lever, kGravity, si, true));
  const std::unique_ptr<ceres::CostFunction> plain(
      AccelVelocityProcessResidual::Create(dt, Vec3d(accel - b), lever, kGravity, si));
  EXPECT_LT((evaluate(*biased, with_b) - evaluate(*plain, state)).norm(), 1e-9);
  const std::vector<RowMajorXd> J =
      reportedJacobians(*biased, with_b, {true, true, false, false, false, false, false});
  EXPECT_LT((J[6] - RowMajorXd(Mat3d::Identity() * si * dt)).cwiseAbs().maxCoeff(), 1e-9);

  const std::unique_ptr<ceres::CostFunction> rest(AccelVelocityProcessResidual::Create(
      dt, Vec3d(0.05, 0, kGravity), lever, kGravity, si, true));
  const auto level = block(Quatd::Identity());
  const std::vector<double> zero = {0, 0, 0};
  EXPECT_LT(evaluate(*rest, {level, level, zero, zero, zero, zero, {0.05, 0, 0}}).norm(), 1e-12);
  EXPECT_NEAR(evaluate(*rest, {level, level, zero, zero, zero, zero, zero})[0], -0.05 * dt * si,
              1e-12);
}

// ------------------------------------------------------------------------------------------
// Gyro increment
// ------------------------------------------------------------------------------------------

TEST(SmootherResidualGyroIncrement, JacobiansMatchNumeric) {
  std::mt19937 rng(4);
  for (int trial = 0; trial < kTrials; ++trial) {
    SCOPED_TRACE(trial);
    const double dt = uniform(rng, 0.05, 0.2);
    // Heading-only (z) on even trials, all three axes on odd ones.
    const double si = 1.0 / std::sqrt(0.0031 * 0.0031 * 0.01 * dt);
    const Vec3d sqrt_info = trial % 2 ? Vec3d::Constant(si) : Vec3d(0, 0, si);
    const std::unique_ptr<ceres::CostFunction> cf(
        GyroIncrementResidual::Create(dt, randomVector<3>(rng, 0.01), sqrt_info));
    const Quatd q0 = randomAttitude(rng);
    checkCostFunctionJacobians(
        *cf, {block(q0), block(nextAttitude(rng, q0)), block(randomVector<3>(rng, 0.01))},
        {true, true, false});
  }
}

// Level rover turning rot about z over Δt = 0.1, gyro increment 0.01 rad on z, bias 0.001 rad/s:
// the bias-corrected increment is 0.01 − 0.001 · 0.1 = 0.0099, so r_z = sqrt_info_z (rot −
// 0.0099): 0 for rot = 0.0099, 100 · 0.0021 = 0.21 for rot = 0.012. Unmeasured axes (sqrt_info
// 0) give zero rows whatever their increments and biases.
TEST(SmootherResidualGyroIncrement, HandChecked) {
  const std::unique_ptr<ceres::CostFunction> cf(
      GyroIncrementResidual::Create(0.1, Vec3d(0.3, -0.2, 0.01), Vec3d(0, 0, 100)));
  const auto q0 = block(Quatd::Identity());
  const std::vector<double> bias = {0.05, -0.02, 0.001};
  EXPECT_LT(evaluate(*cf, {q0, block(so3::expQuat(Vec3d(0, 0, 0.0099))), bias}).norm(), 1e-13);
  EXPECT_LT((evaluate(*cf, {q0, block(so3::expQuat(Vec3d(0, 0, 0.012))), bias}) -
             Eigen::Vector3d(0, 0, 0.21))
                .norm(),
            1e-13);
}

// ------------------------------------------------------------------------------------------
// Sun sensor
// ------------------------------------------------------------------------------------------

TEST(SmootherResidualSunSensor, JacobiansMatchNumeric) {
  std::mt19937 rng(5);
  const Vec3d sun = Vec3d(-1, 1, 1).normalized();
  sensors::SunSensorGeometry geo;
  geo.R_body_sensor = so3::exp(Vec3d(0.1, -0.05, 0.3));
  int trial = 0;
  while (trial < kTrials) {
    const Quatd q0 = randomAttitude(rng);
    const Quatd q1 = nextAttitude(rng, q0);
    if (!sensors::sunInFieldOfView(q0, geo, sun) || !sensors::sunInFieldOfView(q1, geo, sun))
      continue;  // such readings never become residuals
    SCOPED_TRACE(trial);
    const double u = trial == 0 ? 0.0 : trial == 1 ? 1.0 : uniform(rng, 0.0, 1.0);
    const Vec2d reading = sensors::sunSensorPredict(q0, geo, sun) + randomVector<2>(rng, 0.01);
    const std::unique_ptr<ceres::CostFunction> cf(
        SunSensorResidual::Create(u, reading, sun, geo, 200.0));
    checkCostFunctionJacobians(*cf, {block(q0), block(q1)}, {true, true});
    ++trial;
  }
}

// Sun at the site zenith and a level rover (sensor boresight = body z): the prediction is
// (0, 0), so r = sqrt_info · reading. Sun at (1, 0, 1)/√2 with the rover yawed 45° (u = 0.5
// between yaw 0 and yaw 90°): in the body the sun is (0.5, −0.5, 1/√2), ρ = 1/√2, α = π/4, so
// s_m = (2/π)(α/ρ)(0.5, −0.5) = (√2/4, −√2/4).
TEST(SmootherResidualSunSensor, HandChecked) {
  const auto level = block(Quatd::Identity());
  {
    const std::unique_ptr<ceres::CostFunction> cf(
        SunSensorResidual::Create(0.3, Vec2d(0.1, -0.2), Vec3d::UnitZ(), {}, 200.0));
    EXPECT_LT((evaluate(*cf, {level, level}) - Eigen::Vector2d(20, -40)).norm(), 1e-12);
  }
  {
    const double c = std::sqrt(2.0) / 4;
    const std::unique_ptr<ceres::CostFunction> cf(
        SunSensorResidual::Create(0.5, Vec2d(c, -c), Vec3d(1, 0, 1).normalized(), {}, 200.0));
    const auto yaw90 = block(so3::fromRollPitchYaw(0.0, 0.0, M_PI / 2));
    EXPECT_LT(evaluate(*cf, {level, yaw90}).norm(), 1e-12);
  }
}

// ------------------------------------------------------------------------------------------
// Slip
// ------------------------------------------------------------------------------------------

const rover::RoverGeometry& rocky7() {
  static const rover::RoverGeometry geo = [] {
    const std::string dir = testing::sourceDir() + "/datasets/rovers/rocky7/";
    return io::loadRoverGeometry(dir + "rover.urdf", io::loadRoverConfig(dir + "rover.yaml"));
  }();
  return geo;
}

TEST(SmootherResidualSlip, JacobiansMatchNumericAndAutodiffTwin) {
  const rover::RoverGeometry& geo = rocky7();
  std::mt19937 rng(6);
  for (int trial = 0; trial < 4 * kTrials; ++trial) {
    SCOPED_TRACE(trial);
    rover::JointVectord q = rover::JointVectord::Zero(r7::kNumCoords);
    q.head<3>() = randomVector<3>(rng, 0.3);
    q.segment<2>(r7::kLambda1) = randomVector<2>(rng, 0.5);
    const auto kin = rover::forwardKinematics<double>(geo, q);
    const int i = trial % r7::kNumWheels;
    const Twistd jt = rover::wheelJointTwist(kin[i], randomVector<r7::kNumCoords>(rng, 1.0));
    // Σ: the slip noise plus a random correlated part (the joint-rate noise carried through).
    Eigen::Matrix4d A = randomVector<16>(rng, 0.003).reshaped(4, 4);
    const Eigen::Matrix4d cov =
        Vec4d(0.004, 0.004, 0.004, 0.02).array().square().matrix().asDiagonal().toDenseMatrix() +
        A * A.transpose();
    const Eigen::Matrix4d L_inv = sqrtInformation<4>(cov, "slip");
    const SlipResidual cf(i, r7::kNumWheels, kin[i].T_body_wheel, geo.wheels[i].radius, jt,
                          randomVector<4>(rng, 0.02), L_inv);
    const Vec3d v = randomVector<3>(rng, 0.1), w = randomVector<3>(rng, 0.1);
    const Vec6d xi = randomVector<6>(rng, 0.3);
    checkCostFunctionJacobians(cf, {block(v), block(w), block(xi)}, {false, false, false});

    // The autodiff twin, through ceres::Jet: same residual, same Jacobian [∂v | ∂ω | ∂ξ].
    Eigen::Matrix<double, 12, 1> x;
    x << v, w, xi;
    const auto twin = [&](const auto& s) {
      using T = typename std::decay_t<decltype(s)>::Scalar;
      return cf.residual<T>(Vec3<T>(s.template head<3>()), Vec3<T>(s.template segment<3>(3)),
                            Eigen::Matrix<T, 6, 1>(s.template tail<6>()));
    };
    const Eigen::VectorXd r = evaluate(cf, {block(v), block(w), block(xi)});
    EXPECT_LT((r - twin(x)).cwiseAbs().maxCoeff(), 1e-12 * std::max(1.0, r.cwiseAbs().maxCoeff()));
    const auto J = reportedJacobians(cf, {block(v), block(w), block(xi)}, {false, false, false});
    Eigen::Matrix<double, 4, 12> J_analytic;
    J_analytic << J[0], J[1], J[2];
    const Eigen::Matrix<double, 4, 12> J_jet = testing::autodiffJacobian<4, 12>(twin, x);
    EXPECT_LT((J_analytic - J_jet).cwiseAbs().maxCoeff(),
              1e-12 * std::max(1.0, J_jet.cwiseAbs().maxCoeff()))
        << "analytic:\n"
        << J_analytic << "\njet:\n"
        << J_jet;
    // Only wheel i's contact angle enters.
    for (int c = 0; c < 6; ++c) {
      if (c != i) {
        EXPECT_EQ(J[2].col(c).norm(), 0.0);
      }
    }

    // The smoother's form, which refers to numbers kept in its own array (SlipWheelData), is
    // the same function bit for bit.
    const SlipWheelData data{kin[i].T_body_wheel, geo.wheels[i].radius, jt,
                             randomVector<4>(rng, 0.02), L_inv};
    const SlipResidual owning(i, r7::kNumWheels, data.T_body_wheel, data.radius, data.joint_twist,
                              data.nominal_slip, data.sqrt_info);
    const SlipResidual referring(i, r7::kNumWheels, &data);
    const Params at{block(v), block(w), block(xi)};
    EXPECT_EQ(evaluate(owning, at), evaluate(referring, at));
    const auto J_own = reportedJacobians(owning, at, {false, false, false});
    const auto J_ref = reportedJacobians(referring, at, {false, false, false});
    for (size_t b = 0; b < J_own.size(); ++b) EXPECT_EQ(J_own[b], J_ref[b]);
  }
}

// Without cmd.csv the nominal slip follows the state: at random joint states, steering, seeds
// and states (with the common slip c), the residual is exactly L (t_nom(v_x + c_x, ω_z) − t)
// (the nominal is affine in (v_x + c_x, ω_z), so linearising it about the seed is exact), and
// its analytic Jacobians equal the Jet twin's and central differences. Also the rover-level
// rover::nominalSlipJacobian against central differences of nominalSlip(nominalBodyTwist(…)).
TEST(SmootherResidualSlip, NominalFollowsTheStateWithoutCmd) {
  rover::RoverGeometry geo = rocky7();
  std::mt19937 rng(16);
  for (int trial = 0; trial < 4 * kTrials; ++trial) {
    SCOPED_TRACE(trial);
    geo.turn_centre_x = randomVector<1>(rng, 0.3)[0];  // and a skid-steer ICR offset below
    rover::JointVectord q = rover::JointVectord::Zero(r7::kNumCoords);
    q.head<3>() = randomVector<3>(rng, 0.3);
    q.segment<2>(r7::kLambda1) = randomVector<2>(rng, 0.5);
    const auto kin = rover::forwardKinematics<double>(geo, q);
    const int i = trial % r7::kNumWheels;
    const double radius = geo.wheels[i].radius, icr = randomVector<1>(rng, 0.4)[0];
    const Twistd jt = rover::wheelJointTwist(kin[i], randomVector<r7::kNumCoords>(rng, 1.0));
    const auto nominal = [&](const Vec2d& u) {
      return rover::nominalSlip(kin[i].T_body_wheel, radius,
                                rover::nominalBodyTwist(geo, u.x(), u.y()), jt, icr);
    };
    const Eigen::Matrix<double, 4, 2> N =
        rover::nominalSlipJacobian(geo, kin[i].T_body_wheel, radius, jt, icr);
    const Vec2d u0 = randomVector<2>(rng, 0.1);
    Eigen::Matrix<double, 4, 2> N_num;
    for (int c = 0; c < 2; ++c) {
      const Vec2d h = Vec2d::Unit(c) * 1e-6;
      N_num.col(c) = (nominal(u0 + h) - nominal(u0 - h)) / 2e-6;
    }
    EXPECT_LT((N - N_num).cwiseAbs().maxCoeff(), 1e-8);

    const Eigen::Matrix4d L = Vec4d(250, 250, 250, 50).asDiagonal();
    const SlipWheelData data{kin[i].T_body_wheel, radius, jt, nominal(u0), L, N, u0};
    const SlipResidual cf(i, r7::kNumWheels, data, 2);
    const Vec3d v = randomVector<3>(rng, 0.1), w = randomVector<3>(rng, 0.1);
    const Vec6d xi = randomVector<6>(rng, 0.3);
    const Vec2d c = randomVector<2>(rng, 0.01);
    const Params at{block(v), block(w), block(xi), block(c)};
    const Vec3d v_wheels = v + Vec3d(c.x(), c.y(), 0.0);
    const Vec4d t =
        rover::slipConstraint<double>(kin[i].T_body_wheel, radius, jt, v_wheels, w, xi[i]);
    const Vec4d expected = L * (nominal(Vec2d(v_wheels.x(), w.z())) - t);
    EXPECT_LT((evaluate(cf, at) - expected).cwiseAbs().maxCoeff(), 1e-9);
    checkCostFunctionJacobians(cf, at, {false, false, false, false});

    Eigen::Matrix<double, 14, 1> x;
    x << v, w, xi, c;
    const auto twin = [&](const auto& s) {
      using T = typename std::decay_t<decltype(s)>::Scalar;
      return cf.residual<T>(Vec3<T>(s.template head<3>()), Vec3<T>(s.template segment<3>(3)),
                            Eigen::Matrix<T, 6, 1>(s.template segment<6>(6)),
                            Vec3<T>(s[12], s[13], T(0)));
    };
    const auto J = reportedJacobians(cf, at, {false, false, false, false});
    Eigen::Matrix<double, 4, 14> J_analytic;
    J_analytic << J[0], J[1], J[2], J[3];
    const Eigen::Matrix<double, 4, 14> J_jet = testing::autodiffJacobian<4, 14>(twin, x);
    EXPECT_LT((J_analytic - J_jet).cwiseAbs().maxCoeff(),
              1e-12 * std::max(1.0, J_jet.cwiseAbs().maxCoeff()));
  }
}

// Rocky-7 at zero joint angles on flat ground (ξ = 0), driving straight at v = 0.07 with every
// wheel rolling (ψ̇ = v/r): the slip t is 0, so r = sqrt_info · nominal = diag(1/0.004 ×3,
// 1/0.02) (0, 0.01, 0, 0.02) = (0, 2.5, 0, 1). Wheels locked (ψ̇ = 0): the contact point slides
// forward at v, t = (0.07, 0, 0, 0), r = sqrt_info (nominal − t) = (−17.5, 2.5, 0, 1).
TEST(SmootherResidualSlip, HandChecked) {
  const rover::RoverGeometry& geo = rocky7();
  const auto kin = rover::forwardKinematics<double>(geo, rover::JointVectord::Zero(r7::kNumCoords));
  const double v = 0.07, radius = geo.wheels[0].radius;
  ASSERT_DOUBLE_EQ(radius, 0.065);
  rover::JointVectord q_dot = rover::JointVectord::Zero(r7::kNumCoords);
  q_dot.tail<6>().setConstant(v / radius);
  const Eigen::Matrix4d sqrt_info = Vec4d(250, 250, 250, 50).asDiagonal();
  const Vec4d nominal(0, 0.01, 0, 0.02);
  const Params state = {{v, 0, 0}, {0, 0, 0}, {0, 0, 0, 0, 0, 0}};
  for (int i = 0; i < r7::kNumWheels; ++i) {
    SCOPED_TRACE(i);
    const SlipResidual rolling(i, r7::kNumWheels, kin[i].T_body_wheel, radius,
                               rover::wheelJointTwist(kin[i], q_dot), nominal, sqrt_info);
    EXPECT_LT((evaluate(rolling, state) - Eigen::Vector4d(0, 2.5, 0, 1)).norm(), 1e-12);
    const SlipResidual locked(i, r7::kNumWheels, kin[i].T_body_wheel, radius, Twistd::Zero(),
                              nominal, sqrt_info);
    EXPECT_LT((evaluate(locked, state) - Eigen::Vector4d(-17.5, 2.5, 0, 1)).norm(), 1e-12);
  }
}

// ------------------------------------------------------------------------------------------
// Gravity (at rest)
// ------------------------------------------------------------------------------------------

TEST(SmootherResidualGravity, JacobiansMatchNumeric) {
  std::mt19937 rng(7);
  for (int trial = 0; trial < kTrials;) {
    const Quatd q = randomAttitude(rng);
    const Vec3d f = q.conjugate() * Vec3d(0, 0, kGravity) + Vec3d(randomVector<3>(rng, 0.01));
    const sensors::RollPitchMeasurement m =
        sensors::rollPitchAtRest(f, Mat3d::Identity() * (0.01 * 0.01 / 200));
    if (std::abs(m.roll_pitch[1]) > 1.4) continue;  // roll is ill-defined near pitch ±90°
    SCOPED_TRACE(trial++);
    const std::unique_ptr<ceres::CostFunction> cf(
        GravityResidual::Create(m.roll_pitch, sqrtInformation<2>(m.covariance, "gravity")));
    checkCostFunctionJacobians(*cf, {block(q)}, {true});
  }
}

// With the accelerometer's bias: blocks q and b_a, at random attitudes and biases.
TEST(SmootherResidualGravity, WithBiasJacobiansMatchNumeric) {
  std::mt19937 rng(17);
  for (int trial = 0; trial < kTrials;) {
    const Quatd q = randomAttitude(rng);
    const Vec3d b = randomVector<3>(rng, 0.2);
    const Vec3d f = q.conjugate() * Vec3d(0, 0, kGravity) + b + Vec3d(randomVector<3>(rng, 0.01));
    const sensors::RollPitchMeasurement m =
        sensors::rollPitchAtRest(f, Mat3d::Identity() * (0.01 * 0.01 / 200));
    if (std::abs(m.roll_pitch[1]) > 1.4) continue;  // roll is ill-defined near pitch ±90°
    SCOPED_TRACE(trial++);
    const std::unique_ptr<ceres::CostFunction> cf(GravityBiasResidual::Create(
        m.roll_pitch, sqrtInformation<2>(m.covariance, "gravity"), kGravity));
    checkCostFunctionJacobians(*cf, {block(q), block(b)}, {true, false});
  }
}

// Level with b_a = (0, 0.0981, 0) and g = 9.81: the mean specific force is (0, 0.0981, 9.81),
// roll = atan2(0.0981, 9.81) = atan(0.01), pitch 0; with b_a = (−0.0981, 0, 0), pitch = atan(0.01)
// (pitch = atan2(−f_x, √(f_y² + f_z²))); b_a along z changes neither. At b_a = 0 it is the
// bias-free residual at any attitude.
TEST(SmootherResidualGravity, WithBiasHandChecked) {
  const Eigen::Matrix2d sqrt_info = Eigen::Matrix2d::Identity() * 100.0;
  const auto r = [&](const Vec2d& rp, const Quatd& q, const Vec3d& b) {
    const std::unique_ptr<ceres::CostFunction> cf(GravityBiasResidual::Create(rp, sqrt_info, 9.81));
    return Vec2d(evaluate(*cf, {block(q), block(b)}));
  };
  const double t = std::atan(0.01);
  EXPECT_LT(r(Vec2d(t, 0), Quatd::Identity(), Vec3d(0, 0.0981, 0)).norm(), 1e-12);
  EXPECT_LT(r(Vec2d(0, t), Quatd::Identity(), Vec3d(-0.0981, 0, 0)).norm(), 1e-12);
  EXPECT_LT(r(Vec2d(0, 0), Quatd::Identity(), Vec3d(0, 0, 0.5)).norm(), 1e-12);
  EXPECT_NEAR(r(Vec2d(0, 0), Quatd::Identity(), Vec3d(0, 0.0981, 0))[0], -100.0 * t, 1e-12);
  std::mt19937 rng(18);
  for (int trial = 0; trial < 5; ++trial) {
    const Quatd q = randomAttitude(rng);
    const Vec2d rp = randomVector<2>(rng, 0.5);
    const std::unique_ptr<ceres::CostFunction> plain(GravityResidual::Create(rp, sqrt_info));
    EXPECT_LT((r(rp, q, Vec3d::Zero()) - Vec2d(evaluate(*plain, {block(q)}))).norm(), 1e-12);
  }
}

// Level: h(q) = (0, 0). A roll of 0.1 about x: Rᵀ e_z = (0, sin 0.1, cos 0.1), roll =
// atan2(sin 0.1, cos 0.1) = 0.1, pitch 0. A pitch of 0.2 about y: (0, 0.2). Measured roll 3.1
// against a predicted −3.1 (rolled upside down past ±π): the difference 6.2 wraps to 6.2 − 2π.
TEST(SmootherResidualGravity, HandChecked) {
  Eigen::Matrix2d sqrt_info;
  sqrt_info << 100, 0, 10, 200;
  const auto r = [&](const Vec2d& rp, const Quatd& q) {
    const std::unique_ptr<ceres::CostFunction> cf(GravityResidual::Create(rp, sqrt_info));
    return Vec2d(evaluate(*cf, {block(q)}));
  };
  EXPECT_LT(r(Vec2d::Zero(), Quatd::Identity()).norm(), 1e-15);
  const Quatd roll01(Eigen::AngleAxisd(0.1, Vec3d::UnitX()));
  EXPECT_LT(r(Vec2d(0.1, 0), roll01).norm(), 1e-13);
  EXPECT_LT((r(Vec2d::Zero(), roll01) - sqrt_info * Vec2d(-0.1, 0)).norm(), 1e-12);
  const Quatd pitch02(Eigen::AngleAxisd(0.2, Vec3d::UnitY()));
  EXPECT_LT(r(Vec2d(0, 0.2), pitch02).norm(), 1e-13);
  const Quatd roll_m31(Eigen::AngleAxisd(-3.1, Vec3d::UnitX()));
  EXPECT_LT((r(Vec2d(3.1, 0), roll_m31) - sqrt_info * Vec2d(6.2 - 2 * M_PI, 0)).norm(), 1e-12);
}

// ------------------------------------------------------------------------------------------
// Zero motion, rest bias
// ------------------------------------------------------------------------------------------

TEST(SmootherResidualZeroMotion, JacobiansMatchNumeric) {
  std::mt19937 rng(8);
  for (int trial = 0; trial < kTrials; ++trial) {
    SCOPED_TRACE(trial);
    const ZeroMotionResidual cf(uniform(rng, 1e-3, 1e-2));
    checkCostFunctionJacobians(cf, {block(randomVector<3>(rng, 0.1))}, {false});
  }
}

// σ = 0.01, v = (0.01, −0.02, 0.005) → r = v/σ = (1, −2, 0.5).
TEST(SmootherResidualZeroMotion, HandChecked) {
  const ZeroMotionResidual cf(0.01);
  EXPECT_LT((evaluate(cf, {{0.01, -0.02, 0.005}}) - Eigen::Vector3d(1, -2, 0.5)).norm(), 1e-14);
  EXPECT_EQ(evaluate(cf, {{0, 0, 0}}).norm(), 0.0);
}

TEST(SmootherResidualRestBias, JacobiansMatchNumeric) {
  std::mt19937 rng(9);
  for (int trial = 0; trial < kTrials; ++trial) {
    SCOPED_TRACE(trial);
    const double si = std::sqrt(uniform(rng, 10, 1000)) / 0.0031;
    const RestBiasResidual cf(randomVector<3>(rng, 0.01),
                              trial % 2 ? Vec3d(0, 0, si) : Vec3d::Constant(si));
    checkCostFunctionJacobians(cf, {block(randomVector<3>(rng, 0.01))}, {false});
  }
}

// N = 100 readings of σ_g = 0.0031 on z only: sqrt_info_z = √100/0.0031. Mean reading
// (0.001, 0.002, 0.003), bias (0, 0, 0.004): r = (0, 0, 0.001 · 10/0.0031) = (0, 0, 3.2258…).
TEST(SmootherResidualRestBias, HandChecked) {
  const RestBiasResidual cf(Vec3d(0.001, 0.002, 0.003), Vec3d(0, 0, 10 / 0.0031));
  EXPECT_LT((evaluate(cf, {{0, 0, 0.004}}) - Eigen::Vector3d(0, 0, 0.01 / 0.0031)).norm(), 1e-12);
}

// ------------------------------------------------------------------------------------------
// Start prior
// ------------------------------------------------------------------------------------------

TEST(SmootherResidualStartPrior, JacobiansMatchNumeric) {
  std::mt19937 rng(10);
  for (int trial = 0; trial < kTrials; ++trial) {
    SCOPED_TRACE(trial);
    const Quatd q_prior = randomAttitude(rng);
    const Vec3d x_prior = randomVector<3>(rng, 10.0);
    Mat6d A = randomVector<36>(rng, 0.01).reshaped(6, 6);
    const Mat6d cov = A * A.transpose() + 1e-4 * Mat6d::Identity();
    const std::unique_ptr<ceres::CostFunction> cf(
        StartPriorResidual::Create(q_prior, x_prior, sqrtInformation<6>(cov, "prior")));
    checkCostFunctionJacobians(
        *cf, {block(nextAttitude(rng, q_prior)), block(Vec3d(x_prior + randomVector<3>(rng, 0.1)))},
        {true, false});
  }
}

// At the prior r = 0. 1 cm along x with sqrt_info = I/0.01: r = (1, 0, 0, 0, 0, 0). The attitude
// error is body-framed: q = q̄ ⊗ Exp(0.02 e_y) gives (0, 0, 0, 0, 2, 0) whatever q̄; the same
// rotation applied on the site side, Exp(0.02 e_y) ⊗ q̄, gives Log(q̄⁻¹ Exp(d) q̄) = R(q̄)ᵀ d:
// R(q̄)ᵀ (0, 0.02, 0) / 0.01.
TEST(SmootherResidualStartPrior, HandChecked) {
  const Quatd q_prior = so3::fromRollPitchYaw(0.1, -0.2, 1.0);
  const Vec3d x_prior(1, 2, 3);
  const std::unique_ptr<ceres::CostFunction> cf(
      StartPriorResidual::Create(q_prior, x_prior, Mat6d::Identity() / 0.01));
  EXPECT_LT(evaluate(*cf, {block(q_prior), block(x_prior)}).norm(), 1e-13);
  Vec6d expected;
  expected << 1, 0, 0, 0, 0, 0;
  EXPECT_LT((evaluate(*cf, {block(q_prior), {1.01, 2, 3}}) - expected).norm(), 1e-12);
  const Vec3d dy(0, 0.02, 0);
  expected << 0, 0, 0, 0, 2, 0;
  EXPECT_LT((evaluate(*cf, {block(so3::boxplus(q_prior, dy)), block(x_prior)}) - expected).norm(),
            1e-12);
  expected << Vec3d::Zero(), q_prior.conjugate() * dy / 0.01;
  EXPECT_LT(
      (evaluate(*cf, {block(Quatd(so3::expQuat(dy) * q_prior)), block(x_prior)}) - expected).norm(),
      1e-12);
}

// ------------------------------------------------------------------------------------------
// Markov process
// ------------------------------------------------------------------------------------------

TEST(SmootherResidualMarkovProcess, JacobiansMatchNumeric) {
  std::mt19937 rng(11);
  for (int trial = 0; trial < kTrials; ++trial) {
    SCOPED_TRACE(trial);
    const double dt = uniform(rng, 0.05, 0.2);
    Vec3d a = -Vec3d(randomVector<3>(rng, 1.0)).cwiseAbs();
    if (trial % 3 == 0) a.setZero();  // random walk
    const Vec3d q = Vec3d(randomVector<3>(rng, 0.01)).cwiseAbs() + Vec3d::Constant(1e-4);
    const MarkovProcessResidual<3> cf3(dt, a, q, randomVector<3>(rng, 0.1),
                                       randomVector<3>(rng, 0.1));
    checkCostFunctionJacobians(
        cf3, {block(randomVector<3>(rng, 0.1)), block(randomVector<3>(rng, 0.1))}, {false, false});
    const MarkovProcessResidual<6> cf6(dt, Vec6d::Constant(-0.5), Vec6d::Constant(0.0025),
                                       Vec6d::Zero(), Vec6d::Zero());
    checkCostFunctionJacobians(
        cf6, {block(randomVector<6>(rng, 0.3)), block(randomVector<6>(rng, 0.3))}, {false, false});
    using V1 = Eigen::Matrix<double, 1, 1>;
    const MarkovProcessResidual<1> cf1(dt, V1(a[0]), V1(q[0]), V1(0.01), V1(-0.02));
    checkCostFunctionJacobians(
        cf1, {block(randomVector<1>(rng, 0.1)), block(randomVector<1>(rng, 0.1))}, {false, false});
  }
}

// a = −0.5 /s, q = 0.0025, Δt = 0.1: φ = e^{−0.05}, σ² = q (1 − e^{−0.1}) / 1.0. With means
// m_k = 0.1, m_{k+1} = 0.2, y_k = 0.3, y_{k+1} = 0.5: r = (0.3 − φ · 0.2)/σ. Random walk (a = 0):
// φ = 1, σ² = q Δt, and a → 0 approaches it continuously (σ² = q Δt (1 + a Δt + …)).
TEST(SmootherResidualMarkovProcess, HandCheckedAndRandomWalkLimit) {
  using V1 = Eigen::Matrix<double, 1, 1>;
  const double dt = 0.1, qd = 0.0025;
  const MarkovProcessResidual<1> ou(dt, V1(-0.5), V1(qd), V1(0.1), V1(0.2));
  const double phi = std::exp(-0.05), var = qd * (1 - std::exp(-0.1)) / 1.0;
  EXPECT_NEAR(ou.functor().phi()[0], phi, 1e-15);
  EXPECT_NEAR(ou.functor().sqrtInformation()[0], 1 / std::sqrt(var), 1e-9);
  EXPECT_NEAR(evaluate(ou, {{0.3}, {0.5}})[0], (0.3 - phi * 0.2) / std::sqrt(var), 1e-9);

  const MarkovProcessResidual<1> rw(dt, V1(0.0), V1(qd), V1(0.0), V1(0.0));
  EXPECT_EQ(rw.functor().phi()[0], 1.0);
  EXPECT_NEAR(rw.functor().sqrtInformation()[0], 1 / std::sqrt(qd * dt), 1e-12);
  EXPECT_NEAR(evaluate(rw, {{0.3}, {0.5}})[0], 0.2 / std::sqrt(qd * dt), 1e-10);
  for (double a : {-1e-3, -1e-5, -1e-8}) {
    const MarkovProcessResidual<1> near(dt, V1(a), V1(qd), V1(0.0), V1(0.0));
    const double expected_var = qd * dt * (1 + a * dt);  // to first order in a Δt
    EXPECT_NEAR(std::pow(near.functor().sqrtInformation()[0], -2) / expected_var, 1.0,
                std::max(1e-6, 2 * (a * dt) * (a * dt)))
        << "a = " << a;
  }
}

// One wheel's K-8 increment as its own row: the same number as row i of the six-row process,
// Jacobian nonzero only at component i; hand value with φ = e^{−0.05}, σ² = 0.0025 (1 − e^{−0.1}).
TEST(SmootherResidualMarkovComponent, MatchesTheBlockRowAndIsHandChecked) {
  std::mt19937 rng(21);
  const double a = -0.5, qd = 0.0025;
  for (int trial = 0; trial < kTrials; ++trial) {
    SCOPED_TRACE(trial);
    const double dt = uniform(rng, 0.05, 0.2);
    const MarkovProcessResidual<6> block6(dt, Vec6d::Constant(a), Vec6d::Constant(qd),
                                          Vec6d::Zero(), Vec6d::Zero());
    const std::vector<double> y0 = block(randomVector<6>(rng, 0.3)),
                              y1 = block(randomVector<6>(rng, 0.3));
    const Eigen::VectorXd rows = evaluate(block6, {y0, y1});
    for (int i = 0; i < 6; ++i) {
      const MarkovComponentResidual one(i, 6, dt, a, qd);
      EXPECT_NEAR(evaluate(one, {y0, y1})[0], rows[i], 1e-12) << i;
      checkCostFunctionJacobians(one, {y0, y1}, {false, false});
    }
  }
  const MarkovComponentResidual wheel3(3, 6, 0.1, a, qd);
  const double phi = std::exp(-0.05), sigma = std::sqrt(qd * (1 - std::exp(-0.1)));
  std::vector<double> y0(6, 0.0), y1(6, 0.0);
  y0[3] = 0.2, y1[3] = 0.5, y0[1] = y1[4] = 9.0;  // other wheels do not enter
  EXPECT_NEAR(evaluate(wheel3, {y0, y1})[0], (0.5 - phi * 0.2) / sigma, 1e-9);
}

// The contact angles' common mode (MarkovCommonMode): Jacobians against numerical
// differentiation at random states; the n per-wheel rows plus the common row carry exactly the
// information of the correlated process, JᵀJ = Q_d⁻¹ with Q_d = σ² (I + (ρ − 1)/n 1 1ᵀ),
// ρ = q_c/q; and a hand value: random walk (a = 0), Δt = 1, q = 1, q_c = 0.25, n = 4,
// y_k = 0, y_{k+1} = (1, 1, 1, 1): r = √(4 · 3) · 1 = 3.4641.
TEST(SmootherResidualMarkovCommonMode, CarriesTheCorrelatedProcessInformation) {
  std::mt19937 rng(23);
  for (int trial = 0; trial < kTrials; ++trial) {
    SCOPED_TRACE(trial);
    const double dt = uniform(rng, 0.05, 0.2), a = trial % 3 == 0 ? 0.0 : -uniform(rng, 0.2, 2.0);
    const double q = uniform(rng, 1e-4, 0.01), q_c = q * uniform(rng, 0.01, 0.9);
    const int n = 4 + trial % 3;
    const DynamicAnalyticCost<MarkovCommonMode> common(n, dt, a, q, q_c);
    std::vector<double> y0(static_cast<size_t>(n)), y1(static_cast<size_t>(n));
    for (int i = 0; i < n; ++i) y0[i] = uniform(rng, -0.3, 0.3), y1[i] = uniform(rng, -0.3, 0.3);
    checkCostFunctionJacobians(common, {y0, y1}, {false, false});
    // Information on y_{k+1} (y_k held): the per-wheel rows' and the common row's.
    Eigen::MatrixXd info = Eigen::MatrixXd::Zero(n, n);
    for (int i = 0; i < n; ++i) {
      const MarkovComponentResidual one(i, n, dt, a, q);
      std::vector<double> j0(static_cast<size_t>(n)), j1(static_cast<size_t>(n));
      double* jac[2] = {j0.data(), j1.data()};
      evaluate(one, {y0, y1}, jac);
      const Eigen::Map<Eigen::RowVectorXd> row(j1.data(), n);
      info += row.transpose() * row;
    }
    std::vector<double> c0(static_cast<size_t>(n)), c1(static_cast<size_t>(n));
    double* cjac[2] = {c0.data(), c1.data()};
    evaluate(common, {y0, y1}, cjac);
    const Eigen::Map<Eigen::RowVectorXd> crow(c1.data(), n);
    info += crow.transpose() * crow;
    const MarkovStep step(dt, a, q);
    const double var = 1.0 / (step.sqrt_info * step.sqrt_info);
    const Eigen::MatrixXd Qd = var * (Eigen::MatrixXd::Identity(n, n) +
                                      Eigen::MatrixXd::Constant(n, n, (q_c / q - 1.0) / n));
    EXPECT_LE((info * Qd - Eigen::MatrixXd::Identity(n, n)).cwiseAbs().maxCoeff(), 1e-9);
    // The stationary prior: the same split of N(0, (q/(−2a)) (I + (ρ − 1)/n 1 1ᵀ)).
    if (a < 0) {
      const DynamicAnalyticCost<MarkovCommonMode> prior(MarkovCommonMode::stationary(n, a, q, q_c));
      checkCostFunctionJacobians(prior, {y0}, {false});
      std::vector<double> p0(static_cast<size_t>(n));
      double* pjac[1] = {p0.data()};
      evaluate(prior, {y0}, pjac);
      const Eigen::Map<Eigen::RowVectorXd> prow(p0.data(), n);
      const double s2 = q / (-2.0 * a);
      const Eigen::MatrixXd pinfo = Eigen::MatrixXd::Identity(n, n) / s2 + prow.transpose() * prow;
      const Eigen::MatrixXd P = s2 * (Eigen::MatrixXd::Identity(n, n) +
                                      Eigen::MatrixXd::Constant(n, n, (q_c / q - 1.0) / n));
      EXPECT_LE((pinfo * P - Eigen::MatrixXd::Identity(n, n)).cwiseAbs().maxCoeff(), 1e-9);
    }
  }
  const DynamicAnalyticCost<MarkovCommonMode> hand(4, 1.0, 0.0, 1.0, 0.25);
  EXPECT_NEAR(evaluate(hand, {{0, 0, 0, 0}, {1, 1, 1, 1}})[0], std::sqrt(12.0), 1e-12);
  EXPECT_NEAR(evaluate(hand, {{1, 1, 1, 1}, {1, 1, 1, 1}})[0], 0.0, 1e-12);    // a = 0: φ = 1
  EXPECT_NEAR(evaluate(hand, {{0, 0, 0, 0}, {1, -1, 1, -1}})[0], 0.0, 1e-12);  // no common part
}

// The whitening, statistically: simulate ẏ = a y + n (m = 0) by Euler-Maruyama on a grid 200×
// finer than Δt and check that the residuals have unit variance and no lag-1 correlation.
TEST(SmootherResidualMarkovProcess, WhitensASimulatedProcess) {
  using V1 = Eigen::Matrix<double, 1, 1>;
  const double a = -0.8, qd = 0.01, dt = 0.5;
  const int substeps = 200, samples = 4000;
  const MarkovProcessResidual<1> cf(dt, V1(a), V1(qd), V1(0.0), V1(0.0));
  std::mt19937 rng(12);
  std::normal_distribution<double> n(0.0, 1.0);
  const double h = dt / substeps, step_sigma = std::sqrt(qd * h);
  double y = std::sqrt(qd / (-2 * a)) * n(rng);  // stationary start
  double sum = 0, sum_sq = 0, lag = 0, prev = 0;
  for (int k = 0; k < samples; ++k) {
    const double y0 = y;
    for (int s = 0; s < substeps; ++s) y += a * y * h + step_sigma * n(rng);
    const double r = evaluate(cf, {{y0}, {y}})[0];
    sum += r;
    sum_sq += r * r;
    lag += r * prev;
    prev = r;
  }
  const double mean = sum / samples, var = sum_sq / samples - mean * mean;
  EXPECT_NEAR(mean, 0.0, 0.06);  // 4 standard errors of 1/√4000
  EXPECT_NEAR(var, 1.0, 0.1);    // ~4.5 standard errors √(2/4000)
  EXPECT_NEAR(lag / samples, 0.0, 0.06);
}

// A covariance the data make singular (a zero noise in rover.yaml) is a NumericalError, which
// solveSegment turns into a fallback; it is not a std::logic_error (a bug, which surfaces).
TEST(SmootherWhitening, SingularCovarianceIsANumericalError) {
  const Eigen::Matrix2d zero = Eigen::Matrix2d::Zero();
  EXPECT_THROW(sqrtInformation<2>(zero, "gravity"), NumericalError);
  try {
    sqrtInformation<2>(zero, "gravity");
  } catch (const std::logic_error&) {
    ADD_FAILURE() << "a singular covariance must not be a logic_error";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("gravity"), std::string::npos);
  }
  const Eigen::Matrix2d cov = Vec2d(4.0, 0.25).asDiagonal();  // hand-checked: diag(1/2, 2)
  EXPECT_TRUE(sqrtInformation<2>(cov, "x").isApprox(Vec2d(0.5, 2.0).asDiagonal().toDenseMatrix()));
}

// ------------------------------------------------------------------------------------------
// Constraints and the residual collector
// ------------------------------------------------------------------------------------------

TEST(SmootherResidualCollector, EqualFunctorsShareACostFunctionAndTheCostIsCeres) {
  std::mt19937 rng(31);
  struct Node {
    double q[4], x[3], v[3], w[3], xi[6], b[3];
  };
  std::vector<Node> storage(3);
  for (Node& n : storage) {
    const Quatd q = randomUnitQuaternion(rng);
    for (int i = 0; i < 4; ++i) n.q[i] = q.coeffs()[i];
    for (double* a : {n.x, n.v, n.w, n.b}) Eigen::Map<Vec3d>{a} = randomVector<3>(rng, 0.1);
    Eigen::Map<Vec6d>{n.xi} = randomVector<6>(rng, 0.1);
  }
  BodyQuaternionManifold manifold;
  std::vector<NodeHandles> h(storage.size());
  for (size_t k = 0; k < h.size(); ++k) {
    using C = NodeColumns;
    Node& n = storage[k];
    const int node = static_cast<int>(k);
    h[k] = {{n.q, 4, {node, C::kAttitude, 3}, &manifold},
            {n.x, 3, {node, C::kPosition, 3}, nullptr},
            {n.v, 3, {node, C::kVelocity, 3}, nullptr},
            {n.w, 3, {node, C::kRate, 3}, nullptr},
            {n.xi, 6, {node, C::kContact, 6}, nullptr},
            {n.b, 3, {node, C::bias(6), 3}, nullptr},
            {},
            {},
            {}};
  }
  ceres::CauchyLoss loss(1.0);
  ResidualCollector out;
  CostMemo<AttitudeProcessResidual> attitude;
  CostMemo<MarkovProcess<3>> rate;
  std::vector<CostMemo<MarkovComponent>> contact(r7::kNumWheels);
  const Vec3d info(100, 200, 300), cmd(0.01, 0.0, -0.02);
  addAttitudeProcess(out, attitude, 0.05, info, h[0], h[1]);          // 0: new
  addAttitudeProcess(out, attitude, 0.05, info, h[1], h[2]);          // 1: equal functor, shared
  addAttitudeProcess(out, attitude, 0.06, info, h[1], h[2]);          // 2: Δt differs
  addRateProcess(out, rate, 0.05, -1.0, 0.01, cmd, cmd, h[0], h[1]);  // 3: new
  addRateProcess(out, rate, 0.05, -1.0, 0.01, cmd, cmd, h[1], h[2]);  // 4: shared
  addRateProcess(out, rate, 0.05, -1.0, 0.01, cmd, Vec3d::Zero(), h[1], h[2]);  // 5: mean differs
  addContactProcess(out, contact, 0.05, 2.0, 0.05, 0.05, &loss, h[0], h[1]);  // 6–11: one per wheel
  addContactProcess(out, contact, 0.05, 2.0, 0.05, 0.05, &loss, h[1],
                    h[2]);  // 12–17: shared per wheel
  addGyroIncrement(out, 0.05, Vec3d(0.001, 0.0, 0.002), 0.003, 0.01, Vec3d(0, 0, 1), h[0], h[1]);

  const std::vector<ResidualEntry>& e = out.entries();
  ASSERT_EQ(e.size(), 19u);
  EXPECT_EQ(e[1].f, e[0].f);
  EXPECT_NE(e[2].f, e[1].f);
  EXPECT_EQ(attitude.f, e[2].f);
  EXPECT_EQ(e[4].f, e[3].f);
  EXPECT_NE(e[5].f, e[4].f);
  for (size_t i = 0; i < 6; ++i) {
    EXPECT_EQ(e[12 + i].f, e[6 + i].f) << i;
    if (i > 0) {
      EXPECT_NE(e[6 + i].f, e[6].f) << i;  // each wheel its own component
    }
    EXPECT_EQ(e[6 + i].loss, &loss);
  }
  // Blocks in the functor's order, as handles of the nodes given.
  EXPECT_EQ(e[1].num_blocks, 4);
  EXPECT_EQ(e[1].blocks[0], &h[1].q);
  EXPECT_EQ(e[1].blocks[1], &h[2].q);
  EXPECT_EQ(e[1].blocks[2], &h[1].w);
  EXPECT_EQ(e[1].blocks[3], &h[2].w);
  EXPECT_EQ(e[18].num_blocks, 3);
  EXPECT_EQ(e[18].blocks[2], &h[0].bias);
  EXPECT_EQ(e[18].kind, std::string("gyro"));

  ceres::Problem::Options po;
  po.cost_function_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  po.loss_function_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  po.manifold_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  ceres::Problem problem(po);
  for (const NodeHandles& n : h)
    for (const BlockHandle* b : {&n.q, &n.x, &n.v, &n.w, &n.xi, &n.bias})
      problem.AddParameterBlock(b->data, b->size, b->manifold);
  out.addTo(problem);
  EXPECT_EQ(problem.NumResidualBlocks(), 19);
  double ceres_cost = 0.0;
  problem.Evaluate(ceres::Problem::EvaluateOptions(), &ceres_cost, nullptr, nullptr, nullptr);
  BlockEvaluator evaluator;
  EXPECT_NEAR(out.cost(evaluator), ceres_cost, 1e-12 * ceres_cost);
  EXPECT_GT(ceres_cost, 0.0);
}

}  // namespace
}  // namespace traverse::smoother
