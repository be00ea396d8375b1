// Exact marginal covariances of a block-chain least-squares problem, in O(N d³).
//
// The batch smoother's unknowns are N node blocks of tangent size d (node k: columns
// [k d, (k+1) d)) followed by m global columns (the segment's gyro bias; m may be 0). Every
// residual row touches at most two consecutive nodes and possibly the global columns, so the
// Gauss-Newton information H = JᵀJ is block tridiagonal plus a dense last block row/column (an
// "arrow"):
//
//        ⎡ H₀₀  B₀              E₀ ⎤     B_k = H_{k,k+1}   (d×d)
//   H =  ⎢ B₀ᵀ  H₁₁  B₁         E₁ ⎥     E_k = H_{k,g}     (d×m)
//        ⎢      ⋱    ⋱    ⋱     ⋮  ⎥     H_gg              (m×m)
//        ⎣ E₀ᵀ  E₁ᵀ   …        H_gg⎦
//
// Forward pass: block LDLᵀ in natural order (nodes, then g). Eliminating node k with pivot A_k
// fills nothing new; it only updates the next pivot, the next coupling and the global pivot:
//   A₀ = H₀₀,  E'₀ = E₀,  F = H_gg
//   G_k = A_k⁻¹ B_k,  K_k = A_k⁻¹ E'_k                 (L_{k+1,k} = G_kᵀ, L_{g,k} = K_kᵀ)
//   A_{k+1} = H_{k+1,k+1} − B_kᵀ G_k,  E'_{k+1} = E_{k+1} − B_kᵀ K_k,  F ← F − E'_kᵀ K_k
// so D = diag(A₀ … A_{N−1}, F), and H is positive definite iff every A_k and F are.
//
// Backward pass (Takahashi et al. 1973; the RTS smoother's covariance recursion): from
// Σ = H⁻¹ = L⁻ᵀ D⁻¹ L⁻¹ we have Lᵀ Σ = D⁻¹ L⁻¹, whose right side is block upper triangular with
// diagonal D⁻¹. Reading off the blocks (i, j), i ≤ j, of  Σ = D⁻¹ L⁻¹ + (I − Lᵀ) Σ  gives
//   Σ_gg = F⁻¹
//   Σ_kg      = −G_k Σ_{k+1,g}   − K_k Σ_gg
//   Σ_{k,k+1} = −G_k Σ_{k+1,k+1} − K_k Σ_{g,k+1}
//   Σ_kk      = A_k⁻¹ − G_k Σ_{k+1,k} − K_k Σ_{g,k}
// for k = N−1 … 0, where the G terms are absent at k = N−1. Only the blocks in H's sparsity
// pattern are ever needed, which is what makes the recursion exact and linear in N. Memory: the
// outputs plus O(d²) (A_k⁻¹ and K_k are kept in the output slots they are replaced by; G_k is
// recomputed from A_k⁻¹ in the backward pass).
#pragma once

#include <span>
#include <vector>

#include <ceres/crs_matrix.h>
#include <Eigen/Core>

namespace traverse::smoother {

/// Information matrix H = JᵀJ of a chain problem in block form (upper triangle of the arrow).
struct ChainInformation {
  int node_dim = 0, global_dim = 0;
  std::vector<Eigen::MatrixXd> diag;             ///< N blocks H_kk (d×d)
  std::vector<Eigen::MatrixXd> upper;            ///< N−1 blocks H_{k,k+1} (d×d)
  std::vector<Eigen::MatrixXd> global_coupling;  ///< N blocks H_{k,g} (d×m)
  Eigen::MatrixXd global;                        ///< H_gg (m×m)
  int numNodes() const { return static_cast<int>(diag.size()); }
};

/// A zero information matrix with num_nodes ≥ 1 nodes; throws std::invalid_argument otherwise.
ChainInformation makeChainInformation(int num_nodes, int node_dim, int global_dim);

/// Adds JₗᵀJₗ for a dense block of Jacobian rows Jₗ that touch at most nodes `first_node` and
/// `first_node` + 1 and the global columns. Jₗ's columns are the local window: node first_node
/// (d), node first_node + 1 (d, only if first_node + 1 < N), then the m global columns.
void addChainRows(ChainInformation& H, int first_node,
                  const Eigen::Ref<const Eigen::MatrixXd>& J_local);

/// Accumulates JᵀJ from a ceres::CRSMatrix whose columns are ordered as described (N·d node
/// columns then m global columns). Throws std::invalid_argument naming the row if a row couples
/// nodes more than one apart, or if the column count does not match.
ChainInformation chainInformationFromJacobian(const ceres::CRSMatrix& J, int num_nodes,
                                              int node_dim, int global_dim);

/// Where one parameter block's tangent columns sit in a chain problem: in node `node`'s block
/// (0 ≤ node < N) or, with node = kGlobal, among the m global columns; starting at column `col`
/// of that block, `size` columns wide.
struct ChainPlace {
  static constexpr int kGlobal = -1;
  int node = kGlobal, col = 0, size = 0;
};

/// Adds JᵀJ of one residual block whose Jacobian comes split by parameter block, as Ceres'
/// Problem::EvaluateResidualBlock returns it: jacobians[i] is the rows × places[i].size
/// Jacobian of parameter block i, row-major. Only the products of blocks that share rows are
/// formed (Σᵢ sizeᵢ)² · rows flops, not the (2d + m)² · rows of a dense two-node window. Throws
/// std::invalid_argument if a place is out of range or two blocks sit on nodes more than one
/// apart.
void addChainResidual(ChainInformation& H, std::span<const ChainPlace> places,
                      const double* const* jacobians, int rows);

struct ChainMarginals {
  bool ok = false;  ///< false if H is not positive definite (the other members are then empty)
  std::vector<Eigen::MatrixXd> node;         ///< Σ_kk (d×d)
  Eigen::MatrixXd global;                    ///< Σ_gg (m×m)
  std::vector<Eigen::MatrixXd> node_global;  ///< Σ_kg (d×m)
};

/// The diagonal blocks of H⁻¹ (and Σ_kg) by the recursion above; symmetric outputs. Throws
/// std::invalid_argument if the blocks' sizes are inconsistent.
ChainMarginals chainMarginals(const ChainInformation& H);

}  // namespace traverse::smoother
