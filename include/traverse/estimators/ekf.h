// Forward error-state EKF on the kinematic rover model (K §2.2, §3; O-1 … O-4; R-16 … R-21).
//
// Nominal state: attitude q (body → site), rate perturbation ω_p, position x (site), velocity
// perturbation v_p (body), gyro bias b, contact angles ξ1..ξN (one per wheel of the rover's
// URDF), and, when rover.yaml declares it (slip_noise.common_*), the wheels' common slip
// c = (c_x, c_y) (body, m/s; a Gauss–Markov process: ċ = −c/τ + n_c), and, when rover.yaml
// declares accelerometer.bias_sigma_mps2, the accelerometer's bias b_a (body, m/s²; a random
// walk). Error state (15 + N + C + A, C = 0 or 2, A = 0 or 3):
//   [δθ (body small angle, q = q̂ ⊗ Exp(δθ)), δω_p, δx, δv_p, δb, δξ, δc, δb_a].
// Process (continuous-discrete): K-1 ẋ = R(q)(v_c + v_p), v̇_p = A_v v_p + n_v; K-2/K-7 attitude
// with ω = ω_c + ω_p (gyro as a measurement, K-12) or the hybrid O-1 form ω = B_gᵀ(ω_m − b) +
// ω_p on the measured axes (default; the gyro drives the heading); K-8 ξ̇ = A_ξ ξ + n_ξ;
// K-9 ḃ = n_b; or O-4, the accelerometer driving the velocity. The slip rows see the body
// moving at v + c. Updates are processed
// sequentially as each stream's samples arrive (R §5): slip constraint (K-17, four rows per
// wheel), sun sensor (K-15/16), gyro (K-12, when a measurement), and at rest zero velocity, zero
// rate, the bias (each gyro sample: Nickels' drift filter) and roll/pitch from gravity. Joseph-form
// covariance updates; the attitude error is re-absorbed into q after every update (K-21), with the
// reset Jacobian applied to the covariance.
#pragma once

#include <array>
#include <optional>
#include <string>
#include <vector>

#include "traverse/estimators/initialization.h"
#include "traverse/estimators/trajectory.h"
#include "traverse/rover/joint_sample.h"
#include "traverse/rover/kinematics.h"

