// Per-segment batch smoother (docs/model.md "Smoother"; estimation-design.md "Per-segment batch
// smoother"): each stop-to-stop segment — rest window, motion, rest window — is one nonlinear
// least-squares problem over all its nodes, solved with Ceres (Levenberg-Marquardt,
// SPARSE_NORMAL_CHOLESKY on SuiteSparse) from the forward EKF's trajectory.
//
// Per node k (a joint sample): attitude q_k (BodyQuaternionManifold, storage x, y, z, w), site
// position x_k, body velocity v_k, body rate ω_k, contact angles ξ_k. Per segment: the gyro
// bias b (constant), or one b_k per node tied by a random walk (K-9).
//
// Segments are independent problems, solved in parallel; each segment's result depends only on
// its own data, so the output does not depend on the thread count. Consecutive segments share a
// rest window; each node is reported once, the shared window by the later segment. They agree
// there in position exactly: stitching, in time order, translates segment s+1 so that its
// position at the window's middle node equals segment s's — the problems are invariant under
// translation (only the start prior sees absolute position), so this is the gauge, not an
// approximation. Attitude needs no stitching: each segment's is anchored by its own sun and
// gravity data, and the two estimates of the shared rest attitude differ by a few hundredths of
// a degree (reported per segment as stitch_rotation_rad).
#pragma once

#include <string>
#include <vector>

#include "traverse/estimators/ekf.h"
#include "traverse/estimators/segmentation.h"
#include "traverse/estimators/segments_output.h"

