#include "traverse/estimators/rest_noise.h"

#include <cmath>
#include <cstdio>
#include <utility>

namespace traverse::est {

std::string RestNoise::message() const {
  char buf[320];
  std::snprintf(buf, sizeof buf,
                "noise at rest %.3g %s on %s (%d samples in %d rests) is %.1f times %s %.3g in "
                "rover.yaml: the measured value is used",
                measured, unit.c_str(), column.c_str(), samples, windows, measured / declared,
                key.c_str(), declared);
  return buf;
}

namespace {

/// Where the wheels stand still: runs of joint samples whose mean rolling speed stays below
/// `threshold`, at least `min_s` long. Not the segmentation's rests: its detector reads the gyro
/// against the declared noise, so a gyro ten times noisier than declared leaves no rest at all.
std::vector<std::pair<double, double>> stillWindows(const io::TraverseLog& log, double threshold,
                                                    double min_s) {
  std::vector<std::pair<double, double>> out;
  const Eigen::VectorXd v = wheelSpeeds(log);
  const io::Stream& j = log.joints;
  Eigen::Index start = -1;
  for (Eigen::Index k = 0; k <= j.size(); ++k) {
    const bool still = k < j.size() && std::isfinite(v[k]) && v[k] < threshold;
    if (still && start < 0) start = k;
    if (!still && start >= 0) {
      if (j.t[k - 1] - j.t[start] >= min_s) out.emplace_back(j.t[start], j.t[k - 1]);
      start = -1;
    }
  }
  return out;
}

/// The noisiest channel of `s` at rest: pooled σ about each window's mean.
RestNoise pooled(const io::Stream& s, const std::vector<std::pair<double, double>>& still,
                 const RestNoiseOptions& o) {
  RestNoise best;
  for (Eigen::Index c = 0; c < s.values.cols(); ++c) {
    double ss = 0.0;
    int dof = 0, windows = 0;
    double t_first = 0.0;
    for (const auto& [t0, t1] : still) {
      const double a = t0 + o.margin_s, b = t1 - o.margin_s;
      if (!(b > a)) continue;
      const Eigen::Index i0 = std::lower_bound(s.t.data(), s.t.data() + s.size(), a) - s.t.data();
      const Eigen::Index i1 = std::upper_bound(s.t.data(), s.t.data() + s.size(), b) - s.t.data();
      const Eigen::Index n = i1 - i0;
      if (n < 3) continue;
      const double mean = s.values.col(c).segment(i0, n).mean();
      ss += (s.values.col(c).segment(i0, n).array() - mean).square().sum();
      dof += static_cast<int>(n - 1);
      if (windows++ == 0) t_first = t0;
    }
    if (dof < o.min_samples) continue;
    const double sigma = std::sqrt(ss / dof);
    if (sigma > best.measured) {
      best.measured = sigma, best.samples = dof, best.windows = windows, best.t = t_first;
      best.column = s.columns[static_cast<size_t>(c)];
    }
  }
  return best;
}

}  // namespace

std::vector<RestNoise> restNoise(const io::TraverseLog& log, const RestNoiseOptions& o) {
  std::vector<RestNoise> out;
  const auto still = stillWindows(log, o.wheel_speed_threshold_mps, o.min_window_s);
  const auto judge = [&](const io::Stream& s, const char* file, const char* key, const char* unit,
                         double declared) {
    RestNoise r = pooled(s, still, o);
    if (r.samples == 0 || !(declared > 0.0) || !(r.measured > o.max_ratio * declared)) return;
    r.file = file, r.key = key, r.unit = unit, r.declared = declared;
    out.push_back(r);
  };
  judge(log.gyro, "gyro.csv", "gyro.noise_rad_s", "rad/s", log.config.gyro.noise_rad_s);
  if (log.accel)
    judge(*log.accel, "accel.csv", "accelerometer.noise_mps2", "m/s^2",
          log.config.accel.noise_mps2);
  return out;
}

io::TraverseLog withRestNoise(const io::TraverseLog& log, const std::vector<RestNoise>& noise) {
  io::TraverseLog out = log;
  for (const RestNoise& r : noise) {
    if (r.file == "gyro.csv") out.config.gyro.noise_rad_s = r.measured;
    if (r.file == "accel.csv") out.config.accel.noise_mps2 = r.measured;
  }
  return out;
}

}  // namespace traverse::est
