// Stream diagnostics (include/traverse/io/diagnostics.h): gaps, time order, rate changes,
// overlap, stuck channels, spikes, sun readings.
#include "traverse/io/diagnostics.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <utility>

namespace traverse::io {
namespace {

std::string general(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.6g", v);
  return buf;
}

std::string hertz(double period_s) {
  return general(1.0 / period_s) + " Hz";
}

double median(std::vector<double>& v) {
  const auto mid = v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2);
  std::nth_element(v.begin(), mid, v.end());
  double m = *mid;
  if (v.size() % 2 == 0) m = 0.5 * (m + *std::max_element(v.begin(), mid));
  return m;
}

Finding finding(const std::string& file, const std::string& kind, double t, std::string message) {
  Finding f;
  f.file = file;
  f.kind = kind;
  f.t = t;
  f.message = std::move(message);
  return f;
}

void diagnoseOrder(const Stream& s, const std::string& file, std::vector<Finding>* out) {
  for (Eigen::Index k = 1; k < s.size(); ++k) {
    if (s.t[k] > s.t[k - 1]) continue;
    const bool same = s.t[k] == s.t[k - 1];
    out->push_back(
        finding(file, "time_order", s.t[k],
                (same ? "duplicated stamp t=" : "stamp t=") + formatSeconds(s.t[k]) +
                    (same ? "" : " before the previous t=" + formatSeconds(s.t[k - 1]))));
  }
}

void diagnoseRate(const Stream& s, const std::string& file, const DiagnosticsOptions& o,
                  std::vector<Finding>* out) {
  const Eigen::Index w = o.rate_window;
  if (w < 2 || s.size() < 2 * w + 1) return;
  double rate_period = medianInterval(s);
  std::vector<double> dt;
  for (Eigen::Index b = 1; b + w <= s.size(); b += w) {
    dt.clear();
    for (Eigen::Index k = b; k < b + w; ++k) {
      if (s.t[k] > s.t[k - 1]) dt.push_back(s.t[k] - s.t[k - 1]);
    }
    if (dt.empty()) continue;
    const double p = median(dt);
    const double ratio = p / rate_period;
    if (ratio <= o.rate_change_factor && ratio >= 1.0 / o.rate_change_factor) continue;
    out->push_back(finding(file, "rate_change", s.t[b - 1],
                           "rate changes from " + hertz(rate_period) + " to " + hertz(p) +
                               " at t=" + formatSeconds(s.t[b - 1])));
    rate_period = p;
  }
}

/// late_start / early_end / no_overlap of `s` against the reference stream `ref`.
void diagnoseOverlap(const Stream& s, const std::string& file, const Stream& ref,
                     const std::string& ref_file, const DiagnosticsOptions& o,
                     std::vector<Finding>* out) {
  if (s.empty() || ref.empty()) return;
  const double a0 = s.t[0], a1 = s.t[s.size() - 1];
  const double b0 = ref.t[0], b1 = ref.t[ref.size() - 1];
  if (a1 < b0 || a0 > b1) {
    out->push_back(finding(file, "no_overlap", a0,
                           "does not overlap " + ref_file + " in time: t " + formatSeconds(a0) +
                               " .. " + formatSeconds(a1) + " s against " + formatSeconds(b0) +
                               " .. " + formatSeconds(b1) + " s"));
    return;
  }
  const double tolerance = o.gap_factor * std::max(medianInterval(s), medianInterval(ref));
  if (a0 - b0 > tolerance) {
    Finding f = finding(file, "late_start", a0,
                        "starts at t=" + formatSeconds(a0) + ", " + formatSeconds(a0 - b0) +
                            " s after " + ref_file + " (t=" + formatSeconds(b0) + ")");
    f.duration_s = a0 - b0;
    out->push_back(f);
  }
  if (b1 - a1 > tolerance) {
    Finding f = finding(file, "early_end", a1,
                        "ends at t=" + formatSeconds(a1) + ", " + formatSeconds(b1 - a1) +
                            " s before " + ref_file + " (t=" + formatSeconds(b1) + ")");
    f.duration_s = b1 - a1;
    out->push_back(f);
  }
}

/// What a joints column is: from the rover's geometry; for a log built without one (tests),
/// from the conventional names (gamma*, lambda*, anything else a wheel).
rover::CoordKind columnKind(const TraverseLog& log, const std::string& c) {
  for (const rover::Coordinate& k : log.geometry.coords)
    if (k.column == c) return k.kind;
  if (c.rfind("gamma", 0) == 0) return rover::CoordKind::kSuspension;
  if (c.rfind("lambda", 0) == 0) return rover::CoordKind::kSteering;
  return rover::CoordKind::kDrive;
}

/// Motion through the middle half of [t0, t1] (a stretch's ends touch the starts and stops of
/// the drive, which lag or lead one wheel against another): some wheel other than `except` (a
/// joints column) turns by more than motion_wheel_rad.
bool moving(const TraverseLog& log, double t0, double t1, const std::string& except,
            const DiagnosticsOptions& o) {
  const double margin = 0.25 * (t1 - t0);
  const Stream& j = log.joints;
  const double* tb = j.t.data();
  const auto i0 = std::lower_bound(tb, tb + j.size(), t0 + margin) - tb;
  const auto i1 = std::upper_bound(tb, tb + j.size(), t1 - margin) - tb;
  for (std::size_t c = 0; c < j.columns.size() && i1 > i0; ++c) {
    if (columnKind(log, j.columns[c]) != rover::CoordKind::kDrive || j.columns[c] == except)
      continue;
    const auto seg = j.values.col(static_cast<Eigen::Index>(c)).segment(i0, i1 - i0);
    if (seg.maxCoeff() - seg.minCoeff() > o.motion_wheel_rad) return true;
  }
  return false;
}

void diagnoseStuck(const TraverseLog& log, const Stream& s, const std::string& file,
                   bool wheels_only, const DiagnosticsOptions& o, std::vector<Finding>* out) {
  for (std::size_t c = 0; c < s.columns.size(); ++c) {
    const std::string& name = s.columns[c];
    if (wheels_only && columnKind(log, name) != rover::CoordKind::kDrive) continue;
    const auto v = s.values.col(static_cast<Eigen::Index>(c));
    Eigen::Index begin = 0;
    for (Eigen::Index k = 1; k <= s.size(); ++k) {
      if (k < s.size() && v[k] == v[begin]) continue;
      const Eigen::Index n = k - begin;
      const double t0 = s.t[begin], t1 = s.t[k - 1];
      if (n >= o.stuck_min_samples && t1 - t0 >= o.stuck_min_s &&
          moving(log, t0, t1, file == "joints.csv" ? name : "", o)) {
        Finding f = finding(file, "stuck", t0,
                            name + " stuck at " + general(v[begin]) + " for " +
                                formatSeconds(t1 - t0) + " s (" + std::to_string(n) +
                                " samples) from t=" + formatSeconds(t0) + " while the rover moves");
        f.duration_s = t1 - t0;
        f.column = name;
        f.value = v[begin];
        out->push_back(f);
      }
      begin = k;
    }
  }
}

void diagnoseSun(const Stream& sun, const RoverConfig& config, std::vector<Finding>* out) {
  if (sun.empty() || !sun.has("valid") || !sun.has("s1") || !sun.has("s2")) return;
  const auto valid = sun.channel("valid");
  const auto s1 = sun.channel("s1");
  const auto s2 = sun.channel("s2");
  if ((valid.array() == 0.0).all()) {
    out->push_back(finding("sun.csv", "sun_invalid", sun.t[0],
                           "no valid reading (all " + std::to_string(sun.size()) +
                               " rows have valid = 0): the sun sensor is not used"));
    return;
  }
  // K-15: the off-boresight angle is (π/2)·|s_m|, so a reading inside the full cone has
  // |s_m| ≤ fov/π; three noise σ of slack keep honest readings at the edge quiet.
  const double fov = config.sun_sensor.field_of_view_rad;
  const double limit = fov / M_PI + 3.0 * config.sun_sensor.noise;
  Eigen::Index k = 0;
  while (k < sun.size()) {
    if (valid[k] != 1.0 || std::hypot(s1[k], s2[k]) <= limit) {
      ++k;
      continue;
    }
    Eigen::Index e = k;
    while (e + 1 < sun.size() && valid[e + 1] == 1.0 && std::hypot(s1[e + 1], s2[e + 1]) > limit)
      ++e;
    const long n = static_cast<long>(e - k + 1);
    Finding f = finding("sun.csv", "sun_out_of_view", sun.t[k],
                        std::to_string(n) + " valid reading" + (n == 1 ? "" : "s") +
                            " outside the " + general(fov * 180.0 / M_PI) +
                            " deg field of view from t=" + formatSeconds(sun.t[k]) +
                            " to t=" + formatSeconds(sun.t[e]));
    f.duration_s = sun.t[e] - sun.t[k];
    out->push_back(f);
    k = e + 1;
  }
}

/// Each joints column's declared noise (rover.yaml joint_sensors): suspension, steering, and
/// the wheels' drive encoders.
std::vector<double> jointNoise(const TraverseLog& log, const Stream& joints,
                               const RoverConfig& config) {
  std::vector<double> noise;
  for (const std::string& c : joints.columns) {
    switch (columnKind(log, c)) {
      case rover::CoordKind::kSuspension:
        noise.push_back(config.joints.angle_noise_rad);
        break;
      case rover::CoordKind::kSteering:
        noise.push_back(config.joints.steeringNoise());
        break;
      case rover::CoordKind::kDrive:
        noise.push_back(config.joints.wheel_noise_rad);
        break;
    }
  }
  return noise;
}

}  // namespace

