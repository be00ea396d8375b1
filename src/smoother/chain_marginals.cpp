#include "traverse/smoother/chain_marginals.h"

#include <algorithm>
#include <cstdlib>
#include <limits>
#include <stdexcept>
#include <string>

#include <Eigen/Cholesky>

namespace traverse::smoother {
namespace {

using Eigen::MatrixXd;

/// Rows buffered per dense rank update in chainInformationFromJacobian.
constexpr int kRowBatch = 64;

/// Width of the local window of addChainRows starting at node `first`.
int windowWidth(const ChainInformation& H, int first) {
  const int nodes = first + 1 < H.numNodes() ? 2 : 1;
  return nodes * H.node_dim + H.global_dim;
}

void requireBlock(const MatrixXd& M, int rows, int cols, const char* what) {
  if (M.rows() != rows || M.cols() != cols)
    throw std::invalid_argument(std::string("chainMarginals: ") + what + " block is " +
                                std::to_string(M.rows()) + "x" + std::to_string(M.cols()) +
                                ", expected " + std::to_string(rows) + "x" + std::to_string(cols));
}

void validate(const ChainInformation& H) {
  const int n = H.numNodes(), d = H.node_dim, m = H.global_dim;
  if (n < 1 || d < 1 || m < 0)
    throw std::invalid_argument("chainMarginals: need at least one node of positive size");
  if (static_cast<int>(H.upper.size()) != n - 1 || static_cast<int>(H.global_coupling.size()) != n)
    throw std::invalid_argument("chainMarginals: need N-1 upper and N global coupling blocks");
  for (int k = 0; k < n; ++k) {
    requireBlock(H.diag[k], d, d, "diagonal");
    requireBlock(H.global_coupling[k], d, m, "global coupling");
    if (k + 1 < n) requireBlock(H.upper[k], d, d, "upper");
  }
  requireBlock(H.global, m, m, "global");
}

/// M ← (M + Mᵀ)/2 in place.
void symmetrize(MatrixXd& M) {
  for (Eigen::Index j = 0; j < M.cols(); ++j)
    for (Eigen::Index i = j + 1; i < M.rows(); ++i) M(i, j) = M(j, i) = 0.5 * (M(i, j) + M(j, i));
}

/// The block LDLᵀ forward pass (header equations). Leaves A_k⁻¹ in out.node[k], K_k in
/// out.node_global[k] and the global pivot in F; false if a node pivot is not positive definite.
/// G_k = A_k⁻¹ B_k is not stored (it would double the peak memory, N d² doubles); the backward
/// pass recomputes it. With A_k = L Lᵀ, W = L⁻¹ B_k and V = L⁻¹ E'_k:
///   B_kᵀ G_k = WᵀW,  K_k = L⁻ᵀ V,  E'_kᵀ K_k = VᵀV,  B_kᵀ K_k = WᵀV.
bool forwardPass(const ChainInformation& H, ChainMarginals& out, MatrixXd& F) {
  const int n = H.numNodes(), d = H.node_dim, m = H.global_dim;
  MatrixXd A = H.diag[0], E = H.global_coupling[0], W(d, d), V(d, m);
  F = H.global;
  const MatrixXd I = MatrixXd::Identity(d, d);
  Eigen::LLT<MatrixXd> llt(d);
  for (int k = 0; k < n; ++k) {
    llt.compute(A);  // reads the lower triangle only
    if (llt.info() != Eigen::Success) return false;
    const auto L = llt.matrixL();
    out.node[k] = llt.solve(I);
    symmetrize(out.node[k]);
    if (m > 0) {
      V = E;
      L.solveInPlace(V);
      out.node_global[k] = V;
      llt.matrixU().solveInPlace(out.node_global[k]);
      F.selfadjointView<Eigen::Lower>().rankUpdate(V.transpose(), -1.0);
    }
    if (k + 1 == n) break;
    W = H.upper[k];
    L.solveInPlace(W);
    A = H.diag[k + 1];
    A.selfadjointView<Eigen::Lower>().rankUpdate(W.transpose(), -1.0);
    if (m > 0) {
      E = H.global_coupling[k + 1];
      E.noalias() -= W.transpose() * V;
    }
  }
  return true;
}

/// The backward recursion (header equations), k = N−1 … 0, overwriting A_k⁻¹ and K_k in place
/// with Σ_kk and Σ_kg; needs Σ_gg in out.global.
void backwardPass(const ChainInformation& H, ChainMarginals& out) {
  const int n = H.numNodes(), d = H.node_dim, m = H.global_dim;
  MatrixXd G(d, d), S_kg(d, m), S_k_k1(d, d);
  for (int k = n - 1; k >= 0; --k) {
    MatrixXd& S_kk = out.node[k];  // A_k⁻¹ on entry
    const MatrixXd& K = out.node_global[k];
    if (m > 0) S_kg.noalias() = -K * out.global;
    if (k + 1 < n) {
      G.noalias() = S_kk * H.upper[k];
      const MatrixXd& S_k1g = out.node_global[k + 1];
      if (m > 0) S_kg.noalias() -= G * S_k1g;
      S_k_k1.noalias() = -G * out.node[k + 1];
      if (m > 0) S_k_k1.noalias() -= K * S_k1g.transpose();
      S_kk.noalias() -= G * S_k_k1.transpose();
    }
    if (m > 0) S_kk.noalias() -= K * S_kg.transpose();
    symmetrize(S_kk);
    out.node_global[k] = S_kg;
  }
}

}  // namespace

ChainInformation makeChainInformation(int num_nodes, int node_dim, int global_dim) {
  if (num_nodes < 1 || node_dim < 1 || global_dim < 0)
    throw std::invalid_argument("makeChainInformation: need num_nodes >= 1, node_dim >= 1, " +
                                std::string("global_dim >= 0"));
  ChainInformation H;
  H.node_dim = node_dim;
  H.global_dim = global_dim;
  const auto n = static_cast<size_t>(num_nodes);
  H.diag.assign(n, MatrixXd::Zero(node_dim, node_dim));
  H.upper.assign(n - 1, MatrixXd::Zero(node_dim, node_dim));
  H.global_coupling.assign(n, MatrixXd::Zero(node_dim, global_dim));
  H.global = MatrixXd::Zero(global_dim, global_dim);
  return H;
}

void addChainRows(ChainInformation& H, int first_node,
                  const Eigen::Ref<const Eigen::MatrixXd>& J_local) {
  if (first_node < 0 || first_node >= H.numNodes())
    throw std::invalid_argument("addChainRows: node " + std::to_string(first_node) +
                                " out of range");
  const int d = H.node_dim, m = H.global_dim, w = windowWidth(H, first_node);
  if (J_local.cols() != w)
    throw std::invalid_argument("addChainRows: block has " + std::to_string(J_local.cols()) +
                                " columns, window at node " + std::to_string(first_node) + " has " +
                                std::to_string(w));
  MatrixXd S(w, w);
  S.noalias() = J_local.transpose() * J_local;
  const int g = w - m;  // first global column of the window
  H.diag[first_node] += S.topLeftCorner(d, d);
  H.global_coupling[first_node] += S.block(0, g, d, m);
  H.global += S.bottomRightCorner(m, m);
  if (g == 2 * d) {
    H.upper[first_node] += S.block(0, d, d, d);
    H.diag[first_node + 1] += S.block(d, d, d, d);
    H.global_coupling[first_node + 1] += S.block(d, g, d, m);
  }
}

void addChainResidual(ChainInformation& H, std::span<const ChainPlace> places,
                      const double* const* jacobians, int rows) {
  using RowMajorMap =
      Eigen::Map<const Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>>;
  const int n = H.numNodes(), d = H.node_dim, m = H.global_dim;
  for (const ChainPlace& p : places) {
    const int width = p.node == ChainPlace::kGlobal ? m : d;
    if (p.node < ChainPlace::kGlobal || p.node >= n || p.col < 0 || p.size < 0 ||
        p.col + p.size > width)
      throw std::invalid_argument("addChainResidual: block at node " + std::to_string(p.node) +
                                  ", columns " + std::to_string(p.col) + "+" +
                                  std::to_string(p.size) + " is outside the chain");
  }
  for (size_t i = 0; i < places.size(); ++i) {
    const ChainPlace& a = places[i];
    const RowMajorMap Ja(jacobians[i], rows, a.size);
    for (size_t j = 0; j < places.size(); ++j) {
      const ChainPlace& b = places[j];
      const RowMajorMap Jb(jacobians[j], rows, b.size);
      // Each unordered pair lands once in the stored upper arrow; the diagonal blocks are kept
      // whole (both orders of a same-node pair are added).
      if (a.node != ChainPlace::kGlobal && b.node != ChainPlace::kGlobal) {
        if (std::abs(a.node - b.node) > 1)
          throw std::invalid_argument("addChainResidual: a residual couples nodes " +
                                      std::to_string(a.node) + " and " + std::to_string(b.node));
        if (a.node == b.node)
          H.diag[a.node].block(a.col, b.col, a.size, b.size).noalias() += Ja.transpose() * Jb;
        else if (b.node == a.node + 1)
          H.upper[a.node].block(a.col, b.col, a.size, b.size).noalias() += Ja.transpose() * Jb;
      } else if (a.node != ChainPlace::kGlobal) {
        H.global_coupling[a.node].block(a.col, b.col, a.size, b.size).noalias() +=
            Ja.transpose() * Jb;
      } else if (b.node == ChainPlace::kGlobal) {
        H.global.block(a.col, b.col, a.size, b.size).noalias() += Ja.transpose() * Jb;
      }
    }
  }
}

ChainInformation chainInformationFromJacobian(const ceres::CRSMatrix& J, int num_nodes,
                                              int node_dim, int global_dim) {
  ChainInformation H = makeChainInformation(num_nodes, node_dim, global_dim);
  const int node_cols = num_nodes * node_dim;
  if (J.num_cols != node_cols + global_dim)
    throw std::invalid_argument("chainInformationFromJacobian: Jacobian has " +
                                std::to_string(J.num_cols) + " columns, expected " +
                                std::to_string(node_cols + global_dim));
  if (static_cast<int>(J.rows.size()) != J.num_rows + 1)
    throw std::invalid_argument("chainInformationFromJacobian: malformed CRS row offsets");

  // Consecutive rows that fit one two-node window are gathered densely and added by one rank
  // update; a row outside the current window (or a full buffer) flushes the batch.
  MatrixXd batch(kRowBatch, 2 * node_dim + global_dim);
  int window = 0, count = 0;
  const auto flush = [&] {
    if (count > 0) addChainRows(H, window, batch.topLeftCorner(count, windowWidth(H, window)));
    count = 0;
  };
  for (int r = 0; r < J.num_rows; ++r) {
    int lo = std::numeric_limits<int>::max(), hi = -1;
    for (int i = J.rows[r]; i < J.rows[r + 1]; ++i) {
      const int c = J.cols[i];
      if (c < 0 || c >= J.num_cols)
        throw std::invalid_argument("chainInformationFromJacobian: row " + std::to_string(r) +
                                    " has column " + std::to_string(c) + " out of range");
      if (c < node_cols) {
        lo = std::min(lo, c / node_dim);
        hi = std::max(hi, c / node_dim);
      }
    }
    if (hi >= 0 && hi - lo > 1)
      throw std::invalid_argument("chainInformationFromJacobian: row " + std::to_string(r) +
                                  " couples nodes " + std::to_string(lo) + " and " +
                                  std::to_string(hi) + ", more than one apart");
    if (hi >= 0 && (lo < window || hi > window + 1)) {
      flush();
      window = lo;
    }
    if (count == kRowBatch) flush();
    const int g = windowWidth(H, window) - global_dim;
    auto row = batch.row(count++);
    row.setZero();
    for (int i = J.rows[r]; i < J.rows[r + 1]; ++i) {
      const int c = J.cols[i];
      row[c < node_cols ? c - window * node_dim : g + (c - node_cols)] += J.values[i];
    }
  }
  flush();
  return H;
}

ChainMarginals chainMarginals(const ChainInformation& H) {
  validate(H);
  const int n = H.numNodes(), d = H.node_dim, m = H.global_dim;
  ChainMarginals out;
  out.node.assign(static_cast<size_t>(n), MatrixXd(d, d));
  out.node_global.assign(static_cast<size_t>(n), MatrixXd(d, m));
  MatrixXd F;
  if (!forwardPass(H, out, F)) return ChainMarginals{};
  if (m > 0) {
    Eigen::LLT<MatrixXd> llt_g(F);
    if (llt_g.info() != Eigen::Success) return ChainMarginals{};
    out.global = llt_g.solve(MatrixXd::Identity(m, m));
    symmetrize(out.global);
  } else {
    out.global.resize(0, 0);
  }
  backwardPass(H, out);
  out.ok = true;
  return out;
}

}  // namespace traverse::smoother