namespace traverse::est {

/// Size of the error state of a rover with `wheels` wheels, `common_slip` (0, 2 or 3) common slip
/// states, `accel_bias` (0 or 3) accelerometer-bias states and `icr` (0 or 1) ICR half-track
/// states, and its largest value.
constexpr int ekfStates(int wheels, int common_slip = 0, int accel_bias = 0, int icr = 0) {
  return 15 + wheels + common_slip + accel_bias + icr;
}
inline constexpr int kCommonSlipStates = 3;  ///< the most: c_x, c_y, c_ω
inline constexpr int kAccelBiasStates = 3;
inline constexpr int kIcrStates = 1;
/// The gyro reading's white noise, carried for one joint sample's slip rows (Ekf::updateSlip).
inline constexpr int kGyroNoiseStates = 3;
inline constexpr int kMaxEkfStates =
    ekfStates(rover::kMaxWheels, kCommonSlipStates, kAccelBiasStates, kIcrStates) +
    kGyroNoiseStates;
/// Error-state vectors and matrices: fixed storage (no heap), size ekfStates(wheels).
using EkfVector = Eigen::Matrix<double, Eigen::Dynamic, 1, 0, kMaxEkfStates, 1>;
using EkfMatrix =
    Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, 0, kMaxEkfStates, kMaxEkfStates>;
/// An M-row measurement Jacobian H (M × states) and an M-column gain (states × M).
template <int M>
using EkfRows = Eigen::Matrix<double, M, Eigen::Dynamic, M == 1 ? Eigen::RowMajor : Eigen::ColMajor,
                              M, kMaxEkfStates>;
template <int M>
using EkfCols = Eigen::Matrix<double, Eigen::Dynamic, M, 0, kMaxEkfStates, M>;

/// Offsets of the error-state blocks (ξ, c, b_a and δ last: their offsets depend on the rover's
/// wheel count; c starts at commonSlip(N), b_a at accelBias(N, C), δ at icr(N, C, A)).
struct EkfIndex {
  static constexpr int kTheta = 0, kRate = 3, kPos = 6, kVel = 9, kBias = 12, kXi = 15;
  static constexpr int commonSlip(int wheels) { return kXi + wheels; }
  static constexpr int accelBias(int wheels, int common_slip) { return kXi + wheels + common_slip; }
  static constexpr int icr(int wheels, int common_slip, int accel_bias) {
    return kXi + wheels + common_slip + accel_bias;
  }
};

struct EkfOptions {
  enum class AttitudeModel { kGyroDriven, kGyroMeasurement };
  enum class VelocityModel { kAuto, kPerturbation, kAccelDriven };
  AttitudeModel attitude = AttitudeModel::kGyroDriven;  ///< O-1 hybrid (default) or K-2 + K-12
  /// O-4 when the log has an accelerometer (it keeps roll and pitch observable in motion:
  /// multi-stop roll/pitch RMSE 0.05°/0.07° against 0.39°/0.44° with K-1), else K-1.
  VelocityModel velocity = VelocityModel::kAuto;
  bool use_sun = true, use_slip = true, use_rest = true;
  bool gating = true;
  double gate_probability = 0.9999;  ///< χ² gate for sun and slip innovations
  /// The common slip c changes by jumps as well as by its Gauss–Markov drift (the ground gives
  /// under every wheel at once: a slip burst). At each joint sample the wheels' mean velocity
  /// mismatch (body x, y) is tested against its covariance; beyond this χ²₂ probability the
  /// mismatch is taken for a jump of c and added to c's covariance (ū ūᵀ) before the wheels'
  /// rows are processed, so that the wheels move c, not the velocity the accelerometer holds.
  double common_slip_jump_probability = 0.999;
  bool common_slip_jumps = true;  ///< the jump test (off: c is only the Gauss–Markov process)
  double zero_velocity_sigma_mps = 0.001;
  double zero_rate_sigma_rad_s = 1e-4;  ///< added to the gyro noise
  /// n_ω on gyro-driven axes is small (O §2.2.1): this times the process rate noise, unless
  /// rover.yaml gives gyro.rate_perturbation_rad_s2_per_sqrt_hz.
  double rate_noise_scale_measured_axes = 0.1;
  double initial_velocity_sigma_mps = 0.01;
  double initial_rate_sigma_rad_s = 0.01;
  double initial_contact_sigma_rad = 0.1;
  double initial_position_sigma_m = 1e-4;
  /// Also run the Rauch–Tung–Striebel smoother over the filter's stored states (rts.h):
  /// EkfResult::rts, the trajectory "rts".
  bool rts = false;
};

/// Counts of each update, and of the innovations the χ² gate rejected.
struct EkfStats {
  long propagations = 0;
  long slip_updates = 0, slip_rejected = 0;
  long slip_not_used = 0;  ///< wheel slip updates skipped inside a wheel outage
  long sun_updates = 0, sun_rejected = 0;
  long gyro_updates = 0, zero_velocity_updates = 0, zero_rate_updates = 0, gravity_updates = 0;
  long bias_updates = 0;
  long common_slip_jumps = 0;  ///< joint samples whose wheels' mismatch was taken for a jump of c
};

/// Inputs at one instant: gyro reading (all three axes; with a heading-only gyro only z is
/// meaningful), commanded body twist (zero when the log has no cmd.csv), accelerometer reading.
struct EkfInputs {
  Vec3d gyro = Vec3d::Zero();
  Vec3d v_cmd = Vec3d::Zero(), w_cmd = Vec3d::Zero();
  Vec3d accel = Vec3d::Zero();
  bool has_accel = false;
  /// Inside a gap of gyro.csv / accel.csv (io::TimeGaps): the reading is an interpolation
  /// across time nothing measured. A gyro gap turns the gyro's axes into unmeasured ones for
  /// the step (ω from the command and ω_p, with the full rate noise); an accelerometer gap
  /// leaves the O-4 velocity a random walk (no v̇, the velocity process noise).
  bool gyro_gap = false, accel_gap = false;
  /// Variance of the gyro reading's white noise over one sample's: (1 − u)² + u² for the
  /// interpolation at u between two samples (1 at a sample).
  double gyro_noise_variance_factor = 1.0;
};

using rover::JointSample;

/// The nominal state (the point the error state is taken about).
struct EkfState {
  Quatd q_site_body = Quatd::Identity();
  Vec3d w_p = Vec3d::Zero();     ///< rate perturbation ω_p (body)
  Vec3d p_site = Vec3d::Zero();  ///< position x (site)
  Vec3d v_p = Vec3d::Zero();     ///< velocity perturbation v_p (body; O-4: the body velocity)
  rover::WheelVectord xi;        ///< contact angles ξ1..ξN
  Vec3d bias = Vec3d::Zero();    ///< gyro bias b
  /// c (body x, y in m/s, yaw rate c_ω in rad/s; zero without the state, c_ω zero unless declared)
  Vec3d common_slip = Vec3d::Zero();
  Vec3d accel_bias = Vec3d::Zero();  ///< b_a (body, m/s²; zero without the state)
  /// δ: the skid-steer ICRs' half-track error (m; io::SkidSteerConfig; zero without the state).
  double icr = 0.0;
};

/// What a Rauch–Tung–Striebel pass over the filter needs (rts.h), recorded while it runs: the
/// chain of posteriors (the state after each batch of updates) and, between consecutive ones, the
/// transition the propagations made — Φ composed over every step since the posterior, and the
/// prior they gave (state and covariance just before the next batch of updates). Matrices are
/// numStates() square.
struct RtsPoint {
  EkfState posterior;
  Eigen::MatrixXd P_post;
  Eigen::MatrixXd phi;  ///< to the next point (empty at the last)
  EkfState prior;       ///< the next point's prior
  Eigen::MatrixXd P_prior;
};

struct RtsChain {
  std::vector<RtsPoint> points;
  /// Per trajectory node: its point, time and inputs (the node's derived ω and v need them).
  std::vector<size_t> node_points;
  std::vector<double> node_t;
  std::vector<EkfInputs> node_inputs;
};

class Ekf {
 public:
  Ekf(const io::RoverConfig& config, const rover::RoverGeometry& geometry,
      const EkfOptions& options, const InitialState& init, bool three_axis_gyro, bool has_cmd);

