// Rocker-bogie kinematics and the slip constraint (K §2, K-17 … K-20) on the bundled Rocky-7.
#include <gtest/gtest.h>

#include "support/jacobian_check.h"
#include "support/rocky7.h"
#include "traverse/io/rover_description.h"
#include "traverse/rover/joint_rates.h"
#include "traverse/rover/kinematics.h"
#include "traverse/rover/nominal_slip.h"
#include "traverse/rover/slip_constraint.h"

namespace traverse::rover {
namespace {

using testing::randomVector;

using testing::rocky7;

JointVectord randomSuspension(std::mt19937& rng) {
  JointVectord q = JointVectord::Zero(r7::kNumCoords);
  q.head<3>() = randomVector<3>(rng, 0.3);
  q.segment<2>(r7::kLambda1) = randomVector<2>(rng, 0.5);
  q.tail<6>() = randomVector<6>(rng, 10.0);
  return q;
}

TEST(RoverGeometry, LoadsRocky7FromUrdf) {
  const RoverGeometry& g = rocky7();
  EXPECT_EQ(g.name, "rocky7");
  for (const Wheel& w : g.wheels) EXPECT_DOUBLE_EQ(w.radius, 0.065);
  EXPECT_DOUBLE_EQ(g.turn_centre_x, -0.10);
  int mimics = 0;
  for (const KinematicJoint& j : g.joints) mimics += j.multiplier == -1.0 && j.coord == r7::kGamma0;
  EXPECT_EQ(mimics, 1) << "the right rocker follows the differential with multiplier −1";
}

// Joint angle zero: all six wheel centres in one plane parallel to the body x-y plane.
TEST(RoverKinematics, ZeroAnglesPutWheelCentresInOnePlane) {
  const auto kin = forwardKinematics<double>(rocky7(), JointVectord::Zero(r7::kNumCoords));
  const Vec3d expected[r7::kNumWheels] = {{0.25, 0.24, -0.12},  {0.0, 0.24, -0.12},
                                          {-0.20, 0.24, -0.12}, {0.25, -0.24, -0.12},
                                          {0.0, -0.24, -0.12},  {-0.20, -0.24, -0.12}};
  for (int i = 0; i < r7::kNumWheels; ++i) {
    EXPECT_LT((kin[i].T_body_wheel.p - expected[i]).norm(), 1e-15) << "wheel " << i + 1;
    EXPECT_LT((kin[i].T_body_wheel.R - Mat3d::Identity()).norm(), 1e-15);
  }
}

// Hand-checked: γ0 = 0.1 rotates the left rocker about its pivot (0, 0.20, 0) by +0.1 about y and
// the right one by −0.1 (differential); a rotation about +y by a takes (x, z) to
// (x cos a + z sin a, −x sin a + z cos a).
TEST(RoverKinematics, DifferentialRotatesRockersOppositely) {
  JointVectord q = JointVectord::Zero(r7::kNumCoords);
  q[r7::kGamma0] = 0.1;
  const auto kin = forwardKinematics<double>(rocky7(), q);
  const double c = std::cos(0.1), s = std::sin(0.1);
  const Vec3d front_left(0.25 * c - 0.12 * s, 0.24, -0.25 * s - 0.12 * c);
  const Vec3d front_right(0.25 * c + 0.12 * s, -0.24, 0.25 * s - 0.12 * c);
  EXPECT_LT((kin[0].T_body_wheel.p - front_left).norm(), 1e-15);
  EXPECT_LT((kin[3].T_body_wheel.p - front_right).norm(), 1e-15);
}

// J^s_{s f_i} against finite differences of the forward kinematics (wheel frame including its
// drive rotation): column c = ((∂g/∂q_c) g⁻¹)^∨ = [ṗ − ω × p; ω].
TEST(RoverKinematics, SpatialJacobianMatchesFiniteDifferences) {
  std::mt19937 rng(11);
  const RoverGeometry& geo = rocky7();
  for (int trial = 0; trial < 20; ++trial) {
    const JointVectord q = randomSuspension(rng);
    const auto kin = forwardKinematics<double>(geo, q);
    for (int i = 0; i < r7::kNumWheels; ++i) {
      const int d = geo.wheels[i].drive_joint;
      for (int c = 0; c < r7::kNumCoords; ++c) {
        const double h = 1e-6;
        JointVectord qp = q, qm = q;
        qp[c] += h;
        qm[c] -= h;
        const Posed gp = jointPoses<double>(geo, qp)[d], gm = jointPoses<double>(geo, qm)[d];
        const Posed g0 = jointPoses<double>(geo, q)[d];
        const Vec3d w = so3::vee<double>((gp.R - gm.R) / (2 * h) * g0.R.transpose());
        const Vec3d pdot = (gp.p - gm.p) / (2 * h);
        Twistd col;
        col << pdot - w.cross(g0.p), w;
        EXPECT_LT((kin[i].J.col(c) - col).norm(), 1e-8)
            << "wheel " << i + 1 << " coord " << rocky7().coords[static_cast<size_t>(c)].column;
      }
    }
  }
}

TEST(RoverKinematics, ContactAtZeroXiIsWheelBottom) {
  std::mt19937 rng(12);
  for (int trial = 0; trial < 10; ++trial) {
    const auto kin = forwardKinematics<double>(rocky7(), randomSuspension(rng));
    for (int i = 0; i < r7::kNumWheels; ++i) {
      const Posed& w = kin[i].T_body_wheel;
      const Posed l = contactFrame(w, 0.065, 0.0);
      EXPECT_LT((l.p - (w.p - 0.065 * w.R.col(2))).norm(), 1e-15);
      EXPECT_LT((l.R - w.R).norm(), 1e-15);
    }
  }
  // ξ > 0 moves the contact forward and tilts the normal backwards (climbing a step ahead).
  const Posed l = wheelToContact(M_PI / 2, 0.065);
  EXPECT_LT((l.p - Vec3d(0.065, 0, 0)).norm(), 1e-15);
  EXPECT_LT((l.R.col(2) - Vec3d(-1, 0, 0)).norm(), 1e-15);
}

TEST(SlipConstraint, RollingOnFlatGroundIsZero) {
  const RoverGeometry& geo = rocky7();
  const auto kin = forwardKinematics<double>(geo, JointVectord::Zero(r7::kNumCoords));
  const double v = 0.07;
  JointVectord q_dot = JointVectord::Zero(r7::kNumCoords);
  q_dot.tail<6>().setConstant(v / 0.065);
  for (int i = 0; i < r7::kNumWheels; ++i) {
    const Vec4d t =
        slipConstraint<double>(kin[i].T_body_wheel, 0.065, wheelJointTwist(kin[i], q_dot),
                               Vec3d(v, 0, 0), Vec3d::Zero(), 0.0);
    EXPECT_LT(t.norm(), 1e-15) << "wheel " << i + 1;
  }
  // Hand-checked: wheels locked (ψ̇ = 0) while the body moves at v: the contact point slides
  // forward with the body, t = (v, 0, 0, 0).
  const Vec4d t = slipConstraint<double>(kin[1].T_body_wheel, 0.065, Twistd::Zero(), Vec3d(v, 0, 0),
                                         Vec3d::Zero(), 0.0);
  EXPECT_LT((t - Vec4d(v, 0, 0, 0)).norm(), 1e-15);
}

// A rover on a plane of slope 20° driving diagonally across it: the body (parallel to the plane)
// moves along its x axis in the site frame; in body coordinates rolling still gives t = 0.
TEST(SlipConstraint, RollingOnTiltedPlaneIsZero) {
  const RoverGeometry& geo = rocky7();
  const Quatd q_site_body = so3::fromRollPitchYaw(0.15, -0.30, 0.7);  // on a ~20° slope
  const double v = 0.05;
  const Vec3d v_site = q_site_body * Vec3d(v, 0, 0);  // along the plane
  const Vec3d v_body = q_site_body.conjugate() * v_site;
  const auto kin = forwardKinematics<double>(geo, JointVectord::Zero(r7::kNumCoords));
  JointVectord q_dot = JointVectord::Zero(r7::kNumCoords);
  q_dot.tail<6>().setConstant(v / 0.065);
  for (int i = 0; i < r7::kNumWheels; ++i) {
    const Vec4d t = slipConstraint<double>(
        kin[i].T_body_wheel, 0.065, wheelJointTwist(kin[i], q_dot), v_body, Vec3d::Zero(), 0.0);
    EXPECT_LT(t.norm(), 1e-15);
  }
}

// The general case: articulated suspension in motion (random γ, γ̇, heave, pitch rate) with
// each wheel rolling on its own locally tilted ground. Every wheel centre then moves in its
// wheel's x-z plane; the ground tangent is along that velocity (ξ_i = atan2(u_z, u_x)) and the
// wheel rolls at ψ̇_i = |u_i|/r. K-17 must give t = 0 for every wheel.
TEST(SlipConstraint, ArticulatedRollingOnLocalSlopesIsZero) {
  const RoverGeometry& geo = rocky7();
  std::mt19937 rng(13);
  for (int trial = 0; trial < 50; ++trial) {
    JointVectord q = JointVectord::Zero(r7::kNumCoords);
    q.head<3>() = randomVector<3>(rng, 0.3);
    const auto kin = forwardKinematics<double>(geo, q);
    JointVectord q_dot = JointVectord::Zero(r7::kNumCoords);
    q_dot.head<3>() = randomVector<3>(rng, 0.2);
    const Vec3d v(0.1, 0.0, randomVector<1>(rng, 0.02)[0]);
    const Vec3d w(0.0, randomVector<1>(rng, 0.1)[0], 0.0);
    for (int i = 0; i < r7::kNumWheels; ++i) {
      const Twistd jt_no_drive = wheelJointTwist(kin[i], q_dot);
      const Posed& g = kin[i].T_body_wheel;
      const Vec3d u_body = v + jt_no_drive.head<3>() + (w + jt_no_drive.tail<3>()).cross(g.p);
      const Vec3d u = g.R.transpose() * u_body;  // wheel-centre velocity in the wheel frame
      ASSERT_LT(std::abs(u.y()), 1e-12);
      const double xi = std::atan2(u.z(), u.x());
      JointVectord q_dot_i = q_dot;
      q_dot_i[r7::kPsi1 + i] =
          u.norm() / geo.wheels[i].radius - (g.R.transpose() * (w + jt_no_drive.tail<3>())).y();
      const Vec4d t = slipConstraint<double>(g, geo.wheels[i].radius,
                                             wheelJointTwist(kin[i], q_dot_i), v, w, xi);
      EXPECT_LT(t.norm(), 1e-12) << "wheel " << i + 1 << " t = " << t.transpose();
    }
  }
}

// Turn in place about (x_c, 0): front wheels steered tangent to the circle and rolling, bogie
// wheels rolling along their heading. Front wheels: only the spin ω; bogie wheels: spin ω and
// the deterministic transverse slip ω (x_i − x_c) of K §2.3.4. nominalSlip() must agree.
TEST(SlipConstraint, TurnInPlaceGivesNominalSpinAndBogieSlip) {
  const RoverGeometry& geo = rocky7();
  const double wz = 0.2, xc = geo.turn_centre_x;
  JointVectord q = JointVectord::Zero(r7::kNumCoords);
  const auto kin0 = forwardKinematics<double>(geo, q);
  // Steer each front wheel perpendicular to the radius from the turn centre.
  for (int i : {0, 3}) {
    const Vec3d p = kin0[i].T_body_wheel.p;
    q[i == 0 ? r7::kLambda1 : r7::kLambda2] = -std::atan((p.x() - xc) / p.y());
  }
  const auto kin = forwardKinematics<double>(geo, q);
  const Twistd V = nominalBodyTwist(geo, 0.0, wz);
  JointVectord q_dot = JointVectord::Zero(r7::kNumCoords);
  for (int i = 0; i < r7::kNumWheels; ++i) {
    const Vec3d c = kin[i].T_body_wheel.p - 0.065 * kin[i].T_body_wheel.R.col(2);
    const Vec3d vc = V.head<3>() + V.tail<3>().cross(c);
    q_dot[r7::kPsi1 + i] = (kin[i].T_body_wheel.R.transpose() * vc).x() / 0.065;
  }
  for (int i = 0; i < r7::kNumWheels; ++i) {
    const Twistd jt = wheelJointTwist(kin[i], q_dot);
    const Vec4d t = slipConstraint<double>(kin[i].T_body_wheel, 0.065, jt, Vec3d(V.head<3>()),
                                           Vec3d(V.tail<3>()), 0.0);
    const bool front = i == 0 || i == 3;
    const double x = kin[i].T_body_wheel.p.x();
    const Vec4d expected(0, front ? 0.0 : wz * (x - xc), 0, wz);
    EXPECT_LT((t - expected).norm(), 1e-14) << "wheel " << i + 1 << ": " << t.transpose();
    EXPECT_LT((nominalSlip(kin[i].T_body_wheel, 0.065, V, jt) - expected).norm(), 1e-14);
  }
}

TEST(SlipConstraint, JacobianMatchesNumericAtRandomStates) {
  const RoverGeometry& geo = rocky7();
  std::mt19937 rng(14);
  for (int trial = 0; trial < 30; ++trial) {
    const auto kin = forwardKinematics<double>(geo, randomSuspension(rng));
    const JointVectord q_dot = randomVector<r7::kNumCoords>(rng, 1.0);
    const int i = trial % r7::kNumWheels;
    const Twistd jt = wheelJointTwist(kin[i], q_dot);
    Eigen::Matrix<double, 7, 1> x;
    x << randomVector<3>(rng, 0.2), randomVector<3>(rng, 0.5), randomVector<1>(rng, 0.6);
    testing::expectJacobianMatchesNumeric<4, 7>(
        [&](const auto& s) {
          using T = typename std::decay_t<decltype(s)>::Scalar;
          return slipConstraint<T>(kin[i].T_body_wheel, geo.wheels[i].radius, jt,
                                   Vec3<T>(s.template head<3>()), Vec3<T>(s.template segment<3>(3)),
                                   s[6]);
        },
        x);
  }
}

TEST(JointRates, ExactForQuadraticsWithIrregularSampling) {
  std::mt19937 rng(15);
  std::vector<double> t;
  double tk = 0.0;
  for (int k = 0; k < 60; ++k) t.push_back(tk += 0.05 + 0.05 * randomVector<1>(rng, 1.0)[0] * 0.5);
  Eigen::MatrixXd a(60, 2);
  for (int k = 0; k < 60; ++k) a.row(k) << 1 + 2 * t[k] - 0.5 * t[k] * t[k], std::cos(0.3) * t[k];
  const Eigen::MatrixXd r = jointRates(t, a);
  for (int k = 0; k < 60; ++k) {
    EXPECT_NEAR(r(k, 0), 2 - t[k], 1e-9);
    EXPECT_NEAR(r(k, 1), std::cos(0.3), 1e-9);
  }
}

TEST(JointRates, SmoothsNoiseByTheDocumentedGain) {
  std::mt19937 rng(16);
  std::normal_distribution<double> n(0.0, 0.01);
  const int N = 20000, h = 3;
  const double dt = 0.1;
  std::vector<double> t(N);
  Eigen::MatrixXd a(N, 1);
  for (int k = 0; k < N; ++k) t[k] = k * dt, a(k, 0) = n(rng);
  const Eigen::MatrixXd r = jointRates(t, a, {h});
  const double expected = 0.01 * std::sqrt(3.0 / (h * (h + 1.0) * (2 * h + 1.0))) / dt;
  const double sample = std::sqrt(r.middleRows(h, N - 2 * h).squaredNorm() / (N - 2 * h));
  EXPECT_NEAR(sample / expected, 1.0, 0.03);
}

}  // namespace
}  // namespace traverse::rover

