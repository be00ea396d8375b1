// Gyro with bias (K-12, K-13):  ω_m = B_g (ω + b) + n_g.
//
// b is a per-body-axis bias (3-vector) so the same state serves a 3-axis gyro (B_g = I) and the
// heading-only gyro of Rocky-7 (B_g = [0 0 1]); with a heading gyro only b_z is observable
// through this model.
#pragma once

#include "traverse/core/types.h"

namespace traverse::sensors {

/// Prediction of all three axes, ω + b (rad/s); B_g selects the rows the gyro has.
template <typename T>
Vec3<T> gyroPredict(const Vec3<T>& w_body, const Vec3<T>& bias) {
  return w_body + bias;
}

/// Body axes a gyro measures: {2} for heading-only (B_g = [0 0 1]), {0, 1, 2} for three axes.
struct GyroAxesList {
  int count = 1;
  int axis[3] = {2, 0, 0};
  static GyroAxesList headingOnly() { return {1, {2, 0, 0}}; }
  static GyroAxesList threeAxis() { return {3, {0, 1, 2}}; }
};

}  // namespace traverse::sensors
