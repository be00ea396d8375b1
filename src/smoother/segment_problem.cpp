// One smoother segment: build the Ceres problem from the log and the EKF seed, solve it, and
// read the marginal covariances (include/traverse/smoother/segment_problem.h).
#include "traverse/smoother/segment_problem.h"

#include <array>
#include <chrono>
#include <cmath>
#include <iostream>
#include <limits>
#include <map>
#include <memory>
#include <span>
#include <sstream>
#include <stdexcept>

#include <ceres/ceres.h>

#include "traverse/core/error.h"
#include "traverse/rover/nominal_slip.h"
#include "traverse/smoother/block_evaluation.h"
#include "traverse/smoother/body_quaternion_manifold.h"
#include "traverse/smoother/chain_marginals.h"
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
#include "traverse/smoother/residuals/whitening.h"
#include "traverse/smoother/residuals/zero_motion_residual.h"

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
    throw std::invalid_argument("smoother: the seed trajectory needs one node per joint sample");
  for (size_t k = 0; k < joints.size(); ++k) {
    if (nodes.empty() || k + 1 == joints.size() ||
        joints[k].t - joints[nodes.back()].t >= options.node_period_s - 1e-9)
      nodes.push_back(k);
  }
  three_axis_gyro = log.gyro.values.cols() == 3;
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
  Eigen::MatrixXd g = Eigen::MatrixXd::Zero(log.gyro.size(), 3);
  if (three_axis_gyro)
    g = log.gyro.values;
  else
    g.col(2) = log.gyro.values.col(0);
  gyro = IntegratedSignal(log.gyro.t, g);
  if (log.accel) {
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
  double q[4], x[3], v[3], w[3], xi[6], b[3];
};

/// Most parameter blocks any residual here takes (the position and accelerometer processes).
constexpr int kMaxBlocksPerResidual = 6;

/// One residual block as added: its id, cost function, loss, and parameter blocks with their
/// manifolds (nullptr: Euclidean), in the cost function's order.
struct ResidualEntry {
  ceres::ResidualBlockId id = nullptr;  ///< set once every entry is made (addToProblem)
  const char* kind = nullptr;           ///< for the solver report's cost by kind
  ceres::CostFunction* f = nullptr;
  ceres::LossFunction* loss = nullptr;
  int num_rows = 0, num_blocks = 0;
  std::array<double*, kMaxBlocksPerResidual> blocks{};
  std::array<const ceres::Manifold*, kMaxBlocksPerResidual> manifolds{};
  std::span<double* const> parameterBlocks() const {
    return {blocks.data(), static_cast<size_t>(num_blocks)};
  }
  std::span<const ceres::Manifold* const> blockManifolds() const {
    return {manifolds.data(), static_cast<size_t>(num_blocks)};
  }
};

/// The last cost function made for one kind of residual and the numbers that define it. Nodes are
/// mostly equally spaced, so consecutive process residuals (attitude, position, rate, contact,
/// zero motion) are often the same function of their parameter blocks: one cost function then
/// serves every such residual block (Ceres evaluates a cost function for any number of them),
/// which saves an allocation, a free and its cache lines per node. Any change of a defining
/// number (Δt, a weight, a command) makes a new one.
struct CostMemo {
  static constexpr size_t kMaxKey = 12;
  std::array<double, kMaxKey> key{};
  size_t size = 0;
  ceres::CostFunction* f = nullptr;
  bool matches(std::span<const double> k) const {
    return f != nullptr && k.size() == size && std::equal(k.begin(), k.end(), key.begin());
  }
};