namespace traverse::smoother {

struct SmootherOptions {
  /// Node period: 0 puts a node at every joint sample; otherwise joint samples at least this
  /// far apart (the slip constraint is applied at the nodes only).
  double node_period_s = 0.0;
  /// kAuto picks per segment by randomWalkBiasPays (a constant bias where rover.yaml declares
  /// no drift, or where the segment is too short for the drift to matter).
  enum class BiasModel { kAuto, kConstant, kRandomWalk };
  BiasModel bias_model = BiasModel::kAuto;
  /// Robust loss on the sun and slip residuals; kRoverConfig: rover.yaml's `smoother.loss`
  /// (Huber when it names none).
  enum class Loss { kRoverConfig, kNone, kHuber, kCauchy };
  Loss loss = Loss::kRoverConfig;
  double loss_scale = 0.0;  ///< in whitened units (σ); 0: rover.yaml's, else 3
  /// Contact angles (K-8): each wheel's increment is its own residual under a Cauchy loss of this
  /// scale (σ), so a wheel meeting an edge may jump while the Gaussian process would spread the
  /// step over its neighbours (obstacle: final position 0.021 → 0.012 m, contact-angle RMSE
  /// 2.5° → 1.3°; docs/results.md). 0: the Gaussian process, one six-row residual per interval.
  double contact_loss_scale = 1.0;
  enum class VelocityModel { kAuto, kPerturbation, kAccelDriven };
  VelocityModel velocity = VelocityModel::kAuto;  ///< kAuto: O-4 when the log has accel.csv
  bool use_sun = true, use_slip = true, use_rest = true;
  double zero_velocity_sigma_mps = 0.001;
  double zero_rate_sigma_rad_s = 1e-4;
  double start_position_sigma_m = 1e-4;  ///< the gauge anchor at a segment's first node
  double rest_margin_s = 0.25;           ///< rest measurements keep clear of the boundaries
  double attitude_floor_rad = 1e-6, position_floor_m = 1e-6;  ///< process σ floors
  // Solver.
  int max_iterations = 50;
  /// The segment problems are nearly linear around the EKF seed, so Levenberg-Marquardt should
  /// take Gauss-Newton steps at once. Its damping is λ = 1/radius on the Jacobi-scaled normal
  /// equations (unit diagonal), and a chain's smoothest mode — all six contact angles shifting
  /// together with a slow vertical drift over the whole segment — has an eigenvalue of order
  /// (π/N)² there: 1e-7 at N = 10 000 nodes. Any λ near that stalls the mode, one fraction of it
  /// per iteration at an accepted-step ratio of 1 (radius 1e8: 5–6 iterations at 1k–10k nodes
  /// that never quite converge; 1e14: 2, to a lower cost). Ceres' default 1e4 took 13.
  double initial_trust_region_radius = 1e14;
  bool chain_ordering = true;  ///< eliminate nodes in time order, the bias last (else AMD)
  /// Stop when an iteration lowers the cost by less than 1e-5 of it: the cost is ~½ × the number of
  /// residual rows, so that is a change in log-likelihood far below one unit.
  double function_tolerance = 1e-5, gradient_tolerance = 1e-10, parameter_tolerance = 1e-8;
  int threads = 0;  ///< segments solved in parallel (0: all cores)
  bool covariance = true;
  bool solver_report = false;  ///< print Ceres' full report per segment to stderr
};

/// How a segment's solve ended (segments.csv `status`: toString).
enum class SegmentStatus {
  kConverged,      ///< converged: Ceres' convergence test held
  kNoConvergence,  ///< no_convergence: stopped at the iteration limit; the best states are kept
  kFallbackEkf,    ///< fallback_ekf: the solve failed or could not be set up; the EKF's states
};
/// The segments.csv spelling: converged | no_convergence | fallback_ekf.
inline const char* toString(SegmentStatus s) {
  switch (s) {
    case SegmentStatus::kConverged:
      return "converged";
    case SegmentStatus::kNoConvergence:
      return "no_convergence";
    case SegmentStatus::kFallbackEkf:
      return "fallback_ekf";
  }
  return "unknown";
}

/// What the smoother reports per segment (segments.csv adds the bias and solver columns).
struct SegmentSummary {
  int index = 0;
  int motion_segment = -1;  ///< index into Segmentation::segments of the segment's motion
  double t_start = 0.0, t_end = 0.0;
  size_t first_node = 0, num_nodes = 0;  ///< the nodes it reports in the smoothed trajectory
  Vec3d bias = Vec3d::Zero(), bias_sigma = Vec3d::Zero();
  /// The accelerometer's bias (body, m/s²) and its σ when the rover declares it (else zero):
  /// the segment's constant, or the EKF's at the segment's middle when it fell back.
  Vec3d accel_bias = Vec3d::Zero(), accel_bias_sigma = Vec3d::Zero();
  /// The skid-steer ICRs' half-track error δ and its σ (m) when estimated (else zero), likewise.
  double icr = 0.0, icr_sigma = 0.0;
  SegmentStatus status = SegmentStatus::kFallbackEkf;
  int iterations = 0;
  /// ½ Σ ρ(‖r‖²): at the EKF's states (seed_cost), where Levenberg-Marquardt started (the EKF
  /// made self-consistent, when that is lower) and at the solution (the EKF's cost again when
  /// the segment fell back to it). final_cost ≤ seed_cost.
  double seed_cost = 0.0, initial_cost = 0.0, final_cost = 0.0;
  std::string message;  ///< the solver's termination message, or why the segment fell back
  double solve_seconds = 0.0, covariance_seconds = 0.0;  ///< solve includes building
  double build_seconds = 0.0;
  /// Where solve_seconds went after building: the seed (EKF cost, self-consistent seed, its
  /// cost), Ceres' preprocessing (program, ordering, evaluator) and its minimiser, split into
  /// Jacobian evaluations, residual-only evaluations and linear solves.
  double seed_seconds = 0.0, ceres_preprocess_seconds = 0.0, ceres_minimizer_seconds = 0.0;
  double ceres_jacobian_seconds = 0.0, ceres_residual_seconds = 0.0;
  double ceres_linear_solver_seconds = 0.0;
  int residual_blocks = 0, parameters = 0;
  double stitch_translation_m = 0.0, stitch_rotation_rad = 0.0;
  bool random_walk_bias = false;  ///< the bias model it was solved with (K-9 when true)
};

struct SmootherResult {
  est::Trajectory trajectory;  ///< "smoothed", with covariance
  std::vector<SegmentSummary> segments;
};

/// The rule of BiasModel::kAuto for one segment of duration T: the bias is a random walk (K-9)
/// when its declared drift over the segment, q·√T, exceeds the resolution the gyro itself gives a
/// constant bias over that segment, σ_w/√T (σ_w = noise_rad_s·√(gyro period), the gyro's white
/// density) — i.e. when q·T > σ_w. Then the constant is not the truth the data can tell apart
/// (planar-18m, 180 s, q = 5e-4: constant yaw RMSE 2.9°, RMSE/σ 5.9; random walk 0.25°, 0.69).
/// Below it, the constant is the better-determined model. q = 0 always gives the constant.
bool randomWalkBiasPays(double bias_random_walk_rad_s_per_sqrt_s, double gyro_noise_rad_s,
                        double gyro_period_s, double segment_seconds);

/// Smooths a log, seeded by the EKF trajectory (one node per est::jointSamples entry, as runEkf
/// gives).
SmootherResult smooth(const io::TraverseLog& log, const est::Segmentation& seg,
                      const est::Trajectory& ekf, const SmootherOptions& options = {});

/// segments.csv rows: the EKF's rows (segmentRows), with each motion row carrying its smoother
/// segment's bias ± σ and solver summary.
std::vector<est::SegmentRow> smootherSegmentRows(const std::vector<est::SegmentRow>& ekf_rows,
                                                 const SmootherResult& result);

}  // namespace traverse::smoother