std::string formatSeconds(double s) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.3f", s);
  std::string out = buf;
  while (out.size() > 1 && out.back() == '0' && out[out.size() - 2] != '.') out.pop_back();
  return out;
}

double medianInterval(const Stream& s) {
  if (s.size() < 2) return 0.0;
  const Eigen::Index n = s.size() - 1;
  const Eigen::VectorXd dt = s.t.tail(n) - s.t.head(n);
  std::vector<double> sorted(dt.data(), dt.data() + n);
  return median(sorted);
}

std::vector<Gap> findGaps(const Stream& s, double factor) {
  std::vector<Gap> gaps;
  const double limit = factor * medianInterval(s);
  for (Eigen::Index k = 0; k + 1 < s.size(); ++k) {
    const double dt = s.t[k + 1] - s.t[k];
    if (dt > limit) gaps.push_back({k, dt});
  }
  return gaps;
}

TimeGaps::TimeGaps(const Stream& s, double factor) {
  for (const Gap& g : findGaps(s, factor)) spans_.emplace_back(s.t[g.before], s.t[g.before + 1]);
}

namespace {

/// The first span that ends after t (spans are in time order and disjoint).
auto firstEndingAfter(const std::vector<std::pair<double, double>>& spans, double t) {
  return std::upper_bound(spans.begin(), spans.end(), t,
                          [](double x, const auto& span) { return x < span.second; });
}

}  // namespace

