// Simulator fault injection (issue 15, FaultSpec, docs/simulator.md "Faults"): on straight-1m,
// each fault set through --set does what it says to its own stream and leaves every other
// stream byte for byte as the clean run's.
#include <cmath>
#include <fstream>
#include <set>

#include <gtest/gtest.h>

#include "support/jacobian_check.h"
#include "traverse/core/error.h"
#include "traverse/sensors/sun_sensor.h"
#include "traverse/sim/simulator.h"

namespace traverse::sim {
namespace {

std::filesystem::path datasets() {
  return std::filesystem::path(testing::sourceDir()) / "datasets";
}
std::filesystem::path rocky7Dir() {
  return datasets() / "rovers" / "rocky7";
}

Simulation run(const std::vector<std::string>& sets) {
  return simulate(loadScenario("straight-1m", datasets(), sets), rocky7Dir(), 1);
}
const Simulation& clean() {
  static const Simulation s = run({});
  return s;
}
/// The clean simulation with the sensor faults of `sets` applied afterwards: the same log as
/// run(sets) (SimFaults.SensorFaultsAfterTheFactEqualASimulationWithThem), without the physics
/// again (about 20 s per run under ASan).
Simulation faulted(const std::vector<std::string>& sets) {
  return withSensorFaults(clean(), loadScenario("straight-1m", datasets(), sets), 1);
}

bool sameLog(const io::TraverseLog& a, const io::TraverseLog& b);

bool same(const io::Stream& a, const io::Stream& b) {
  return a.columns == b.columns && a.t.size() == b.t.size() && a.values.rows() == b.values.rows() &&
         a.values.cols() == b.values.cols() && a.t == b.t && a.values == b.values;
}

bool sameLog(const io::TraverseLog& a, const io::TraverseLog& b) {
  const auto x = io::logStreams(a), y = io::logStreams(b);
  if (x.size() != y.size()) return false;
  for (size_t i = 0; i < x.size(); ++i) {
    if ((x[i].stream == nullptr) != (y[i].stream == nullptr)) return false;
    if (x[i].stream && !same(*x[i].stream, *y[i].stream)) return false;
  }
  return true;
}

/// Every stream of `log` but those named in `changed` equals the clean run's exactly.
void expectOthersUnchanged(const io::TraverseLog& log, const std::set<std::string>& changed) {
  const auto mine = io::logStreams(log);
  const auto ref = io::logStreams(clean().log);
  for (size_t i = 0; i < mine.size(); ++i) {
    if (changed.count(mine[i].file)) continue;
    ASSERT_EQ(mine[i].stream == nullptr, ref[i].stream == nullptr) << mine[i].file;
    if (mine[i].stream) {
      EXPECT_TRUE(same(*mine[i].stream, *ref[i].stream)) << mine[i].file;
    }
  }
}

/// Column index of psi<wheel> in joints.csv.
int psi(int wheel) {
  return clean().log.joints.col("psi" + std::to_string(wheel));
}

TEST(SimFaults, OffByDefault) {
  const FaultSpec f = loadScenario("straight-1m", datasets()).faults;
  EXPECT_TRUE(f.gyro.gaps.empty() && f.joints.gaps.empty() && f.sun.gaps.empty() &&
              f.accel.gaps.empty() && f.cmd.gaps.empty());
  EXPECT_EQ(f.gyro_spike_count + f.sun_outlier_count + f.stuck_wheel, 0);
  EXPECT_TRUE(f.slip_burst.empty());
  EXPECT_FALSE(f.no_accel);
  // Explicit zero-size faults change nothing either.
  const Simulation s = run({"faults.gap.gyro=[]", "faults.gyro_spikes.count=0",
                            "faults.sun_dropout.fraction=0", "faults.stuck_wheel.window=[10, 0]",
                            "faults.slip_burst.window=[10, 0]", "faults.clock_offset.sun=0"});
  expectOthersUnchanged(s.log, {});
}

// What the other tests rely on: applying the sensor faults to the clean simulation gives the
// same log, bit for bit, as simulating with them (every kind at once, and one alone).
TEST(SimFaults, SensorFaultsAfterTheFactEqualASimulationWithThem) {
  for (const std::vector<std::string>& sets :
       {std::vector<std::string>{"faults.gap.joints=[[10, 2]]", "faults.gyro_spikes.count=3",
                                 "faults.sun_dropout.fraction=0.2", "faults.sun_outliers.count=2",
                                 "faults.stuck_wheel.wheel=4", "faults.stuck_wheel.window=[12, 3]",
                                 "faults.clock_offset.sun=0.1", "faults.no_accel=true"},
        std::vector<std::string>{"faults.clock_offset.joints=-0.05"}}) {
    const Simulation a = run(sets), b = faulted(sets);
    EXPECT_TRUE(sameLog(a.log, b.log)) << sets.front();
  }
  EXPECT_THROW(faulted({"faults.slip_burst.window=[10, 5]"}), std::invalid_argument);
}

TEST(SimFaults, GapsDropTheRowsOfTheirStreamOnly) {
  for (const std::string stream : {"gyro", "joints", "sun", "accel", "cmd"}) {
    const Simulation s = faulted({"faults.gap." + stream + "=[[10, 2], [20.1, 0.5]]"});
    const std::string file = stream + ".csv";
    expectOthersUnchanged(s.log, {file});
    const io::Stream* got = nullptr;
    const io::Stream* ref = nullptr;
    for (size_t i = 0; i < io::logStreams(s.log).size(); ++i) {
      if (io::logStreams(s.log)[i].file == file) {
        got = io::logStreams(s.log)[i].stream;
        ref = io::logStreams(clean().log)[i].stream;
      }
    }
    ASSERT_TRUE(got && ref) << file;
    Eigen::Index j = 0, dropped = 0;
    for (Eigen::Index k = 0; k < ref->size(); ++k) {
      const double t = ref->t[k];
      if ((t >= 10 && t < 12) || (t >= 20.1 && t < 20.6)) {
        ++dropped;
        continue;
      }
      ASSERT_LT(j, got->size()) << file;
      EXPECT_EQ(got->t[j], t) << file;
      EXPECT_TRUE(got->values.row(j) == ref->values.row(k)) << file << " t=" << t;
      ++j;
    }
    EXPECT_EQ(j, got->size()) << file;
    EXPECT_GT(dropped, 2) << file;
  }
}

TEST(SimFaults, ClockOffsetShiftsOneStreamsStamps) {
  const Simulation s = faulted({"faults.clock_offset.sun=0.3"});
  expectOthersUnchanged(s.log, {"sun.csv"});
  ASSERT_TRUE(s.log.sun && clean().log.sun);
  EXPECT_TRUE(s.log.sun->values == clean().log.sun->values);
  EXPECT_LT((s.log.sun->t.array() - clean().log.sun->t.array() - 0.3).abs().maxCoeff(), 1e-12);
  const Simulation g = faulted({"faults.clock_offset.gyro=-0.02"});
  expectOthersUnchanged(g.log, {"gyro.csv"});
  EXPECT_NEAR(g.log.gyro.t[0], -0.02, 1e-15);
}

TEST(SimFaults, GyroSpikesAreSingleSamplesOfTheStatedSize) {
  const Simulation s =
      faulted({"faults.gyro_spikes.count=5", "faults.gyro_spikes.magnitude_rad_s=0.4"});
  expectOthersUnchanged(s.log, {"gyro.csv"});
  const io::Stream& g = s.log.gyro;
  const io::Stream& c = clean().log.gyro;
  ASSERT_TRUE(g.t == c.t);
  int spikes = 0;
  for (Eigen::Index k = 0; k < g.size(); ++k) {
    const double d = g.values(k, 0) - c.values(k, 0);
    if (d == 0.0) continue;
    ++spikes;
    EXPECT_NEAR(std::abs(d), 0.4, 1e-12) << "t=" << g.t[k];
  }
  EXPECT_EQ(spikes, 5);
  // Another seed puts them elsewhere; the same seed in the same place.
  const Simulation again =
      faulted({"faults.gyro_spikes.count=5", "faults.gyro_spikes.magnitude_rad_s=0.4"});
  EXPECT_TRUE(again.log.gyro.values == g.values);
}

TEST(SimFaults, SunDropoutsMarkReadingsInvalid) {
  const Simulation s =
      faulted({"faults.sun_dropout.windows=[10, 5]", "faults.sun_dropout.fraction=0.3"});
  expectOthersUnchanged(s.log, {"sun.csv"});
  const io::Stream& u = *s.log.sun;
  const io::Stream& c = *clean().log.sun;
  ASSERT_TRUE(u.t == c.t);
  int random_drops = 0, outside = 0;
  for (Eigen::Index k = 0; k < u.size(); ++k) {
    const bool invalid = u.values(k, 2) == 0.0;
    if (invalid) {
      EXPECT_EQ(u.values(k, 0), 0.0);
      EXPECT_EQ(u.values(k, 1), 0.0);
    } else {
      EXPECT_TRUE(u.values.row(k) == c.values.row(k));
    }
    if (u.t[k] >= 10 && u.t[k] < 15) {
      EXPECT_TRUE(invalid) << "t=" << u.t[k];
    } else {
      ++outside;
      random_drops += invalid;
    }
  }
  // Binomial(outside, 0.3): well inside ±5σ.
  const double mean = 0.3 * outside, sd = std::sqrt(outside * 0.3 * 0.7);
  EXPECT_NEAR(random_drops, mean, 5 * sd);
}

TEST(SimFaults, SunOutliersAreValidReadingsOfAWrongDirection) {
  const Simulation s =
      faulted({"faults.sun_outliers.count=4", "faults.sun_outliers.angle_rad=0.5"});
  expectOthersUnchanged(s.log, {"sun.csv"});
  const io::Stream& u = *s.log.sun;
  const io::Stream& c = *clean().log.sun;
  ASSERT_TRUE(u.t == c.t);
  int outliers = 0;
  for (Eigen::Index k = 0; k < u.size(); ++k) {
    if (u.values.row(k) == c.values.row(k)) continue;
    ++outliers;
    EXPECT_EQ(u.values(k, 2), 1.0);
    // The direction read differs from the true one by about the injected azimuth error (the
    // sun is ~35° up: 0.5 rad of azimuth is ~0.4 rad of arc), far beyond the noise (0.002).
    const Vec3d a = sensors::fisheyeUnproject(Vec2d(u.values(k, 0), u.values(k, 1)));
    const Vec3d b = sensors::fisheyeUnproject(Vec2d(c.values(k, 0), c.values(k, 1)));
    EXPECT_GT(std::acos(std::clamp(a.dot(b), -1.0, 1.0)), 0.3) << "t=" << u.t[k];
  }
  EXPECT_EQ(outliers, 4);
}

TEST(SimFaults, StuckWheelEncoderHoldsThenCountsOn) {
  const Simulation s = faulted({"faults.stuck_wheel.wheel=2", "faults.stuck_wheel.window=[12, 6]"});
  expectOthersUnchanged(s.log, {"joints.csv"});
  const io::Stream& j = s.log.joints;
  const io::Stream& c = clean().log.joints;
  ASSERT_TRUE(j.t == c.t);
  const int col = psi(2);
  for (Eigen::Index k = 0; k < j.values.cols(); ++k) {
    if (k != col) {
      EXPECT_TRUE(j.values.col(k) == c.values.col(k)) << c.columns[k];
    }
  }
  Eigen::Index first = -1;
  for (Eigen::Index k = 0; k < j.size(); ++k) {
    const double t = j.t[k];
    if (t < 12) {
      EXPECT_EQ(j.values(k, col), c.values(k, col));
    } else if (t < 18) {
      if (first < 0) first = k;
      EXPECT_EQ(j.values(k, col), c.values(first, col)) << "t=" << t;
    } else {
      // Counts on: the same increments as the clean encoder, from the held value.
      EXPECT_NEAR(j.values(k, col) - j.values(k - 1, col),
                  k - 1 >= first && j.t[k - 1] < 18 ? 0.0 : c.values(k, col) - c.values(k - 1, col),
                  1e-12)
          << "t=" << t;
    }
  }
  // The wheel turned meanwhile: the encoder lost that turn for good.
  const double lost = c.values(j.size() - 1, col) - j.values(j.size() - 1, col);
  EXPECT_GT(lost, 0.5 * 0.05 * 6 / 0.065);  // > half of 6 s at 5 cm/s on a 6.5 cm wheel
}

TEST(SimFaults, SlipBurstIsInThePhysics) {
  // Longitudinal: the wheels turn more than the body moves; the body path (truth) is unchanged.
  const Simulation s =
      run({"faults.slip_burst.window=[10, 5]", "faults.slip_burst.longitudinal_mps=-0.02"});
  expectOthersUnchanged(s.log, {"joints.csv"});
  const io::Stream& j = s.log.joints;
  const io::Stream& c = clean().log.joints;
  const Eigen::Index last = j.size() - 1;
  for (int w = 1; w <= 6; ++w) {
    // 0.02 m/s for 5 s at cruise speed on 6.5 cm wheels: ~1.5 rad extra.
    EXPECT_NEAR(j.values(last, psi(w)) - c.values(last, psi(w)), 0.02 * 5 / 0.065, 0.1) << w;
  }
  // One wheel only, and sideways: the body moves left, so truth changes too.
  const Simulation one =
      run({"faults.slip_burst.window=[10, 5]", "faults.slip_burst.wheel=3",
           "faults.slip_burst.longitudinal_mps=-0.05", "faults.slip_burst.lateral_mps=0.01"});
  const io::Stream& t1 = *one.log.truth;
  const io::Stream& t0 = *clean().log.truth;
  const Eigen::Index y = t0.col("y");
  EXPECT_NEAR(t1.values(t1.size() - 1, y) - t0.values(t0.size() - 1, y), 0.01 * 5, 0.005);
  EXPECT_NEAR(one.log.joints.values(last, psi(3)) - c.values(last, psi(3)), 0.05 * 5 / 0.065, 0.3);
  EXPECT_LT(std::abs(one.log.joints.values(last, psi(1)) - c.values(last, psi(1))), 0.1);
  // Inside a rest it does nothing (slip scales with speed).
  const Simulation rest =
      run({"faults.slip_burst.window=[0, 4]", "faults.slip_burst.lateral_mps=0.05"});
  expectOthersUnchanged(rest.log, {});
}

TEST(SimFaults, NoAccelerometer) {
  const Simulation s = faulted({"faults.no_accel=true"});
  EXPECT_FALSE(s.log.accel.has_value());
  expectOthersUnchanged(s.log, {"accel.csv"});
}

TEST(SimFaults, KeysAreChecked) {
  const auto load = [](const std::vector<std::string>& sets) {
    return loadScenario("straight-1m", datasets(), sets);
  };
  EXPECT_THROW(load({"faults.typo=1"}), InputError);
  EXPECT_THROW(load({"faults.gap.truth=[1, 2]"}), InputError);
  EXPECT_THROW(load({"faults.gap.gyro=[1, 2, 3]"}), InputError);
  EXPECT_THROW(load({"faults.gap.gyro=[[1, -2]]"}), InputError);
  EXPECT_THROW(load({"faults.sun_dropout.fraction=1.5"}), InputError);
  EXPECT_THROW(load({"faults.gyro_spikes.count=-1"}), InputError);
  EXPECT_THROW(load({"faults.stuck_wheel.window=5"}), InputError);
  EXPECT_THROW(run({"faults.stuck_wheel.wheel=7", "faults.stuck_wheel.window=[1, 1]"}), InputError);
  // A faults block in a scenario file reads like --set.
  const auto file = std::filesystem::temp_directory_path() / "traverse_faults_scenario.yaml";
  {
    std::ifstream in(datasets() / "scenarios" / "straight-1m.yaml");
    std::ofstream out(file);
    out << in.rdbuf()
        << "faults:\n  gap: {gyro: [3, 1], joints: [[1, 1], [4, 2]]}\n"
           "  clock_offset: {accel: 0.01}\n  no_accel: true\n"
           "  slip_burst: {window: [8, 2], wheel: 1, lateral_mps: 0.003}\n";
  }
  const FaultSpec f = loadScenario(file.string(), datasets()).faults;
  std::filesystem::remove(file);
  ASSERT_EQ(f.gyro.gaps.size(), 1u);
  EXPECT_EQ(f.gyro.gaps[0].t_start_s, 3.0);
  ASSERT_EQ(f.joints.gaps.size(), 2u);
  EXPECT_EQ(f.joints.gaps[1].duration_s, 2.0);
  EXPECT_EQ(f.accel.clock_offset_s, 0.01);
  EXPECT_TRUE(f.no_accel);
  EXPECT_EQ(f.slip_burst.t_start_s, 8.0);
  EXPECT_EQ(f.slip_burst_wheel, 1);
  EXPECT_EQ(f.slip_burst_longitudinal_mps, -0.02);  // the default
  EXPECT_EQ(f.slip_burst_lateral_mps, 0.003);
}

}  // namespace
}  // namespace traverse::sim
