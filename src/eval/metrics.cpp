// Metric definitions: include/traverse/eval/metrics.h and docs/evaluation.md.
#include "traverse/eval/metrics.h"

#include <algorithm>
#include <cmath>
#include <optional>

#include <Eigen/Eigenvalues>

#include "eval/table.h"
#include "traverse/core/so3.h"
#include "traverse/eval/alignment.h"

namespace traverse::eval {
namespace {

constexpr double kRadToDeg = 180.0 / M_PI;
/// Lengths below this (m) are treated as zero: no percentage of them is meaningful.
constexpr double kMinLength = 1e-9;

/// The estimate at its nodes and the truth interpolated at the same times.
struct NodePairs {
  std::vector<double> t;
  std::vector<Vec3d> p_hat_raw;  ///< as estimated (for the ATE, which aligns on its own)
  std::vector<Vec3d> p_hat;      ///< after the initial translation p(t_0) − p̂_0 (and turn)
  std::vector<Vec3d> p;
  std::vector<Quatd> q_hat, q;  ///< q_hat after the initial turn
  /// The turn about the vertical applied to the estimate (identity unless the heading is the
  /// gauge: EvaluateOptions::heading_is_gauge); its position covariance turns with it.
  Mat3d R_gauge = Mat3d::Identity();

