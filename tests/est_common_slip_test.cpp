// The wheels' common slip c (rover.yaml slip_noise.common_*; issue 13 "correlated slip as
// states", issue 15's slip burst): a first-order Gauss–Markov process per body axis that the
// slip rows see as t_i(v + c, ω, ξ_i), and with c_ω (common_yaw_rate_rad_s) as
// t_i(v + c_v, ω + c_ω e_z, ξ_i). Checked here: the EKF's process (F, the stationary σ),
// its slip update with c against a dense reference whose H is central differences of the whole
// residual over the error state (random unit quaternions, random joint samples, with and without
// cmd.csv, both velocity models), and the smoother's slip residual with the c block against
// central differences and a hand-checked value.
#include <gtest/gtest.h>
#include <cmath>

#include <random>

#include "support/ekf_state.h"
#include "support/jacobian_check.h"
#include "support/rocky7.h"
#include "traverse/estimators/ekf.h"
#include "traverse/io/rover_config.h"
#include "traverse/rover/nominal_slip.h"
#include "traverse/smoother/residuals/slip_residual.h"

namespace traverse::est {
namespace {

using I = EkfIndex;
using testing::randomJointSample;
using testing::randomUnitQuaternion;
using testing::randomVector;
constexpr int kWheels = 6;
constexpr int kN = ekfStates(kWheels, 2);   // 23: c_x, c_y
constexpr int kC = I::commonSlip(kWheels);  // 21

io::RoverConfig commonSlipConfig() {
  io::RoverConfig c =
      io::loadRoverConfig(testing::sourceDir() + "/datasets/rovers/rocky7/rover.yaml");
  c.slip_noise.common_longitudinal_mps = 0.012;
  c.slip_noise.common_lateral_mps = 0.005;
  c.slip_noise.common_time_constant_s = 4.0;
  return c;
}

EkfState randomState(std::mt19937& rng) {
  return testing::randomEkfState(rng, kWheels, 2);
}

TEST(EstCommonSlip, StateExistsOnlyWhenDeclared) {
  const InitialState init;
  io::RoverConfig off = commonSlipConfig();
  off.slip_noise.common_longitudinal_mps = off.slip_noise.common_lateral_mps = 0.0;
  const Ekf without(off, testing::rocky7(), {}, init, false, true);
  EXPECT_EQ(without.numStates(), ekfStates(kWheels));
  EXPECT_FALSE(without.hasCommonSlip());
  const io::RoverConfig on = commonSlipConfig();
  const Ekf with(on, testing::rocky7(), {}, init, false, true);
  EXPECT_EQ(with.numStates(), kN);
  EXPECT_TRUE(with.hasCommonSlip());
  // It starts in the process' stationary distribution, uncorrelated with the rest.
  const EkfMatrix& P = with.covariance();
  EXPECT_DOUBLE_EQ(P(kC, kC), 0.012 * 0.012);
  EXPECT_DOUBLE_EQ(P(kC + 1, kC + 1), 0.005 * 0.005);
  EXPECT_TRUE(P.block(0, kC, kC, 2).isZero(0.0));
}

// F with c is F without it plus the diagonal −1/τ on c; propagation keeps c's stationary σ
// (q = 2σ²/τ) and decays its mean by exp(−Δt/τ).
TEST(EstCommonSlip, ProcessIsAGaussMarkovWithTheDeclaredSigmaAndTimeConstant) {
  const InitialState init;
  const io::RoverConfig on = commonSlipConfig();
  io::RoverConfig off = on;
  off.slip_noise.common_longitudinal_mps = off.slip_noise.common_lateral_mps = 0.0;
  std::mt19937 rng(70);
  for (const bool accel : {false, true}) {
    EkfOptions o;
    o.velocity =
        accel ? EkfOptions::VelocityModel::kAccelDriven : EkfOptions::VelocityModel::kPerturbation;
    Ekf with(on, testing::rocky7(), o, init, true, true);
    Ekf without(off, testing::rocky7(), o, init, true, true);
    const EkfState x = randomState(rng);
    with.setState(x), without.setState(x);
    EkfInputs in;
    in.gyro = randomVector<3>(rng, 0.3);
    in.v_cmd = randomVector<3>(rng, 0.1), in.w_cmd = randomVector<3>(rng, 0.2);
    in.accel = Vec3d(0.1, -0.2, 9.7), in.has_accel = accel;
    const EkfMatrix F = with.processJacobian(in), F0 = without.processJacobian(in);
    EXPECT_EQ(Eigen::MatrixXd(F.topLeftCorner(kC, kC)), Eigen::MatrixXd(F0));
    EXPECT_TRUE(F.block(0, kC, kC, 2).isZero(0.0));
    EXPECT_TRUE(F.block(kC, 0, 2, kC).isZero(0.0));
    EXPECT_TRUE(Eigen::Matrix2d(F.block<2, 2>(kC, kC))
                    .isApprox(Eigen::Matrix2d::Identity() * (-1.0 / 4.0)));
  }
  // 200 s of propagation at 20 Hz with nothing else: the mean decays, σ stays (to O(Δt/τ)).
  Ekf ekf(on, testing::rocky7(), {}, init, false, true);
  EkfState x = ekf.state();
  x.common_slip = Vec3d(0.02, -0.01, 0.0);
  ekf.setState(x);
  for (int k = 0; k < 20; ++k) ekf.propagate(0.05, EkfInputs{});
  EXPECT_NEAR(ekf.state().common_slip.x(), 0.02 * std::exp(-1.0 / 4.0), 1e-12);
  EXPECT_NEAR(ekf.state().common_slip.y(), -0.01 * std::exp(-1.0 / 4.0), 1e-12);
  for (int k = 0; k < 4000; ++k) ekf.propagate(0.05, EkfInputs{});
  EXPECT_NEAR(std::sqrt(ekf.covariance()(kC, kC)), 0.012, 0.012 * 0.01);
  EXPECT_NEAR(std::sqrt(ekf.covariance()(kC + 1, kC + 1)), 0.005, 0.005 * 0.01);
}

// With c_ω declared: a 3 × 3 diagonal −1/τ block, the stationary σ of each component, and c_ω
// starts in it, uncorrelated with the rest.
TEST(EstCommonSlip, YawComponentIsAGaussMarkovWithItsOwnSigma) {
  io::RoverConfig cfg = commonSlipConfig();
  cfg.slip_noise.common_yaw_rate_rad_s = 0.004;
  Ekf ekf(cfg, testing::rocky7(), {}, InitialState{}, false, true);
  ASSERT_EQ(ekf.numStates(), ekfStates(kWheels, 3));
  EXPECT_DOUBLE_EQ(ekf.covariance()(kC + 2, kC + 2), 0.004 * 0.004);
  EXPECT_TRUE(ekf.covariance().block(0, kC + 2, kC + 2, 1).isZero(0.0));
  const EkfMatrix F = ekf.processJacobian(EkfInputs{});
  EXPECT_TRUE(
      Eigen::Matrix3d(F.block<3, 3>(kC, kC)).isApprox(Eigen::Matrix3d::Identity() * (-1.0 / 4.0)));
  EXPECT_TRUE(F.block(0, kC + 2, kC + 2, 1).isZero(0.0));
  EXPECT_TRUE(F.block(kC + 2, 0, 1, kC + 2).isZero(0.0));
  EkfState x = ekf.state();
  x.common_slip = Vec3d(0.0, 0.0, 0.01);
  ekf.setState(x);
  for (int k = 0; k < 20; ++k) ekf.propagate(0.05, EkfInputs{});
  EXPECT_NEAR(ekf.state().common_slip.z(), 0.01 * std::exp(-1.0 / 4.0), 1e-12);
  for (int k = 0; k < 4000; ++k) ekf.propagate(0.05, EkfInputs{});
  EXPECT_NEAR(std::sqrt(ekf.covariance()(kC + 2, kC + 2)), 0.004, 0.004 * 0.01);
}

// updateSlip with c, one wheel at a time, against the textbook update with H = −∂r/∂δx by
// central differences of the residual r = nominal − t(v + c_v, ω + c_ω e_z, ξ_i) over every
// error-state direction (so the composition onto v_p, ω_p, the bias, ξ_i and c is what is
// checked), with c = (c_x, c_y) and with c_ω.
TEST(EstCommonSlip, EkfSlipUpdateMatchesDenseReferenceWithNumericH) {
  const rover::RoverGeometry& geo = testing::rocky7();
  std::mt19937 rng(71);
  double worst = 0.0;
  for (const int nc : {2, 3}) {
    io::RoverConfig cfg = commonSlipConfig();
    if (nc == 3) cfg.slip_noise.common_yaw_rate_rad_s = 0.004;
    const int n = ekfStates(kWheels, nc);
    for (const bool has_cmd : {true, false}) {
      for (const bool accel : {false, true}) {
        EkfOptions o = testing::ungatedOptions(accel);
        o.common_slip_jumps = false;  // the update alone (random states are far from consistent)
        Ekf ekf(cfg, geo, o, InitialState{}, true, has_cmd);
        ASSERT_EQ(ekf.numStates(), n);
        ASSERT_EQ(ekf.commonSlipStates(), nc);
        for (int trial = 0; trial < 6; ++trial) {
          const int wheel = trial % kWheels;
          rover::JointSample js = randomJointSample(rng);
          for (auto& C : js.joint_twist_covariance) C = 1e-6 * Mat6d::Identity();
          js.used.assign(kWheels, 0);
          js.used[static_cast<size_t>(wheel)] = 1;
          const EkfState x = testing::randomEkfState(rng, kWheels, nc);
          const EkfInputs in = testing::randomSlipInputs(rng, has_cmd, accel);
          const EkfMatrix P = testing::randomSmallCovariance(rng, n);
          ekf.setState(x);
          ekf.setCovariance(P);
          ekf.updateSlip(js, in);

          const Twistd cmd = rover::nominalBodyTwist(geo, in.v_cmd.x(), in.w_cmd.z());
          const auto s_of = [&](const EkfState& y) {
            Eigen::Matrix<double, 7, 1> s;
            const Vec3d v = accel ? y.v_p : ekf.velocity<double>(y.v_p, in);
            s << v + Vec3d(y.common_slip.x(), y.common_slip.y(), 0.0),
                ekf.omega<double>(y.w_p, y.bias, in) + Vec3d(0, 0, y.common_slip.z()), y.xi[wheel];
            return s;
          };
          const auto r_of = [&](const EkfVector& dx) {
            Eigen::Matrix<double, 4, 7> unused;
            return slipUpdateResidual(geo, js, wheel, has_cmd ? &cmd : nullptr,
                                      s_of(testing::ekfBoxplus(x, dx, nc, false)), &unused);
          };
          Eigen::MatrixXd H(4, n);
          const double eps = 1e-6;
          for (int j = 0; j < n; ++j) {
            const EkfVector e = EkfVector::Unit(n, j) * eps;
            H.col(j) = -(r_of(e) - r_of(-e)) / (2 * eps);
          }
          Eigen::Matrix<double, 4, 7> Hs, Jt;
          const Vec4d r =
              slipUpdateResidual(geo, js, wheel, has_cmd ? &cmd : nullptr, s_of(x), &Hs, &Jt);
          const Eigen::Matrix<double, 7, 1> s = s_of(x);
          const Eigen::Matrix4d R = rover::slipCovariance(cfg.slip_noise, js, wheel, s.head<3>(),
                                                          s.segment<3>(3), Jt.leftCols<6>());
          // (the filter is three-axis here: the gyro's noise on every axis, unit variance factor)
          const testing::DenseUpdate ref = testing::denseEkfUpdate(
              P, H,
              testing::withGyroNoise(R, H, Mat3d::Identity(), std::pow(cfg.gyro.noise_rad_s, 2)),
              r);
          const double err = testing::relativeDifference(ekf.covariance(), ref.P);
          worst = std::max(worst, err);
          EXPECT_LE(err, 1e-7) << "c " << nc << " cmd " << has_cmd << " accel " << accel
                               << " wheel " << wheel;
          const EkfState y = ekf.state(), y_ref = testing::ekfBoxplus(x, ref.dx, nc, false);
          EXPECT_LE((y.common_slip - y_ref.common_slip).cwiseAbs().maxCoeff(), 1e-9);
          EXPECT_LE((y.v_p - y_ref.v_p).cwiseAbs().maxCoeff(), 1e-9);
          EXPECT_LE((y.w_p - y_ref.w_p).cwiseAbs().maxCoeff(), 1e-9);
          EXPECT_LE((y.xi - y_ref.xi).cwiseAbs().maxCoeff(), 1e-9);
          EXPECT_LE((y.bias - y_ref.bias).cwiseAbs().maxCoeff(), 1e-9);
          // c really is in the update: its columns of H are v's x and y columns (s = v + c),
          // and c_ω's is ω_p's z column (s = ω + c_ω e_z).
          EXPECT_LE((H.middleCols<2>(kC) - H.middleCols<2>(I::kVel)).cwiseAbs().maxCoeff(), 1e-7);
          EXPECT_GT(H.middleCols<2>(kC).cwiseAbs().maxCoeff(), 0.1);
          if (nc == 3) {
            EXPECT_LE((H.col(kC + 2) - H.col(I::kRate + 2)).cwiseAbs().maxCoeff(), 1e-7);
            EXPECT_GT(H.col(kC + 2).cwiseAbs().maxCoeff(), 0.05);
          }
        }
      }
    }
  }
  RecordProperty("worst_relative_error", std::to_string(worst));
}

// The jump test: all six wheels at rest on level ground while the filter's body moves at v
// along x (a commanded 10 cm/s): the wheels' mean mismatch is −v in x. Against c's σ 12 mm/s,
// v's 10 mm/s and the rows' 4 mm/s over six wheels, d² = 0.1² / (1.44e-4 + 1e-4 + 2.7e-6) ≈ 40
// > 13.8 (χ²₂ at 0.999): it fires once, growing c's variance by ū ūᵀ = 0.1² in x, so the rows
// then move c (to ≈ −0.1 · 0.0101/0.0103), not v; 1 mm/s does not fire.
TEST(EstCommonSlip, EkfJumpTestFiresOnALargeCommonMismatchOnly) {
  const io::RoverConfig cfg = commonSlipConfig();
  const rover::RoverGeometry& geo = testing::rocky7();
  const auto kin =
      rover::forwardKinematics<double>(geo, rover::JointVectord::Zero(geo.numCoords()));
  rover::JointSample js;
  js.resize(kWheels);
  for (int i = 0; i < kWheels; ++i) {
    js.T_body_wheel[static_cast<size_t>(i)] = kin[i].T_body_wheel;
    js.joint_twist[static_cast<size_t>(i)].setZero();
    js.joint_twist_covariance[static_cast<size_t>(i)].setZero();
  }
  for (const double speed : {0.1, 0.001}) {
    EkfOptions o;
    o.velocity = EkfOptions::VelocityModel::kPerturbation;
    o.gating = false;
    Ekf ekf(cfg, geo, o, InitialState{}, false, true);
    const double before = ekf.covariance()(kC, kC);
    EkfInputs in;
    in.v_cmd = Vec3d(speed, 0, 0);
    ekf.updateSlip(js, in);
    if (speed > 0.01) {
      EXPECT_EQ(ekf.stats().common_slip_jumps, 1);
      // The jump's variance was added before the rows, which then moved c, not only v.
      EXPECT_NEAR(ekf.state().common_slip.x(), -0.1 * 0.0101 / 0.0103, 0.003);
      EXPECT_NEAR(ekf.state().v_p.x(), -0.1 * 0.0001 / 0.0103, 0.003);
      EXPECT_LT(ekf.covariance()(kC, kC), before + speed * speed);
    } else {
      EXPECT_EQ(ekf.stats().common_slip_jumps, 0);
    }
  }
}

// Hand-checked: six level wheels at zero joint angles and rates, the body moving at
// v = (0.05, 0, 0) with no rotation, c = (0.02, 0): each wheel's contact point slips at
// v + c = 0.07 m/s along x, so with a zero nominal slip the residual's first row is −0.07 (unit
// weights), and c's Jacobian block is −I on the x, y rows.
TEST(SmootherCommonSlip, SlipResidualHandChecked) {
  const rover::RoverGeometry& geo = testing::rocky7();
  const auto kin =
      rover::forwardKinematics<double>(geo, rover::JointVectord::Zero(geo.numCoords()));
  for (int i = 0; i < kWheels; ++i) {
    const smoother::SlipWheelData d{kin[i].T_body_wheel, geo.wheels[i].radius, Twistd::Zero(),
                                    Vec4d::Zero(), Eigen::Matrix4d::Identity()};
    const smoother::SlipResidual f(i, kWheels, &d, 2);
    ASSERT_EQ(f.parameter_block_sizes().size(), 4u);
    const double v[3] = {0.05, 0.0, 0.0}, w[3] = {0, 0, 0}, c[2] = {0.02, 0.0};
    double xi[kWheels] = {};
    const double* params[4] = {v, w, xi, c};
    double r[4], Jc[8];
    double* jac[4] = {nullptr, nullptr, nullptr, Jc};
    ASSERT_TRUE(f.Evaluate(params, r, jac));
    EXPECT_NEAR(r[0], -0.07, 1e-15) << "wheel " << i;
    EXPECT_NEAR(r[1], 0.0, 1e-15);
    EXPECT_NEAR(r[2], 0.0, 1e-15);
    EXPECT_NEAR(r[3], 0.0, 1e-15);
    const Eigen::Map<const Eigen::Matrix<double, 4, 2, Eigen::RowMajor>> J(Jc);
    Eigen::Matrix<double, 4, 2> expected = Eigen::Matrix<double, 4, 2>::Zero();
    expected(0, 0) = expected(1, 1) = -1.0;
    EXPECT_LE((J - expected).cwiseAbs().maxCoeff(), 1e-15) << J;
  }
}

// The smoother's slip residual with c: its analytic Jacobians (all four blocks) against the Jet
// Jacobian of the templated model (the fast twin's proof) and against central differences, at
// random joint samples and states.
TEST(SmootherCommonSlip, SlipResidualJacobiansMatchNumeric) {
  std::mt19937 rng(72);
  for (int trial = 0; trial < 24; ++trial) {
    const int wheel = trial % kWheels;
    const rover::JointSample js = randomJointSample(rng);
    Eigen::Matrix4d L = Eigen::Matrix4d::Identity() * 200.0;
    L(0, 1) = 30.0, L(2, 3) = -10.0;
    const smoother::SlipWheelData d{js.T_body_wheel[static_cast<size_t>(wheel)],
                                    testing::rocky7().wheels[static_cast<size_t>(wheel)].radius,
                                    js.joint_twist[static_cast<size_t>(wheel)],
                                    randomVector<4>(rng, 0.01), L};
    const smoother::SlipResidual f(wheel, kWheels, &d, 2);
    // x = (v, ω, ξ (6), c)
    Eigen::Matrix<double, 14, 1> x;
    x << randomVector<3>(rng, 0.3), randomVector<3>(rng, 0.5), randomVector<kWheels>(rng, 0.4),
        randomVector<2>(rng, 0.03);
    const auto eval = [&](const Eigen::Matrix<double, 14, 1>& z, double* jac_out) {
      const double* params[4] = {z.data(), z.data() + 3, z.data() + 6, z.data() + 12};
      Vec4d r;
      double J0[12], J1[12], J2[4 * kWheels], J3[8];
      double* jac[4] = {J0, J1, J2, J3};
      EXPECT_TRUE(f.Evaluate(params, r.data(), jac_out ? jac : nullptr));
      if (jac_out) {  // stack into a 4 × 14 row-major matrix
        using Rm = Eigen::Matrix<double, 4, Eigen::Dynamic, Eigen::RowMajor>;
        Eigen::Map<Eigen::Matrix<double, 4, 14, Eigen::RowMajor>> out(jac_out);
        out.leftCols<3>() = Eigen::Map<Rm>(J0, 4, 3);
        out.middleCols<3>(3) = Eigen::Map<Rm>(J1, 4, 3);
        out.middleCols<kWheels>(6) = Eigen::Map<Rm>(J2, 4, kWheels);
        out.rightCols<2>() = Eigen::Map<Rm>(J3, 4, 2);
      }
      return r;
    };
    double Ja[4 * 14];
    const Vec4d r = eval(x, Ja);
    // The templated model (what every estimator shares), as Jets: value and Jacobian.
    const auto model = [&](const auto& z) {
      using T = typename std::decay_t<decltype(z)>::Scalar;
      return f.residual<T>(Vec3<T>(z.template head<3>()), Vec3<T>(z.template segment<3>(3)),
                           Eigen::Matrix<T, kWheels, 1>(z.template segment<kWheels>(6)),
                           Vec3<T>(z[12], z[13], T(0)));
    };
    EXPECT_LE((r - model(x)).cwiseAbs().maxCoeff(), 1e-12);
    const Eigen::Matrix<double, 4, 14> Jjet = testing::autodiffJacobian<4, 14>(model, x);
    const Eigen::Matrix<double, 4, 14> Jn =
        testing::numericJacobian<4, 14>([&](const auto& z) { return eval(z, nullptr); }, x);
    const Eigen::Map<const Eigen::Matrix<double, 4, 14, Eigen::RowMajor>> J(Ja);
    EXPECT_LE((J - Jjet).cwiseAbs().maxCoeff(), 1e-12 * std::max(1.0, Jjet.cwiseAbs().maxCoeff()))
        << "wheel " << wheel << "\nanalytic:\n"
        << J << "\nJet:\n"
        << Jjet;
    EXPECT_LE((J - Jn).cwiseAbs().maxCoeff(), 1e-6 * std::max(1.0, Jn.cwiseAbs().maxCoeff()))
        << "wheel " << wheel << "\nanalytic:\n"
        << J << "\nnumeric:\n"
        << Jn;
  }
}

// Hand-checked c_ω: six level wheels at zero joint angles and rates, the body at rest and
// c = (0, 0, 0.1): the wheels roll as if the body turned at 0.1 rad/s, so wheel i's contact point
// (x_i, y_i, −) slips at (−0.1 y_i, 0.1 x_i, 0) and spins at 0.1 about its normal; with a zero
// nominal (cmd.csv) and unit weights the residual is −t, and c_ω's Jacobian column is −∂t/∂ω_z.
TEST(SmootherCommonSlip, YawSlipResidualHandChecked) {
  const rover::RoverGeometry& geo = testing::rocky7();
  const auto kin =
      rover::forwardKinematics<double>(geo, rover::JointVectord::Zero(geo.numCoords()));
  for (int i = 0; i < kWheels; ++i) {
    const smoother::SlipWheelData d{kin[i].T_body_wheel, geo.wheels[i].radius, Twistd::Zero(),
                                    Vec4d::Zero(), Eigen::Matrix4d::Identity()};
    const smoother::SlipResidual f(i, kWheels, &d, 3);
    ASSERT_EQ(f.parameter_block_sizes().back(), 3);
    const double v[3] = {0, 0, 0}, w[3] = {0, 0, 0}, c[3] = {0, 0, 0.1};
    double xi[kWheels] = {};
    const double* params[4] = {v, w, xi, c};
    double r[4], Jc[12];
    double* jac[4] = {nullptr, nullptr, nullptr, Jc};
    ASSERT_TRUE(f.Evaluate(params, r, jac));
    const Vec3d p = kin[i].T_body_wheel.p;
    EXPECT_NEAR(r[0], 0.1 * p.y(), 1e-15) << "wheel " << i;
    EXPECT_NEAR(r[1], -0.1 * p.x(), 1e-15);
    EXPECT_NEAR(r[2], 0.0, 1e-15);
    EXPECT_NEAR(r[3], -0.1, 1e-15);
    const Eigen::Map<const Eigen::Matrix<double, 4, 3, Eigen::RowMajor>> J(Jc);
    EXPECT_LE((J.col(2) - Vec4d(p.y(), -p.x(), 0.0, -1.0)).cwiseAbs().maxCoeff(), 1e-15) << J;
  }
}

// The smoother's slip residual with c = (c_x, c_y, c_ω), with the command's nominal and with a
// nominal that follows the state (then c_ω moves the nominal too), and with the ICR block: the
// analytic Jacobians of every block against the Jet Jacobian of the templated model and against
// central differences, at random joint samples and states.
TEST(SmootherCommonSlip, YawSlipResidualJacobiansMatchNumeric) {
  std::mt19937 rng(73);
  constexpr int kZ = 16;  // v, ω, ξ (6), c (3), δ
  for (int trial = 0; trial < 24; ++trial) {
    const int wheel = trial % kWheels;
    const bool follows = trial % 2 == 0;
    const rover::JointSample js = randomJointSample(rng);
    Eigen::Matrix4d L = Eigen::Matrix4d::Identity() * 200.0;
    L(0, 1) = 30.0, L(2, 3) = -10.0;
    smoother::SlipWheelData d{js.T_body_wheel[static_cast<size_t>(wheel)],
                              testing::rocky7().wheels[static_cast<size_t>(wheel)].radius,
                              js.joint_twist[static_cast<size_t>(wheel)],
                              randomVector<4>(rng, 0.01),
                              L,
                              Eigen::Matrix<double, 4, 2>::Zero(),
                              Vec2d::Zero(),
                              wheel % 2 == 0 ? 1.0 : -1.0,
                              follows,
                              0.3};
    if (follows) {
      d.nominal_jacobian = randomVector<8>(rng, 0.3).reshaped(4, 2);
      d.nominal_at = randomVector<2>(rng, 0.2);
    }
    const smoother::SlipResidual f(wheel, kWheels, &d, 3, true);
    Eigen::Matrix<double, kZ, 1> z;
    z << randomVector<3>(rng, 0.3), randomVector<3>(rng, 0.5), randomVector<kWheels>(rng, 0.4),
        randomVector<2>(rng, 0.03), randomVector<1>(rng, 0.01), randomVector<1>(rng, 0.05);
    const auto eval = [&](const Eigen::Matrix<double, kZ, 1>& y, double* jac_out) {
      const double* params[5] = {y.data(), y.data() + 3, y.data() + 6, y.data() + 12,
                                 y.data() + 15};
      Vec4d r;
      double J0[12], J1[12], J2[4 * kWheels], J3[12], J4[4];
      double* jac[5] = {J0, J1, J2, J3, J4};
      EXPECT_TRUE(f.Evaluate(params, r.data(), jac_out ? jac : nullptr));
      if (jac_out) {
        using Rm = Eigen::Matrix<double, 4, Eigen::Dynamic, Eigen::RowMajor>;
        Eigen::Map<Eigen::Matrix<double, 4, kZ, Eigen::RowMajor>> out(jac_out);
        out.leftCols<3>() = Eigen::Map<Rm>(J0, 4, 3);
        out.middleCols<3>(3) = Eigen::Map<Rm>(J1, 4, 3);
        out.middleCols<kWheels>(6) = Eigen::Map<Rm>(J2, 4, kWheels);
        out.middleCols<3>(12) = Eigen::Map<Rm>(J3, 4, 3);
        out.col(15) = Eigen::Map<Vec4d>(J4);
      }
      return r;
    };
    double Ja[4 * kZ];
    const Vec4d r = eval(z, Ja);
    const auto model = [&](const auto& y) {
      using T = typename std::decay_t<decltype(y)>::Scalar;
      return f.residual<T>(Vec3<T>(y.template head<3>()), Vec3<T>(y.template segment<3>(3)),
                           Eigen::Matrix<T, kWheels, 1>(y.template segment<kWheels>(6)),
                           Vec3<T>(y.template segment<3>(12)), y[15]);
    };
    EXPECT_LE((r - model(z)).cwiseAbs().maxCoeff(), 1e-12);
    const Eigen::Matrix<double, 4, kZ> Jjet = testing::autodiffJacobian<4, kZ>(model, z);
    const Eigen::Matrix<double, 4, kZ> Jn =
        testing::numericJacobian<4, kZ>([&](const auto& y) { return eval(y, nullptr); }, z);
    const Eigen::Map<const Eigen::Matrix<double, 4, kZ, Eigen::RowMajor>> J(Ja);
    EXPECT_LE((J - Jjet).cwiseAbs().maxCoeff(), 1e-12 * std::max(1.0, Jjet.cwiseAbs().maxCoeff()))
        << "wheel " << wheel << " follows " << follows << "\nanalytic:\n"
        << J << "\nJet:\n"
        << Jjet;
    EXPECT_LE((J - Jn).cwiseAbs().maxCoeff(), 1e-6 * std::max(1.0, Jn.cwiseAbs().maxCoeff()))
        << "wheel " << wheel << " follows " << follows;
    // c_ω moves the residual as ω_z does.
    EXPECT_LE((J.col(14) - J.col(5)).cwiseAbs().maxCoeff(), 1e-12);
  }
}

}  // namespace
}  // namespace traverse::est
