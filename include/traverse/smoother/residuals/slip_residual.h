// Slip constraint (K-17 … K-20) of wheel i at a node: four rows, the contact point's slip
// velocity along the contact frame's x, y, z and the spin about the contact normal,
//
//   r = L⁻¹ (t_nom − t_i(v, ω, ξ_i)),   t_i = Bᵀ Ad⁻¹_{g_{s l_i}}(ξ_i) ([v; ω] + J q̇)
//
// t_nom is the nominal slip of K §2.3.4 (transverse slip and spin a turn cannot avoid), Σ = L Lᵀ
// the slip noise of rover.yaml plus the joint-rate noise carried through ∂t/∂[v; ω] and the
// steering-angle noise (as in the EKF; evaluated once, at the seed). A robust loss is attached
// where the residual is added.
//
// This is the smoother's hot residual (four rows per wheel and node), so its Jacobian is analytic —
// rover::slipConstraintWithJacobian, itself tested against the Jet derivative of
// rover::slipConstraint, the templated model every estimator shares.
//
// With the wheels' common slip c (rover.yaml slip_noise.common_*) the wheels roll as if the body
// moved at v + (c_x, c_y, 0), and with its yaw component c_ω (slip_noise.common_yaw_rate_rad_s)
// as if it turned at ω + (0, 0, c_ω): t_i(v + c_v, ω + c_ω e_z, ξ_i). Without cmd.csv the
// nominal follows the wheels' apparent motion (v_x + c_x, ω_z + c_ω), as in the EKF.
//
// Without cmd.csv the nominal body twist is the estimate's own (v_x + c_x, ω_z + c_ω), as in the
// EKF: t_nom = t_nom(u₀) + N (u − u₀), u = (v_x + c_x, ω_z + c_ω), N = rover::nominalSlipJacobian —
// exact, the nominal being affine in u — so the residual and its Jacobian follow the state instead
// of holding the seed's nominal (which carried the EKF's yaw-rate error into every slip row).
//
// On a skid-steered rover whose ICRs are estimated (io::SkidSteerConfig) the nominal
// longitudinal slip is ω_z,nom (icr_offset_y + icr_side δ), δ the segment's ICR half-track error:
// t_nom,0 += icr_side ω_z,nom δ, with ω_z,nom the command's or (no cmd.csv) the state's ω_z (+
// c_ω).
//
// Parameter blocks: v (body, m/s), ω (body, rad/s), ξ (every wheel's contact angle, rad), with
// the common slip c (body x, y in m/s, and c_ω in rad/s when declared), and with the ICRs δ (m).
#pragma once

#include <ceres/cost_function.h>

#include <memory>
#include <vector>

#include "traverse/estimators/trajectory.h"
#include "traverse/rover/joint_sample.h"
#include "traverse/rover/rover_geometry.h"
#include "traverse/rover/slip_constraint.h"
#include "traverse/smoother/residual_collector.h"

