// The wheels' yaw rate against the gyro's (estimators/slip_correlation.h): white slip refuted
// only where the wheels' differential slip is correlated in time, a turn-proportional error (a
// track or ICR error) fitted out rather than taken for slip, and the measured σ carried as the
// common yaw slip c_ω.
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

#include "support/bundled.h"
#include "traverse/estimators/segmentation.h"
#include "traverse/estimators/slip_correlation.h"
#include "traverse/io/log_reader.h"

namespace traverse {
namespace {

io::TraverseLog bundled(const std::string& name) {
  return io::readLog(std::filesystem::path(testing::sourceDir()) / "datasets" / "logs" / name);
}

/// The log with every left wheel's (body y > 0) drive angle advanced, while the rover moves, at
/// the rolling speed rate(t) (m/s) / r: the left wheels slip by rate(t) relative to the right.
template <typename Rate>
io::TraverseLog withLeftWheelsSlipping(io::TraverseLog log, const est::Segmentation& seg,
                                       Rate rate) {
  io::Stream& j = log.joints;
  double offset_m = 0.0;  // accumulated extra rolling of the left wheels
  for (Eigen::Index k = 1; k < j.size(); ++k) {
    if (!seg.atRest(j.t[k])) offset_m += rate(j.t[k], k) * (j.t[k] - j.t[k - 1]);
    for (const rover::Wheel& w : log.geometry.wheels) {
      if (w.left_share > 0.5) j.values(k, w.coord) += offset_m / w.radius;
    }
  }
  return log;
}

TEST(EstSlipCorrelation, TheBundledLogsShowNoCorrelatedSlip) {
  for (const char* name :
       {"straight-1m", "multi-stop", "wvu-pathfinder-s5t1", "wvu-pathfinder-test17run"}) {
    const io::TraverseLog log = bundled(name);
    const est::SlipCorrelation c = est::wheelYawRateCheck(log, est::segment(log));
    EXPECT_FALSE(c.refuted) << name << ": " << c.message();
  }
  const io::TraverseLog log = bundled("multi-stop");
  const est::SlipCorrelation c = est::wheelYawRateCheck(log, est::segment(log));
  EXPECT_GE(c.windows, 20);
  EXPECT_EQ(c.dof, c.windows - 2);
  EXPECT_LT(c.chi2, 2.0 * c.dof);
  EXPECT_GT(c.samples, 1000);
}

// A 15 s gap in gyro.csv while the rover drives: the joint samples inside it have no gyro rate
// (interpolated across the gap, a turn would read as the wheels departing from the gyro), so
// they are left out and nothing is refuted.
TEST(EstSlipCorrelation, AGyroGapIsNotTakenForSlip) {
  io::TraverseLog log = bundled("multi-stop");
  const est::Segmentation seg = est::segment(log);
  double t0 = 0.0;  // 15 s inside the longest motion segment
  double longest = 0.0;
  for (const est::Segment& s : seg.segments) {
    if (s.kind == est::Segment::Kind::kMotion && s.t_end - s.t_start > longest)
      longest = s.t_end - s.t_start, t0 = s.t_start + 0.5 * (s.t_end - s.t_start - 15.0);
  }
  ASSERT_GT(longest, 20.0);
  io::Stream& g = log.gyro;
  std::vector<Eigen::Index> keep;
  for (Eigen::Index k = 0; k < g.size(); ++k)
    if (g.t[k] < t0 || g.t[k] > t0 + 15.0) keep.push_back(k);
  ASSERT_LT(static_cast<Eigen::Index>(keep.size()), g.size());
  io::Stream cut;
  cut.columns = g.columns;
  cut.t.resize(static_cast<Eigen::Index>(keep.size()));
  cut.values.resize(cut.t.size(), g.values.cols());
  for (Eigen::Index i = 0; i < cut.t.size(); ++i)
    cut.t[i] = g.t[keep[static_cast<size_t>(i)]],
    cut.values.row(i) = g.values.row(keep[static_cast<size_t>(i)]);
  g = cut;
  const est::SlipCorrelation c = est::wheelYawRateCheck(log, seg);
  EXPECT_FALSE(c.refuted) << c.message();
  const est::SlipCorrelation whole = est::wheelYawRateCheck(bundled("multi-stop"), seg);
  EXPECT_LT(c.samples, whole.samples - 100);  // the samples inside the gap were left out
}

// The left wheels slip by 20 mm/s × sin(2π t / 20 s) relative to the right: six wheels at
// y = ±0.24 m read a yaw rate off by up to ≈ 0.02 / 0.48 = 0.042 rad/s, slowly: 5 s means of
// RMS ≈ 0.042 · 0.71 · 0.9 = 0.027 rad/s, where multi-stop's declared white slip (its simulator's,
// larger than Rocky-7's) allows 0.0065. Refuted, with c_ω's σ of that order
// (√((0.027² − 0.0065²) / 0.74) ≈ 0.03 for τ = 5 s); the log then carries c_ω at that σ.
TEST(EstSlipCorrelation, FindsSlowDifferentialSlipAndCarriesIt) {
  const io::TraverseLog clean = bundled("multi-stop");
  const est::Segmentation seg = est::segment(clean);
  const io::TraverseLog slipping = withLeftWheelsSlipping(clean, seg, [](double t, Eigen::Index) {
    return 0.02 * std::sin(2.0 * std::numbers::pi * t / 20.0);
  });
  const est::SlipCorrelation c = est::wheelYawRateCheck(slipping, est::segment(slipping));
  ASSERT_TRUE(c.refuted) << c.message();
  EXPECT_GT(c.chi2, 10.0 * c.dof);
  EXPECT_GT(c.sigma_yaw_rate, 0.015);
  EXPECT_LT(c.sigma_yaw_rate, 0.06);
  EXPECT_GT(c.rms_residual, 3.0 * c.rms_predicted);
  EXPECT_NE(c.message().find("correlated in time"), std::string::npos) << c.message();
  const io::TraverseLog carried = est::withCommonYawSlip(slipping, c);
  EXPECT_EQ(carried.config.slip_noise.common_yaw_rate_rad_s, c.sigma_yaw_rate);
  EXPECT_EQ(carried.config.slip_noise.commonSlipStates(), 3);
  // multi-stop declares c_x, c_y: kept as declared.
  EXPECT_EQ(carried.config.slip_noise.common_longitudinal_mps,
            clean.config.slip_noise.common_longitudinal_mps);
  // Without a declared common slip, c_x and c_y get the mean of six independent wheel slips
  // of σ_u = σ_ω √(Σ y_i²): six wheels at y = ±0.24 m, Σ y_i² = 0.3456 m².
  EXPECT_NEAR(c.wheel_lever_m2, 0.3456, 0.02);
  io::TraverseLog bare = slipping;
  bare.config.slip_noise.common_longitudinal_mps = bare.config.slip_noise.common_lateral_mps = 0.0;
  const io::TraverseLog bare_carried = est::withCommonYawSlip(bare, c);
  const double mean = c.sigma_yaw_rate * std::sqrt(c.wheel_lever_m2) / std::sqrt(6.0);
  EXPECT_NEAR(bare_carried.config.slip_noise.common_longitudinal_mps, mean, 1e-15);
  EXPECT_NEAR(bare_carried.config.slip_noise.common_lateral_mps, mean, 1e-15);
  EXPECT_EQ(bare_carried.config.slip_noise.commonSlipStates(), 3);
}

// A yaw-rate error proportional to the turn — the left wheels rolling ω_z · 0.48 m too far, so
// the wheels read every turn at twice its rate, as a track or ICR far off would — is a scale,
// not slip: the fit takes it out and nothing is refuted. (Without the proportional column the
// same log is refuted: χ² 793 for 109 dof, the window means moving with every turn.)
TEST(EstSlipCorrelation, ATurnProportionalErrorIsNotTakenForSlip) {
  const io::TraverseLog clean = bundled("multi-stop");
  const est::Segmentation seg = est::segment(clean);
  const io::Stream& g = clean.gyro;
  const int gz = g.col("wz");
  const double b = seg.rests.front().bias.z();
  const io::TraverseLog scaled = withLeftWheelsSlipping(clean, seg, [&](double t, Eigen::Index) {
    return 1.0 * 0.48 * (io::interpolateRow(g, t)[gz] - b);
  });
  const est::SlipCorrelation c = est::wheelYawRateCheck(scaled, est::segment(scaled));
  EXPECT_FALSE(c.refuted) << c.message();
  EXPECT_LT(c.chi2, 2.0 * c.dof);
}

}  // namespace
}  // namespace traverse
