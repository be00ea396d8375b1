// The inertial noise measured at the rests (estimators/rest_noise.h): none refuted on the bundled
// logs, a gyro and an accelerometer noisier than declared found and used, and the EKF honest again.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "support/bundled.h"
#include "traverse/estimators/rest_noise.h"
#include "traverse/eval/metrics.h"
#include "traverse/pipeline/pipeline.h"

namespace traverse {
namespace {

io::TraverseLog bundled(const std::string& name) {
  return io::readLog(std::filesystem::path(testing::sourceDir()) / "datasets" / "logs" / name);
}

/// The log with white noise of σ `extra` added to every value of the stream.
io::TraverseLog withExtraNoise(io::TraverseLog log, io::Stream& (*stream)(io::TraverseLog&),
                               double extra, uint32_t seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> n(0.0, extra);
  io::Stream& s = stream(log);
  for (Eigen::Index k = 0; k < s.values.size(); ++k) s.values.data()[k] += n(rng);
  return log;
}
io::Stream& gyroOf(io::TraverseLog& l) {
  return l.gyro;
}
io::Stream& accelOf(io::TraverseLog& l) {
  return *l.accel;
}

TEST(EstRestNoise, TheBundledLogsRefuteNoDeclaredNoise) {
  for (const char* name :
       {"straight-1m", "multi-stop", "wvu-pathfinder-s5t1", "wvu-pathfinder-test17run"}) {
    const io::TraverseLog log = bundled(name);
    const auto r = est::restNoise(log);
    EXPECT_TRUE(r.empty()) << name << " " << (r.empty() ? "" : r[0].file + ": " + r[0].message());
  }
}

TEST(EstRestNoise, FindsAGyroAndAnAccelerometerNoisierThanDeclared) {
  const io::TraverseLog clean = bundled("multi-stop");
  const double g0 = clean.config.gyro.noise_rad_s, a0 = clean.config.accel.noise_mps2;
  // Gyro: 0.03 rad/s more (about ten times the declared 0.0031), accelerometer 0.03 m/s² more.
  const io::TraverseLog noisy =
      withExtraNoise(withExtraNoise(clean, gyroOf, 0.03, 1), accelOf, 0.03, 2);
  const std::vector<est::RestNoise> found = est::restNoise(noisy);
  ASSERT_EQ(found.size(), 2u);
  EXPECT_EQ(found[0].file, "gyro.csv");
  EXPECT_EQ(found[0].column, "wz");
  EXPECT_NEAR(found[0].measured, std::hypot(g0, 0.03), 0.1 * std::hypot(g0, 0.03));
  EXPECT_EQ(found[0].declared, g0);
  EXPECT_GT(found[0].samples, 1000);
  EXPECT_EQ(found[1].file, "accel.csv");
  EXPECT_NEAR(found[1].measured, std::hypot(a0, 0.03), 0.1 * std::hypot(a0, 0.03));
  EXPECT_NE(found[0].message().find("is 9."), std::string::npos) << found[0].message();
  const io::TraverseLog used = est::withRestNoise(noisy, found);
  EXPECT_EQ(used.config.gyro.noise_rad_s, found[0].measured);
  EXPECT_EQ(used.config.accel.noise_mps2, found[1].measured);
  // A declared noise larger than the data's is kept.
  io::TraverseLog loud = clean;
  loud.config.gyro.noise_rad_s = 10 * g0;
  EXPECT_TRUE(est::restNoise(loud).empty());
}

TEST(EstRestNoise, TheEkfIsHonestWithTheMeasuredNoise) {
  // A gyro ten times noisier than declared: the rests' rest test and the EKF's gates and weights
  // all assumed the declared σ.
  const io::TraverseLog clean = bundled("multi-stop");
  const io::TraverseLog noisy = withExtraNoise(clean, gyroOf, 0.03, 3);
  const eval::TruthTrajectory truth(*noisy.truth);
  pipeline::PipelineConfig with, without;
  without.measure_rest_noise = false;
  const pipeline::Estimates e = pipeline::estimate(noisy, with);
  ASSERT_EQ(e.noise.size(), 1u);
  const eval::Metrics m = eval::evaluate(e.ekf.trajectory, truth);
  const eval::Metrics m0 = eval::evaluate(pipeline::estimate(noisy, without).ekf.trajectory, truth);
  // Measured (extra noise seed 3): yaw RMSE 0.38° against 2.80°, yaw RMSE/σ 0.98, position NEES
  // 3.6 against 3.1 (until session 27: 0.37° against 3.32°, NEES 4.6 against 4.9; since then the
  // slip rows carry the gyro reading's noise, at the declared σ without the measurement, and the
  // declared-noise filter's position is no longer the worse of the two).
  EXPECT_LT(*m.get("yaw_rmse_deg"), 0.25 * *m0.get("yaw_rmse_deg"));
  EXPECT_GT(*m.get("yaw_rmse_over_sigma"), 0.6);
  EXPECT_LT(*m.get("yaw_rmse_over_sigma"), 1.4);
  EXPECT_LT(*m.get("nees_position_mean"), 6.0);  // 3.61; the clean log's is 1.55
}

}  // namespace
}  // namespace traverse
