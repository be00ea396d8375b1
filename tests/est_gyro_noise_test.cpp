// The gyro reading's white noise in the gyro-driven EKF's slip rows (est::Ekf::updateSlip): every
// wheel's rows take ω from the same reading, so its noise is common to the wheels. The filter
// carries it as nuisance states for one joint sample's rows and marginalises them after; here that
// is checked against a dense sequential reference with the nuisance written out, the rows'
// Jacobian by central differences at each wheel's re-linearisation point.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "support/ekf_state.h"
#include "support/jacobian_check.h"
#include "support/rocky7.h"
#include "traverse/estimators/ekf.h"
#include "traverse/io/rover_config.h"
#include "traverse/rover/nominal_slip.h"

namespace traverse {
namespace {

using est::Ekf;
using est::EkfInputs;
using est::EkfMatrix;
using est::EkfOptions;
using est::EkfState;
using est::EkfVector;
using est::InitialState;
using I = est::EkfIndex;

constexpr int kWheels = 6;

io::RoverConfig rocky7Config() {
  return io::loadRoverConfig(testing::sourceDir() + "/datasets/rovers/rocky7/rover.yaml");
}

// Every wheel used, heading-only and three-axis gyro, with and without cmd.csv, both velocity
// models, the reading between two samples (variance factor 0.62).
TEST(EstGyroNoise, SlipRowsOfAllWheelsShareTheReadingsNoise) {
  const rover::RoverGeometry& geo = testing::rocky7();
  const io::RoverConfig cfg = rocky7Config();
  const int n = est::ekfStates(kWheels);
  std::mt19937 rng(5);
  double worst = 0.0;
  for (const bool three_axis : {false, true}) {
    const Mat3d S = three_axis ? Mat3d::Identity() : Vec3d(0, 0, 1).asDiagonal().toDenseMatrix();
    const int ne = three_axis ? 3 : 1;
    for (const bool has_cmd : {true, false}) {
      for (const bool accel : {false, true}) {
        EkfOptions o = testing::ungatedOptions(accel);
        Ekf ekf(cfg, geo, o, InitialState{}, three_axis, has_cmd);
        ASSERT_EQ(ekf.numStates(), n);
        rover::JointSample js = testing::randomJointSample(rng);
        for (auto& C : js.joint_twist_covariance) C = 1e-6 * Mat6d::Identity();
        const EkfState x0 = testing::randomEkfState(rng, kWheels);
        EkfInputs in = testing::randomSlipInputs(rng, has_cmd, accel);
        in.gyro_noise_variance_factor = 0.62;
        const EkfMatrix P0 = testing::randomSmallCovariance(rng, n);
        ekf.setState(x0);
        ekf.setCovariance(P0);
        ekf.updateSlip(js, in);
        ASSERT_EQ(ekf.covariance().rows(), n);  // the nuisance is gone after the rows

        // The reference: P with the nuisance appended, wheel by wheel, dense.
        const double var = cfg.gyro.noise_rad_s * cfg.gyro.noise_rad_s * 0.62;
        Eigen::MatrixXd Pa = Eigen::MatrixXd::Zero(n + ne, n + ne);
        Pa.topLeftCorner(n, n) = P0;
        Pa.bottomRightCorner(ne, ne) = var * Eigen::MatrixXd::Identity(ne, ne);
        const Twistd cmd = rover::nominalBodyTwist(geo, in.v_cmd.x(), in.w_cmd.z());
        EkfState x = x0;
        for (int wheel = 0; wheel < kWheels; ++wheel) {
          const auto s_of = [&](const EkfState& y) {
            Eigen::Matrix<double, 7, 1> s;
            s << (accel ? y.v_p : ekf.velocity<double>(y.v_p, in)),
                ekf.omega<double>(y.w_p, y.bias, in), y.xi[wheel];
            return s;
          };
          const auto r_of = [&](const EkfVector& dx) {
            Eigen::Matrix<double, 4, 7> unused;
            return est::slipUpdateResidual(geo, js, wheel, has_cmd ? &cmd : nullptr,
                                           s_of(testing::ekfBoxplus(x, dx, 0, false)), &unused);
          };
          Eigen::MatrixXd H = Eigen::MatrixXd::Zero(4, n + ne);
          const double eps = 1e-6;
          for (int j = 0; j < n; ++j) {
            const EkfVector e = EkfVector::Unit(n, j) * eps;
            H.col(j) = -(r_of(e) - r_of(-e)) / (2 * eps);
          }
          // ε enters as ω_p's measured components do: ω = S (ω_m + ε − b) + … + ω_p.
          for (int k = 0, a = 0; a < 3; ++a) {
            if (S(a, a) > 0) H.col(n + k++) = H.col(I::kRate + a);
          }
          Eigen::Matrix<double, 4, 7> Hs, Jt;
          const Vec4d r =
              est::slipUpdateResidual(geo, js, wheel, has_cmd ? &cmd : nullptr, s_of(x), &Hs, &Jt);
          const Eigen::Matrix<double, 7, 1> s = s_of(x);
          const Eigen::Matrix4d R = rover::slipCovariance(cfg.slip_noise, js, wheel, s.head<3>(),
                                                          s.segment<3>(3), Jt.leftCols<6>());
          const testing::DenseUpdate u = testing::denseEkfUpdate(Pa, H, R, r);
          Pa = u.P;
          x = testing::ekfBoxplus(x, EkfVector(u.dx.head(n)), 0, false);
        }
        const Eigen::MatrixXd P_ref = Pa.topLeftCorner(n, n);
        const double err = testing::relativeDifference(ekf.covariance(), P_ref);
        worst = std::max(worst, err);
        EXPECT_LE(err, 1e-6) << "three-axis " << three_axis << " cmd " << has_cmd << " accel "
                             << accel;
        const EkfState y = ekf.state();
        EXPECT_LE((y.v_p - x.v_p).cwiseAbs().maxCoeff(), 1e-8);
        EXPECT_LE((y.w_p - x.w_p).cwiseAbs().maxCoeff(), 1e-8);
        EXPECT_LE((y.xi - x.xi).cwiseAbs().maxCoeff(), 1e-8);
        EXPECT_LE((y.bias - x.bias).cwiseAbs().maxCoeff(), 1e-8);
        EXPECT_LE(so3::boxminus(y.q_site_body, x.q_site_body).norm(), 1e-8);
      }
    }
  }
  RecordProperty("worst_relative_error", std::to_string(worst));
}

// One wheel: the nuisance marginalised after the update is the slip noise plus H_ω S σ² Sᵀ H_ωᵀ
// (testing::withGyroNoise), at a sample (factor 1) and half-way between two (factor ½).
TEST(EstGyroNoise, OneWheelIsTheNoiseAddedToItsRows) {
  const rover::RoverGeometry& geo = testing::rocky7();
  const io::RoverConfig cfg = rocky7Config();
  const int n = est::ekfStates(kWheels);
  std::mt19937 rng(8);
  for (const double factor : {1.0, 0.5}) {
    EkfOptions o;
    o.gating = false;
    Ekf ekf(cfg, geo, o, InitialState{}, false, true);
    rover::JointSample js = testing::randomJointSample(rng);
    for (auto& C : js.joint_twist_covariance) C = 1e-6 * Mat6d::Identity();
    js.used.assign(kWheels, 0);
    js.used[2] = 1;
    const EkfState x = testing::randomEkfState(rng, kWheels);
    EkfInputs in = testing::randomSlipInputs(rng, true, false);
    in.gyro_noise_variance_factor = factor;
    const EkfMatrix P = testing::randomSmallCovariance(rng, n);
    ekf.setState(x);
    ekf.setCovariance(P);
    ekf.updateSlip(js, in);
    const Twistd cmd = rover::nominalBodyTwist(geo, in.v_cmd.x(), in.w_cmd.z());
    Eigen::Matrix<double, 7, 1> s;
    s << ekf.velocity<double>(x.v_p, in), ekf.omega<double>(x.w_p, x.bias, in), x.xi[2];
    Eigen::Matrix<double, 4, 7> J, Jt;
    const Vec4d r = est::slipUpdateResidual(geo, js, 2, &cmd, s, &J, &Jt);
    Eigen::MatrixXd H = Eigen::MatrixXd::Zero(4, n);
    H.middleCols<3>(I::kVel) = J.leftCols<3>();
    H.middleCols<3>(I::kRate) = J.middleCols<3>(3);
    const Mat3d S = Vec3d(0, 0, 1).asDiagonal();
    H.middleCols<3>(I::kBias) = -J.middleCols<3>(3) * S;
    H.col(I::kXi + 2) = J.col(6);
    const Eigen::Matrix4d R = rover::slipCovariance(cfg.slip_noise, js, 2, s.head<3>(),
                                                    s.segment<3>(3), Jt.leftCols<6>());
    const double var = std::pow(cfg.gyro.noise_rad_s, 2) * factor;
    const testing::DenseUpdate ref =
        testing::denseEkfUpdate(P, H, testing::withGyroNoise(R, H, S, var), r);
    EXPECT_LE(testing::relativeDifference(ekf.covariance(), ref.P), 1e-9) << factor;
    // Hand-checked: the variance the rows see through ω_z on the longitudinal row is
    // σ² factor (∂t_x/∂ω_z)², here added to R(0, 0).
    const Eigen::MatrixXd Rg = testing::withGyroNoise(R, H, S, var);
    EXPECT_NEAR(Rg(0, 0) - R(0, 0), var * J(0, 5) * J(0, 5), 1e-15);
  }
}

// The variance factor of a reading interpolated between two gyro samples: (1 − u)² + u².
TEST(EstGyroNoise, InterpolatedReadingHasLessNoise) {
  const Eigen::VectorXd t = Eigen::VectorXd::LinSpaced(11, 0.0, 1.0);
  EXPECT_NEAR(est::interpolationVarianceFactor(t, 0.3), 1.0, 1e-12);
  EXPECT_NEAR(est::interpolationVarianceFactor(t, 0.35), 0.5, 1e-12);
  EXPECT_NEAR(est::interpolationVarianceFactor(t, 0.325), 0.625, 1e-12);
  EXPECT_DOUBLE_EQ(est::interpolationVarianceFactor(t, -1.0), 1.0);
  EXPECT_DOUBLE_EQ(est::interpolationVarianceFactor(t, 2.0), 1.0);
}

}  // namespace
}  // namespace traverse