double seconds(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

/// Builds and owns one segment's problem.
class SegmentBuilder {
 public:
  SegmentBuilder(const SmootherData& d, const SegmentSpec& spec, const SmootherOptions& o)
      : d_(d), spec_(spec), o_(o), cfg_(d.log.config), n_(spec.last - spec.first + 1) {
    ceres::Problem::Options po;
    // The builder owns every cost function, loss and manifold (costs_, loss_, the manifolds):
    // a Problem that owns them keeps a hash map of reference counts, one insertion per residual
    // block and a walk over it on destruction — a tenth of the build time for nothing here.
    po.cost_function_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
    po.manifold_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
    po.loss_function_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
    problem_ = std::make_unique<ceres::Problem>(po);
    if (!d.three_axis_gyro)
      bias_manifold_ = std::make_unique<ceres::SubsetManifold>(3, std::vector<int>{0, 1});
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
    gyro_axes_ = d.three_axis_gyro ? Vec3d::Ones() : Vec3d(0, 0, 1);
    seedStates();
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
  double* bias(size_t k) { return randomWalkBias() ? nodes_[k].b : segment_bias_; }

  /// Records a residual block with a new cost function, which the builder then owns (Ceres gets
  /// the blocks in addToProblem).
  template <typename... Blocks>
  void add(const char* kind, ceres::CostFunction* f, ceres::LossFunction* loss, Blocks*... blocks) {
    costs_.emplace_back(f);
    addBlock(kind, f, loss, blocks...);
  }
  /// Records a residual block whose cost function is make() — or the memo's, when `key` (the
  /// numbers that define it) equals the one it was made with (CostMemo).
  template <typename Make, typename... Blocks>
  void addShared(const char* kind, CostMemo& memo, std::initializer_list<double> key, Make make,
                 ceres::LossFunction* loss, Blocks*... blocks) {
    const std::span<const double> k(key.begin(), key.size());
    if (!memo.matches(k)) {
      if (k.size() > CostMemo::kMaxKey) throw std::logic_error("smoother: cost memo key too long");
      std::copy(k.begin(), k.end(), memo.key.begin());
      memo.size = k.size();
      memo.f = make();
      costs_.emplace_back(memo.f);
    }
    addBlock(kind, memo.f, loss, blocks...);
  }
  template <typename... Blocks>
  void addBlock(const char* kind, ceres::CostFunction* f, ceres::LossFunction* loss,
                Blocks*... blocks) {
    static_assert(sizeof...(Blocks) <= kMaxBlocksPerResidual);
    residuals_.push_back({nullptr,
                          kind,
                          f,
                          loss,
                          f->num_residuals(),
                          static_cast<int>(sizeof...(Blocks)),
                          {blocks...},
                          {manifoldOf(blocks)...}});
  }
  void addToProblem();
  /// The manifold a parameter block was added with (nullptr: Euclidean).
  const ceres::Manifold* manifoldOf(const double* block) const {
    if (block == segment_bias_) return bias_manifold_.get();
    const smoother::ChainPlace p = place(block);
    if (p.col == 0) return &quaternion_manifold_;
    if (p.col == 18) return bias_manifold_.get();
    return nullptr;
  }
  void reportCostByKind() const;
  /// ½ Σ ρ(‖r‖²) at the current states, block by block (BlockEvaluator): Problem::Evaluate
  /// would first build a whole evaluation program (offsets, scratch, a state vector) for one
  /// number.
  double cost();
  /// Column place of a parameter block in the chain information (smoother::ChainPlace).
  smoother::ChainPlace place(const double* block) const;
  void seedStates();
  void markRest();
  void makeSeedConsistent();
  void addParameterBlocks();
  void addProcessResiduals(size_t k);
  void addSlipResiduals(size_t k);
  void addZeroMotionResiduals(size_t k);
  void addRestWindowResiduals();
  void addSunResiduals(size_t k);
  void addStartPrior();
  bool computeCovariance(SegmentSolution* out);

  const SmootherData& d_;
  const SegmentSpec& spec_;
  const SmootherOptions& o_;
  const io::RoverConfig& cfg_;
  size_t n_;
  std::vector<NodeBlocks> nodes_;
  double segment_bias_[3] = {0, 0, 0};
  std::vector<unsigned char> rest_;  ///< node inside a rest window's trimmed part
  Eigen::Index sun_next_ = 0;        ///< next sun reading addSunResiduals looks at
  Vec3d gyro_axes_;
  std::vector<std::unique_ptr<ceres::CostFunction>> costs_;  ///< outlive problem_ (declared first)
  std::vector<ResidualEntry> residuals_;
  /// Every slip residual's numbers, one array (SlipResidual refers to them): reserved for all
  /// nodes before the first is added, so the addresses never move.
  std::vector<SlipWheelData> slip_data_;
  std::unique_ptr<ceres::Problem> problem_;
  BodyQuaternionManifold quaternion_manifold_;
  std::unique_ptr<ceres::Manifold> bias_manifold_;
  std::unique_ptr<ceres::LossFunction> loss_, contact_loss_;
  std::map<std::string, std::vector<ceres::ResidualBlockId>> by_kind_;
  CostMemo attitude_memo_, position_memo_, rate_memo_, velocity_memo_, zero_velocity_memo_,
      zero_rate_memo_;
  std::array<CostMemo, rover::kNumWheels> contact_memo_;
  BlockEvaluator evaluator_;
};

void SegmentBuilder::addToProblem() {
  // Every cost function exists before the first residual block: Ceres' blocks (a ResidualBlock
  // and its parameter-block array each) then lie one after the other in memory, in the order
  // every pass of its preprocessing, evaluation and teardown walks them, instead of interleaved
  // with the cost functions. At 10 000 nodes those walks run from memory, not cache, and the
  // interleaving made them — and freeing the blocks — grow faster than the node count.
  for (ResidualEntry& e : residuals_) {
    e.id = problem_->AddResidualBlock(e.f, e.loss, e.blocks.data(), e.num_blocks);
    if (o_.solver_report) by_kind_[e.kind].push_back(e.id);
  }
}

double SegmentBuilder::cost() {
  double total = 0.0;
  for (const ResidualEntry& e : residuals_) {
    double c = 0.0;
    if (!evaluator_.evaluate(*e.f, e.loss, e.parameterBlocks(), e.blockManifolds(), &c, nullptr,
                             nullptr))
      return std::numeric_limits<double>::quiet_NaN();
    total += c;
  }
  return total;
}

smoother::ChainPlace SegmentBuilder::place(const double* block) const {
  const int bias_dim = bias_manifold_ ? bias_manifold_->TangentSize() : 3;
  if (block == segment_bias_) return {smoother::ChainPlace::kGlobal, 0, bias_dim};
  // Node k's blocks live in nodes_[k]; find k from the address, then the member.
  const auto offset =
      reinterpret_cast<const char*>(block) - reinterpret_cast<const char*>(nodes_.data());
  const auto k = static_cast<size_t>(offset) / sizeof(NodeBlocks);
  if (offset < 0 || k >= nodes_.size())
    throw std::logic_error("smoother: a residual refers to a parameter block of no node");
  const NodeBlocks& b = nodes_[k];
  const int node = static_cast<int>(k);
  // Tangent order per node: δθ (3), x, v, ω, ξ [, b]; the segment bias is the global block.
  if (block == b.q) return {node, 0, 3};
  if (block == b.x) return {node, 3, 3};
  if (block == b.v) return {node, 6, 3};
  if (block == b.w) return {node, 9, 3};
  if (block == b.xi) return {node, 12, 6};
  if (block == b.b) return {node, 18, bias_dim};
  throw std::logic_error("smoother: a residual refers to an unknown member of a node");
}

/// Cost ½ Σ ρ(‖r‖²) of each kind of residual at the current states (solver_report only).
void SegmentBuilder::reportCostByKind() const {
  std::cerr << "segment " << time(0) << " .. " << time(n_ - 1) << " s (" << n_
            << " nodes), cost by residual:";
  for (const auto& [kind, ids] : by_kind_) {
    ceres::Problem::EvaluateOptions eo;
    eo.residual_blocks = ids;
    double cost = 0.0;
    problem_->Evaluate(eo, &cost, nullptr, nullptr, nullptr);
    std::cerr << " " << kind << " " << cost << " (" << ids.size() << ")";
  }
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
    for (int i = 0; i < 6; ++i) b.xi[i] = s.xi[static_cast<size_t>(i)];
    Eigen::Map<Vec3d>(b.b) = s.bias;
  }
  // Constant bias: the seed's at the segment's middle (the EKF has seen the first rest by then).
  Eigen::Map<Vec3d>{segment_bias_} = seedNode(n_ / 2).bias;
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
  for (size_t k = 0; k < n_; ++k) {
    NodeBlocks& b = nodes_[k];
    problem_->AddParameterBlock(b.q, 4, &quaternion_manifold_);
    problem_->AddParameterBlock(b.x, 3);
    problem_->AddParameterBlock(b.v, 3);
    problem_->AddParameterBlock(b.w, 3);
    problem_->AddParameterBlock(b.xi, 6);
    if (randomWalkBias()) problem_->AddParameterBlock(b.b, 3, bias_manifold_.get());
  }
  if (!randomWalkBias()) problem_->AddParameterBlock(segment_bias_, 3, bias_manifold_.get());
}

void SegmentBuilder::addProcessResiduals(size_t k) {
  NodeBlocks &a = nodes_[k], &b = nodes_[k + 1];
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
  addShared(
      "attitude", attitude_memo_, {dt, att_info[0], att_info[1], att_info[2]},
      [&] { return AttitudeProcessResidual::Create(dt, att_info); }, nullptr, a.q, b.q, a.w, b.w);
  const bool accel = d_.accel_driven && !at_rest;
  const double q_a = cfg_.accel.noise_mps2 * cfg_.accel.noise_mps2 * d_.accel_period_s;
  const double q_v =
      accel ? q_a : pc.velocity_noise_mps2_per_sqrt_hz * pc.velocity_noise_mps2_per_sqrt_hz;
  const double pos_info = at_rest ? 1.0 / (o_.zero_velocity_sigma_mps * dt)
                                  : PositionProcessResidual::sqrtInfo(dt, q_v, o_.position_floor_m);
  addShared(
      "position", position_memo_, {dt, pos_info},
      [&] { return PositionProcessResidual::Create(dt, pos_info); }, nullptr, a.x, b.x, a.q, b.q,
      a.v, b.v);
  // Rate and velocity perturbations (K-1, K-2): around the command when there is one, random
  // walks otherwise (K §4.2); the velocity driven by the accelerometer instead (O-4).
  const Vec3d a_w = Vec3d::Constant(d_.has_cmd ? -1.0 / pc.rate_time_constant_s : 0.0);
  const Vec3d w0 = d_.cmd.row(i0).tail<3>(), w1 = d_.cmd.row(i1).tail<3>();
  addShared(
      "rate", rate_memo_, {dt, a_w[0], q_w, w0[0], w0[1], w0[2], w1[0], w1[1], w1[2]},
      [&] { return new MarkovProcessResidual<3>(dt, a_w, Vec3d::Constant(q_w), w0, w1); }, nullptr,
      a.w, b.w);
  if (accel) {
    const Vec3d mean_accel = d_.accel.integral(t0, t1) / dt;
    add("accel_velocity",
        AccelVelocityProcessResidual::Create(dt, mean_accel, cfg_.accel.lever_arm_m,
                                             cfg_.gravity_mps2, 1.0 / std::sqrt(q_a * dt + 1e-12)),
        nullptr, a.q, b.q, a.v, b.v, a.w, b.w);
  } else {
    const Vec3d a_v = Vec3d::Constant(d_.has_cmd ? -1.0 / pc.velocity_time_constant_s : 0.0);
    const Vec3d v0 = d_.cmd.row(i0).head<3>(), v1 = d_.cmd.row(i1).head<3>();
    addShared(
        "velocity", velocity_memo_, {dt, a_v[0], q_v, v0[0], v0[1], v0[2], v1[0], v1[1], v1[2]},
        [&] { return new MarkovProcessResidual<3>(dt, a_v, Vec3d::Constant(q_v), v0, v1); },
        nullptr, a.v, b.v);
  }
  // Contact angles (K-8).
  const double n_xi = pc.contact_angle_noise_rad_per_sqrt_s;
  using Vec6 = Eigen::Matrix<double, 6, 1>;
  if (contact_loss_) {  // per wheel, heavy-tailed (SmootherOptions::contact_loss_scale)
    const double a_xi = -1.0 / pc.contact_angle_time_constant_s;
    for (int i = 0; i < rover::kNumWheels; ++i)
      addShared(
          "contact", contact_memo_[static_cast<size_t>(i)], {dt, a_xi, n_xi},
          [&] { return new MarkovComponentResidual<6>(i, dt, a_xi, n_xi * n_xi); },
          contact_loss_.get(), a.xi, b.xi);
  } else {
    add("contact",
        new MarkovProcessResidual<6>(dt, Vec6::Constant(-1.0 / pc.contact_angle_time_constant_s),
                                     Vec6::Constant(n_xi * n_xi), Vec6::Zero(), Vec6::Zero()),
        nullptr, a.xi, b.xi);
  }
  // Gyro increments (K-12/K-13 integrated; O-1), except inside rest windows, whose readings
  // the rest-bias residual carries.
  if (!at_rest) {
    const double sigma = cfg_.gyro.noise_rad_s * std::sqrt(d_.gyro_period_s * dt);
    add("gyro", GyroIncrementResidual::Create(dt, d_.gyro.integral(t0, t1), gyro_axes_ / sigma),
        nullptr, a.q, b.q, bias(k));
  }
  if (randomWalkBias()) {  // K-9
    const double s = cfg_.gyro.bias_random_walk_rad_s_per_sqrt_s;
    add("bias_walk",
        new MarkovProcessResidual<3>(dt, Vec3d::Zero(), Vec3d::Constant(s * s), Vec3d::Zero(),
                                     Vec3d::Zero()),
        nullptr, a.b, b.b);
  }
}

void SegmentBuilder::addSlipResiduals(size_t k) {
  const rover::JointSample& js = joint(k);
  NodeBlocks& b = nodes_[k];
  const Eigen::Index row = static_cast<Eigen::Index>(spec_.first + k);
  const est::TrajectoryNode& s = seedNode(k);
  const Twistd nominal_twist =
      d_.has_cmd ? rover::nominalBodyTwist(d_.log.geometry, d_.cmd(row, 0), d_.cmd(row, 5))
                 : rover::nominalBodyTwist(d_.log.geometry, s.v_body.x(), s.w_body.z());
  for (int i = 0; i < rover::kNumWheels; ++i) {
    const double radius = d_.log.geometry.wheels[i].radius;
    Eigen::Matrix<double, 4, 7> J;
    rover::slipConstraintWithJacobian(js.T_body_wheel[i], radius, js.joint_twist[i], s.v_body,
                                      s.w_body, s.xi[static_cast<size_t>(i)], &J);
    const Eigen::Matrix4d R =
        rover::slipCovariance(cfg_.slip_noise, js, i, s.v_body, s.w_body, J.leftCols<6>());
    const Vec4d nominal =
        rover::nominalSlip(js.T_body_wheel[i], radius, nominal_twist, js.joint_twist[i]);
    if (slip_data_.size() == slip_data_.capacity())
      throw std::logic_error("smoother: slip data would move under its cost functions");
    slip_data_.push_back(
        {js.T_body_wheel[i], radius, js.joint_twist[i], nominal, sqrtInformation<4>(R, "slip")});
    add("slip", new SlipResidual(i, &slip_data_.back()), loss_.get(), b.v, b.w, b.xi);
  }
}

void SegmentBuilder::addZeroMotionResiduals(size_t k) {
  if (!rest_[k]) return;
  addShared(
      "zero_velocity", zero_velocity_memo_, {o_.zero_velocity_sigma_mps},
      [&] { return new ZeroMotionResidual(o_.zero_velocity_sigma_mps); }, nullptr, nodes_[k].v);
  addShared(
      "zero_rate", zero_rate_memo_, {o_.zero_rate_sigma_rad_s},
      [&] { return new ZeroMotionResidual(o_.zero_rate_sigma_rad_s); }, nullptr, nodes_[k].w);
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
    const Vec3d mean = d_.gyro.integral(time(first), time(last)) / duration;
    const double sigma = cfg_.gyro.noise_rad_s * std::sqrt(d_.gyro_period_s / duration);
    const size_t mid = (first + last) / 2;
    add("rest_bias", new RestBiasResidual(mean, gyro_axes_ / sigma), nullptr, bias(mid));
    if (w->has_gravity) {
      add("gravity",
          GravityResidual::Create(w->roll_pitch.roll_pitch,
                                  sqrtInformation<2>(w->roll_pitch.covariance, "gravity")),
          nullptr, nodes_[mid].q);
    }
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
    add("sun",
        SunSensorResidual::Create(u, sun.values.row(j).head<2>().transpose(), sun_site, geo,
                                  1.0 / cfg_.sun_sensor.noise),
        loss_.get(), nodes_[k].q, nodes_[k + 1].q);
  }
}

