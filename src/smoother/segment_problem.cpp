// One smoother segment: build the Ceres problem from the log and the EKF seed — which residuals
// for which node; each residual's constraint function, beside its functor in smoother/residuals/,
// adds it — then solve it (segment_solve.h) and read the marginal covariances
// (segment_covariance.h). include/traverse/smoother/segment_problem.h.
#include "traverse/smoother/segment_problem.h"

#include <array>
#include <chrono>
#include <cmath>
#include <iostream>
#include <memory>
#include <sstream>
#include <stdexcept>

#include <ceres/ceres.h>

#include "traverse/core/error.h"
#include "traverse/rover/nominal_slip.h"
#include "traverse/smoother/block_evaluation.h"
#include "traverse/smoother/body_quaternion_manifold.h"
#include "traverse/smoother/residual_collector.h"
#include "traverse/smoother/residuals/accel_velocity_process.h"
#include "traverse/smoother/residuals/attitude_process.h"
#include "traverse/smoother/residuals/gravity_residual.h"
#include "traverse/smoother/residuals/gyro_increment.h"
#include "traverse/smoother/residuals/interpolation.h"
#include "traverse/smoother/residuals/markov_process.h"
#include "traverse/smoother/residuals/position_process.h"
#include "traverse/smoother/residuals/rest_bias_residual.h"
#include "traverse/smoother/residuals/slip_residual.h"
#include "traverse/smoother/residuals/start_prior_residual.h"
#include "traverse/smoother/residuals/sun_sensor_residual.h"
#include "traverse/smoother/residuals/zero_motion_residual.h"
#include "traverse/smoother/segment_covariance.h"
#include "traverse/smoother/segment_solve.h"

