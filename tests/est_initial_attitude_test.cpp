// The EKF's initial attitude covariance: the σ of roll, pitch and yaw (Z-Y-X) carried into the
// body-frame error δθ (q = q̂ ⊗ Exp(δθ)) by δθ = E (δroll, δpitch, δyaw). The yaw's σ is then
// about the site's vertical, which gravity does not see — before, it sat on the tilted body's z
// axis, so a tight roll/pitch pinned the heading of a rover with no sun (docs/results.md,
// session 19). Without a sun the heading is the gauge: σ 0 at the start.
#include <gtest/gtest.h>

#include <random>

#include "support/jacobian_check.h"
#include "support/rocky7.h"
#include "traverse/core/so3.h"
#include "traverse/estimators/ekf.h"
#include "traverse/estimators/initialization.h"
#include "traverse/estimators/segmentation.h"
#include "traverse/eval/truth.h"
#include "traverse/io/log_reader.h"
#include "traverse/sensors/gravity.h"
#include "traverse/sim/simulator.h"

namespace traverse::est {
namespace {

using I = EkfIndex;

io::RoverConfig config() {
  return io::loadRoverConfig(testing::sourceDir() + "/datasets/rovers/rocky7/rover.yaml");
}

Mat3d attitudeCovariance(const io::RoverConfig& c, const Quatd& q, const Vec3d& sigma) {
  InitialState init;
  init.q_site_body = q;
  init.attitude_sigma = sigma;
  const Ekf ekf(c, testing::rocky7(), {}, init, true, true);
  return ekf.covariance().block<3, 3>(I::kTheta, I::kTheta);
}

// Against central differences: E's column i is ∂ Log(q⁻¹ q(rpy + h e_i)) / ∂h, at random
// attitudes (pitch within ±69°), so P_θθ = E diag(σ²) Eᵀ.
TEST(EstInitialAttitude, CovarianceIsTheEulerSigmasCarriedIntoTheBodyFrame) {
  const io::RoverConfig c = config();
  std::mt19937 rng(5);
  for (int trial = 0; trial < 20;) {
    const Quatd q = testing::randomUnitQuaternion(rng);
    const Vec3d rpy = so3::rollPitchYaw(q);
    if (std::abs(rpy.y()) > 1.2) continue;
    ++trial;
    Mat3d E;
    const double h = 1e-6;
    for (int i = 0; i < 3; ++i) {
      const Vec3d d = Vec3d::Unit(i) * h;
      const Quatd plus = so3::fromRollPitchYaw(rpy.x() + d.x(), rpy.y() + d.y(), rpy.z() + d.z());
      const Quatd minus = so3::fromRollPitchYaw(rpy.x() - d.x(), rpy.y() - d.y(), rpy.z() - d.z());
      E.col(i) = (so3::boxminus(plus, q) - so3::boxminus(minus, q)) / (2 * h);
    }
    const Vec3d sigma(0.01, 0.02, 0.3);
    const Mat3d expected = E * sigma.cwiseAbs2().asDiagonal() * E.transpose();
    EXPECT_LE((attitudeCovariance(c, q, sigma) - expected).cwiseAbs().maxCoeff(), 1e-9)
        << "trial " << trial;
    // The yaw column is the site's vertical seen from the body, Rᵀ e_z.
    EXPECT_LE((E.col(2) - q.conjugate() * Vec3d::UnitZ()).norm(), 1e-8);
  }
}

// Hand-checked: a level rover (any heading) has E = I, P_θθ = diag(σ²); a rover rolled by 90°
// has its body y axis vertical, so the yaw's variance sits entirely on δθ_y.
TEST(EstInitialAttitude, HandChecked) {
  const io::RoverConfig c = config();
  const Vec3d sigma(0.01, 0.02, 0.3);
  EXPECT_LE((attitudeCovariance(c, so3::fromRollPitchYaw(0.0, 0.0, 0.7), sigma) -
             Mat3d(sigma.cwiseAbs2().asDiagonal()))
                .cwiseAbs()
                .maxCoeff(),
            1e-15);
  const Mat3d P =
      attitudeCovariance(c, so3::fromRollPitchYaw(M_PI / 2, 0.0, 0.0), Vec3d(0, 0, 0.3));
  Mat3d expected = Mat3d::Zero();
  expected(1, 1) = 0.09;
  EXPECT_LE((P - expected).cwiseAbs().maxCoeff(), 1e-15);
}

// On a tilted rover, a roll/pitch measurement from gravity leaves the variance about the
// vertical — the heading's — where it was: gravity carries no heading.
TEST(EstInitialAttitude, GravityDoesNotTellTheHeading) {
  const io::RoverConfig c = config();
  InitialState init;
  init.q_site_body = so3::fromRollPitchYaw(0.05, -0.04, 1.0);
  init.attitude_sigma = Vec3d(0.01, 0.01, 0.5);
  Ekf ekf(c, testing::rocky7(), {}, init, true, true);
  const Vec3d up = init.q_site_body.conjugate() * Vec3d::UnitZ();
  const auto headingVariance = [&] {
    return up.dot(ekf.covariance().block<3, 3>(I::kTheta, I::kTheta) * up);
  };
  EXPECT_NEAR(headingVariance(), 0.25, 1e-6);  // (+ roll/pitch σ² × sin² tilt)
  sensors::RollPitchMeasurement m;
  m.roll_pitch = Vec2d(0.05, -0.04);
  m.covariance = Eigen::Matrix2d::Identity() * 1e-8;
  ekf.updateGravity(m);
  EXPECT_NEAR(headingVariance(), 0.25, 1e-6);  // body-diagonal: it fell to (σ_tilt / sin tilt)²
  const Mat3d P = ekf.covariance().block<3, 3>(I::kTheta, I::kTheta);
  EXPECT_LT(P.trace() - headingVariance(), 3e-8);  // roll and pitch now as measured
}

// A log with no sun reading: the heading is the gauge (σ 0 at the start).
TEST(EstInitialAttitude, WithoutASunTheHeadingIsTheGauge) {
  const io::TraverseLog log =
      io::readLog(testing::sourceDir() + "/datasets/logs/wvu-pathfinder-test17run");
  ASSERT_FALSE(log.sun.has_value());
  const Segmentation seg = segment(log);
  const InitialState init = initialState(log, seg);
  EXPECT_EQ(init.attitude_sigma.z(), 0.0);
  EXPECT_GT(init.attitude_sigma.x(), 0.0);
  EXPECT_TRUE(init.roll_pitch_from_gravity);
}

// No sun in the first rest (a dropout over its first 40 s) while the rover turns in place: the
// first valid reading gives the heading at its own time, half a turn or more after the start.
// The gyro's turn since the start is taken off, and the σ grows by the bias's over that time.
// (Before session 22 that heading was taken as the start's: 25° of yaw RMSE on multi-stop with
// a 110 s dropout.)
TEST(EstInitialAttitude, ASunReadingAfterTheStartIsCarriedBackByTheGyro) {
  const std::filesystem::path d = std::filesystem::path(testing::sourceDir()) / "datasets";
  const sim::Simulation s = sim::simulate(
      sim::loadScenario("turn-in-place-360", d, {"faults.sun_dropout.windows=[[0,40]]"}),
      d / "rovers" / "rocky7", 1);
  const Segmentation seg = segment(s.log);
  const InitialState init = initialState(s.log, seg);
  ASSERT_TRUE(init.yaw_from_sun);
  double t_sun = 0;
  for (Eigen::Index k = 0; k < s.log.sun->size(); ++k) {
    if (s.log.sun->values(k, 2) > 0.5) {
      t_sun = s.log.sun->t[k];
      break;
    }
  }
  const eval::TruthTrajectory truth(*s.log.truth);
  const double turned =
      so3::rollPitchYaw(truth.attitude(t_sun)).z() - so3::rollPitchYaw(truth.attitude(init.t)).z();
  ASSERT_GT(std::abs(so3::wrapAngle(turned)), 1.0) << t_sun;  // the rover did turn before it
  const double err = so3::wrapAngle(so3::rollPitchYaw(init.q_site_body).z() -
                                    so3::rollPitchYaw(truth.attitude(init.t)).z());
  // Within a few degrees (the reading is taken with the start's tilt on undulating ground),
  // inside 3σ of the prior the filter starts from.
  EXPECT_LT(std::abs(err), 0.15);  // rad
  EXPECT_LT(std::abs(err), 3 * init.attitude_sigma.z());
  EXPECT_GT(init.attitude_sigma.z(), init.bias_sigma.z() * (t_sun - init.t));
  EXPECT_EQ(init.attitude_prior_sigma.z(), init.attitude_sigma.z());
}

}  // namespace
}  // namespace traverse::est