bool TimeGaps::contains(double t) const {
  const auto it = firstEndingAfter(spans_, t);
  return it != spans_.end() && it->first < t;
}

bool TimeGaps::overlaps(double t0, double t1) const {
  if (!(t1 > t0)) return contains(t0);
  // (a, b) meets (t0, t1) iff a < t1 and t0 < b.
  const auto it = firstEndingAfter(spans_, t0);
  return it != spans_.end() && it->first < t1;
}

void diagnoseTiming(const Stream& s, const std::string& file, const DiagnosticsOptions& o,
                    std::vector<Finding>* out) {
  diagnoseOrder(s, file, out);
  for (const Gap& g : findGaps(s, o.gap_factor)) {
    Finding f =
        finding(file, "gap", s.t[g.before],
                "gap of " + formatSeconds(g.length_s) + " s at t=" + formatSeconds(s.t[g.before]));
    f.duration_s = g.length_s;
    out->push_back(f);
  }
  diagnoseRate(s, file, o, out);
}

void diagnoseSpikes(const Stream& s, const std::string& file,
                    const std::vector<double>& noise_floors, const DiagnosticsOptions& o,
                    std::vector<Finding>* out) {
  const Eigen::Index h = o.spike_half_window;
  if (h < 1 || s.size() < 2 * h + 1 || noise_floors.empty()) return;
  std::vector<double> window, deviation;
  struct Candidate {
    Eigen::Index k;
    double median, sigma;
  };
  std::vector<Candidate> candidates;
  for (std::size_t c = 0; c < s.columns.size(); ++c) {
    const double noise_floor = noise_floors[std::min(c, noise_floors.size() - 1)];
    const auto v = s.values.col(static_cast<Eigen::Index>(c));
    candidates.clear();
    for (Eigen::Index k = 0; k < s.size(); ++k) {
      // The window is the 2h neighbours, shifted inwards at the ends, never the sample itself.
      const Eigen::Index b = std::clamp<Eigen::Index>(k - h, 0, s.size() - 2 * h - 1);
      window.clear();
      for (Eigen::Index i = b; i <= b + 2 * h; ++i) {
        if (i != k) window.push_back(v[i]);
      }
      if (static_cast<Eigen::Index>(window.size()) > 2 * h) window.pop_back();
      const double m = median(window);
      deviation.clear();
      for (const double x : window) deviation.push_back(std::abs(x - m));
      const double sigma = std::max(1.4826 * median(deviation), noise_floor);
      // σ = 0 (a quantised reading at rest, no declared noise): no scale to judge by.
      if (!(sigma > 0.0) || !(std::abs(v[k] - m) > o.spike_k * sigma)) continue;
      // A spike stands out from both sides: an onset (a wheel that starts to turn, a rate that
      // steps) sits at one side's level and moves away from the other's — it is a change, not a
      // spike. Where both sides have h samples, the sample must differ from the median of each
      // by more than the threshold, in the same sense.
      if (k >= h && k + h < s.size()) {
        const auto side = [&](Eigen::Index from) {
          window.clear();
          for (Eigen::Index i = from; i < from + h; ++i) window.push_back(v[i]);
          return v[k] - median(window);
        };
        const double left = side(k - h), right = side(k + 1);
        if (!(left * right > 0.0) ||
            !(std::min(std::abs(left), std::abs(right)) > o.spike_k * sigma))
          continue;
      }
      candidates.push_back({k, m, sigma});
    }
    // A glitch is one sample or two (a rate differenced from a glitched angle); a run of more
    // outlying samples in a row is a real transient — a brief turn, a bump — and is kept.
    for (std::size_t i = 0; i < candidates.size();) {
      std::size_t j = i + 1;
      while (j < candidates.size() && candidates[j].k == candidates[j - 1].k + 1) ++j;
      if (static_cast<int>(j - i) <= o.spike_max_run) {
        for (std::size_t r = i; r < j; ++r) {
          const Candidate& cand = candidates[r];
          const double x = v[cand.k];
          Finding f = finding(file, "spike", s.t[cand.k],
                              "spike in " + s.columns[c] + " at t=" + formatSeconds(s.t[cand.k]) +
                                  ": " + general(x) + ", " + general(std::abs(x - cand.median)) +
                                  " off the local median " + general(cand.median) +
                                  " (robust sigma " + general(cand.sigma) + ")");
          f.column = s.columns[c];
          f.value = x;
          out->push_back(f);
        }
      }
      i = j;
    }
  }
}

