#include "traverse/rover/joint_sample.h"

#include <cmath>

namespace traverse::rover {

Eigen::Matrix4d slipCovariance(const SlipNoise& sn, const JointSample& js, int i,
                               const Vec3d& v_body, const Vec3d& w_body,
                               const Eigen::Matrix<double, 4, 6>& J_vw) {
  Eigen::Matrix4d R =
      Vec4d(sn.longitudinal_mps * sn.longitudinal_mps, sn.lateral_mps * sn.lateral_mps,
            sn.normal_mps * sn.normal_mps, sn.spin_rad_s * sn.spin_rad_s)
          .asDiagonal();
  // Joint noise enters the constraint too: the joint twist J q̇ through ∂t/∂[v; ω] (t is linear
  // in the twist), and a steering-angle error turns the wheel's heading, moving the contact
  // point's velocity into the transverse row by |v_wheel| δλ.
  R.noalias() += J_vw * js.joint_twist_covariance[i] * J_vw.transpose();
  const double wz2 = w_body.z() * w_body.z();
  R(0, 0) += sn.longitudinal_per_yaw_rate_m * sn.longitudinal_per_yaw_rate_m * wz2;
  R(1, 1) += sn.lateral_per_yaw_rate_m * sn.lateral_per_yaw_rate_m * wz2;
  R(0, 0) += std::pow(sn.longitudinal_per_speed * v_body.x(), 2);
  if (js.steering_variance[i] > 0) {
    const Posed& g = js.T_body_wheel[i];
    const Twistd& jt = js.joint_twist[i];
    const Vec3d u = g.R.transpose() * (v_body + jt.head<3>() + (w_body + jt.tail<3>()).cross(g.p));
    R(1, 1) += js.steering_variance[i] * (u.x() * u.x() + u.y() * u.y());
  }
  return R;
}

}  // namespace traverse::rover
