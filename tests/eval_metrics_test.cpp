// Evaluation against truth: truth interpolation, posyaw alignment, each metric on a
// hand-computed case, metrics.json and the Monte Carlo aggregation, `traverse evaluate`.
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <limits>
#include <random>

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "traverse/core/error.h"
#include "traverse/core/so3.h"
#include "traverse/estimators/trajectory.h"
#include "traverse/eval/aggregate.h"
#include "traverse/eval/alignment.h"
#include "traverse/eval/metrics.h"
#include "traverse/io/csv.h"
#include "traverse/io/diagnostics.h"

namespace traverse::eval {
namespace {

namespace fs = std::filesystem;
using ::testing::ElementsAre;
using ::testing::ElementsAreArray;
using ::testing::HasSubstr;
using ::testing::Not;
using ::testing::StartsWith;

constexpr double kDeg = M_PI / 180.0;
constexpr double kTol = 1e-9;

struct Pose {
  double t;
  Vec3d p;
  Quatd q;
};

Quatd yawQuat(double yaw) {
  return Quatd(Eigen::AngleAxisd(yaw, Vec3d::UnitZ()));
}

/// Straight drive along `heading` at 1 m/s for `length` m, a pose every `dt` s, facing forward.
std::vector<Pose> straight(double heading, double length, double dt) {
  std::vector<Pose> out;
  const Vec3d dir(std::cos(heading), std::sin(heading), 0.0);
  for (int k = 0; k * dt <= length + 1e-12; ++k) {
    out.push_back({k * dt, k * dt * dir, yawQuat(heading)});
  }
  return out;
}

struct TruthGroups {
  std::optional<double> xi;   ///< the same contact angle on all wheels
  std::optional<Vec3d> bias;  ///< constant gyro bias
  bool velocity = false;      ///< body velocity from the position differences
};

io::Stream truthStream(const std::vector<Pose>& poses, const TruthGroups& g = {}) {
  io::Stream s;
  s.columns = {"x", "y", "z", "qw", "qx", "qy", "qz"};
  if (g.xi) s.columns.insert(s.columns.end(), {"xi1", "xi2", "xi3", "xi4", "xi5", "xi6"});
  if (g.bias) s.columns.insert(s.columns.end(), {"bx", "by", "bz"});
  if (g.velocity) s.columns.insert(s.columns.end(), {"vx", "vy", "vz"});
  const auto n = static_cast<Eigen::Index>(poses.size());
  s.t.resize(n);
  s.values.resize(n, static_cast<Eigen::Index>(s.columns.size()));
  for (Eigen::Index k = 0; k < n; ++k) {
    const Pose& a = poses[static_cast<std::size_t>(k)];
    std::vector<double> row = {a.p.x(), a.p.y(), a.p.z(), a.q.w(), a.q.x(), a.q.y(), a.q.z()};
    if (g.xi) row.insert(row.end(), 6, *g.xi);
    if (g.bias) row.insert(row.end(), {g.bias->x(), g.bias->y(), g.bias->z()});
    if (g.velocity) {
      const std::size_t i = std::min<std::size_t>(static_cast<std::size_t>(k), poses.size() - 2);
      const Vec3d v_body =
          a.q.conjugate() * (poses[i + 1].p - poses[i].p) / (poses[i + 1].t - poses[i].t);
      row.insert(row.end(), {v_body.x(), v_body.y(), v_body.z()});
    }
    s.t[k] = a.t;
    for (std::size_t c = 0; c < row.size(); ++c) s.values(k, static_cast<Eigen::Index>(c)) = row[c];
  }
  return s;
}

/// An estimate equal to the poses, with xi/bias equal to the truth groups.
est::Trajectory trajectoryOf(const std::vector<Pose>& poses, const TruthGroups& g = {},
                             bool covariance = false) {
  est::Trajectory tr{"ekf", covariance, {}};
  for (const Pose& a : poses) {
    est::TrajectoryNode n;
    n.t = a.t;
    n.p_site = a.p;
    n.q_site_body = a.q;
    n.xi = rover::WheelVectord::Constant(6, g.xi.value_or(0.0));
    n.bias = g.bias.value_or(Vec3d::Zero());
    if (covariance) n.covariance = 0.01 * Mat6d::Identity(), n.bias_sigma.setConstant(1e-3);
    tr.nodes.push_back(n);
  }
  return tr;
}

double metric(const Metrics& m, std::string_view key) {
  const auto v = m.get(key);
  EXPECT_TRUE(v.has_value()) << key;
  return v.value_or(std::numeric_limits<double>::quiet_NaN());
}

// --- truth interpolation -------------------------------------------------------------------

TEST(EvalTruth, InterpolatesLinearlyAndSlerpsAndClamps) {
  const std::vector<Pose> poses = {{0.0, Vec3d(0, 0, 0), yawQuat(0.0)},
                                   {2.0, Vec3d(2, 4, 0), yawQuat(M_PI / 2)}};
  const TruthTrajectory truth(truthStream(poses, {0.1, Vec3d(0, 0, 0.002), true}));
  EXPECT_TRUE(truth.position(0.5).isApprox(Vec3d(0.5, 1.0, 0.0)));
  EXPECT_NEAR(so3::rollPitchYaw(truth.attitude(1.0)).z(), M_PI / 4, kTol);
  EXPECT_NEAR(so3::rollPitchYaw(truth.attitude(0.5)).z(), M_PI / 8, kTol);
  EXPECT_TRUE(truth.position(-5.0).isApprox(Vec3d::Zero()));
  EXPECT_TRUE(truth.position(9.0).isApprox(Vec3d(2, 4, 0)));
  EXPECT_DOUBLE_EQ(truth.contactAngles(1.3)[5], 0.1);
  EXPECT_DOUBLE_EQ(truth.bias(7.0).z(), 0.002);
  EXPECT_NEAR(truth.pathLength(0.0, 2.0), std::sqrt(20.0), kTol);
  EXPECT_NEAR(truth.pathLength(0.5, 1.5), std::sqrt(20.0) / 2, kTol);
  EXPECT_NEAR(truth.distanceTravelled(10.0), std::sqrt(20.0), kTol);
}

TEST(EvalTruth, KnowsWhichOptionalGroupsExist) {
  const auto poses = straight(0.0, 2.0, 1.0);
  const TruthTrajectory bare(truthStream(poses));
  EXPECT_FALSE(bare.hasContactAngles() || bare.hasBias() || bare.hasVelocity());
  EXPECT_FALSE(bare.hasBodyRate());
  EXPECT_THROW(bare.bias(0.0), std::logic_error);
  EXPECT_THROW(bare.contactAngles(0.0), std::logic_error);
  // Without velocities the site velocity is the polyline slope.
  EXPECT_TRUE(bare.velocitySite(0.5).isApprox(Vec3d::UnitX()));
  const TruthTrajectory full(truthStream(poses, {0.0, Vec3d::Zero(), true}));
  EXPECT_TRUE(full.hasContactAngles() && full.hasBias() && full.hasVelocity());
  EXPECT_TRUE(full.velocitySite(0.5).isApprox(Vec3d::UnitX()));
  EXPECT_THROW(TruthTrajectory(io::Stream{}), std::invalid_argument);
}

// --- alignment -------------------------------------------------------------------------------

TEST(EvalAlignment, RecoversYawAndTranslation) {
  const std::vector<Vec3d> truth = {{0, 0, 0}, {1, 0, 0.1}, {2, 1, 0}, {2, 3, -0.2}};
  const PosYawAlignment known{0.3, Vec3d(1, -2, 0.5)};
  std::vector<Vec3d> estimate;  // truth = known.apply(estimate)
  for (const Vec3d& p : truth) {
    estimate.push_back(Eigen::AngleAxisd(-0.3, Vec3d::UnitZ()) * (p - known.translation));
  }
  const PosYawAlignment a = alignPosYaw(estimate, truth);
  EXPECT_NEAR(a.yaw, 0.3, kTol);
  EXPECT_TRUE(a.translation.isApprox(known.translation, kTol));
  EXPECT_NEAR(absoluteTrajectoryErrorPosYaw(estimate, truth), 0.0, kTol);
  EXPECT_THROW(alignPosYaw({}, {}), std::invalid_argument);
}

TEST(EvalAlignment, HeightErrorsAlternatingSignRemainAfterAlignment) {
  // ±0.1 m in z with zero mean: no yaw or translation can remove it, so ATE = 0.1 m.
  std::vector<Vec3d> truth, estimate;
  for (int k = 0; k < 6; ++k) {
    truth.emplace_back(k, 0.5 * k, 0.0);
    estimate.emplace_back(k, 0.5 * k, k % 2 == 0 ? 0.1 : -0.1);
  }
  EXPECT_NEAR(absoluteTrajectoryErrorPosYaw(estimate, truth), 0.1, kTol);
}

// --- metrics ---------------------------------------------------------------------------------

TEST(EvalMetrics, IdenticalEstimateHasZeroErrorsAndEveryKey) {
  const TruthGroups groups{0.05, Vec3d(0, 0, 0.002), true};
  const auto poses = straight(0.4, 6.0, 0.5);
  const Metrics m =
      evaluate(trajectoryOf(poses, groups, true), TruthTrajectory(truthStream(poses, groups)));
  // Every key but the rest windows' (restBiasConsistency, from a segmentation).
  std::vector<std::string_view> keys(kMetricKeys.begin(), kMetricKeys.end());
  std::erase(keys, "rest_bias_z_within_3sigma_pct");
  // … and those of position-only truth (eval/position_truth.h).
  std::erase_if(keys, [](std::string_view k) {
    return k == "ate_posyaw_horizontal_m" || k == "ate_first_span_m" || k.starts_with("gps_");
  });
  EXPECT_THAT(m.keys(), ElementsAreArray(keys));
  for (const auto& [key, value] : m.entries) {
    if (key == "nees_dof" || key == "bias_z_within_3sigma_pct") continue;
    EXPECT_NEAR(value, 0.0, kTol) << key;
  }
  EXPECT_EQ(metric(m, "nees_dof"), 3.0);
  EXPECT_EQ(metric(m, "bias_z_within_3sigma_pct"), 100.0);
}

// Hand-checked: the estimate climbs 1 cm per metre above a flat truth, so the final vertical
// error after 8 m is 8 cm; the bias is off by 3.5 mrad/s on nodes 0..3 and by 0.5 mrad/s on the
// rest, with σ 1 mrad/s: 5 of the 9 nodes are within 3σ.
TEST(EvalMetrics, FinalVerticalErrorAndBiasConsistency) {
  const TruthGroups groups{std::nullopt, Vec3d(0, 0, 0.01), false};
  const auto poses = straight(0.0, 8.0, 1.0);  // 9 nodes
  est::Trajectory tr = trajectoryOf(poses, groups);
  for (size_t k = 0; k < tr.nodes.size(); ++k) {
    tr.nodes[k].p_site.z() += 0.01 * static_cast<double>(k);
    tr.nodes[k].bias.z() += k < 4 ? 0.0035 : 0.0005;
    tr.nodes[k].bias_sigma.z() = 0.001;
  }
  const Metrics m = evaluate(tr, TruthTrajectory(truthStream(poses, groups)));
  EXPECT_NEAR(metric(m, "final_vertical_error_m"), 0.08, kTol);
  EXPECT_NEAR(metric(m, "bias_z_within_3sigma_pct"), 100.0 * 5 / 9, kTol);
  // Rest windows: 1 mrad/s off at σ 0.2 mrad/s (5σ) and at σ 0.5 mrad/s (2σ); one heading-less.
  std::vector<est::RestWindow> rests(3);
  rests[0].t_start = 0, rests[0].t_end = 2, rests[0].bias.z() = 0.011,
  rests[0].bias_sigma.z() = 2e-4;
  rests[1].t_start = 4, rests[1].t_end = 6, rests[1].bias.z() = 0.009,
  rests[1].bias_sigma.z() = 5e-4;
  rests[2].bias_axes[2] = false;
  const auto [within, windows] =
      restBiasConsistency(rests, TruthTrajectory(truthStream(poses, groups)));
  EXPECT_EQ(within, 1);
  EXPECT_EQ(windows, 2);
}

TEST(EvalMetrics, ConstantOffsetIsRemovedByInitialTranslation) {
  const auto poses = straight(1.0, 8.0, 1.0);
  est::Trajectory tr = trajectoryOf(poses);
  for (auto& n : tr.nodes) n.p_site += Vec3d(1, 2, 0);
  const Metrics m = evaluate(tr, TruthTrajectory(truthStream(poses)));
  for (const auto& [key, value] : m.entries) EXPECT_NEAR(value, 0.0, kTol) << key;
}

TEST(EvalMetrics, YawRotationAboutStart) {
  // The whole estimate rotated by ψ about the start: final error 2·10·sin(ψ/2), cross-track
  // 10 sin ψ, yaw error ψ everywhere; relative motion and the posyaw-aligned ATE are exact.
  const double psi = 10 * kDeg;
  const auto truth_poses = straight(0.0, 10.0, 0.5);
  est::Trajectory tr = trajectoryOf(straight(0.0, 10.0, 1.0));
  for (auto& n : tr.nodes) {
    n.p_site = yawQuat(psi) * n.p_site;
    n.q_site_body = yawQuat(psi) * n.q_site_body;
  }
  const Metrics m = evaluate(tr, TruthTrajectory(truthStream(truth_poses)));
  EXPECT_NEAR(metric(m, "final_position_error_m"), 20 * std::sin(psi / 2), kTol);
  EXPECT_NEAR(metric(m, "final_error_pct_of_path"), 20 * std::sin(psi / 2) / 10 * 100, kTol);
  EXPECT_NEAR(metric(m, "max_cross_track_m"), 10 * std::sin(psi), kTol);
  EXPECT_NEAR(metric(m, "position_rmse_m"), 2 * std::sin(psi / 2) * std::sqrt(35.0), kTol);
  EXPECT_NEAR(metric(m, "distance_error_pct"), 0.0, kTol);
  EXPECT_NEAR(metric(m, "yaw_rmse_deg"), 10.0, kTol);
  EXPECT_NEAR(metric(m, "roll_rmse_deg"), 0.0, kTol);
  EXPECT_NEAR(metric(m, "ate_posyaw_m"), 0.0, kTol);
  EXPECT_NEAR(metric(m, "rpe_pct_per_m"), 0.0, kTol);
}

TEST(EvalMetrics, AnUnmeasuredStartHeadingIsTurnedOntoTheTruthsLikeTheStartPosition) {
  // No sun: the estimate starts at heading 0 (the gauge) where the truth starts at 20°, and
  // elsewhere (the start position is a gauge too). Turned about its start onto the truth's start
  // heading, an estimate that is the truth in its own frame has no error at all — and its
  // position covariance turns with it: a σ of 1 m along its own x, 1 cm across, is 1 m along
  // the truth's 20° line, so an error along that line is consistent.
  const double psi = 20 * kDeg;
  const auto truth_poses = straight(psi, 10.0, 0.5);
  est::Trajectory tr = trajectoryOf(straight(0.0, 10.0, 1.0), {}, true);
  for (auto& n : tr.nodes) {
    n.p_site += Vec3d(5, -3, 1);
    n.covariance.topLeftCorner<3, 3>() = Vec3d(1.0, 1e-4, 1e-4).asDiagonal();
  }
  EvaluateOptions gauge;
  gauge.heading_is_gauge = true;
  const Metrics m = evaluate(tr, TruthTrajectory(truthStream(truth_poses)), gauge);
  for (const char* key : {"final_position_error_m", "position_rmse_m", "max_cross_track_m",
                          "yaw_rmse_deg", "rpe_pct_per_m", "ate_posyaw_m", "nees_position_mean"})
    EXPECT_NEAR(metric(m, key), 0.0, 1e-9) << key;
  // Without the gauge option the same estimate is 20° off (as YawRotationAboutStart).
  const Metrics raw = evaluate(tr, TruthTrajectory(truthStream(truth_poses)));
  EXPECT_NEAR(metric(raw, "yaw_rmse_deg"), 20.0, 1e-9);
  // An error of 0.5 m along the truth's heading at the end: NEES (0.5/1)² at that node only.
  tr.nodes.back().p_site += Vec3d(0.5, 0, 0);
  const Metrics along = evaluate(tr, TruthTrajectory(truthStream(truth_poses)), gauge);
  EXPECT_NEAR(metric(along, "final_position_error_m"), 0.5, 1e-9);
  EXPECT_NEAR(metric(along, "nees_position_mean"), 0.25 / static_cast<double>(tr.nodes.size()),
              1e-9);
}
TEST(EvalMetrics, DriftOnStraightPathGivesKnownCrossTrackDistanceAndRpe) {
  // Heading 30°, 10 m. The estimate drifts 2 % along track and 5 % sideways.
  const double heading = 30 * kDeg;
  const Vec3d along(std::cos(heading), std::sin(heading), 0), lateral(-along.y(), along.x(), 0);
  const auto truth_poses = straight(heading, 10.0, 0.5);
  est::Trajectory tr = trajectoryOf(straight(heading, 10.0, 1.0));
  for (auto& n : tr.nodes) n.p_site += n.t * (0.02 * along + 0.05 * lateral) + Vec3d(3, 3, 3);
  for (const bool with_velocity : {false, true}) {
    const Metrics m =
        evaluate(tr, TruthTrajectory(truthStream(truth_poses, {{}, {}, with_velocity})));
    const double final_error = 10 * std::hypot(0.02, 0.05);
    EXPECT_NEAR(metric(m, "max_cross_track_m"), 0.5, kTol);
    EXPECT_NEAR(metric(m, "final_position_error_m"), final_error, kTol);
    EXPECT_NEAR(metric(m, "final_error_pct_of_path"), final_error / 10 * 100, kTol);
    EXPECT_NEAR(metric(m, "distance_error_pct"), (std::hypot(1.02, 0.05) - 1) * 100, kTol);
    EXPECT_NEAR(metric(m, "position_rmse_m"), std::hypot(0.02, 0.05) * std::sqrt(35.0), kTol);
    // 1 m segments: each relative error is the per-metre drift, sqrt(0.02² + 0.05²) × 100 %.
    EXPECT_NEAR(metric(m, "rpe_pct_per_m"), 100 * std::hypot(0.02, 0.05), kTol);
  }
}

TEST(EvalMetrics, ShortPathUsesQuarterOfPathForRpe) {
  // 2 m path < 4 m: segment 0.5 m. Nodes every 0.25 m; estimate stretched 10 % along track.
  const auto poses = straight(0.0, 2.0, 0.25);
  est::Trajectory tr = trajectoryOf(poses);
  for (auto& n : tr.nodes) n.p_site *= 1.1;
  const Metrics m = evaluate(tr, TruthTrajectory(truthStream(poses)));
  EXPECT_NEAR(metric(m, "rpe_pct_per_m"), 10.0, kTol);
  EXPECT_NEAR(metric(m, "distance_error_pct"), 10.0, kTol);
}

TEST(EvalMetrics, RestingTruthUsesHeadingAndOmitsPercentages) {
  // The rover stands still facing +y: lateral is ±x, so only the x error is cross-track.
  std::vector<Pose> poses;
  for (int k = 0; k <= 10; ++k) poses.push_back({double(k), Vec3d(5, 5, 0), yawQuat(M_PI / 2)});
  est::Trajectory tr = trajectoryOf(poses);
  for (auto& n : tr.nodes) n.p_site += Vec3d(0.03 * n.t, n.t > 0 ? 0.5 : 0.0, 0.0);
  const Metrics m = evaluate(tr, TruthTrajectory(truthStream(poses, {{}, {}, true})));
  EXPECT_NEAR(metric(m, "max_cross_track_m"), 0.3, kTol);
  EXPECT_FALSE(m.has("distance_error_pct"));
  EXPECT_FALSE(m.has("final_error_pct_of_path"));
  EXPECT_FALSE(m.has("rpe_pct_per_m"));
  EXPECT_NEAR(metric(m, "final_position_error_m"), std::hypot(0.3, 0.5), kTol);
}

TEST(EvalMetrics, ConstantYawErrorAcrossTheWrap) {
  // Truth yaw 170° … 190° with roll 2°, pitch −4°; the estimate is yawed 3° about site z,
  // which changes only the Z-Y-X yaw. Wrapping keeps the error 3°, not 357°.
  std::vector<Pose> poses;
  for (int k = 0; k <= 10; ++k) {
    const double yaw = (170.0 + 2.0 * k) * kDeg;
    poses.push_back({double(k), Vec3d(k, 0, 0), so3::fromRollPitchYaw(2 * kDeg, -4 * kDeg, yaw)});
  }
  est::Trajectory tr = trajectoryOf(poses);
  for (auto& n : tr.nodes) n.q_site_body = yawQuat(3 * kDeg) * n.q_site_body;
  const Metrics m = evaluate(tr, TruthTrajectory(truthStream(poses)));
  EXPECT_NEAR(metric(m, "yaw_rmse_deg"), 3.0, kTol);
  EXPECT_NEAR(metric(m, "roll_rmse_deg"), 0.0, kTol);
  EXPECT_NEAR(metric(m, "pitch_rmse_deg"), 0.0, kTol);
}

TEST(EvalMetrics, NeesKnownValues) {
  const Quatd q_true = so3::fromRollPitchYaw(5 * kDeg, 0.0, 40 * kDeg);
  const std::vector<Pose> poses = {
      {0, Vec3d(1, 1, 0), q_true}, {1, Vec3d(1, 1, 0), q_true}, {2, Vec3d(1, 1, 0), q_true}};
  est::Trajectory tr = trajectoryOf(poses, {}, true);
  tr.nodes[0].covariance.setZero();  // given initial pose: skipped
  // Node 1: e_p = (1,0,0), P = diag(4,1,1) → 1/4; e_θ = (0,0.1,0), P = diag(.01,.04,.01) → 1/4.
  tr.nodes[1].p_site -= Vec3d(1, 0, 0);
  tr.nodes[1].q_site_body = so3::boxplus(q_true, Vec3d(0, -0.1, 0));
  tr.nodes[1].covariance.diagonal() << 4, 1, 1, 0.01, 0.04, 0.01;
  // Node 2: e_p = (1,1,0), P = [2 1 0; 1 2 0; 0 0 1] → 2/3; e_θ = (0.02,0,0), P_xx = 1e-4 → 4.
  tr.nodes[2].p_site -= Vec3d(1, 1, 0);
  tr.nodes[2].q_site_body = so3::boxplus(q_true, Vec3d(-0.02, 0, 0));
  Mat6d& P = tr.nodes[2].covariance;
  P.setIdentity();
  P.topLeftCorner<2, 2>() << 2, 1, 1, 2;
  P(3, 3) = 1e-4;
  const Metrics m = evaluate(tr, TruthTrajectory(truthStream(poses)));
  EXPECT_NEAR(metric(m, "nees_position_mean"), (0.25 + 2.0 / 3.0) / 2, 1e-12);
  EXPECT_NEAR(metric(m, "nees_attitude_mean"), (0.25 + 4.0) / 2, 1e-9);
  EXPECT_EQ(metric(m, "nees_dof"), 3.0);
  // A singular attitude block drops only that node's attitude term.
  tr.nodes[2].covariance.bottomRightCorner<3, 3>().setZero();
  const Metrics m2 = evaluate(tr, TruthTrajectory(truthStream(poses)));
  EXPECT_NEAR(metric(m2, "nees_attitude_mean"), 0.25, 1e-9);
  EXPECT_NEAR(metric(m2, "nees_position_mean"), (0.25 + 2.0 / 3.0) / 2, 1e-12);
}

TEST(EvalMetrics, BiasAndContactAngleErrors) {
  const TruthGroups groups{0.1, Vec3d(0, 0, 0.002), false};
  const auto poses = straight(0.0, 5.0, 1.0);  // 6 nodes
  est::Trajectory tr = trajectoryOf(poses, groups);
  for (std::size_t k = 0; k < tr.nodes.size(); ++k) {
    tr.nodes[k].bias.z() = k % 2 == 0 ? 0.003 : -0.001;  // |error| 0.001, 0.003 rad/s
    tr.nodes[k].xi.fill(k % 2 == 0 ? 0.11 : 0.07);       // error 0.01, −0.03 rad
  }
  const Metrics m = evaluate(tr, TruthTrajectory(truthStream(poses, groups)));
  EXPECT_NEAR(metric(m, "bias_z_error_dps"), 0.002 / kDeg, kTol);
  EXPECT_NEAR(metric(m, "contact_angle_rmse_deg"), std::sqrt(0.0005) / kDeg, kTol);
}

TEST(EvalMetrics, MissingTruthGroupsAndCovarianceOmitKeys) {
  const auto poses = straight(0.0, 5.0, 1.0);
  const Metrics m = evaluate(trajectoryOf(poses), TruthTrajectory(truthStream(poses)));
  EXPECT_THAT(
      m.keys(),
      ElementsAre("distance_error_pct", "final_position_error_m", "final_error_pct_of_path",
                  "max_cross_track_m", "position_rmse_m", "roll_rmse_deg", "pitch_rmse_deg",
                  "yaw_rmse_deg", "ate_posyaw_m", "rpe_pct_per_m", "final_vertical_error_m"));
  EXPECT_TRUE(evaluate(est::Trajectory{}, TruthTrajectory(truthStream(poses))).entries.empty());
}

TEST(EvalMetrics, EvaluateAllNamesSmootherAndMeasuresPath) {
  const auto poses = straight(0.0, 5.0, 1.0);
  est::Trajectory dr = trajectoryOf(poses), smoothed = trajectoryOf(poses);
  dr.name = "dr";
  smoothed.name = "smoothed";
  const MetricsReport r =
      evaluateAll("log-a", {dr, smoothed}, TruthTrajectory(truthStream(straight(0.0, 7.0, 1.0))));
  ASSERT_EQ(r.estimators.size(), 2u);
  EXPECT_EQ(r.estimators[0].estimator, "dr");
  EXPECT_EQ(r.estimators[1].estimator, "smoother");
  EXPECT_NEAR(r.path_length_m, 5.0, kTol);  // over the trajectories' span, not the whole truth
  EXPECT_THAT(formatMetricsTable(r), HasSubstr("smoother"));
}

// --- JSON ------------------------------------------------------------------------------------

TEST(EvalJson, MetricsReportRoundTripsThroughTheReader) {
  MetricsReport r{"lo\"g\n", 12.25, {}};
  r.estimators.push_back({"dr", {{{"final_position_error_m", 0.1}, {"x", 1e300}}}});
  r.estimators.push_back({"ekf", {{{"nees", std::numeric_limits<double>::quiet_NaN()}}}});
  io::Diagnostics d;
  io::Finding f;
  f.file = "gyro.csv", f.kind = "spike", f.t = 3.25, f.column = "wz", f.value = -2.0;
  f.message = "spike of 2 rad/s", f.not_used = true;
  d.findings.push_back(f);
  f = io::Finding{};
  f.file = "joints.csv", f.kind = "gap", f.t = 5, f.duration_s = 15, f.message = "gap";
  d.findings.push_back(f);
  r.diagnostics = d;
  r.run = RunSummary{100.5, 33.0, 7, 6, 1, 12.5};
  const MetricsReport back = parseMetricsJson(formatMetricsJson(r), "m.json");
  EXPECT_EQ(back.log, r.log);
  EXPECT_EQ(back.path_length_m, 12.25);
  ASSERT_EQ(back.estimators.size(), 2u);
  EXPECT_EQ(back.estimators[0].estimator, "dr");
  EXPECT_EQ(back.estimators[0].metrics.get("final_position_error_m"), 0.1);  // exact: round trip
  EXPECT_EQ(back.estimators[0].metrics.get("x"), 1e300);
  EXPECT_TRUE(std::isnan(*back.estimators[1].metrics.get("nees")));  // written as null
  ASSERT_TRUE(back.diagnostics && back.diagnostics->findings.size() == 2u);
  EXPECT_EQ(back.diagnostics->findings[0].column, "wz");
  EXPECT_EQ(back.diagnostics->findings[0].value, -2.0);
  EXPECT_TRUE(back.diagnostics->findings[0].not_used);
  EXPECT_EQ(back.diagnostics->findings[1].duration_s, 15.0);
  EXPECT_FALSE(back.diagnostics->findings[1].not_used);
  ASSERT_TRUE(back.run);
  EXPECT_EQ(back.run->duration_s, 100.5);
  EXPECT_EQ(back.run->segments, 7);
  EXPECT_EQ(back.run->smoother_fallbacks, 1);
  EXPECT_EQ(back.run->slip_updates_gated_pct, 12.5);
  // Without truth: no estimators, evaluated false.
  MetricsReport none;
  none.log = "x", none.evaluated = false;
  EXPECT_FALSE(parseMetricsJson(formatMetricsJson(none), "m.json").evaluated);
}

TEST(EvalJson, AReaderNamesTheFileOfABadDocument) {
  for (const std::string bad : {"{", "[]", "{\"log\": 3}",
                                "{\"log\": \"a\", \"estimators\": {\"dr\": {\"x\": \"y\"}}, "
                                "\"path_length_m\": 1}"}) {
    try {
      parseMetricsJson(bad, "out/a/metrics.json");
      ADD_FAILURE() << "accepted " << bad;
    } catch (const InputError& e) {
      EXPECT_THAT(std::string(e.what()), StartsWith("out/a/metrics.json: ")) << bad;
    }
  }
}

TEST(EvalJson, MetricsReportExactText) {
  MetricsReport r{"straight-1m", 1.5, {}};
  r.estimators.push_back({"dr", {{{"final_position_error_m", 0.25}, {"nees_dof", 3.0}}}});
  r.estimators.push_back(
      {"smoother", {{{"yaw_rmse_deg", std::numeric_limits<double>::infinity()}}}});
  r.estimators.push_back({"ekf", {}});
  EXPECT_EQ(formatMetricsJson(r),
            "{\n"
            "  \"log\": \"straight-1m\",\n"
            "  \"path_length_m\": 1.5,\n"
            "  \"estimators\": {\n"
            "    \"dr\": {\n"
            "      \"final_position_error_m\": 0.25,\n"
            "      \"nees_dof\": 3.0\n"
            "    },\n"
            "    \"smoother\": {\n"
            "      \"yaw_rmse_deg\": null\n"
            "    },\n"
            "    \"ekf\": {}\n"
            "  }\n"
            "}\n");
  const fs::path file = fs::temp_directory_path() / ("eval_json_" + std::to_string(::getpid()));
  writeMetricsJson(file, r);
  std::ifstream in(file);
  EXPECT_EQ(std::string(std::istreambuf_iterator<char>(in), {}), formatMetricsJson(r));
  EXPECT_FALSE(fs::exists(file.string() + ".tmp"));
  fs::remove(file);
}

// --- Monte Carlo -------------------------------------------------------------------------------

TEST(EvalAggregate, MeanSampleStdMedianMax) {
  const Statistics s = summarize({4, 1, 10, 3, 2});
  EXPECT_DOUBLE_EQ(s.mean, 4.0);
  EXPECT_DOUBLE_EQ(s.stddev, std::sqrt(50.0 / 4.0));  // Σ(x − 4)² = 50, N − 1 = 4
  EXPECT_DOUBLE_EQ(s.median, 3.0);
  EXPECT_DOUBLE_EQ(s.max, 10.0);
  EXPECT_EQ(s.count, 5u);
  EXPECT_DOUBLE_EQ(summarize({4, 1, 3, 2}).median, 2.5);
  const Statistics one = summarize({7});
  EXPECT_DOUBLE_EQ(one.median, 7.0);
  EXPECT_TRUE(std::isnan(one.stddev));
  const Statistics broken = summarize({1, std::numeric_limits<double>::quiet_NaN()});
  EXPECT_TRUE(std::isnan(broken.mean) && std::isnan(broken.median) && std::isnan(broken.max));
}

TEST(EvalAggregate, AccuracyJsonExactTextAndTable) {
  auto run = [](double final_error, std::optional<double> rpe) {
    MetricsReport r{"log", 1.0, {}};
    Metrics m;
    if (rpe) m.set("rpe_pct_per_m", *rpe);
    m.set("final_position_error_m", final_error);
    r.estimators.push_back({"ekf", m});
    return r;
  };
  const AccuracyReport a = aggregate("straight-1m", {run(1.0, 5.0), run(3.0, std::nullopt)});
  EXPECT_EQ(formatAccuracyJson(a),
            "{\n"
            "  \"scenario\": \"straight-1m\",\n"
            "  \"runs\": 2,\n"
            "  \"estimators\": {\n"
            "    \"ekf\": {\n"
            "      \"final_position_error_m\": {\n"
            "        \"mean\": 2.0,\n"
            "        \"std\": 1.4142135623730951,\n"
            "        \"median\": 2.0,\n"
            "        \"max\": 3.0\n"
            "      },\n"
            "      \"rpe_pct_per_m\": {\n"
            "        \"mean\": 5.0,\n"
            "        \"std\": null,\n"
            "        \"median\": 5.0,\n"
            "        \"max\": 5.0\n"
            "      }\n"
            "    }\n"
            "  }\n"
            "}\n");
  const std::string table = formatAccuracyTable(a);
  EXPECT_THAT(table, HasSubstr("2 runs"));
  EXPECT_THAT(table, HasSubstr("final_position_error_m  2 ± 1.414"));
}

// --- traverse evaluate -------------------------------------------------------------------------

class EvalCli : public ::testing::Test {
 protected:
  void SetUp() override {
    root_ = fs::temp_directory_path() /
            ("traverse_eval_" + std::to_string(::getpid()) + "_" +
             ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(root_);
    fs::create_directories(log_ = root_ / "tiny-log");
    fs::create_directories(out_ = root_ / "out");
  }
  void TearDown() override { fs::remove_all(root_); }

  /// Runs the CLI; returns the exit code and fills out/err.
  int run(const std::string& args) {
    const std::string cmd = std::string(TRAVERSE_CLI_PATH) + " " + args + " >" +
                            (root_ / "stdout").string() + " 2>" + (root_ / "stderr").string();
    const int status = std::system(cmd.c_str());
    out = slurp(root_ / "stdout");
    err = slurp(root_ / "stderr");
    return WEXITSTATUS(status);
  }
  static std::string slurp(const fs::path& p) {
    std::ifstream f(p);
    return std::string(std::istreambuf_iterator<char>(f), {});
  }

  fs::path root_, log_, out_;
  std::string out, err;
};

TEST_F(EvalCli, EvaluateWritesMetricsJson) {
  const auto poses = straight(0.0, 3.0, 0.5);
  io::writeCsv(log_ / "truth.csv", truthStream(poses, {0.0, Vec3d::Zero(), true}));
  est::Trajectory ekf = trajectoryOf(poses, {0.0, Vec3d::Zero(), true}, true), smoothed = ekf;
  smoothed.name = "smoothed";
  est::writeTrajectory(out_, ekf);
  est::writeTrajectory(out_, smoothed);
  ASSERT_EQ(run("evaluate " + out_.string() + " --truth " + log_.string() + "/"), 0) << err;
  EXPECT_EQ(err, "");
  EXPECT_THAT(out, HasSubstr("position_rmse_m"));
  const std::string json = slurp(out_ / "metrics.json");
  EXPECT_THAT(json, HasSubstr("\"log\": \"tiny-log\""));
  EXPECT_THAT(json, HasSubstr("\"path_length_m\": 3.0,"));
  EXPECT_THAT(json, HasSubstr("\"smoother\": {"));
  EXPECT_THAT(json, HasSubstr("\"final_position_error_m\": 0.0,"));
  EXPECT_THAT(json, Not(HasSubstr("\"dr\"")));
  ASSERT_EQ(run("--quiet evaluate " + out_.string() + " --truth " + log_.string()), 0) << err;
  EXPECT_EQ(out, "");
}

// est::asWritten is the file's round trip in memory: attitude and covariance bit for bit what
// readTrajectory returns after writeTrajectory (σ written, squared back; the cross terms of
// position and attitude dropped), at random nodes; the fields the file does not carry are kept.
TEST(EstTrajectory, AsWrittenIsTheFilesRoundTrip) {
  std::mt19937 rng(7);
  std::normal_distribution<double> n;
  est::Trajectory tr;
  tr.name = "ekf";
  tr.has_covariance = true;
  for (int k = 0; k < 20; ++k) {
    est::TrajectoryNode nd;
    nd.t = 0.1 * k;
    nd.p_site = Vec3d(n(rng), n(rng), n(rng));
    nd.q_site_body = Quatd(n(rng), n(rng), n(rng), n(rng));  // not normalised: the file's is
    nd.xi = rover::WheelVectord::Constant(6, 0.01 * k);
    nd.bias = Vec3d(1e-4, 2e-4, 3e-4);
    nd.bias_sigma = Vec3d(1e-5, 2e-5, 3e-5 * (k + 1));
    Mat6d A;
    for (int i = 0; i < 36; ++i) A.data()[i] = 0.1 * n(rng);
    nd.covariance = A * A.transpose() + 1e-3 * Mat6d::Identity();
    tr.nodes.push_back(nd);
  }
  const fs::path dir = fs::path(testing::TempDir()) / "as_written";
  fs::remove_all(dir);
  est::writeTrajectory(dir, tr);
  const est::Trajectory back = est::readTrajectory(dir, "ekf");
  const est::Trajectory w = est::asWritten(tr);
  ASSERT_EQ(w.nodes.size(), back.nodes.size());
  for (size_t k = 0; k < w.nodes.size(); ++k) {
    EXPECT_EQ(w.nodes[k].q_site_body.coeffs(), back.nodes[k].q_site_body.coeffs()) << k;
    EXPECT_EQ(w.nodes[k].covariance, back.nodes[k].covariance) << k;
    EXPECT_EQ(w.nodes[k].p_site, back.nodes[k].p_site) << k;
    EXPECT_EQ(w.nodes[k].bias_sigma, tr.nodes[k].bias_sigma) << k;  // not in the file: kept
    EXPECT_TRUE((w.nodes[k].covariance.topRightCorner<3, 3>().isZero(0.0))) << k;
    EXPECT_FALSE((tr.nodes[k].covariance.topRightCorner<3, 3>().isZero(0.0))) << k;
  }
}

TEST_F(EvalCli, MissingTruthOrTrajectoriesIsBadInput) {
  est::writeTrajectory(out_, trajectoryOf(straight(0.0, 3.0, 0.5)));
  EXPECT_EQ(run("evaluate " + out_.string() + " --truth " + log_.string()), 2);
  EXPECT_THAT(err, HasSubstr("truth.csv"));
  EXPECT_EQ(std::count(err.begin(), err.end(), '\n'), 1);
  io::writeCsv(log_ / "truth.csv", truthStream(straight(0.0, 3.0, 0.5)));
  fs::remove(out_ / "ekf.csv");
  EXPECT_EQ(run("evaluate " + out_.string() + " --truth " + log_.string()), 2);
  EXPECT_THAT(err, HasSubstr("no trajectory"));
}

}  // namespace
}  // namespace traverse::eval
