// Marginal covariances of one solved segment (docs/model.md "Covariance"): H = JᵀJ at the
// solution accumulated residual block by residual block straight into the chain's blocks
// (chain_marginals.h), then the exact marginal blocks of H⁻¹.
#pragma once

#include <span>

#include "traverse/estimators/trajectory.h"
#include "traverse/smoother/block_evaluation.h"
#include "traverse/smoother/residual_collector.h"

namespace traverse::smoother {

/// Fills each out[k]'s covariance ([δp_site; δθ_body]), bias_sigma and (with the segment's
/// accelerometer bias, nodes[0].ba) accel_bias_sigma from the residuals at the
/// blocks' current values. nodes: the segment's handles (node k's bias on node k with the
/// random-walk model, on ChainPlace::kGlobal otherwise); bias_axes: the body axes of the bias's
/// tangent columns, in order (all three, or z alone for a heading-only gyro). False if a block
/// fails to evaluate or H is not positive definite.
bool segmentCovariance(const ResidualCollector& residuals, std::span<const NodeHandles> nodes,
                       std::span<const int> bias_axes, BlockEvaluator& evaluator,
                       std::span<est::TrajectoryNode> out);

}  // namespace traverse::smoother
