// A rover none of the shipped ones resembles (tests/data/rovers/eight-wheel: eight wheels, a
// rocker and two bogies per side, every wheel steered, Mars gravity, the accelerometer off the
// body origin): its URDF and rover.yaml are all traverse needs, from the simulator to the three
// estimators. It is also where the gyro-driven EKF's slip rows were found to leave the gyro
// reading's noise out (docs/results.md, session 27): with its 0.8 m track the EKF sank 12 mm per
// metre on flat ground, position RMSE/σ 2.5.
#include <gtest/gtest.h>

#include <filesystem>
#include <string>

#include "support/jacobian_check.h"
#include "traverse/eval/metrics.h"
#include "traverse/eval/truth.h"
#include "traverse/pipeline/pipeline.h"
#include "traverse/sim/scenario.h"
#include "traverse/sim/simulator.h"

namespace traverse {
namespace {

TEST(RoverEightWheel, SimulatedAndEstimatedFromItsUrdfAlone) {
  const std::filesystem::path datasets = testing::sourceDir() + "/datasets";
  const std::string dir = testing::sourceDir() + "/tests/data/rovers/eight-wheel";
  const sim::Scenario sc = sim::loadScenario(dir + "/scenario.yaml", datasets, {"rover=" + dir});
  const sim::Simulation sim = sim::simulate(sc, sim::roverDirectory(sc, datasets), 1);
  ASSERT_EQ(sim.log.joints.columns.size(), 21u);  // 5 suspension, 8 steering, 8 drive
  ASSERT_TRUE(sim.log.truth);
  EXPECT_TRUE(sim.log.truth->has("xi8"));
  pipeline::PipelineConfig config;
  config.smooth = true;
  const pipeline::Estimates e = pipeline::estimate(sim.log, config);
  ASSERT_TRUE(e.smoothed);
  for (const auto& s : e.smoothed->segments)
    EXPECT_NE(s.status, smoother::SegmentStatus::kFallbackEkf) << "segment " << s.index;
  EXPECT_EQ(e.ekf.trajectory.nodes.back().xi.size(), 8);
  EXPECT_EQ(e.ekf.stats.slip_rejected, 0);

  const eval::TruthTrajectory truth(*sim.log.truth);
  const eval::Metrics dr = eval::evaluate(e.dr, truth);
  const eval::Metrics ekf = eval::evaluate(e.ekf.trajectory, truth);
  const eval::Metrics sm = eval::evaluate(e.smoothed->trajectory, truth);
  // Seed 1 (6 m of legs): DR 21 mm position RMSE, EKF 4.8 mm (RMSE/σ 0.31, 4.7 mm high at the
  // end), smoother 1.9 mm (0.12, 3.4 mm).
  EXPECT_LT(*ekf.get("position_rmse_m"), 0.5 * *dr.get("position_rmse_m"));
  EXPECT_LT(*sm.get("position_rmse_m"), 0.5 * *dr.get("position_rmse_m"));
  for (const eval::Metrics* m : {&ekf, &sm}) {
    EXPECT_LT(*m->get("final_vertical_error_m"), 0.015);  // 2.5 mm/m; the defect gave 12
    EXPECT_LT(*m->get("position_rmse_over_sigma"), 1.25);
    EXPECT_LT(*m->get("yaw_rmse_over_sigma"), 1.25);
  }
}

}  // namespace
}  // namespace traverse
