#include "traverse/eval/truth.h"

#include <algorithm>
#include <stdexcept>
#include <string>

namespace traverse::eval {
namespace {

/// Column indices of a group, or an empty vector when any of them is missing.
std::vector<int> groupColumns(const io::Stream& s, std::initializer_list<const char*> names) {
  std::vector<int> cols;
  for (const char* n : names) {
    const int c = s.col(n);
    if (c < 0) return {};
    cols.push_back(c);
  }
  return cols;
}

Vec3d row3(const io::Stream& s, Eigen::Index k, const std::vector<int>& c) {
  return Vec3d(s.values(k, c[0]), s.values(k, c[1]), s.values(k, c[2]));
}

}  // namespace

TruthTrajectory::TruthTrajectory(const io::Stream& truth) {
  if (truth.empty()) throw std::invalid_argument("truth: no samples");
  const auto pos = groupColumns(truth, {"x", "y", "z"});
  const auto quat = groupColumns(truth, {"qw", "qx", "qy", "qz"});
  if (pos.empty() || quat.empty()) throw std::invalid_argument("truth: needs x,y,z,qw,qx,qy,qz");
  std::vector<int> xi;  // xi1..xiN: every wheel's contact angle
  for (int i = 1; truth.has("xi" + std::to_string(i)); ++i)
    xi.push_back(truth.col("xi" + std::to_string(i)));
  if (xi.size() > static_cast<size_t>(rover::kMaxWheels))
    throw std::invalid_argument("truth: too many xi columns");
  const auto bias = groupColumns(truth, {"bx", "by", "bz"});
  const auto vel = groupColumns(truth, {"vx", "vy", "vz"});
  const auto rate = groupColumns(truth, {"wx", "wy", "wz"});
  has_xi_ = !xi.empty();
  has_bias_ = !bias.empty();
  has_velocity_ = !vel.empty();
  has_rate_ = !rate.empty();
  for (Eigen::Index k = 0; k < truth.size(); ++k) {
    t_.push_back(truth.t[k]);
    p_.push_back(row3(truth, k, pos));
    const auto& v = truth.values;
    q_.push_back(Quatd(v(k, quat[0]), v(k, quat[1]), v(k, quat[2]), v(k, quat[3])).normalized());
    if (has_xi_) {
      rover::WheelVectord a(static_cast<Eigen::Index>(xi.size()));
      for (std::size_t i = 0; i < xi.size(); ++i) a[static_cast<Eigen::Index>(i)] = v(k, xi[i]);
      xi_.push_back(a);
    }
    if (has_bias_) bias_.push_back(row3(truth, k, bias));
    if (has_velocity_) v_.push_back(row3(truth, k, vel));
    if (has_rate_) w_.push_back(row3(truth, k, rate));
    s_.push_back(k == 0 ? 0.0 : s_.back() + (p_[k] - p_[k - 1]).norm());
  }
}

TruthTrajectory::Bracket TruthTrajectory::locate(double t) const {
  if (t_.size() == 1 || t <= t_.front()) return {0, 0.0};
  if (t >= t_.back()) return {t_.size() - 1, 0.0};
  // First sample strictly after t; t lies in [t_{i}, t_{i+1}).
  const auto it = std::upper_bound(t_.begin(), t_.end(), t);
  const std::size_t i = static_cast<std::size_t>(it - t_.begin()) - 1;
  return {i, (t - t_[i]) / (t_[i + 1] - t_[i])};
}

Vec3d TruthTrajectory::lerp3(const std::vector<Vec3d>& x, double t) const {
  const Bracket b = locate(t);
  if (b.a == 0.0) return x[b.i];
  return (1.0 - b.a) * x[b.i] + b.a * x[b.i + 1];
}

Vec3d TruthTrajectory::position(double t) const {
  return lerp3(p_, t);
}

Quatd TruthTrajectory::attitude(double t) const {
  const Bracket b = locate(t);
  if (b.a == 0.0) return q_[b.i];
  return q_[b.i].slerp(b.a, q_[b.i + 1]).normalized();
}

rover::WheelVectord TruthTrajectory::contactAngles(double t) const {
  if (!has_xi_) throw std::logic_error("truth has no contact angles");
  const Bracket b = locate(t);
  if (b.a == 0.0) return xi_[b.i];
  return (1.0 - b.a) * xi_[b.i] + b.a * xi_[b.i + 1];
}

Vec3d TruthTrajectory::bias(double t) const {
  if (!has_bias_) throw std::logic_error("truth has no gyro bias");
  return lerp3(bias_, t);
}

Vec3d TruthTrajectory::velocityBody(double t) const {
  if (!has_velocity_) throw std::logic_error("truth has no body velocity");
  return lerp3(v_, t);
}

Vec3d TruthTrajectory::bodyRate(double t) const {
  if (!has_rate_) throw std::logic_error("truth has no body rate");
  return lerp3(w_, t);
}

Vec3d TruthTrajectory::velocitySite(double t) const {
  if (has_velocity_) return attitude(t) * velocityBody(t);
  if (t_.size() < 2) return Vec3d::Zero();
  const std::size_t i = std::min(locate(t).i, t_.size() - 2);
  return (p_[i + 1] - p_[i]) / (t_[i + 1] - t_[i]);
}

double TruthTrajectory::distanceTravelled(double t) const {
  // Position is linear between samples, so the distance along a segment is linear in time too.
  const Bracket b = locate(t);
  if (b.a == 0.0) return s_[b.i];
  return (1.0 - b.a) * s_[b.i] + b.a * s_[b.i + 1];
}

}  // namespace traverse::eval