namespace traverse::smoother {

IntegratedSignal::IntegratedSignal(const Eigen::VectorXd& t, const Eigen::MatrixXd& values)
    : t_(t), y_(values), c_(Eigen::MatrixXd::Zero(values.rows(), values.cols())) {
  for (Eigen::Index k = 1; k < t.size(); ++k)
    c_.row(k) = c_.row(k - 1) + 0.5 * (t[k] - t[k - 1]) * (y_.row(k - 1) + y_.row(k));
}

Eigen::VectorXd IntegratedSignal::at(double t) const {
  const Eigen::Index n = t_.size();
  if (t <= t_[0]) return (c_.row(0) - (t_[0] - t) * y_.row(0)).transpose();
  if (t >= t_[n - 1]) return (c_.row(n - 1) + (t - t_[n - 1]) * y_.row(n - 1)).transpose();
  const Eigen::Index k = std::upper_bound(t_.data(), t_.data() + n, t) - t_.data() - 1;
  const double h = t_[k + 1] - t_[k], s = t - t_[k];
  // ∫ over [t_k, t] of the linear interpolant: s y_k + ½ s² (y_{k+1} − y_k)/h.
  return (c_.row(k) + s * y_.row(k) + 0.5 * s * s / h * (y_.row(k + 1) - y_.row(k))).transpose();
}

SmootherData::SmootherData(const io::TraverseLog& log, const est::Trajectory& seed,
                           const SmootherOptions& options)
    : log(log), seed(seed), joints(est::jointSamples(log)) {
  if (seed.nodes.size() != joints.size())
    throw std::invalid_argument(
        "smoother: the seed trajectory needs one node per est::jointSamples entry");
  for (size_t k = 0; k < joints.size(); ++k) {
    if (nodes.empty() || k + 1 == joints.size() ||
        joints[k].t - joints[nodes.back()].t >= options.node_period_s - 1e-9)
      nodes.push_back(k);
  }
  gyro_axes = sensors::GyroAxes::forColumns(log.gyro.values.cols());
  has_cmd = log.cmd.has_value();
  accel_driven = log.accel && options.velocity != SmootherOptions::VelocityModel::kPerturbation;
  if (options.velocity == SmootherOptions::VelocityModel::kAccelDriven && !log.accel)
    throw std::invalid_argument("smoother: the accelerometer-driven model needs accel.csv");
  // K-9 with zero noise would weight the bias steps infinitely: every segment would fail and
  // silently keep the EKF's states. A bias that does not wander is the constant model.
  if (options.bias_model == SmootherOptions::BiasModel::kRandomWalk &&
      !(log.config.gyro.bias_random_walk_rad_s_per_sqrt_s > 0.0)) {
    std::ostringstream what;
    what << "the random-walk bias model needs gyro.bias_random_walk_rad_s_per_sqrt_s > 0 (it is "
         << log.config.gyro.bias_random_walk_rad_s_per_sqrt_s << "); use the constant bias model";
    throw InputError((log.dir / "rover.yaml").string(), 0, what.str());
  }
  gyro_period_s = io::medianPeriod(log.gyro);
  Eigen::MatrixXd g(log.gyro.size(), 3);
  for (Eigen::Index k = 0; k < log.gyro.size(); ++k)
    g.row(k) = gyro_axes.toBody(log.gyro.values.row(k)).transpose();
  gyro = IntegratedSignal(log.gyro.t, g);
  gyro_gaps = io::TimeGaps(log.gyro);
  if (log.accel) {
    accel_gaps = io::TimeGaps(*log.accel);
    accel_period_s = io::medianPeriod(*log.accel);
    accel = IntegratedSignal(log.accel->t, log.accel->values);
  }
  cmd.setZero(static_cast<Eigen::Index>(nodes.size()), 6);
  if (has_cmd) {
    for (size_t n = 0; n < nodes.size(); ++n)
      cmd.row(static_cast<Eigen::Index>(n)) =
          io::interpolateRow(*log.cmd, joints[nodes[n]].t).transpose();
  }
}

namespace {

/// Parameter blocks of one node. Quaternion storage: x, y, z, w.
struct NodeBlocks {
  double q[4], x[3], v[3], w[3], xi[rover::kMaxWheels], b[3];  // ξ: the first numWheels()
  double c[3];  // the wheels' common slip c_x, c_y (, c_ω): the first nc_ (when declared)
};

double seconds(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

/// Builds and owns one segment's problem.
class SegmentBuilder {
 public:
  SegmentBuilder(const SmootherData& d, const SegmentSpec& spec, const SmootherOptions& o)
      : d_(d),
        spec_(spec),
        o_(o),
        cfg_(d.log.config),
        n_(spec.last - spec.first + 1),
        nw_(d.log.geometry.numWheels()),
        nc_(d.log.config.slip_noise.commonSlipStates()),
        na_(d.log.config.accel.hasBias() && d.log.accel ? 3 : 0),
        nk_(d.log.config.estimatesIcr() ? 1 : 0),
        contact_memo_(static_cast<size_t>(nw_)) {
    ceres::Problem::Options po;
    // The builder owns every cost function (residuals_), loss and manifold: a Problem that owns
    // them keeps a hash map of reference counts, one insertion per residual block and a walk
    // over it on destruction — a tenth of the build time for nothing here.
    po.cost_function_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
    po.manifold_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
    po.loss_function_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
    problem_ = std::make_unique<ceres::Problem>(po);
    if (!d.gyro_axes.isThreeAxis())  // hold the bias on the axes nothing observes
      bias_manifold_ = std::make_unique<ceres::SubsetManifold>(3, d.gyro_axes.unmeasured());
    SmootherOptions::Loss loss = o.loss;
    if (loss == SmootherOptions::Loss::kRoverConfig) {
      const std::string name = cfg_.smoother.loss.value_or("huber");
      loss = name == "cauchy" ? SmootherOptions::Loss::kCauchy
             : name == "none" ? SmootherOptions::Loss::kNone
                              : SmootherOptions::Loss::kHuber;
    }
    const double scale = o.loss_scale > 0 ? o.loss_scale : cfg_.smoother.loss_scale.value_or(3.0);
    if (loss == SmootherOptions::Loss::kHuber) loss_ = std::make_unique<ceres::HuberLoss>(scale);
    if (loss == SmootherOptions::Loss::kCauchy) loss_ = std::make_unique<ceres::CauchyLoss>(scale);
    if (o.contact_loss_scale > 0)
      contact_loss_ = std::make_unique<ceres::CauchyLoss>(o.contact_loss_scale);
    // The common slip's steps: Gaussian drift, and the jumps of a slip burst (the EKF's jump
    // test) — a Cauchy tail from 3σ.
    common_slip_loss_ = std::make_unique<ceres::CauchyLoss>(3.0);
    gyro_axes_ = d.gyro_axes.mask();
    seedStates();
    makeHandles();
    markRest();
  }

  SegmentSolution solve();

 private:
  const est::TrajectoryNode& seedNode(size_t k) const {
    return d_.seed.nodes[d_.nodes[spec_.first + k]];
  }
  const rover::JointSample& joint(size_t k) const { return d_.joints[d_.nodes[spec_.first + k]]; }
  double time(size_t k) const { return joint(k).t; }
  bool randomWalkBias() const { return o_.bias_model == SmootherOptions::BiasModel::kRandomWalk; }

  void seedStates();
  /// One handle per parameter block (nodes_, segment_bias_), made once: storage, size,
  /// manifold and chain place.
  void makeHandles();
  void markRest();
  void makeSeedConsistent();
  void addParameterBlocks();
  void addProcessResiduals(size_t k);
  void addSlipResiduals(size_t k);
  void addSunResiduals(size_t k);
  void addRestWindowResiduals();
  void addStartPriors();
  void reportCostByKind();

  const SmootherData& d_;
  const SegmentSpec& spec_;
  const SmootherOptions& o_;
  const io::RoverConfig& cfg_;
  size_t n_;
  int nw_;  ///< wheels
  int nc_;  ///< common slip states per node (0, 2 or 3)
  int na_;  ///< the segment's accelerometer-bias states (0 or 3)
  int nk_;  ///< the segment's ICR half-track error (0 or 1)
  std::vector<NodeBlocks> nodes_;
  double segment_bias_[3] = {0, 0, 0};
  double segment_accel_bias_[3] = {0, 0, 0};  ///< b_a (body, m/s²), one per segment
  double segment_icr_ = 0.0;                  ///< δ (m), one per segment
  std::vector<NodeHandles> handles_;          ///< per node; never resized once made
  std::vector<unsigned char> rest_;           ///< node inside a rest window's trimmed part
  Eigen::Index sun_next_ = 0;                 ///< next sun reading addSunResiduals looks at
  Vec3d gyro_axes_;
  ResidualCollector residuals_;  ///< owns the cost functions: outlives problem_ (declared first)
  /// Every slip residual's numbers, one array (SlipResidual refers to them): reserved for all
  /// nodes before the first is added, so the addresses never move.
  std::vector<SlipWheelData> slip_data_;
  std::unique_ptr<ceres::Problem> problem_;
  BodyQuaternionManifold quaternion_manifold_;
  std::unique_ptr<ceres::Manifold> bias_manifold_;
  std::unique_ptr<ceres::LossFunction> loss_, contact_loss_, common_slip_loss_;
  CostMemo<AttitudeProcessResidual> attitude_memo_;
  CostMemo<PositionProcessResidual> position_memo_;
  CostMemo<MarkovProcess<3>> rate_memo_, velocity_memo_;
  CostMemo<MarkovProcess<2>> common_slip_memo_;
  CostMemo<MarkovProcess<3>> common_slip3_memo_;  ///< with c_ω
  CostMemo<ZeroMotion> zero_velocity_memo_, zero_rate_memo_;
  std::vector<CostMemo<MarkovComponent>> contact_memo_;  ///< one per wheel
  BlockEvaluator evaluator_;
};

void SegmentBuilder::reportCostByKind() {
  std::cerr << "segment " << time(0) << " .. " << time(n_ - 1) << " s (" << n_
            << " nodes), cost by residual:";
  smoother::reportCostByKind(std::cerr, *problem_, residuals_);
  std::cerr << "\n";
}

void SegmentBuilder::seedStates() {
  nodes_.resize(n_);
  for (size_t k = 0; k < n_; ++k) {
    const est::TrajectoryNode& s = seedNode(k);
    NodeBlocks& b = nodes_[k];
    Eigen::Map<Eigen::Vector4d>(b.q) = s.q_site_body.normalized().coeffs();  // x, y, z, w
    Eigen::Map<Vec3d>(b.x) = s.p_site;
    Eigen::Map<Vec3d>(b.v) = s.v_body;
    Eigen::Map<Vec3d>(b.w) = s.w_body;
    std::fill(std::begin(b.xi), std::end(b.xi), 0.0);
    for (int i = 0; i < nw_; ++i) b.xi[i] = s.xi[i];
    Eigen::Map<Vec3d>(b.b) = s.bias;
    Eigen::Map<Vec3d>(b.c) = s.common_slip;
  }
  // Constant bias: the seed's at the segment's middle (the EKF has seen the first rest by then).
  Eigen::Map<Vec3d>{segment_bias_} = seedNode(n_ / 2).bias;
  // The accelerometer's bias: the EKF's at the segment's start (its prior there, addStartPriors).
  Eigen::Map<Vec3d>{segment_accel_bias_} = seedNode(0).accel_bias;
  // The ICRs: the EKF's in the segment's middle (it has seen the segment's first turns).
  segment_icr_ = seedNode(n_ / 2).icr;
}

void SegmentBuilder::makeHandles() {
  using C = NodeColumns;
  ceres::Manifold* bias_manifold = bias_manifold_.get();
  const int bias_dim = bias_manifold ? bias_manifold->TangentSize() : 3;
  const BlockHandle segment_bias{
      segment_bias_, 3, {ChainPlace::kGlobal, 0, bias_dim}, bias_manifold};
  // b_a: global columns after the constant gyro bias (the random-walk bias is on the nodes).
  const BlockHandle accel_bias =
      na_ > 0 ? BlockHandle{segment_accel_bias_,
                            3,
                            {ChainPlace::kGlobal, randomWalkBias() ? 0 : bias_dim, 3},
                            nullptr}
              : BlockHandle{};
  // δ: the last global column.
  const int icr_col = (randomWalkBias() ? 0 : bias_dim) + na_;
  const BlockHandle icr =
      nk_ > 0 ? BlockHandle{&segment_icr_, 1, {ChainPlace::kGlobal, icr_col, 1}, nullptr}
              : BlockHandle{};
  handles_.resize(n_);
  for (size_t k = 0; k < n_; ++k) {
    NodeBlocks& b = nodes_[k];
    const int node = static_cast<int>(k);
    handles_[k] = {
        {b.q, 4, {node, C::kAttitude, 3}, &quaternion_manifold_},
        {b.x, 3, {node, C::kPosition, 3}, nullptr},
        {b.v, 3, {node, C::kVelocity, 3}, nullptr},
        {b.w, 3, {node, C::kRate, 3}, nullptr},
        {b.xi, nw_, {node, C::kContact, nw_}, nullptr},
        randomWalkBias() ? BlockHandle{b.b, 3, {node, C::bias(nw_, nc_), bias_dim}, bias_manifold}
                         : segment_bias,
        nc_ > 0 ? BlockHandle{b.c, nc_, {node, C::commonSlip(nw_), nc_}, nullptr} : BlockHandle{},
        accel_bias,
        icr};
  }
}

void SegmentBuilder::makeSeedConsistent() {
  // The EKF's nodes are snapshots of a filter whose attitude jumps at updates and whose rate
  // carries the gyro's noise: its rates disagree with its own attitude increments, and at rest
  // they are not zero. Seeding the rates from the increments, zero motion at rest, and the
  // positions from the process (K-1) starts Levenberg-Marquardt near the process manifold —
  // fewer iterations, same optimum.
  std::vector<Vec3d> inc(n_ > 0 ? n_ - 1 : 0);
  for (size_t k = 0; k + 1 < n_; ++k) {
    const Quatd qa(Eigen::Map<const Eigen::Vector4d>(nodes_[k].q));
    const Quatd qb(Eigen::Map<const Eigen::Vector4d>(nodes_[k + 1].q));
    inc[k] = so3::boxminus(qb, qa) / (time(k + 1) - time(k));
  }
  for (size_t k = 0; k < n_; ++k) {
    NodeBlocks& b = nodes_[k];
    if (rest_[k]) {
      Eigen::Map<Vec3d>{b.v}.setZero();
      Eigen::Map<Vec3d>{b.w}.setZero();
    } else if (n_ > 1) {
      const Vec3d w = k == 0        ? inc[0]
                      : k + 1 == n_ ? inc[k - 1]
                                    : Vec3d(0.5 * (inc[k - 1] + inc[k]));
      Eigen::Map<Vec3d>{b.w} = w;
    }
  }
  for (size_t k = 0; k + 1 < n_; ++k) {
    NodeBlocks &a = nodes_[k], &b = nodes_[k + 1];
    const Quatd qa(Eigen::Map<const Eigen::Vector4d>(a.q));
    const Quatd qb(Eigen::Map<const Eigen::Vector4d>(b.q));
    const Quatd q_mid = interpolateAttitude(qa, qb, 0.5);
    const Vec3d v_mid = 0.5 * (Eigen::Map<const Vec3d>(a.v) + Eigen::Map<const Vec3d>(b.v));
    Eigen::Map<Vec3d>{b.x} = Eigen::Map<const Vec3d>(a.x) + q_mid * v_mid * (time(k + 1) - time(k));
  }
}

void SegmentBuilder::markRest() {
  rest_.assign(n_, 0);
  if (!o_.use_rest) return;
  for (const est::RestWindow* w : spec_.rests) {
    for (size_t k = 0; k < n_; ++k) {
      const double t = time(k);
      if (t >= w->t_start + o_.rest_margin_s && t <= w->t_end - o_.rest_margin_s) rest_[k] = 1;
    }
  }
}

void SegmentBuilder::addParameterBlocks() {
  const auto add = [&](const BlockHandle& h) {
    problem_->AddParameterBlock(h.data, h.size, h.manifold);
  };
  for (const NodeHandles& h : handles_) {
    add(h.q);
    for (const BlockHandle* b : {&h.x, &h.v, &h.w, &h.xi})
      problem_->AddParameterBlock(b->data, b->size);  // Euclidean
    if (nc_ > 0) problem_->AddParameterBlock(h.c.data, h.c.size);
    if (randomWalkBias()) add(h.bias);
  }
  if (!randomWalkBias()) add(handles_.front().bias);
  if (na_ > 0) add(handles_.front().ba);
  if (nk_ > 0) add(handles_.front().icr);
}

void SegmentBuilder::addProcessResiduals(size_t k) {
  const NodeHandles &a = handles_[k], &b = handles_[k + 1];
  const double t0 = time(k), t1 = time(k + 1), dt = t1 - t0;
  const bool at_rest = rest_[k] && rest_[k + 1];
  const auto& pc = cfg_.process;
  const Eigen::Index i0 = static_cast<Eigen::Index>(spec_.first + k), i1 = i0 + 1;
  // Attitude (K-2/K-7) and position (K-1). Inside a rest window the rover does not move at all:
  // the increments are held to the zero-rate / zero-velocity tolerance over Δt.
  const double q_w = pc.rate_noise_rad_s2_per_sqrt_hz * pc.rate_noise_rad_s2_per_sqrt_hz;
  const Vec3d att_info =
      at_rest ? Vec3d::Constant(1.0 / (o_.zero_rate_sigma_rad_s * dt))
              : AttitudeProcessResidual::sqrtInfo(dt, Vec3d::Constant(q_w), o_.attitude_floor_rad);
  addAttitudeProcess(residuals_, attitude_memo_, dt, att_info, a, b);
  const bool accel = d_.accel_driven && !at_rest && !d_.accel_gaps.overlaps(t0, t1);
  const double q_a = cfg_.accel.noise_mps2 * cfg_.accel.noise_mps2 * d_.accel_period_s;
  const double q_v =
      accel ? q_a : pc.velocity_noise_mps2_per_sqrt_hz * pc.velocity_noise_mps2_per_sqrt_hz;
  const double pos_info = at_rest ? 1.0 / (o_.zero_velocity_sigma_mps * dt)
                                  : PositionProcessResidual::sqrtInfo(dt, q_v, o_.position_floor_m);
  addPositionProcess(residuals_, position_memo_, dt, pos_info, a, b);
  // Rate and velocity perturbations (K-1, K-2): around the command when there is one, random
  // walks otherwise (K §4.2); the velocity driven by the accelerometer instead (O-4).
  addRateProcess(residuals_, rate_memo_, dt, d_.has_cmd ? -1.0 / pc.rate_time_constant_s : 0.0, q_w,
                 d_.cmd.row(i0).tail<3>(), d_.cmd.row(i1).tail<3>(), a, b);
  if (accel) {
    addAccelVelocityProcess(residuals_, dt, d_.accel.integral(t0, t1) / dt, cfg_.accel.lever_arm_m,
                            cfg_.gravity_mps2, q_a, a, b);
  } else {
    addVelocityProcess(residuals_, velocity_memo_, dt,
                       d_.has_cmd ? -1.0 / pc.velocity_time_constant_s : 0.0, q_v,
                       d_.cmd.row(i0).head<3>(), d_.cmd.row(i1).head<3>(), a, b);
  }
  // Contact angles (K-8): per wheel under a heavy-tailed loss, or the Gaussian process.
  addContactProcess(residuals_, contact_memo_, dt, pc.contact_angle_time_constant_s,
                    pc.contact_angle_noise_rad_per_sqrt_s, pc.commonContactAngleNoise(),
                    contact_loss_.get(), a, b);
  // Gyro increments (K-12/K-13 integrated; O-1), except inside rest windows, whose readings
  // the rest-bias residual carries.
  if (!at_rest && !d_.gyro_gaps.overlaps(t0, t1))
    addGyroIncrement(residuals_, dt, d_.gyro.integral(t0, t1), cfg_.gyro.noise_rad_s,
                     d_.gyro_period_s, gyro_axes_, a, b);
  if (randomWalkBias())  // K-9
    addBiasWalk(residuals_, dt, cfg_.gyro.bias_random_walk_rad_s_per_sqrt_s, a, b);
  if (nc_ == 2)
    addCommonSlipProcess(residuals_, common_slip_memo_, dt, cfg_.slip_noise,
                         common_slip_loss_.get(), a, b);
  if (nc_ == 3)
    addCommonSlipProcess(residuals_, common_slip3_memo_, dt, cfg_.slip_noise,
                         common_slip_loss_.get(), a, b);
}

void SegmentBuilder::addSlipResiduals(size_t k) {
  const Eigen::Index row = static_cast<Eigen::Index>(spec_.first + k);
  const est::TrajectoryNode& s = seedNode(k);
  // Without cmd.csv the nominal follows the state (addSlipResiduals linearises it exactly).
  const Twistd nominal_twist =
      d_.has_cmd ? rover::nominalBodyTwist(d_.log.geometry, d_.cmd(row, 0), d_.cmd(row, 5))
                 : Twistd::Zero();
  smoother::addSlipResiduals(residuals_, slip_data_, d_.log.geometry, cfg_.slip_noise, joint(k), s,
                             nominal_twist, loss_.get(), handles_[k], !d_.has_cmd);
}

void SegmentBuilder::addRestWindowResiduals() {
  if (!o_.use_rest) return;
  for (const est::RestWindow* w : spec_.rests) {
    // The window's trimmed nodes [first, last]: their gyro readings give the bias (the gyro
    // increments skip these intervals), the middle node the roll/pitch from gravity.
    size_t first = n_, last = 0;
    for (size_t k = 0; k < n_; ++k) {
      const double t = time(k);
      if (t >= w->t_start + o_.rest_margin_s && t <= w->t_end - o_.rest_margin_s)
        first = std::min(first, k), last = std::max(last, k);
    }
    if (first >= last) continue;
    const double duration = time(last) - time(first);
    const size_t mid = (first + last) / 2;
    addRestBias(residuals_, d_.gyro.integral(time(first), time(last)) / duration,
                cfg_.gyro.noise_rad_s, d_.gyro_period_s, duration, gyro_axes_, handles_[mid]);
    if (w->has_gravity) addGravity(residuals_, w->roll_pitch, handles_[mid], cfg_.gravity_mps2);
  }
}

void SegmentBuilder::addSunResiduals(size_t k) {
  // The readings in [t_k, t_{k+1}) (the last interval closed), between nodes k and k + 1.
  if (!o_.use_sun || !d_.log.sun || k + 1 >= n_) return;
  const io::Stream& sun = *d_.log.sun;
  const sensors::SunSensorGeometry geo{cfg_.sun_sensor.R_body_sensor,
                                       0.5 * cfg_.sun_sensor.field_of_view_rad};
  if (k == 0) {
    const double* begin = sun.t.data();
    sun_next_ = std::lower_bound(begin, begin + sun.size(), time(0)) - begin;
  }
  const double t_end = time(k + 1);
  const bool last = k + 2 == n_;
  for (;
       sun_next_ < sun.size() && (sun.t[sun_next_] < t_end || (last && sun.t[sun_next_] <= t_end));
       ++sun_next_) {
    const Eigen::Index j = sun_next_;
    if (sun.values(j, 2) < 0.5) continue;  // valid = 0
    const double t = sun.t[j];
    const double u = std::clamp((t - time(k)) / (time(k + 1) - time(k)), 0.0, 1.0);
    const Vec3d sun_site = cfg_.sun.directionAt(t);
    const Quatd q_seed = so3::boxplus(
        seedNode(k).q_site_body,
        Vec3d(u * so3::boxminus(seedNode(k + 1).q_site_body, seedNode(k).q_site_body)));
    if (sensors::sunOffBoresight(q_seed, geo, sun_site) > geo.half_fov_rad + 0.1) continue;
    addSunReading(residuals_, u, sun.values.row(j).head<2>().transpose(), sun_site, geo,
                  cfg_.sun_sensor.noise, loss_.get(), handles_[k], handles_[k + 1]);
  }
}

void SegmentBuilder::addStartPriors() {
  const est::TrajectoryNode& s = seedNode(0);
  // The log's first segment: the EKF's first node carries the leading rest's gravity (roll,
  // pitch) and mean sun heading (est::InitialState), which this segment's own gravity and sun
  // residuals count again — so there the prior is widened by 0.1 rad (as without them) along
  // what those residuals measure; the heading stays the gauge without sun. Later segments' first
  // nodes have seen only readings before the segment.
  Mat3d attitude_cov = s.covariance.bottomRightCorner<3, 3>();
  if (spec_.first == 0 && o_.use_rest && !spec_.rests.empty() &&
      spec_.rests.front()->t_start <= time(0) && spec_.rests.front()->t_end > time(0)) {
    const est::RestWindow& w = *spec_.rests.front();
    const double wide = 0.1 * 0.1;
    const Vec3d added(w.has_gravity ? wide : 0.0, w.has_gravity ? wide : 0.0,
                      w.has_sun && o_.use_sun ? wide : 0.0);
    const Mat3d E = so3::eulerRateToBodyRate(s.q_site_body);
    attitude_cov += E * added.asDiagonal() * E.transpose();
  }
  addStartPrior(residuals_, s.q_site_body, s.p_site, o_.start_position_sigma_m, attitude_cov,
                handles_[0]);
  // Contact angles start from the stationary distribution of K-8.
  addContactPrior(residuals_, cfg_.process.contact_angle_time_constant_s,
                  cfg_.process.contact_angle_noise_rad_per_sqrt_s,
                  cfg_.process.commonContactAngleNoise(), handles_[0]);
  if (nc_ > 0) addCommonSlipPrior(residuals_, cfg_.slip_noise, handles_[0]);
  // The gyro bias keeps the EKF's estimate at the first node as a prior: a later segment's
  // first node is the start of its leading rest window, so the EKF has used every reading before
  // the segment and none of it — the prior carries what the earlier rests and sun readings say,
  // independent of this segment's residuals. Not the log's first segment where it has a rest
  // window: the EKF's initial bias is that window's gyro mean (est::initialState), which the
  // segment's rest residual already counts. A constant segment bias stands for the whole leg:
  // its σ grows by the random walk over the segment (as b_a's below). Without rest windows
  // (or with them unused) the prior is there in every segment, as the bias's only anchor. A
  // seed without σ gives no prior where rest windows observe the bias. (overSegment: the σ of a
  // constant that stands for the whole segment, a random walk of density rw over its duration.)
  const double duration = time(n_ - 1) - time(0);
  const auto overSegment = [&](const Vec3d& sigma, double rw) -> Vec3d {
    return (sigma.cwiseProduct(sigma).array() + rw * rw * duration).sqrt().matrix();
  };
  const bool rests_observe_bias = !spec_.rests.empty() && o_.use_rest;
  if (!rests_observe_bias || (spec_.first > 0 && s.bias_sigma.minCoeff() > 0.0)) {
    const double rw = randomWalkBias() ? 0.0 : cfg_.gyro.bias_random_walk_rad_s_per_sqrt_s;
    addBiasPrior(residuals_, s.bias, overSegment(s.bias_sigma, rw), handles_[0]);
  }
  // The accelerometer's bias always does: one rest's gravity cannot tell a tilt of the attitude
  // from a tilt of b_a (both move roll and pitch alike), so without it a segment's b_a would be
  // unobserved wherever the accelerometer does not drive the velocity. Its σ grows by the
  // random walk over the segment (the constant b_a stands for the whole leg).
  if (na_ > 0)
    addAccelBiasPrior(residuals_, s.accel_bias,
                      overSegment(s.accel_bias_sigma, cfg_.accel.bias_random_walk_mps2_per_sqrt_s),
                      handles_[0]);
  // The ICRs likewise: the EKF's δ at the first node has seen the turns before the segment only.
  if (nk_ > 0) {
    const double rw = cfg_.skid_steer->icr_half_track_random_walk_m_per_sqrt_s;
    addIcrPrior(residuals_, s.icr, std::sqrt(s.icr_sigma * s.icr_sigma + rw * rw * duration),
                handles_[0]);
  }
}

SegmentSolution SegmentBuilder::solve() {
  SegmentSolution out;
  SegmentSummary& sum = out.summary;
  const auto t0 = std::chrono::steady_clock::now();
  addParameterBlocks();
  // About 18 residual blocks per moving node (process 10, slip 6, gyro, sun), of which about 9
  // have a cost function of their own (CostMemo shares the rest); reserving keeps the two lists
  // from being copied as they grow (at 10 000 nodes, 170 000 entries).
  residuals_.reserve(18 * n_ + 64, 10 * n_ + 64);
  slip_data_.reserve(static_cast<size_t>(nw_) * n_);
  // Residuals node by node, so that Ceres' Jacobian rows run in time order like its columns
  // (chain ordering): forming JᵀJ and evaluating then sweep memory once, locally, instead of
  // once per kind of residual over the whole problem.
  for (size_t k = 0; k < n_; ++k) {
    if (k + 1 < n_) addProcessResiduals(k);
    if (o_.use_slip) addSlipResiduals(k);
    if (rest_[k])
      addZeroMotion(residuals_, zero_velocity_memo_, zero_rate_memo_, o_.zero_velocity_sigma_mps,
                    o_.zero_rate_sigma_rad_s, handles_[k]);
    addSunResiduals(k);
  }
  addRestWindowResiduals();
  addStartPriors();
  residuals_.addTo(*problem_);
  sum.residual_blocks = problem_->NumResidualBlocks();
  sum.parameters = problem_->NumParameters();
  sum.build_seconds = seconds(t0);

  // Start from the EKF, or from its self-consistent version when that costs less; seed_cost is
  // the cost of the EKF's own states, the bound the solution must beat.
  const auto ts = std::chrono::steady_clock::now();
  sum.seed_cost = residuals_.cost(evaluator_);
  const std::vector<NodeBlocks> ekf_states = nodes_;
  makeSeedConsistent();
  if (!(residuals_.cost(evaluator_) <= sum.seed_cost)) nodes_ = ekf_states;
  sum.seed_seconds = seconds(ts);
  if (o_.solver_report) reportCostByKind();
  const ceres::Solver::Summary summary =
      solveSegmentProblem(*problem_, segmentSolverOptions(o_, handles_), t0, sum);
  if (o_.solver_report) {
    std::cerr << summary.FullReport() << "\nproblem built in " << sum.build_seconds << " s\n";
    reportCostByKind();
  }

  bool finite = std::isfinite(summary.final_cost);
  for (const NodeBlocks& b : nodes_) {
    for (double v : b.q) finite = finite && std::isfinite(v);
    for (double v : b.x) finite = finite && std::isfinite(v);
  }
  std::string why;
  sum.status = segmentStatus(summary, finite, &why);
  if (!why.empty()) sum.message = why;
  if (sum.status == SegmentStatus::kFallbackEkf)
    sum.final_cost = sum.seed_cost;  // the EKF's states stay

  out.nodes.resize(n_);
  for (size_t k = 0; k < n_; ++k) {
    est::TrajectoryNode& node = out.nodes[k];
    if (sum.status == SegmentStatus::kFallbackEkf) {
      node = seedNode(k);
      continue;
    }
    const NodeBlocks& b = nodes_[k];
    node.t = time(k);
    node.q_site_body = Quatd(Eigen::Map<const Eigen::Vector4d>(b.q)).normalized();
    node.p_site = Eigen::Map<const Vec3d>(b.x);
    node.v_body = Eigen::Map<const Vec3d>(b.v);
    node.w_body = Eigen::Map<const Vec3d>(b.w);
    node.xi = Eigen::Map<const rover::WheelVectord>(b.xi, nw_);
    node.bias = Eigen::Map<const Vec3d>(randomWalkBias() ? b.b : segment_bias_);
    if (nc_ > 0) node.common_slip.head(nc_) = Eigen::Map<const Eigen::VectorXd>(b.c, nc_);
    if (na_ > 0) node.accel_bias = Eigen::Map<const Vec3d>(segment_accel_bias_);
    if (nk_ > 0) node.icr = segment_icr_;
  }
  if (sum.status != SegmentStatus::kFallbackEkf && o_.covariance) {
    const auto tc = std::chrono::steady_clock::now();
    // Bias axes in the tangent: all three, or z only (heading-only gyro, x and y held).
    const std::vector<int> axes = bias_manifold_ ? std::vector<int>{2} : std::vector<int>{0, 1, 2};
    out.has_covariance = segmentCovariance(residuals_, handles_, axes, evaluator_, out.nodes);
    sum.covariance_seconds = seconds(tc);
  }
  if (sum.status == SegmentStatus::kFallbackEkf) out.has_covariance = true;  // the EKF's
  const est::TrajectoryNode& mid = out.nodes[n_ / 2];
  out.bias = mid.bias, out.bias_sigma = mid.bias_sigma;
  sum.num_nodes = n_;
  sum.t_start = time(0), sum.t_end = time(n_ - 1);
  return out;
}

}  // namespace

SegmentSolution solveSegment(const SmootherData& data, const SegmentSpec& spec,
                             const SmootherOptions& options) {
  if (spec.last <= spec.first || spec.last >= data.nodes.size())
    throw std::invalid_argument("smoother: a segment needs at least two nodes");
  try {
    SegmentBuilder builder(data, spec, options);
    return builder.solve();
  } catch (const std::runtime_error& e) {
    // A segment that cannot even be set up (bad input, or numbers the data make impossible: a
    // zero noise in rover.yaml makes a weight infinite) keeps the EKF's states; the rest of the
    // log goes on. A std::logic_error is a bug and surfaces.
    SegmentSolution out;
    for (size_t k = spec.first; k <= spec.last; ++k)
      out.nodes.push_back(data.seed.nodes[data.nodes[k]]);
    out.has_covariance = data.seed.has_covariance;
    SegmentSummary& sum = out.summary;
    sum.status = SegmentStatus::kFallbackEkf;
    sum.message = e.what();
    sum.num_nodes = out.nodes.size();
    sum.t_start = out.nodes.front().t, sum.t_end = out.nodes.back().t;
    const est::TrajectoryNode& mid = out.nodes[out.nodes.size() / 2];
    out.bias = mid.bias, out.bias_sigma = mid.bias_sigma;
    return out;
  }
}

}  // namespace traverse::smoother
