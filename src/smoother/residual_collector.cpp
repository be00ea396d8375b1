// include/traverse/smoother/residual_collector.h
#include "traverse/smoother/residual_collector.h"

#include <limits>

namespace traverse::smoother {

void ResidualCollector::addTo(ceres::Problem& problem) {
  // Every cost function exists before the first residual block: Ceres' blocks (a ResidualBlock
  // and its parameter-block array each) then lie one after the other in memory, in the order
  // every pass of its preprocessing, evaluation and teardown walks them, instead of interleaved
  // with the cost functions. At 10 000 nodes those walks run from memory, not cache, and the
  // interleaving made them — and freeing the blocks — grow faster than the node count.
  for (ResidualEntry& e : entries_) {
    const EntryBlocks b(e);
    e.id = problem.AddResidualBlock(e.f, e.loss, b.data.data(), e.num_blocks);
  }
}

double ResidualCollector::cost(BlockEvaluator& evaluator) const {
  double total = 0.0;
  for (const ResidualEntry& e : entries_) {
    const EntryBlocks b(e);
    double c = 0.0;
    if (!evaluator.evaluate(*e.f, e.loss, b.parameterBlocks(), b.blockManifolds(), &c, nullptr,
                            nullptr))
      return std::numeric_limits<double>::quiet_NaN();
    total += c;
  }
  return total;
}

}  // namespace traverse::smoother
