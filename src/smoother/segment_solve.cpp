// include/traverse/smoother/segment_solve.h
#include "traverse/smoother/segment_solve.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <memory>
#include <ostream>
#include <sstream>
#include <string>
#include <vector>

namespace traverse::smoother {

ceres::Solver::Options segmentSolverOptions(const SmootherOptions& o,
                                            std::span<const NodeHandles> nodes) {
  ceres::Solver::Options so;
  so.minimizer_type = ceres::TRUST_REGION;
  so.trust_region_strategy_type = ceres::LEVENBERG_MARQUARDT;
  so.linear_solver_type = ceres::SPARSE_NORMAL_CHOLESKY;
  so.sparse_linear_algebra_library_type = ceres::SUITE_SPARSE;
  so.max_num_iterations = o.max_iterations;
  so.function_tolerance = o.function_tolerance;
  so.gradient_tolerance = o.gradient_tolerance;
  so.parameter_tolerance = o.parameter_tolerance;
  so.num_threads = 1;  // segments run in parallel; one thread each keeps results reproducible
  so.logging_type = o.solver_report ? ceres::PER_MINIMIZER_ITERATION : ceres::SILENT;
  so.minimizer_progress_to_stdout = o.solver_report;
  so.initial_trust_region_radius = o.initial_trust_region_radius;
  if (o.chain_ordering && !nodes.empty()) {
    // Eliminate node by node in time order, the segment's biases last: the normal equations are a
    // band (each residual ties nodes k and k+1) with one dense border, so this order has no
    // fill outside the band and keeps the factor's memory local — AMD on the whole problem
    // scatters a chain and grows worse than linearly with its length.
    auto ordering = std::make_shared<ceres::ParameterBlockOrdering>();
    for (size_t k = 0; k < nodes.size(); ++k) {
      const NodeHandles& h = nodes[k];
      for (const BlockHandle* b : {&h.q, &h.x, &h.v, &h.w, &h.xi})
        ordering->AddElementToGroup(b->data, static_cast<int>(k));
      if (h.c.size > 0) ordering->AddElementToGroup(h.c.data, static_cast<int>(k));
      if (h.bias.place.node != ChainPlace::kGlobal)
        ordering->AddElementToGroup(h.bias.data, static_cast<int>(k));
    }
    const BlockHandle& bias = nodes.front().bias;
    if (bias.place.node == ChainPlace::kGlobal)
      ordering->AddElementToGroup(bias.data, static_cast<int>(nodes.size()));
    if (nodes.front().ba.size > 0)
      ordering->AddElementToGroup(nodes.front().ba.data, static_cast<int>(nodes.size()));
    if (nodes.front().icr.size > 0)
      ordering->AddElementToGroup(nodes.front().icr.data, static_cast<int>(nodes.size()));
    so.linear_solver_ordering = ordering;
  }
  return so;
}

ceres::Solver::Summary solveSegmentProblem(ceres::Problem& problem,
                                           const ceres::Solver::Options& options,
                                           std::chrono::steady_clock::time_point t0,
                                           SegmentSummary& sum) {
  ceres::Solver::Summary summary;
  ceres::Solve(options, &problem, &summary);
  sum.solve_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  sum.ceres_preprocess_seconds = summary.preprocessor_time_in_seconds;
  sum.ceres_minimizer_seconds = summary.minimizer_time_in_seconds;
  sum.ceres_jacobian_seconds = summary.jacobian_evaluation_time_in_seconds;
  sum.ceres_residual_seconds = summary.residual_evaluation_time_in_seconds;
  sum.ceres_linear_solver_seconds = summary.linear_solver_time_in_seconds;
  sum.iterations = std::max(0, static_cast<int>(summary.iterations.size()) - 1);
  sum.initial_cost = summary.initial_cost;
  sum.final_cost = summary.final_cost;
  sum.message = summary.message;
  return summary;
}

double chiSquareBound(double dof) {
  constexpr double kZ = 3.719016485;  // standard normal quantile at 0.9999
  const double a = 2.0 / (9.0 * dof);
  return dof * std::pow(1.0 - a + kZ * std::sqrt(a), 3);
}

SegmentStatus segmentStatus(const ceres::Solver::Summary& summary, bool finite, std::string* why) {
  const auto say = [&](const std::string& text) {
    if (why) *why = text;
  };
  if (!finite) {
    say("the solution is not finite (" + summary.message + ")");
    return SegmentStatus::kFallbackEkf;
  }
  if (summary.termination_type == ceres::CONVERGENCE) return SegmentStatus::kConverged;
  if (summary.termination_type != ceres::NO_CONVERGENCE) {
    say("the solve failed: " + summary.message);
    return SegmentStatus::kFallbackEkf;
  }
  if (summary.final_cost > summary.initial_cost) {
    say("no convergence, and the cost rose above the EKF seed's");
    return SegmentStatus::kFallbackEkf;
  }
  const double rows = std::max(1, summary.num_residuals);
  const double bound = chiSquareBound(rows);
  if (2.0 * summary.final_cost > bound) {
    std::ostringstream s;
    s << "no convergence in " << std::max<int>(0, static_cast<int>(summary.iterations.size()) - 1)
      << " iterations and an inconsistent cost: 2 x " << summary.final_cost << " > " << bound
      << " (chi2 at 0.9999 for " << summary.num_residuals << " residual rows)";
    say(s.str());
    return SegmentStatus::kFallbackEkf;
  }
  return SegmentStatus::kNoConvergence;
}

void reportCostByKind(std::ostream& out, ceres::Problem& problem,
                      const ResidualCollector& residuals) {
  std::map<std::string, std::vector<ceres::ResidualBlockId>> by_kind;
  for (const ResidualEntry& e : residuals.entries()) by_kind[e.kind].push_back(e.id);
  for (const auto& [kind, ids] : by_kind) {
    ceres::Problem::EvaluateOptions eo;
    eo.residual_blocks = ids;
    double cost = 0.0;
    problem.Evaluate(eo, &cost, nullptr, nullptr, nullptr);
    out << " " << kind << " " << cost << " (" << ids.size() << ")";
  }
}

}  // namespace traverse::smoother