Diagnostics diagnose(const TraverseLog& log, const DiagnosticsOptions& o) {
  Diagnostics d;
  std::vector<Finding>& out = d.findings;
  for (const auto& [file, stream] : logStreams(log)) {
    if (stream == nullptr) continue;
    const std::size_t first = out.size();
    diagnoseTiming(*stream, file, o, &out);
    const bool is_joints = stream == &log.joints;
    diagnoseOverlap(*stream, file, is_joints ? log.gyro : log.joints,
                    is_joints ? "gyro.csv" : "joints.csv", o, &out);
    if (stream == &log.gyro || is_joints || (log.accel && stream == &*log.accel))
      diagnoseStuck(log, *stream, file, is_joints, o, &out);
    if (stream == &log.gyro) diagnoseSpikes(*stream, file, {log.config.gyro.noise_rad_s}, o, &out);
    if (is_joints) diagnoseSpikes(*stream, file, jointNoise(log, *stream, log.config), o, &out);
    if (log.accel && stream == &*log.accel)
      diagnoseSpikes(*stream, file, {log.config.accel.noise_mps2}, o, &out);
    if (log.sun && stream == &*log.sun) {
      diagnoseSun(*stream, log.config, &out);
      // Spikes among the valid readings (s1, s2): an outlier that a rest or a straight leg's
      // neighbours all deny. A reading the EKF meets before the heading is pinned would pass
      // its χ² gate and then have the good readings gated out.
      if (stream->has("valid") && stream->has("s1") && stream->has("s2")) {
        const auto valid = stream->channel("valid");
        Stream v;
        v.columns = {"s1", "s2"};
        const Eigen::Index n = (valid.array() == 1.0).count();
        v.t.resize(n);
        v.values.resize(n, 2);
        for (Eigen::Index k = 0, i = 0; k < stream->size(); ++k) {
          if (valid[k] != 1.0) continue;
          v.t[i] = stream->t[k];
          v.values(i, 0) = stream->values(k, stream->col("s1"));
          v.values(i, 1) = stream->values(k, stream->col("s2"));
          ++i;
        }
        diagnoseSpikes(v, file, {log.config.sun_sensor.noise}, o, &out);
      }
    }
    std::stable_sort(out.begin() + static_cast<std::ptrdiff_t>(first), out.end(),
                     [](const Finding& a, const Finding& b) { return a.t < b.t; });
  }
  return d;
}

std::map<std::string, long> Diagnostics::countsByKind() const {
  std::map<std::string, long> counts;
  for (const std::string& k : kFindingKinds) counts[k] = 0;
  for (const Finding& f : findings) ++counts[f.kind];
  return counts;
}

std::map<std::string, std::map<std::string, long>> Diagnostics::countsByFile() const {
  std::map<std::string, std::map<std::string, long>> counts;
  for (const Finding& f : findings) ++counts[f.file][f.kind];
  return counts;
}

std::vector<std::string> Diagnostics::warningLines(int max_lines_per_kind) const {
  std::vector<std::string> lines;
  std::map<std::pair<std::string, std::string>, long> shown;
  for (const Finding& f : findings) {
    if (++shown[{f.file, f.kind}] <= max_lines_per_kind)
      lines.push_back("warning: " + f.file + ": " + f.message);
  }
  for (const auto& [key, n] : shown) {
    if (n > max_lines_per_kind) {
      lines.push_back("warning: " + key.first + ": " + std::to_string(n - max_lines_per_kind) +
                      " more " + key.second + " findings not shown (metrics.json lists them)");
    }
  }
  return lines;
}

}  // namespace traverse::io
