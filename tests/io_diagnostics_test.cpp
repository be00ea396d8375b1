// Stream diagnostics (io/diagnostics.h) on hand-made streams: each kind found where it is and
// nowhere else, the stderr lines, the metrics.json block; the clean bundled logs raise nothing.
#include <cstdlib>
#include <random>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "traverse/eval/metrics.h"
#include "traverse/io/diagnostics.h"
#include "traverse/io/log_reader.h"

namespace traverse::io {
namespace {

using ::testing::HasSubstr;
using ::testing::Not;

Stream regular(std::vector<std::string> columns, double t0, double t1, double rate_hz) {
  Stream s;
  s.columns = std::move(columns);
  const auto n = static_cast<Eigen::Index>(std::lround((t1 - t0) * rate_hz)) + 1;
  s.t = Eigen::VectorXd::LinSpaced(n, t0, t1);
  s.values = Eigen::MatrixXd::Zero(n, static_cast<Eigen::Index>(s.columns.size()));
  return s;
}

/// Keeps the rows whose time satisfies `keep`.
template <typename Keep>
Stream filtered(const Stream& s, Keep keep) {
  std::vector<Eigen::Index> rows;
  for (Eigen::Index k = 0; k < s.size(); ++k)
    if (keep(s.t[k])) rows.push_back(k);
  Stream out;
  out.columns = s.columns;
  out.t.resize(static_cast<Eigen::Index>(rows.size()));
  out.values.resize(static_cast<Eigen::Index>(rows.size()), s.values.cols());
  for (std::size_t i = 0; i < rows.size(); ++i) {
    out.t[static_cast<Eigen::Index>(i)] = s.t[rows[i]];
    out.values.row(static_cast<Eigen::Index>(i)) = s.values.row(rows[i]);
  }
  return out;
}

/// 60 s: rest, a drive at 1 rad/s of every wheel from 10 to 50 s, rest. Gyro 20 Hz, joints,
/// accel 10 Hz, sun 1 Hz (all valid, 30° off the boresight), white noise at the declared σ.
TraverseLog cleanLog() {
  std::mt19937_64 rng(3);
  std::normal_distribution<double> n01(0.0, 1.0);
  TraverseLog log;
  log.config.gyro.noise_rad_s = 0.001;
  log.config.accel.noise_mps2 = 0.01;
  log.gyro = regular({"wz"}, 0, 60, 20);
  for (Eigen::Index k = 0; k < log.gyro.size(); ++k) log.gyro.values(k, 0) = 0.001 * n01(rng);
  log.joints = regular({"gamma0", "gamma1", "gamma2", "lambda1", "lambda2", "psi1", "psi2", "psi3",
                        "psi4", "psi5", "psi6"},
                       0, 60, 10);
  for (Eigen::Index k = 0; k < log.joints.size(); ++k) {
    const double t = log.joints.t[k];
    for (int c = 0; c < 5; ++c) log.joints.values(k, c) = 0.001 * n01(rng);
    for (int c = 5; c < 11; ++c) log.joints.values(k, c) = std::clamp(t - 10.0, 0.0, 40.0);
  }
  log.accel = regular({"ax", "ay", "az"}, 0, 60, 10);
  for (Eigen::Index k = 0; k < log.accel->size(); ++k) {
    for (int c = 0; c < 3; ++c) log.accel->values(k, c) = (c == 2 ? 9.8 : 0.0) + 0.01 * n01(rng);
  }
  log.sun = regular({"s1", "s2", "valid"}, 0, 60, 1);
  for (Eigen::Index k = 0; k < log.sun->size(); ++k)
    log.sun->values.row(k) << 0.236 + 0.005 * n01(rng), 0.236 + 0.005 * n01(rng), 1.0;
  return log;
}

std::vector<Finding> ofKind(const Diagnostics& d, const std::string& kind) {
  std::vector<Finding> out;
  for (const Finding& f : d.findings)
    if (f.kind == kind) out.push_back(f);
  return out;
}

/// Every stderr line, for a failure message.
std::string lines(const Diagnostics& d) {
  std::string out;
  for (const std::string& l : d.warningLines()) out += l + "\n";
  return out;
}

std::string sourceDir() {
  const char* env = std::getenv("TRAVERSE_SOURCE_DIR");
  return env != nullptr ? env : TRAVERSE_SOURCE_DIR;
}

TEST(IoDiagnostics, CleanLogsRaiseNothing) {
  EXPECT_TRUE(diagnose(cleanLog()).findings.empty());
  for (const char* name : {"straight-1m", "multi-stop"}) {
    const Diagnostics d = diagnose(readLog(sourceDir() + "/datasets/logs/" + name));
    EXPECT_TRUE(d.findings.empty()) << name << ": " << lines(d);
  }
}

TEST(IoDiagnostics, GapIsFoundWithItsLengthAndStart) {
  TraverseLog log = cleanLog();
  log.gyro = filtered(log.gyro, [](double t) { return !(t > 5.0 && t < 20.0); });
  const Diagnostics d = diagnose(log);
  ASSERT_EQ(d.findings.size(), 1U) << lines(d);
  EXPECT_EQ(d.findings[0].kind, "gap");
  EXPECT_DOUBLE_EQ(d.findings[0].duration_s, 15.0);
  EXPECT_EQ(d.warningLines(),
            std::vector<std::string>{"warning: gyro.csv: gap of 15.0 s at t=5.0"});
  EXPECT_EQ(d.countsByKind().at("gap"), 1);
  EXPECT_EQ(d.countsByFile().at("gyro.csv").at("gap"), 1);
}

TEST(IoDiagnostics, JitterIsNoGap) {
  TraverseLog log = cleanLog();
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> u(-0.01, 0.01);  // ±20 % of the 0.05 s interval
  for (Eigen::Index k = 1; k + 1 < log.gyro.size(); ++k) log.gyro.t[k] += u(rng);
  EXPECT_TRUE(ofKind(diagnose(log), "gap").empty());
}

TEST(IoDiagnostics, DuplicatedAndBackwardStamps) {
  Stream s = regular({"wz"}, 0, 10, 10);
  s.t[30] = s.t[29];        // duplicated
  s.t[60] = s.t[59] - 0.5;  // backwards
  std::vector<Finding> out;
  diagnoseTiming(s, "gyro.csv", {}, &out);
  std::vector<Finding> order;
  for (const Finding& f : out)
    if (f.kind == "time_order") order.push_back(f);
  ASSERT_EQ(order.size(), 2U);
  EXPECT_EQ(order[0].message, "duplicated stamp t=2.9");
  EXPECT_EQ(order[1].message, "stamp t=5.4 before the previous t=5.9");
}

TEST(IoDiagnostics, RateChange) {
  TraverseLog log = cleanLog();
  // 20 Hz to 30 s, then every other sample: 10 Hz.
  log.gyro =
      filtered(log.gyro, [](double t) { return t <= 30.0 || std::lround(t * 20.0) % 2 == 0; });
  const auto changes = ofKind(diagnose(log), "rate_change");
  ASSERT_EQ(changes.size(), 1U);
  EXPECT_THAT(changes[0].message, HasSubstr("rate changes from 20 Hz to 10 Hz at t="));
  EXPECT_NEAR(changes[0].t, 30.0, 2.5);  // within the 50-sample window holding the change
  EXPECT_TRUE(ofKind(diagnose(log), "gap").empty());
}

TEST(IoDiagnostics, StreamsThatDoNotOverlapStartLateOrEndEarly) {
  TraverseLog log = cleanLog();
  log.sun->t.array() += 1000.0;
  log.accel = filtered(*log.accel, [](double t) { return t >= 10.0 && t <= 30.0; });
  const Diagnostics d = diagnose(log);
  const auto none = ofKind(d, "no_overlap");
  ASSERT_EQ(none.size(), 1U);
  EXPECT_EQ(none[0].file, "sun.csv");
  EXPECT_EQ(none[0].message,
            "does not overlap joints.csv in time: t 1000.0 .. 1060.0 s against 0.0 .. 60.0 s");
  ASSERT_EQ(ofKind(d, "late_start").size(), 1U);
  EXPECT_EQ(ofKind(d, "late_start")[0].message,
            "starts at t=10.0, 10.0 s after joints.csv (t=0.0)");
  ASSERT_EQ(ofKind(d, "early_end").size(), 1U);
  EXPECT_EQ(ofKind(d, "early_end")[0].message, "ends at t=30.0, 30.0 s before joints.csv (t=60.0)");
  EXPECT_EQ(d.findings.size(), 3U);
}

TEST(IoDiagnostics, StuckWheelAndGyroWhileTheRoverMoves) {
  TraverseLog log = cleanLog();
  const int psi3 = log.joints.col("psi3");
  for (Eigen::Index k = 0; k < log.joints.size(); ++k) {
    const double t = log.joints.t[k];
    if (t >= 20.0 && t <= 40.0) log.joints.values(k, psi3) = 10.0;
  }
  for (Eigen::Index k = 0; k < log.gyro.size(); ++k)
    if (log.gyro.t[k] >= 20.0 && log.gyro.t[k] <= 25.0) log.gyro.values(k, 0) = 0.0123;
  const Diagnostics d = diagnose(log);
  const auto stuck = ofKind(d, "stuck");
  ASSERT_EQ(stuck.size(), 2U) << lines(d);
  EXPECT_EQ(stuck[0].file, "gyro.csv");
  EXPECT_EQ(stuck[0].column, "wz");
  EXPECT_THAT(stuck[0].message, HasSubstr("wz stuck at 0.0123 for 5.0 s"));
  EXPECT_EQ(stuck[1].file, "joints.csv");
  EXPECT_EQ(stuck[1].column, "psi3");
  EXPECT_DOUBLE_EQ(stuck[1].duration_s, 20.0);
  EXPECT_EQ(d.findings.size(), 2U);
}

TEST(IoDiagnostics, AReadingHeldAtRestIsNotStuck) {
  TraverseLog log = cleanLog();  // wheels constant for 10 s at each end
  for (Eigen::Index k = 0; k < log.gyro.size(); ++k)
    if (log.gyro.t[k] > 52.0) log.gyro.values(k, 0) = 0.0;  // a quiet, quantised gyro at rest
  EXPECT_TRUE(diagnose(log).findings.empty());
}

TEST(IoDiagnostics, GyroAndAccelerometerSpikes) {
  TraverseLog log = cleanLog();
  log.gyro.values(500, 0) += 2.0;    // t = 25 s
  log.accel->values(300, 1) -= 5.0;  // t = 30 s
  const Diagnostics d = diagnose(log);
  const auto spikes = ofKind(d, "spike");
  ASSERT_EQ(spikes.size(), 2U);
  EXPECT_EQ(spikes[0].file, "gyro.csv");
  EXPECT_DOUBLE_EQ(spikes[0].t, 25.0);
  EXPECT_THAT(spikes[0].message, HasSubstr("spike in wz at t=25.0: 1.99"));
  EXPECT_EQ(spikes[1].file, "accel.csv");
  EXPECT_EQ(spikes[1].column, "ay");
  EXPECT_EQ(d.findings.size(), 2U);
}

TEST(IoDiagnostics, JointAngleSpikeButNotTheDriveRamp) {
  TraverseLog log = cleanLog();  // every ψ ramps at 1 rad/s from 10 to 50 s: no spike
  log.joints.values(200, log.joints.col("gamma1")) += 0.2;  // a potentiometer glitch at 20 s
  const Diagnostics d = diagnose(log);
  ASSERT_EQ(d.findings.size(), 1U) << lines(d);
  EXPECT_EQ(d.findings[0].kind, "spike");
  EXPECT_EQ(d.findings[0].column, "gamma1");
  EXPECT_DOUBLE_EQ(d.findings[0].t, 20.0);
}

TEST(IoDiagnostics, ATurnIsNoSpike) {
  TraverseLog log = cleanLog();
  for (Eigen::Index k = 0; k < log.gyro.size(); ++k)
    if (log.gyro.t[k] >= 20.0 && log.gyro.t[k] < 40.0) log.gyro.values(k, 0) += 0.3;  // steps
  EXPECT_TRUE(ofKind(diagnose(log), "spike").empty());
}

// A glitch is one or two samples; five in a row at 20 Hz are a brief real turn, kept.
TEST(IoDiagnostics, ABriefTransientIsNoSpikeButATwoSampleGlitchIs) {
  TraverseLog log = cleanLog();
  for (int k = 400; k < 405; ++k) log.gyro.values(k, 0) += 0.3;  // 0.25 s at t = 20 s
  EXPECT_TRUE(ofKind(diagnose(log), "spike").empty()) << lines(diagnose(log));
  log.gyro.values(800, 0) += 0.3;  // t = 40 s, two samples
  log.gyro.values(801, 0) += 0.3;
  const auto spikes = ofKind(diagnose(log), "spike");
  ASSERT_EQ(spikes.size(), 2U);
  EXPECT_DOUBLE_EQ(spikes[0].t, 40.0);
  EXPECT_DOUBLE_EQ(spikes[1].t, 40.05);
  EXPECT_THAT(spikes[0].message, HasSubstr("off the local median"));
}

// A rate that settles at a new level one sample after a quiet stretch (a wheel that starts to
// turn, a quantised encoder) is a change, not a spike: it sits at one side's level.
TEST(IoDiagnostics, AnOnsetIsNoSpike) {
  TraverseLog log = cleanLog();
  for (Eigen::Index k = 0; k < log.gyro.size(); ++k) {
    const double t = log.gyro.t[k];
    log.gyro.values(k, 0) = t < 20.0 ? 0.0 : t < 20.3 ? 0.2 : t < 21.0 ? 0.0 : 0.2;
  }
  EXPECT_TRUE(ofKind(diagnose(log), "spike").empty()) << lines(diagnose(log));
}

TEST(IoDiagnostics, SunAllInvalidOrOutOfView) {
  TraverseLog log = cleanLog();
  log.sun->values.col(2).setZero();
  auto d = diagnose(log);
  ASSERT_EQ(d.findings.size(), 1U);
  EXPECT_EQ(d.findings[0].kind, "sun_invalid");
  EXPECT_THAT(d.findings[0].message, HasSubstr("no valid reading (all 61 rows have valid = 0)"));

  log = cleanLog();
  for (int k = 20; k < 23; ++k) log.sun->values.row(k) << 0.7, -0.7, 1.0;  // 89° off boresight
  log.sun->values.row(40) << 0.7, -0.7, 0.0;  // flagged invalid: nothing to say
  d = diagnose(log);
  ASSERT_EQ(d.findings.size(), 1U);
  EXPECT_EQ(d.findings[0].kind, "sun_out_of_view");
  EXPECT_EQ(d.findings[0].message,
            "3 valid readings outside the 160 deg field of view from t=20.0 to t=22.0");
  EXPECT_DOUBLE_EQ(d.findings[0].duration_s, 2.0);
}

TEST(IoDiagnostics, WarningLinesAreCappedPerKindButAllCounted) {
  TraverseLog log = cleanLog();
  for (int i = 0; i < 15; ++i) log.gyro.values(100 + 50 * i, 0) += 1.0;
  const Diagnostics d = diagnose(log);
  EXPECT_EQ(d.countsByKind().at("spike"), 15);
  const auto lines = d.warningLines(10);
  ASSERT_EQ(lines.size(), 11U);
  EXPECT_EQ(lines.back(),
            "warning: gyro.csv: 5 more spike findings not shown (metrics.json lists them)");
}

TEST(IoDiagnostics, MetricsJsonHasTheDiagnosticsBlock) {
  TraverseLog log = cleanLog();
  log.gyro = filtered(log.gyro, [](double t) { return !(t > 5.0 && t < 20.0); });
  eval::MetricsReport report;
  report.log = "synthetic";
  report.evaluated = false;
  report.diagnostics = diagnose(log);
  const std::string json = eval::formatMetricsJson(report);
  EXPECT_THAT(json, Not(HasSubstr("estimators")));
  EXPECT_THAT(json, HasSubstr("\"diagnostics\": {"));
  EXPECT_THAT(json, HasSubstr("\"counts\": {\n      \"gap\": 1,\n      \"time_order\": 0,"));
  EXPECT_THAT(json, HasSubstr("\"by_file\": {\n      \"gyro.csv\": {\n        \"gap\": 1\n"));
  EXPECT_THAT(json, HasSubstr("\"findings\": [\n      {\n        \"file\": \"gyro.csv\",\n"
                              "        \"kind\": \"gap\",\n        \"t\": 5.0,\n"
                              "        \"duration_s\": 15.0,\n"
                              "        \"message\": \"gap of 15.0 s at t=5.0\"\n      }\n    ]"));
}

}  // namespace
}  // namespace traverse::io
