// Rest/motion segmentation on a multi-stop traverse (rough terrain, straights, arcs, turns in
// place, a slow turn, drifting bias): classification against the truth, rest windows, at-rest
// measurements.
#include <gtest/gtest.h>

#include "support/jacobian_check.h"
#include "support/rocky7_coords.h"
#include "traverse/estimators/ekf.h"  // chiSquareQuantile
#include "traverse/estimators/segmentation.h"
#include "traverse/sim/simulator.h"

namespace traverse::est {
namespace {

sim::Scenario multiStopLike() {
  const auto data = std::filesystem::path(testing::sourceDir()) / "datasets";
  sim::Scenario sc = sim::loadScenario("multi-stop", data);
  sc.legs.resize(9);  // rest, straight, rest, arc, rest, straight, rest, turn, rest
  sim::Leg slow_turn;
  slow_turn.kind = sim::Leg::Kind::kTurnInPlace;
  slow_turn.angle_rad = 0.3, slow_turn.rate_rad_s = 0.02, slow_turn.ramp_s = 3;  // 1.1 °/s
  sc.legs.push_back(slow_turn);
  sc.legs.push_back(sc.legs[0]);
  return sc;
}

struct Fixture {
  sim::Simulation sim;
  Segmentation seg;
};

const Fixture& fixture() {
  static const Fixture f = [] {
    const auto rover =
        std::filesystem::path(testing::sourceDir()) / "datasets" / "rovers" / "rocky7";
    Fixture x{sim::simulate(multiStopLike(), rover, 5), {}};
    x.seg = segment(x.sim.log);
    return x;
  }();
  return f;
}

/// Truth: the body moves, at the detector's own sensitivity — Nickels' 0.5 °/s transient
/// threshold and the 2 mm/s wheel threshold. (The quintic ramps spend a few tenths of a second
/// below both; a 0.0031 rad/s gyro cannot see 0.1 °/s sample by sample.)
bool trulyMoving(const sim::TruthSample& s) {
  return s.v_body.norm() > 2e-3 || s.w_body.norm() > 0.5 * M_PI / 180;
}

TEST(EstSegmentation, ClassifiesAtLeast99PercentOfSamplesAsTruthSays) {
  const Fixture& f = fixture();
  long agree = 0, total = 0, turning_called_rest = 0;
  for (Eigen::Index k = 0; k < f.seg.gyro_t.size(); ++k) {
    const sim::TruthSample s = sim::interpolateTruth(f.sim.truth, f.seg.gyro_t[k]);
    const bool rest = f.seg.gyro_rest[static_cast<size_t>(k)];
    agree += rest != trulyMoving(s);
    ++total;
    // A turn in place at cruise rate must never be called rest.
    if (std::abs(s.w_body.z()) > 0.01 && s.v_body.norm() < 0.01 && rest) ++turning_called_rest;
  }
  const double pct = 100.0 * agree / total;
  std::cout << "segmentation agrees with truth on " << pct << " % of " << total
            << " gyro samples\n";
  EXPECT_GE(pct, 99.0);
  EXPECT_EQ(turning_called_rest, 0);
}

TEST(EstSegmentation, FindsEveryRestWindow) {
  const Fixture& f = fixture();
  const sim::Scenario sc = multiStopLike();
  int true_rests = 0;
  for (const sim::Leg& l : sc.legs) true_rests += l.kind == sim::Leg::Kind::kRest;
  EXPECT_EQ(static_cast<int>(f.seg.rests.size()), true_rests);
  // Segments alternate and cover the log.
  for (size_t i = 1; i < f.seg.segments.size(); ++i) {
    EXPECT_NE(f.seg.segments[i].kind, f.seg.segments[i - 1].kind);
    EXPECT_DOUBLE_EQ(f.seg.segments[i].t_start, f.seg.segments[i - 1].t_end);
  }
}

// Each rest window's bias and roll/pitch measurements agree with the truth within 3σ (the
// bias drifts, so compare with the true bias at the window's middle).
TEST(EstSegmentation, RestMeasurementsAreConsistentWithTruth) {
  const Fixture& f = fixture();
  int bias_out = 0, grav_out = 0;
  for (const RestWindow& w : f.seg.rests) {
    const sim::TruthSample s = sim::interpolateTruth(f.sim.truth, 0.5 * (w.t_start + w.t_end));
    if (std::abs(w.bias.z() - s.gyro_bias.z()) > 3 * w.bias_sigma.z()) ++bias_out;
    ASSERT_TRUE(w.has_gravity);
    const Vec2d e = w.roll_pitch.roll_pitch - so3::rollPitchYaw(s.q_site_body).head<2>();
    if (e.transpose() * w.roll_pitch.covariance.inverse() * e > 11.8) ++grav_out;  // χ²(2) 99.7 %
    EXPECT_GT(w.drift_sigma.z(), 0.0);
  }
  EXPECT_LE(bias_out, 1) << "of " << f.seg.rests.size();
  EXPECT_LE(grav_out, 1) << "of " << f.seg.rests.size();
}

// Slow starts and stops: legs whose ramps are as long as the leg (no cruise), so each leg
// spends seconds below the transient detector's thresholds at both ends. Rest windows must not
// swallow that motion: the rotation the truth makes inside rest windows stays at the level the
// gyro cannot see, and each window's bias is within 3σ of the true bias.
sim::Scenario slowOnset(bool three_axis) {
  const auto data = std::filesystem::path(testing::sourceDir()) / "datasets";
  sim::Scenario sc = sim::loadScenario("multi-stop", data);
  const sim::Leg rest = sc.legs[0];
  sc.legs.clear();
  for (int i = 0; i < 4; ++i) {
    sc.legs.push_back(rest);
    sim::Leg leg;
    if (i % 2 == 0) {
      leg.kind = sim::Leg::Kind::kTurnInPlace;
      leg.angle_rad = (i == 0 ? 1 : -1) * 0.35, leg.rate_rad_s = 0.06, leg.ramp_s = 8;
    } else {
      leg.kind = sim::Leg::Kind::kStraight;
      leg.distance_m = 0.6, leg.speed_mps = 0.06, leg.ramp_s = 12;
    }
    sc.legs.push_back(leg);
  }
  sc.legs.push_back(rest);
  if (three_axis) sc.sensors.gyro_three_axis = true;
  return sc;
}

TEST(EstSegmentation, SlowStartsAndStopsAreNotSwallowedByRests) {
  const auto rover = std::filesystem::path(testing::sourceDir()) / "datasets" / "rovers" / "rocky7";
  for (const uint64_t seed : {1, 2, 3}) {
    const sim::Simulation sim = sim::simulate(slowOnset(false), rover, seed);
    const Segmentation seg = segment(sim.log);
    const double sg = sim.log.config.gyro.noise_rad_s;
    for (const RestWindow& w : seg.rests) {
      // The true rotation inside the window, against what the gyro can resolve over it.
      double rot = 0, travel = 0;
      long n = 0;
      for (Eigen::Index k = 0; k < seg.gyro_t.size(); ++k) {
        const double t = seg.gyro_t[k];
        if (t < w.t_start || t > w.t_end) continue;
        const sim::TruthSample s = sim::interpolateTruth(sim.truth, t);
        const double dt = k > 0 ? t - seg.gyro_t[k - 1] : 0.0;
        rot += std::abs(s.w_body.z()) * dt, travel += s.v_body.norm() * dt, ++n;
      }
      const double dt = (w.t_end - w.t_start) / std::max<long>(n - 1, 1);
      // 4.5σ of the integrated gyro noise over the window (trim threshold), with margin.
      EXPECT_LE(rot, 6.0 * sg * dt * std::sqrt(static_cast<double>(n)))
          << "seed " << seed << " window " << w.t_start << "–" << w.t_end;
      EXPECT_LE(travel, 0.002) << "seed " << seed << " window " << w.t_start << "–" << w.t_end;
      const sim::TruthSample mid = sim::interpolateTruth(sim.truth, 0.5 * (w.t_start + w.t_end));
      EXPECT_LE(std::abs(w.bias.z() - mid.gyro_bias.z()), 3.5 * w.bias_sigma.z())
          << "seed " << seed << " window " << w.t_start << "–" << w.t_end;
    }
    EXPECT_EQ(seg.rests.size(), 5u) << "seed " << seed;
  }
}

// A creep: the wheels roll at 0.3 mm/s for the first 30 s of the log, then stand still for 15 s
// (a rover inching forward — or an encoder drifting — under the wheel detector's 2 mm/s and with
// no rate the gyro can see). The trim cannot cut it: it trims only edges that border motion, and
// this run borders the log's ends. Without the χ² rest test creep and rest are one rest window;
// with it the creep is refused (and reported) and the rest keeps a window holding at most a
// sliver of the creep.
TEST(EstSegmentation, CreepingIsNeverRest) {
  const auto data = std::filesystem::path(testing::sourceDir()) / "datasets";
  sim::Scenario sc = sim::loadScenario("multi-stop", data);
  sim::Leg rest = sc.legs[0];
  rest.duration_s = 45;
  sc.legs = {rest};
  const double creep_end = 30.0, speed = 3e-4;
  for (const uint64_t seed : {1, 2, 3}) {
    sim::Simulation sim = sim::simulate(sc, data / "rovers" / "rocky7", seed);
    io::Stream& j = sim.log.joints;
    for (Eigen::Index k = 0; k < j.size(); ++k) {
      for (int i = 0; i < r7::kNumWheels; ++i) {
        j.values(k, r7::kPsi1 + i) +=
            speed * std::min(j.t[k] - creep_end, 0.0) / sim.log.geometry.wheels[i].radius;
      }
    }
    const Segmentation seg = segment(sim.log);
    SegmentationOptions untested;
    untested.rest_test_probability = 0;
    const Segmentation before = segment(sim.log, untested);
    ASSERT_EQ(before.rests.size(), 1u);
    EXPECT_LT(before.rests[0].t_start, 1.0) << "the creep was rest without the test";
    ASSERT_EQ(seg.rests.size(), 1u) << "seed " << seed;
    const RestWindow& w = seg.rests[0];
    // At most a second of creep (0.3 mm) inside the window, and at least half the rest kept.
    EXPECT_GE(w.t_start, creep_end - 1.0) << "seed " << seed;
    EXPECT_LE(w.t_start, creep_end + 7.5) << "seed " << seed;
    EXPECT_EQ(w.rest_dof, 7);
    ASSERT_FALSE(seg.refused_rests.empty());
    EXPECT_LT(seg.refused_rests.front().t_start, 1.0);
    EXPECT_GT(seg.refused_rests.front().chi2, seg.refused_rests.front().threshold);
  }
}

// The test refuses no true rest: every window of the multi-stop-like fixture passes it (its
// statistic is below the quantile), and the bundled straight-1m log keeps both its windows.
TEST(EstSegmentation, RestTestKeepsTrueRests) {
  const Fixture& f = fixture();
  EXPECT_TRUE(f.seg.refused_rests.empty());
  const double threshold = chiSquareQuantile(0.9999, 7);
  for (const RestWindow& w : f.seg.rests) {
    EXPECT_EQ(w.rest_dof, 7);  // heading gyro + six wheels
    EXPECT_LE(w.rest_chi2, threshold);
  }
}

}  // namespace
}  // namespace traverse::est
