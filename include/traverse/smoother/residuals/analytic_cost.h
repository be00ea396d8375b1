// A residual functor with an analytic Jacobian as a Ceres cost function: Functor::Evaluate has
// ceres::CostFunction::Evaluate's signature and meaning. The functor stays a plain value — it
// can have a defaulted operator==, which a CostFunction subclass cannot — so the smoother's
// cost memo (residual_collector.h) compares functors, not a key written out beside them.
#pragma once

#include <concepts>
#include <utility>

#include <ceres/cost_function.h>
#include <ceres/sized_cost_function.h>

namespace traverse::smoother {

template <typename Functor, int kResiduals, int... kSizes>
class AnalyticCost final : public ceres::SizedCostFunction<kResiduals, kSizes...> {
 public:
  /// Constructs the functor from `args` (its own constructor's, or a functor to copy).
  template <typename... Args>
  requires std::constructible_from<Functor, Args...>
  explicit AnalyticCost(Args&&... args) : f_(std::forward<Args>(args)...) {}

  bool Evaluate(double const* const* parameters, double* residuals,
                double** jacobians) const override {
    return f_.Evaluate(parameters, residuals, jacobians);
  }

  const Functor& functor() const { return f_; }

 private:
  Functor f_;
};

/// The same for parameter blocks whose sizes are known at run time only (a rover's contact
/// angles: one per wheel). The functor says them: numResiduals() and blockSizes().
template <typename Functor>
class DynamicAnalyticCost final : public ceres::CostFunction {
 public:
  template <typename... Args>
  requires std::constructible_from<Functor, Args...>
  explicit DynamicAnalyticCost(Args&&... args) : f_(std::forward<Args>(args)...) {
    set_num_residuals(f_.numResiduals());
    for (const int size : f_.blockSizes()) mutable_parameter_block_sizes()->push_back(size);
  }

  bool Evaluate(double const* const* parameters, double* residuals,
                double** jacobians) const override {
    return f_.Evaluate(parameters, residuals, jacobians);
  }

  const Functor& functor() const { return f_; }

 private:
  Functor f_;
};

}  // namespace traverse::smoother