namespace traverse::smoother {

/// The numbers that define wheel i's slip residual at one node.
struct SlipWheelData {
  Posed T_body_wheel;
  double radius = 0.0;
  Twistd joint_twist = Twistd::Zero();
  Vec4d nominal_slip = Vec4d::Zero();
  Eigen::Matrix4d sqrt_info = Eigen::Matrix4d::Identity();
  /// Without cmd.csv: ∂t_nom/∂(v_x + c_x, ω_z) and the u₀ at which nominal_slip was taken
  /// (zero with cmd.csv: the nominal is the command's, a constant).
  Eigen::Matrix<double, 4, 2> nominal_jacobian = Eigen::Matrix<double, 4, 2>::Zero();
  Vec2d nominal_at = Vec2d::Zero();
  /// ICR block only: rover::Wheel::icr_side, whether ω_z,nom is the state's (no cmd.csv), and
  /// the command's ω_z otherwise. nominal_slip is taken at δ = 0.
  double icr_side = 0.0;
  bool nominal_follows_state = false;
  double command_w_z = 0.0;
};

class SlipResidual final : public ceres::CostFunction {
 public:
  /// Wheel `wheel` of `wheels` (the size of the ξ block). Keeps its own copy of the numbers.
  /// `common_slip`: the size of a fourth block, c (0: none, 2: c_x, c_y, 3: with c_ω).
  SlipResidual(int wheel, int wheels, const Posed& T_body_wheel, double radius,
               const Twistd& joint_twist, const Vec4d& nominal_slip,
               const Eigen::Matrix4d& sqrt_info, int common_slip = 0)
      : wheel_(wheel),
        common_(common_slip),
        owned_(std::make_unique<SlipWheelData>(
            SlipWheelData{T_body_wheel, radius, joint_twist, nominal_slip, sqrt_info,
                          Eigen::Matrix<double, 4, 2>::Zero(), Vec2d::Zero()})),
        d_(owned_.get()) {
    setSizes(wheels);
  }
  /// Keeps its own copy of `data` (a nominal that follows the state included). `icr`: a last
  /// block, the ICRs' half-track error δ.
  SlipResidual(int wheel, int wheels, const SlipWheelData& data, int common_slip, bool icr = false)
      : wheel_(wheel),
        common_(common_slip),
        icr_(icr),
        owned_(std::make_unique<SlipWheelData>(data)),
        d_(owned_.get()) {
    setSizes(wheels);
  }
  /// Refers to numbers kept elsewhere, which must outlive it. The smoother keeps a segment's in
  /// one array: the cost function is then 56 bytes instead of 350, and Ceres' passes over every
  /// residual block's cost function (sizes, row counts) read a dense run of memory instead of
  /// one cache line every 370 bytes (docs/results.md, "Speed", session 6).
  SlipResidual(int wheel, int wheels, const SlipWheelData* data, int common_slip = 0,
               bool icr = false)
      : wheel_(wheel), common_(common_slip), icr_(icr), d_(data) {
    setSizes(wheels);
  }

  bool Evaluate(double const* const* parameters, double* residuals,
                double** jacobians) const override {
    Vec3d w = Eigen::Map<const Vec3d>(parameters[1]);
    Vec3d v = Eigen::Map<const Vec3d>(parameters[0]);
    if (common_ > 0) v.head<2>() += Eigen::Map<const Vec2d>(parameters[3]);
    if (common_ == 3) w.z() += parameters[3][2];
    const double xi = parameters[2][wheel_];
    Eigen::Matrix<double, 4, 7> J;
    const SlipWheelData& d = *d_;
    const Vec4d t =
        rover::slipConstraintWithJacobian(d.T_body_wheel, d.radius, d.joint_twist, v, w, xi, &J);
    Vec4d nominal = d.nominal_slip + d.nominal_jacobian * (Vec2d(v.x(), w.z()) - d.nominal_at);
    const int icr_block = common_ > 0 ? 4 : 3;
    const double icr = icr_ ? parameters[icr_block][0] : 0.0;
    const double w_nom = d.nominal_follows_state ? w.z() : d.command_w_z;
    nominal[0] += d.icr_side * w_nom * icr;
    Eigen::Map<Vec4d>{residuals} = d.sqrt_info * (nominal - t);
    if (jacobians) {
      using Rm43 = Eigen::Matrix<double, 4, 3, Eigen::RowMajor>;
      using Rm4X = Eigen::Matrix<double, 4, Eigen::Dynamic, Eigen::RowMajor>;
      // ∂r/∂s = L (∂t_nom/∂s − ∂t/∂s); t_nom moves with v_x (and c_x) and ω_z only.
      J.col(0) -= d.nominal_jacobian.col(0);
      J.col(5) -= d.nominal_jacobian.col(1);
      if (d.nominal_follows_state) J(0, 5) -= d.icr_side * icr;
      if (jacobians[0]) Eigen::Map<Rm43>{jacobians[0]} = -d.sqrt_info * J.leftCols<3>();
      if (jacobians[1]) Eigen::Map<Rm43>{jacobians[1]} = -d.sqrt_info * J.middleCols<3>(3);
      if (jacobians[2]) {
        Eigen::Map<Rm4X> Jxi(jacobians[2], 4, parameter_block_sizes()[2]);
        Jxi.setZero();
        Jxi.col(wheel_) = -d.sqrt_info * J.col(6);
      }
      if (common_ > 0 && jacobians[3]) {  // c_x, c_y move like v_x, v_y; c_ω like ω_z
        Eigen::Map<Rm4X> Jc(jacobians[3], 4, common_);
        Jc.leftCols<2>() = -d.sqrt_info * J.leftCols<2>();
        if (common_ == 3) Jc.col(2) = -d.sqrt_info * J.col(5);
      }
      if (icr_ && jacobians[icr_block])
        Eigen::Map<Vec4d>{jacobians[icr_block]} = d.sqrt_info.col(0) * (d.icr_side * w_nom);
    }
    return true;
  }

