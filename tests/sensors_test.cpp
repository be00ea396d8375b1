// Measurement models (K-10 … K-16, Nickels rest mode): hand-checked values and Jacobians
// against finite differences at random states (random unit quaternions).
#include <gtest/gtest.h>

#include "support/jacobian_check.h"
#include "traverse/sensors/accelerometer.h"
#include "traverse/sensors/gravity.h"
#include "traverse/sensors/gyro.h"
#include "traverse/sensors/sun_sensor.h"

namespace traverse::sensors {
namespace {

using testing::randomUnitQuaternion;
using testing::randomVector;

template <typename T>
Quat<T> perturbed(const Quatd& q0, const Eigen::Matrix<T, 3, 1>& d) {
  return so3::boxplus(Quat<T>(q0.cast<T>()), d);
}

TEST(GyroModel, HandCheckedAndJacobian) {
  EXPECT_LT((gyroPredict<double>(Vec3d(0.1, -0.2, 0.3), Vec3d(0.01, 0.02, 0.03)) -
             Vec3d(0.11, -0.18, 0.33))
                .norm(),
            1e-15);
  // B_g: heading-only [0 0 1], three-axis I.
  const GyroAxes z = GyroAxes::headingOnly(), xyz = GyroAxes::threeAxis();
  EXPECT_EQ(z.count(), 1);
  EXPECT_EQ(z.axis(0), 2);
  EXPECT_EQ(xyz.axis(1), 1);
  EXPECT_EQ(GyroAxes::forColumns(1).count(), 1);
  EXPECT_EQ(GyroAxes::forColumns(3).count(), 3);
  EXPECT_EQ(z.mask(), Vec3d(0, 0, 1));
  EXPECT_EQ(xyz.selection(), Mat3d::Identity());
  EXPECT_EQ(z.toBody(Eigen::VectorXd::Constant(1, 0.5)), Vec3d(0, 0, 0.5));
  EXPECT_EQ(xyz.toBody(Vec3d(1, 2, 3)), Vec3d(1, 2, 3));
  EXPECT_EQ(z.unmeasured(), (std::vector<int>{0, 1}));
  EXPECT_TRUE(xyz.unmeasured().empty());
  // The reading B_g(ω + b) a heading gyro gives is the z row of gyroPredict.
  const Vec3d w(0.1, -0.2, 0.3), b(0.01, 0.02, 0.03);
  EXPECT_EQ(z.toBody(Eigen::VectorXd::Constant(1, gyroPredict<double>(w, b)[z.axis(0)])),
            Vec3d(z.selection() * gyroPredict<double>(w, b)));
  std::mt19937 rng(20);
  for (int k = 0; k < 10; ++k) {
    testing::expectJacobianMatchesNumeric<3, 6>(
        [](const auto& x) {
          using T = typename std::decay_t<decltype(x)>::Scalar;
          return gyroPredict<T>(x.template head<3>(), x.template tail<3>());
        },
        randomVector<6>(rng));
  }
}

TEST(SunSensorModel, SunAtZenithReadsZero) {
  const Vec2d s = sunSensorPredict<double>(Quatd::Identity(), {}, Vec3d::UnitZ());
  EXPECT_LT(s.norm(), 1e-15);
}

// Sun on the sensor x axis at 45° from the boresight: α = π/4, s_m = (2/π)(π/4) = 0.5.
TEST(SunSensorModel, SunAt45DegreesOnXAxisReadsHalf) {
  const Vec3d sun = Vec3d(1, 0, 1).normalized();
  const Vec2d s = sunSensorPredict<double>(Quatd::Identity(), {}, sun);
  EXPECT_NEAR(s.x(), 0.5, 1e-15);
  EXPECT_NEAR(s.y(), 0.0, 1e-15);
  EXPECT_NEAR(M_PI / 2 * (1 - s.norm()), M_PI / 4, 1e-15);  // the paper's elevation formula
  // Rotating the rover by +90° in yaw moves the sun to the sensor's −y axis.
  const Vec2d s2 = sunSensorPredict<double>(so3::fromRollPitchYaw(0.0, 0.0, M_PI / 2), {}, sun);
  EXPECT_LT((s2 - Vec2d(0, -0.5)).norm(), 1e-15);
}

// At the boresight the factor (2/π) arcsin(ρ)/ρ → 2/π: a small tilt δ about y moves s1 by 2δ/π.
TEST(SunSensorModel, BoresightIsNumericallySafe) {
  const auto f = [](const auto& d) {
    using T = typename std::decay_t<decltype(d)>::Scalar;
    return sunSensorPredict<T>(perturbed(Quatd::Identity(), Vec3<T>(d)), SunSensorGeometry{},
                               Vec3d::UnitZ());
  };
  const auto J = testing::autodiffJacobian<2, 3>(f, Vec3d::Zero().eval());
  ASSERT_TRUE(J.allFinite());
  // Rotating the body by +δ about y tilts the sun towards body −x: s1 = −2δ/π.
  EXPECT_NEAR(J(0, 1), -2.0 / M_PI, 1e-12);
  EXPECT_NEAR(J(1, 0), 2.0 / M_PI, 1e-12);
  testing::expectJacobianMatchesNumeric<2, 3>(f, Vec3d(1e-9, -2e-9, 0).eval(), 1e-5);
}

TEST(SunSensorModel, JacobianMatchesNumericAtRandomAttitudes) {
  std::mt19937 rng(21);
  SunSensorGeometry geo;
  geo.R_body_sensor = so3::exp(Vec3d(0.05, -0.1, 0.3));
  int tested = 0;
  while (tested < 50) {
    const Quatd q0 = randomUnitQuaternion(rng);
    const Vec3d sun = randomVector<3>(rng).normalized();
    if (!sunInFieldOfView(q0, geo, sun)) continue;
    ++tested;
    testing::expectJacobianMatchesNumeric<2, 3>(
        [&](const auto& d) {
          using T = typename std::decay_t<decltype(d)>::Scalar;
          return sunSensorPredict<T>(perturbed(q0, Vec3<T>(d)), geo, sun);
        },
        Vec3d::Zero().eval(), 1e-6);
  }
}

TEST(SunSensorModel, FieldOfViewAndInverse) {
  SunSensorGeometry geo;  // 160° field of view
  const auto at = [](double deg) {
    return Vec3d(std::sin(deg * M_PI / 180), 0, std::cos(deg * M_PI / 180));
  };
  EXPECT_TRUE(sunInFieldOfView(Quatd::Identity(), geo, at(79.9)));
  EXPECT_FALSE(sunInFieldOfView(Quatd::Identity(), geo, at(80.1)));
  std::mt19937 rng(22);
  for (int k = 0; k < 100; ++k) {
    Vec3d s = randomVector<3>(rng).normalized();
    s.z() = std::abs(s.z());
    EXPECT_LT((fisheyeUnproject(fisheyeProject<double>(s)) - s).norm(), 1e-12);
  }
}

TEST(AccelerometerModel, LevelRoverAtRestReadsPlusG) {
  const Vec3d f = accelAtRest<double>(Quatd::Identity(), 9.80665);
  EXPECT_LT((f - Vec3d(0, 0, 9.80665)).norm(), 1e-15);
  const Vec3d full =
      accelPredict<double>(Quatd::Identity(), Vec3d::Zero(), Vec3d::Zero(), Vec3d::Zero(),
                           Vec3d::Zero(), Vec3d(0.1, 0.2, 0.3), 9.80665);
  EXPECT_LT((full - f).norm(), 1e-15);
  // Hand-checked centripetal term: ω = (0, 0, 1) rad/s, lever arm (0.5, 0, 0): ω×(ω×L) = (−0.5, 0,
  // 0).
  const Vec3d spin = accelPredict<double>(Quatd::Identity(), Vec3d::Zero(), Vec3d::Zero(),
                                          Vec3d::UnitZ(), Vec3d::Zero(), Vec3d(0.5, 0, 0), 9.80665);
  EXPECT_LT((spin - Vec3d(-0.5, 0, 9.80665)).norm(), 1e-15);
}

TEST(AccelerometerModel, JacobianMatchesNumericAndInvertsVelocityModel) {
  std::mt19937 rng(23);
  const Vec3d lever(0.05, -0.02, 0.1);
  for (int k = 0; k < 30; ++k) {
    const Quatd q0 = randomUnitQuaternion(rng);
    Eigen::Matrix<double, 15, 1> x;
    x << Vec3d::Zero(), randomVector<12>(rng);
    const auto f = [&](const auto& s) {
      using T = typename std::decay_t<decltype(s)>::Scalar;
      return accelPredict<T>(perturbed(q0, Vec3<T>(s.template head<3>())), s.template segment<3>(3),
                             s.template segment<3>(6), s.template segment<3>(9),
                             s.template segment<3>(12), lever, 3.71);
    };
    testing::expectJacobianMatchesNumeric<3, 15>(f, x);
    // K-11/O-4 solve K-10 for a: feeding the prediction back returns the acceleration.
    const Vec3d am = f(x);
    const Vec3d a = velocityRateFromAccel<double>(am, q0, x.segment<3>(6), x.segment<3>(9),
                                                  x.segment<3>(12), lever, 3.71);
    EXPECT_LT((a - x.segment<3>(3)).norm(), 1e-12);
  }
}

TEST(GravityAtRest, RollPitchMatchEulerAngles) {
  std::mt19937 rng(24);
  for (int k = 0; k < 100; ++k) {
    const Vec3d rpy(randomVector<1>(rng, 1.2)[0], randomVector<1>(rng, 1.2)[0],
                    randomVector<1>(rng, 3.0)[0]);
    const Quatd q = so3::fromRollPitchYaw(rpy.x(), rpy.y(), rpy.z());
    const Vec2d rp = rollPitchFromSpecificForce<double>(accelAtRest<double>(q, 9.81));
    EXPECT_LT((rp - rpy.head<2>()).norm(), 1e-12);
    EXPECT_LT((gravityRollPitchPredict<double>(q) - rpy.head<2>()).norm(), 1e-12);
  }
  // Hand-checked: level rover → roll = pitch = 0. Pitch +0.1 rad (a rotation about +y, which
  // takes the nose x towards −z) reads f = g (−sin 0.1, 0, cos 0.1).
  EXPECT_LT(rollPitchFromSpecificForce<double>(Vec3d(0, 0, 9.81)).norm(), 1e-15);
  const Vec2d rp = rollPitchFromSpecificForce<double>(Vec3d(-std::sin(0.1), 0, std::cos(0.1)));
  EXPECT_NEAR(rp.y(), 0.1, 1e-15);
}

TEST(GravityAtRest, JacobiansMatchNumeric) {
  std::mt19937 rng(25);
  for (int k = 0; k < 30; ++k) {
    const Quatd q0 = so3::fromRollPitchYaw(
        randomVector<1>(rng, 1.0)[0], randomVector<1>(rng, 1.0)[0], randomVector<1>(rng, 3.0)[0]);
    testing::expectJacobianMatchesNumeric<2, 3>(
        [&](const auto& d) {
          using T = typename std::decay_t<decltype(d)>::Scalar;
          return gravityRollPitchPredict<T>(perturbed(q0, Vec3<T>(d)));
        },
        Vec3d::Zero().eval());
    // The covariance propagation's analytic Jacobian against finite differences.
    const Vec3d f = accelAtRest<double>(q0, 9.81) + randomVector<3>(rng, 0.1);
    const Eigen::Matrix<double, 2, 3> Jn = testing::numericJacobian<2, 3>(
        [](const Vec3d& x) { return rollPitchFromSpecificForce<double>(x); }, f);
    const Mat3d cov = 1e-4 * Mat3d::Identity();
    const RollPitchMeasurement m = rollPitchAtRest(f, cov);
    EXPECT_LT((m.covariance - Jn * cov * Jn.transpose()).norm(), 1e-12);
  }
}

}  // namespace
}  // namespace traverse::sensors