  std::size_t size() const { return t.size(); }
};

NodePairs pairUp(const est::Trajectory& trajectory, const TruthTrajectory& truth,
                 const EvaluateOptions& o) {
  NodePairs n;
  for (const est::TrajectoryNode& node : trajectory.nodes) {
    n.t.push_back(node.t);
    n.p_hat_raw.push_back(node.p_site);
    n.p.push_back(truth.position(node.t));
    n.q_hat.push_back(node.q_site_body.normalized());
    n.q.push_back(truth.attitude(node.t));
  }
  if (o.heading_is_gauge) {
    // The start heading was not measured (no sun): like the start position, it is put on the
    // truth's — the estimate turned about the vertical through its start by the yaw between them.
    const double turn =
        so3::wrapAngle(so3::rollPitchYaw(n.q.front()).z() - so3::rollPitchYaw(n.q_hat.front()).z());
    const Quatd r(Eigen::AngleAxisd(turn, Vec3d::UnitZ()));
    n.R_gauge = r.toRotationMatrix();
    for (Quatd& q : n.q_hat) q = (r * q).normalized();
  }
  for (const Vec3d& p : n.p_hat_raw)
    n.p_hat.push_back(n.p.front() + n.R_gauge * (p - n.p_hat_raw.front()));
  return n;
}

double rootMean(double sum_sq, std::size_t count) {
  return std::sqrt(sum_sq / static_cast<double>(count));
}

void addPositionMetrics(Metrics& m, const NodePairs& n, double path_length) {
  const std::size_t last = n.size() - 1;
  const double true_distance = (n.p[last] - n.p[0]).norm();
  if (true_distance > kMinLength) {
    const double est_distance = (n.p_hat[last] - n.p_hat[0]).norm();
    m.set("distance_error_pct", std::abs(est_distance - true_distance) / true_distance * 100.0);
  }
  const double final_error = (n.p_hat[last] - n.p[last]).norm();
  m.set("final_position_error_m", final_error);
  m.set("final_vertical_error_m", std::abs(n.p_hat[last].z() - n.p[last].z()));
  if (path_length > kMinLength) m.set("final_error_pct_of_path", final_error / path_length * 100.0);
  double sum_sq = 0.0;
  for (std::size_t k = 0; k < n.size(); ++k) sum_sq += (n.p_hat[k] - n.p[k]).squaredNorm();
  m.set("position_rmse_m", rootMean(sum_sq, n.size()));
}

/// Horizontal unit vector perpendicular to the true direction of travel at time t.
Eigen::Vector2d lateralDirection(const TruthTrajectory& truth, double t, const Quatd& q_true,
                                 double min_speed) {
  Eigen::Vector2d along = truth.velocitySite(t).head<2>();
  if (along.norm() < min_speed) {
    const double yaw = so3::rollPitchYaw(q_true).z();
    along = Eigen::Vector2d(std::cos(yaw), std::sin(yaw));
  }
  along.normalize();
  return Eigen::Vector2d(-along.y(), along.x());
}

double maxCrossTrack(const NodePairs& n, const TruthTrajectory& truth, double min_speed) {
  double worst = 0.0;
  for (std::size_t k = 0; k < n.size(); ++k) {
    const Eigen::Vector2d lateral = lateralDirection(truth, n.t[k], n.q[k], min_speed);
    const Eigen::Vector2d e_h = (n.p_hat[k] - n.p[k]).head<2>();
    worst = std::max(worst, std::abs(e_h.dot(lateral)));
  }
  return worst;
}

void addAttitudeMetrics(Metrics& m, const NodePairs& n) {
  Vec3d sum_sq = Vec3d::Zero();
  for (std::size_t k = 0; k < n.size(); ++k) {
    const Vec3d d = so3::rollPitchYaw(n.q_hat[k]) - so3::rollPitchYaw(n.q[k]);
    for (int a = 0; a < 3; ++a) sum_sq[a] += std::pow(so3::wrapAngle(d[a]), 2);
  }
  m.set("roll_rmse_deg", rootMean(sum_sq[0], n.size()) * kRadToDeg);
  m.set("pitch_rmse_deg", rootMean(sum_sq[1], n.size()) * kRadToDeg);
  m.set("yaw_rmse_deg", rootMean(sum_sq[2], n.size()) * kRadToDeg);
}

void addStateMetrics(Metrics& m, const est::Trajectory& tr, const TruthTrajectory& truth) {
  const std::size_t count = tr.nodes.size();
  // Contact angles: when truth and estimate have the same wheels (a truth for another rover
  // is not compared).
  if (truth.hasContactAngles() && count > 0 &&
      truth.contactAngles(tr.nodes.front().t).size() == tr.nodes.front().xi.size()) {
    double sum_sq = 0.0;
    std::size_t terms = 0;
    for (const est::TrajectoryNode& node : tr.nodes) {
      const rover::WheelVectord xi = truth.contactAngles(node.t);
      if (xi.size() != node.xi.size()) continue;
      sum_sq += (node.xi - xi).squaredNorm();
      terms += static_cast<std::size_t>(xi.size());
    }
    if (terms > 0) m.set("contact_angle_rmse_deg", rootMean(sum_sq, terms) * kRadToDeg);
  }
  if (truth.hasBias()) {
    double sum_abs = 0.0;
    for (const est::TrajectoryNode& node : tr.nodes) {
      sum_abs += std::abs(node.bias.z() - truth.bias(node.t).z());
    }
    m.set("bias_z_error_dps", sum_abs / static_cast<double>(count) * kRadToDeg);
    std::size_t within = 0, with_sigma = 0;
    for (const est::TrajectoryNode& node : tr.nodes) {
      if (!(node.bias_sigma.z() > 0)) continue;
      ++with_sigma;
      within += std::abs(node.bias.z() - truth.bias(node.t).z()) <= 3 * node.bias_sigma.z();
    }
    if (with_sigma > 0)
      m.set("bias_z_within_3sigma_pct",
            100.0 * static_cast<double>(within) / static_cast<double>(with_sigma));
  }
}

/// Mean relative translation error per distance travelled (header: rpe_pct_per_m).
std::optional<double> relativePoseError(const NodePairs& n, const TruthTrajectory& truth,
                                        double path_length, const EvaluateOptions& o) {
  const double segment =
      path_length < o.rpe_short_path_m ? o.rpe_short_fraction * path_length : o.rpe_segment_m;
  if (segment <= kMinLength) return std::nullopt;
  std::vector<double> s;
  for (double t : n.t) s.push_back(truth.distanceTravelled(t));
  // A relative tolerance keeps a pair whose distance equals the segment up to rounding.
  const double reach = segment * (1.0 - 1e-12);
  double sum = 0.0;
  std::size_t pairs = 0, j = 0;
  for (std::size_t i = 0; i < n.size(); ++i) {
    j = std::max(j, i + 1);  // s is non-decreasing in node time, so j only moves forward
    while (j < n.size() && s[j] - s[i] < reach) ++j;
    if (j >= n.size()) break;
    const Vec3d d_hat = n.q_hat[i].conjugate() * (n.p_hat[j] - n.p_hat[i]);
    const Vec3d d_true = n.q[i].conjugate() * (n.p[j] - n.p[i]);
    sum += (d_hat - d_true).norm() / (s[j] - s[i]) * 100.0;
    ++pairs;
  }
  if (pairs == 0) return std::nullopt;
  return sum / static_cast<double>(pairs);
}

/// eᵀ P⁻¹ e, or nothing when P is not finite or has an eigenvalue below min_eigenvalue.
std::optional<double> normalizedSquare(const Mat3d& P, const Vec3d& e, double min_eigenvalue) {
  if (!P.allFinite() || !e.allFinite()) return std::nullopt;
  const Eigen::SelfAdjointEigenSolver<Mat3d> eig(0.5 * (P + P.transpose()));
  if (eig.info() != Eigen::Success || eig.eigenvalues().minCoeff() < min_eigenvalue) {
    return std::nullopt;
  }
  // P = V Λ Vᵀ ⇒ eᵀ P⁻¹ e = Σ (v_iᵀ e)² / λ_i.
  const Vec3d y = eig.eigenvectors().transpose() * e;
  return (y.array().square() / eig.eigenvalues().array()).sum();
}

void addNees(Metrics& m, const est::Trajectory& tr, const NodePairs& n, double min_eigenvalue) {
  double sum_p = 0.0, sum_a = 0.0;
  double e2_p = 0.0, s2_p = 0.0, e2_y = 0.0, s2_y = 0.0;
  std::size_t count_p = 0, count_a = 0;
  for (std::size_t k = 0; k < n.size(); ++k) {
    const Mat6d& P = tr.nodes[k].covariance;
    const Vec3d e_p = n.p[k] - n.p_hat[k];
    const Vec3d e_a = so3::boxminus(n.q[k], n.q_hat[k]);  // Log(q̂⁻¹ q): q = q̂ ⊗ Exp(e)
    // Position in the site frame turns with the gauge; attitude's is in the body frame.
    const Mat3d P_p = n.R_gauge * P.topLeftCorner<3, 3>() * n.R_gauge.transpose();
    if (const auto v = normalizedSquare(P_p, e_p, min_eigenvalue)) {
      sum_p += *v;
      ++count_p;
      e2_p += e_p.squaredNorm(), s2_p += P_p.trace();
    }
    if (const auto v = normalizedSquare(P.bottomRightCorner<3, 3>(), e_a, min_eigenvalue)) {
      sum_a += *v;
      ++count_a;
      e2_y += e_a.z() * e_a.z(), s2_y += P(5, 5);
    }
  }
  if (count_p > 0) m.set("nees_position_mean", sum_p / static_cast<double>(count_p));
  if (count_a > 0) m.set("nees_attitude_mean", sum_a / static_cast<double>(count_a));
  if (count_p > 0 || count_a > 0) m.set("nees_dof", 3.0);
  if (count_p > 0 && s2_p > 0) m.set("position_rmse_over_sigma", std::sqrt(e2_p / s2_p));
  if (count_a > 0 && s2_y > 0) m.set("yaw_rmse_over_sigma", std::sqrt(e2_y / s2_y));
}

}  // namespace

void Metrics::set(std::string_view key, double value) {
  for (auto& [k, v] : entries) {
    if (k == key) {
      v = value;
      return;
    }
  }
  entries.emplace_back(std::string(key), value);
}

std::optional<double> Metrics::get(std::string_view key) const {
  for (const auto& [k, v] : entries) {
    if (k == key) return v;
  }
  return std::nullopt;
}

std::vector<std::string> Metrics::keys() const {
  std::vector<std::string> out;
  for (const auto& entry : entries) out.push_back(entry.first);
  return out;
}

std::pair<int, int> restBiasConsistency(const std::vector<est::RestWindow>& rests,
                                        const TruthTrajectory& truth) {
  std::pair<int, int> out{0, 0};
  if (!truth.hasBias()) return out;
  for (const est::RestWindow& w : rests) {
    if (!w.bias_axes[2] || !(w.bias_sigma.z() > 0)) continue;
    const double e = w.bias.z() - truth.bias(0.5 * (w.t_start + w.t_end)).z();
    out.first += std::abs(e) <= 3 * w.bias_sigma.z();
    ++out.second;
  }
  return out;
}

Metrics evaluate(const est::Trajectory& trajectory, const TruthTrajectory& truth,
                 const EvaluateOptions& options) {
  Metrics m;
  if (trajectory.nodes.empty()) return m;
  const NodePairs n = pairUp(trajectory, truth, options);
  const double path_length = truth.pathLength(n.t.front(), n.t.back());
  addPositionMetrics(m, n, path_length);
  m.set("max_cross_track_m", maxCrossTrack(n, truth, options.min_speed_mps));
  addAttitudeMetrics(m, n);
  addStateMetrics(m, trajectory, truth);
  m.set("ate_posyaw_m", absoluteTrajectoryErrorPosYaw(n.p_hat_raw, n.p));
  if (const auto rpe = relativePoseError(n, truth, path_length, options)) {
    m.set("rpe_pct_per_m", *rpe);
  }
  if (trajectory.has_covariance) addNees(m, trajectory, n, options.min_covariance_eigenvalue);
  // The helpers group metrics by what they need; metrics.json lists them in kMetricKeys order.
  std::stable_sort(m.entries.begin(), m.entries.end(), [](const auto& a, const auto& b) {
    return detail::metricKeyRank(a.first) < detail::metricKeyRank(b.first);
  });
  return m;
}

}  // namespace traverse::eval
