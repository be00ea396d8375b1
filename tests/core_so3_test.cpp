// SO(3)/SE(3) helpers: reference values (GTSAM's gtsam/geometry/tests/testRot3.cpp), the angles
// near 0 and π, and derivatives against finite differences.
#include <gtest/gtest.h>

#include "support/jacobian_check.h"
#include "traverse/core/se3.h"
#include "traverse/core/so3.h"

namespace traverse {
namespace {

using testing::randomUnitQuaternion;
using testing::randomVector;

// testRot3.cpp "Rodrigues2": 3.14/4 about y.
TEST(CoreSo3, ExpMatchesGtsamRodrigues2) {
  Mat3d expected;
  expected << 0.707388, 0, 0.706825, 0, 1, 0, -0.706825, 0, 0.707388;
  EXPECT_TRUE(so3::exp(Vec3d(0, 3.14 / 4.0, 0)).isApprox(expected, 1e-5));
}

// testRot3.cpp "Rodrigues4": π/2 about z.
TEST(CoreSo3, ExpMatchesGtsamRodrigues4) {
  Mat3d expected;
  expected << 0, -1, 0, 1, 0, 0, 0, 0, 1;
  EXPECT_LT((so3::exp(Vec3d(0, 0, M_PI / 2)) - expected).norm(), 1e-15);
}

// testRot3.cpp "log": Log(Exp(w)) = w for zero, tiny (Taylor), normal and π rotations.
TEST(CoreSo3, LogMatchesGtsamCases) {
  const double n = std::sqrt(21.0);
  const Vec3d dir(1 / n, 4 / n, 2 / n);
  std::vector<Vec3d> cases = {Vec3d::Zero()};
  for (double d : {1e-4, 0.1}) {
    cases.insert(cases.end(), {Vec3d(d, 0, 0), Vec3d(0, d, 0), Vec3d(0, 0, d), dir * d});
  }
  for (const Vec3d& w : cases)
    EXPECT_LT((so3::log(so3::exp(w)) - w).norm(), 1e-12) << w.transpose();
  // At exactly π, w and −w are the same rotation: accept either, and check it round-trips.
  for (const Vec3d& w :
       {Vec3d(M_PI, 0, 0), Vec3d(0, M_PI, 0), Vec3d(0, 0, M_PI), Vec3d(dir * M_PI)}) {
    const Vec3d l = so3::log(so3::expQuat(w));
    EXPECT_TRUE((l - w).norm() < 1e-12 || (l + w).norm() < 1e-12) << l.transpose();
    EXPECT_LT((so3::exp(l) - so3::exp(w)).norm(), 1e-12);
  }
  // 360°: identity.
  for (const Vec3d& w : {Vec3d(2 * M_PI, 0, 0), Vec3d(dir * 2 * M_PI)}) {
    EXPECT_LT(so3::log(so3::expQuat(w)).norm(), 1e-12);
  }
}

// testRot3.cpp "logmapStability": w = (1e-8, 0, 0) exactly recovered.
TEST(CoreSo3, LogIsStableForTinyAngles) {
  const Vec3d w(1e-8, 0, 0);
  EXPECT_LT((so3::log(so3::expQuat(w)) - w).norm(), 1e-15);
}

// testRot3.cpp "expmapStability": the Taylor series of Rodrigues' formula.
TEST(CoreSo3, ExpIsStableForTinyAngles) {
  const Vec3d w(78e-9, 5e-8, 97e-7);
  const double t2 = w.squaredNorm();
  const Mat3d W = so3::skew(w);
  const Mat3d expected =
      Mat3d::Identity() + (1 - t2 / 6 + t2 * t2 / 120) * W + (0.5 - t2 / 24) * W * W;
  EXPECT_LT((so3::exp(w) - expected).norm(), 1e-10);
}

// testRot3.cpp "quaternion": q1 ↔ R1.
TEST(CoreSo3, QuaternionMatchesGtsamReference) {
  const Quatd q1(0.710997408193224, 0.360544029310185, 0.594459869568306, 0.105395217842782);
  Mat3d R1;
  R1 << 0.271018623057411, 0.278786459830371, 0.921318086098018, 0.578529366719085,
      0.717799701969298, -0.387385285854279, -0.769319620053772, 0.637998195662053,
      0.033250932803219;
  EXPECT_LT((q1.toRotationMatrix() - R1).norm(), 1e-12);
  EXPECT_LT((so3::exp(so3::log(q1)) - R1).norm(), 1e-12);
}

// testRot3.cpp "RQ": xyz angles of Rodrigues(0.1, 0.4, 0.2) — our roll, pitch, yaw (Z-Y-X).
TEST(CoreSo3, RollPitchYawMatchesGtsamRQ) {
  const Vec3d rpy = so3::rollPitchYaw(so3::expQuat(Vec3d(0.1, 0.4, 0.2)));
  EXPECT_LT((rpy - Vec3d(0.14715, 0.385821, 0.231671)).norm(), 1e-6);
  const Vec3d back = so3::rollPitchYaw(so3::fromRollPitchYaw(0.1, 0.2, 0.3));
  EXPECT_LT((back - Vec3d(0.1, 0.2, 0.3)).norm(), 1e-14);
}

TEST(CoreSo3, LogIsAccurateNearPi) {
  std::mt19937 rng(7);
  for (double eps : {1e-3, 1e-6, 1e-9}) {
    for (int k = 0; k < 20; ++k) {
      const Vec3d w = randomVector<3>(rng).normalized() * (M_PI - eps);
      EXPECT_LT((so3::log(so3::expQuat(w)) - w).norm(), 1e-9) << "eps " << eps;
      EXPECT_LT((so3::log(so3::exp(w)) - w).norm(), 1e-7) << "matrix path, eps " << eps;
    }
  }
}

TEST(CoreSo3, ExpLogRoundTripRandom) {
  std::mt19937 rng(1);
  for (int k = 0; k < 200; ++k) {
    const Quatd q = randomUnitQuaternion(rng);
    EXPECT_NEAR(so3::expQuat(so3::log(q)).angularDistance(q), 0.0, 1e-12);
  }
}

TEST(CoreSo3, ExpAndLogJetJacobiansMatchNumeric) {
  std::mt19937 rng(2);
  for (int k = 0; k < 50; ++k) {
    const Vec3d phi = randomVector<3>(rng, 3.0 / std::sqrt(3.0));
    testing::expectJacobianMatchesNumeric<4, 3>(
        [](const auto& x) {
          return so3::expQuat(Vec3<typename std::decay_t<decltype(x)>::Scalar>(x)).coeffs().eval();
        },
        phi);
    const Quatd q0 = randomUnitQuaternion(rng);
    testing::expectJacobianMatchesNumeric<3, 3>(
        [&](const auto& d) {
          using T = typename std::decay_t<decltype(d)>::Scalar;
          return so3::log(so3::boxplus(Quat<T>(q0.cast<T>()), Vec3<T>(d)));
        },
        Vec3d::Zero().eval(), 1e-6);
  }
}

TEST(CoreSo3, JetDerivativesAreFiniteAtZero) {
  const auto J = testing::autodiffJacobian<4, 3>(
      [](const auto& x) {
        return so3::expQuat(Vec3<typename std::decay_t<decltype(x)>::Scalar>(x)).coeffs().eval();
      },
      Vec3d::Zero().eval());
  // d vec(q)/dφ = ½ I, d w/dφ = 0 at φ = 0 (coeffs order x, y, z, w).
  EXPECT_LT((J.topRows<3>() - 0.5 * Mat3d::Identity()).norm(), 1e-15);
  EXPECT_LT(J.row(3).norm(), 1e-15);
  const auto Jl = testing::autodiffJacobian<3, 3>(
      [](const auto& d) {
        using T = typename std::decay_t<decltype(d)>::Scalar;
        return so3::log(so3::expQuat(Vec3<T>(d)));
      },
      Vec3d::Zero().eval());
  EXPECT_LT((Jl - Mat3d::Identity()).norm(), 1e-14);
}

TEST(CoreSo3, RightJacobianMatchesNumericAndInverse) {
  std::mt19937 rng(3);
  for (double scale : {1e-6, 0.3, 2.5}) {
    for (int k = 0; k < 20; ++k) {
      const Vec3d phi = randomVector<3>(rng).normalized() * scale;
      // Log(Exp(φ)⁻¹ Exp(φ + δ)) ≈ Jr(φ) δ
      const auto f = [&](const Vec3d& d) {
        return so3::boxminus(so3::expQuat(Vec3d(phi + d)), so3::expQuat(phi));
      };
      const Mat3d Jn = testing::numericJacobian<3, 3>(f, Vec3d::Zero().eval());
      EXPECT_LT((so3::rightJacobian(phi) - Jn).norm(), 1e-7);
      EXPECT_LT(
          (so3::rightJacobianInverse(phi) * so3::rightJacobian(phi) - Mat3d::Identity()).norm(),
          1e-9);
      EXPECT_LT((so3::leftJacobian(phi) - so3::exp(phi) * so3::rightJacobian(phi)).norm(), 1e-9);
    }
  }
}

TEST(CoreSe3, AdjointAndInverseComposeToIdentity) {
  std::mt19937 rng(4);
  for (int k = 0; k < 50; ++k) {
    const Posed g{randomUnitQuaternion(rng).toRotationMatrix(), randomVector<3>(rng)};
    EXPECT_LT((adjoint(g) * adjointInverse(g) - Mat6d::Identity()).norm(), 1e-12);
    EXPECT_LT((adjointInverse(g) - adjoint(g.inverse())).norm(), 1e-12);
    const Twistd V = randomVector<6>(rng);
    EXPECT_LT((applyAdjointInverse(g, V) - adjointInverse(g) * V).norm(), 1e-12);
  }
}

// Hand-checked: a frame translated by p, rotating about its parent's z at 1 rad/s through the
// parent origin: the child origin moves at ω × p, seen from the child.
TEST(CoreSe3, AdjointInverseGivesPointVelocity) {
  const Posed g{Mat3d::Identity(), Vec3d(2.0, 0.0, 0.0)};
  Twistd V;
  V << 0, 0, 0, 0, 0, 1;
  const Twistd Vc = applyAdjointInverse(g, V);
  EXPECT_LT((Vc.head<3>() - Vec3d(0, 2, 0)).norm(), 1e-15);
  EXPECT_LT((Vc.tail<3>() - Vec3d(0, 0, 1)).norm(), 1e-15);
}

}  // namespace
}  // namespace traverse
