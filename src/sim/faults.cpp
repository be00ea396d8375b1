// Sensor faults injected into a simulated log (issue 15; FaultSpec in sim/scenario.h,
// docs/simulator.md "Faults"): applied to the synthesized streams, truth untouched.
#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include "sim/sensor_synthesis.h"
#include "traverse/core/error.h"
#include "traverse/sensors/sun_sensor.h"
#include "traverse/sim/random.h"

namespace traverse::sim {
namespace {

/// `count` distinct indices drawn uniformly from `candidates` (all of them if fewer), in the
/// order drawn.
std::vector<Eigen::Index> pickDistinct(std::vector<Eigen::Index> candidates, int count, Rng& rng) {
  std::vector<Eigen::Index> out;
  for (int k = 0; k < count && !candidates.empty(); ++k) {
    const auto j =
        std::min(candidates.size() - 1,
                 static_cast<size_t>(rng.uniform() * static_cast<double>(candidates.size())));
    out.push_back(candidates[j]);
    candidates.erase(candidates.begin() + static_cast<std::ptrdiff_t>(j));
  }
  return out;
}

std::vector<Eigen::Index> allRows(const io::Stream& s) {
  std::vector<Eigen::Index> rows(static_cast<size_t>(s.size()));
  for (Eigen::Index k = 0; k < s.size(); ++k) rows[static_cast<size_t>(k)] = k;
  return rows;
}

bool inAny(const std::vector<TimeWindow>& windows, double t) {
  return std::any_of(windows.begin(), windows.end(),
                     [t](const TimeWindow& w) { return w.contains(t); });
}

/// Drops the rows stamped inside a gap, then shifts the stamps by the clock offset.
void gapsAndClock(io::Stream& s, const StreamFaults& f) {
  if (!f.gaps.empty()) {
    std::vector<Eigen::Index> keep;
    for (Eigen::Index k = 0; k < s.size(); ++k) {
      if (!inAny(f.gaps, s.t[k])) keep.push_back(k);
    }
    if (static_cast<Eigen::Index>(keep.size()) != s.size()) {
      io::Stream out;
      out.columns = s.columns;
      out.t.resize(static_cast<Eigen::Index>(keep.size()));
      out.values.resize(out.t.size(), s.values.cols());
      for (size_t i = 0; i < keep.size(); ++i) {
        out.t[static_cast<Eigen::Index>(i)] = s.t[keep[i]];
        out.values.row(static_cast<Eigen::Index>(i)) = s.values.row(keep[i]);
      }
      s = std::move(out);
    }
  }
  if (f.clock_offset_s != 0.0) s.t.array() += f.clock_offset_s;
}

void gyroSpikes(const FaultSpec& f, io::Stream& gyro, uint64_t seed) {
  if (f.gyro_spike_count == 0) return;
  Rng rng(seed, 301);
  for (const Eigen::Index k : pickDistinct(allRows(gyro), f.gyro_spike_count, rng)) {
    const double sign = rng.uniform() < 0.5 ? -1.0 : 1.0;
    gyro.values.row(k).array() += sign * f.gyro_spike_rad_s;
  }
}

void sunDropouts(const FaultSpec& f, io::Stream& sun, uint64_t seed) {
  if (f.sun_dropout_windows.empty() && f.sun_dropout_fraction == 0.0) return;
  Rng rng(seed, 302);
  for (Eigen::Index k = 0; k < sun.size(); ++k) {
    const bool random_drop = rng.uniform() < f.sun_dropout_fraction;  // one draw per row
    if (random_drop || inAny(f.sun_dropout_windows, sun.t[k])) {
      sun.values.row(k).setZero();  // as a reading out of view: s1 = s2 = 0, valid = 0
    }
  }
}

void sunOutliers(const Scenario& sc, const io::RoverConfig& config,
                 const std::vector<TruthSample>& truth, io::Stream& sun, uint64_t seed) {
  const FaultSpec& f = sc.faults;
  if (f.sun_outlier_count == 0) return;
  Rng rng(seed, 303);
  const int valid = sun.col("valid");
  std::vector<Eigen::Index> candidates;
  for (Eigen::Index k = 0; k < sun.size(); ++k) {
    if (sun.values(k, valid) != 0.0) candidates.push_back(k);
  }
  const sensors::SunSensorGeometry sg{config.sun_sensor.R_body_sensor,
                                      0.5 * sc.sensors.sun_fov_rad};
  for (const Eigen::Index k : pickDistinct(candidates, f.sun_outlier_count, rng)) {
    const double sign = rng.uniform() < 0.5 ? -1.0 : 1.0;
    const double n1 = rng.normal(), n2 = rng.normal();
    const TruthSample x = interpolateTruth(truth, sun.t[k]);
    // The sun as if it stood sun_outlier_rad further round in azimuth: a heading error of that
    // size, which a sun sensor's reflections or a misidentified bright spot give.
    const Vec3d wrong = Eigen::AngleAxisd(sign * f.sun_outlier_rad, Vec3d::UnitZ()) *
                        sunDirectionAt(sc.sensors, sun.t[k]);
    if (!sensors::sunInFieldOfView(x.q_site_body, sg, wrong)) continue;  // stays as it was
    const Vec2d m = sensors::sunSensorPredict<double>(x.q_site_body, sg, wrong);
    sun.values(k, 0) = std::clamp(m.x() + sc.sensors.sun_noise * n1, -1.0, 1.0);
    sun.values(k, 1) = std::clamp(m.y() + sc.sensors.sun_noise * n2, -1.0, 1.0);
  }
}

/// The drive encoder of wheel `f.stuck_wheel` reads the value it had on entering the window
/// throughout it, then counts on from there (its later readings lose the turn it missed).
void stuckWheel(const FaultSpec& f, const rover::RoverGeometry& geo, io::Stream& joints) {
  if (f.stuck_wheel == 0 || f.stuck_wheel_window.empty()) return;
  const Eigen::Index c = geo.wheels[static_cast<size_t>(f.stuck_wheel - 1)].coord;
  const TimeWindow& w = f.stuck_wheel_window;
  Eigen::Index k = 0;
  while (k < joints.size() && joints.t[k] < w.t_start_s) ++k;
  if (k == joints.size()) return;
  const double held = joints.values(k, c);
  for (; k < joints.size() && w.contains(joints.t[k]); ++k) joints.values(k, c) = held;
  if (k == joints.size()) return;
  const double missed = joints.values(k, c) - held;
  for (; k < joints.size(); ++k) joints.values(k, c) -= missed;
}

}  // namespace

void checkFaults(const Scenario& sc, const rover::RoverGeometry& geo) {
  for (const int wheel : {sc.faults.stuck_wheel, sc.faults.slip_burst_wheel}) {
    if (wheel > geo.numWheels()) {
      throw InputError(sc.name, 0,
                       "faults: wheel " + std::to_string(wheel) + " but the rover has " +
                           std::to_string(geo.numWheels()) + " wheels");
    }
  }
}

void applyFaults(const Scenario& sc, const io::RoverConfig& config, const rover::RoverGeometry& geo,
                 const std::vector<TruthSample>& truth, io::TraverseLog& log, uint64_t seed) {
  const FaultSpec& f = sc.faults;
  checkFaults(sc, geo);
  gyroSpikes(f, log.gyro, seed);
  if (log.sun) {
    sunDropouts(f, *log.sun, seed);
    sunOutliers(sc, config, truth, *log.sun, seed);
  }
  stuckWheel(f, geo, log.joints);
  gapsAndClock(log.gyro, f.gyro);
  gapsAndClock(log.joints, f.joints);
  if (log.sun) gapsAndClock(*log.sun, f.sun);
  if (log.accel) gapsAndClock(*log.accel, f.accel);
  if (log.cmd) gapsAndClock(*log.cmd, f.cmd);
  if (f.no_accel) log.accel.reset();
}

}  // namespace traverse::sim