  /// The same residual through the templated model (the autodiff twin the tests compare with);
  /// c: the common slip (c_x, c_y, c_ω; zero without it), icr: δ (zero without it).
  template <typename T, typename Xi>
  Vec4<T> residual(const Vec3<T>& v, const Vec3<T>& w, const Xi& xi,
                   const Vec3<T>& c = Vec3<T>::Zero(), const T& icr = T(0)) const {
    const SlipWheelData& d = *d_;
    const Vec3<T> v_wheels(v.x() + c.x(), v.y() + c.y(), v.z());
    const Vec3<T> w_wheels(w.x(), w.y(), w.z() + c.z());
    const Vec4<T> t = rover::slipConstraint<T>(d.T_body_wheel, d.radius, d.joint_twist, v_wheels,
                                               w_wheels, xi[wheel_]);
    const Vec2<T> u(v_wheels.x() - T(d.nominal_at.x()), w_wheels.z() - T(d.nominal_at.y()));
    Vec4<T> nominal = d.nominal_slip.cast<T>() + d.nominal_jacobian.cast<T>() * u;
    const T w_nom = d.nominal_follows_state ? w_wheels.z() : T(d.command_w_z);
    nominal[0] += T(d.icr_side) * w_nom * icr;
    return d.sqrt_info.cast<T>() * (nominal - t);
  }
  bool hasCommonSlip() const { return common_ > 0; }
  int commonSlipStates() const { return common_; }
  bool hasIcr() const { return icr_; }

 private:
  void setSizes(int wheels) {
    set_num_residuals(4);
    *mutable_parameter_block_sizes() = {3, 3, wheels};
    if (common_ > 0) mutable_parameter_block_sizes()->push_back(common_);
    if (icr_) mutable_parameter_block_sizes()->push_back(1);
  }

  int wheel_;
  int common_ = 0;  ///< c's size: 0, 2 or 3
  bool icr_ = false;
  std::unique_ptr<SlipWheelData> owned_;  ///< set by the owning constructor only
  const SlipWheelData* d_;
};

/// Constraint (residual_collector.h): every wheel's slip residuals at node k, under the robust
/// loss. Blocks v_k, ω_k, ξ_k, c_k when the node has the common slip (k.c.size > 0), and the
/// segment's ICR error δ when it has one (k.icr.size > 0). Σ is the
/// slip noise plus the joint-rate and steering noise carried through at the seed's states
/// (rover::slipCovariance); t_nom the nominal slip of the nominal body twist (rover::nominalSlip),
/// the command's, or with `nominal_follows_state` (no cmd.csv) the state's own (v_x + c_x, ω_z),
/// linearised exactly about the seed's (nominal_twist is then ignored).
/// Each wheel's numbers are appended to `data`, which the cost functions refer to: it is reserved
/// beforehand and must not reallocate (std::logic_error if it would).
void addSlipResiduals(ResidualCollector& out, std::vector<SlipWheelData>& data,
                      const rover::RoverGeometry& geometry, const rover::SlipNoise& noise,
                      const rover::JointSample& js, const est::TrajectoryNode& seed,
                      const Twistd& nominal_twist, ceres::LossFunction* loss, const NodeHandles& k,
                      bool nominal_follows_state = false);

}  // namespace traverse::smoother
