// Gyro with bias (K-12, K-13):  ω_m = B_g (ω + b) + n_g.
//
// b is a per-body-axis bias (3-vector) so the same state serves a 3-axis gyro (B_g = I) and the
// heading-only gyro of Rocky-7 (B_g = [0 0 1]); with a heading gyro only b_z is observable
// through this model.
#pragma once

#include <vector>

#include "traverse/core/types.h"

namespace traverse::sensors {

/// Prediction of all three axes, ω + b (rad/s); B_g selects the rows the gyro has.
template <typename T>
Vec3<T> gyroPredict(const Vec3<T>& w_body, const Vec3<T>& bias) {
  return w_body + bias;
}

/// B_g of K-12/K-13, the one description of which body axes a gyro measures, used by the
/// simulator (synthesising readings), the segmentation, dead reckoning, the EKF and the smoother.
/// Column c of gyro.csv measures body axis axis(c): heading-only (one column `wz`, B_g = [0 0 1])
/// or three-axis (`wx,wy,wz`, B_g = I).
class GyroAxes {
 public:
  static GyroAxes headingOnly() { return GyroAxes(1); }
  static GyroAxes threeAxis() { return GyroAxes(3); }
  /// The gyro of a gyro.csv with this many columns (1 or 3; the log reader checks the header).
  static GyroAxes forColumns(Eigen::Index columns) { return GyroAxes(columns == 3 ? 3 : 1); }

  int count() const { return count_; }
  bool isThreeAxis() const { return count_ == 3; }
  /// Body axis measured by column c.
  int axis(Eigen::Index c) const { return count_ == 3 ? static_cast<int>(c) : 2; }
  bool measures(int body_axis) const { return count_ == 3 || body_axis == 2; }
  /// diag(B_gᵀ B_g): 1 on measured axes.
  Vec3d mask() const { return count_ == 3 ? Vec3d::Ones() : Vec3d(0, 0, 1); }
  /// B_gᵀ B_g: projects a body vector on the measured axes.
  Mat3d selection() const { return Mat3d(mask().asDiagonal()); }
  /// B_gᵀ m: a reading (one value per column) as a body vector, 0 on axes not measured.
  template <typename Derived>
  Vec3d toBody(const Eigen::MatrixBase<Derived>& reading) const {
    Vec3d w = Vec3d::Zero();
    for (Eigen::Index c = 0; c < reading.size(); ++c) w[axis(c)] = reading[c];
    return w;
  }
  /// The unmeasured axes (the bias parameters nothing observes: held by the smoother).
  std::vector<int> unmeasured() const {
    std::vector<int> out;
    for (int a = 0; a < 3; ++a)
      if (!measures(a)) out.push_back(a);
    return out;
  }

 private:
  explicit GyroAxes(int count) : count_(count) {}
  int count_;
};

}  // namespace traverse::sensors
