// Joint rates from sampled joint angles by smoothing and differencing (K §3: "simple smoothing
// and differencing").
//
// Filter: at every sample k a quadratic a + b τ + c τ² (τ = t − t_k) is fitted by least squares
// to the samples k−h … k+h (the window is shifted, not shrunk, at the ends of the record), and
// the rate is b. For uniform sampling this is the Savitzky–Golay first-derivative filter of
// order 2; using the true timestamps keeps it correct when samples are irregular or missing.
// It is exact for angles quadratic in time, and its noise gain for white angle noise σ at
// period Δt is σ·sqrt(3/(h(h+1)(2h+1)))/Δt for interior samples.
#pragma once

#include <span>

#include <Eigen/Core>

namespace traverse::rover {

struct JointRateFilter {
  int half_window = 3;  ///< h: samples on each side (window 2h+1)
};

/// Rates (per second) of each column of `angles` (rows = samples), sampled at times `t`.
Eigen::MatrixXd jointRates(std::span<const double> t, const Eigen::MatrixXd& angles,
                           const JointRateFilter& filter = {});

/// The same local quadratic fit, returning the smoothed values (the fit at each sample) and the
/// rates together. For white noise σ the smoothed value's σ is about σ √(3(3h²+3h−1) /
/// ((2h−1)(2h+1)(2h+3))) at interior samples (≈ 1.5 σ/√(2h+1) for large h).
struct SmoothedJoints {
  Eigen::MatrixXd values, rates;
};
SmoothedJoints smoothJoints(std::span<const double> t, const Eigen::MatrixXd& angles,
                            const JointRateFilter& filter);

/// Variance factors of smoothJoints for white noise at interior samples: value, and rate × Δt².
double smoothedValueVarianceFactor(int half_window);
double smoothedRateVarianceFactor(int half_window);

}  // namespace traverse::rover
