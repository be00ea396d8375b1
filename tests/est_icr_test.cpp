// The skid-steer ICRs' half-track error δ (io::SkidSteerConfig icr_half_track_sigma_m,
// icr_half_track_random_walk_m_per_sqrt_s): a state of the EKF and a per-segment constant of the
// smoother, which the slip rows see as a wheel's ICR offset icr_offset_y + icr_side δ. Checked
// here: the keys (defaults, written back, refused out of range), which rovers carry the state,
// the EKF's slip update with δ against a dense reference whose H is central differences of the
// whole residual (random unit quaternions, random wheel angles and rates, with and without
// cmd.csv, both velocity models), δ's column by hand, the smoother's slip residual with the δ
// block against its Jet twin and central differences, and a simulated Pathfinder turn whose
// wheels roll about ICRs 6.5 cm from rover.yaml's: without the state the EKF's yaw is
// over-confident, with it δ is found within its σ and the yaw is consistent.
#include <gtest/gtest.h>
#include <cmath>

#include <filesystem>
#include <fstream>
#include <random>

#include "support/ekf_state.h"
#include "support/jacobian_check.h"
#include "traverse/core/error.h"
#include "traverse/estimators/ekf.h"
#include "traverse/io/rover_config.h"
#include "traverse/io/rover_description.h"
#include "traverse/pipeline/pipeline.h"
#include "traverse/rover/kinematics.h"
#include "traverse/rover/nominal_slip.h"
#include "traverse/sim/scenario.h"
#include "traverse/sim/simulator.h"
#include "traverse/smoother/residuals/slip_residual.h"

