// Contact solver: on every terrain, at every point of a path, every wheel is within 0.1 mm of the
// surface, tangent to it within 0.1°, and no wheel is below it.
#include <gtest/gtest.h>

#include "support/jacobian_check.h"
#include "support/rocky7.h"
#include "traverse/io/rover_description.h"
#include "traverse/sim/contact_solver.h"

namespace traverse::sim {
namespace {

using testing::rocky7;

struct Case {
  const char* name;
  std::shared_ptr<const Terrain> terrain;
  double x0, y0, yaw, length;
};

class SimContact : public ::testing::TestWithParam<int> {};

std::vector<Case> cases() {
  RoughTerrain::Options rough;
  rough.rms_height_m = 0.02;
  rough.correlation_length_m = 0.4;
  rough.x_min = -3, rough.x_max = 6, rough.y_min = -3, rough.y_max = 3;
  return {
      {"flat", std::make_shared<FlatTerrain>(0.3), 0, 0, 0.4, 1.0},
      {"plane", std::make_shared<PlaneTerrain>(0.2, 0.7), 0, 0, -0.3, 1.0},
      {"undulating", std::make_shared<UndulatingTerrain>(), 0, 0, 0.0, 1.0},
      {"step", std::make_shared<StepTerrain>(0.06, 0.5, -1.0, 0.0, 0.15), 0, 0, 0.0, 1.2},
      {"rough", std::make_shared<RoughTerrain>(rough), 0, 0, 0.2, 3.0},
  };
}

TEST_P(SimContact, EveryWheelTouchesAlongAPath) {
  const Case c = cases()[GetParam()];
  const ContactSolver solver(rocky7(), *c.terrain);
  ContactState s = solver.initialGuess(c.x0, c.y0, c.yaw);
  double worst_gap = 0, worst_tangency = 0, worst_below = 0;
  const int n = 400;
  for (int k = 0; k <= n; ++k) {
    const double d = c.length * k / n;
    const double x = c.x0 + d * std::cos(c.yaw), y = c.y0 + d * std::sin(c.yaw);
    ASSERT_NO_THROW(s = solver.solve(x, y, c.yaw, Vec2d::Zero(), s)) << c.name << " at " << d;
    for (const WheelContactCheck& w : solver.check(x, y, c.yaw, Vec2d::Zero(), s)) {
      worst_gap = std::max(worst_gap, std::abs(w.gap_m));
      worst_tangency = std::max(worst_tangency, w.tangency_rad);
      worst_below = std::min(worst_below, w.min_rim_gap_m);
    }
  }
  EXPECT_LT(worst_gap, 1e-4) << c.name;
  EXPECT_LT(worst_tangency, 0.1 * M_PI / 180) << c.name;
  EXPECT_GT(worst_below, -1e-4) << c.name;
}

INSTANTIATE_TEST_SUITE_P(Terrains, SimContact, ::testing::Range(0, 5),
                         [](const auto& info) { return std::string(cases()[info.param].name); });

// Hand-checked: on a plane of slope α rising along the heading, γ = 0 and the body pitches by
// −α (nose up is negative pitch in Z-Y-X), every contact at ξ = 0.
TEST(SimContactPlane, BodyFollowsThePlane) {
  const PlaneTerrain plane(0.15, 0.0);
  const ContactSolver solver(rocky7(), plane);
  const ContactState s =
      solver.solve(1.0, 0.5, 0.0, Vec2d::Zero(), solver.initialGuess(1.0, 0.5, 0.0));
  EXPECT_NEAR(s.pitch, -0.15, 1e-9);
  EXPECT_NEAR(s.roll, 0.0, 1e-9);
  EXPECT_LT(s.suspension.norm(), 1e-8);
  for (double xi : s.xi) EXPECT_NEAR(xi, 0.0, 1e-7);
}

// A step that cannot be climbed in one configuration: the solver fails loudly and says where.
TEST(SimContactPlane, FailsLoudlyWithWhere) {
  const StepTerrain wall(2.0, 0.3, -1.0, 1.0, 0.01);
  const ContactSolver solver(rocky7(), wall);
  try {
    solver.solve(0.2, 0.0, 0.0, Vec2d::Zero(), solver.initialGuess(0.0, 0.0, 0.0));
    FAIL() << "expected ContactError";
  } catch (const ContactError& e) {
    EXPECT_NE(std::string(e.what()).find("x = 0.2"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace traverse::sim