namespace traverse::rover {
namespace {

// The EKF's analytic K-17 Jacobian equals the Jet derivative of the templated model.
TEST(SlipConstraint, AnalyticJacobianMatchesJets) {
  const RoverGeometry& geo = rocky7();
  std::mt19937 rng(17);
  for (int trial = 0; trial < 60; ++trial) {
    const auto kin = forwardKinematics<double>(geo, randomSuspension(rng));
    const int i = trial % r7::kNumWheels;
    const Twistd jt = wheelJointTwist(kin[i], randomVector<r7::kNumCoords>(rng, 1.0));
    Eigen::Matrix<double, 7, 1> x;
    x << randomVector<3>(rng, 0.2), randomVector<3>(rng, 0.5), randomVector<1>(rng, 0.6);
    const auto f = [&](const auto& s) {
      using T = typename std::decay_t<decltype(s)>::Scalar;
      return slipConstraint<T>(kin[i].T_body_wheel, geo.wheels[i].radius, jt,
                               Vec3<T>(s.template head<3>()), Vec3<T>(s.template segment<3>(3)),
                               s[6]);
    };
    Eigen::Matrix<double, 4, 7> J;
    const Vec4d t = slipConstraintWithJacobian(kin[i].T_body_wheel, geo.wheels[i].radius, jt,
                                               x.head<3>(), x.segment<3>(3), x[6], &J);
    EXPECT_LT((t - f(x)).norm(), 1e-14);
    EXPECT_LT((J - testing::autodiffJacobian<4, 7>(f, x)).cwiseAbs().maxCoeff(), 1e-12);
  }
}

}  // namespace
}  // namespace traverse::rover
