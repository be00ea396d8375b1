// The accelerometer's bias b_a as estimated states (issue 14 "Real IMUs"; rover.yaml
// accelerometer.bias_sigma_mps2, bias_random_walk_mps2_per_sqrt_s). Checked here: the states
// exist only when declared and the keys round-trip; the EKF's gravity update with b_a against
// a dense reference whose H is central differences of the whole residual over the error state
// (random unit quaternions, random b_a); the initial attitude–bias correlation when roll and
// pitch were read from gravity; the process noise; the covariance kernel of a four-wheel rover
// with b_a against the dense form; and on simulated traverses with an injected bias, that the
// EKF and the smoother recover it within 3σ and keep the position of the unbiased run.
// (F with b_a: est_ekf_process_jacobian_test.cpp; the smoother's residuals with b_a:
// smoother_residuals_test.cpp.)
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <random>

#include <unistd.h>

#include "support/ekf_state.h"
#include "support/jacobian_check.h"
#include "support/rocky7.h"
#include "traverse/core/error.h"
#include "traverse/estimators/ekf.h"
#include "traverse/eval/metrics.h"
#include "traverse/io/rover_config.h"
#include "traverse/pipeline/pipeline.h"
#include "traverse/sensors/gravity.h"
#include "traverse/sim/simulator.h"