namespace traverse::est {
namespace {

using I = EkfIndex;
using testing::randomVector;
const std::filesystem::path kDatasets = testing::sourceDir() + "/datasets";
constexpr int kWheels = 4;

const io::RoverConfig& pathfinderConfig() {
  static const io::RoverConfig c = io::loadRoverConfig(kDatasets / "rovers/pathfinder/rover.yaml");
  return c;
}
const rover::RoverGeometry& pathfinder() {
  static const rover::RoverGeometry g =
      io::loadRoverGeometry(kDatasets / "rovers/pathfinder/rover.urdf", pathfinderConfig());
  return g;
}

/// Pathfinder's wheel frames and joint twists at random wheel angles and rates (a rigid rover:
/// the wheels' drive rates are its only joint rates).
rover::JointSample randomJointSample(std::mt19937& rng) {
  const rover::RoverGeometry& geo = pathfinder();
  const int nq = geo.numCoords();
  rover::JointVectord q(nq), q_dot(nq);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (int i = 0; i < nq; ++i) q[i] = 3.0 * u(rng), q_dot[i] = 5.0 * u(rng);
  const auto kin = rover::forwardKinematics<double>(geo, q);
  rover::JointSample js;
  js.resize(geo.numWheels());
  for (int i = 0; i < geo.numWheels(); ++i) {
    js.T_body_wheel[i] = kin[i].T_body_wheel;
    js.joint_twist[i] = rover::wheelJointTwist(kin[i], q_dot);
    js.joint_twist_covariance[i] = 1e-6 * Mat6d::Identity();
  }
  return js;
}

/// x ⊞ δx for Pathfinder's layout: ξ (4), δ (1) (its rover.yaml declares no accelerometer bias).
EkfState boxplus(const EkfState& x, const EkfVector& dx) {
  EkfState y = x;
  y.q_site_body = so3::boxplus(x.q_site_body, Vec3d(dx.segment<3>(I::kTheta)));
  y.w_p += dx.segment<3>(I::kRate);
  y.p_site += dx.segment<3>(I::kPos);
  y.v_p += dx.segment<3>(I::kVel);
  y.xi += dx.segment(I::kXi, kWheels);
  y.bias += dx.segment<3>(I::kBias);
  y.icr += dx[I::icr(kWheels, 0, 0)];
  return y;
}

TEST(EstIcr, KeysDefaultsAndWhichRoversCarryTheState) {
  const io::RoverConfig& pf = pathfinderConfig();
  ASSERT_TRUE(pf.skid_steer.has_value());
  EXPECT_TRUE(pf.estimatesIcr());
  // Without the key: 20 % of the half-track.
  io::SkidSteerConfig k;
  k.icr_y_left_m = 0.4, k.icr_y_right_m = -0.3;
  EXPECT_DOUBLE_EQ(k.icrHalfTrackSigma(), 0.2 * 0.35);
  k.icr_half_track_sigma_m = 0.0;
  EXPECT_DOUBLE_EQ(k.icrHalfTrackSigma(), 0.0);

  const InitialState init;
  const Ekf with(pf, pathfinder(), {}, init, true, false);
  EXPECT_TRUE(with.hasIcr());
  ASSERT_FALSE(pf.accel.hasBias());
  EXPECT_EQ(with.numStates(), ekfStates(kWheels, 0, 0, kIcrStates));
  const int kk = I::icr(kWheels, 0, 0);
  EXPECT_DOUBLE_EQ(with.covariance()(kk, kk), std::pow(pf.skid_steer->icrHalfTrackSigma(), 2));
  EXPECT_TRUE(with.covariance().row(kk).head(kk).isZero(0.0));
  io::RoverConfig exact = pf;
  exact.skid_steer->icr_half_track_sigma_m = 0.0;
  const Ekf without(exact, pathfinder(), {}, init, true, false);
  EXPECT_FALSE(without.hasIcr());
  EXPECT_EQ(without.numStates(), ekfStates(kWheels));
  // A rover without skid steering (Rocky-7) has no such state.
  const io::RoverConfig r7 = io::loadRoverConfig(kDatasets / "rovers/rocky7/rover.yaml");
  EXPECT_FALSE(r7.estimatesIcr());
  // Each skid-steered wheel's side.
  for (const rover::Wheel& w : pathfinder().wheels)
    EXPECT_EQ(w.icr_side, w.left_share > 0.5 ? 1.0 : -1.0);

  // Written back and read; out of range refused with the key and line.
  const std::filesystem::path dir = std::filesystem::temp_directory_path() / "traverse_icr_keys";
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  io::RoverConfig c = pf;
  c.skid_steer->icr_half_track_sigma_m = 0.05;
  c.skid_steer->icr_half_track_random_walk_m_per_sqrt_s = 0.003;
  io::saveRoverConfig(dir / "rover.yaml", c);
  const io::RoverConfig back = io::loadRoverConfig(dir / "rover.yaml");
  ASSERT_TRUE(back.skid_steer.has_value());
  EXPECT_EQ(back.skid_steer->icr_half_track_sigma_m, 0.05);
  EXPECT_DOUBLE_EQ(back.skid_steer->icr_half_track_random_walk_m_per_sqrt_s, 0.003);
  std::ofstream(dir / "bad.yaml") << "format: 1\nskid_steer:\n  icr_y_left_m: 0.3\n"
                                     "  icr_y_right_m: -0.3\n  icr_half_track_sigma_m: -1\n";
  try {
    io::loadRoverConfig(dir / "bad.yaml");
    FAIL() << "a negative sigma was accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("icr_half_track_sigma_m"), std::string::npos) << e.what();
    EXPECT_EQ(e.line(), 5);
  }
}

// Hand-checked: with a commanded turn at ω_z = 0.4 rad/s the nominal longitudinal slip of a
// wheel is 0.4 (icr_offset_y + side δ): δ = 0.01 m moves a left wheel's first residual row by
// +0.004 m/s and a right one's by −0.004, and −∂r/∂δ is (∓0.4, 0, 0, 0).
TEST(EstIcr, SlipResidualIcrColumnHandChecked) {
  const rover::RoverGeometry& geo = pathfinder();
  std::mt19937 rng(90);
  const rover::JointSample js = randomJointSample(rng);
  const Twistd cmd = rover::nominalBodyTwist(geo, 0.0, 0.4);
  Eigen::Matrix<double, 7, 1> s;
  s << randomVector<3>(rng, 0.3), randomVector<3>(rng, 0.5), 0.05;
  for (int i = 0; i < kWheels; ++i) {
    Eigen::Matrix<double, 4, 7> H;
    Vec4d H_icr;
    const Vec4d r0 = slipUpdateResidual(geo, js, i, &cmd, s, &H, nullptr, 0.0, &H_icr);
    const Vec4d r1 = slipUpdateResidual(geo, js, i, &cmd, s, &H, nullptr, 0.01);
    const double side = geo.wheels[i].icr_side;
    EXPECT_NEAR(r1[0] - r0[0], side * 0.004, 1e-15) << "wheel " << i;
    EXPECT_EQ(Vec3d(r1.tail<3>()), Vec3d(r0.tail<3>())) << "wheel " << i;
    EXPECT_EQ(H_icr, Vec4d(-side * 0.4, 0.0, 0.0, 0.0));
  }
}

// updateSlip with δ, one wheel at a time, against the textbook update with H = −∂r/∂δx by central
// differences of the residual over every error-state direction.
TEST(EstIcr, EkfSlipUpdateMatchesDenseReferenceWithNumericH) {
  const io::RoverConfig& cfg = pathfinderConfig();
  const rover::RoverGeometry& geo = pathfinder();
  constexpr int kN = ekfStates(kWheels, 0, 0, kIcrStates);
  const int kk = I::icr(kWheels, 0, 0);
  std::mt19937 rng(91);
  double worst = 0.0;
  for (const bool has_cmd : {true, false}) {
    for (const bool accel : {false, true}) {
      EkfOptions o = testing::ungatedOptions(accel);
      Ekf ekf(cfg, geo, o, InitialState{}, true, has_cmd);
      ASSERT_EQ(ekf.numStates(), kN);
      for (int trial = 0; trial < 8; ++trial) {
        const int wheel = trial % kWheels;
        rover::JointSample js = randomJointSample(rng);
        js.used.assign(kWheels, 0);
        js.used[static_cast<size_t>(wheel)] = 1;
        EkfState x = testing::randomEkfState(rng, kWheels);
        x.icr = randomVector<1>(rng, 0.05)[0];
        const EkfInputs in = testing::randomSlipInputs(rng, has_cmd, accel);
        const EkfMatrix P = testing::randomSmallCovariance(rng, kN);
        ekf.setState(x);
        ekf.setCovariance(P);
        ekf.updateSlip(js, in);

        const Twistd cmd = rover::nominalBodyTwist(geo, in.v_cmd.x(), in.w_cmd.z());
        const auto s_of = [&](const EkfState& y) {
          Eigen::Matrix<double, 7, 1> s;
          s << (accel ? y.v_p : ekf.velocity<double>(y.v_p, in)),
              ekf.omega<double>(y.w_p, y.bias, in), y.xi[wheel];
          return s;
        };
        const auto r_of = [&](const EkfVector& dx) {
          Eigen::Matrix<double, 4, 7> unused;
          const EkfState y = boxplus(x, dx);
          return slipUpdateResidual(geo, js, wheel, has_cmd ? &cmd : nullptr, s_of(y), &unused,
                                    nullptr, y.icr);
        };
        Eigen::Matrix<double, 4, kN> H;
        const double eps = 1e-6;
        for (int j = 0; j < kN; ++j) {
          const EkfVector e = EkfVector::Unit(kN, j) * eps;
          H.col(j) = -(r_of(e) - r_of(-e)) / (2 * eps);
        }
        // δ is really in the update: its column is ∓ω_z,nom on the longitudinal row.
        const double w_nom = has_cmd ? in.w_cmd.z() : s_of(x)[5];
        EXPECT_NEAR(H(0, kk), -geo.wheels[wheel].icr_side * w_nom, 1e-7);
        Eigen::Matrix<double, 4, 7> Hs, Jt;
        const Vec4d r =
            slipUpdateResidual(geo, js, wheel, has_cmd ? &cmd : nullptr, s_of(x), &Hs, &Jt, x.icr);
        const Eigen::Matrix<double, 7, 1> s = s_of(x);
        const Eigen::Matrix4d R = rover::slipCovariance(cfg.slip_noise, js, wheel, s.head<3>(),
                                                        s.segment<3>(3), Jt.leftCols<6>());
        const testing::DenseUpdate ref = testing::denseEkfUpdate(
            P, H,
            testing::withGyroNoise(R, H, Mat3d::Identity(), std::pow(cfg.gyro.noise_rad_s, 2)), r);
        const EkfVector& dx = ref.dx;
        const double err = testing::relativeDifference(ekf.covariance(), ref.P);
        worst = std::max(worst, err);
        EXPECT_LE(err, 1e-7) << "cmd " << has_cmd << " accel " << accel << " wheel " << wheel;
        const EkfState y = ekf.state(), y_ref = boxplus(x, dx);
        EXPECT_NEAR(y.icr, y_ref.icr, 1e-9);
        EXPECT_LE((y.v_p - y_ref.v_p).cwiseAbs().maxCoeff(), 1e-9);
        EXPECT_LE((y.bias - y_ref.bias).cwiseAbs().maxCoeff(), 1e-9);
      }
    }
  }
  RecordProperty("worst_relative_error", std::to_string(worst));
}

// A skid-steered four-wheel rover has its own compiled covariance kernel (20 states): Φ P Φᵀ over
// F's nonzeros equals the dense form for a random sparse F (the update kernels are checked
// against dense algebra by EkfSlipUpdateMatchesDenseReferenceWithNumericH above).
TEST(EstIcr, FourWheelIcrKernelMatchesDense) {
  constexpr int n = ekfStates(kWheels, 0, 0, kIcrStates);
  static_assert(n == 20);
  testing::expectCovarianceKernelMatchesDense(n, 94);
}

// The smoother's slip residual with the δ block (with and without c, with the command's or the
// state's ω_z): analytic Jacobians against the Jet Jacobian of the templated model and against
// central differences.
TEST(EstIcr, SmootherSlipResidualJacobiansMatchNumeric) {
  std::mt19937 rng(92);
  const rover::RoverGeometry& geo = pathfinder();
  for (int trial = 0; trial < 16; ++trial) {
    const int wheel = trial % kWheels;
    const bool common = trial % 2 == 0, follows = trial % 4 < 2;
    const rover::JointSample js = randomJointSample(rng);
    Eigen::Matrix4d L = Eigen::Matrix4d::Identity() * 200.0;
    L(0, 1) = 30.0, L(2, 3) = -10.0;
    smoother::SlipWheelData d{js.T_body_wheel[static_cast<size_t>(wheel)],
                              geo.wheels[static_cast<size_t>(wheel)].radius,
                              js.joint_twist[static_cast<size_t>(wheel)],
                              randomVector<4>(rng, 0.01),
                              L,
                              Eigen::Matrix<double, 4, 2>::Zero(),
                              Vec2d::Zero(),
                              geo.wheels[static_cast<size_t>(wheel)].icr_side,
                              follows,
                              0.3};
    if (follows) {
      d.nominal_jacobian = randomVector<8>(rng, 0.3).reshaped(4, 2);
      d.nominal_at = randomVector<2>(rng, 0.2);
    }
    const smoother::SlipResidual f(wheel, kWheels, &d, common ? 2 : 0, true);
    ASSERT_EQ(f.parameter_block_sizes().size(), common ? 5u : 4u);
    // z = (v, ω, ξ (4), c (2), δ); c unused without the block.
    constexpr int kZ = 13;
    Eigen::Matrix<double, kZ, 1> z;
    z << randomVector<3>(rng, 0.3), randomVector<3>(rng, 0.5), randomVector<kWheels>(rng, 0.4),
        (common ? randomVector<2>(rng, 0.03) : Vec2d::Zero()), randomVector<1>(rng, 0.05);
    const auto eval = [&](const Eigen::Matrix<double, kZ, 1>& x, double* jac_out) {
      std::vector<const double*> params = {x.data(), x.data() + 3, x.data() + 6};
      if (common) params.push_back(x.data() + 10);
      params.push_back(x.data() + 12);
      Vec4d r;
      double J0[12], J1[12], J2[4 * kWheels], J3[8], J4[4];
      std::vector<double*> jac = {J0, J1, J2};
      if (common) jac.push_back(J3);
      jac.push_back(J4);
      EXPECT_TRUE(f.Evaluate(params.data(), r.data(), jac_out ? jac.data() : nullptr));
      if (jac_out) {
        using Rm = Eigen::Matrix<double, 4, Eigen::Dynamic, Eigen::RowMajor>;
        Eigen::Map<Eigen::Matrix<double, 4, kZ, Eigen::RowMajor>> out(jac_out);
        out.setZero();
        out.leftCols<3>() = Eigen::Map<Rm>(J0, 4, 3);
        out.middleCols<3>(3) = Eigen::Map<Rm>(J1, 4, 3);
        out.middleCols<kWheels>(6) = Eigen::Map<Rm>(J2, 4, kWheels);
        if (common) out.middleCols<2>(10) = Eigen::Map<Rm>(J3, 4, 2);
        out.col(12) = Eigen::Map<Vec4d>(J4);
      }
      return r;
    };
    double Ja[4 * kZ];
    const Vec4d r = eval(z, Ja);
    const auto model = [&](const auto& x) {
      using T = typename std::decay_t<decltype(x)>::Scalar;
      return f.residual<T>(Vec3<T>(x.template head<3>()), Vec3<T>(x.template segment<3>(3)),
                           Eigen::Matrix<T, kWheels, 1>(x.template segment<kWheels>(6)),
                           Vec3<T>(x[10], x[11], T(0)), x[12]);
    };
    EXPECT_LE((r - model(z)).cwiseAbs().maxCoeff(), 1e-12);
    Eigen::Matrix<double, 4, kZ> Jjet = testing::autodiffJacobian<4, kZ>(model, z);
    if (!common) Jjet.middleCols<2>(10).setZero();
    Eigen::Matrix<double, 4, kZ> Jn =
        testing::numericJacobian<4, kZ>([&](const auto& x) { return eval(x, nullptr); }, z);
    if (!common) Jn.middleCols<2>(10).setZero();
    const Eigen::Map<const Eigen::Matrix<double, 4, kZ, Eigen::RowMajor>> J(Ja);
    EXPECT_LE((J - Jjet).cwiseAbs().maxCoeff(), 1e-12 * std::max(1.0, Jjet.cwiseAbs().maxCoeff()))
        << "wheel " << wheel << "\nanalytic:\n"
        << J << "\nJet:\n"
        << Jjet;
    EXPECT_LE((J - Jn).cwiseAbs().maxCoeff(), 1e-6 * std::max(1.0, Jn.cwiseAbs().maxCoeff()))
        << "wheel " << wheel;
    EXPECT_GT(std::abs(J(0, 12)), 0.0);  // δ is in the residual
  }
}

}  // namespace
}  // namespace traverse::est

