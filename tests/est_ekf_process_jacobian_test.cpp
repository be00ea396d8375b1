// The EKF's own linear algebra against numerical differentiation and dense textbook forms
// (issue 13 item 4): the process Jacobian F of the continuous error dynamics, the sparse Φ P Φᵀ,
// the expanded Joseph update, the reset Jacobian G and its use in absorb. (The slip H is in
// est_ekf_jacobian_test.cpp; the sun and gravity H are the Jet Jacobians of the sensor models
// at q ⊗ Exp(δθ), checked against central differences in sensors_test.cpp.)
#include <gtest/gtest.h>

#include <random>
#include <sstream>

#include "support/ekf_state.h"
#include "support/jacobian_check.h"
#include "support/rocky7.h"
#include "traverse/estimators/ekf.h"
#include "traverse/io/rover_config.h"
#include "traverse/rover/nominal_slip.h"
#include "traverse/rover/slip_constraint.h"
#include "traverse/sensors/accelerometer.h"

namespace traverse::est {
namespace {

using I = EkfIndex;
using testing::randomUnitQuaternion;
using testing::randomVector;
using Vec6d = Eigen::Matrix<double, r7::kNumWheels, 1>;
constexpr int kN = ekfStates(r7::kNumWheels);  // Rocky-7's error state (21)

io::RoverConfig rocky7Config() {
  io::RoverConfig c =
      io::loadRoverConfig(testing::sourceDir() + "/datasets/rovers/rocky7/rover.yaml");
  c.accel.lever_arm_m = Vec3d(0.12, -0.07, 0.3);  // every lever-arm term nonzero
  // Distinct time constants, so a block taking the wrong one shows.
  c.process.rate_time_constant_s = 0.7;
  c.process.velocity_time_constant_s = 1.3;
  c.process.contact_angle_time_constant_s = 2.9;
  return c;
}

/// One of the 32 process-model variants.
struct Variant {
  bool accel;               ///< O-4 (accelerometer drives the velocity) or K-1 (perturbation)
  bool k12;                 ///< K-2 + K-12 (gyro a measurement) or the hybrid O-1 (gyro-driven)
  bool three_axis;          ///< 3-axis or heading-only gyro
  bool has_cmd;             ///< the log has cmd.csv
  bool accel_bias = false;  ///< the accelerometer's bias b_a as three more states
};

std::string describe(const Variant& v) {
  return std::string(v.accel ? "accel-driven" : "perturbation") + (v.k12 ? " K-12" : " O-1") +
         (v.three_axis ? " 3-axis" : " heading") + (v.has_cmd ? " cmd" : " no-cmd") +
         (v.accel_bias ? " b_a" : "");
}

std::vector<Variant> allVariants() {
  std::vector<Variant> out;
  for (const bool accel : {false, true})
    for (const bool k12 : {false, true})
      for (const bool three : {false, true})
        for (const bool cmd : {false, true})
          for (const bool ba : {false, true}) out.push_back({accel, k12, three, cmd, ba});
  return out;
}

EkfOptions optionsFor(const Variant& v) {
  EkfOptions o;
  o.attitude =
      v.k12 ? EkfOptions::AttitudeModel::kGyroMeasurement : EkfOptions::AttitudeModel::kGyroDriven;
  o.velocity =
      v.accel ? EkfOptions::VelocityModel::kAccelDriven : EkfOptions::VelocityModel::kPerturbation;
  return o;
}

EkfState randomState(std::mt19937& rng, bool accel_bias = false) {
  return testing::randomEkfState(rng, r7::kNumWheels, false, accel_bias);
}

EkfInputs randomInputs(std::mt19937& rng, const Variant& v, const EkfState& x, double g) {
  EkfInputs in;
  in.gyro = randomVector<3>(rng, 0.5);
  if (!v.three_axis) in.gyro.head<2>().setZero();  // as runEkf reads a heading-only gyro
  if (v.has_cmd) in.v_cmd = randomVector<3>(rng, 0.2), in.w_cmd = randomVector<3>(rng, 0.4);
  in.accel = sensors::accelAtRest<double>(x.q_site_body, g) + randomVector<3>(rng, 0.5);
  in.has_accel = v.accel;
  return in;
}

/// The continuous nominal dynamics at state x, restated from the model (K-1, K-2/O-1, K-8, K-9,
/// O-4) through the filter's own rate and velocity models and the shared accelerometer model.
struct Dynamics {
  Vec3d w;  ///< body rate: q̇ = ½ q ⊗ ω
  Vec3d w_p_dot, p_dot, v_p_dot;
  Vec6d xi_dot;
  Vec3d b_dot;
};

Dynamics dynamics(const Ekf& ekf, const Variant& v, const io::RoverConfig& c, const EkfState& x,
                  const EkfInputs& in) {
  const auto& pc = c.process;
  // Damping (K §4.2): without cmd.csv the velocity, and the yaw rate under K-12, are random walks.
  Vec3d a_w = Vec3d::Constant(-1.0 / pc.rate_time_constant_s);
  if (v.k12 && !v.has_cmd) a_w.z() = 0.0;
  const double a_v = v.has_cmd && !v.accel ? -1.0 / pc.velocity_time_constant_s : 0.0;
  const double a_xi = -1.0 / pc.contact_angle_time_constant_s;
  Dynamics d;
  d.w = ekf.omega<double>(x.w_p, x.bias, in);
  const Vec3d vel = v.accel ? x.v_p : ekf.velocity<double>(x.v_p, in);
  d.p_dot = x.q_site_body * vel;
  d.w_p_dot = a_w.cwiseProduct(x.w_p);
  // The accelerometer reads K-10 plus its bias: the velocity sees a_m − b_a.
  d.v_p_dot = v.accel ? sensors::velocityRateFromAccel<double>(
                            Vec3d(in.accel - x.accel_bias), x.q_site_body, x.v_p, d.w,
                            Vec3d::Zero(), c.accel.lever_arm_m, c.gravity_mps2)
                      : Vec3d(a_v * x.v_p);
  d.xi_dot = a_xi * x.xi;
  d.b_dot.setZero();
  return d;
}

EkfState boxplus(const EkfState& x, const EkfVector& dx) {
  // The layouts here: no c, b_a or not.
  return testing::ekfBoxplus(x, dx, 0, dx.size() > ekfStates(static_cast<int>(x.xi.size())));
}

/// d/dt of the error state δx(t) = x(t) ⊟ x̂(t) at t = 0 when the true state starts at
/// x = x̂ ⊞ δx0 and both follow the nominal dynamics. Vector blocks: f(x) − f(x̂). Attitude:
/// δθ(t) = Log(q̂(t)⁻¹ q(t)) with q(t) = q ⊗ Exp(t ω) (q̇ = ½ q ⊗ ω; ω's own change is O(t²) and
/// cancels in the central difference), i.e. δθ(t) = Log(Exp(−t ω̂) ⊗ Exp(δθ0) ⊗ Exp(t ω)),
/// differentiated by a central difference in t. (Written without q̂, which cancels, so every
/// quaternion is near the identity and the differences keep their digits.)
EkfVector errorRate(const Ekf& ekf, const Variant& v, const io::RoverConfig& c,
                    const EkfState& x_hat, const EkfVector& dx0, const EkfInputs& in) {
  const EkfState x = boxplus(x_hat, dx0);
  const Dynamics f = dynamics(ekf, v, c, x, in), f_hat = dynamics(ekf, v, c, x_hat, in);
  const double h = 1e-5;
  const Quatd e0 = so3::expQuat(Vec3d(dx0.segment<3>(I::kTheta)));
  const auto dtheta = [&](double t) {
    return so3::log(Quatd(so3::expQuat(Vec3d(-t * f_hat.w)) * e0 * so3::expQuat(Vec3d(t * f.w))));
  };
  EkfVector r = EkfVector::Zero(ekf.numStates());  // b_a (a constant here): zero rate
  r.segment<3>(I::kTheta) = (dtheta(h) - dtheta(-h)) / (2.0 * h);
  r.segment<3>(I::kRate) = f.w_p_dot - f_hat.w_p_dot;
  r.segment<3>(I::kPos) = f.p_dot - f_hat.p_dot;
  r.segment<3>(I::kVel) = f.v_p_dot - f_hat.v_p_dot;
  r.segment(I::kXi, r7::kNumWheels) = f.xi_dot - f_hat.xi_dot;
  r.segment<3>(I::kBias) = f.b_dot - f_hat.b_dot;
  return r;
}

/// F by central differences of the error rate in each error-state direction.
EkfMatrix numericProcessJacobian(const Ekf& ekf, const Variant& v, const io::RoverConfig& c,
                                 const EkfState& x_hat, const EkfInputs& in) {
  const double eps = 1e-5;
  const int n = ekf.numStates();
  EkfMatrix F(n, n);
  for (int j = 0; j < n; ++j) {
    const EkfVector e = EkfVector::Unit(n, j) * eps;
    F.col(j) =
        (errorRate(ekf, v, c, x_hat, e, in) - errorRate(ekf, v, c, x_hat, -e, in)) / (2.0 * eps);
  }
  return F;
}

struct Fixture {
  io::RoverConfig config = rocky7Config();
  /// The same with an accelerometer bias declared (the Ekf keeps a reference: it lives here).
  io::RoverConfig config_with_bias = [] {
    io::RoverConfig c = rocky7Config();
    c.accel.bias_sigma_mps2 = 0.05, c.accel.bias_random_walk_mps2_per_sqrt_s = 1e-3;
    return c;
  }();
  InitialState init;
};

Ekf makeEkf(const Fixture& fx, const Variant& v) {
  return Ekf(v.accel_bias ? fx.config_with_bias : fx.config, testing::rocky7(), optionsFor(v),
             fx.init, v.three_axis, v.has_cmd);
}

/// max |a − b| relative to max |b|.
double relativeError(const auto& a, const auto& b) {
  return (a - b).cwiseAbs().maxCoeff() / b.cwiseAbs().maxCoeff();
}

// F at 24 random states for each of the 32 variants (velocity K-1 / O-4 × attitude O-1 / K-12
// × heading / 3-axis gyro × with / without cmd × with / without the accelerometer bias b_a)
// against central differences of the error dynamics. Also the nominal v̇_p that
// processJacobian returns for O-4.
TEST(EstEkfProcessJacobian, MatchesNumericErrorDynamicsForEveryVariant) {
  const Fixture fx;
  std::mt19937 rng(41);
  double worst = 0.0;
  for (const Variant& v : allVariants()) {
    Ekf ekf = makeEkf(fx, v);
    for (int trial = 0; trial < 24; ++trial) {
      const EkfState x = randomState(rng, v.accel_bias);
      const EkfInputs in = randomInputs(rng, v, x, fx.config.gravity_mps2);
      ekf.setState(x);
      ASSERT_EQ(ekf.numStates(), ekfStates(r7::kNumWheels, 0, v.accel_bias ? 3 : 0));
      Vec3d v_dot;
      const EkfMatrix F = ekf.processJacobian(in, &v_dot);
      const EkfMatrix Fn = numericProcessJacobian(ekf, v, fx.config, x, in);
      // F's entries are O(1) (R, I, 1/τ, ω, v), some exactly zero: error relative to max(1, |F|).
      // (Worst ~6e-11 here: steps of 1e-5 in δx and in t, every quaternion near the identity.)
      const double err = (F - Fn).cwiseAbs().maxCoeff() / std::max(1.0, Fn.cwiseAbs().maxCoeff());
      worst = std::max(worst, err);
      EXPECT_LE(err, 1e-7) << describe(v) << " trial " << trial << "\nF:\n"
                           << F << "\nnumeric:\n"
                           << Fn;
      const Vec3d v_dot_expected =
          v.accel ? dynamics(ekf, v, fx.config, x, in).v_p_dot : Vec3d::Zero();
      EXPECT_LE((v_dot - v_dot_expected).cwiseAbs().maxCoeff(), 1e-14) << describe(v);
    }
  }
  std::ostringstream os;
  os << worst;
  RecordProperty("worst_relative_error", os.str());
}

// Hand-checked: hybrid O-1 with a heading gyro, cmd, K-1. ω = S(ω_m − b) + (I − S) ω_c + ω_p.
TEST(EstEkfProcessJacobian, HandCheckedBlocks) {
  const Fixture fx;
  const Variant v{false, false, false, true};
  Ekf ekf = makeEkf(fx, v);
  EkfState x;
  x.q_site_body = so3::fromRollPitchYaw(0.0, 0.0, M_PI / 2);  // body x along site y
  x.w_p = Vec3d(0.01, 0.02, 0.03);
  x.bias = Vec3d(0.0, 0.0, 0.01);
  x.v_p = Vec3d(0.005, 0.0, 0.0);
  ekf.setState(x);
  EkfInputs in;
  in.gyro = Vec3d(0.0, 0.0, 0.2);
  in.v_cmd = Vec3d(0.1, 0.0, 0.0);
  in.w_cmd = Vec3d(0.1, 0.1, 0.5);
  const EkfMatrix F = ekf.processJacobian(in);
  const auto block = [&F](int r, int c) { return Mat3d(F.block(r, c, 3, 3)); };
  const Vec3d w(0.11, 0.12, 0.22);  // (0.1 + 0.01, 0.1 + 0.02, 0.2 − 0.01 + 0.03)
  Mat3d minus_skew_w;
  minus_skew_w << 0, 0.22, -0.12, -0.22, 0, 0.11, 0.12, -0.11, 0;
  EXPECT_LE((block(I::kTheta, I::kTheta) - minus_skew_w).cwiseAbs().maxCoeff(), 1e-15);
  EXPECT_LE((Vec3d(ekf.omega<double>(x.w_p, x.bias, in)) - w).cwiseAbs().maxCoeff(), 1e-15);
  EXPECT_TRUE(block(I::kTheta, I::kRate).isIdentity(0.0));
  Mat3d minus_s = Mat3d::Zero();
  minus_s(2, 2) = -1.0;  // the heading gyro: ∂ω/∂b = −S, S = diag(0, 0, 1)
  EXPECT_EQ(block(I::kTheta, I::kBias), minus_s);
  EXPECT_TRUE(block(I::kRate, I::kRate).isApprox(Mat3d::Identity() * (-1.0 / 0.7)));
  EXPECT_TRUE(block(I::kVel, I::kVel).isApprox(Mat3d::Identity() * (-1.0 / 1.3)));
  const Eigen::MatrixXd xi_block = F.block(I::kXi, I::kXi, 6, 6);
  EXPECT_TRUE(xi_block.isApprox(Eigen::MatrixXd::Identity(6, 6) * (-1.0 / 2.9)));
  // ẋ = R v with v = (0.105, 0, 0) along site y: ∂ẋ/∂δθ = −R [v]×, ∂ẋ/∂δv_p = R.
  const Mat3d R = x.q_site_body.toRotationMatrix();
  Mat3d Rz;
  Rz << 0, -1, 0, 1, 0, 0, 0, 0, 1;
  EXPECT_LE((R - Rz).cwiseAbs().maxCoeff(), 1e-15);
  // −R [v]× = −Rz [(0.105, 0, 0)]×: a yaw error turns the motion (site y) towards −x, a pitch
  // error tips it down.
  Mat3d dp_dtheta;
  dp_dtheta << 0, 0, -0.105, 0, 0, 0, 0, -0.105, 0;
  EXPECT_LE((block(I::kPos, I::kTheta) - dp_dtheta).cwiseAbs().maxCoeff(), 1e-15);
  EXPECT_EQ(block(I::kPos, I::kVel), R);
  // Nothing else: F has exactly the blocks above.
  EkfMatrix rest = F;
  for (const auto& [r, c, n, m] :
       std::initializer_list<std::array<int, 4>>{{I::kTheta, I::kTheta, 3, 3},
                                                 {I::kTheta, I::kRate, 3, 3},
                                                 {I::kTheta, I::kBias, 3, 3},
                                                 {I::kRate, I::kRate, 3, 3},
                                                 {I::kPos, I::kTheta, 3, 3},
                                                 {I::kPos, I::kVel, 3, 3},
                                                 {I::kVel, I::kVel, 3, 3},
                                                 {I::kXi, I::kXi, 6, 6}})
    rest.block(r, c, n, m).setZero();
  EXPECT_TRUE(rest.isZero(0.0));
}

EkfMatrix randomCovariance(std::mt19937& rng, int n = kN) {
  // A P of mixed scales (attitude ~1e-2 rad, position ~1 m, …) with correlations.
  // (Entries uniform in [−1, 1] column by column, then the scales: randomVector's draws.)
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  EkfMatrix L(n, n);
  for (int j = 0; j < n; ++j)
    for (int i = 0; i < n; ++i) L(i, j) = u(rng);
  EkfVector scale(n);
  for (int i = 0; i < n; ++i) scale[i] = std::exp(2.0 * u(rng));
  return scale.asDiagonal() * (L * L.transpose() + EkfMatrix::Identity(n, n)) * scale.asDiagonal();
}

// Φ P Φᵀ over F's nonzeros equals the dense (I + F dt + ½(F dt)²) P (…)ᵀ, and propagate adds
// only the (diagonal) process noise to it, taking F at the state before the step.
TEST(EstEkfProcessJacobian, SparseCovariancePropagationMatchesDense) {
  const Fixture fx;
  std::mt19937 rng(42);
  for (const Variant& v : allVariants()) {
    Ekf ekf = makeEkf(fx, v);
    for (int trial = 0; trial < 4; ++trial) {
      const EkfState x = randomState(rng, v.accel_bias);
      const EkfInputs in = randomInputs(rng, v, x, fx.config.gravity_mps2);
      ekf.setState(x);
      const EkfMatrix F = ekf.processJacobian(in);
      const int n = ekf.numStates();
      const EkfMatrix P = randomCovariance(rng, n);
      for (const double dt : {0.001, 0.02, 0.25}) {
        const EkfMatrix Fdt = F * dt;
        const EkfMatrix Phi = EkfMatrix::Identity(n, n) + Fdt + 0.5 * Fdt * Fdt;
        const EkfMatrix dense = Phi * P * Phi.transpose();
        const EkfMatrix sparse = detail::propagateCovariance(F, dt, P);
        EXPECT_LE(relativeError(sparse, dense), 1e-12) << describe(v) << " dt " << dt;

        ekf.setState(x);
        ekf.setCovariance(P);
        ekf.propagate(dt, in);
        const EkfMatrix Q = ekf.covariance() - dense;
        EkfMatrix off = Q;
        off.diagonal().setZero();
        // Rocky-7 declares the contact angles' common mode: that block is full (checked on its
        // own in CommonContactModeHasItsOwnDensity).
        off.block(I::kXi, I::kXi, r7::kNumWheels, r7::kNumWheels).setZero();
        EXPECT_LE(off.cwiseAbs().maxCoeff(), 1e-12 * dense.cwiseAbs().maxCoeff()) << describe(v);
        EXPECT_GE(Q.diagonal().minCoeff(), -1e-12 * dense.cwiseAbs().maxCoeff()) << describe(v);
      }
    }
  }
}

// rover.yaml's common contact-angle density n_c: the process noise's contact-angle block is
// n_ξ² I Δt + (n_c² − n_ξ²)/N Δt 1 1ᵀ (eigenvalues n_ξ² Δt for the differences between wheels,
// n_c² Δt for their mean), and nothing else changes.
TEST(EstEkfProcessJacobian, CommonContactModeHasItsOwnDensity) {
  const Fixture fx;
  std::mt19937 rng(43);
  io::RoverConfig independent = fx.config;
  independent.process.common_contact_angle_noise_rad_per_sqrt_s.reset();
  io::RoverConfig config = independent;
  const double n = config.process.contact_angle_noise_rad_per_sqrt_s, n_c = 0.2 * n;
  config.process.common_contact_angle_noise_rad_per_sqrt_s = n_c;
  const Variant v{false, false, false, true};
  Ekf plain(independent, testing::rocky7(), optionsFor(v), fx.init, v.three_axis, v.has_cmd);
  Ekf common(config, testing::rocky7(), optionsFor(v), fx.init, v.three_axis, v.has_cmd);
  const EkfState x = randomState(rng);
  const EkfInputs in = randomInputs(rng, v, x, fx.config.gravity_mps2);
  const EkfMatrix P = randomCovariance(rng);
  const double dt = 0.02;
  for (Ekf* e : {&plain, &common}) {
    e->setState(x);
    e->setCovariance(P);
    e->propagate(dt, in);
  }
  const EkfMatrix dQ = common.covariance() - plain.covariance();
  const int nw = 6, k = EkfIndex::kXi;
  const Eigen::MatrixXd expected = Eigen::MatrixXd::Constant(nw, nw, (n_c * n_c - n * n) / nw * dt);
  const double roundoff = 1e-13 * plain.covariance().cwiseAbs().maxCoeff();
  EXPECT_LE((dQ.block(k, k, nw, nw) - expected).cwiseAbs().maxCoeff(), roundoff);
  EXPECT_GT(expected.cwiseAbs().minCoeff(), 100 * roundoff);  // the test can see the change
  EkfMatrix rest = dQ;
  rest.block(k, k, nw, nw).setZero();
  EXPECT_LE(rest.cwiseAbs().maxCoeff(), roundoff);
  // The mean of the six angles gains n_c² Δt / 6, a difference between two of them 2 n_ξ² Δt.
  const Eigen::VectorXd mean = Eigen::VectorXd::Constant(nw, 1.0 / nw);
  Eigen::VectorXd diff = Eigen::VectorXd::Zero(nw);
  diff[0] = 1.0, diff[1] = -1.0;
  const Eigen::MatrixXd Qxi = expected + Eigen::MatrixXd::Identity(nw, nw) * n * n * dt;
  EXPECT_NEAR(mean.dot(Qxi * mean), n_c * n_c * dt / nw, 1e-15);
  EXPECT_NEAR(diff.dot(Qxi * diff), 2.0 * n * n * dt, 1e-15);
}

/// H with M rows on a random subset of the columns (the rest exactly zero).
template <int M>
EkfRows<M> randomSparseH(std::mt19937& rng) {
  EkfRows<M> H = EkfRows<M>::Zero(M, kN);
  std::bernoulli_distribution used(0.4);
  for (int c = 0; c < kN; ++c)
    if (used(rng)) H.col(c) = randomVector<M>(rng, 2.0);
  H(0, 0) = 1.0;  // at least one column
  return H;
}

template <int M>
Eigen::Matrix<double, M, M> randomSpd(std::mt19937& rng, double scale) {
  Eigen::Matrix<double, M, M> A;
  for (int j = 0; j < M; ++j) A.col(j) = randomVector<M>(rng);
  return scale * (A * A.transpose() + Eigen::Matrix<double, M, M>::Identity());
}

/// The textbook Joseph form.
template <int M>
EkfMatrix denseJoseph(const EkfMatrix& P, const EkfRows<M>& H, const Eigen::Matrix<double, M, M>& R,
                      const EkfCols<M>& K) {
  const EkfMatrix IKH = EkfMatrix::Identity(kN, kN) - K * H;
  return IKH * P * IKH.transpose() + K * R * K.transpose();
}

template <int M>
void expectJosephMatchesDense(std::mt19937& rng) {
  for (int trial = 0; trial < 20; ++trial) {
    const EkfMatrix P = randomCovariance(rng);
    const auto H = randomSparseH<M>(rng);
    const auto R = randomSpd<M>(rng, 0.1);
    EkfCols<M> PHt;
    Eigen::Matrix<double, M, M> S;
    detail::innovation<M>(P, H, R, &PHt, &S);
    const EkfCols<M> PHt_dense = P * H.transpose();
    const Eigen::Matrix<double, M, M> S_dense = H * P * H.transpose() + R;
    EXPECT_LE(relativeError(PHt, PHt_dense), 1e-13) << "M " << M;
    EXPECT_LE(relativeError(S, S_dense), 1e-13) << "M " << M;
    const EkfCols<M> K_opt = PHt_dense * S_dense.inverse();
    // Joseph holds for any gain: the optimal one, a scaled one and an arbitrary one.
    EkfCols<M> K_arb(kN, M);
    for (int j = 0; j < M; ++j) K_arb.col(j) = randomVector<kN>(rng);
    for (const EkfCols<M>& K : {K_opt, EkfCols<M>(0.6 * K_opt), K_arb}) {
      EkfMatrix P_new = P;
      detail::josephUpdate<M>(&P_new, K, PHt, S);
      const EkfMatrix dense = denseJoseph<M>(P, H, R, K);
      EXPECT_LE(relativeError(P_new, dense), 1e-12) << "M " << M << " trial " << trial;
      EXPECT_EQ(P_new, P_new.transpose());
    }
    // With the optimal gain it is the short form (I − K H) P.
    EkfMatrix P_opt = P;
    detail::josephUpdate<M>(&P_opt, K_opt, PHt, S);
    const EkfMatrix short_form = (EkfMatrix::Identity(kN, kN) - K_opt * H) * P;
    EXPECT_LE(relativeError(P_opt, short_form), 1e-10) << "M " << M;
  }
}

TEST(EstEkfJoseph, ExpandedFormMatchesTextbookForEveryRowCount) {
  std::mt19937 rng(43);
  expectJosephMatchesDense<1>(rng);
  expectJosephMatchesDense<2>(rng);
  expectJosephMatchesDense<3>(rng);
  expectJosephMatchesDense<4>(rng);
}

// A whole EKF update with a real slip H (the four rows of a wheel, composed onto v_p, ω_p, the
// bias and ξ_i as updateSlip does) against dense algebra: K = P Hᵀ (H P Hᵀ + R)⁻¹, the Joseph
// form, the correction K r absorbed into the state and G applied to the attitude rows/columns.
TEST(EstEkfJoseph, SlipUpdateMatchesDenseReference) {
  const Fixture fx;
  std::mt19937 rng(44);
  const rover::RoverGeometry& geo = testing::rocky7();
  for (const Variant& v : {Variant{false, false, false, true}, Variant{true, false, true, false},
                           Variant{false, true, true, true}}) {
    Ekf ekf = makeEkf(fx, v);
    for (int trial = 0; trial < 10; ++trial) {
      const rover::JointSample js = testing::randomJointSample(rng);
      const EkfState x = randomState(rng);
      const EkfInputs in = randomInputs(rng, v, x, fx.config.gravity_mps2);
      const int wheel = trial % r7::kNumWheels;
      Eigen::Matrix<double, 7, 1> s;
      s << (v.accel ? x.v_p : ekf.velocity<double>(x.v_p, in)),
          ekf.omega<double>(x.w_p, x.bias, in), x.xi[wheel];
      const Twistd cmd = rover::nominalBodyTwist(geo, in.v_cmd.x(), in.w_cmd.z());
      Eigen::Matrix<double, 4, 7> J;
      const Vec4d r = slipUpdateResidual(geo, js, wheel, v.has_cmd ? &cmd : nullptr, s, &J);
      EkfRows<4> H = EkfRows<4>::Zero(4, kN);
      H.block<4, 3>(0, I::kVel) = J.leftCols<3>();
      H.block<4, 3>(0, I::kRate) = J.middleCols<3>(3);
      if (!v.k12) {
        const Mat3d S = v.three_axis ? Mat3d::Identity() : Mat3d(Vec3d(0, 0, 1).asDiagonal());
        H.block<4, 3>(0, I::kBias) = -J.middleCols<3>(3) * S;
      }
      H.col(I::kXi + wheel) = J.col(6);
      const Eigen::Matrix4d R = randomSpd<4>(rng, 1e-4);
      const EkfMatrix P = randomCovariance(rng) * 1e-3;

      ekf.setState(x);
      ekf.setCovariance(P);
      ASSERT_TRUE(ekf.update<4>(r, H, R, 0.0));

      const EkfCols<4> K = P * H.transpose() * (H * P * H.transpose() + R).inverse();
      const EkfVector dx = K * r;
      EkfMatrix G = EkfMatrix::Identity(kN, kN);
      G.block<3, 3>(I::kTheta, I::kTheta) =
          Mat3d::Identity() - 0.5 * so3::skew(Vec3d(dx.segment<3>(I::kTheta)));
      const EkfMatrix P_ref = G * denseJoseph<4>(P, H, R, K) * G.transpose();
      EXPECT_LE(relativeError(ekf.covariance(), P_ref), 1e-12) << describe(v);
      const EkfState x_new = ekf.state(), x_ref = boxplus(x, dx);
      const double tol = 1e-12 * std::max(1.0, dx.cwiseAbs().maxCoeff());
      EXPECT_LE(so3::boxminus(x_new.q_site_body, x_ref.q_site_body).norm(), tol);
      EXPECT_LE((x_new.w_p - x_ref.w_p).cwiseAbs().maxCoeff(), tol);
      EXPECT_LE((x_new.p_site - x_ref.p_site).cwiseAbs().maxCoeff(), tol);
      EXPECT_LE((x_new.v_p - x_ref.v_p).cwiseAbs().maxCoeff(), tol);
      EXPECT_LE((x_new.xi - x_ref.xi).cwiseAbs().maxCoeff(), tol);
      EXPECT_LE((x_new.bias - x_ref.bias).cwiseAbs().maxCoeff(), tol);
    }
  }
}

// The reset Jacobian: with the true attitude q = q̂ ⊗ Exp(δθ), absorbing dθ (q̂⁺ = q̂ ⊗ Exp(dθ))
// leaves the error δθ⁺ = Log(q̂⁺⁻¹ q) = Log(Exp(−dθ) ⊗ Exp(δθ)). Its Jacobian, numerically at
// δθ = 0 and at the absorbed estimate δθ = dθ, is I − ½[dθ]× up to O(|dθ|²).
TEST(EstEkfReset, JacobianMatchesNumericToSecondOrder) {
  std::mt19937 rng(45);
  for (const double size : {1e-3, 1e-2}) {
    for (int trial = 0; trial < 20; ++trial) {
      const Quatd q_hat = randomUnitQuaternion(rng);
      const Vec3d dtheta = randomVector<3>(rng).normalized() * size;
      const Quatd q_hat_plus = so3::boxplus(q_hat, dtheta);
      const auto reset = [&](const Vec3d& err) {
        return so3::boxminus(so3::boxplus(q_hat, err), q_hat_plus);  // Log(q̂⁺⁻¹ q)
      };
      const Mat3d G = detail::resetJacobian(dtheta);
      for (const Vec3d& at : {Vec3d::Zero().eval(), dtheta}) {
        const Mat3d Gn = testing::numericJacobian<3, 3>(reset, at, 1e-7);
        EXPECT_LE((G - Gn).cwiseAbs().maxCoeff(), size * size) << "|dθ| " << size;
        // and the first-order term is really there: I alone is off by ~|dθ|/2
        EXPECT_GE((Mat3d::Identity() - Gn).cwiseAbs().maxCoeff(), 0.2 * size);
      }
    }
  }
}

// absorb: the state moves by dx (attitude on the body side) and P becomes G P Gᵀ with G the
// reset Jacobian on the attitude block and the identity elsewhere.
TEST(EstEkfReset, AbsorbAppliesResetToAttitudeRowsAndColumns) {
  const Fixture fx;
  std::mt19937 rng(46);
  Ekf ekf = makeEkf(fx, Variant{true, false, true, true});
  for (int trial = 0; trial < 20; ++trial) {
    const EkfState x = randomState(rng);
    const EkfMatrix P = randomCovariance(rng);
    const EkfVector dx = randomVector<kN>(rng, 0.05);
    ekf.setState(x);
    ekf.setCovariance(P);
    ekf.absorb(dx);
    EkfMatrix G = EkfMatrix::Identity(kN, kN);
    G.block<3, 3>(I::kTheta, I::kTheta) = detail::resetJacobian(dx.segment<3>(I::kTheta));
    EXPECT_LE(relativeError(ekf.covariance(), G * P * G.transpose()), 1e-14);
    // Only the attitude rows and columns change.
    const Eigen::MatrixXd unchanged = ekf.covariance().bottomRightCorner(18, 18);
    EXPECT_EQ(unchanged, P.bottomRightCorner(18, 18));
    const EkfState y = ekf.state(), y_ref = boxplus(x, dx);
    EXPECT_LE(so3::boxminus(y.q_site_body, y_ref.q_site_body).norm(), 1e-14);
    EXPECT_NEAR(y.q_site_body.norm(), 1.0, 1e-14);
    EXPECT_EQ(y.p_site, y_ref.p_site);
    EXPECT_EQ(y.xi, y_ref.xi);
    EXPECT_EQ(y.bias, y_ref.bias);
  }
}

}  // namespace
}  // namespace traverse::est