  /// Propagates over dt with inputs evaluated at the middle of the interval: the nominal state
  /// by the midpoint rule, the covariance P ← Φ P Φᵀ + Q dt with Φ = I + F dt + ½ (F dt)² and
  /// F = processJacobian(in) at the state before the step.
  void propagate(double dt, const EkfInputs& in);
  /// F = ∂(d δx/dt)/∂δx of the continuous error dynamics at the current nominal state (n × n,
  /// error state as in the file comment). `v_dot` (optional): the nominal v̇_p of the O-4
  /// velocity model when the accelerometer drives it, else zero.
  EkfMatrix processJacobian(const EkfInputs& in, Vec3d* v_dot = nullptr) const;
  /// K-17 for every wheel (sequential, four rows each) against the nominal slip of K §2.3.4.
  void updateSlip(const JointSample& js, const EkfInputs& in);
  /// K-15/K-16 with the sun direction in the site frame.
  void updateSun(const Vec2d& s_m, const Vec3d& sun_site);
  /// K-12 with the gyro as a measurement (AttitudeModel::kGyroMeasurement).
  void updateGyro(const Vec3d& w_m);
  void updateZeroVelocity(const EkfInputs& in);
  /// At rest the rate perturbation ω_p is zero (and with K-12, ω_c + ω_p).
  void updateZeroRate(const EkfInputs& in);
  /// At rest each gyro sample measures the bias (gyro-driven model; K-12 does it in updateGyro).
  void updateRestBias(const EkfInputs& in);
  void updateGravity(const sensors::RollPitchMeasurement& m);

