// include/traverse/smoother/residuals/slip_residual.h
#include "traverse/smoother/residuals/slip_residual.h"

#include <stdexcept>

#include "traverse/rover/nominal_slip.h"
#include "traverse/smoother/residuals/whitening.h"

namespace traverse::smoother {

void addSlipResiduals(ResidualCollector& out, std::vector<SlipWheelData>& data,
                      const rover::RoverGeometry& geometry, const rover::SlipNoise& noise,
                      const rover::JointSample& js, const est::TrajectoryNode& seed,
                      const Twistd& nominal_twist, ceres::LossFunction* loss, const NodeHandles& k,
                      bool nominal_follows_state) {
  const int nw = geometry.numWheels();
  for (int i = 0; i < nw; ++i) {
    if (!js.wheelUsed(i)) continue;  // a wheel outage (a stuck encoder): no slip rows
    const double radius = geometry.wheels[i].radius;
    Eigen::Matrix<double, 4, 7> J;
    // The wheels' apparent motion: the body's plus their common slip (c_ω zero unless carried).
    const Vec3d v_wheels = seed.v_body + Vec3d(seed.common_slip.x(), seed.common_slip.y(), 0.0);
    const Vec3d w_wheels =
        seed.w_body + Vec3d(0.0, 0.0, k.c.size == 3 ? seed.common_slip.z() : 0.0);
    rover::slipConstraintWithJacobian(js.T_body_wheel[i], radius, js.joint_twist[i], v_wheels,
                                      w_wheels, seed.xi[i], &J);
    const Eigen::Matrix4d R =
        rover::slipCovariance(noise, js, i, v_wheels, w_wheels, J.leftCols<6>());
    const double icr = geometry.wheels[i].icr_offset_y;
    SlipWheelData w{js.T_body_wheel[i],
                    radius,
                    js.joint_twist[i],
                    Vec4d::Zero(),
                    sqrtInformation<4>(R, "slip"),
                    Eigen::Matrix<double, 4, 2>::Zero(),
                    Vec2d::Zero(),
                    geometry.wheels[i].icr_side,
                    nominal_follows_state,
                    nominal_twist[5]};
    if (nominal_follows_state) {
      w.nominal_at = Vec2d(v_wheels.x(), w_wheels.z());
      w.nominal_jacobian =
          rover::nominalSlipJacobian(geometry, js.T_body_wheel[i], radius, js.joint_twist[i], icr);
      w.nominal_slip =
          rover::nominalSlip(js.T_body_wheel[i], radius,
                             rover::nominalBodyTwist(geometry, w.nominal_at.x(), w.nominal_at.y()),
                             js.joint_twist[i], icr);
    } else {
      w.nominal_slip =
          rover::nominalSlip(js.T_body_wheel[i], radius, nominal_twist, js.joint_twist[i], icr);
    }
    if (data.size() == data.capacity())
      throw std::logic_error("smoother: slip data would move under its cost functions");
    data.push_back(w);
    const bool common = k.c.size > 0, has_icr = k.icr.size > 0;
    auto* f = new SlipResidual(i, nw, &data.back(), k.c.size, has_icr);
    if (common && has_icr)
      out.add("slip", f, loss, k.v, k.w, k.xi, k.c, k.icr);
    else if (common)
      out.add("slip", f, loss, k.v, k.w, k.xi, k.c);
    else if (has_icr)
      out.add("slip", f, loss, k.v, k.w, k.xi, k.icr);
    else
      out.add("slip", f, loss, k.v, k.w, k.xi);
  }
}

}  // namespace traverse::smoother
