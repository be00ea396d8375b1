// First-order Gauss-Markov process between consecutive nodes, per component i:
//
//   ẏ_i = a_i (y_i − m_i(t)) + n_i,  E[n_i n_i] = q_i δ(t)           (continuous)
//   r_i = (y_{k+1,i} − m_{k+1,i} − φ_i (y_{k,i} − m_{k,i})) / σ_i,   φ_i = exp(a_i Δt),
//   σ_i² = q_i (1 − φ_i²) / (−2 a_i)   (→ q_i Δt as a_i → 0: a random walk)
//
// One functor, four processes of the papers:
//   - K-1 / K-2: velocity and rate perturbations v_p = v − v_c, ω_p = ω − ω_c around the
//     commanded twist m = (v_c, ω_c), decaying with the time constants of rover.yaml (random
//     walks, a = 0, when the log has no cmd.csv — K §4.2);
//   - K-8: contact angles ξ, m = 0, returning toward 0;
//   - K-9: gyro bias random walk, a = 0, m = 0.
// The residual is linear in (y_k, y_{k+1}): the Jacobians are the constant diagonals
// −φ/σ and 1/σ, written out instead of differentiated.
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <vector>

#include <ceres/sized_cost_function.h>

#include "traverse/core/types.h"
#include "traverse/rover/joint_sample.h"
#include "traverse/rover/rover_geometry.h"
#include "traverse/smoother/residual_collector.h"
#include "traverse/smoother/residuals/analytic_cost.h"

namespace traverse::smoother {

/// φ = exp(a Δt) and 1/σ of one component's transition (the header's formulas).
struct MarkovStep {
  double phi = 1.0, sqrt_info = 0.0;
  MarkovStep(double dt, double a, double q)
      : phi(std::exp(a * dt)),
        sqrt_info(1.0 / std::sqrt(a < 0 ? q * -std::expm1(2.0 * a * dt) / (-2.0 * a) : q * dt)) {}
  bool operator==(const MarkovStep&) const = default;
};

/// The N-component process of the header (functor; MarkovProcessResidual is its cost function).
template <int N>
class MarkovProcess {
 public:
  using VecN = Eigen::Matrix<double, N, 1>;

  /// a: rates (1/s, ≤ 0), q: noise densities (units² / s), means at both nodes.
  MarkovProcess(double dt, const VecN& a, const VecN& q, const VecN& mean_k, const VecN& mean_k1)
      : mean_k_(mean_k), mean_k1_(mean_k1) {
    for (int i = 0; i < N; ++i) {
      const MarkovStep step(dt, a[i], q[i]);
      phi_[i] = step.phi, sqrt_info_[i] = step.sqrt_info;
    }
  }

  bool Evaluate(double const* const* parameters, double* residuals, double** jacobians) const {
    const Eigen::Map<const VecN> y_k(parameters[0]), y_k1(parameters[1]);
    Eigen::Map<VecN>{residuals} =
        sqrt_info_.cwiseProduct((y_k1 - mean_k1_) - phi_.cwiseProduct(y_k - mean_k_));
    if (jacobians) {
      using RowMajorN = Eigen::Matrix<double, N, N, N == 1 ? Eigen::ColMajor : Eigen::RowMajor>;
      if (jacobians[0])
        Eigen::Map<RowMajorN>{jacobians[0]} = (-sqrt_info_.cwiseProduct(phi_)).asDiagonal();
      if (jacobians[1]) Eigen::Map<RowMajorN>{jacobians[1]} = sqrt_info_.asDiagonal();
    }
    return true;
  }

  const VecN& sqrtInformation() const { return sqrt_info_; }
  const VecN& phi() const { return phi_; }

  bool operator==(const MarkovProcess&) const = default;

  static ceres::CostFunction* Create(const MarkovProcess& f) {
    return new AnalyticCost<MarkovProcess, N, N, N>(f);
  }

 private:
  VecN mean_k_, mean_k1_, phi_, sqrt_info_;
};

/// Cost function: parameter blocks y_k, y_{k+1} (N each).
template <int N>
using MarkovProcessResidual = AnalyticCost<MarkovProcess<N>, N, N, N>;

}  // namespace traverse::smoother