  /// Sample periods of the gyro and accelerometer: white noise per sample σ becomes the density
  /// σ² Δt when those readings drive the process.
  void setSamplePeriods(double gyro_s, double accel_s) {
    gyro_period_ = gyro_s, accel_period_ = accel_s;
  }

  /// Generic measurement update with residual r = z − h(x̂), Jacobian H = ∂h/∂δx and noise R:
  /// gain K = P Hᵀ S⁻¹ (S = H P Hᵀ + R, over H's nonzero columns), the expanded Joseph form
  /// (detail::josephUpdate), then absorb(K r). False (nothing changed) when S is not positive
  /// definite or, with gate > 0, when the innovation's r S⁻¹ r exceeds it. M = 1 … 4.
  template <int M>
  bool update(const Eigen::Matrix<double, M, 1>& r, const EkfRows<M>& H,
              const Eigen::Matrix<double, M, M>& R, double gate);
  /// Moves the nominal state by the error-state correction dx (attitude by K-21, q ⊗ Exp(dθ))
  /// and applies the reset Jacobian G = detail::resetJacobian(dθ) to P's attitude rows and
  /// columns (the error is now taken about the new q).
  void absorb(const EkfVector& dx);

  TrajectoryNode node(double t, const EkfInputs& in) const;
  /// The node of a given state and covariance (what node() does for the filter's own).
  TrajectoryNode nodeOf(const EkfState& state, const EkfMatrix& P, double t,
                        const EkfInputs& in) const;

  /// Starts recording the chain an RTS pass needs (RtsChain), from the current state.
  void startRecording();
  /// Marks the current state as the node at t (inputs `in`): it becomes a point of the chain.
  void recordNode(double t, const EkfInputs& in);
  /// Ends the recording (the last propagations become a final point) and hands the chain over.
  RtsChain finishRecording();
  const EkfStats& stats() const { return stats_; }
  const EkfMatrix& covariance() const { return P_; }
  /// Replaces the covariance (tests; P must be symmetric positive semi-definite).
  void setCovariance(const EkfMatrix& P) { P_ = P; }
  EkfState state() const { return {q_, w_p_, x_, v_p_, xi_, b_, c_, ba_, icr_}; }
  /// Size of the error state: ekfStates(wheels, common slip states, accelerometer-bias states).
  int numStates() const { return n_; }
  /// Whether the state has the common slip c (rover.yaml declares its σ).
  bool hasCommonSlip() const { return nc_ > 0; }
  /// States of c: 0, 2 (c_x, c_y) or 3 (with c_ω).
  int commonSlipStates() const { return nc_; }
  /// Whether the state has the accelerometer's bias b_a (rover.yaml declares its σ).
  bool hasAccelBias() const { return na_ > 0; }
  /// Whether the state has the ICR half-track error δ (a skid-steer rover whose rover.yaml
  /// gives it a σ > 0).
  bool hasIcr() const { return nk_ > 0; }
  /// Replaces the nominal state (tests).
  void setState(const EkfState& s) {
    q_ = s.q_site_body, w_p_ = s.w_p, x_ = s.p_site, v_p_ = s.v_p, xi_ = s.xi, b_ = s.bias;
    c_ = nc_ > 0 ? s.common_slip : Vec3d::Zero();
    if (nc_ < 3) c_.z() = 0.0;
    ba_ = na_ > 0 ? s.accel_bias : Vec3d::Zero();
    icr_ = nk_ > 0 ? s.icr : 0.0;
  }

  /// Body rate and velocity of the current estimate (templated so Jets differentiate them).
  template <typename T>
  Vec3<T> omega(const Vec3<T>& w_p, const Vec3<T>& b, const EkfInputs& in) const;
  template <typename T>
  Vec3<T> velocity(const Vec3<T>& v_p, const EkfInputs& in) const {
    return in.v_cmd.cast<T>() + v_p;
  }

