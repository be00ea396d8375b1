#include "traverse/estimators/ekf.h"
#include "traverse/estimators/rts.h"

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <limits>

#include <ceres/jet.h>
#include <Eigen/LU>

#include "traverse/io/diagnostics.h"
#include "traverse/rover/joint_rates.h"
#include "traverse/rover/nominal_slip.h"
#include "traverse/sensors/accelerometer.h"
#include "traverse/sensors/gravity.h"
#include "traverse/sensors/gyro.h"
#include "traverse/sensors/sun_sensor.h"

namespace traverse::est {
namespace {

using io::interpolateRow;
using io::medianPeriod;

using I = EkfIndex;

/// Regularized lower incomplete gamma P(a, x): series below a + 1, Lentz continued fraction
/// above (Numerical Recipes §6.2).
double gammaP(double a, double x) {
  if (x <= 0) return 0.0;
  const double log_prefix = a * std::log(x) - x - std::lgamma(a);
  if (x < a + 1) {
    double term = 1.0 / a, sum = term;
    for (int n = 1; n < 500 && std::abs(term) > 1e-16 * std::abs(sum); ++n)
      term *= x / (a + n), sum += term;
    return sum * std::exp(log_prefix);
  }
  double b = x + 1 - a, c = 1e300, d = 1.0 / b, h = d;
  for (int i = 1; i < 500; ++i) {
    const double an = -i * (i - a);
    b += 2;
    d = an * d + b, d = std::abs(d) < 1e-300 ? 1e-300 : d, d = 1.0 / d;
    c = b + an / c, c = std::abs(c) < 1e-300 ? 1e-300 : c;
    h *= d * c;
    if (std::abs(d * c - 1.0) < 1e-16) break;
  }
  return 1.0 - std::exp(log_prefix) * h;
}

template <int N>
using Jet = ceres::Jet<double, N>;

/// Value and Jacobian of f at x (Jets): the Jacobians of the shared models.
template <int M, int N, typename F>
void jacobian(const F& f, const Eigen::Matrix<double, N, 1>& x, Eigen::Matrix<double, M, 1>* value,
              Eigen::Matrix<double, M, N>* J) {
  Eigen::Matrix<Jet<N>, N, 1> xj;
  for (int i = 0; i < N; ++i) xj[i] = Jet<N>(x[i], i);
  const Eigen::Matrix<Jet<N>, M, 1> y = f(xj);
  for (int r = 0; r < M; ++r) {
    (*value)[r] = y[r].a;
    J->row(r) = y[r].v.transpose();
  }
}

/// The at-rest gravity model h(q ⊞ δθ, b_a + δb_a) (roll and pitch of R(q)ᵀ (0, 0, g) + b_a) at
/// δ = 0, and its Jacobian in (δθ, δb_a) by Jets.
Eigen::Matrix<double, 2, 6> gravityJacobian(const Quatd& q, const Vec3d& b_a, double g, Vec2d* h) {
  Eigen::Matrix<double, 2, 6> J;
  Eigen::Matrix<double, 6, 1> z = Eigen::Matrix<double, 6, 1>::Zero();
  z.tail<3>() = b_a;
  jacobian<2, 6>(
      [&](const auto& d) {
        using T = typename std::decay_t<decltype(d)>::Scalar;
        return sensors::gravityRollPitchPredict<T>(
            so3::boxplus(Quat<T>(q.cast<T>()), Vec3<T>(d.template head<3>())),
            Vec3<T>(d.template tail<3>()), g);
      },
      z, h, &J);
  return J;
}

}  // namespace

double chiSquareQuantile(double probability, int dof) {
  // χ²_k CDF is P(k/2, x/2); bisection on it (monotone) to 1e-12 relative.
  double lo = 0.0, hi = 10.0 * dof + 100.0;
  for (int it = 0; it < 200 && hi - lo > 1e-12 * hi; ++it) {
    const double mid = 0.5 * (lo + hi);
    (gammaP(0.5 * dof, 0.5 * mid) < probability ? lo : hi) = mid;
  }
  return 0.5 * (lo + hi);
}

Ekf::Ekf(const io::RoverConfig& config, const rover::RoverGeometry& geometry,
         const EkfOptions& options, const InitialState& init, bool three_axis_gyro, bool has_cmd)
    : config_(config),
      geometry_(geometry),
      options_(options),
      three_axis_(three_axis_gyro),
      has_cmd_(has_cmd),
      nw_(geometry.numWheels()),
      nc_(config.slip_noise.commonSlipStates()),
      kc_(I::commonSlip(nw_)),
      na_(config.accel.hasBias() ? kAccelBiasStates : 0),
      ka_(I::accelBias(nw_, nc_)),
      nk_(config.estimatesIcr() ? kIcrStates : 0),
      kk_(I::icr(nw_, nc_, na_)),
      n_(ekfStates(nw_, nc_, na_, nk_)) {
  S_ =
      (three_axis_ ? sensors::GyroAxes::threeAxis() : sensors::GyroAxes::headingOnly()).selection();
  gate2_ = chiSquareQuantile(options.gate_probability, 2);
  gate4_ = chiSquareQuantile(options.gate_probability, 4);
  jump_gate_ = chiSquareQuantile(options.common_slip_jump_probability, 2);
  q_ = init.q_site_body;
  x_ = init.p_site;
  b_ = init.bias;
  w_p_.setZero(), v_p_.setZero(), xi_.setZero(nw_);
  // A log that starts in motion: the body velocity from the wheels (initialState). v_p is the
  // velocity itself with O-4 and without cmd.csv; with a command it is the perturbation, zero.
  if (options.velocity == EkfOptions::VelocityModel::kAccelDriven || !has_cmd) v_p_ = init.v_body;
  P_.setZero(n_, n_);
  // The initial values and σ are the first rest window's (InitialState), whose mean-sun heading
  // and rest bias the filter does not apply again (runEkf), so each reading counts once. Roll and
  // pitch are the exception: between gravity updates they drift by the unmeasured body rates, so
  // the window's gravity is applied at its middle as every rest's, and the filter starts from
  // the σ before it (0.1 rad) instead — the window's values, counted once.
  const bool gravity_again = init.roll_pitch_from_gravity && options.use_rest;
  Vec3d attitude_sigma = init.attitude_sigma;
  if (gravity_again) attitude_sigma.head<2>() = init.attitude_prior_sigma.head<2>();
  // The σ of roll, pitch and yaw (Z-Y-X) carried into the body-frame error δθ: small Euler
  // increments give δθ = E (δroll, δpitch, δyaw) (E the Euler-rate → body-rate matrix), so
  // the yaw's σ is about the site's vertical — the gravity direction, which no roll/pitch
  // measurement sees — not about the tilted body's z.
  P_.block<3, 3>(I::kTheta, I::kTheta) = so3::eulerRateToBodyRate(q_) *
                                         attitude_sigma.cwiseAbs2().asDiagonal() *
                                         so3::eulerRateToBodyRate(q_).transpose();
  P_.block<3, 3>(I::kRate, I::kRate)
      .diagonal()
      .setConstant(std::pow(options.initial_rate_sigma_rad_s, 2));
  P_.block<3, 3>(I::kPos, I::kPos)
      .diagonal()
      .setConstant(std::pow(options.initial_position_sigma_m, 2));
  P_.block<3, 3>(I::kVel, I::kVel)
      .diagonal()
      .setConstant(std::pow(options.initial_velocity_sigma_mps, 2));
  P_.block(I::kXi, I::kXi, nw_, nw_)
      .diagonal()
      .setConstant(std::pow(options.initial_contact_sigma_rad, 2));
  {  // the common mode of the wheels' angles starts no wider than its stationary σ
    const auto& pc = config.process;
    const double common_sigma =
        pc.commonContactAngleNoise() * std::sqrt(0.5 * pc.contact_angle_time_constant_s);
    const double v0 = std::pow(options.initial_contact_sigma_rad, 2);
    const double vc = std::min(v0, common_sigma * common_sigma);
    P_.block(I::kXi, I::kXi, nw_, nw_).array() += (vc - v0) / nw_;
  }
  P_.block<3, 3>(I::kBias, I::kBias) = init.bias_sigma.cwiseAbs2().asDiagonal();
  if (nc_ > 0) {  // the process' steady state
    const auto& sn = config.slip_noise;
    P_(kc_, kc_) = sn.common_longitudinal_mps * sn.common_longitudinal_mps;
    P_(kc_ + 1, kc_ + 1) = sn.common_lateral_mps * sn.common_lateral_mps;
    if (nc_ == 3) P_(kc_ + 2, kc_ + 2) = sn.common_yaw_rate_rad_s * sn.common_yaw_rate_rad_s;
  }
  if (nk_ > 0) P_(kk_, kk_) = std::pow(config.skid_steer->icrHalfTrackSigma(), 2);
  if (na_ > 0) {
    const Mat3d Sb = Mat3d::Identity() * std::pow(config.accel.bias_sigma_mps2, 2);
    P_.block<3, 3>(ka_, ka_) = Sb;
    if (init.roll_pitch_from_gravity && !gravity_again) {
      // Roll and pitch were read from gravity as if b_a were 0: h(q̂, 0) = h(q, b_a), so to
      // first order H_θ δθ = −H_b b_a (δθ = q ⊟ q̂), δθ = −M b_a with M = H_θ⁺ H_b (H_θ⁺ the
      // minimum-norm inverse: no yaw). The attitude gains M Σ_b Mᵀ, correlated with b_a.
      Vec2d h;
      const Eigen::Matrix<double, 2, 6> J =
          gravityJacobian(q_, Vec3d::Zero(), config.gravity_mps2, &h);
      const Eigen::Matrix<double, 2, 3> Ht = J.leftCols<3>(), Hb = J.rightCols<3>();
      const Mat3d M = Ht.transpose() * (Ht * Ht.transpose()).inverse() * Hb;
      P_.block<3, 3>(I::kTheta, I::kTheta) += M * Sb * M.transpose();
      P_.block<3, 3>(I::kTheta, ka_) = -M * Sb;
      P_.block<3, 3>(ka_, I::kTheta) = -Sb * M.transpose();
    }
  }
}

// O-1 (hybrid): measured axes from the bias-corrected gyro, the others from ω_c; ω_p on all.
// K-2 with K-12 as a measurement: ω = ω_c + ω_p.
template <typename T>
Vec3<T> Ekf::omega(const Vec3<T>& w_p, const Vec3<T>& b, const EkfInputs& in) const {
  if (options_.attitude == EkfOptions::AttitudeModel::kGyroMeasurement)
    return in.w_cmd.cast<T>() + w_p;
  const Mat3<T> S = gyroAxes(in).cast<T>();
  return S * (in.gyro.cast<T>() - b) + (Mat3<T>::Identity() - S) * in.w_cmd.cast<T>() + w_p;
}

Ekf::Damping Ekf::damping(const EkfInputs& in) const {
  // A perturbation decays towards the prescribed motion; without a prescription (no cmd.csv)
  // the velocity, and the yaw rate in K-12 mode, are random walks (K §4.2).
  const auto& pc = config_.process;
  const bool hybrid = options_.attitude == EkfOptions::AttitudeModel::kGyroDriven;
  Damping d;
  d.accel_driven = options_.velocity == EkfOptions::VelocityModel::kAccelDriven && in.has_accel;
  d.a_v = has_cmd_ && !d.accel_driven ? -1.0 / pc.velocity_time_constant_s : 0.0;
  d.a_w = Vec3d::Constant(-1.0 / pc.rate_time_constant_s);
  if (!hybrid && !has_cmd_) d.a_w.z() = 0.0;
  // Across a gyro gap the rate of a gyro axis has no prescription either without cmd.csv.
  if (hybrid && in.gyro_gap && !has_cmd_) d.a_w = d.a_w.cwiseProduct(Vec3d::Ones() - S_.diagonal());
  d.a_xi = -1.0 / pc.contact_angle_time_constant_s;
  d.a_c = -1.0 / config_.slip_noise.common_time_constant_s;
  return d;
}

EkfMatrix Ekf::processJacobian(const EkfInputs& in, Vec3d* v_dot) const {
  Linearisation lin;
  linearise(in, &lin);
  if (v_dot) *v_dot = lin.v_dot;
  return lin.F;
}

void Ekf::linearise(const EkfInputs& in, Linearisation* out) const {
  out->d = damping(in);
  const Damping& d = out->d;
  const bool hybrid = options_.attitude == EkfOptions::AttitudeModel::kGyroDriven;
  const Vec3d w = out->w = omega<double>(w_p_, b_, in);
  const Vec3d v = out->v = d.accel_driven ? v_p_ : velocity<double>(v_p_, in);
  const Mat3d R = q_.toRotationMatrix();
  EkfMatrix& F = out->F;
  F.setZero(n_, n_);
  F.block<3, 3>(I::kTheta, I::kTheta) = -so3::skew(w);
  F.block<3, 3>(I::kTheta, I::kRate).setIdentity();
  if (hybrid) F.block<3, 3>(I::kTheta, I::kBias) = -gyroAxes(in);
  F.block<3, 3>(I::kRate, I::kRate) = d.a_w.asDiagonal();
  F.block<3, 3>(I::kPos, I::kTheta) = -R * so3::skew(v);
  F.block<3, 3>(I::kPos, I::kVel) = R;
  F.block(I::kXi, I::kXi, nw_, nw_).diagonal().setConstant(d.a_xi);
  if (nc_ > 0) F.block(kc_, kc_, nc_, nc_).diagonal().setConstant(d.a_c);
  out->v_dot.setZero();
  if (d.accel_driven &&
      !in.accel_gap) {  // O-4, linearised with Jets through the shared accelerometer model
    Eigen::Matrix<double, 12, 1> s;
    s << Vec3d::Zero(), w_p_, v_p_, b_;
    Eigen::Matrix<double, 3, 12> J;
    Vec3d rate;
    jacobian<3, 12>(
        [&](const auto& z) {
          using T = typename std::decay_t<decltype(z)>::Scalar;
          const Quat<T> q = so3::boxplus(Quat<T>(q_.cast<T>()), Vec3<T>(z.template head<3>()));
          const Vec3<T> wt = omega<T>(z.template segment<3>(3), z.template tail<3>(), in);
          return sensors::velocityRateFromAccel<T>(
              Vec3<T>((in.accel - ba_).cast<T>()), q, Vec3<T>(z.template segment<3>(6)), wt,
              Vec3<T>::Zero(), config_.accel.lever_arm_m, config_.gravity_mps2);
        },
        s, &rate, &J);
    out->v_dot = rate;
    F.block<3, 3>(I::kVel, I::kTheta) = J.block<3, 3>(0, 0);
    F.block<3, 3>(I::kVel, I::kRate) = J.block<3, 3>(0, 3);
    F.block<3, 3>(I::kVel, I::kVel) = J.block<3, 3>(0, 6);
    F.block<3, 3>(I::kVel, I::kBias) = J.block<3, 3>(0, 9);
    // v̇ is a_m − b_a − (…): linear in the reading, so ∂v̇/∂b_a = −I exactly.
    if (na_ > 0) F.block<3, 3>(I::kVel, ka_) = -Mat3d::Identity();
  } else if (!d.accel_driven) {
    F.block<3, 3>(I::kVel, I::kVel).diagonal().setConstant(d.a_v);
  }  // (O-4 across an accelerometer gap: v̇ = 0, a random walk)
}

void Ekf::propagate(double dt, const EkfInputs& in) {
  last_w_cmd_ = in.w_cmd;
  if (dt <= 0) return;
  ++stats_.propagations;
  Linearisation lin;  // the dampings, ω, v, v̇ and F at the state before the step, once
  linearise(in, &lin);
  const Damping& d = lin.d;
  const bool accel_driven = d.accel_driven;
  const bool hybrid = options_.attitude == EkfOptions::AttitudeModel::kGyroDriven;
  const Vec3d &w = lin.w, &v = lin.v, &v_dot = lin.v_dot;
  const auto& pc = config_.process;

  // Continuous noise densities.
  EkfVector qc = EkfVector::Zero(n_);
  const double n_w = pc.rate_noise_rad_s2_per_sqrt_hz;
  const Mat3d S = gyroAxes(in);
  for (int a = 0; a < 3; ++a) {
    const bool measured = hybrid && S(a, a) > 0;
    const double n_measured = config_.gyro.rate_perturbation_rad_s2_per_sqrt_hz.value_or(
        n_w * options_.rate_noise_scale_measured_axes);
    qc[I::kRate + a] = std::pow(measured ? n_measured : n_w, 2);
    // A gyro-driven axis inherits the gyro's white noise (density σ² Δt at its sample period).
    if (measured)
      qc[I::kTheta + a] = config_.gyro.noise_rad_s * config_.gyro.noise_rad_s * gyro_period_;
  }
  qc.segment<3>(I::kVel).setConstant(accel_driven && !in.accel_gap
                                         ? std::pow(config_.accel.noise_mps2, 2) * accel_period_
                                         : std::pow(pc.velocity_noise_mps2_per_sqrt_hz, 2));
  qc.segment(I::kXi, nw_).setConstant(std::pow(pc.contact_angle_noise_rad_per_sqrt_s, 2));
  qc.segment<3>(I::kBias).setConstant(std::pow(config_.gyro.bias_random_walk_rad_s_per_sqrt_s, 2));
  if (nc_ > 0) {  // Gauss–Markov: density 2σ²/τ keeps the steady-state σ
    const auto& sn = config_.slip_noise;
    qc[kc_] = -2.0 * d.a_c * sn.common_longitudinal_mps * sn.common_longitudinal_mps;
    qc[kc_ + 1] = -2.0 * d.a_c * sn.common_lateral_mps * sn.common_lateral_mps;
    if (nc_ == 3) qc[kc_ + 2] = -2.0 * d.a_c * sn.common_yaw_rate_rad_s * sn.common_yaw_rate_rad_s;
  }
  if (na_ > 0)
    qc.segment<3>(ka_).setConstant(std::pow(config_.accel.bias_random_walk_mps2_per_sqrt_s, 2));
  if (nk_ > 0) qc[kk_] = std::pow(config_.skid_steer->icr_half_track_random_walk_m_per_sqrt_s, 2);

  if (recording_) {
    if (updating_) {  // the updates since the last propagation made a posterior
      chain_.points.push_back({state(), P_, {}, {}, {}});
      phi_acc_ = Eigen::MatrixXd::Identity(n_, n_);
      updating_ = false;
    }
    const Eigen::MatrixXd Fdt = lin.F * dt;
    const Eigen::MatrixXd phi = Eigen::MatrixXd::Identity(n_, n_) + Fdt + 0.5 * Fdt * Fdt;
    phi_acc_ = phi * phi_acc_;
  }
  detail::propagateCovarianceInPlace(lin.F, dt, &P_);
  P_.diagonal() += qc * dt;  // white process noise over dt (first order)
  // The contact angles' common mode has its own density n_c (rover.yaml): Q_ξ = n_ξ² I +
  // (n_c² − n_ξ²)/N 1 1ᵀ, eigenvalues n_ξ² (differences between wheels) and n_c² (their mean).
  if (pc.common_contact_angle_noise_rad_per_sqrt_s)
    P_.block(I::kXi, I::kXi, nw_, nw_).array() +=
        (std::pow(*pc.common_contact_angle_noise_rad_per_sqrt_s, 2) -
         std::pow(pc.contact_angle_noise_rad_per_sqrt_s, 2)) /
        nw_ * dt;
  P_ = 0.5 * (P_ + P_.transpose());

  // Nominal state (midpoint rule).
  const Quatd q_mid = q_ * so3::expQuat(Vec3d(0.5 * dt * w));
  const Vec3d v_mid = accel_driven ? Vec3d(v + 0.5 * dt * v_dot) : v;
  x_ += q_mid * v_mid * dt;
  q_ = (q_ * so3::expQuat(Vec3d(w * dt))).normalized();
  w_p_ = (d.a_w * dt).array().exp().matrix().cwiseProduct(w_p_);
  v_p_ = accel_driven ? Vec3d(v_p_ + v_dot * dt) : Vec3d(std::exp(d.a_v * dt) * v_p_);
  xi_ *= std::exp(d.a_xi * dt);
  c_ *= std::exp(d.a_c * dt);
}

namespace detail {

EkfMatrix propagateCovariance(const EkfMatrix& F, double dt, const EkfMatrix& P) {
  EkfMatrix out = P;
  propagateCovarianceInPlace(F, dt, &out);
  return out;
}

namespace {

/// Fixed-size storage at N states, or Eigen::Dynamic sizes within the EKF's fixed capacity
/// (no heap).
constexpr int capacity(int n) {
  return n == Eigen::Dynamic ? kMaxEkfStates : n;
}
template <int N>
using SquareN = Eigen::Matrix<double, N, N, 0, capacity(N), capacity(N)>;
template <int M, int N>
using RowsN =
    Eigen::Matrix<double, M, N, M == 1 ? Eigen::RowMajor : Eigen::ColMajor, M, capacity(N)>;
template <int N, int M>
using ColsN = Eigen::Matrix<double, N, M, 0, capacity(N), M>;

/// Φ P Φᵀ on views of F and P at compile-time size N (the 4- and 6-wheel rovers' 19 and 21) or
/// Eigen::Dynamic: the same operations in the same order, so the same numbers, with the loop
/// bounds known to the compiler where they can be.
template <int N>
void propagateKernel(const double* F_data, double dt, double* P_data, int n) {
  using Mat = SquareN<N>;
  const Eigen::Map<const Mat> F(F_data, n, n);
  Eigen::Map<Mat> P(P_data, n, n);
  // Φ = I + A, A = F dt + ½ (F dt)²; F has ~50 nonzeros of 441, so A P and A (A P)ᵀ are
  // computed over A's nonzero entries: Φ P Φᵀ = P + A P + (A P)ᵀ + A (A P)ᵀ.
  struct Entry {
    int i, j;
    double v;
  };
  std::array<Entry, kMaxEkfStates * kMaxEkfStates> nz;
  int n_nz = 0;
  for (int j = 0; j < n; ++j) {
    for (int i = 0; i < n; ++i) {
      if (F(i, j) != 0.0) nz[n_nz++] = {i, j, F(i, j) * dt};
    }
  }
  // The nonzeros of each row, in the order above (a counting sort), so that the square visits
  // only the pairs (a, b) with row(b) = column(a), in the same order as a scan over all b.
  std::array<int, kMaxEkfStates + 1> row_start{};
  for (int a = 0; a < n_nz; ++a) ++row_start[nz[a].i + 1];
  for (int i = 0; i < n; ++i) row_start[i + 1] += row_start[i];
  std::array<int, kMaxEkfStates * kMaxEkfStates> by_row;
  std::array<int, kMaxEkfStates> fill;
  std::copy_n(row_start.begin(), n, fill.begin());
  for (int a = 0; a < n_nz; ++a) by_row[fill[nz[a].i]++] = a;
  Mat A = Mat::Zero(n, n);  // F dt + ½ (F dt)², the square over the nonzeros
  for (int a = 0; a < n_nz; ++a) {
    A(nz[a].i, nz[a].j) += nz[a].v;
    for (int r = row_start[nz[a].j]; r < row_start[nz[a].j + 1]; ++r) {
      const Entry& b = nz[by_row[r]];
      A(nz[a].i, b.j) += 0.5 * nz[a].v * b.v;
    }
  }
  n_nz = 0;
  for (int j = 0; j < n; ++j) {
    for (int i = 0; i < n; ++i) {
      if (A(i, j) != 0.0) nz[n_nz++] = {i, j, A(i, j)};
    }
  }
  // Column operations only (Eigen is column-major): B = P Aᵀ, D = Bᵀ = A P, E = D Aᵀ = A P Aᵀ.
  Mat B = Mat::Zero(n, n), E = Mat::Zero(n, n);
  for (int a = 0; a < n_nz; ++a) B.col(nz[a].i).noalias() += nz[a].v * P.col(nz[a].j);
  const Mat D = B.transpose();
  for (int a = 0; a < n_nz; ++a) E.col(nz[a].i).noalias() += nz[a].v * D.col(nz[a].j);
  P += D + B + E;
}

/// The expanded Joseph form on a view of P at compile-time size N (as propagateKernel). (Each
/// entry as three M-dot products; folding two into Kᵢ·(S Kⱼ − HPⱼ) gave NaN on the noise-free
/// log, where S is tiny and K huge: EstEkf.NoiseFreeFlatTraverseIsReproduced.)
template <int N, int M>
void josephKernel(double* P_data, int n, const EkfRows<M>& Kt_in, const EkfRows<M>& HP_in,
                  const Eigen::Matrix<double, M, M>& S) {
  using Mat = SquareN<N>;
  using Rows = RowsN<M, N>;
  Eigen::Map<Mat> P(P_data, n, n);
  const Rows Kt = Kt_in, HP = HP_in;
  const Rows SKt = S * Kt;
  for (int j = 0; j < n; ++j) {
    for (int i = j; i < n; ++i)
      P(i, j) += Kt.col(i).dot(SKt.col(j)) - Kt.col(i).dot(HP.col(j)) - HP.col(i).dot(Kt.col(j));
  }
  P.template triangularView<Eigen::StrictlyUpper>() = P.transpose();
}

/// P Hᵀ and S = H P Hᵀ + R over H's nonzero columns, on a view of P at compile-time size N.
template <int N, int M>
void innovationKernel(const double* P_data, int n, const EkfRows<M>& H_in,
                      const Eigen::Matrix<double, M, M>& R, EkfCols<M>* PHt_out,
                      Eigen::Matrix<double, M, M>* S) {
  using Mat = SquareN<N>;
  const Eigen::Map<const Mat> P(P_data, n, n);
  const RowsN<M, N> H = H_in;
  int cols[kMaxEkfStates];
  int k = 0;
  for (int c = 0; c < n; ++c) {
    if (!H.col(c).isZero(0.0)) cols[k++] = c;
  }
  ColsN<N, M> PHt = ColsN<N, M>::Zero(n, M);
  for (int j = 0; j < k; ++j) PHt.noalias() += P.col(cols[j]) * H.col(cols[j]).transpose();
  *S = R;
  for (int j = 0; j < k; ++j) S->noalias() += H.col(cols[j]) * PHt.row(cols[j]);
  *PHt_out = PHt;
}

/// Calls f.template operator()<N>() with N the state count n at compile time for the rovers
/// traverse ships (4 and 6 wheels, with the common slip (2 or 3 states), a 4-wheel rover with an
/// accelerometer bias), Eigen::Dynamic otherwise: the same operations in the same order either way.
template <typename F>
void withStateCount(int n, F&& f) {
  switch (n) {
    case ekfStates(4):
      f.template operator()<ekfStates(4)>();
      break;
    case ekfStates(6):
      f.template operator()<ekfStates(6)>();
      break;
    case ekfStates(6, 2):  // the common slip c_x, c_y
      f.template operator()<ekfStates(6, 2)>();
      break;
    case ekfStates(6, 3):  // with its yaw rate c_ω
      f.template operator()<ekfStates(6, 3)>();
      break;
    case ekfStates(4, 0, kAccelBiasStates):  // a four-wheel rover with a real IMU
      f.template operator()<ekfStates(4, 0, kAccelBiasStates)>();
      break;
    case ekfStates(4, 0, 0, kIcrStates):  // a skid-steered four-wheel rover (Pathfinder)
      f.template operator()<ekfStates(4, 0, 0, kIcrStates)>();
      break;
    // (a skid-steered four-wheel rover with a real IMU, ekfStates(4, 0, 3, 1), is 23 as well)
    default:
      f.template operator()<Eigen::Dynamic>();
      break;
  }
}

}  // namespace

void propagateCovarianceInPlace(const EkfMatrix& F, double dt, EkfMatrix* P) {
  const int n = static_cast<int>(F.rows());
  withStateCount(n, [&]<int N>() { propagateKernel<N>(F.data(), dt, P->data(), n); });
}

template <int M>
void innovation(const EkfMatrix& P, const EkfRows<M>& H, const Eigen::Matrix<double, M, M>& R,
                EkfCols<M>* PHt, Eigen::Matrix<double, M, M>* S) {
  const auto n = static_cast<int>(P.rows());
  withStateCount(n, [&]<int N>() { innovationKernel<N, M>(P.data(), n, H, R, PHt, S); });
}

template <int M>
void josephUpdate(EkfMatrix* P, const EkfCols<M>& K, const EkfCols<M>& PHt,
                  const Eigen::Matrix<double, M, M>& S) {
  // (I − KH) P (I − KH)ᵀ + K R Kᵀ = P − K (HP) − (HP)ᵀ Kᵀ + K S Kᵀ with HP = (P Hᵀ)ᵀ: rank-M
  // products instead of two 21×21×21 ones, on the lower triangle with contiguous M-vectors.
  const EkfRows<M> Kt = K.transpose(), HP = PHt.transpose();
  const auto n = static_cast<int>(P->rows());
  withStateCount(n, [&]<int N>() { josephKernel<N, M>(P->data(), n, Kt, HP, S); });
}

Mat3d resetJacobian(const Vec3d& dtheta) {
  return Mat3d::Identity() - 0.5 * so3::skew(dtheta);
}

}  // namespace detail

template <int M>
bool Ekf::update(const Eigen::Matrix<double, M, 1>& r, const EkfRows<M>& H,
                 const Eigen::Matrix<double, M, M>& R, double gate) {
  EkfCols<M> PHt;
  Eigen::Matrix<double, M, M> S;
  detail::innovation<M>(P_, H, R, &PHt, &S);
  // S is M×M with M ≤ 4: LLT checks it is positive definite, Eigen's closed-form inverse gives
  // the gain (a determinant threshold would reject the small, well-conditioned S of slip rows).
  if (Eigen::LLT<Eigen::Matrix<double, M, M>>(S).info() != Eigen::Success) return false;
  const Eigen::Matrix<double, M, M> S_inv = S.inverse();
  if (gate > 0 && r.dot(S_inv * r) > gate) return false;
  const EkfCols<M> K = PHt * S_inv;
  if (recording_ && !updating_) closeTransition();
  detail::josephUpdate<M>(&P_, K, PHt, S);
  absorb(K * r);
  return true;
}

void Ekf::absorb(const EkfVector& dx) {
  const Vec3d dtheta = dx.segment<3>(I::kTheta);
  q_ = so3::boxplus(q_, dtheta).normalized();  // K-21
  w_p_ += dx.segment<3>(I::kRate);
  x_ += dx.segment<3>(I::kPos);
  v_p_ += dx.segment<3>(I::kVel);
  xi_ += dx.segment(I::kXi, nw_);
  b_ += dx.segment<3>(I::kBias);
  if (nc_ > 0) c_.head(nc_) += dx.segment(kc_, nc_);
  if (na_ > 0) ba_ += dx.segment<3>(ka_);
  if (nk_ > 0) icr_ += dx[kk_];
  // Reset Jacobian of the attitude error: δθ⁺ ≈ (I − ½[dθ]×) δθ.
  const Mat3d G = detail::resetJacobian(dtheta);
  P_.middleRows<3>(I::kTheta) = G * P_.middleRows<3>(I::kTheta);
  P_.middleCols<3>(I::kTheta) = P_.middleCols<3>(I::kTheta) * G.transpose();
}

Vec4d slipUpdateResidual(const rover::RoverGeometry& geometry, const JointSample& js, int i,
                         const Twistd* commanded, const Eigen::Matrix<double, 7, 1>& s,
                         Eigen::Matrix<double, 4, 7>* H, Eigen::Matrix<double, 4, 7>* dt_ds,
                         double icr_delta, Vec4d* H_icr) {
  const double radius = geometry.wheels[i].radius;
  const Twistd& jt = js.joint_twist[i];
  Eigen::Matrix<double, 4, 7> J;
  const Vec4d t = rover::slipConstraintWithJacobian(js.T_body_wheel[i], radius, jt, s.head<3>(),
                                                    s.segment<3>(3), s[6], &J);
  const Twistd nominal_twist =
      commanded ? *commanded : rover::nominalBodyTwist(geometry, s[0], s[5]);
  const double side = geometry.wheels[i].icr_side;
  const double icr = geometry.wheels[i].icr_offset_y + side * icr_delta;
  const Vec4d r = rover::nominalSlip(js.T_body_wheel[i], radius, nominal_twist, jt, icr) - t;
  *H = J;
  if (dt_ds) *dt_ds = J;
  // The nominal longitudinal slip is ω_z,nominal · (icr_offset_y + side δ).
  if (H_icr) *H_icr = Vec4d(-side * nominal_twist[5], 0.0, 0.0, 0.0);
  if (!commanded) {
    // The nominal slip follows the estimate: r = nominal(v_x, ω_z) − t(s), so H = ∂t/∂s −
    // ∂nominal/∂s (rover::nominalSlipJacobian, exact: the nominal is affine in (v_x, ω_z)).
    const Eigen::Matrix<double, 4, 2> N =
        rover::nominalSlipJacobian(geometry, js.T_body_wheel[i], radius, jt, icr);
    H->col(0) -= N.col(0);
    H->col(5) -= N.col(1);
  }
  return r;
}

void Ekf::updateSlip(const JointSample& js, const EkfInputs& in) {
  if (!js.measured) return;  // inside a gap of joints.csv: nothing to update with
  const bool accel_driven =
      options_.velocity == EkfOptions::VelocityModel::kAccelDriven && in.has_accel;
  const auto v_now = [&] { return accel_driven ? v_p_ : velocity<double>(v_p_, in); };
  // Nominal slip (K §2.3.4) from the commanded motion, or from the estimate without cmd.csv
  // (then it is part of the measurement function and is differentiated with it).
  const Twistd cmd_twist = rover::nominalBodyTwist(geometry_, in.v_cmd.x(), in.w_cmd.z());
  const bool hybrid = options_.attitude == EkfOptions::AttitudeModel::kGyroDriven;
  if (nc_ > 0 && options_.common_slip_jumps)
    commonSlipJump(js, in, has_cmd_ ? &cmd_twist : nullptr);
  // Gyro-driven, every wheel's rows take ω from the same gyro reading, and its white noise ε
  // enters all of them through ∂t/∂ω: a noise common to the wheels, not in any wheel's R. Left
  // out, the rows explain each sample's ε with the states (on an eight-wheel rover with a 0.8 m
  // track the EKF sank 12 mm per metre, docs/results.md). It is carried exactly: one nuisance
  // state per measured axis, appended to P with the reading's variance for this sample's rows,
  // then marginalised (its rows and columns dropped; ε is white, so nothing of it is kept).
  const Mat3d S = gyroAxes(in);
  std::array<int, kGyroNoiseStates> noise_axes{};
  int ne = 0;
  if (hybrid) {
    for (int a = 0; a < 3; ++a) {
      if (S.col(a).squaredNorm() > 0) noise_axes[ne++] = a;
    }
  }
  const int n_rows = n_ + ne;
  if (ne > 0) {
    if (recording_ && !updating_) closeTransition();  // the chain records the n-state prior
    P_.conservativeResize(n_rows, n_rows);
    P_.rightCols(ne).setZero();
    P_.bottomRows(ne).setZero();
    const double var =
        config_.gyro.noise_rad_s * config_.gyro.noise_rad_s * in.gyro_noise_variance_factor;
    for (int k = 0; k < ne; ++k) P_(n_ + k, n_ + k) = var;
  }
  for (int i = 0; i < nw_; ++i) {
    if (!js.wheelUsed(i)) {  // a wheel outage: no slip rows from this wheel
      ++stats_.slip_not_used;
      continue;
    }
    // Re-linearise at the state the previous wheel's update left (sequential processing).
    // The wheels roll as if the body moved at v + (c_x, c_y, 0) and turned at ω + (0, 0, c_ω)
    // (c: their common slip, zero without it).
    Eigen::Matrix<double, 7, 1> s;
    s << v_now() + Vec3d(c_.x(), c_.y(), 0.0), omega<double>(w_p_, b_, in) + Vec3d(0, 0, c_.z()),
        xi_[i];
    Eigen::Matrix<double, 4, 7> J;
    Eigen::Matrix<double, 4, 7> Jt;  // ∂t/∂s: the noise is the constraint's (nominal: exact)
    Vec4d H_icr;
    const Vec4d r = slipUpdateResidual(geometry_, js, i, has_cmd_ ? &cmd_twist : nullptr, s, &J,
                                       &Jt, icr_, &H_icr);
    const Eigen::Matrix4d Ri = rover::slipCovariance(config_.slip_noise, js, i, s.head<3>(),
                                                     s.segment<3>(3), Jt.leftCols<6>());
    EkfRows<4> H = EkfRows<4>::Zero(4, n_rows);
    H.block<4, 3>(0, I::kVel) = J.leftCols<3>();
    H.block<4, 3>(0, I::kRate) = J.middleCols<3>(3);
    if (hybrid) H.block<4, 3>(0, I::kBias) = -J.middleCols<3>(3) * S;
    for (int k = 0; k < ne; ++k) H.col(n_ + k) = J.middleCols<3>(3) * S.col(noise_axes[k]);
    H.col(I::kXi + i) = J.col(6);
    if (nc_ > 0) H.block<4, 2>(0, kc_) = J.leftCols<2>();
    if (nc_ == 3) H.col(kc_ + 2) = J.col(5);
    if (nk_ > 0) H.col(kk_) = H_icr;
    ++stats_.slip_updates;
    if (!update<4>(r, H, Ri, options_.gating ? gate4_ : 0.0)) ++stats_.slip_rejected;
  }
  if (ne > 0) P_.conservativeResize(n_, n_);
}

void Ekf::commonSlipJump(const JointSample& js, const EkfInputs& in, const Twistd* commanded) {
  const bool accel_driven =
      options_.velocity == EkfOptions::VelocityModel::kAccelDriven && in.has_accel;
  Eigen::Matrix<double, 7, 1> s;
  s << (accel_driven ? v_p_ : velocity<double>(v_p_, in)) + Vec3d(c_.x(), c_.y(), 0.0),
      omega<double>(w_p_, b_, in) + Vec3d(0, 0, c_.z()), 0.0;
  // Each wheel's contact-point mismatch (rows 0-2 of r = nominal − t) in the body frame,
  // R_l r: under no jump, −(δv + δc) plus the wheel's noise. Their mean over the wheels and its
  // covariance (v + c from P, the rows' noise divided by the wheel count).
  Vec2d u = Vec2d::Zero();
  Eigen::Matrix2d R = Eigen::Matrix2d::Zero();
  int n = 0;
  for (int i = 0; i < nw_; ++i) {
    if (!js.wheelUsed(i)) continue;
    s[6] = xi_[i];
    Eigen::Matrix<double, 4, 7> H, Jt;
    const Vec4d r = slipUpdateResidual(geometry_, js, i, commanded, s, &H, &Jt, icr_);
    const Eigen::Matrix4d Ri = rover::slipCovariance(config_.slip_noise, js, i, s.head<3>(),
                                                     s.segment<3>(3), Jt.leftCols<6>());
    const Mat3d Rl = Jt.block<3, 3>(0, 0).transpose();  // ∂t/∂v = R_lᵀ
    u += (Rl * r.head<3>()).head<2>();
    R += (Rl * Ri.topLeftCorner<3, 3>() * Rl.transpose()).topLeftCorner<2, 2>();
    ++n;
  }
  if (n == 0) return;
  u /= n;
  R /= static_cast<double>(n) * n;
  const Eigen::Matrix2d P_vc = P_.block<2, 2>(I::kVel, I::kVel) + P_.block<2, 2>(kc_, kc_) +
                               P_.block<2, 2>(I::kVel, kc_) + P_.block<2, 2>(kc_, I::kVel);
  const Eigen::Matrix2d S = P_vc + R;
  if (u.dot(S.ldlt().solve(u)) <= jump_gate_) return;
  P_.block<2, 2>(kc_, kc_) += u * u.transpose();
  ++stats_.common_slip_jumps;
}

void Ekf::updateSun(const Vec2d& s_m, const Vec3d& sun_site) {
  const sensors::SunSensorGeometry geo{config_.sun_sensor.R_body_sensor,
                                       0.5 * config_.sun_sensor.field_of_view_rad};
  if (sensors::sunOffBoresight(q_, geo, sun_site) > geo.half_fov_rad + 0.1)
    return;  // predicted out of view
  Vec2d h;
  Eigen::Matrix<double, 2, 3> J;
  jacobian<2, 3>(
      [&](const auto& d) {
        using T = typename std::decay_t<decltype(d)>::Scalar;
        return sensors::sunSensorPredict<T>(so3::boxplus(Quat<T>(q_.cast<T>()), Vec3<T>(d)), geo,
                                            sun_site);
      },
      Vec3d::Zero().eval(), &h, &J);
  EkfRows<2> H = EkfRows<2>::Zero(2, n_);
  H.block<2, 3>(0, I::kTheta) = J;
  const double n2 = config_.sun_sensor.noise * config_.sun_sensor.noise;
  ++stats_.sun_updates;
  if (!update<2>(Vec2d(s_m - h), H, Eigen::Matrix2d::Identity() * n2,
                 options_.gating ? gate2_ : 0.0)) {
    ++stats_.sun_rejected;
  }
}

void Ekf::gyroAxisUpdates(const Vec3d& w_m, bool at_rest, long* count) {
  // K-12, one scalar update per measured axis: ω_m = ω + b with ω = ω_c + ω_p in motion and
  // ω = 0 at rest (then each sample is bias plus noise: Nickels' per-axis drift filter).
  const double n2 = config_.gyro.noise_rad_s * config_.gyro.noise_rad_s;
  for (int a = 0; a < 3; ++a) {
    if (S_(a, a) == 0) continue;
    EkfRows<1> H = EkfRows<1>::Zero(1, n_);
    H(0, I::kBias + a) = 1.0;
    if (!at_rest) H(0, I::kRate + a) = 1.0;
    const double predicted = b_[a] + (at_rest ? 0.0 : w_p_[a] + last_w_cmd_[a]);
    update<1>(Eigen::Matrix<double, 1, 1>(w_m[a] - predicted), H, Eigen::Matrix<double, 1, 1>(n2),
              0.0);
    ++*count;
  }
}

void Ekf::updateGyro(const Vec3d& w_m) {
  gyroAxisUpdates(w_m, false, &stats_.gyro_updates);
}

void Ekf::updateZeroVelocity(const EkfInputs& in) {
  const bool accel_driven =
      options_.velocity == EkfOptions::VelocityModel::kAccelDriven && in.has_accel;
  const Vec3d v = accel_driven ? v_p_ : velocity<double>(v_p_, in);
  EkfRows<3> H = EkfRows<3>::Zero(3, n_);
  H.block<3, 3>(0, I::kVel).setIdentity();
  const double s2 = options_.zero_velocity_sigma_mps * options_.zero_velocity_sigma_mps;
  update<3>(Vec3d(-v), H, Mat3d::Identity() * s2, 0.0);
  ++stats_.zero_velocity_updates;
}

void Ekf::updateZeroRate(const EkfInputs& in) {
  // At rest the body does not turn: the rate not explained by the gyro (O-1) or the command
  // (K-2), ω_p, is zero. (With the gyro-driven model, ω = S(ω_m − b) + ω_p; putting the whole
  // ω = 0 would let ω_p soak up the bias — updateRestBias gives the bias its own measurement.)
  const bool hybrid = options_.attitude == EkfOptions::AttitudeModel::kGyroDriven;
  EkfRows<3> H = EkfRows<3>::Zero(3, n_);
  H.block<3, 3>(0, I::kRate).setIdentity();
  const Vec3d predicted = hybrid ? w_p_ : Vec3d(in.w_cmd + w_p_);
  const double s2 = options_.zero_rate_sigma_rad_s * options_.zero_rate_sigma_rad_s;
  update<3>(Vec3d(-predicted), H, Mat3d::Identity() * s2, 0.0);
  ++stats_.zero_rate_updates;
}

void Ekf::updateRestBias(const EkfInputs& in) {
  gyroAxisUpdates(in.gyro, true, &stats_.bias_updates);
}

void Ekf::updateGravity(const sensors::RollPitchMeasurement& m) {
  // The rest window's mean specific force R(q)ᵀ (0, 0, g) + b_a, seen as roll and pitch
  // (sensors::gravityRollPitchPredict with the bias): differentiated in δθ and δb_a.
  Vec2d h;
  const Eigen::Matrix<double, 2, 6> J = gravityJacobian(q_, ba_, config_.gravity_mps2, &h);
  EkfRows<2> H = EkfRows<2>::Zero(2, n_);
  H.block<2, 3>(0, I::kTheta) = J.leftCols<3>();
  if (na_ > 0) H.block<2, 3>(0, ka_) = J.rightCols<3>();
  const Vec2d r(so3::wrapAngle(m.roll_pitch.x() - h.x()), so3::wrapAngle(m.roll_pitch.y() - h.y()));
  update<2>(r, H, m.covariance, 0.0);
  ++stats_.gravity_updates;
}

TrajectoryNode Ekf::node(double t, const EkfInputs& in) const {
  return nodeOf(state(), P_, t, in);
}

TrajectoryNode Ekf::nodeOf(const EkfState& s, const EkfMatrix& P, double t,
                           const EkfInputs& in) const {
  const bool accel_driven =
      options_.velocity == EkfOptions::VelocityModel::kAccelDriven && in.has_accel;
  TrajectoryNode n;
  n.t = t;
  n.p_site = s.p_site;
  n.q_site_body = s.q_site_body;
  n.v_body = accel_driven ? s.v_p : velocity<double>(s.v_p, in);
  n.w_body = omega<double>(s.w_p, s.bias, in);
  n.xi = s.xi;
  n.bias = s.bias;
  n.bias_sigma = P.block<3, 3>(I::kBias, I::kBias).diagonal().cwiseSqrt();
  n.common_slip = s.common_slip;
  if (na_ > 0) {
    n.accel_bias = s.accel_bias;
    n.accel_bias_sigma = P.block<3, 3>(ka_, ka_).diagonal().cwiseSqrt();
  }
  if (nk_ > 0) n.icr = s.icr, n.icr_sigma = std::sqrt(P(kk_, kk_));
  n.covariance.topLeftCorner<3, 3>() = P.block<3, 3>(I::kPos, I::kPos);
  n.covariance.bottomRightCorner<3, 3>() = P.block<3, 3>(I::kTheta, I::kTheta);
  n.covariance.topRightCorner<3, 3>() = P.block<3, 3>(I::kPos, I::kTheta);
  n.covariance.bottomLeftCorner<3, 3>() = P.block<3, 3>(I::kTheta, I::kPos);
  return n;
}

void Ekf::startRecording() {
  recording_ = true;
  updating_ = false;
  chain_ = RtsChain{};
  chain_.points.push_back({state(), P_, {}, {}, {}});
  phi_acc_ = Eigen::MatrixXd::Identity(n_, n_);
}

void Ekf::closeTransition() {
  RtsPoint& last = chain_.points.back();
  last.phi = phi_acc_;
  last.prior = state();
  last.P_prior = P_;
  updating_ = true;
}

void Ekf::recordNode(double t, const EkfInputs& in) {
  if (!recording_) return;
  // A node with no update since the last propagation (no slip rows in a joints gap): its prior
  // is its posterior, a point of the chain all the same.
  if (!updating_) closeTransition();
  chain_.node_points.push_back(chain_.points.size());  // the point its posterior will be
  chain_.node_t.push_back(t);
  chain_.node_inputs.push_back(in);
}

RtsChain Ekf::finishRecording() {
  if (recording_) {
    if (!updating_ && (phi_acc_ - Eigen::MatrixXd::Identity(n_, n_)).cwiseAbs().maxCoeff() > 0)
      closeTransition();
    if (updating_) chain_.points.push_back({state(), P_, {}, {}, {}});
    recording_ = updating_ = false;
  }
  return std::move(chain_);
}

double interpolationVarianceFactor(const Eigen::VectorXd& ts, double t) {
  const double* b = ts.data();
  const double* e = b + ts.size();
  const double* it = std::lower_bound(b, e, t);
  if (it == b || it == e) return 1.0;
  const double u = (t - *(it - 1)) / (*it - *(it - 1));
  return (1 - u) * (1 - u) + u * u;
}

namespace {

/// The gaps of the streams the inputs interpolate.
struct InputGaps {
  io::TimeGaps gyro, accel;
};

/// Inputs at t, for a step over [t0, t1] (t0 = t1 = t at an update): inside a gap when that
/// interval meets one.
EkfInputs inputsAt(const io::TraverseLog& log, double t, const InputGaps& gaps, double t0,
                   double t1) {
  EkfInputs in;
  in.gyro_gap = gaps.gyro.overlaps(t0, t1);
  in.accel_gap = gaps.accel.overlaps(t0, t1);
  const Eigen::VectorXd g = interpolateRow(log.gyro, t);
  in.gyro = sensors::GyroAxes::forColumns(g.size()).toBody(g);
  in.gyro_noise_variance_factor = interpolationVarianceFactor(log.gyro.t, t);
  if (log.cmd) {
    const Eigen::VectorXd c = interpolateRow(*log.cmd, t);
    in.v_cmd = c.head<3>(), in.w_cmd = c.tail<3>();
  }
  if (log.accel) in.accel = interpolateRow(*log.accel, t), in.has_accel = true;
  return in;
}

/// The rest window containing t, at least `margin` inside it, or nullptr. `cursor` walks
/// forward with t (events come in time order).
const RestWindow* restAt(const Segmentation& seg, double t, double margin, size_t& cursor) {
  while (cursor < seg.rests.size() && seg.rests[cursor].t_end < t) ++cursor;
  if (cursor == seg.rests.size()) return nullptr;
  const RestWindow& w = seg.rests[cursor];
  return t >= w.t_start + margin && t <= w.t_end - margin ? &w : nullptr;
}

}  // namespace

std::vector<JointSample> jointSamples(const io::TraverseLog& log) {
  const io::Stream& j = log.joints;
  const auto& js = log.config.joints;
  const int h = js.rate_filter_half_window;
  const std::span<const double> t(j.t.data(), static_cast<size_t>(j.size()));
  const double dt = medianPeriod(j);
  Eigen::MatrixXd angles = j.values;
  Eigen::MatrixXd rates = rover::jointRates(t, angles, {h});
  const rover::RoverGeometry& geo = log.geometry;
  const std::vector<int> steering = geo.coordsOfKind(rover::CoordKind::kSteering);
  const std::vector<int> suspension = geo.coordsOfKind(rover::CoordKind::kSuspension);
  const auto gather = [&](const std::vector<int>& cols) {
    Eigen::MatrixXd m(j.size(), static_cast<Eigen::Index>(cols.size()));
    for (size_t c = 0; c < cols.size(); ++c)
      m.col(static_cast<Eigen::Index>(c)) = j.values.col(cols[c]);
    return m;
  };
  // Steering: a wider window (rover.yaml steering_filter_window_s) for both angle and rate.
  const int hs = std::max(h, static_cast<int>(std::lround(0.5 * js.steering_filter_window_s / dt)));
  if (!steering.empty()) {
    const rover::SmoothedJoints steer = rover::smoothJoints(t, gather(steering), {hs});
    for (size_t c = 0; c < steering.size(); ++c) {
      angles.col(steering[c]) = steer.values.col(static_cast<Eigen::Index>(c));
      rates.col(steering[c]) = steer.rates.col(static_cast<Eigen::Index>(c));
    }
  }
  // Suspension rates: a fit over a window fixed in time (rover.yaml suspension_filter_window_s,
  // never narrower than the other joints'). A suspension angle enters a slip update twice, in
  // the wheel frames (the angle as logged) and through the rate, and the rate of a neighbouring
  // sample j weighs this sample's noise by w_{k-j} = (k−j)/Σm² of the fit: the filter's state,
  // built from those neighbours, is then correlated with the noise of the frames it is updated
  // through — a second-order bias, not noise, that grows with the joint rate at a fixed width in
  // samples (slow-onset at 50 Hz, docs/results.md). Summed over the neighbours it falls as 1/h.
  const int hg =
      std::max(h, static_cast<int>(std::lround(0.5 * js.suspension_filter_window_s / dt)));
  if (!suspension.empty()) {
    const Eigen::MatrixXd r = rover::jointRates(t, gather(suspension), {hg});
    for (size_t c = 0; c < suspension.size(); ++c)
      rates.col(suspension[c]) = r.col(static_cast<Eigen::Index>(c));
  }
  // Joint-rate noise of the smoothing-and-differencing filter (rover/joint_rates.h).
  const double s_steer = js.steeringNoise();
  rover::JointVectord rate_var(geo.numCoords());
  for (int c = 0; c < geo.numCoords(); ++c) {
    switch (geo.coords[static_cast<size_t>(c)].kind) {
      case rover::CoordKind::kSuspension:
        rate_var[c] = std::pow(js.angle_noise_rad / dt, 2) * rover::smoothedRateVarianceFactor(hg);
        break;
      case rover::CoordKind::kSteering:
        rate_var[c] = std::pow(s_steer / dt, 2) * rover::smoothedRateVarianceFactor(hs);
        break;
      case rover::CoordKind::kDrive:
        rate_var[c] = std::pow(js.wheel_noise_rad / dt, 2) * rover::smoothedRateVarianceFactor(h);
        break;
    }
  }
  const double steer_var = s_steer * s_steer * rover::smoothedValueVarianceFactor(hs);
  const int nw = geo.numWheels();
  // Inside a gap of joints.csv (io::TimeGaps) the trajectory is still wanted: unmeasured
  // samples at the stream's median period, so the EKF writes nodes there and the smoother's
  // states (and σ) follow the gyro and accelerometer across the gap instead of one long
  // interval that hides it. Their frames come from the angles interpolated across the gap
  // (the contact geometry changes slowly); they carry no joint twist and no slip rows.
  const io::TimeGaps gaps(j);
  std::vector<JointSample> out;
  out.reserve(static_cast<size_t>(j.size()));
  const auto frames = [&](const rover::JointVectord& q, JointSample& s) {
    const auto kin = rover::forwardKinematics<double>(geo, q);
    for (int i = 0; i < nw; ++i) s.T_body_wheel[i] = kin[i].T_body_wheel;
    return kin;
  };
  size_t next_gap = 0;
  for (Eigen::Index k = 0; k < j.size(); ++k) {
    const rover::JointVectord q = angles.row(k).transpose();
    const rover::JointVectord q_dot = rates.row(k).transpose();
    JointSample& s = out.emplace_back();
    s.t = j.t[k];
    s.resize(nw);
    const auto kin = frames(q, s);
    for (int i = 0; i < nw; ++i) {
      s.joint_twist[i] = rover::wheelJointTwist(kin[i], q_dot);
      s.joint_twist_covariance[i] = kin[i].J * rate_var.asDiagonal() * kin[i].J.transpose();
      s.steering_variance[i] = geo.wheels[i].steered ? steer_var : 0.0;
      s.used[i] = log.wheelUsed(i, s.t, (h + 1) * dt);
    }
    if (next_gap < gaps.spans().size() && gaps.spans()[next_gap].first == j.t[k] &&
        k + 1 < j.size() && dt > 0.0) {
      const double t0 = j.t[k], t1 = j.t[k + 1];
      const rover::JointVectord q1 = angles.row(k + 1).transpose();
      for (double tv = t0 + dt; tv < t1 - 0.5 * dt; tv += dt) {
        JointSample& v = out.emplace_back();
        v.t = tv;
        v.resize(nw);
        v.measured = false;
        std::fill(v.used.begin(), v.used.end(), 0);
        frames(q + (tv - t0) / (t1 - t0) * (q1 - q), v);
        for (int i = 0; i < nw; ++i) {
          v.joint_twist[i].setZero();
          v.joint_twist_covariance[i].setZero();
        }
      }
      ++next_gap;
    }
  }
  return out;
}

namespace {

double gatedFraction(long rejected, long updates) {
  return updates > 0 ? static_cast<double>(rejected) / static_cast<double>(updates) : 0.0;
}

std::string percent(double f) {
  return std::to_string(static_cast<int>(std::lround(100.0 * f))) + " %";
}

EkfResult runEkfWith(const io::TraverseLog& log, const Segmentation& seg, const InitialState& init,
                     const EkfOptions& options);

}  // namespace

EkfResult runEkf(const io::TraverseLog& log, const Segmentation& seg, const InitialState& init,
                 const EkfOptions& requested) {
  EkfOptions options = requested;
  std::vector<std::string> warnings;
  EkfResult result;
  bool done = false;
  if (options.velocity == EkfOptions::VelocityModel::kAuto) {
    options.velocity = log.accel ? EkfOptions::VelocityModel::kAccelDriven
                                 : EkfOptions::VelocityModel::kPerturbation;
    if (log.accel) {
      result = runEkfWith(log, seg, init, options);
      // An accelerometer error shows as a velocity the wheels deny (slip gated out) or, when
      // the velocity follows the wheels, as a tilt the sun denies (sun gated out).
      const EkfStats& st = result.stats;
      const double fs = gatedFraction(st.slip_rejected, st.slip_updates);
      const double fn = gatedFraction(st.sun_rejected, st.sun_updates);
      const bool slip_bad = st.slip_updates >= 50 && fs > kMaxGatedFraction;
      const bool sun_bad = st.sun_updates >= 20 && fn > kMaxGatedFraction;
      if (slip_bad || sun_bad) {
        warnings.push_back(
            "ekf: the accelerometer-driven velocity model gated out " +
            (slip_bad ? percent(fs) + " of the slip updates"
                      : percent(fn) + " of the sun updates") +
            " (the accelerometer disagrees with the wheels or the sun: an unmodelled bias or "
            "mounting); using the wheel-driven model instead (--velocity-model perturbation)");
        options.velocity = EkfOptions::VelocityModel::kPerturbation;
      } else {
        done = true;
      }
    }
  }
  if (!done) result = runEkfWith(log, seg, init, options);
  result.velocity = options.velocity;
  const EkfStats& s = result.stats;
  if (const double f = gatedFraction(s.slip_rejected, s.slip_updates);
      s.slip_updates >= 50 && f > kMaxGatedFraction) {
    warnings.push_back("ekf: " + percent(f) +
                       " of the slip updates were gated out: the slip "
                       "model does not fit this rover's wheels (rover.yaml slip_noise, "
                       "skid_steer; traverse calibrate)");
  }
  if (const double f = gatedFraction(s.sun_rejected, s.sun_updates);
      s.sun_updates >= 20 && f > kMaxGatedFraction) {
    warnings.push_back("ekf: " + percent(f) +
                       " of the sun updates were gated out: the sun "
                       "sensor's mounting, field of view or the sun's direction does not fit");
  }
  result.warnings = std::move(warnings);
  return result;
}

namespace {

EkfResult runEkfWith(const io::TraverseLog& log, const Segmentation& seg, const InitialState& init,
                     const EkfOptions& options) {
  Ekf ekf(log.config, log.geometry, options, init,
          sensors::GyroAxes::forColumns(log.gyro.values.cols()).isThreeAxis(), log.cmd.has_value());
  ekf.setSamplePeriods(medianPeriod(log.gyro), log.accel ? medianPeriod(*log.accel) : 0.1);
  const std::vector<JointSample> joints = jointSamples(log);
  InputGaps gaps{io::TimeGaps(log.gyro), log.accel ? io::TimeGaps(*log.accel) : io::TimeGaps()};
  const double inf = std::numeric_limits<double>::infinity();
  const double margin = 0.25;  // rest updates keep clear of the detected boundaries
  Eigen::Index ig = 0, ij = 0, is = 0;
  size_t rest_cursor = 0, step_rest_cursor = 0, gravity_next = 0;
  double t = init.t;
  EkfResult result;
  result.trajectory.name = "ekf";
  result.trajectory.has_covariance = true;
  result.trajectory.nodes.reserve(joints.size());
  const bool k12 = options.attitude == EkfOptions::AttitudeModel::kGyroMeasurement;
  // The rest window the initial mean-sun yaw and bias came from: its sun readings and rest-bias
  // updates are in the initial state already and are not applied again (counted twice, the σ
  // after it was 1/√2 of the window's). Its gravity is: the filter starts from the σ before it.
  const RestWindow* init_rest =
      init.rest_index >= 0 ? &seg.rests[static_cast<size_t>(init.rest_index)] : nullptr;
  // The filter starts at the first joint sample (InitialState::t): gyro and sun readings before
  // it are not used.
  while (ig < log.gyro.size() && log.gyro.t[ig] < init.t) ++ig;
  while (log.sun && is < log.sun->size() && log.sun->t[is] < init.t) ++is;
  if (options.rts) ekf.startRecording();
  for (;;) {
    while (log.sun && is < log.sun->size() && log.sun->values(is, 2) < 0.5)
      ++is;  // valid = 0: ignored
    const double tg = ig < log.gyro.size() ? log.gyro.t[ig] : inf;
    const double tj = ij < std::ssize(joints) ? joints[static_cast<size_t>(ij)].t : inf;
    const double ts = log.sun && options.use_sun && is < log.sun->size() ? log.sun->t[is] : inf;
    const double tn = std::min({tg, tj, ts});
    if (tn == inf) break;
    if (tn > t) {
      EkfInputs step = inputsAt(log, 0.5 * (t + tn), gaps, t, tn);
      // Inside a rest window (both ends, trimmed as the rest updates) the velocity is not driven
      // by the accelerometer: its readings there reach the attitude through the gravity update
      // once (as in the smoother), not a second time through v̇ = f + Rᵀg under zero-velocity
      // updates.
      if (step.has_accel && options.use_rest && restAt(seg, t, margin, step_rest_cursor) &&
          restAt(seg, tn, margin, step_rest_cursor))
        step.has_accel = false;
      ekf.propagate(tn - t, step);
    }
    t = tn;
    const EkfInputs in = inputsAt(log, t, gaps, t, t);
    const RestWindow* rest = options.use_rest ? restAt(seg, t, margin, rest_cursor) : nullptr;
    if (tg == t) {
      if (k12) ekf.updateGyro(in.gyro);  // K-12: at rest this observes the bias by itself
      if (rest) {
        ekf.updateZeroRate(in);
        if (!k12 && !(init.bias_from_rest && rest == init_rest)) ekf.updateRestBias(in);
      }
      ++ig;
    }
    if (ts == t) {
      if (!(init.yaw_from_rest_sun && init_rest && t >= init_rest->t_start &&
            t <= init_rest->t_end))
        ekf.updateSun(log.sun->values.row(is).head<2>().transpose(), log.config.sun.directionAt(t));
      ++is;
    }
    if (tj == t) {
      if (options.use_slip) ekf.updateSlip(joints[static_cast<size_t>(ij)], in);
      if (rest) ekf.updateZeroVelocity(in);
      // Roll/pitch from gravity once per rest window, at its middle (the rover does not move).
      while (options.use_rest && gravity_next < seg.rests.size() &&
             t >= 0.5 * (seg.rests[gravity_next].t_start + seg.rests[gravity_next].t_end)) {
        if (seg.rests[gravity_next].has_gravity && t <= seg.rests[gravity_next].t_end) {
          ekf.updateGravity(seg.rests[gravity_next].roll_pitch);
        }
        ++gravity_next;
      }
      result.trajectory.nodes.push_back(ekf.node(t, in));
      ekf.recordNode(t, in);
      ++ij;
    }
  }
  result.stats = ekf.stats();
  if (options.rts) {
    const auto t0 = std::chrono::steady_clock::now();
    result.rts = rtsSmooth(ekf, ekf.finishRecording());
    result.rts_seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  }
  return result;
}

}  // namespace

// The measurement sizes the filter uses (and the tests call), and the double rate model.
#define TRAVERSE_EKF_INSTANTIATE_UPDATE(M)                                                \
  template void detail::innovation<M>(const EkfMatrix&, const EkfRows<M>&,                \
                                      const Eigen::Matrix<double, M, M>&, EkfCols<M>*,    \
                                      Eigen::Matrix<double, M, M>*);                      \
  template void detail::josephUpdate<M>(EkfMatrix*, const EkfCols<M>&, const EkfCols<M>&, \
                                        const Eigen::Matrix<double, M, M>&);              \
  template bool Ekf::update<M>(const Eigen::Matrix<double, M, 1>&, const EkfRows<M>&,     \
                               const Eigen::Matrix<double, M, M>&, double);
TRAVERSE_EKF_INSTANTIATE_UPDATE(1)
TRAVERSE_EKF_INSTANTIATE_UPDATE(2)
TRAVERSE_EKF_INSTANTIATE_UPDATE(3)
TRAVERSE_EKF_INSTANTIATE_UPDATE(4)
#undef TRAVERSE_EKF_INSTANTIATE_UPDATE
template Vec3d Ekf::omega<double>(const Vec3d&, const Vec3d&, const EkfInputs&) const;

}  // namespace traverse::est