void SegmentBuilder::addStartPrior() {
  const est::TrajectoryNode& s = seedNode(0);
  Mat6d cov = Mat6d::Zero();
  cov.topLeftCorner<3, 3>() =
      Mat3d::Identity() * o_.start_position_sigma_m * o_.start_position_sigma_m;
  cov.bottomRightCorner<3, 3>() = s.covariance.bottomRightCorner<3, 3>();
  cov.bottomRightCorner<3, 3>().diagonal().array() += 1e-12;
  add("start_prior",
      StartPriorResidual::Create(s.q_site_body, s.p_site, sqrtInformation<6>(cov, "start prior")),
      nullptr, nodes_[0].q, nodes_[0].x);
  // Contact angles start from the stationary distribution of K-8: ξ ~ N(0, n_ξ² τ / 2).
  const auto& pc = cfg_.process;
  const double sigma_xi =
      pc.contact_angle_noise_rad_per_sqrt_s * std::sqrt(0.5 * pc.contact_angle_time_constant_s);
  using Vec6 = Eigen::Matrix<double, 6, 1>;
  add("contact_prior", new StationaryPriorResidual<6>(Vec6::Constant(sigma_xi)), nullptr,
      nodes_[0].xi);
  // Without a rest window the bias keeps the EKF's estimate as a prior.
  if (spec_.rests.empty() || !o_.use_rest) {
    const Vec3d sigma = s.bias_sigma.cwiseMax(1e-6);
    add("bias_prior", new RestBiasResidual(s.bias, sigma.cwiseInverse()), nullptr, bias(0));
  }
}

}  // namespace