namespace traverse::smoother {

/// One component i of a zero-mean n-dimensional process of the header, as its own one-row
/// residual over the full n-vectors: r = (y_{k+1,i} − φ y_{k,i}) / σ. The smoother uses it for
/// K-8 per wheel (n = the rover's wheel count), so that a robust loss acts on each wheel's
/// contact-angle increment alone: a wheel meeting an edge changes its contact angle by many σ
/// of the Gaussian process within a few samples, and a loss on the whole block would charge
/// that jump to every wheel.
class MarkovComponent {
 public:
  /// component in [0, size); a: rate (1/s, ≤ 0), q: noise density (units² / s).
  MarkovComponent(int component, int size, double dt, double a, double q)
      : i_(component), n_(size), step_(dt, a, q) {}
  int numResiduals() const { return 1; }
  std::array<int, 2> blockSizes() const { return {n_, n_}; }

  bool Evaluate(double const* const* parameters, double* residuals, double** jacobians) const {
    residuals[0] = step_.sqrt_info * (parameters[1][i_] - step_.phi * parameters[0][i_]);
    if (jacobians) {
      for (int k = 0; k < 2; ++k) {
        if (!jacobians[k]) continue;
        std::fill(jacobians[k], jacobians[k] + n_, 0.0);
        jacobians[k][i_] = k == 0 ? -step_.phi * step_.sqrt_info : step_.sqrt_info;
      }
    }
    return true;
  }

  int component() const { return i_; }
  const MarkovStep& step() const { return step_; }

  bool operator==(const MarkovComponent&) const = default;

  static ceres::CostFunction* Create(const MarkovComponent& f) {
    return new DynamicAnalyticCost<MarkovComponent>(f);
  }

 private:
  int i_, n_;
  MarkovStep step_;
};

/// Cost function: parameter blocks y_k, y_{k+1} (n each), one row.
using MarkovComponentResidual = DynamicAnalyticCost<MarkovComponent>;

/// The extra information on the common mode (the mean over components) of a zero-mean
/// n-dimensional process whose components have density q each and whose mean has the smaller
/// density q_c (per-component units): Q = q I + (q_c − q)/n · 1 1ᵀ. Its information is
/// Q⁻¹ = (1/q) (I + (q/q_c − 1)/n · 1 1ᵀ): the n per-component rows (MarkovComponent) carry
/// (1/q) I, and this one row the rank-one rest,
///   r = √(n (q/q_c − 1)) · (ȳ_{k+1} − φ ȳ_k) / σ,   ȳ = mean of the components,
/// σ the per-component step's (MarkovStep with q). With dt = 0 and `stationary` the same for
/// the stationary prior at a segment's first node, r = √(n (q/q_c − 1)) · ȳ_k / σ_stat (one
/// block). The smoother uses it for the contact angles' common mode (rover.yaml
/// process.common_contact_angle_noise_rad_per_sqrt_s).
class MarkovCommonMode {
 public:
  /// Transition between two nodes.
  MarkovCommonMode(int size, double dt, double a, double q, double q_common)
      : n_(size), blocks_(2), phi_(MarkovStep(dt, a, q).phi) {
    weight_ = std::sqrt(size * (q / q_common - 1.0)) * MarkovStep(dt, a, q).sqrt_info;
  }
  /// Stationary prior (one block): σ_stat² = q/(−2a) per component.
  static MarkovCommonMode stationary(int size, double a, double q, double q_common) {
    MarkovCommonMode m(size, 1.0, a, q, q_common);
    m.blocks_ = 1, m.phi_ = 0.0;
    m.weight_ = std::sqrt(size * (q / q_common - 1.0)) / std::sqrt(q / (-2.0 * a));
    return m;
  }
  int numResiduals() const { return 1; }
  std::vector<int> blockSizes() const { return std::vector<int>(static_cast<size_t>(blocks_), n_); }

  bool Evaluate(double const* const* parameters, double* residuals, double** jacobians) const {
    const double w = weight_ / n_;
    double r = 0.0;
    if (blocks_ == 1) {
      for (int i = 0; i < n_; ++i) r += parameters[0][i];
    } else {
      for (int i = 0; i < n_; ++i) r += parameters[1][i] - phi_ * parameters[0][i];
    }
    residuals[0] = w * r;
    if (jacobians) {
      if (blocks_ == 1) {
        if (jacobians[0]) std::fill(jacobians[0], jacobians[0] + n_, w);
      } else {
        if (jacobians[0]) std::fill(jacobians[0], jacobians[0] + n_, -phi_ * w);
        if (jacobians[1]) std::fill(jacobians[1], jacobians[1] + n_, w);
      }
    }
    return true;
  }

