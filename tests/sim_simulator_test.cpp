// Simulator: kinematic consistency of the truth (the slip constraint evaluated on it), sensor
// noise statistics, the straight-1m odometry figure, determinism, scenario files.
#include <fstream>
#include <sstream>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "support/jacobian_check.h"
#include "support/rocky7_coords.h"
#include "traverse/core/error.h"
#include "traverse/io/log_writer.h"
#include "traverse/io/rover_description.h"
#include "traverse/rover/nominal_slip.h"
#include "traverse/sim/simulator.h"

namespace traverse::sim {
namespace {

using r7::kNumWheels;

std::filesystem::path datasets() {
  return std::filesystem::path(testing::sourceDir()) / "datasets";
}
std::filesystem::path rocky7Dir() {
  return datasets() / "rovers" / "rocky7";
}

const rover::RoverGeometry& rocky7() {
  static const rover::RoverGeometry geo = [] {
    const auto c = io::loadRoverConfig(rocky7Dir() / "rover.yaml");
    return io::loadRoverGeometry(rocky7Dir() / "rover.urdf", c);
  }();
  return geo;
}

/// A noise-free scenario: no slip, no sensor noise.
Scenario quiet(const std::string& terrain, std::vector<Leg> legs) {
  Scenario sc;
  sc.name = "test";
  sc.terrain.type = terrain;
  sc.terrain.slope_rad = 0.12, sc.terrain.direction_rad = 0.5;
  sc.terrain.step_x_m = 0.4;
  sc.terrain.rms_height_m = 0.02;
  sc.legs = std::move(legs);
  sc.sensors.gyro_noise_rad_s = 0, sc.sensors.sun_noise = 0, sc.sensors.accel_noise_mps2 = 0;
  sc.start = Vec3d(-0.1, 0.0, 0.0);
  return sc;
}

Leg rest(double s) {
  return Leg{Leg::Kind::kRest, s};
}
Leg straight(double d) {
  Leg l{Leg::Kind::kStraight};
  l.distance_m = d, l.speed_mps = 0.05, l.ramp_s = 1.0;
  return l;
}
Leg arc(double d, double r) {
  Leg l = straight(d);
  l.kind = Leg::Kind::kArc, l.radius_m = r;
  return l;
}
Leg turn(double a) {
  Leg l{Leg::Kind::kTurnInPlace};
  l.angle_rad = a, l.rate_rad_s = 0.1, l.ramp_s = 1.0;
  return l;
}

/// Slip constraint on the truth minus the nominal slip of K §2.3.4, per row, worst and RMS over
/// the moving samples. The nominal slip is computed from the commanded planar motion (what an
/// estimator knows), or with `true_twist` from the true body twist (exact for planar ground).
struct SlipStats {
  Vec4d max_abs = Vec4d::Zero(), rms = Vec4d::Zero();
};
SlipStats slipOnTruth(const Simulation& sim, bool true_twist = false) {
  SlipStats st;
  long n = 0;
  for (const TruthSample& s : sim.truth) {
    if (!s.moving) continue;
    const auto kin = rover::forwardKinematics<double>(rocky7(), s.joints);
    Twistd nominal = rover::nominalBodyTwist(rocky7(), s.cmd[0], s.cmd[5]);
    if (true_twist) nominal << s.v_body, s.w_body;
    for (int i = 0; i < kNumWheels; ++i) {
      const Twistd jt = rover::wheelJointTwist(kin[i], s.joint_rates);
      const double r = rocky7().wheels[i].radius;
      const Vec4d t =
          rover::slipConstraint<double>(kin[i].T_body_wheel, r, jt, s.v_body, s.w_body, s.xi[i]);
      const Vec4d d = t - rover::nominalSlip(kin[i].T_body_wheel, r, nominal, jt);
      st.max_abs = st.max_abs.cwiseMax(d.cwiseAbs());
      st.rms += d.cwiseAbs2();
      ++n;
    }
  }
  st.rms = (st.rms / std::max<long>(n, 1)).cwiseSqrt();
  return st;
}

// On flat ground and on a tilted plane, with no slip injected, the truth satisfies K-17 exactly
// up to the simulator's finite differences: zero for straight motion, the nominal slip of
// K §2.3.4 for arcs and turns in place. On flat ground the nominal slip from the commanded
// motion is exact; on a slope the paper's flat-ground approximation is off by the tilt (the
// yaw rate projects onto the body axes), so there it is computed from the true body twist.
TEST(SimSlipOnTruth, ZeroOnPlanarTerrainsForEveryPathType) {
  for (const char* terrain : {"flat", "plane"}) {
    const Simulation sim = simulate(quiet(terrain, {rest(1), straight(0.5), rest(1), arc(0.6, 1.5),
                                                    rest(1), turn(0.8), rest(1)}),
                                    rocky7Dir(), 1);
    const SlipStats st = slipOnTruth(sim, std::string(terrain) == "plane");
    EXPECT_LT(st.max_abs.head<3>().maxCoeff(), 2e-5) << terrain << ": " << st.max_abs.transpose();
    EXPECT_LT(st.max_abs[3], 2e-4) << terrain << ": " << st.max_abs.transpose();
  }
}

// On curved terrain the rolling row is zero by construction; the normal row is zero only when the
// wheel plane contains the surface normal — with camber on 3-D terrain the thin-wheel contact
// frame's z leaves the true normal, so it stays below 1 mm/s RMS rather than at the numerical
// level. Transverse slip and spin are the terrain-curvature slip the paper describes (K §2.3.4):
// small but not zero, reported (docs/simulator.md) and bounded.
TEST(SimSlipOnTruth, CurvedTerrainsKeepRollingAndContact) {
  for (const char* terrain : {"undulating", "step", "rough"}) {
    const Simulation sim = simulate(
        quiet(terrain, {rest(1), straight(1.0), rest(1), turn(0.5), rest(1)}), rocky7Dir(), 1);
    const SlipStats st = slipOnTruth(sim);
    std::cout << terrain << ": slip on truth, RMS per row (x, y, z m/s; spin rad/s) "
              << st.rms.transpose() << "\n";
    EXPECT_LT(st.max_abs[0], 1e-9) << terrain;
    EXPECT_LT(st.rms[2], 1e-3) << terrain << " rms " << st.rms.transpose();
    EXPECT_LT(st.rms[1], 5e-3) << terrain << " rms " << st.rms.transpose();
  }
}

double sampleSigma(const Eigen::VectorXd& x) {
  return std::sqrt((x.array() - x.mean()).square().sum() / (x.size() - 1));
}

// Sensor noise matches its configuration: sample σ within 5 % (rover at rest, so the noise is
// the reading minus its mean).
TEST(SimSensors, NoiseStatisticsMatchConfiguration) {
  Scenario sc = quiet("flat", {rest(400)});
  sc.sensors.gyro_noise_rad_s = 0.003;
  sc.sensors.gyro_three_axis = true;
  sc.sensors.sun_noise = 0.004, sc.sensors.sun_rate_hz = 10;
  sc.sensors.accel_noise_mps2 = 0.02;
  sc.sensors.joint_angle_noise_rad = 0.001, sc.sensors.steering_noise_rad = 0.002,
  sc.sensors.wheel_angle_noise_rad = 0.0005;
  const Simulation sim = simulate(sc, rocky7Dir(), 3);
  for (int c = 0; c < 3; ++c)
    EXPECT_NEAR(sampleSigma(sim.log.gyro.values.col(c)) / 0.003, 1.0, 0.05);
  for (int c = 0; c < 2; ++c)
    EXPECT_NEAR(sampleSigma(sim.log.sun->values.col(c)) / 0.004, 1.0, 0.05);
  for (int c = 0; c < 3; ++c)
    EXPECT_NEAR(sampleSigma(sim.log.accel->values.col(c)) / 0.02, 1.0, 0.05);
  EXPECT_NEAR(sampleSigma(sim.log.joints.values.col(r7::kGamma1)) / 0.001, 1.0, 0.05);
  EXPECT_NEAR(sampleSigma(sim.log.joints.values.col(r7::kLambda2)) / 0.002, 1.0, 0.05);
  EXPECT_NEAR(sampleSigma(sim.log.joints.values.col(r7::kPsi5)) / 0.0005, 1.0, 0.05);
  // Gyro mean = configured bias.
  EXPECT_NEAR(sim.log.gyro.values.col(2).mean(), 0.002, 4 * 0.003 / std::sqrt(sim.log.gyro.size()));
}

// The log's rover.yaml states the slip that was injected (configureLog): what the wheels share
// as the common slip c, what each has alone as white row noise, each at the power it has on
// average over the motion (slip is injected times the leg's progress |speed| / cruise: a
// smooth-profile leg, progress 16u²(1 − u)², has mean progress² 256 B(5, 5) = 0.40635).
// Hand-checked at cruise power for six wheels at 10 Hz, τ = 5 s: per-wheel Gauss–Markov
// σ = 3 mm/s splits into a shared mean (σ²/6 = 1.5e-6) and deviations stated white,
// 2 σ² (5/6) τ f = 7.5e-4; bursts of 2 cm/s for 2 s at 0.05 per m at 0.05 m/s (p = 0.005) have
// low-frequency power 2 p A² D = 8e-6 = 2 σ_b² τ, so σ_b² = 8e-7; c_y² is the lateral σ².
// Without lateral correlated slip no c is declared and the shared parts stay in the white rows
// (as before c existed).
TEST(SimSensors, SlipNoiseStatesWhatWasInjected) {
  const auto base = io::loadRoverConfig(rocky7Dir() / "rover.yaml").slip_noise;
  Leg leg = straight(0.2);
  leg.profile = Leg::Profile::kSmooth;
  Scenario sc = quiet("flat", {rest(1), leg, rest(1)});
  sc.sensors.joints_rate_hz = 10;
  sc.slip.longitudinal_white_mps = 0.003;
  sc.slip.longitudinal_correlated_mps = 0.003;
  sc.slip.lateral_correlated_mps = 0.002;
  sc.slip.correlation_time_s = 5;
  sc.slip.burst_rate_per_m = 0.05, sc.slip.burst_duration_s = 2, sc.slip.burst_mps = -0.02;
  const Simulation sim = simulate(sc, rocky7Dir(), 1);
  double p2 = 0.0;
  int moving = 0;
  for (const TruthSample& x : sim.truth) {
    if (x.moving) p2 += x.progress * x.progress, ++moving;
  }
  p2 /= moving;
  EXPECT_NEAR(p2, 256.0 * 576.0 / 362880.0, 2e-3);
  const rover::SlipNoise& sn = sim.log.config.slip_noise;
  ASSERT_EQ(kNumWheels, 6);
  EXPECT_NEAR(sn.common_longitudinal_mps, std::sqrt(p2 * (1.5e-6 + 8e-7)), 1e-12);
  EXPECT_NEAR(sn.common_lateral_mps, std::sqrt(p2) * 0.002, 1e-12);
  EXPECT_EQ(sn.common_time_constant_s, 5.0);
  EXPECT_NEAR(sn.longitudinal_mps,
              std::sqrt(std::pow(base.longitudinal_mps, 2) + p2 * (9e-6 + 7.5e-4)), 1e-12);
  EXPECT_NEAR(sn.lateral_mps, base.lateral_mps, 1e-12);

  sc.slip.lateral_correlated_mps = 0.0;  // nothing shared on both axes: no c
  const rover::SlipNoise white = simulate(sc, rocky7Dir(), 1).log.config.slip_noise;
  EXPECT_FALSE(white.hasCommonSlip());
  EXPECT_NEAR(white.longitudinal_mps,
              std::sqrt(std::pow(base.longitudinal_mps, 2) + p2 * (9e-6 + 9e-4 + 10 * 8e-6)),
              1e-12);
  EXPECT_NEAR(white.lateral_mps, base.lateral_mps, 1e-12);
}

// Bias random walk: over many independent axes-runs the bias change after T seconds has
// σ = q √T; the sample σ of 60 increments must lie within the 99 % range of its distribution.
TEST(SimSensors, BiasRandomWalkHasExpectedSpread) {
  Scenario sc = quiet("flat", {rest(100)});
  sc.sensors.gyro_bias_random_walk_rad_s_per_sqrt_s = 1e-4;
  std::vector<double> d;
  for (uint64_t seed = 1; seed <= 20; ++seed) {
    const Simulation sim = simulate(sc, rocky7Dir(), seed);
    const Vec3d change = sim.truth.back().gyro_bias - sim.truth.front().gyro_bias;
    d.insert(d.end(), {change.x(), change.y(), change.z()});
  }
  const Eigen::Map<Eigen::VectorXd> v(d.data(), static_cast<Eigen::Index>(d.size()));
  const double expected = 1e-4 * std::sqrt(100.0);
  const double ratio = std::sqrt(v.squaredNorm() / v.size()) / expected;
  EXPECT_GT(ratio, 0.75);  // chi-square(60) 99 % interval of sqrt(χ²/60): [0.76, 1.27]
  EXPECT_LT(ratio, 1.27);
}

// straight-1m through averaged-wheel odometry: the paper reports 2.04 % (1.0204 m for 1 m).
// Our K-22 terrain gives a smaller figure (docs/simulator.md explains); assert the order.
TEST(SimScenarios, Straight1mOdometryErrorIsOfThePapersOrder) {
  const Scenario sc = loadScenario("straight-1m", datasets());
  const Simulation sim = simulate(sc, rocky7Dir(), 1);
  const auto& j = sim.log.joints.values;
  const double wheels =
      (j.bottomRows<1>().rightCols<6>() - j.topRows<1>().rightCols<6>()).mean() * 0.065;
  const double truth = (sim.truth.back().p_site - sim.truth.front().p_site).head<2>().norm();
  const double error_pct = 100.0 * (wheels - truth) / truth;
  RecordProperty("straight_1m_dr_error_pct", std::to_string(error_pct));
  std::cout << "straight-1m averaged-wheel distance " << wheels << " m for " << truth
            << " m: " << error_pct << " %\n";
  EXPECT_GT(error_pct, 0.1);
  EXPECT_LT(error_pct, 5.0);
}

std::string slurp(const std::filesystem::path& p) {
  std::ifstream f(p, std::ios::binary);
  std::stringstream ss;
  ss << f.rdbuf();
  return ss.str();
}

TEST(SimScenarios, SameSeedGivesByteIdenticalLogs) {
  const auto base = std::filesystem::temp_directory_path() / "traverse_sim_determinism";
  std::filesystem::remove_all(base);
  const Scenario sc = loadScenario("obstacle", datasets(), {"path.1.straight=0.3"});
  io::writeLog(base / "a", simulate(sc, rocky7Dir(), 42).log);
  io::writeLog(base / "b", simulate(sc, rocky7Dir(), 42).log);
  io::writeLog(base / "c", simulate(sc, rocky7Dir(), 43).log);
  for (const char* f : {"gyro.csv", "joints.csv", "sun.csv", "accel.csv", "cmd.csv", "truth.csv",
                        "rover.yaml", "rover.urdf"}) {
    EXPECT_EQ(slurp(base / "a" / f), slurp(base / "b" / f)) << f;
  }
  EXPECT_NE(slurp(base / "a" / "gyro.csv"), slurp(base / "c" / "gyro.csv"));
  std::filesystem::remove_all(base);
}

// datasets/logs/straight-1m is what scripts/make_datasets.sh writes: regenerate and compare.
TEST(SimScenarios, BundledLogIsReproducible) {
  const auto out = std::filesystem::temp_directory_path() / "traverse_bundled_straight";
  std::filesystem::remove_all(out);
  io::writeLog(out, simulate(loadScenario("straight-1m", datasets()), rocky7Dir(), 1).log);
  for (const char* f :
       {"gyro.csv", "joints.csv", "sun.csv", "accel.csv", "cmd.csv", "truth.csv", "rover.yaml"}) {
    EXPECT_EQ(slurp(out / f), slurp(datasets() / "logs" / "straight-1m" / f))
        << f << ": run scripts/make_datasets.sh";
  }
  std::filesystem::remove_all(out);
}

TEST(SimScenarios, EveryBundledScenarioLoads) {
  for (const char* name :
       {"straight-1m", "turn-in-place-360", "obstacle", "planar-18m", "multi-stop", "slow-onset"}) {
    const Scenario sc = loadScenario(name, datasets());
    EXPECT_EQ(sc.name, name);
    EXPECT_FALSE(sc.legs.empty());
  }
  const Scenario ms = loadScenario("multi-stop", datasets());
  double distance = 0;
  int motion_legs = 0;
  for (const Leg& l : ms.legs) {
    if (l.kind == Leg::Kind::kStraight || l.kind == Leg::Kind::kArc) distance += l.distance_m;
    if (l.kind != Leg::Kind::kRest) ++motion_legs;
    if (l.kind == Leg::Kind::kRest) {
      EXPECT_GE(l.duration_s, 10.0);
    }
  }
  EXPECT_GE(distance, 50.0);
  EXPECT_GE(motion_legs, 10);
  EXPECT_EQ(ms.terrain.type, "rough");
  EXPECT_GT(ms.sensors.gyro_bias_random_walk_rad_s_per_sqrt_s, 0.0);
}

TEST(SimScenarios, OverridesAndErrors) {
  const Scenario sc =
      loadScenario("straight-1m", datasets(),
                   {"terrain.type=flat", "path.1.speed_mps=0.1", "sensors.sun.rate_hz=2"});
  EXPECT_EQ(sc.terrain.type, "flat");
  EXPECT_EQ(sc.legs[1].speed_mps, 0.1);
  EXPECT_EQ(sc.sensors.sun_rate_hz, 2.0);
  EXPECT_THROW(loadScenario("straight-1m", datasets(), {"terrain.type=lava"}), InputError);
  EXPECT_THROW(loadScenario("straight-1m", datasets(), {"terrain.typo=1"}), InputError);
  EXPECT_THROW(loadScenario("straight-1m", datasets(), {"path.9.speed_mps=1"}), InputError);
  EXPECT_THROW(loadScenario("no-such-scenario", datasets()), InputError);
}

// The smooth (slow-onset) profile: position is the integral of the rate, the rate is the
// derivative of position, 0 at both ends and positive inside, a single bump with no cruise,
// peaking at (and never above) the cruise speed; the duration is amount·(15/8)/cruise.
TEST(SimPath, SmoothProfileIsExactAndHasNoCruise) {
  for (const auto& [amount, cruise] : {std::pair{1.5, 0.1}, {0.6, 0.1}, {3.0, 0.05}}) {
    const SpeedProfile p(Leg::Profile::kSmooth, amount, cruise, 2.0);
    const double T = p.duration();
    EXPECT_NEAR(T, amount * 15.0 / 8.0 / cruise, 1e-12);
    EXPECT_EQ(p.cruise_time, 0.0);
    EXPECT_EQ(p.rate(0.0), 0.0);
    EXPECT_EQ(p.rate(T), 0.0);
    EXPECT_EQ(p.position(0.0), 0.0);
    EXPECT_EQ(p.position(T), amount);
    EXPECT_NEAR(p.rate(T / 2), cruise, 1e-12);
    // Simpson's rule on the rate reproduces the position; central differences of the position
    // reproduce the rate.
    const int n = 2000;
    const double h = T / n;
    double integral = 0, peak = 0, prev = 0;
    for (int k = 1; k < n; ++k) {
      const double t = k * h;
      const double r = p.rate(t);
      EXPECT_GT(r, 0.0) << "t " << t;
      peak = std::max(peak, r);
      if (2 * k < n) {
        EXPECT_GT(r, prev) << "rising until the middle, no cruise";
      } else if (2 * k > n + 1) {
        EXPECT_LT(r, prev) << "falling after the middle, no cruise";
      }
      prev = r;
      if (k % 2 == 0) {
        integral += h / 3 * (p.rate(t - 2 * h) + 4 * p.rate(t - h) + r);
        EXPECT_NEAR(integral, p.position(t), 1e-10 * amount) << "t " << t;
      }
      const double e = 1e-5 * T;
      EXPECT_NEAR((p.position(t + e) - p.position(t - e)) / (2 * e), r, 1e-7 * cruise);
    }
    EXPECT_LE(peak, cruise * (1 + 1e-12));
  }
  // The default profile still cruises.
  const SpeedProfile ramped(Leg::Profile::kRamped, 1.5, 0.1, 2.0);
  EXPECT_NEAR(ramped.cruise_time, 13.0, 1e-12);
  EXPECT_EQ(ramped.rate(8.0), 0.1);
}

// Smooth straights, arcs and turns in place through samplePath: the commanded rates integrate
// to the poses, and each leg ends where its amount says.
TEST(SimPath, SmoothLegsOfEveryKindIntegrateToTheirPoses) {
  std::vector<Leg> legs{rest(1),    straight(0.8), rest(1),        arc(0.9, 1.5), rest(1),
                        turn(-0.7), rest(1),       arc(0.5, -2.0), rest(1)};
  for (Leg& l : legs) l.profile = Leg::Profile::kSmooth;
  const Scenario sc = quiet("flat", legs);
  const auto path = samplePath(sc, rocky7());
  const double dt = 1.0 / sc.truth_rate_hz;
  double yaw = path.front().yaw, s = 0;
  double moving_time = 0;
  for (size_t k = 1; k < path.size(); ++k) {
    const PathSample &a = path[k - 1], &b = path[k];
    yaw += 0.5 * (a.yaw_rate_rad_s + b.yaw_rate_rad_s) * dt;
    s += 0.5 * (a.speed_mps + b.speed_mps) * dt;
    EXPECT_NEAR(b.yaw - a.yaw, 0.5 * (a.yaw_rate_rad_s + b.yaw_rate_rad_s) * dt, 1e-8);
    const Vec2d mid_dir(std::cos(0.5 * (a.yaw + b.yaw)), std::sin(0.5 * (a.yaw + b.yaw)));
    EXPECT_NEAR((b.centre - a.centre).dot(mid_dir), 0.5 * (a.speed_mps + b.speed_mps) * dt, 1e-8);
    EXPECT_LE(b.progress, 1.0 + 1e-12);
    if (b.moving) moving_time += dt;
  }
  EXPECT_NEAR(s, 0.8 + 0.9 + 0.5, 1e-6);
  EXPECT_NEAR(yaw, path.back().yaw, 1e-6);
  EXPECT_NEAR(path.back().yaw - path.front().yaw, 0.9 / 1.5 - 0.7 + 0.5 / -2.0, 1e-12);
  EXPECT_NEAR(moving_time, (0.8 + 0.9 + 0.5) * 15 / 8 / 0.05 + 0.7 * 15 / 8 / 0.1, 0.1);
  // A straight ends exactly its distance along the heading.
  const auto line = samplePath(quiet("flat", {legs[1]}), rocky7());
  EXPECT_NEAR((line.back().centre - line.front().centre).norm(), 0.8, 1e-12);
}

/// Smallest range of `speed` over any `window`-s stretch of each moving run (a
/// constant-speed phase has range 0).
double smallestWindowRange(const std::vector<double>& speed, const std::vector<bool>& moving,
                           double rate_hz, double window) {
  const size_t w = static_cast<size_t>(window * rate_hz);
  double smallest = 1e9;
  for (size_t i = 0; i + w < speed.size(); ++i) {
    bool all = true;
    double lo = 1e9, hi = -1e9;
    for (size_t j = i; j <= i + w && all; ++j) {
      all = moving[j];
      lo = std::min(lo, speed[j]), hi = std::max(hi, speed[j]);
    }
    if (all) smallest = std::min(smallest, hi - lo);
  }
  return smallest;
}

TEST(SimScenarios, SlowOnsetNeverCruises) {
  const Scenario sc = loadScenario("slow-onset", datasets());
  EXPECT_EQ(sc.terrain.type, "plane");
  EXPECT_GT(std::abs(sc.terrain.slope_rad), 0.03);
  EXPECT_EQ(sc.sensors.joints_rate_hz, 50.0);
  EXPECT_NEAR(sc.sensors.joint_angle_noise_rad, 0.05 * M_PI / 180, 1e-8);
  double distance = 0;
  int motion_legs = 0, kinds = 0;
  for (const Leg& l : sc.legs) {
    if (l.kind == Leg::Kind::kRest) continue;
    ++motion_legs, kinds |= 1 << static_cast<int>(l.kind);
    EXPECT_EQ(l.profile, Leg::Profile::kSmooth);
    if (l.kind != Leg::Kind::kTurnInPlace) distance += std::abs(l.distance_m);
  }
  EXPECT_GE(motion_legs, 10);
  EXPECT_EQ(kinds, 0b1110);  // straights, arcs and turns in place
  EXPECT_GE(distance, 10.0);
  EXPECT_LE(distance, 15.0);

  const Simulation sim = simulate(sc, rocky7Dir(), 1);
  std::vector<double> speed, true_speed;
  std::vector<bool> moving;
  for (const TruthSample& t : sim.truth) {
    // commanded motion: |v_x| for straights and arcs, |ω_z| (normalised) for turns in place
    speed.push_back(std::max(std::abs(t.cmd[0]) / 0.1, std::abs(t.cmd[5]) / 0.1));
    true_speed.push_back(t.v_body.norm());
    moving.push_back(t.moving);
  }
  // Never constant over any 2 s while moving (a cruise phase would give 0); the ramped
  // multi-stop does cruise.
  const double range = smallestWindowRange(speed, moving, sc.truth_rate_hz, 2.0);
  EXPECT_GT(range, 2e-3);
  EXPECT_LT(range, 1.0);  // there are moving windows at all
  EXPECT_LE(*std::max_element(speed.begin(), speed.end()), 1.0 + 1e-9);
  const auto ms = samplePath(loadScenario("multi-stop", datasets()), rocky7());
  std::vector<double> ms_speed;
  std::vector<bool> ms_moving;
  for (const PathSample& p : ms) ms_speed.push_back(p.progress), ms_moving.push_back(p.moving);
  EXPECT_LT(smallestWindowRange(ms_speed, ms_moving, 200.0, 2.0), 1e-12);
  // The true body speed stays below the cruise speed plus slip and the lever arm of a turn.
  EXPECT_LT(*std::max_element(true_speed.begin(), true_speed.end()), 0.13);
}

TEST(SimScenarios, SmoothProfileKeyIsChecked) {
  EXPECT_EQ(loadScenario("straight-1m", datasets()).legs[1].profile, Leg::Profile::kRamped);
  EXPECT_EQ(loadScenario("straight-1m", datasets(), {"path.1.profile=smooth"}).legs[1].profile,
            Leg::Profile::kSmooth);
  EXPECT_THROW(loadScenario("straight-1m", datasets(), {"path.1.profile=bumpy"}), InputError);
  EXPECT_THROW(loadScenario("straight-1m", datasets(), {"path.0.profile=smooth"}), InputError);
}

}  // namespace
}  // namespace traverse::sim
