// The per-segment batch smoother (include/traverse/smoother/smoother.h) on simulated traverses
// with truth: accuracy on noise-free data, cost never above the EKF seed's, bias recovery,
// thread-count independence, stitching at shared rest windows, fallback, covariance.
#include <gtest/gtest.h>

#include <Eigen/Eigenvalues>
#include <cmath>
#include <cstring>
#include <limits>

#include "support/jacobian_check.h"
#include "traverse/core/error.h"
#include "traverse/core/so3.h"
#include "traverse/eval/metrics.h"
#include "traverse/pipeline/pipeline.h"
#include "traverse/sim/simulator.h"
#include "traverse/smoother/segment_solve.h"

namespace traverse::smoother {
namespace {

constexpr double kDeg = M_PI / 180.0;

std::filesystem::path datasets() {
  return std::filesystem::path(testing::sourceDir()) / "datasets";
}

// Simulated at the simulator's minimum internal rate (200 Hz; straight-1m asks for 400) to keep
// the tests fast: the simulation is most of their time.
sim::Simulation simulate(const std::string& scenario, std::vector<std::string> overrides,
                         uint64_t seed = 1) {
  overrides.insert(overrides.begin(), "truth_rate_hz=200");
  const sim::Scenario sc = sim::loadScenario(scenario, datasets(), overrides);
  return sim::simulate(sc, sim::roverDirectory(sc, datasets()), seed);
}

pipeline::Estimates estimateSmoothed(const io::TraverseLog& log,
                                     const SmootherOptions& options = {}) {
  pipeline::PipelineConfig config;
  config.smooth = true;
  config.smoother = options;
  return pipeline::estimate(log, config);
}

// Three stop-to-stop legs on straight-1m's undulating terrain (straight, left arc, straight),
// ~46 s: three smoother segments sharing two rest windows, the arc making the stitch rotation
// more than a roll/pitch difference.
const std::vector<std::string> kThreeLegs = {
    "path=[{rest: 5}, {straight: 0.3, speed_mps: 0.05, ramp_s: 2}, {rest: 5},"
    " {arc: 0.3, radius_m: 1.5, speed_mps: 0.05, ramp_s: 2}, {rest: 5},"
    " {straight: 0.3, speed_mps: 0.05, ramp_s: 2}, {rest: 5}]"};

/// The three-leg log and its estimates, simulated and smoothed once per test program.
struct ThreeLegRun {
  sim::Simulation sim;
  pipeline::Estimates est;
};
const ThreeLegRun& threeLegs() {
  static const ThreeLegRun run = [] {
    ThreeLegRun r{simulate("straight-1m", kThreeLegs), {}};
    r.est = estimateSmoothed(r.sim.log);
    return r;
  }();
  return run;
}

template <typename T>
bool sameBits(const T& a, const T& b) {
  return std::memcmp(&a, &b, sizeof(T)) == 0;
}
/// A wheel vector: its size and its used entries (the storage beyond size is not a value).
bool sameBits(const rover::WheelVectord& a, const rover::WheelVectord& b) {
  return a.size() == b.size() &&
         std::memcmp(a.data(), b.data(), sizeof(double) * static_cast<size_t>(a.size())) == 0;
}

/// Field by field (no struct padding): bitwise equal nodes.
bool sameNode(const est::TrajectoryNode& a, const est::TrajectoryNode& b) {
  return sameBits(a.t, b.t) && sameBits(a.p_site, b.p_site) &&
         sameBits(a.q_site_body.coeffs(), b.q_site_body.coeffs()) && sameBits(a.v_body, b.v_body) &&
         sameBits(a.w_body, b.w_body) && sameBits(a.xi, b.xi) && sameBits(a.bias, b.bias) &&
         sameBits(a.covariance, b.covariance) && sameBits(a.bias_sigma, b.bias_sigma);
}

/// Everything in a summary except the wall-clock times.
void expectSameSummary(const SegmentSummary& a, const SegmentSummary& b) {
  EXPECT_EQ(a.index, b.index);
  EXPECT_EQ(a.motion_segment, b.motion_segment);
  EXPECT_TRUE(sameBits(a.t_start, b.t_start) && sameBits(a.t_end, b.t_end));
  EXPECT_EQ(a.first_node, b.first_node);
  EXPECT_EQ(a.num_nodes, b.num_nodes);
  EXPECT_TRUE(sameBits(a.bias, b.bias) && sameBits(a.bias_sigma, b.bias_sigma));
  EXPECT_EQ(a.status, b.status);
  EXPECT_EQ(a.iterations, b.iterations);
  EXPECT_TRUE(sameBits(a.initial_cost, b.initial_cost) && sameBits(a.final_cost, b.final_cost));
  EXPECT_EQ(a.residual_blocks, b.residual_blocks);
  EXPECT_EQ(a.parameters, b.parameters);
  EXPECT_TRUE(sameBits(a.stitch_translation_m, b.stitch_translation_m) &&
              sameBits(a.stitch_rotation_rad, b.stitch_rotation_rad));
}

// The segments.csv spelling of every status is one of the three outputs.md names.
bool validStatus(SegmentStatus status) {
  const std::string s = toString(status);
  return s == "converged" || s == "no_convergence" || s == "fallback_ekf";
}

// Noise-free straight-1m on flat ground. Zero noise cannot be given to the smoother: the log's
// rover.yaml then states σ = 0 for the gyro, sun sensor and accelerometer, and their whitening is
// infinite (a zero gravity covariance makes the build throw; an infinite gyro weight makes the
// first evaluation fail, and the segment falls back to the EKF). So every sensor and the white
// slip get 1e-6 of noise instead (joint noise and wheel quantisation 0, as the EKF test). What
// remains is model error: the trapezoid gyro increment and position process over the 50 ms
// joint period and the contact-angle Markov prior; on flat ground it is below 0.1 mm and 2e-3°
// (seen: 90 µm worst position, 23 µm final, 1.3e-3° worst attitude), so 1 mm and 0.01° bound
// it with margin.
TEST(Smoother, NoiseFreeLogSmoothsToTruth) {
  const sim::Simulation s = simulate(
      "straight-1m", {"terrain.type=flat", "slip.longitudinal_white_mps=1e-6",
                      "sensors.gyro.noise_rad_s=1e-6", "sensors.sun.noise=1e-6",
                      "sensors.accel.noise_mps2=1e-6", "sensors.joints.angle_noise_rad=0",
                      "sensors.joints.steering_noise_rad=0", "sensors.joints.wheel_quantum_rad=0"});
  const pipeline::Estimates e = estimateSmoothed(s.log);
  ASSERT_TRUE(e.smoothed.has_value());
  const SmootherResult& r = *e.smoothed;
  ASSERT_EQ(r.segments.size(), 1u);
  for (const SegmentSummary& g : r.segments) EXPECT_EQ(g.status, SegmentStatus::kConverged);
  ASSERT_EQ(r.trajectory.nodes.size(), e.ekf.trajectory.nodes.size());

  // As eval::evaluate: the start position is not observable, the estimate is translated onto
  // the truth's at the first node; no rotation (heading is observable).
  const eval::TruthTrajectory truth(*s.log.truth);
  const Vec3d offset = truth.position(r.trajectory.nodes.front().t) - r.trajectory.nodes[0].p_site;
  double max_position = 0.0, max_attitude = 0.0;
  for (const est::TrajectoryNode& n : r.trajectory.nodes) {
    max_position = std::max(max_position, (n.p_site + offset - truth.position(n.t)).norm());
    max_attitude = std::max(max_attitude, so3::boxminus(truth.attitude(n.t), n.q_site_body).norm());
  }
  EXPECT_LT(max_position, 1e-3);
  EXPECT_LT(max_attitude, 0.01 * kDeg);
  const eval::Metrics m = eval::evaluate(r.trajectory, truth);
  EXPECT_LT(*m.get("final_position_error_m"), 1e-3);
  EXPECT_LT(*m.get("yaw_rmse_deg"), 0.01);
  EXPECT_NEAR(r.segments[0].bias.z(),
              truth.bias(r.trajectory.nodes[r.trajectory.nodes.size() / 2].t).z(), 1e-6);
}

// seed_cost is the cost of the EKF's own states; the solver starts there or at their
// self-consistent version when that is lower (initial_cost), and Levenberg–Marquardt only
// accepts steps that lower the cost, so the solution's cost is never above the EKF's.
TEST(Smoother, NeverWorseThanTheEkfSeed) {
  for (uint64_t seed = 1; seed <= 3; ++seed) {
    const pipeline::Estimates e = estimateSmoothed(simulate("straight-1m", {}, seed).log);
    ASSERT_TRUE(e.smoothed.has_value());
    ASSERT_FALSE(e.smoothed->segments.empty());
    for (const SegmentSummary& g : e.smoothed->segments) {
      EXPECT_EQ(g.status, SegmentStatus::kConverged) << "seed " << seed;
      EXPECT_GT(g.iterations, 0) << "seed " << seed;
      EXPECT_TRUE(std::isfinite(g.seed_cost) && std::isfinite(g.final_cost));
      EXPECT_GT(g.final_cost, 0.0);
      EXPECT_LE(g.initial_cost, g.seed_cost) << "seed " << seed;
      EXPECT_LE(g.final_cost, g.initial_cost) << "seed " << seed;
      EXPECT_LT(g.final_cost, g.seed_cost) << "seed " << seed;
    }
  }
}

// A 0.003 rad/s gyro bias (straight-1m has 0.002): the segment's constant bias, from both rest
// windows and the motion between them, lands within 3σ of the truth with σ ≈ 4e-5 rad/s (seen
// 4.4e-5), below the EKF's σ at the segment's middle (7e-5: the EKF has seen one rest window).
// Over three seeds its mean error is below the EKF's at the middle (seen 2.3e-5 vs 7.0e-5).
TEST(Smoother, RecoversAnInjectedBias) {
  double smoother_error = 0.0, ekf_error = 0.0;
  for (uint64_t seed = 1; seed <= 3; ++seed) {
    const sim::Simulation s =
        simulate("straight-1m", {"sensors.gyro.bias_rad_s=[0,0,0.003]"}, seed);
    const pipeline::Estimates e = estimateSmoothed(s.log);
    ASSERT_TRUE(e.smoothed.has_value());
    ASSERT_EQ(e.smoothed->segments.size(), 1u);
    const SegmentSummary& g = e.smoothed->segments[0];
    EXPECT_EQ(g.status, SegmentStatus::kConverged);
    const est::TrajectoryNode& ekf_mid = e.ekf.trajectory.nodes[g.first_node + g.num_nodes / 2];
    const double truth_bias = eval::TruthTrajectory(*s.log.truth).bias(ekf_mid.t).z();
    ASSERT_DOUBLE_EQ(truth_bias, 0.003);
    EXPECT_GT(g.bias_sigma.z(), 0.0);
    EXPECT_LT(g.bias_sigma.z(), 1e-4);
    EXPECT_LT(g.bias_sigma.z(), ekf_mid.bias_sigma.z());
    EXPECT_NEAR(g.bias.z(), truth_bias, 3.0 * g.bias_sigma.z()) << "seed " << seed;
    // Heading-only gyro: x and y are held (not estimated).
    EXPECT_EQ(g.bias.x(), 0.0);
    EXPECT_EQ(g.bias_sigma.x(), 0.0);
    smoother_error += std::abs(g.bias.z() - truth_bias) / 3.0;
    ekf_error += std::abs(ekf_mid.bias.z() - truth_bias) / 3.0;
  }
  EXPECT_LT(smoother_error, ekf_error);
}

// Segments are solved in parallel, each into its own slot with a single-threaded Ceres, and
// stitched in time order afterwards: 1, 2 or 3 threads give bitwise the same result.
TEST(Smoother, ResultsDoNotDependOnThreadCount) {
  const ThreeLegRun& run = threeLegs();
  const io::TraverseLog& log = run.sim.log;
  const pipeline::Estimates& e = run.est;
  SmootherOptions options;
  options.threads = 1;
  const SmootherResult one = smooth(log, e.segmentation, e.ekf.trajectory, options);
  ASSERT_EQ(one.segments.size(), 3u);
  for (const int threads : {2, 3}) {
    SCOPED_TRACE(threads);
    options.threads = threads;
    const SmootherResult many = smooth(log, e.segmentation, e.ekf.trajectory, options);
    EXPECT_EQ(many.trajectory.name, one.trajectory.name);
    EXPECT_EQ(many.trajectory.has_covariance, one.trajectory.has_covariance);
    ASSERT_EQ(many.trajectory.nodes.size(), one.trajectory.nodes.size());
    size_t differing = 0;
    for (size_t k = 0; k < one.trajectory.nodes.size(); ++k)
      differing += !sameNode(one.trajectory.nodes[k], many.trajectory.nodes[k]);
    EXPECT_EQ(differing, 0u);
    ASSERT_EQ(many.segments.size(), one.segments.size());
    for (size_t s = 0; s < one.segments.size(); ++s)
      expectSameSummary(one.segments[s], many.segments[s]);
  }
  // threads = 0 (all cores) through the pipeline: the same again.
  const SmootherResult& all = *e.smoothed;
  ASSERT_EQ(all.trajectory.nodes.size(), one.trajectory.nodes.size());
  for (size_t k = 0; k < one.trajectory.nodes.size(); ++k)
    ASSERT_TRUE(sameNode(one.trajectory.nodes[k], all.trajectory.nodes[k])) << "node " << k;
}

// Consecutive segments share a rest window; the later one reports it, moved onto the earlier
// one's pose at the window's middle. The output has each joint sample once, in time order, and
// no jump at the seams: the rover stands still through the rest windows.
TEST(Smoother, SharedRestWindowsAgree) {
  const ThreeLegRun& run = threeLegs();
  const pipeline::Estimates& e = run.est;
  const SmootherResult& r = *e.smoothed;
  const auto& nodes = r.trajectory.nodes;
  const auto& ekf = e.ekf.trajectory.nodes;
  ASSERT_EQ(nodes.size(), ekf.size());  // node_period_s = 0: one node per joint sample
  for (size_t k = 0; k < nodes.size(); ++k) {
    ASSERT_EQ(nodes[k].t, ekf[k].t) << "node " << k;
    if (k > 0) {
      ASSERT_GT(nodes[k].t, nodes[k - 1].t) << "node " << k;
    }
  }
  // Segment node ranges tile the output; each later segment starts inside a rest window.
  ASSERT_EQ(r.segments.size(), 3u);
  EXPECT_EQ(r.segments.front().first_node, 0u);
  EXPECT_EQ(r.segments.back().first_node + r.segments.back().num_nodes, nodes.size());
  const auto inRest = [&](double t) {
    for (const est::Segment& g : e.segmentation.segments)
      if (g.kind == est::Segment::Kind::kRest && t >= g.t_start && t <= g.t_end) return true;
    return false;
  };
  for (size_t s = 0; s < r.segments.size(); ++s) {
    const SegmentSummary& g = r.segments[s];
    EXPECT_EQ(g.status, SegmentStatus::kConverged);
    if (s == 0) {
      EXPECT_EQ(g.stitch_rotation_rad, 0.0);
      continue;
    }
    const SegmentSummary& prev = r.segments[s - 1];
    EXPECT_GT(g.first_node, prev.first_node);
    // Each node is reported once: the shared window by the later segment.
    EXPECT_EQ(g.first_node, prev.first_node + prev.num_nodes);
    EXPECT_TRUE(inRest(nodes[g.first_node].t));
    // Two estimates of one rest attitude, from different data: seen 0.008°–0.04°.
    EXPECT_LT(g.stitch_rotation_rad, 0.5 * kDeg) << "segment " << s;
    // The seam itself: the last node from segment s − 1 and the first from segment s.
    const size_t k = g.first_node;
    EXPECT_LT((nodes[k].p_site - nodes[k - 1].p_site).norm(), 1e-3) << "segment " << s;
    EXPECT_LT(so3::boxminus(nodes[k].q_site_body, nodes[k - 1].q_site_body).norm(), 0.05 * kDeg)
        << "segment " << s;
  }
  // Through every rest window: sub-millimetre steps between consecutive nodes (seen 0.1 mm).
  double max_rest_step = 0.0;
  for (size_t k = 1; k < nodes.size(); ++k) {
    if (inRest(nodes[k - 1].t) && inRest(nodes[k].t))
      max_rest_step = std::max(max_rest_step, (nodes[k].p_site - nodes[k - 1].p_site).norm());
  }
  EXPECT_LT(max_rest_step, 1e-3);
}

// A segment whose solve fails keeps the EKF's states; the others are unaffected. A NaN in one
// sun reading mid-way through the second leg (the EKF seed comes from the clean log) makes
// Ceres' first evaluation fail in the one segment that reads it. (A NaN in a seed node's
// position no longer does: the seed's positions are re-integrated from the process first.)
TEST(Smoother, FallsBackToTheEkfWhenTheSolverFails) {
  const ThreeLegRun& run = threeLegs();
  const pipeline::Estimates& e = run.est;
  const est::Segment& leg2 = e.segmentation.segments[3];
  ASSERT_EQ(leg2.kind, est::Segment::Kind::kMotion);
  io::TraverseLog log = run.sim.log;
  ASSERT_TRUE(log.sun.has_value());
  Eigen::Index j = 0;
  while (log.sun->t[j] < 0.5 * (leg2.t_start + leg2.t_end)) ++j;
  ASSERT_GT(log.sun->values(j, 2), 0.5);  // a valid reading
  log.sun->values(j, 0) = std::numeric_limits<double>::quiet_NaN();
  SmootherOptions options;
  options.threads = 1;
  const SmootherResult r = smooth(log, e.segmentation, e.ekf.trajectory, options);
  ASSERT_EQ(r.segments.size(), 3u);
  for (const SegmentSummary& g : r.segments)
    EXPECT_TRUE(validStatus(g.status)) << toString(g.status);
  EXPECT_EQ(r.segments[0].status, SegmentStatus::kConverged);
  EXPECT_EQ(r.segments[1].status, SegmentStatus::kFallbackEkf);
  EXPECT_EQ(r.segments[2].status, SegmentStatus::kConverged);
  // The fallback segment's nodes are the EKF's, up to the stitch's rigid move (which leaves the
  // body-frame states and the distances between nodes alone); its bias is the EKF's at its
  // middle node.
  const auto& ekf = e.ekf.trajectory.nodes;
  // The output reports the window segment 1 shares with segment 2 from segment 2.
  const SegmentSummary& g = r.segments[1];
  const size_t reported_end = r.segments[2].first_node;
  ASSERT_EQ(reported_end, g.first_node + g.num_nodes);
  for (size_t k = g.first_node; k < reported_end; ++k) {
    const est::TrajectoryNode& n = r.trajectory.nodes[k];
    ASSERT_EQ(n.t, ekf[k].t);
    ASSERT_TRUE(sameBits(n.v_body, ekf[k].v_body) && sameBits(n.w_body, ekf[k].w_body) &&
                sameBits(n.xi, ekf[k].xi) && sameBits(n.bias, ekf[k].bias))
        << "node " << k;
    if (k > g.first_node) {
      ASSERT_NEAR((n.p_site - r.trajectory.nodes[k - 1].p_site).norm(),
                  (ekf[k].p_site - ekf[k - 1].p_site).norm(), 1e-12)
          << "node " << k;
    }
  }
  // The segment's bias is the EKF's at the middle of its whole span (both rest windows).
  size_t k0 = 0, k1 = 0;
  while (ekf[k0].t < g.t_start) ++k0;
  while (ekf[k1].t < g.t_end) ++k1;
  EXPECT_TRUE(sameBits(g.bias, ekf[k0 + (k1 - k0 + 1) / 2].bias));
  EXPECT_TRUE(sameBits(g.final_cost, g.seed_cost));  // the EKF's cost (NaN here: the bad reading)
  // The neighbours solved as before (segment 2 is stitched onto the fallback, so only its
  // solver summary is compared).
  const std::vector<SegmentSummary>& clean = e.smoothed->segments;
  EXPECT_TRUE(sameBits(r.segments[0].bias, clean[0].bias));
  EXPECT_TRUE(sameBits(r.segments[0].final_cost, clean[0].final_cost));
  EXPECT_TRUE(sameBits(r.segments[2].bias, clean[2].bias));
  EXPECT_TRUE(sameBits(r.segments[2].final_cost, clean[2].final_cost));
  for (size_t k = 0; k < r.segments[1].first_node; ++k)
    ASSERT_TRUE(sameNode(r.trajectory.nodes[k], e.smoothed->trajectory.nodes[k])) << k;
}

// An iteration limit the solver hits: no_convergence, the (partial) solution kept, its cost
// still not above the seed's.
TEST(Smoother, StopsAtTheIterationLimitWithoutLosingGround) {
  const sim::Simulation s = simulate("straight-1m", {});
  SmootherOptions options;
  options.max_iterations = 1;
  options.function_tolerance = options.gradient_tolerance = options.parameter_tolerance = 1e-30;
  const pipeline::Estimates e = estimateSmoothed(s.log, options);
  ASSERT_TRUE(e.smoothed.has_value());
  for (const SegmentSummary& g : e.smoothed->segments) {
    EXPECT_TRUE(validStatus(g.status)) << toString(g.status);
    EXPECT_EQ(g.status, SegmentStatus::kNoConvergence);
    EXPECT_EQ(g.iterations, 1);
    EXPECT_LE(g.final_cost, g.initial_cost);
  }
  // The kept solution is not the EKF's.
  EXPECT_FALSE(
      sameBits(e.smoothed->trajectory.nodes[100].p_site, e.ekf.trajectory.nodes[100].p_site));
}

// A solve stopped at the iteration limit is kept only when its cost is consistent with the
// declared noise (2F within the χ² quantile at 0.9999 for its residual rows); otherwise the
// segment falls back to the EKF and the reason says why.
TEST(Smoother, ANonConvergedSolveIsKeptOnlyWithAConsistentCost) {
  // Wilson–Hilferty against the tabulated χ² quantile at 0.9999 for 100 dof (161.3).
  EXPECT_NEAR(chiSquareBound(100.0), 161.3, 0.5);
  ceres::Solver::Summary s;
  s.termination_type = ceres::NO_CONVERGENCE;
  s.num_residuals = 100;
  s.initial_cost = 500.0;
  s.final_cost = 70.0;  // 2F = 140: consistent
  std::string why;
  EXPECT_EQ(segmentStatus(s, true, &why), SegmentStatus::kNoConvergence);
  EXPECT_TRUE(why.empty());
  s.final_cost = 90.0;  // 2F = 180 > 161.3
  EXPECT_EQ(segmentStatus(s, true, &why), SegmentStatus::kFallbackEkf);
  EXPECT_NE(why.find("inconsistent cost"), std::string::npos) << why;
  s.final_cost = 600.0;  // above the seed's
  EXPECT_EQ(segmentStatus(s, true, &why), SegmentStatus::kFallbackEkf);
  EXPECT_NE(why.find("rose"), std::string::npos) << why;
  s.final_cost = 70.0;
  EXPECT_EQ(segmentStatus(s, false, &why), SegmentStatus::kFallbackEkf);
  EXPECT_NE(why.find("not finite"), std::string::npos) << why;
  s.termination_type = ceres::CONVERGENCE;
  EXPECT_EQ(segmentStatus(s, true), SegmentStatus::kConverged);
}

// The random-walk bias model with a zero random-walk noise would weight every bias step
// infinitely, fail every segment and silently keep the EKF: it is refused, naming rover.yaml.
TEST(Smoother, RandomWalkBiasNeedsARandomWalkNoise) {
  sim::Simulation s = simulate("straight-1m", {});
  s.log.config.gyro.bias_random_walk_rad_s_per_sqrt_s = 0.0;
  SmootherOptions options;
  options.bias_model = SmootherOptions::BiasModel::kRandomWalk;
  try {
    estimateSmoothed(s.log, options);
    FAIL() << "expected an InputError";
  } catch (const InputError& e) {
    EXPECT_NE(e.file().find("rover.yaml"), std::string::npos) << e.what();
    EXPECT_NE(e.message().find("bias_random_walk_rad_s_per_sqrt_s"), std::string::npos) << e.what();
  }
  options.bias_model = SmootherOptions::BiasModel::kConstant;  // fine without a random walk
  const pipeline::Estimates e = estimateSmoothed(s.log, options);
  ASSERT_TRUE(e.smoothed.has_value());
  for (const SegmentSummary& g : e.smoothed->segments)
    EXPECT_NE(g.status, SegmentStatus::kFallbackEkf);
}

// BiasModel::kAuto's rule, at hand-checked values: the gyro's white density is
// σ_w = 0.0031 · √0.05 = 6.93e-4 rad/√s (Rocky-7's gyro at 20 Hz); the random walk pays when
// q · T > σ_w.
TEST(Smoother, AutoBiasModelRule) {
  EXPECT_FALSE(randomWalkBiasPays(0.0, 0.0031, 0.05, 1000.0));  // no declared drift
  EXPECT_TRUE(randomWalkBiasPays(5e-4, 0.0031, 0.05, 180.0));   // 0.09 > 6.93e-4
  EXPECT_FALSE(randomWalkBiasPays(5e-4, 0.0031, 0.05, 1.0));    // 5e-4 < 6.93e-4
  EXPECT_FALSE(randomWalkBiasPays(2e-5, 0.0031, 0.05, 30.0));   // 6.0e-4 < 6.93e-4
  EXPECT_TRUE(randomWalkBiasPays(2e-5, 0.0031, 0.05, 40.0));    // 8.0e-4 > 6.93e-4
  EXPECT_FALSE(randomWalkBiasPays(1e-3, 0.0031, 0.05, 0.0));    // an empty segment
}

// kAuto (the default) on a log: without declared drift every segment keeps one constant bias;
// with a drift that is large over the segments' length, the motion segments take the random
// walk and converge (no fallback).
TEST(Smoother, AutoBiasModelFollowsTheDeclaredDrift) {
  sim::Simulation s = simulate("straight-1m", {});
  s.log.config.gyro.bias_random_walk_rad_s_per_sqrt_s = 0.0;
  SmootherOptions options;
  ASSERT_EQ(options.bias_model, SmootherOptions::BiasModel::kAuto);
  const pipeline::Estimates constant = estimateSmoothed(s.log, options);
  ASSERT_TRUE(constant.smoothed.has_value());
  for (const SegmentSummary& g : constant.smoothed->segments) EXPECT_FALSE(g.random_walk_bias);
  s.log.config.gyro.bias_random_walk_rad_s_per_sqrt_s = 1e-3;
  const pipeline::Estimates drifting = estimateSmoothed(s.log, options);
  ASSERT_TRUE(drifting.smoothed.has_value());
  int random_walk = 0;
  for (const SegmentSummary& g : drifting.smoothed->segments) {
    random_walk += g.random_walk_bias;
    EXPECT_NE(g.status, SegmentStatus::kFallbackEkf) << g.message;
  }
  EXPECT_GE(random_walk, 1);
}

// Every segment's gyro bias keeps the EKF's estimate at the segment's first node as a prior
// (docs/model.md, `addBiasPrior`): the EKF has used every reading before that node and none of
// the segment's. On the three-leg log with a constant bias (no declared drift, so the prior's σ
// is the EKF's own), the second segment is solved three ways: with the prior made uninformative
// (σ 1 rad/s) it gives the segment's own b_d ± σ_d; with a prior b_d + 4σ_d ± σ_d the posterior
// is the two's information-weighted mean, b_d + 2σ_d ± σ_d/√2 (linear-Gaussian: the bias enters
// the gyro and rest residuals linearly).
TEST(Smoother, BiasPriorIsTheEkfsEstimateAtTheSegmentsFirstNode) {
  sim::Simulation s = simulate("straight-1m", kThreeLegs);
  s.log.config.gyro.bias_random_walk_rad_s_per_sqrt_s = 0.0;
  const pipeline::Estimates e = estimateSmoothed(s.log);
  ASSERT_TRUE(e.smoothed.has_value());
  ASSERT_EQ(e.smoothed->segments.size(), 3u);
  const size_t first = e.smoothed->segments[1].first_node;
  const auto secondSegment = [&](double bias, double sigma) {
    est::Trajectory seed = e.ekf.trajectory;
    seed.nodes[first].bias.z() = bias;
    seed.nodes[first].bias_sigma.z() = sigma;
    const SmootherResult r = smooth(s.log, e.segmentation, seed);
    EXPECT_EQ(r.segments[1].status, SegmentStatus::kConverged);
    EXPECT_FALSE(r.segments[1].random_walk_bias);
    return r.segments[1];
  };
  const SegmentSummary own = secondSegment(e.ekf.trajectory.nodes[first].bias.z(), 1.0);
  const double b_d = own.bias.z(), s_d = own.bias_sigma.z();
  ASSERT_GT(s_d, 0.0);
  ASSERT_LT(s_d, 1e-3);
  const SegmentSummary with_prior = secondSegment(b_d + 4.0 * s_d, s_d);
  EXPECT_NEAR(with_prior.bias.z(), b_d + 2.0 * s_d, 0.1 * s_d);
  EXPECT_NEAR(with_prior.bias_sigma.z(), s_d / std::sqrt(2.0), 0.05 * s_d);
  // The EKF's own estimate there, with its own σ, is a prior too: the default run's second
  // segment lies between the segment's own estimate and the EKF's.
  const est::TrajectoryNode& ekf_first = e.ekf.trajectory.nodes[first];
  const double w =
      (1.0 / (s_d * s_d)) / (1.0 / (s_d * s_d) + 1.0 / std::pow(ekf_first.bias_sigma.z(), 2));
  EXPECT_NEAR(e.smoothed->segments[1].bias.z(), w * b_d + (1.0 - w) * ekf_first.bias.z(),
              0.1 * s_d);
}

// Marginal covariances: symmetric positive definite at every node; the position uncertainty
// grows through each leg (dead reckoning between the gauge at the segment's start and the rest
// window after it).
TEST(Smoother, CovarianceIsPositiveAndGrowsInMotion) {
  const ThreeLegRun& run = threeLegs();
  const pipeline::Estimates& e = run.est;
  const auto& nodes = e.smoothed->trajectory.nodes;
  ASSERT_TRUE(e.smoothed->trajectory.has_covariance);
  for (size_t k = 0; k < nodes.size(); ++k) {
    const Mat6d& C = nodes[k].covariance;
    ASSERT_TRUE(C.allFinite()) << "node " << k;
    EXPECT_LE((C - C.transpose()).cwiseAbs().maxCoeff(), 1e-12 * C.cwiseAbs().maxCoeff())
        << "node " << k;
    EXPECT_GT(Eigen::SelfAdjointEigenSolver<Mat6d>(C).eigenvalues().minCoeff(), 0.0)
        << "node " << k;
  }
  const auto nodeAt = [&](double t) {
    size_t k = 0;
    while (k + 1 < nodes.size() && nodes[k].t < t) ++k;
    return k;
  };
  int legs = 0;
  for (const est::Segment& g : e.segmentation.segments) {
    if (g.kind != est::Segment::Kind::kMotion) continue;
    ++legs;
    const Mat3d start = nodes[nodeAt(g.t_start)].covariance.topLeftCorner<3, 3>();
    const Mat3d end = nodes[nodeAt(g.t_end)].covariance.topLeftCorner<3, 3>();
    // What the leg adds: later legs start with the chain's uncertainty (stitching adds the
    // anchor's position covariance), so the growth is judged on the increment, which is
    // positive definite (more uncertain in every direction) and millimetres in size.
    EXPECT_GT(Eigen::SelfAdjointEigenSolver<Mat3d>(end - start).eigenvalues().minCoeff(), 0.0)
        << "leg " << legs;
    EXPECT_GT(std::sqrt(end.trace() - start.trace()), 1e-3) << "leg " << legs;  // seen ~4 mm
  }
  EXPECT_EQ(legs, 3);
}

}  // namespace
}  // namespace traverse::smoother
