// The wheels' unknown rolling radius as a consider parameter (rover.yaml
// odometry.wheel_radius_scale_sigma / _side_sigma; issue 14, σ honesty on real logs): no
// estimator estimates it (it is not observable without an absolute reference of speed), every
// position covariance carries it (est::addOdometryScaleCovariance). Checked here: the keys (read,
// written back, refused out of range), each wheel's side, the variance of the mean wheel speed's
// scale, the covariance term by hand, and on a simulated skid-steer traverse whose wheels roll
// on radii 4 % and 2 % larger than the URDF's: without the keys the final position error is far
// outside every estimator's σ, with them inside, and no estimate moves.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

#include "support/jacobian_check.h"
#include "traverse/core/error.h"
#include "traverse/estimators/trajectory.h"
#include "traverse/io/rover_config.h"
#include "traverse/io/rover_description.h"
#include "traverse/pipeline/pipeline.h"
#include "traverse/sim/scenario.h"
#include "traverse/sim/simulator.h"

namespace traverse {
namespace {

const std::filesystem::path kDatasets = testing::sourceDir() + "/datasets";

TEST(OdometryScale, KeysAreReadWrittenBackAndRangeChecked) {
  const io::RoverConfig base = io::loadRoverConfig(kDatasets / "rovers/pathfinder/rover.yaml");
  const std::filesystem::path dir =
      std::filesystem::temp_directory_path() / "traverse_odometry_scale_keys";
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  io::RoverConfig c = base;
  c.odometry.wheel_radius_scale_sigma = 0.05;
  c.odometry.wheel_radius_scale_side_sigma = 0.02;
  EXPECT_TRUE(c.odometry.hasScaleUncertainty());
  EXPECT_FALSE(c.odometry.isDefault());
  io::saveRoverConfig(dir / "rover.yaml", c);
  const io::RoverConfig back = io::loadRoverConfig(dir / "rover.yaml");
  EXPECT_DOUBLE_EQ(back.odometry.wheel_radius_scale_sigma, 0.05);
  EXPECT_DOUBLE_EQ(back.odometry.wheel_radius_scale_side_sigma, 0.02);
  EXPECT_DOUBLE_EQ(back.odometry.wheel_radius_scale_left, 1.0);
  // Absent: zero, and a file without them is written without them.
  io::RoverConfig none = base;
  none.odometry = io::OdometryConfig{};
  io::saveRoverConfig(dir / "none.yaml", none);
  std::ifstream f(dir / "none.yaml");
  const std::string text((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
  EXPECT_EQ(text.find("wheel_radius_scale"), std::string::npos);
  // Out of range: one line naming the file and the key.
  std::ofstream(dir / "bad.yaml") << "format: 1\nodometry:\n  wheel_radius_scale_sigma: -0.1\n";
  try {
    io::loadRoverConfig(dir / "bad.yaml");
    FAIL() << "a negative sigma was accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("wheel_radius_scale_sigma"), std::string::npos)
        << e.what();
    EXPECT_EQ(e.line(), 3);
  }
  std::filesystem::remove_all(dir);
}

TEST(OdometryScale, WheelSidesAndTheMeanSpeedsVariance) {
  const io::RoverConfig cfg = io::loadRoverConfig(kDatasets / "rovers/pathfinder/rover.yaml");
  const rover::RoverGeometry geo =
      io::loadRoverGeometry(kDatasets / "rovers/pathfinder/rover.urdf", cfg);
  ASSERT_EQ(geo.numWheels(), 4);
  int left = 0;
  for (const rover::Wheel& w : geo.wheels) {
    EXPECT_TRUE(w.left_share == 0.0 || w.left_share == 1.0);
    left += w.left_share == 1.0;
  }
  EXPECT_EQ(left, 2);
  io::OdometryConfig o;
  o.wheel_radius_scale_sigma = 0.03;
  o.wheel_radius_scale_side_sigma = 0.02;
  // Symmetric: σ_c² + σ_s²/2 = 9e-4 + 2e-4; all on one side: σ_c² + σ_s².
  EXPECT_NEAR(o.meanScaleVariance(0.5), 1.1e-3, 1e-15);
  EXPECT_NEAR(o.meanScaleVariance(1.0), 1.3e-3, 1e-15);
}

TEST(OdometryScale, ConsiderCovarianceByHand) {
  est::Trajectory tr;
  tr.has_covariance = true;
  tr.nodes.resize(2);
  tr.nodes[0].p_site = Vec3d(1, 1, 0);
  tr.nodes[1].p_site = Vec3d(4, 5, 0);  // 3, 4, 0 from the start
  for (auto& n : tr.nodes) n.covariance = 1e-4 * Mat6d::Identity();
  est::addOdometryScaleCovariance(&tr, 0.0025);
  EXPECT_TRUE(tr.nodes[0].covariance.isApprox(1e-4 * Mat6d::Identity()));
  Mat6d expected = 1e-4 * Mat6d::Identity();
  expected.topLeftCorner<2, 2>() += 0.0025 * (Eigen::Matrix2d() << 9, 12, 12, 16).finished();
  EXPECT_TRUE(tr.nodes[1].covariance.isApprox(expected)) << tr.nodes[1].covariance;
  est::Trajectory no_cov = tr;
  no_cov.has_covariance = false;
  est::addOdometryScaleCovariance(&no_cov, 0.5);
  EXPECT_EQ(no_cov.nodes[1].covariance, tr.nodes[1].covariance);
}

// A constant IMU-to-wheels misalignment, by hand: a level drive along x at 0.5 m/s for 10 s
// (nodes every 0.1 s) gains pitch σ × 5 m of height σ and yaw σ × 5 m of cross-track σ, nothing
// along the track; then a turn to +y for 4 s more: the cross-track of the first leg (y) and of
// the second (x) are one yaw error's, and the height's is over the whole 7 m.
TEST(OdometryScale, MountingConsiderCovarianceByHand) {
  est::Trajectory tr;
  tr.has_covariance = true;
  for (int k = 0; k <= 140; ++k) {
    est::TrajectoryNode n;
    n.t = 0.1 * k;
    n.v_body = Vec3d(0.5, 0, 0);
    n.q_site_body =
        k < 100 ? Quatd::Identity() : Quatd(Eigen::AngleAxisd(std::acos(-1.0) / 2, Vec3d::UnitZ()));
    tr.nodes.push_back(n);
  }
  est::addMountingCovariance(&tr, 0.01);
  const Mat3d P10 = tr.nodes[100].covariance.topLeftCorner<3, 3>();
  EXPECT_NEAR(P10(0, 0), 0.0, 1e-15);
  EXPECT_NEAR(P10(1, 1), std::pow(0.01 * 5.0, 2), 1e-12);
  EXPECT_NEAR(P10(2, 2), std::pow(0.01 * 5.0, 2), 1e-12);
  const Mat3d P14 = tr.nodes[140].covariance.topLeftCorner<3, 3>();
  // Yaw δ moves the first leg's end by 5δ along y and the second leg's by −2δ along x.
  EXPECT_NEAR(P14(0, 0), std::pow(0.01 * 2.0, 2), 1e-12);
  EXPECT_NEAR(P14(1, 1), std::pow(0.01 * 5.0, 2), 1e-12);
  EXPECT_NEAR(P14(0, 1), -0.01 * 0.01 * 2.0 * 5.0, 1e-12);
  // Height: pitch δ (about body y) lowers the nose on either leg, δ e_y × v = −0.5 δ e_z, over
  // the whole 7 m; roll does nothing to a velocity along body x.
  EXPECT_NEAR(P14(2, 2), std::pow(0.01 * 7.0, 2), 1e-12);
  est::addMountingCovariance(&tr, 0.0);  // no-op
  const Mat3d P14_again = tr.nodes[140].covariance.topLeftCorner<3, 3>();
  EXPECT_EQ(P14_again, P14);
}

TEST(OdometryScale, SimulatedRadiusErrorIsCoveredByEveryEstimatorsSigma) {
  const sim::Scenario sc = sim::loadScenario("planar-18m", kDatasets, {"rover=pathfinder"});
  const sim::Simulation sim = sim::simulate(sc, sim::roverDirectory(sc, kDatasets), 3);
  io::TraverseLog log = sim.log;
  for (rover::Wheel& w : log.geometry.wheels) w.radius /= w.left_share > 0.5 ? 1.04 : 1.02;
  const Vec3d end = sim.truth.back().p_site - sim.truth.front().p_site;
  const auto nees = [&](const est::Trajectory& tr) {
    const Mat3d P = tr.nodes.back().covariance.topLeftCorner<3, 3>();
    const Vec3d err = tr.nodes.back().p_site - end;
    return err.dot(P.ldlt().solve(err));
  };
  pipeline::PipelineConfig config;
  config.smooth = true;
  config.ekf.rts = true;
  config.ekf.velocity = est::EkfOptions::VelocityModel::kPerturbation;  // speed from the wheels
  log.config.odometry.wheel_radius_scale_sigma = 0.0;  // (Pathfinder's rover.yaml declares it)
  log.config.odometry.wheel_radius_scale_side_sigma = 0.0;
  const pipeline::Estimates before = pipeline::estimate(log, config);
  EXPECT_EQ(before.odometry_scale_variance, 0.0);
  ASSERT_TRUE(before.smoothed && before.ekf.rts);
  for (const est::Trajectory* tr :
       {&before.ekf.trajectory, &*before.ekf.rts, &before.smoothed->trajectory})
    EXPECT_GT(nees(*tr), 16.0) << tr->name;
  log.config.odometry.wheel_radius_scale_sigma = 0.05;
  log.config.odometry.wheel_radius_scale_side_sigma = 0.02;
  const pipeline::Estimates after = pipeline::estimate(log, config);
  EXPECT_NEAR(after.odometry_scale_variance, 0.05 * 0.05 + 0.5 * 0.02 * 0.02, 1e-15);
  ASSERT_TRUE(after.smoothed && after.ekf.rts);
  for (const est::Trajectory* tr :
       {&after.ekf.trajectory, &*after.ekf.rts, &after.smoothed->trajectory}) {
    EXPECT_LT(nees(*tr), 16.0) << tr->name;
  }
  // A consider parameter: the estimates themselves are what they were.
  EXPECT_EQ(after.ekf.trajectory.nodes.back().p_site, before.ekf.trajectory.nodes.back().p_site);
  EXPECT_EQ(after.smoothed->trajectory.nodes.back().p_site,
            before.smoothed->trajectory.nodes.back().p_site);
}

}  // namespace
}  // namespace traverse
