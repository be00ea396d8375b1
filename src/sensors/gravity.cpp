#include "traverse/sensors/gravity.h"

namespace traverse::sensors {

RollPitchMeasurement rollPitchAtRest(const Vec3d& f, const Mat3d& cov) {
  RollPitchMeasurement m;
  m.roll_pitch = rollPitchFromSpecificForce(f);
  // ∂(roll, pitch)/∂f, analytic.
  const double yz2 = f.y() * f.y() + f.z() * f.z();
  const double yz = std::sqrt(yz2);
  const double n2 = yz2 + f.x() * f.x();
  Eigen::Matrix<double, 2, 3> J;
  J << 0.0, f.z() / yz2, -f.y() / yz2,  //
      -yz / n2, f.x() * f.y() / (yz * n2), f.x() * f.z() / (yz * n2);
  m.covariance = J * cov * J.transpose();
  return m;
}

}  // namespace traverse::sensors
