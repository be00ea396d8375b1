// A cost function whose residual sees the two attitudes of a node interval only through their
// midpoint, r = F(q̄, other blocks), q̄ = q_k ⊗ Exp(½ Log(q_k⁻¹ ⊗ q_{k+1})) (interpolation.h): the
// position process (K-1) and the accelerometer-driven velocity process (K-11, O-4).
//
// Differentiated by the chain rule in two automatic stages instead of one: ∂q̄/∂(q_k, q_{k+1})
// with 8-wide Jets (the Log/Exp of the interpolation), then F with Jets over q̄ and the other
// blocks only. A single AutoDiffCostFunction carries 20-wide Jets through the Log/Exp; that was
// over half of the smoother's Jacobian evaluation time. The physics stays in the functor's one
// templated F (Functor::atMidpoint), also used for the residual without Jacobians and for the
// full-autodiff twin the tests compare against.
//
// Parameter blocks: six, of sizes kSizes...; blocks kQa and kQb are q_k and q_{k+1} (x, y, z, w;
// ambient Jacobians, 4 columns, as AutoDiffCostFunction reports them). Functor::atMidpoint<T>(
// const Quat<T>& q_mid, const T* const* blocks, T* r) reads every other block from blocks[i].
#pragma once

#include <array>

#include <ceres/jet.h>
#include <ceres/sized_cost_function.h>

#include "traverse/smoother/residuals/interpolation.h"

namespace traverse::smoother {

template <typename Functor, int kResiduals, int kQa, int kQb, int... kSizes>
class MidpointAttitudeCost final : public ceres::SizedCostFunction<kResiduals, kSizes...> {
  static constexpr int kBlocks = sizeof...(kSizes);
  static constexpr std::array<int, kBlocks> kSize{kSizes...};
  static_assert(kSize[kQa] == 4 && kSize[kQb] == 4, "the attitude blocks are quaternions");
  static constexpr int kMaxBlockSize = 4;
  /// Jet width of the second stage: q̄ (4) and every non-attitude parameter.
  static constexpr int kWidth = (kSizes + ...) - 4;

 public:
  explicit MidpointAttitudeCost(Functor f) : f_(std::move(f)) {}

  const Functor& functor() const { return f_; }

  bool Evaluate(double const* const* p, double* r, double** J) const override {
    if (!J) {
      return f_.atMidpoint(midpointAttitude(p[kQa], p[kQb]), p, r);
    }
    // Stage 1: q̄ and ∂q̄/∂q_k (derivative slots 0–3), ∂q̄/∂q_{k+1} (slots 4–7).
    using J8 = ceres::Jet<double, 8>;
    Quat<J8> qa, qb;
    for (int i = 0; i < 4; ++i) {
      qa.coeffs()[i] = J8(p[kQa][i], i);
      qb.coeffs()[i] = J8(p[kQb][i], 4 + i);
    }
    const Quat<J8> q_mid8 = interpolateAttitude(qa, qb, 0.5);
    // Stage 2: F with q̄ in slots 0–3 and the other blocks after, in block order.
    using JN = ceres::Jet<double, kWidth>;
    std::array<std::array<JN, kMaxBlockSize>, kBlocks> values;
    std::array<const JN*, kBlocks> blocks{};
    std::array<int, kBlocks> slot{};
    for (int b = 0, next = 4; b < kBlocks; ++b) {
      blocks[static_cast<size_t>(b)] = values[static_cast<size_t>(b)].data();
      if (b == kQa || b == kQb) continue;
      slot[static_cast<size_t>(b)] = next;
      for (int i = 0; i < kSize[static_cast<size_t>(b)]; ++i)
        values[static_cast<size_t>(b)][static_cast<size_t>(i)] = JN(p[b][i], next++);
    }
    Quat<JN> q_mid;
    for (int i = 0; i < 4; ++i) q_mid.coeffs()[i] = JN(q_mid8.coeffs()[i].a, i);
    std::array<JN, kResiduals> res;
    if (!f_.atMidpoint(q_mid, blocks.data(), res.data())) return false;
    for (int k = 0; k < kResiduals; ++k) r[k] = res[static_cast<size_t>(k)].a;
    for (int b = 0; b < kBlocks; ++b) {
      if (!J[b]) continue;
      const int size = kSize[static_cast<size_t>(b)];
      for (int k = 0; k < kResiduals; ++k) {
        const JN& rk = res[static_cast<size_t>(k)];
        double* row = J[b] + k * size;
        if (b == kQa || b == kQb) {  // ∂r/∂q̄ · ∂q̄/∂q
          const int from = b == kQa ? 0 : 4;
          for (int c = 0; c < 4; ++c) {
            double sum = 0.0;
            for (int m = 0; m < 4; ++m) sum += rk.v[m] * q_mid8.coeffs()[m].v[from + c];
            row[c] = sum;
          }
        } else {
          for (int c = 0; c < size; ++c) row[c] = rk.v[slot[static_cast<size_t>(b)] + c];
        }
      }
    }
    return true;
  }

 private:
  Functor f_;
};

}  // namespace traverse::smoother
