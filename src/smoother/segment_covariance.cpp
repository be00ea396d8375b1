// include/traverse/smoother/segment_covariance.h
#include "traverse/smoother/segment_covariance.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <vector>

#include "traverse/smoother/chain_marginals.h"

namespace traverse::smoother {

bool segmentCovariance(const ResidualCollector& residuals, std::span<const NodeHandles> nodes,
                       std::span<const int> bias_axes, BlockEvaluator& evaluator,
                       std::span<est::TrajectoryNode> out) {
  // H = JᵀJ at the solution (robust losses applied as in the solver), accumulated residual block
  // by residual block straight into the chain's blocks: no global Jacobian is ever formed (with
  // Problem::Evaluate it was built as a CRS matrix, then copied — two thirds of the covariance
  // time at 10 000 nodes).
  const BlockHandle& bias = nodes.front().bias;
  const bool node_bias = bias.place.node != ChainPlace::kGlobal;
  const int wheels = nodes.front().xi.place.size;
  const int common = nodes.front().c.place.size;
  const int node_dim = NodeColumns::states(wheels, common) + (node_bias ? bias.place.size : 0);
  const BlockHandle& accel_bias = nodes.front().ba;  // size 0 without
  const BlockHandle& icr = nodes.front().icr;        // size 0 without
  const int global_dim = (node_bias ? 0 : bias.place.size) + accel_bias.place.size + icr.place.size;
  ChainInformation H = makeChainInformation(static_cast<int>(nodes.size()), node_dim, global_dim);
  std::vector<double> jacobian;
  std::array<ChainPlace, kMaxBlocksPerResidual> places;
  std::array<double*, kMaxBlocksPerResidual> jacobians{};
  for (const ResidualEntry& e : residuals.entries()) {
    const EntryBlocks blocks(e);
    int cols = 0;
    for (size_t i = 0; i < static_cast<size_t>(e.num_blocks); ++i) {
      places[i] = e.blocks[i]->place;
      cols += places[i].size;
    }
    jacobian.resize(static_cast<size_t>(e.num_rows * cols));
    for (int i = 0, c = 0; i < e.num_blocks; c += places[static_cast<size_t>(i)].size, ++i)
      jacobians[static_cast<size_t>(i)] = jacobian.data() + static_cast<ptrdiff_t>(e.num_rows * c);
    if (!evaluator.evaluate(*e.f, e.loss, blocks.parameterBlocks(), blocks.blockManifolds(),
                            nullptr, nullptr, jacobians.data()))
      return false;
    addChainResidual(H, std::span(places.data(), static_cast<size_t>(e.num_blocks)),
                     jacobians.data(), e.num_rows);
  }
  const ChainMarginals m = chainMarginals(H);
  if (!m.ok) return false;
  constexpr int p = NodeColumns::kPosition, a = NodeColumns::kAttitude;
  for (size_t k = 0; k < nodes.size(); ++k) {
    const Eigen::MatrixXd& S = m.node[k];
    est::TrajectoryNode& node = out[k];
    node.covariance.topLeftCorner<3, 3>() = S.block<3, 3>(p, p);
    node.covariance.bottomRightCorner<3, 3>() = S.block<3, 3>(a, a);
    node.covariance.topRightCorner<3, 3>() = S.block<3, 3>(p, a);
    node.covariance.bottomLeftCorner<3, 3>() = S.block<3, 3>(a, p);
    node.bias_sigma.setZero();
    for (size_t i = 0; i < bias_axes.size(); ++i) {
      const int c = static_cast<int>(i);
      const int col = NodeColumns::bias(wheels, common) + c;
      const double var = node_bias ? S(col, col) : m.global(c, c);
      node.bias_sigma[bias_axes[i]] = std::sqrt(std::max(var, 0.0));
    }
    if (accel_bias.size > 0) {
      const int c = accel_bias.place.col;
      node.accel_bias_sigma = m.global.block<3, 3>(c, c).diagonal().cwiseMax(0.0).cwiseSqrt();
    }
    if (icr.size > 0)
      node.icr_sigma = std::sqrt(std::max(m.global(icr.place.col, icr.place.col), 0.0));
  }
  return true;
}

}  // namespace traverse::smoother