namespace {

bool SegmentBuilder::computeCovariance(SegmentSolution* out) {
  // H = JᵀJ at the solution (robust losses applied as in the solver), accumulated residual block
  // by residual block straight into the chain's blocks: no global Jacobian is ever formed (with
  // Problem::Evaluate it was built as a CRS matrix, then copied — two thirds of the covariance
  // time at 10 000 nodes).
  const int bias_dim = bias_manifold_ ? bias_manifold_->TangentSize() : 3;
  const int node_dim = 18 + (randomWalkBias() ? bias_dim : 0);
  const int global_dim = randomWalkBias() ? 0 : bias_dim;
  smoother::ChainInformation H =
      smoother::makeChainInformation(static_cast<int>(n_), node_dim, global_dim);
  std::vector<double> jacobian;
  std::array<smoother::ChainPlace, kMaxBlocksPerResidual> places;
  std::array<double*, kMaxBlocksPerResidual> jacobians{};
  for (const ResidualEntry& e : residuals_) {
    int cols = 0;
    for (int i = 0; i < e.num_blocks; ++i) {
      places[static_cast<size_t>(i)] = place(e.blocks[static_cast<size_t>(i)]);
      cols += places[static_cast<size_t>(i)].size;
    }
    jacobian.resize(static_cast<size_t>(e.num_rows * cols));
    for (int i = 0, c = 0; i < e.num_blocks; c += places[static_cast<size_t>(i)].size, ++i)
      jacobians[static_cast<size_t>(i)] = jacobian.data() + static_cast<ptrdiff_t>(e.num_rows * c);
    if (!evaluator_.evaluate(*e.f, e.loss, e.parameterBlocks(), e.blockManifolds(), nullptr,
                             nullptr, jacobians.data()))
      return false;
    smoother::addChainResidual(H, std::span(places.data(), static_cast<size_t>(e.num_blocks)),
                               jacobians.data(), e.num_rows);
  }
  const smoother::ChainMarginals m = smoother::chainMarginals(H);
  if (!m.ok) return false;
  // Bias axes in the tangent: all three, or z only (heading-only gyro, x and y held).
  const std::vector<int> axes = bias_manifold_ ? std::vector<int>{2} : std::vector<int>{0, 1, 2};
  for (size_t k = 0; k < n_; ++k) {
    const Eigen::MatrixXd& S = m.node[k];
    est::TrajectoryNode& node = out->nodes[k];
    node.covariance.topLeftCorner<3, 3>() = S.block<3, 3>(3, 3);
    node.covariance.bottomRightCorner<3, 3>() = S.block<3, 3>(0, 0);
    node.covariance.topRightCorner<3, 3>() = S.block<3, 3>(3, 0);
    node.covariance.bottomLeftCorner<3, 3>() = S.block<3, 3>(0, 3);
    node.bias_sigma.setZero();
    for (size_t a = 0; a < axes.size(); ++a) {
      const double var = randomWalkBias() ? S(18 + static_cast<int>(a), 18 + static_cast<int>(a))
                                          : m.global(static_cast<int>(a), static_cast<int>(a));
      node.bias_sigma[axes[a]] = std::sqrt(std::max(var, 0.0));
    }
  }
  return true;
}

SegmentSolution SegmentBuilder::solve() {
  SegmentSolution out;
  SegmentSummary& sum = out.summary;
  const auto t0 = std::chrono::steady_clock::now();
  addParameterBlocks();
  // About 18 residual blocks per moving node (process 10, slip 6, gyro, sun), of which about 9
  // have a cost function of their own (CostMemo shares the rest); reserving keeps the two lists
  // from being copied as they grow (at 10 000 nodes, 170 000 entries).
  residuals_.reserve(18 * n_ + 64);
  costs_.reserve(10 * n_ + 64);
  slip_data_.reserve(rover::kNumWheels * n_);
  // Residuals node by node, so that Ceres' Jacobian rows run in time order like its columns
  // (chain ordering): forming JᵀJ and evaluating then sweep memory once, locally, instead of
  // once per kind of residual over the whole problem.
  for (size_t k = 0; k < n_; ++k) {
    if (k + 1 < n_) addProcessResiduals(k);
    if (o_.use_slip) addSlipResiduals(k);
    addZeroMotionResiduals(k);
    addSunResiduals(k);
  }
  addRestWindowResiduals();
  addStartPrior();
  addToProblem();
  sum.residual_blocks = problem_->NumResidualBlocks();
  sum.parameters = problem_->NumParameters();
  sum.build_seconds = seconds(t0);

  // Start from the EKF, or from its self-consistent version when that costs less; seed_cost is
  // the cost of the EKF's own states, the bound the solution must beat.
  const auto ts = std::chrono::steady_clock::now();
  sum.seed_cost = cost();
  const std::vector<NodeBlocks> ekf_states = nodes_;
  makeSeedConsistent();
  if (!(cost() <= sum.seed_cost)) nodes_ = ekf_states;
  sum.seed_seconds = seconds(ts);
  if (o_.solver_report) reportCostByKind();
  ceres::Solver::Options so;
  so.minimizer_type = ceres::TRUST_REGION;
  so.trust_region_strategy_type = ceres::LEVENBERG_MARQUARDT;
  so.linear_solver_type = ceres::SPARSE_NORMAL_CHOLESKY;
  so.sparse_linear_algebra_library_type = ceres::SUITE_SPARSE;
  so.max_num_iterations = o_.max_iterations;
  so.function_tolerance = o_.function_tolerance;
  so.gradient_tolerance = o_.gradient_tolerance;
  so.parameter_tolerance = o_.parameter_tolerance;
  so.num_threads = 1;  // segments run in parallel; one thread each keeps results reproducible
  so.logging_type = o_.solver_report ? ceres::PER_MINIMIZER_ITERATION : ceres::SILENT;
  so.minimizer_progress_to_stdout = o_.solver_report;
  so.initial_trust_region_radius = o_.initial_trust_region_radius;
  if (o_.chain_ordering) {
    // Eliminate node by node in time order, the segment bias last: the normal equations are a
    // band (each residual ties nodes k and k+1) with one dense border, so this order has no
    // fill outside the band and keeps the factor's memory local — AMD on the whole problem
    // scatters a chain and grows worse than linearly with its length.
    auto ordering = std::make_shared<ceres::ParameterBlockOrdering>();
    for (size_t k = 0; k < n_; ++k) {
      NodeBlocks& b = nodes_[k];
      for (double* p : {b.q, b.x, b.v, b.w, b.xi})
        ordering->AddElementToGroup(p, static_cast<int>(k));
      if (randomWalkBias()) ordering->AddElementToGroup(b.b, static_cast<int>(k));
    }
    if (!randomWalkBias()) ordering->AddElementToGroup(segment_bias_, static_cast<int>(n_));
    so.linear_solver_ordering = ordering;
  }
  ceres::Solver::Summary summary;
  ceres::Solve(so, problem_.get(), &summary);
  sum.solve_seconds = seconds(t0);
  sum.ceres_preprocess_seconds = summary.preprocessor_time_in_seconds;
  sum.ceres_minimizer_seconds = summary.minimizer_time_in_seconds;
  sum.ceres_jacobian_seconds = summary.jacobian_evaluation_time_in_seconds;
  sum.ceres_residual_seconds = summary.residual_evaluation_time_in_seconds;
  sum.ceres_linear_solver_seconds = summary.linear_solver_time_in_seconds;
  if (o_.solver_report) {
    std::cerr << summary.FullReport() << "\nproblem built in " << sum.build_seconds << " s\n";
    reportCostByKind();
  }
  sum.iterations = std::max(0, static_cast<int>(summary.iterations.size()) - 1);
  sum.initial_cost = summary.initial_cost;
  sum.final_cost = summary.final_cost;
  sum.message = summary.message;

  bool finite = std::isfinite(summary.final_cost);
  for (const NodeBlocks& b : nodes_) {
    for (double v : b.q) finite = finite && std::isfinite(v);
    for (double v : b.x) finite = finite && std::isfinite(v);
  }
  if (summary.termination_type == ceres::CONVERGENCE && finite)
    sum.status = SegmentStatus::kConverged;
  else if (summary.termination_type == ceres::NO_CONVERGENCE && finite &&
           summary.final_cost <= summary.initial_cost)
    sum.status = SegmentStatus::kNoConvergence;
  else
    sum.status = SegmentStatus::kFallbackEkf;
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
    for (int i = 0; i < 6; ++i) node.xi[static_cast<size_t>(i)] = b.xi[i];
    node.bias = Eigen::Map<const Vec3d>(randomWalkBias() ? b.b : segment_bias_);
  }
  if (sum.status != SegmentStatus::kFallbackEkf && o_.covariance) {
    const auto tc = std::chrono::steady_clock::now();
    out.has_covariance = computeCovariance(&out);
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