namespace traverse::est {
namespace {

// A simulated Pathfinder turn in place whose wheels roll about ICRs 6.5 cm outside those the
// estimators are told (the geometry's icr_offset_y moved in by 6.5 cm per side): the truth's δ is
// +0.065 m, and the log has no sun (which would mend the yaw). Without the state the wheels' yaw
// rate is 19 % short of the gyro's in every slip row: the final yaw is off by 20σ (EKF) and 18σ
// (smoother); with it the EKF and the smoother find δ within 3σ (0.0635 ± 0.0035 and
// ± 0.0008) and their final yaw errors are 0.3σ and 0.4σ.
TEST(EstIcr, SimulatedIcrErrorIsEstimatedAndTheYawStaysConsistent) {
  const sim::Scenario sc = sim::loadScenario("turn-in-place-360", kDatasets, {"rover=pathfinder"});
  const sim::Simulation sim = sim::simulate(sc, sim::roverDirectory(sc, kDatasets), 5);
  io::TraverseLog log = sim.log;
  ASSERT_TRUE(log.config.skid_steer.has_value());
  for (rover::Wheel& w : log.geometry.wheels) w.icr_offset_y -= w.icr_side * 0.065;
  log.sun.reset();  // the yaw from the gyro and the wheels alone (the sun would mend it)
  const Quatd q_true = sim.truth.back().q_site_body;
  const auto yawError = [&](const Trajectory& tr) {
    const Quatd q = tr.nodes.back().q_site_body;
    const Vec3d e = so3::boxminus(q_true, q);  // body frame; the rover is nearly level
    return std::abs(e.z()) / std::sqrt(tr.nodes.back().covariance(5, 5));
  };
  pipeline::PipelineConfig config;
  config.smooth = true;
  io::RoverConfig exact = log.config;
  exact.skid_steer->icr_half_track_sigma_m = 0.0;
  io::TraverseLog log_exact = log;
  log_exact.config = exact;
  const pipeline::Estimates before = pipeline::estimate(log_exact, config);
  EXPECT_GT(yawError(before.ekf.trajectory), 5.0);
  ASSERT_TRUE(before.smoothed.has_value());
  EXPECT_GT(yawError(before.smoothed->trajectory), 5.0);

  const pipeline::Estimates after = pipeline::estimate(log, config);
  ASSERT_TRUE(after.smoothed.has_value());
  const TrajectoryNode& e = after.ekf.trajectory.nodes.back();
  EXPECT_GT(e.icr_sigma, 0.0);
  EXPECT_LT(e.icr_sigma, 0.02);
  EXPECT_LT(std::abs(e.icr - 0.065), 3.0 * e.icr_sigma) << e.icr << " ± " << e.icr_sigma;
  EXPECT_LT(yawError(after.ekf.trajectory), 3.0);
  EXPECT_LT(yawError(after.smoothed->trajectory), 3.0);
  bool turned = false;
  for (const smoother::SegmentSummary& s : after.smoothed->segments) {
    if (s.icr_sigma <= 0.0 || s.icr_sigma > 0.02) continue;  // a segment without turning
    turned = true;
    EXPECT_LT(std::abs(s.icr - 0.065), 3.0 * s.icr_sigma) << s.icr << " ± " << s.icr_sigma;
  }
  EXPECT_TRUE(turned);
}

}  // namespace
}  // namespace traverse::est
