// Shared test helpers: the Jacobian that ceres::Jet gives a scalar-templated model (the one the
// EKF and the smoother use) against central finite differences, and random test states.
//
// A model under test is a generic lambda taking one Eigen vector x of its scalar type T and
// returning an Eigen vector of T. Quaternion arguments enter as a body-frame perturbation δθ
// around a base attitude (q = q0 ⊗ Exp(δθ)), the project's tangent space.
#pragma once

#include <random>

#include <ceres/jet.h>
#include <gtest/gtest.h>

#include "traverse/core/so3.h"

namespace traverse::testing {

template <int NOut, int NIn, typename F>
Eigen::Matrix<double, NOut, NIn> autodiffJacobian(const F& f,
                                                  const Eigen::Matrix<double, NIn, 1>& x) {
  using Jet = ceres::Jet<double, NIn>;
  Eigen::Matrix<Jet, NIn, 1> xj;
  for (int i = 0; i < NIn; ++i) xj[i] = Jet(x[i], i);
  const Eigen::Matrix<Jet, NOut, 1> y = f(xj);
  Eigen::Matrix<double, NOut, NIn> J;
  for (int r = 0; r < NOut; ++r) J.row(r) = y[r].v.transpose();
  return J;
}

template <int NOut, int NIn, typename F>
Eigen::Matrix<double, NOut, NIn> numericJacobian(const F& f, const Eigen::Matrix<double, NIn, 1>& x,
                                                 double h = 1e-6) {
  Eigen::Matrix<double, NOut, NIn> J;
  for (int i = 0; i < NIn; ++i) {
    Eigen::Matrix<double, NIn, 1> xp = x, xm = x;
    xp[i] += h;
    xm[i] -= h;
    J.col(i) = (f(xp) - f(xm)) / (2.0 * h);
  }
  return J;
}

/// Expects the Jet Jacobian to match central differences within `tol` (absolute, scaled by
/// max(1, |J|)) and to be finite.
template <int NOut, int NIn, typename F>
void expectJacobianMatchesNumeric(const F& f, const Eigen::Matrix<double, NIn, 1>& x,
                                  double tol = 1e-6) {
  const auto Ja = autodiffJacobian<NOut, NIn>(f, x);
  const auto Jn = numericJacobian<NOut, NIn>(f, x);
  ASSERT_TRUE(Ja.allFinite()) << "autodiff Jacobian not finite at x = " << x.transpose();
  const double scale = std::max(1.0, Jn.cwiseAbs().maxCoeff());
  EXPECT_LE((Ja - Jn).cwiseAbs().maxCoeff(), tol * scale)
      << "x = " << x.transpose() << "\nautodiff:\n"
      << Ja << "\nnumeric:\n"
      << Jn;
}

/// A uniformly distributed random unit quaternion (Shoemake's method).
inline Quatd randomUnitQuaternion(std::mt19937& rng) {
  std::uniform_real_distribution<double> u(0.0, 1.0);
  const double u1 = u(rng), u2 = 2.0 * M_PI * u(rng), u3 = 2.0 * M_PI * u(rng);
  const double a = std::sqrt(1.0 - u1), b = std::sqrt(u1);
  return Quatd(b * std::cos(u3), a * std::sin(u2), a * std::cos(u2), b * std::sin(u3));
}

template <int N>
Eigen::Matrix<double, N, 1> randomVector(std::mt19937& rng, double scale = 1.0) {
  std::uniform_real_distribution<double> u(-scale, scale);
  Eigen::Matrix<double, N, 1> v;
  for (int i = 0; i < N; ++i) v[i] = u(rng);
  return v;
}

/// Source tree root (for datasets/), from the environment or the build definition.
inline std::string sourceDir() {
  if (const char* env = std::getenv("TRAVERSE_SOURCE_DIR")) return env;
  return TRAVERSE_SOURCE_DIR;
}

}  // namespace traverse::testing