 private:
  /// Damping of the process at these inputs (K §4.2): ω̇_p = a_w ⊙ ω_p, v̇_p = a_v v_p (K-1),
  /// ξ̇ = a_ξ ξ; accel_driven: the accelerometer drives the velocity (O-4).
  struct Damping {
    bool accel_driven;
    Vec3d a_w;
    double a_v, a_xi, a_c;
  };
  Damping damping(const EkfInputs& in) const;
  /// What a propagation step needs at the state before it: the dampings, ω, v, v̇ (O-4; zero
  /// otherwise) and F. processJacobian returns its F; propagate uses all of it (once).
  struct Linearisation {
    Damping d;
    Vec3d w, v, v_dot;
    EkfMatrix F;
  };
  void linearise(const EkfInputs& in, Linearisation* out) const;
  void gyroAxisUpdates(const Vec3d& w_m, bool at_rest, long* count);
  /// The jump test of EkfOptions::common_slip_jump_probability at this joint sample (c's
  /// covariance grows when it fires).
  void commonSlipJump(const JointSample& js, const EkfInputs& in, const Twistd* commanded);

  const io::RoverConfig& config_;
  const rover::RoverGeometry& geometry_;
  EkfOptions options_;
  bool three_axis_, has_cmd_;
  Mat3d S_;  ///< ∂ω/∂b = −S_ (gyro-driven) — the gyro's axes
  /// The gyro's axes at these inputs: S_, or none inside a gyro gap.
  Mat3d gyroAxes(const EkfInputs& in) const { return in.gyro_gap ? Mat3d::Zero() : S_; }
  double gate2_, gate4_, jump_gate_;
  double gyro_period_ = 0.05, accel_period_ = 0.1;
  Vec3d last_w_cmd_ = Vec3d::Zero();  ///< commanded rate at the latest propagation (K-12 mode)
  // Nominal state.
  Quatd q_;
  Vec3d w_p_, x_, v_p_, b_;
  rover::WheelVectord xi_;
  Vec3d c_ = Vec3d::Zero();  ///< c_x, c_y, c_ω (the last zero unless nc_ == 3)
  Vec3d ba_ = Vec3d::Zero();
  double icr_ = 0.0;
  /// Wheels, common slip states (0, 2, 3) and their offset, accelerometer-bias states (0, 3) and
  /// their offset, ICR states (0, 1) and their offset, error-state size.
  int nw_, nc_, kc_, na_, ka_, nk_, kk_, n_;
  EkfMatrix P_;
  EkfStats stats_;
  // RTS recording (startRecording): Φ since the latest posterior, whether updates followed it.
  bool recording_ = false, updating_ = false;
  Eigen::MatrixXd phi_acc_;
  RtsChain chain_;
  /// Before the first update of a batch: the transition into it is complete.
  void closeTransition();
};

struct EkfResult {
  Trajectory trajectory;  ///< one node per jointSamples entry
  EkfStats stats;
  EkfOptions::VelocityModel velocity = EkfOptions::VelocityModel::kPerturbation;  ///< as run
  /// What the run should tell its user (one line each, without "warning: "): most updates of
  /// a kind gated out, the velocity model given up.
  std::vector<std::string> warnings;
  /// The Rauch–Tung–Striebel smoother over this run's stored states (EkfOptions::rts; rts.h).
  std::optional<Trajectory> rts;
  double rts_seconds = 0.0;  ///< wall time of the backward pass
};

/// Above this fraction of slip (or sun) updates rejected by the χ² gate the model, not the
/// data, is wrong: runEkf says so, and gives up the accelerometer-driven velocity model.
inline constexpr double kMaxGatedFraction = 0.2;

/// Runs the filter over a whole log (events in time order: gyro, joints, sun, accel).
/// VelocityModel::kAuto: the accelerometer drives the velocity (O-4) when the log has one, unless
/// that run gates out more than kMaxGatedFraction of its slip updates — the wheels then disagree
/// with the integrated accelerometer (an unmodelled bias, a mounting error), which would
/// otherwise integrate into metres — and the run is repeated with the wheel-driven model (K-1),
/// with a warning.
EkfResult runEkf(const io::TraverseLog& log, const Segmentation& seg, const InitialState& init,
                 const EkfOptions& options = {});

/// Wheel frames and joint twists for every joint sample (joint rates by smoothing and
/// differencing, K §3), in time order; inside each gap of joints.csv (io::TimeGaps), samples at
/// the stream's median period with `measured` false (no joint twist, no slip rows; frames from
/// the angles interpolated across the gap), so a trajectory node exists there too.
std::vector<JointSample> jointSamples(const io::TraverseLog& log);

/// (1 − u)² + u²: the variance of a stream's white noise in its linear interpolation at t, u of
/// the way between the samples around it, in units of one sample's variance (1 at a sample or
/// outside the stream; EkfInputs::gyro_noise_variance_factor). `stamps`: strictly increasing.
double interpolationVarianceFactor(const Eigen::VectorXd& stamps, double t);

/// Residual r = nominal − t of wheel i's four slip rows (K-17, K §2.3.4) at s = (v, ω, ξ_i) and
/// H = −∂r/∂s, the measurement Jacobian of the EKF's slip update. The nominal slip comes from
/// the commanded twist when there is one (`commanded`), otherwise from the state itself
/// (v_x, ω_z), and is then differentiated with the constraint. `dt_ds` (optional): ∂t/∂s of
/// the constraint alone, which carries the joint noise (rover::slipCovariance). `icr`: the ICRs'
/// half-track error δ (skid steering: the wheel's ICR offset is icr_offset_y + icr_side δ);
/// `H_icr` (optional): −∂r/∂δ.
Vec4d slipUpdateResidual(const rover::RoverGeometry& geometry, const JointSample& js, int wheel,
                         const Twistd* commanded, const Eigen::Matrix<double, 7, 1>& s,
                         Eigen::Matrix<double, 4, 7>* H,
                         Eigen::Matrix<double, 4, 7>* dt_ds = nullptr, double icr = 0.0,
                         Vec4d* H_icr = nullptr);

/// Building blocks of Ekf, exposed so that tests check each against its dense textbook form
/// (tests/est_ekf_process_jacobian_test.cpp).
namespace detail {

/// Φ P Φᵀ with Φ = I + F dt + ½ (F dt)², over F's nonzeros only (F has ~50 of 441 for six wheels):
/// A = Φ − I, P + A P + P Aᵀ + A P Aᵀ by column operations. No process noise.
EkfMatrix propagateCovariance(const EkfMatrix& F, double dt, const EkfMatrix& P);
/// The same, in place (the filter's form: no copy of P).
void propagateCovarianceInPlace(const EkfMatrix& F, double dt, EkfMatrix* P);

/// P Hᵀ and S = H P Hᵀ + R over H's nonzero columns only (a slip row touches 10 of 21 states
/// of a six-wheel rover). M = 1 … 4.
template <int M>
void innovation(const EkfMatrix& P, const EkfRows<M>& H, const Eigen::Matrix<double, M, M>& R,
                EkfCols<M>* PHt, Eigen::Matrix<double, M, M>* S);

/// The Joseph form (I − K H) P (I − K H)ᵀ + K R Kᵀ, expanded as P − K (HP) − (HP)ᵀ Kᵀ + K S Kᵀ
/// (valid for any gain K) from P Hᵀ and S of `innovation`, at rank-M cost; replaces *P. P stays
/// exactly symmetric (lower triangle computed, then mirrored). M = 1 … 4.
template <int M>
void josephUpdate(EkfMatrix* P, const EkfCols<M>& K, const EkfCols<M>& PHt,
                  const Eigen::Matrix<double, M, M>& S);

/// Reset Jacobian of the attitude error when dθ is absorbed into q̂ (q̂⁺ = q̂ ⊗ Exp(dθ)):
/// δθ⁺ = Log(q̂⁺⁻¹ q) ≈ G δθ with G = I − ½[dθ]× (first order in dθ).
Mat3d resetJacobian(const Vec3d& dtheta);

}  // namespace detail

/// χ² quantile for `dof` degrees of freedom (regularized incomplete gamma), for gating.
double chiSquareQuantile(double probability, int dof);

}  // namespace traverse::est
