// A segment problem's parameter blocks as typed handles, and the residual blocks added on them
// (fuse's constraint/functor split: each residual's functor computes it; the constraint function
// beside it in smoother/residuals/ knows which blocks it takes and how it is weighted, and adds
// itself to a ResidualCollector).
//
// A handle is made once, when the parameter block is: its storage, its ambient size, its
// manifold and its place in the chain information (chain_marginals.h) — what Ceres, the block
// evaluator and the covariance each need, never recovered from the storage address.
#pragma once

#include <array>
#include <memory>
#include <optional>
#include <span>
#include <type_traits>
#include <vector>

#include <ceres/cost_function.h>
#include <ceres/loss_function.h>
#include <ceres/manifold.h>
#include <ceres/problem.h>

#include "traverse/smoother/block_evaluation.h"
#include "traverse/smoother/chain_marginals.h"

namespace traverse::smoother {

/// One parameter block of a segment problem.
struct BlockHandle {
  double* data = nullptr;
  int size = 0;                         ///< ambient size (a quaternion: 4)
  ChainPlace place;                     ///< tangent columns in the chain information
  ceres::Manifold* manifold = nullptr;  ///< nullptr: Euclidean
};

/// A node's tangent columns in the chain information (ChainPlace::col): δθ, x, v, ω, ξ (one per
/// wheel), X,
/// then, with the random-walk bias model, the node's own bias.
struct NodeColumns {
  static constexpr int kAttitude = 0, kPosition = 3, kVelocity = 6, kRate = 9, kContact = 12;
  static constexpr int commonSlip(int wheels) { return kContact + wheels; }
  /// Columns before the bias, and the bias's first column, for a rover with `wheels` wheels.
  static constexpr int states(int wheels, int common = 0) { return kContact + wheels + common; }
  static constexpr int bias(int wheels, int common = 0) { return kContact + wheels + common; }
};

/// Node k's blocks. `bias` is the gyro bias its residuals use: the node's own (random-walk
/// model; place on node k) or the segment's (constant model; ChainPlace::kGlobal). `c`: the
/// wheels' common slip (body x, y, and c_ω when declared), size 0 (no storage) when the rover
/// does not declare it.
/// `ba`: the accelerometer's bias (body, m/s²), one per segment (ChainPlace::kGlobal, after the
/// constant gyro bias), size 0 when the rover does not declare it or the log has no accel.csv.
/// `icr`: the skid-steer ICRs' half-track error δ (m, io::SkidSteerConfig), one per segment
/// (ChainPlace::kGlobal, after b_a), size 0 without it.
struct NodeHandles {
  BlockHandle q, x, v, w, xi, bias, c, ba, icr;
};

/// The last functor one kind of residual was made from, and its cost function. Nodes are mostly
/// equally spaced, so consecutive process residuals (attitude, position, rate, contact, zero
/// motion) are often the same function of their parameter blocks: one cost function then serves
/// every such residual block (Ceres evaluates a cost function for any number of them), which
/// saves an allocation, a free and its cache lines per node. The key is the functor itself
/// (its defaulted operator==: every number that defines it), so it cannot drift from the
/// constructor: a functor equal to the last reuses its cost function, any other makes a new one.
template <typename Functor>
struct CostMemo {
  std::optional<Functor> last;
  ceres::CostFunction* f = nullptr;
};

/// Most parameter blocks any residual here takes (the accelerometer process with its bias).
constexpr int kMaxBlocksPerResidual = 7;

/// One residual block as added: its cost function, loss and parameter blocks, in the cost
/// function's order.
struct ResidualEntry {
  ceres::ResidualBlockId id = nullptr;  ///< set by ResidualCollector::addTo
  const char* kind = nullptr;           ///< for the solver report's cost by kind
  ceres::CostFunction* f = nullptr;
  ceres::LossFunction* loss = nullptr;
  int num_rows = 0, num_blocks = 0;
  std::array<const BlockHandle*, kMaxBlocksPerResidual> blocks{};
};

/// A segment's residual blocks, collected before any goes to Ceres (addTo). It owns every cost
/// function; the handles it is given must outlive it (the builder's, made once).
class ResidualCollector {
 public:
  void reserve(size_t residual_blocks, size_t cost_functions) {
    entries_.reserve(residual_blocks);
    costs_.reserve(cost_functions);
  }

  /// A residual block with a new cost function, which the collector then owns.
  template <typename... Blocks>
  void add(const char* kind, ceres::CostFunction* f, ceres::LossFunction* loss,
           const Blocks&... blocks) {
    costs_.emplace_back(f);
    addBlock(kind, f, loss, blocks...);
  }

  /// A residual block whose cost function is Functor::Create(functor), or the memo's when
  /// functor equals the one it was made from (CostMemo).
  template <typename Functor, typename... Blocks>
  void addShared(const char* kind, CostMemo<Functor>& memo, const Functor& functor,
                 ceres::LossFunction* loss, const Blocks&... blocks) {
    if (!memo.last || !(*memo.last == functor)) {
      memo.f = Functor::Create(functor);
      costs_.emplace_back(memo.f);
      memo.last = functor;
    }
    addBlock(kind, memo.f, loss, blocks...);
  }

  /// Adds every residual block to `problem`, in the order collected, and records its id.
  void addTo(ceres::Problem& problem);
  /// ½ Σ ρ(‖r‖²) at the blocks' current values, block by block (BlockEvaluator): NaN if any
  /// block fails to evaluate.
  double cost(BlockEvaluator& evaluator) const;

  const std::vector<ResidualEntry>& entries() const { return entries_; }

 private:
  template <typename... Blocks>
  void addBlock(const char* kind, ceres::CostFunction* f, ceres::LossFunction* loss,
                const Blocks&... blocks) {
    static_assert(sizeof...(Blocks) <= kMaxBlocksPerResidual);
    static_assert((std::is_same_v<Blocks, BlockHandle> && ...));
    entries_.push_back({nullptr,
                        kind,
                        f,
                        loss,
                        f->num_residuals(),
                        static_cast<int>(sizeof...(Blocks)),
                        {&blocks...}});
  }

  std::vector<std::unique_ptr<ceres::CostFunction>> costs_;
  std::vector<ResidualEntry> entries_;
};

/// An entry's parameter-block storage and manifolds, in order, as Ceres and BlockEvaluator take
/// them.
struct EntryBlocks {
  std::array<double*, kMaxBlocksPerResidual> data{};
  std::array<const ceres::Manifold*, kMaxBlocksPerResidual> manifolds{};
  int size = 0;
  explicit EntryBlocks(const ResidualEntry& e) : size(e.num_blocks) {
    for (size_t i = 0; i < static_cast<size_t>(e.num_blocks); ++i) {
      data[i] = e.blocks[i]->data;
      manifolds[i] = e.blocks[i]->manifold;
    }
  }
  std::span<double* const> parameterBlocks() const {
    return {data.data(), static_cast<size_t>(size)};
  }
  std::span<const ceres::Manifold* const> blockManifolds() const {
    return {manifolds.data(), static_cast<size_t>(size)};
  }
};

}  // namespace traverse::smoother