namespace traverse::est {
namespace {

using I = EkfIndex;
using testing::randomUnitQuaternion;
using testing::randomVector;
constexpr int kWheels = 6;
constexpr int kN = ekfStates(kWheels, 0, kAccelBiasStates);  // 24
constexpr int kA = I::accelBias(kWheels, 0);                 // 21

io::RoverConfig biasConfig() {
  io::RoverConfig c =
      io::loadRoverConfig(testing::sourceDir() + "/datasets/rovers/rocky7/rover.yaml");
  c.accel.bias_sigma_mps2 = 0.05;
  c.accel.bias_random_walk_mps2_per_sqrt_s = 2e-3;
  return c;
}

EkfMatrix randomCovariance(std::mt19937& rng) {
  return testing::randomSmallCovariance(rng, kN);
}

TEST(EstAccelBias, StatesExistOnlyWhenDeclaredAndKeysRoundTrip) {
  const InitialState init;
  io::RoverConfig off = biasConfig();
  off.accel.bias_sigma_mps2 = 0.0;
  const Ekf without(off, testing::rocky7(), {}, init, false, true);
  EXPECT_EQ(without.numStates(), ekfStates(kWheels));
  EXPECT_FALSE(without.hasAccelBias());
  const io::RoverConfig on = biasConfig();
  const Ekf with(on, testing::rocky7(), {}, init, false, true);
  EXPECT_EQ(with.numStates(), kN);
  EXPECT_TRUE(with.hasAccelBias());
  // The prior: σ² I on b_a, nothing correlated (roll and pitch not from gravity here).
  const EkfMatrix& P = with.covariance();
  EXPECT_TRUE(Mat3d(P.block<3, 3>(kA, kA)).isApprox(Mat3d::Identity() * 0.05 * 0.05));
  EXPECT_TRUE(P.block(0, kA, kA, 3).isZero(0.0));

  const std::filesystem::path dir =
      std::filesystem::temp_directory_path() / ("traverse_accel_bias_" + std::to_string(getpid()));
  std::filesystem::create_directories(dir);
  io::saveRoverConfig(dir / "rover.yaml", on);
  const io::RoverConfig back = io::loadRoverConfig(dir / "rover.yaml");
  EXPECT_EQ(back.accel.bias_sigma_mps2, 0.05);
  EXPECT_EQ(back.accel.bias_random_walk_mps2_per_sqrt_s, 2e-3);
  io::saveRoverConfig(dir / "rover.yaml", off);
  std::ifstream in(dir / "rover.yaml");
  const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  EXPECT_EQ(text.find("bias_sigma_mps2"), std::string::npos);  // 0 is not written
  // Out of range: one line naming the file and key.
  std::ofstream(dir / "bad.yaml") << "format: 1\naccelerometer:\n  bias_sigma_mps2: 7\n";
  try {
    io::loadRoverConfig(dir / "bad.yaml");
    ADD_FAILURE() << "a bias σ of 7 m/s² was accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("bias_sigma_mps2"), std::string::npos) << e.what();
  }
  std::filesystem::remove_all(dir);
}

// The hand-checked model: level, g = 9.81, b_a = (0, 0.0981, 0): f = (0, 0.0981, 9.81), roll =
// atan(0.01); b_a = (−0.0981, 0, 0): pitch = atan(0.01); b_a along z: level; b_a = 0: the
// bias-free model at any attitude.
TEST(EstAccelBias, GravityModelWithBiasHandChecked) {
  const Quatd level = Quatd::Identity();
  const double t = std::atan(0.01);
  EXPECT_LT(
      (sensors::gravityRollPitchPredict<double>(level, Vec3d(0, 0.0981, 0), 9.81) - Vec2d(t, 0))
          .norm(),
      1e-15);
  EXPECT_LT(
      (sensors::gravityRollPitchPredict<double>(level, Vec3d(-0.0981, 0, 0), 9.81) - Vec2d(0, t))
          .norm(),
      1e-15);
  EXPECT_LT(sensors::gravityRollPitchPredict<double>(level, Vec3d(0, 0, 0.3), 9.81).norm(), 1e-15);
  std::mt19937 rng(5);
  for (int i = 0; i < 10; ++i) {
    const Quatd q = randomUnitQuaternion(rng);
    EXPECT_LT((sensors::gravityRollPitchPredict<double>(q, Vec3d::Zero(), 9.81) -
               sensors::gravityRollPitchPredict<double>(q))
                  .norm(),
              1e-12);
  }
}

// updateGravity with b_a against the textbook update: r = wrap(m − h(q̂ ⊞ δθ, b̂_a + δb_a)), H =
// −∂r/∂δx by central differences over every error-state direction, K = P Hᵀ S⁻¹, Joseph form,
// then the reset Jacobian. H's b_a columns must be there (the bias tilts the apparent gravity).
TEST(EstAccelBias, GravityUpdateMatchesDenseReferenceWithNumericH) {
  const io::RoverConfig cfg = biasConfig();
  std::mt19937 rng(91);
  double worst = 0.0;
  Ekf ekf(cfg, testing::rocky7(), {}, InitialState{}, true, true);
  for (int trial = 0; trial < 20;) {
    const EkfState x = testing::randomEkfState(rng, kWheels, 0, true);
    const Vec2d h0 =
        sensors::gravityRollPitchPredict<double>(x.q_site_body, x.accel_bias, cfg.gravity_mps2);
    if (std::abs(h0.y()) > 1.3) continue;  // roll is ill-defined near pitch ±90°
    ++trial;
    sensors::RollPitchMeasurement m;
    m.roll_pitch = h0 + randomVector<2>(rng, 0.02);
    m.covariance = Eigen::Matrix2d::Identity() * 1e-5;
    const EkfMatrix P = randomCovariance(rng);
    ekf.setState(x);
    ekf.setCovariance(P);
    ekf.updateGravity(m);

    const auto r_of = [&](const EkfVector& dx) {
      const EkfState y = testing::ekfBoxplus(x, dx, 0, true);
      const Vec2d h =
          sensors::gravityRollPitchPredict<double>(y.q_site_body, y.accel_bias, cfg.gravity_mps2);
      return Vec2d(so3::wrapAngle(m.roll_pitch.x() - h.x()),
                   so3::wrapAngle(m.roll_pitch.y() - h.y()));
    };
    Eigen::Matrix<double, 2, kN> H;
    const double eps = 1e-6;
    for (int j = 0; j < kN; ++j) {
      const EkfVector e = EkfVector::Unit(kN, j) * eps;
      H.col(j) = -(r_of(e) - r_of(-e)) / (2 * eps);
    }
    EXPECT_GT(H.middleCols<3>(kA).cwiseAbs().maxCoeff(), 0.05);  // ~1/g
    const Vec2d r = r_of(EkfVector::Zero(kN));
    const testing::DenseUpdate ref = testing::denseEkfUpdate(P, H, m.covariance, r);
    const EkfVector& dx = ref.dx;
    const double err = testing::relativeDifference(ekf.covariance(), ref.P);
    worst = std::max(worst, err);
    EXPECT_LE(err, 1e-6) << "trial " << trial;
    const EkfState y = ekf.state(), y_ref = testing::ekfBoxplus(x, dx, 0, true);
    EXPECT_LE((y.accel_bias - y_ref.accel_bias).cwiseAbs().maxCoeff(), 1e-9);
    EXPECT_LE(so3::boxminus(y.q_site_body, y_ref.q_site_body).norm(), 1e-9);
  }
  RecordProperty("worst_relative_error", std::to_string(worst));
}

// Roll and pitch read from the first rest's gravity as if b_a were 0 are off by what b_a tilts
// gravity by: the filter starts with δθ = −M b_a (M = H_θ⁺ H_b), so H_θ P_θb + H_b Σ_b = 0 (the
// reading predicted at the start is exactly as certain as the reading was) and P_θθ grows by
// M Σ_b Mᵀ. Checked with H from central differences at random attitudes.
TEST(EstAccelBias, InitialAttitudeIsCorrelatedWithTheBiasWhenReadFromGravity) {
  const io::RoverConfig cfg = biasConfig();
  std::mt19937 rng(92);
  for (int trial = 0; trial < 10;) {
    InitialState init;
    const Quatd q = randomUnitQuaternion(rng);
    const Vec3d rpy = so3::rollPitchYaw(q);
    if (std::abs(rpy.y()) > 1.2) continue;
    ++trial;
    init.q_site_body = q;
    init.roll_pitch_from_gravity = true;
    InitialState plain = init;
    plain.roll_pitch_from_gravity = false;
    // Without rest updates the filter does not count the window again, so it keeps the window's
    // σ and the correlation (with them it starts roll and pitch from the σ before the window and
    // applies its gravity: EstEkf.FirstRestIsCountedOnce).
    EkfOptions no_rest;
    no_rest.use_rest = false;
    const Ekf ekf(cfg, testing::rocky7(), no_rest, init, true, true);
    const Ekf ref(cfg, testing::rocky7(), no_rest, plain, true, true);
    const Quatd q0 = ekf.state().q_site_body;
    const auto h = [&](const Eigen::Matrix<double, 6, 1>& z) {
      return sensors::gravityRollPitchPredict<double>(so3::boxplus(q0, Vec3d(z.head<3>())),
                                                      Vec3d(z.tail<3>()), cfg.gravity_mps2);
    };
    Eigen::Matrix<double, 2, 6> J;
    for (int j = 0; j < 6; ++j) {
      Eigen::Matrix<double, 6, 1> e = Eigen::Matrix<double, 6, 1>::Zero();
      e[j] = 1e-6;
      J.col(j) = (h(e) - h(-e)) / 2e-6;
    }
    const EkfMatrix& P = ekf.covariance();
    const Mat3d Sb = P.block<3, 3>(kA, kA), Ptb = P.block<3, 3>(I::kTheta, kA);
    EXPECT_TRUE(Sb.isApprox(Mat3d::Identity() * 0.05 * 0.05));
    const Eigen::Matrix<double, 2, 3> zero = J.leftCols<3>() * Ptb + J.rightCols<3>() * Sb;
    EXPECT_LE(zero.cwiseAbs().maxCoeff(), 1e-8 * Sb(0, 0)) << "trial " << trial;
    EXPECT_GT(Ptb.cwiseAbs().maxCoeff(), 1e-6);
    // P_θθ − P_θθ(plain) = M Σ_b Mᵀ = Ptb Σ_b⁻¹ Ptbᵀ.
    const Mat3d added =
        P.block<3, 3>(I::kTheta, I::kTheta) - ref.covariance().block<3, 3>(I::kTheta, I::kTheta);
    EXPECT_LE((added - Ptb * Sb.inverse() * Ptb.transpose()).cwiseAbs().maxCoeff(), 1e-12);
    // δθ = −M b_a explains the bias's roll/pitch (H_θ M = H_b) with the minimum-norm attitude
    // error: M's columns lie in H_θ's row space (nothing along the unobserved yaw direction).
    const Mat3d M = -Ptb * Sb.inverse();
    const Eigen::Matrix<double, 2, 3> Ht = J.leftCols<3>();
    EXPECT_LE((Ht * M - J.rightCols<3>()).cwiseAbs().maxCoeff(), 1e-7);
    const Mat3d null_projector =
        Mat3d::Identity() - Ht.transpose() * (Ht * Ht.transpose()).inverse() * Ht;
    EXPECT_LE((null_projector * M).cwiseAbs().maxCoeff(), 1e-7);
  }
}

// The random walk: over dt with nothing else, b_a's variance grows by rw² dt; the other states'
// propagation is the bias-free filter's (b_a = 0 on the perturbation model, where the
// accelerometer does not drive the velocity).
TEST(EstAccelBias, ProcessNoiseIsTheDeclaredRandomWalk) {
  const io::RoverConfig cfg = biasConfig();
  Ekf ekf(cfg, testing::rocky7(), {}, InitialState{}, true, true);
  const Mat3d before = ekf.covariance().block<3, 3>(kA, kA);
  EkfInputs in;
  in.accel = Vec3d(0, 0, cfg.gravity_mps2);
  ekf.propagate(2.0, in);
  const Mat3d after = ekf.covariance().block<3, 3>(kA, kA);
  EXPECT_TRUE((after - before).isApprox(Mat3d::Identity() * 2e-3 * 2e-3 * 2.0, 1e-12));
}

// A four-wheel rover with b_a has its own compiled covariance kernel (22 states): Φ P Φᵀ over F's
// nonzeros equals the dense form for a random sparse F.
TEST(EstAccelBias, FourWheelKernelMatchesDense) {
  constexpr int n = ekfStates(4, 0, kAccelBiasStates);
  static_assert(n == 22);
  testing::expectCovarianceKernelMatchesDense(n, 93);
}

// ---------------------------------------------------------------------------------------------
// On simulated traverses with a bias the log's rover.yaml declares (sensors.accel.bias_mps2,
// bias_sigma_mps2): the accelerometer-driven EKF (O-4) integrates an unmodelled bias into the
// velocity — the wheels disagree and the slip updates are gated — whereas with the states the
// wheels observe b_a while driving.
// ---------------------------------------------------------------------------------------------

std::filesystem::path datasets() {
  return std::filesystem::path(testing::sourceDir()) / "datasets";
}

/// Simulated once per process (both tests use the declared one).
const sim::Simulation& simulateWithBias(bool declared) {
  static const auto make = [](bool d) {
    // multi-stop's terrain, noise and slip on a shorter path (207 s): three legs between which
    // the heading turns by 90° twice, so that rests at other headings separate b_a from a tilt.
    std::vector<std::string> o = {
        "path=[{rest: 12}, {straight: 3.0, speed_mps: 0.1, ramp_s: 2}, {rest: 12},"
        " {turn: 1.57, rate_rad_s: 0.1, ramp_s: 2}, {rest: 12},"
        " {arc: 3.0, radius_m: -5.0, speed_mps: 0.1, ramp_s: 2}, {rest: 12},"
        " {turn: 1.57, rate_rad_s: 0.1, ramp_s: 2}, {rest: 12},"
        " {straight: 3.0, speed_mps: 0.1, ramp_s: 2}, {rest: 12}]",
        "sensors.accel.bias_mps2=[0.04,-0.03,0.05]"};
    if (d) o.emplace_back("sensors.accel.bias_sigma_mps2=0.05");
    return sim::simulate(sim::loadScenario("multi-stop", datasets(), o),
                         datasets() / "rovers" / "rocky7", 3);
  };
  if (declared) {
    static const sim::Simulation s = make(true);
    return s;
  }
  static const sim::Simulation s = make(false);
  return s;
}

pipeline::PipelineConfig accelDriven(bool smooth) {
  pipeline::PipelineConfig c;
  c.ekf.velocity = EkfOptions::VelocityModel::kAccelDriven;
  c.smooth = smooth;
  return c;
}

TEST(EstAccelBias, EkfAndSmootherRecoverAnInjectedBias) {
  const Vec3d truth(0.04, -0.03, 0.05);
  const sim::Simulation& s = simulateWithBias(true);
  ASSERT_EQ(s.log.config.accel.bias_sigma_mps2, 0.05);
  const pipeline::Estimates e = pipeline::estimate(s.log, accelDriven(true));
  ASSERT_EQ(e.ekf.velocity, EkfOptions::VelocityModel::kAccelDriven);
  const TrajectoryNode& last = e.ekf.trajectory.nodes.back();
  for (int i = 0; i < 3; ++i) {
    EXPECT_GT(last.accel_bias_sigma[i], 0.0);
    EXPECT_LT(last.accel_bias_sigma[i], 0.5 * 0.05) << "axis " << i << ": b_a not observed";
    EXPECT_LE(std::abs(last.accel_bias[i] - truth[i]), 3.0 * last.accel_bias_sigma[i])
        << "EKF axis " << i << ": " << last.accel_bias.transpose();
  }
  ASSERT_TRUE(e.smoothed.has_value());
  int checked = 0;
  for (const TrajectoryNode& n : e.smoothed->trajectory.nodes) {
    if (n.accel_bias_sigma.isZero()) continue;  // a segment that kept the EKF's states
    for (int i = 0; i < 3; ++i)
      ASSERT_LE(std::abs(n.accel_bias[i] - truth[i]), 3.0 * n.accel_bias_sigma[i] + 1e-9)
          << "smoother axis " << i << " at t = " << n.t << ": " << n.accel_bias.transpose();
    ++checked;
  }
  EXPECT_GT(checked, 0);
  const eval::Metrics m = eval::evaluate(e.ekf.trajectory, eval::TruthTrajectory(*s.log.truth));
  EXPECT_LT(m.get("final_position_error_m").value(), 0.5);
}

// Undeclared, the same bias leaves the accelerometer-driven EKF worse than with the states.
TEST(EstAccelBias, DeclaringTheBiasBeatsIgnoringIt) {
  const sim::Simulation& with = simulateWithBias(true);
  const sim::Simulation& without = simulateWithBias(false);
  const pipeline::Estimates a = pipeline::estimate(with.log, accelDriven(false));
  const pipeline::Estimates b = pipeline::estimate(without.log, accelDriven(false));
  const eval::TruthTrajectory truth(*with.log.truth);
  const double ea = eval::evaluate(a.ekf.trajectory, truth).get("position_rmse_m").value();
  const double eb = eval::evaluate(b.ekf.trajectory, truth).get("position_rmse_m").value();
  RecordProperty("rmse_with_states_m", std::to_string(ea));
  RecordProperty("rmse_without_m", std::to_string(eb));
  EXPECT_LT(ea, eb);
}

}  // namespace
}  // namespace traverse::est