  double weight() const { return weight_; }
  bool operator==(const MarkovCommonMode&) const = default;

  static ceres::CostFunction* Create(const MarkovCommonMode& f) {
    return new DynamicAnalyticCost<MarkovCommonMode>(f);
  }

 private:
  int n_, blocks_;
  double phi_, weight_ = 0.0;
};

/// The process's stationary distribution at a segment's first node (e.g. K-8's contact angles,
/// ξ ~ N(0, q τ / 2)): r = y / σ, one block of sigma.size(). Without it a contact angle no wheel
/// constrains would be unobservable.
class StationaryPriorResidual final : public ceres::CostFunction {
 public:
  explicit StationaryPriorResidual(const Eigen::VectorXd& sigma)
      : sqrt_info_(sigma.cwiseInverse()) {
    set_num_residuals(static_cast<int>(sigma.size()));
    mutable_parameter_block_sizes()->push_back(static_cast<int>(sigma.size()));
  }

  bool Evaluate(double const* const* parameters, double* residuals,
                double** jacobians) const override {
    const auto n = sqrt_info_.size();
    Eigen::Map<Eigen::VectorXd>(residuals, n) =
        sqrt_info_.cwiseProduct(Eigen::Map<const Eigen::VectorXd>(parameters[0], n));
    if (jacobians && jacobians[0]) {  // n × n, row-major (diagonal: the same either way)
      Eigen::Map<Eigen::MatrixXd>(jacobians[0], n, n) = sqrt_info_.asDiagonal();
    }
    return true;
  }

