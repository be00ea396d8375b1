// The EKF's slip-update Jacobian against central differences of its whole residual
// (nominal − t, K-17 and K §2.3.4), with the nominal slip from a command and from the state.
#include <gtest/gtest.h>

#include <random>

#include "support/jacobian_check.h"
#include "support/rocky7.h"
#include "traverse/estimators/ekf.h"
#include "traverse/io/rover_description.h"
#include "traverse/rover/nominal_slip.h"
#include "traverse/rover/slip_constraint.h"

namespace traverse::est {
namespace {

using testing::randomJointSample;
using testing::rocky7;

void expectSlipJacobianMatchesNumeric(bool with_command) {
  std::mt19937 rng(with_command ? 11 : 12);
  const rover::RoverGeometry& geo = rocky7();
  for (int trial = 0; trial < 20; ++trial) {
    const rover::JointSample js = randomJointSample(rng);
    const Twistd cmd = rover::nominalBodyTwist(geo, 0.1 * trial / 20.0, 0.05);
    const Twistd* commanded = with_command ? &cmd : nullptr;
    Eigen::Matrix<double, 7, 1> s = testing::randomVector<7>(rng, 0.2);
    s[6] = 0.4 * (s[6] / 0.2);  // contact angle up to ±0.4 rad
    for (int i = 0; i < r7::kNumWheels; ++i) {
      Eigen::Matrix<double, 4, 7> H, Jt;
      slipUpdateResidual(geo, js, i, commanded, s, &H, &Jt);
      // H = −∂r/∂s (r = z − h(x) with z the nominal slip or 0).
      const auto r = [&](const Eigen::Matrix<double, 7, 1>& x) {
        Eigen::Matrix<double, 4, 7> unused;
        return slipUpdateResidual(geo, js, i, commanded, x, &unused);
      };
      const Eigen::Matrix<double, 4, 7> Hn = -testing::numericJacobian<4, 7>(r, s);
      EXPECT_LE((H - Hn).cwiseAbs().maxCoeff(), 1e-7 * std::max(1.0, Hn.cwiseAbs().maxCoeff()))
          << "wheel " << i << " command " << with_command << "\nH:\n"
          << H << "\nnumeric:\n"
          << Hn;
      // dt_ds is the constraint's own Jacobian; with a command it equals H.
      if (with_command) {
        EXPECT_LE((H - Jt).cwiseAbs().maxCoeff(), 1e-15);
      }
    }
  }
}

TEST(EstEkfJacobian, SlipUpdateWithCommandMatchesNumeric) {
  expectSlipJacobianMatchesNumeric(true);
}

TEST(EstEkfJacobian, SlipUpdateWithoutCommandDifferentiatesTheNominalSlip) {
  expectSlipJacobianMatchesNumeric(false);
}

// Hand-checked: a level rover at zero joint angles turning in place at ω_z with no command.
// The nominal slip is computed from ω_z itself, so the spin row (ω_z about the contact normal in
// both t and the nominal) carries no information on ω_z: its H entry is 0, where the
// constraint alone would claim 1.
TEST(EstEkfJacobian, SpinRowHasNoInformationOnYawRateWithoutCommand) {
  const rover::RoverGeometry& geo = rocky7();
  const auto kin = rover::forwardKinematics<double>(geo, rover::JointVectord::Zero(r7::kNumCoords));
  rover::JointSample js;
  js.resize(geo.numWheels());
  for (int i = 0; i < r7::kNumWheels; ++i) {
    js.T_body_wheel[i] = kin[i].T_body_wheel;
    js.joint_twist[i].setZero();
  }
  Eigen::Matrix<double, 7, 1> s = Eigen::Matrix<double, 7, 1>::Zero();
  s[5] = 0.2;
  s[1] = -0.2 * geo.turn_centre_x;  // the nominal twist of that turn
  for (int i = 0; i < r7::kNumWheels; ++i) {
    Eigen::Matrix<double, 4, 7> H, Jt;
    const Vec4d r = slipUpdateResidual(geo, js, i, nullptr, s, &H, &Jt);
    // The state is the nominal motion: the nominal rows (transverse, spin) have no residual.
    EXPECT_NEAR(r[1], 0.0, 1e-12) << "wheel " << i;
    EXPECT_NEAR(r[3], 0.0, 1e-12) << "wheel " << i;
    EXPECT_NEAR(Jt(3, 5), 1.0, 1e-12) << "wheel " << i;  // the constraint's spin row: ∂/∂ω_z = 1
    EXPECT_NEAR(H(3, 5), 0.0, 1e-12) << "wheel " << i;  // the whole residual's: none
  }
}

}  // namespace
}  // namespace traverse::est
