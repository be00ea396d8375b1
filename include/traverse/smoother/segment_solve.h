// Solving one segment's Ceres problem (segment_problem.h builds it): the solver's options, the
// solve with its summary, and the segment's status from how it ended.
#pragma once

#include <chrono>
#include <iosfwd>
#include <span>

#include <ceres/problem.h>
#include <ceres/solver.h>

#include "traverse/smoother/residual_collector.h"
#include "traverse/smoother/smoother.h"

namespace traverse::smoother {

/// Levenberg-Marquardt with SPARSE_NORMAL_CHOLESKY on SuiteSparse, one thread, the tolerances
/// and trust region of `options`; with options.chain_ordering, the nodes' blocks eliminated in
/// time order and the segment bias (a bias handle on ChainPlace::kGlobal) last.
ceres::Solver::Options segmentSolverOptions(const SmootherOptions& options,
                                            std::span<const NodeHandles> nodes);

/// Solves and copies Ceres' times, iterations, costs and message into `sum` (solve_seconds:
/// since `t0`, the segment's start, so that it includes building).
ceres::Solver::Summary solveSegmentProblem(ceres::Problem& problem,
                                           const ceres::Solver::Options& options,
                                           std::chrono::steady_clock::time_point t0,
                                           SegmentSummary& sum);

/// converged when Ceres' convergence test held; no_convergence at the iteration limit with a
/// cost no higher than the start; fallback_ekf otherwise or when the solution is not finite.
SegmentStatus segmentStatus(const ceres::Solver::Summary& summary, bool finite);

/// Cost ½ Σ ρ(‖r‖²) of each kind of residual at the current states, " kind cost (blocks)" per
/// kind in name order (solver_report).
void reportCostByKind(std::ostream& out, ceres::Problem& problem,
                      const ResidualCollector& residuals);

}  // namespace traverse::smoother