 private:
  Eigen::VectorXd sqrt_info_;
};

// Constraints (residual_collector.h): this file's residuals in a segment problem, between nodes
// k and k + 1 unless said otherwise.

/// A body twist's perturbation (`member`: &NodeHandles::w for the rate, K-2; &NodeHandles::v for
/// the velocity, K-1) around the commanded one (cmd_k, cmd_k1; zero, with a = 0, without
/// cmd.csv), a and q per axis. Consecutive equal ones share a cost function.
inline void addTwistProcess(ResidualCollector& out, const char* kind,
                            CostMemo<MarkovProcess<3>>& memo, BlockHandle NodeHandles::*member,
                            double dt, double a, double q, const Vec3d& cmd_k, const Vec3d& cmd_k1,
                            const NodeHandles& k, const NodeHandles& k1) {
  out.addShared(kind, memo,
                MarkovProcess<3>(dt, Vec3d::Constant(a), Vec3d::Constant(q), cmd_k, cmd_k1),
                nullptr, k.*member, k1.*member);
}

/// Rate perturbation (K-2). Blocks ω_k, ω_{k+1}.
inline void addRateProcess(ResidualCollector& out, CostMemo<MarkovProcess<3>>& memo, double dt,
                           double a, double q, const Vec3d& cmd_k, const Vec3d& cmd_k1,
                           const NodeHandles& k, const NodeHandles& k1) {
  addTwistProcess(out, "rate", memo, &NodeHandles::w, dt, a, q, cmd_k, cmd_k1, k, k1);
}

/// Velocity perturbation (K-1). Blocks v_k, v_{k+1}.
inline void addVelocityProcess(ResidualCollector& out, CostMemo<MarkovProcess<3>>& memo, double dt,
                               double a, double q, const Vec3d& cmd_k, const Vec3d& cmd_k1,
                               const NodeHandles& k, const NodeHandles& k1) {
  addTwistProcess(out, "velocity", memo, &NodeHandles::v, dt, a, q, cmd_k, cmd_k1, k, k1);
}

/// Contact angles (K-8), time constant τ and noise density n_ξ. Blocks ξ_k, ξ_{k+1} (one angle
/// per wheel: `memos` has one entry per wheel). One row per wheel, under the loss when there is
/// one (SmootherOptions::contact_loss_scale), else Gaussian.
/// With common_noise < noise (rover.yaml's common-mode density), one more Gaussian row on the
/// wheels' mean (MarkovCommonMode): a single wheel may still jump under the loss, all of them
/// together may not.
inline void addContactProcess(ResidualCollector& out, std::vector<CostMemo<MarkovComponent>>& memos,
                              double dt, double time_constant, double noise, double common_noise,
                              ceres::LossFunction* loss, const NodeHandles& k,
                              const NodeHandles& k1) {
  const double a = -1.0 / time_constant;
  const int n = k.xi.size;
  for (int i = 0; i < n; ++i)
    out.addShared("contact", memos[static_cast<size_t>(i)],
                  MarkovComponent(i, n, dt, a, noise * noise), loss, k.xi, k1.xi);
  if (common_noise < noise && n > 1)
    out.add("contact_common",
            MarkovCommonMode::Create(
                MarkovCommonMode(n, dt, a, noise * noise, common_noise * common_noise)),
            nullptr, k.xi, k1.xi);
}

/// Stationary σ of the common slip's states (c_x, c_y in m/s, and c_ω in rad/s when declared).
inline Eigen::VectorXd commonSlipSigma(const rover::SlipNoise& noise) {
  Eigen::VectorXd s(noise.commonSlipStates());
  if (s.size() >= 2) s.head<2>() << noise.common_longitudinal_mps, noise.common_lateral_mps;
  if (s.size() == 3) s[2] = noise.common_yaw_rate_rad_s;
  return s;
}

/// The wheels' common slip c (rover::SlipNoise::common_*): zero mean, steady-state σ per
/// component and correlation time τ, so a = −1/τ and q = 2σ²/τ. Blocks c_k, c_{k+1} (N = 2, or 3
/// with c_ω). Under `loss` (heavy-tailed): c also changes by jumps (a slip burst), as the EKF's
/// jump test has it.
template <int N>
void addCommonSlipProcess(ResidualCollector& out, CostMemo<MarkovProcess<N>>& memo, double dt,
                          const rover::SlipNoise& noise, ceres::LossFunction* loss,
                          const NodeHandles& k, const NodeHandles& k1) {
  using VecN = Eigen::Matrix<double, N, 1>;
  const double tau = noise.common_time_constant_s;
  const VecN q = 2.0 / tau * VecN(commonSlipSigma(noise)).cwiseAbs2();
  out.addShared("common_slip", memo,
                MarkovProcess<N>(dt, VecN::Constant(-1.0 / tau), q, VecN::Zero(), VecN::Zero()),
                loss, k.c, k1.c);
}

/// Gyro bias random walk (K-9, the random-walk bias model), σ_b per √s. Blocks b_k, b_{k+1}.
inline void addBiasWalk(ResidualCollector& out, double dt, double walk, const NodeHandles& k,
                        const NodeHandles& k1) {
  out.add("bias_walk",
          new MarkovProcessResidual<3>(dt, Vec3d::Zero(), Vec3d::Constant(walk * walk),
                                       Vec3d::Zero(), Vec3d::Zero()),
          nullptr, k.bias, k1.bias);
}

/// Contact angles at a segment's first node k from K-8's stationary distribution,
/// ξ ~ N(0, n_ξ² τ / 2). Block ξ_k.
inline void addContactPrior(ResidualCollector& out, double time_constant, double noise,
                            double common_noise, const NodeHandles& k) {
  const double sigma = noise * std::sqrt(0.5 * time_constant);
  out.add("contact_prior", new StationaryPriorResidual(Eigen::VectorXd::Constant(k.xi.size, sigma)),
          nullptr, k.xi);
  if (common_noise < noise && k.xi.size > 1)
    out.add("contact_prior",
            MarkovCommonMode::Create(MarkovCommonMode::stationary(
                k.xi.size, -1.0 / time_constant, noise * noise, common_noise * common_noise)),
            nullptr, k.xi);
}

/// The common slip's stationary distribution at a segment's first node: c ~ N(0, diag σ²)
/// (commonSlipSigma).
inline void addCommonSlipPrior(ResidualCollector& out, const rover::SlipNoise& noise,
                               const NodeHandles& k) {
  out.add("common_slip_prior", new StationaryPriorResidual(commonSlipSigma(noise)), nullptr, k.c);
}

}  // namespace traverse::smoother
