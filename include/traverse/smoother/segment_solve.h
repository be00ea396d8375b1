// Solving one segment's Ceres problem (segment_problem.h builds it): the solver's options, the
// solve with its summary, and the segment's status from how it ended.
#pragma once

#include <chrono>
#include <iosfwd>
#include <span>
#include <string>

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

/// converged when Ceres' convergence test held. A solve stopped at the iteration limit is kept
/// (no_convergence) only when its states are finite, its cost is no higher than the seed's and
/// the cost is consistent with the noise the residuals declare: 2 × final cost (Σ ρ(‖r‖²) of
/// whitened residuals, χ² with about as many degrees of freedom as residual rows when the model
/// holds) within the χ² quantile at 0.9999 for that many rows (Wilson–Hilferty). Otherwise, or
/// when the solution is not finite, fallback_ekf; `why` (optional) then gets the reason
/// (segments.csv's status says fallback_ekf, the run's output line says why).
SegmentStatus segmentStatus(const ceres::Solver::Summary& summary, bool finite,
                            std::string* why = nullptr);
/// The χ² quantile at 0.9999 for `dof` degrees of freedom (Wilson–Hilferty; dof ≥ 1).
double chiSquareBound(double dof);

/// Cost ½ Σ ρ(‖r‖²) of each kind of residual at the current states, " kind cost (blocks)" per
/// kind in name order (solver_report).
void reportCostByKind(std::ostream& out, ceres::Problem& problem,
                      const ResidualCollector& residuals);

}  // namespace traverse::smoother
